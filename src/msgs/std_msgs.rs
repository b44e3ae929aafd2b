//! `std_msgs/msg/Header`.

use super::builtin_interfaces::Time;
use super::RosMessage;
use serde::{Deserialize, Serialize};

/// `std_msgs/msg/Header`: a stamp and a coordinate frame.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// When the data was taken (sensor clock).
    pub stamp: Time,
    /// The coordinate frame of the data.
    pub frame_id: String,
}

impl RosMessage for Header {
    const PACKAGE: &'static str = "std_msgs";
    const NAME: &'static str = "Header";
    const FIELDS: &'static [(&'static str, &'static str)] =
        &[("builtin_interfaces/Time", "stamp"), ("string", "frame_id")];
}
