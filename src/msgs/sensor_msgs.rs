//! `sensor_msgs`: the IMU and temperature messages fdavar analyses.

use super::builtin_interfaces::Time;
use super::geometry_msgs::{Quaternion, Vector3, QUATERNION, VECTOR3};
use super::std_msgs::{Header, HEADER};
use super::{MsgDef, MsgError};
use crate::signal::{ImuSample, TemperatureSample};
use serde::{Deserialize, Serialize};

/// `sensor_msgs/msg/Imu`: one IMU reading (orientation, angular velocity, linear acceleration).
///
/// fdavar uses `angular_velocity` (gyro axes, rad/s) and `linear_acceleration` (accel axes, m/s²)
/// and the header stamp; orientation and covariances are carried through unchanged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Sensor time and frame.
    pub header: Header,
    /// Orientation estimate, if the IMU makes one.
    pub orientation: Quaternion,
    /// Row-major 3×3 covariance of `orientation`; element 0 = −1 means "no orientation estimate".
    pub orientation_covariance: [f64; 9],
    /// Angular velocity, rad/s.
    pub angular_velocity: Vector3,
    /// Row-major 3×3 covariance of `angular_velocity`; all zero means "unknown".
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration, m/s².
    pub linear_acceleration: Vector3,
    /// Row-major 3×3 covariance of `linear_acceleration`; all zero means "unknown".
    pub linear_acceleration_covariance: [f64; 9],
}

/// What the analysis of a recording reads of an [`Imu`] message, its stamp and rates, decoded
/// from the same bytes (`msgs::decode_as`) without keeping its frame or the rest.
///
/// Why: a whole [`Imu`] allocates its `frame_id` for every message, only for the reader to drop
/// it: reading an hour at 100 Hz took 0.150 s that way and 0.139 s this way (`cargo bench
/// --bench bag_read`). The fields are [`Imu`]'s, in its order, as CDR needs; a test checks that
/// both decode the same sample from any message.
#[derive(Deserialize)]
pub(crate) struct ImuReading {
    header: StampReading,
    _orientation: Quaternion,
    _orientation_covariance: [f64; 9],
    angular_velocity: Vector3,
    _angular_velocity_covariance: [f64; 9],
    linear_acceleration: Vector3,
    _linear_acceleration_covariance: [f64; 9],
}

/// A [`Header`] read for its stamp: the frame name is checked to be a string, then dropped.
#[derive(Deserialize)]
struct StampReading {
    stamp: Time,
    _frame_id: Unread,
}

/// A string field read past without a copy.
struct Unread;

impl<'de> Deserialize<'de> for Unread {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Past;
        impl serde::de::Visitor<'_> for Past {
            type Value = Unread;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a string")
            }
            fn visit_str<E: serde::de::Error>(self, _: &str) -> Result<Unread, E> {
                Ok(Unread)
            }
        }
        deserializer.deserialize_str(Past)
    }
}

impl ImuReading {
    /// The six rates, timed as [`Imu::to_sample`] times them.
    pub(crate) fn to_sample(&self, log_time_ns: i64) -> ImuSample {
        ImuSample {
            stamp_ns: sample_time(self.header.stamp, log_time_ns),
            gyro: self.angular_velocity.to_array(),
            accel: self.linear_acceleration.to_array(),
        }
    }
}

/// The `.msg` definition of [`Imu`].
pub static IMU: MsgDef = MsgDef {
    name: "sensor_msgs/msg/Imu",
    text: "std_msgs/Header header\n\
           geometry_msgs/Quaternion orientation\n\
           float64[9] orientation_covariance\n\
           geometry_msgs/Vector3 angular_velocity\n\
           float64[9] angular_velocity_covariance\n\
           geometry_msgs/Vector3 linear_acceleration\n\
           float64[9] linear_acceleration_covariance\n",
    deps: &[&HEADER, &QUATERNION, &VECTOR3],
    type_hash: "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b",
};

/// The sample time of a header: its stamp, or `log_time_ns` when the stamp is zero (docs/design.md §1).
fn sample_time(stamp: Time, log_time_ns: i64) -> i64 {
    if stamp.is_zero() {
        log_time_ns
    } else {
        stamp.to_ns()
    }
}

/// A header stamped `stamp_ns` in `frame_id`.
fn header(stamp_ns: i64, frame_id: &str) -> Result<Header, MsgError> {
    Ok(Header {
        stamp: Time::from_ns(stamp_ns)?,
        frame_id: frame_id.to_string(),
    })
}

impl Imu {
    /// The six rates of this message, timed by its header stamp.
    ///
    /// `log_time_ns` (when the recorder received it) stands in for a zero stamp, the convention of
    /// drivers that have no clock of their own.
    pub fn to_sample(&self, log_time_ns: i64) -> ImuSample {
        ImuSample {
            stamp_ns: sample_time(self.header.stamp, log_time_ns),
            gyro: self.angular_velocity.to_array(),
            accel: self.linear_acceleration.to_array(),
        }
    }

    /// A message carrying `sample`'s rates, stamped `sample.stamp_ns`, in `frame_id`.
    ///
    /// The IMU has no orientation estimate (identity quaternion, `orientation_covariance[0] = −1`,
    /// the sensor_msgs convention) and the rate covariances are unknown (all zero).
    ///
    /// # Errors
    /// [`MsgError::StampOutOfRange`] when the stamp does not fit a ROS `Time`.
    pub fn from_sample(sample: &ImuSample, frame_id: &str) -> Result<Imu, MsgError> {
        let mut orientation_covariance = [0.0; 9];
        orientation_covariance[0] = -1.0;
        Ok(Imu {
            header: header(sample.stamp_ns, frame_id)?,
            orientation: Quaternion::default(),
            orientation_covariance,
            angular_velocity: Vector3::from_array(sample.gyro),
            angular_velocity_covariance: [0.0; 9],
            linear_acceleration: Vector3::from_array(sample.accel),
            linear_acceleration_covariance: [0.0; 9],
        })
    }
}

