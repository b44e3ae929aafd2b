//! `std_msgs`: the message header.

use super::builtin_interfaces::{Time, TIME};
use super::MsgDef;
use serde::{Deserialize, Serialize};

/// `std_msgs/msg/Header`: when (sensor clock) and in which frame a measurement was taken.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// Sensor time of the measurement.
    pub stamp: Time,
    /// Coordinate frame of the measurement, e.g. `imu_link`.
    pub frame_id: String,
}

/// The `.msg` definition of [`Header`].
pub static HEADER: MsgDef = MsgDef {
    name: "std_msgs/msg/Header",
    text: "builtin_interfaces/Time stamp\nstring frame_id\n",
    deps: &[&TIME],
    type_hash: "",
};
