//! `sensor_msgs/msg/Imu` and `sensor_msgs/msg/Temperature`.

use super::std_msgs::Header;
use super::RosMessage;
use crate::signal::{ImuSample, TemperatureSample};
use serde::{Deserialize, Serialize};

/// `geometry_msgs/msg/Vector3`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x component.
    pub x: f64,
    /// y component.
    pub y: f64,
    /// z component.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x component.
    pub x: f64,
    /// y component.
    pub y: f64,
    /// z component.
    pub z: f64,
    /// w component.
    pub w: f64,
}

/// `sensor_msgs/msg/Imu`: orientation, angular velocity (rad/s), linear acceleration (m/s²).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Sensor stamp and frame.
    pub header: Header,
    /// Orientation estimate (unused by fdavar).
    pub orientation: Quaternion,
    /// Row-major 3×3 covariance of the orientation.
    pub orientation_covariance: [f64; 9],
    /// Angular velocity, rad/s.
    pub angular_velocity: Vector3,
    /// Row-major 3×3 covariance of the angular velocity.
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration, m/s².
    pub linear_acceleration: Vector3,
    /// Row-major 3×3 covariance of the linear acceleration.
    pub linear_acceleration_covariance: [f64; 9],
}

impl Imu {
    /// The six rates of this message at its header stamp.
    pub fn sample(&self) -> ImuSample {
        let (g, a) = (self.angular_velocity, self.linear_acceleration);
        ImuSample {
            stamp_ns: self.header.stamp.to_nanos(),
            gyro: [g.x, g.y, g.z],
            accel: [a.x, a.y, a.z],
        }
    }
}

impl RosMessage for Imu {
    const PACKAGE: &'static str = "sensor_msgs";
    const NAME: &'static str = "Imu";
    const FIELDS: &'static [(&'static str, &'static str)] = &[
        ("std_msgs/Header", "header"),
        ("geometry_msgs/Quaternion", "orientation"),
        ("float64[9]", "orientation_covariance"),
        ("geometry_msgs/Vector3", "angular_velocity"),
        ("float64[9]", "angular_velocity_covariance"),
        ("geometry_msgs/Vector3", "linear_acceleration"),
        ("float64[9]", "linear_acceleration_covariance"),
    ];
}

/// `sensor_msgs/msg/Temperature`: degrees Celsius and its variance.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Temperature {
    /// Sensor stamp and frame.
    pub header: Header,
    /// Temperature, °C.
    pub temperature: f64,
    /// Variance, °C² (0 = unknown).
    pub variance: f64,
}

impl Temperature {
    /// This reading as a [`TemperatureSample`].
    pub fn sample(&self) -> TemperatureSample {
        TemperatureSample {
            stamp_ns: self.header.stamp.to_nanos(),
            celsius: self.temperature,
        }
    }
}

impl RosMessage for Temperature {
    const PACKAGE: &'static str = "sensor_msgs";
    const NAME: &'static str = "Temperature";
    const FIELDS: &'static [(&'static str, &'static str)] = &[
        ("std_msgs/Header", "header"),
        ("float64", "temperature"),
        ("float64", "variance"),
    ];
}