/// `sensor_msgs/msg/Temperature`: one temperature reading, °C.
///
/// Read alongside the IMU to regress the `temperature` effect (docs/design.md §4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Temperature {
    /// Sensor time and frame.
    pub header: Header,
    /// Temperature, °C.
    pub temperature: f64,
    /// Variance of `temperature`, 0 = unknown.
    pub variance: f64,
}

/// The `.msg` definition of [`Temperature`].
pub static TEMPERATURE: MsgDef = MsgDef {
    name: "sensor_msgs/msg/Temperature",
    text: "std_msgs/Header header\nfloat64 temperature\nfloat64 variance\n",
    deps: &[&HEADER],
    type_hash: "RIHS01_72514a14126ab9f8a9abec974c78e5610a367b59db5da355ff1fb982d5bad4b8",
};

impl Temperature {
    /// The reading as a sample, timed like [`Imu::to_sample`].
    pub fn to_sample(&self, log_time_ns: i64) -> TemperatureSample {
        TemperatureSample {
            stamp_ns: sample_time(self.header.stamp, log_time_ns),
            celsius: self.temperature,
        }
    }

    /// A message carrying `sample`, in `frame_id`, variance unknown (0).
    ///
    /// # Errors
    /// [`MsgError::StampOutOfRange`] when the stamp does not fit a ROS `Time`.
    pub fn from_sample(
        sample: &TemperatureSample,
        frame_id: &str,
    ) -> Result<Temperature, MsgError> {
        Ok(Temperature {
            header: header(sample.stamp_ns, frame_id)?,
            temperature: sample.celsius,
            variance: 0.0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::{decode, encode};

    fn imu_sample() -> ImuSample {
        ImuSample {
            stamp_ns: 1_700_000_000_123_456_789,
            gyro: [0.1, -0.2, 0.3],
            accel: [-9.81, 0.01, 1e-300],
        }
    }

    #[test]
    fn imu_cdr_has_the_documented_size_and_round_trips() {
        let msg = Imu::from_sample(&imu_sample(), "imu_link").unwrap();
        let bytes = encode(&msg).unwrap();
        // 4 + align8(13 + len("imu_link")) + 296 (rosbag2 notes).
        assert_eq!(bytes.len(), 4 + 24 + 296);
        assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
        let back: Imu = decode(&bytes).unwrap();
        assert_eq!(back, msg);
        assert_eq!(back.to_sample(5), imu_sample());
    }

    #[test]
    fn temperature_cdr_has_the_documented_size() {
        let s = TemperatureSample {
            stamp_ns: 42,
            celsius: 36.6,
        };
        let bytes = encode(&Temperature::from_sample(&s, "imu_link").unwrap()).unwrap();
        assert_eq!(bytes.len(), 44);
        let back: Temperature = decode(&bytes).unwrap();
        assert_eq!(back.to_sample(0), s);
    }

    #[test]
    fn zero_stamp_falls_back_to_log_time() {
        let mut s = imu_sample();
        s.stamp_ns = 0;
        let msg = Imu::from_sample(&s, "x").unwrap();
        assert_eq!(msg.to_sample(777).stamp_ns, 777);
    }

    #[test]
    fn schema_text_lists_every_dependency_once() {
        let text = IMU.schema_text();
        assert!(text.starts_with("std_msgs/Header header\n"));
        for dep in [
            "std_msgs/Header",
            "builtin_interfaces/Time",
            "geometry_msgs/Quaternion",
            "geometry_msgs/Vector3",
        ] {
            assert_eq!(
                text.matches(&format!("\nMSG: {dep}\n")).count(),
                1,
                "{dep} in\n{text}"
            );
        }
    }

    proptest::proptest! {
        /// Any finite or non-finite value, any stamp a ROS Time can hold, any frame name: the CDR
        /// round trip gives back the same bits.
        #[test]
        fn imu_round_trip_is_bit_exact(
            bits in proptest::array::uniform6(proptest::num::u64::ANY),
            stamp_ns in -(1i64 << 31) * 1_000_000_000..(1i64 << 31) * 1_000_000_000 - 1,
            frame_id in "[a-z_/]{0,40}",
        ) {
            let v = bits.map(f64::from_bits);
            let s = ImuSample { stamp_ns, gyro: [v[0], v[1], v[2]], accel: [v[3], v[4], v[5]] };
            let msg = Imu::from_sample(&s, &frame_id).unwrap();
            let bytes = encode(&msg).unwrap();
            let back: Imu = decode(&bytes).unwrap();
            proptest::prop_assert_eq!(&back.header.frame_id, &frame_id);
            // What a recording's reader decodes of the same bytes: the same sample, bit for bit.
            let reading: ImuReading = crate::msgs::decode_as(&bytes, IMU.name).unwrap();
            let (a, b) = (reading.to_sample(1), back.to_sample(1));
            proptest::prop_assert_eq!(a.stamp_ns, b.stamp_ns);
            proptest::prop_assert_eq!(a.values().map(f64::to_bits), b.values().map(f64::to_bits));
            let got = back.to_sample(1).values().map(f64::to_bits);
            proptest::prop_assert_eq!(got, bits);
            if stamp_ns != 0 {
                proptest::prop_assert_eq!(back.to_sample(1).stamp_ns, stamp_ns);
            }
        }
    }
}
