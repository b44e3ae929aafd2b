//! `geometry_msgs`: vectors and rotations.

use super::MsgDef;
use serde::{Deserialize, Serialize};

/// `geometry_msgs/msg/Vector3`: a free vector (rates, accelerations).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x component.
    pub x: f64,
    /// y component.
    pub y: f64,
    /// z component.
    pub z: f64,
}

impl Vector3 {
    /// The components as `[x, y, z]`.
    pub fn to_array(self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }

    /// A vector from `[x, y, z]`.
    pub fn from_array([x, y, z]: [f64; 3]) -> Self {
        Vector3 { x, y, z }
    }
}

/// The `.msg` definition of [`Vector3`].
pub static VECTOR3: MsgDef = MsgDef {
    name: "geometry_msgs/msg/Vector3",
    text: "float64 x\nfloat64 y\nfloat64 z\n",
    deps: &[],
    type_hash: "",
};

/// `geometry_msgs/msg/Quaternion`: an orientation, `w` last.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x component.
    pub x: f64,
    /// y component.
    pub y: f64,
    /// z component.
    pub z: f64,
    /// w (scalar) component.
    pub w: f64,
}

impl Default for Quaternion {
    /// The identity rotation, as the ROS 2 message defaults it (`w = 1`).
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// The `.msg` definition of [`Quaternion`] (with the ROS 2 default values).
pub static QUATERNION: MsgDef = MsgDef {
    name: "geometry_msgs/msg/Quaternion",
    text: "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    deps: &[],
    type_hash: "",
};
