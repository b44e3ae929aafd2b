//! Serde mirrors of the ROS 2 messages fdavar reads and writes (CDR field order), no ROS client types.
//!
//! One file per ROS package (`sensor_msgs.rs`, …), one struct per message with its fields in the
//! order of the `.msg` file, because CDR is positional: serde's derive then *is* the wire format
//! (`float64[9]` → `[f64; 9]`, no length prefix; `string` → `String`, length with its NUL).
//! Each message also carries its `.msg` text ([`MsgDef`]) because MCAP files store it as the schema
//! readers decode with.
//!
//! [`encode`] / [`decode`] add and check the 4-byte encapsulation header (`00 01 00 00`, CDR little
//! endian) that rosbag2 stores before every message. CDR alignment counts from the byte after that
//! header, so the header is split off before the body goes to `cdr_encoding`.
//!
//! Rejected alternative: decoding from the schema text at run time (as `mcap-ros2-support` does).
//! fdavar only needs a handful of fixed types, and a typed mirror fails loudly on a wrong type.

pub mod builtin_interfaces;
pub mod diagnostic_msgs;
pub mod fdavar_msgs;
pub mod geometry_msgs;
pub mod rosgraph_msgs;
pub mod sensor_msgs;
pub mod std_msgs;

use byteorder::{BigEndian, LittleEndian};
use serde::de::DeserializeOwned;
use serde::Serialize;

/// Encapsulation header of little-endian plain CDR, as rosbag2 writes it.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// The line that separates dependencies in a `ros2msg` schema (exactly 80 `=`).
const SCHEMA_SEPARATOR: &str =
    "================================================================================";

/// Why a message could not be encoded or decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum MsgError {
    /// Fewer bytes than the 4-byte encapsulation header.
    #[error("{type_name}: {len} bytes is too short for a CDR message (needs a 4-byte header)")]
    TooShort {
        /// ROS type being decoded.
        type_name: &'static str,
        /// Bytes available.
        len: usize,
    },
    /// An encapsulation other than plain CDR (e.g. XCDR2 or PL_CDR).
    #[error("{type_name}: unsupported CDR encapsulation {got:02x?} (expected 00 00 or 00 01)")]
    Encapsulation {
        /// ROS type being decoded.
        type_name: &'static str,
        /// The first two header bytes.
        got: [u8; 2],
    },
    /// The body does not decode as this type (truncated, bad string, …).
    #[error("{type_name}: malformed CDR: {reason}")]
    Cdr {
        /// ROS type being decoded or encoded.
        type_name: &'static str,
        /// What `cdr_encoding` reported.
        reason: String,
    },
    /// A stamp whose seconds do not fit the `int32` of `builtin_interfaces/Time`.
    #[error("stamp {stamp_ns} ns does not fit builtin_interfaces/Time (int32 seconds)")]
    StampOutOfRange {
        /// The stamp, nanoseconds since the epoch.
        stamp_ns: i64,
    },
}

/// The `.msg` definition of one ROS message type and the types it uses.
///
/// MCAP's `ros2msg` schema encoding stores this text; rosbag2 readers (and `rosbags`,
/// `mcap-ros2-support`) decode messages from it.
#[derive(Debug)]
pub struct MsgDef {
    /// Full type name, e.g. `sensor_msgs/msg/Imu`.
    pub name: &'static str,
    /// The `.msg` text of this type alone (fields in order, one per line).
    pub text: &'static str,
    /// The message types the fields use directly.
    pub deps: &'static [&'static MsgDef],
    /// The ROS 2 type hash (`RIHS01_…`, REP 2011) that Jazzy records as `type_description_hash`,
    /// or `""` where unknown (rosbag2's own convention for "no hash").
    pub type_hash: &'static str,
}

impl MsgDef {
    /// The `ros2msg` schema: this type's text, then each (transitive) dependency once, after a
    /// line of 80 `=` and `MSG: pkg/Type`, in depth-first order as rosbag2 writes it.
    pub fn schema_text(&self) -> String {
        let mut out = self.text.to_string();
        let mut seen = vec![self.name];
        self.append_deps(&mut out, &mut seen);
        out
    }

    fn append_deps(&self, out: &mut String, seen: &mut Vec<&'static str>) {
        for dep in self.deps {
            if seen.contains(&dep.name) {
                continue;
            }
            seen.push(dep.name);
            out.push_str(SCHEMA_SEPARATOR);
            out.push_str("\nMSG: ");
            out.push_str(&dep.name.replacen("/msg/", "/", 1));
            out.push('\n');
            out.push_str(dep.text);
            dep.append_deps(out, seen);
        }
    }
}

/// A ROS message mirror: its serde form is its CDR form, and it knows its definition.
pub trait RosMessage: Serialize + DeserializeOwned {
    /// The definition (name, `.msg` text, dependencies).
    const DEF: &'static MsgDef;
}

