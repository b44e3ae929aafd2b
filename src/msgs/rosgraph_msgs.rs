//! `rosgraph_msgs/msg/Clock`, what `ros2 bag play --clock` and simulators publish on `/clock`.

use super::builtin_interfaces::Time;
use super::RosMessage;
use serde::{Deserialize, Serialize};

/// `rosgraph_msgs/msg/Clock`: the simulated time.
///
/// Why a mirror of our own: ros2-client 0.12.1 subscribes `/clock` as `builtin_interfaces/Time`,
/// which never matches a real clock publisher; the node subscribes this type itself.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Clock {
    /// The current simulated time.
    pub clock: Time,
}

impl RosMessage for Clock {
    const PACKAGE: &'static str = "rosgraph_msgs";
    const NAME: &'static str = "Clock";
    const FIELDS: &'static [(&'static str, &'static str)] = &[("builtin_interfaces/Time", "clock")];
}
