//! `rosgraph_msgs/msg/Clock`, what `ros2 bag play --clock` and simulators publish on `/clock`.

use super::builtin_interfaces::{Time, TIME};
use super::{MsgDef, RosMessage};
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

/// The `.msg` definition of [`Clock`].
pub static CLOCK: MsgDef = MsgDef {
    name: "rosgraph_msgs/msg/Clock",
    text: "builtin_interfaces/Time clock\n",
    deps: &[&TIME],
    type_hash: "",
};

impl RosMessage for Clock {
    const DEF: &'static MsgDef = &CLOCK;
}