impl RosMessage for sensor_msgs::Imu {
    const DEF: &'static MsgDef = &sensor_msgs::IMU;
}

impl RosMessage for sensor_msgs::Temperature {
    const DEF: &'static MsgDef = &sensor_msgs::TEMPERATURE;
}

impl MsgDef {
    /// The ROS package, e.g. `sensor_msgs` for `sensor_msgs/msg/Imu`.
    pub fn package(&self) -> &'static str {
        self.name.split('/').next().unwrap_or(self.name)
    }

    /// The type name inside its package, e.g. `Imu` for `sensor_msgs/msg/Imu`.
    pub fn type_name(&self) -> &'static str {
        self.name.rsplit('/').next().unwrap_or(self.name)
    }
}

/// Serialises `msg` as rosbag2 stores it: the little-endian CDR header, then the CDR body.
///
/// # Errors
/// [`MsgError::Cdr`] if the serializer refuses a value (it does not for fdavar's types).
pub fn encode<M: RosMessage>(msg: &M) -> Result<Vec<u8>, MsgError> {
    let body = cdr_encoding::to_vec::<M, LittleEndian>(msg).map_err(|e| MsgError::Cdr {
        type_name: M::DEF.name,
        reason: e.to_string(),
    })?;
    let mut out = Vec::with_capacity(4 + body.len());
    out.extend_from_slice(&CDR_LE_HEADER);
    out.extend_from_slice(&body);
    Ok(out)
}

/// Decodes one stored message: checks the encapsulation header, then decodes the body in the byte
/// order the header names. Trailing padding after the last field is allowed.
///
/// # Errors
/// [`MsgError::TooShort`], [`MsgError::Encapsulation`], or [`MsgError::Cdr`] for a body that is
/// truncated or malformed. Never panics on bad bytes.
pub fn decode<M: RosMessage>(bytes: &[u8]) -> Result<M, MsgError> {
    decode_as(bytes, M::DEF.name)
}

/// [`decode`] into `M`, a type laid out as the message `type_name` (or as the start of it), e.g.
/// [`sensor_msgs::ImuReading`].
///
/// # Errors
/// As [`decode`].
pub(crate) fn decode_as<M: DeserializeOwned>(bytes: &[u8], type_name: &'static str) -> Result<M, MsgError> {
    if bytes.len() < 4 {
        return Err(MsgError::TooShort {
            type_name,
            len: bytes.len(),
        });
    }
    let body = &bytes[4..];
    let decoded = match [bytes[0], bytes[1]] {
        [0x00, 0x01] => cdr_encoding::from_bytes::<M, LittleEndian>(body),
        [0x00, 0x00] => cdr_encoding::from_bytes::<M, BigEndian>(body),
        got => return Err(MsgError::Encapsulation { type_name, got }),
    };
    decoded
        .map(|(msg, _consumed)| msg)
        .map_err(|e| MsgError::Cdr {
            type_name,
            reason: e.to_string(),
        })
}

#[cfg(test)]
mod tests {
    use super::sensor_msgs::Imu;
    use super::*;
    use crate::signal::ImuSample;
    use rand::{Rng, SeedableRng};

    fn encoded_imu() -> Vec<u8> {
        let s = ImuSample {
            stamp_ns: 1_000_000_123,
            gyro: [1.0, 2.0, 3.0],
            accel: [4.0, 5.0, 6.0],
        };
        encode(&Imu::from_sample(&s, "imu_link").unwrap()).unwrap()
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        let bytes = encoded_imu();
        for len in 0..bytes.len() {
            assert!(decode::<Imu>(&bytes[..len]).is_err(), "len {len} decoded");
        }
    }

    #[test]
    fn random_bytes_never_panic() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let good = encoded_imu();
        for _ in 0..2000 {
            let mut b = good.clone();
            for _ in 0..rng.random_range(1..8) {
                let i = rng.random_range(0..b.len());
                b[i] = rng.random();
            }
            let _ = decode::<Imu>(&b);
        }
    }

    #[test]
    fn big_endian_bodies_decode() {
        let msg: Imu = decode(&encoded_imu()).unwrap();
        let mut be = vec![0, 0, 0, 0];
        be.extend(cdr_encoding::to_vec::<Imu, BigEndian>(&msg).unwrap());
        assert_eq!(decode::<Imu>(&be).unwrap(), msg);
    }

    #[test]
    fn other_encapsulations_are_named() {
        let mut b = encoded_imu();
        b[1] = 0x07;
        assert_eq!(
            decode::<Imu>(&b),
            Err(MsgError::Encapsulation {
                type_name: "sensor_msgs/msg/Imu",
                got: [0, 7]
            })
        );
    }
}
