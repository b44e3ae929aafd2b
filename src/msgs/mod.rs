//! Serde mirrors of the ROS 2 messages fdavar reads and writes (CDR field order), no ROS client types.
//!
//! Each mirror is a plain struct whose fields follow the `.msg` definition in order, so that
//! `cdr-encoding` (XCDR1, little endian) gives the bytes a ROS 2 peer expects. Fixed-size arrays
//! (`float64[9]`) are Rust arrays, unbounded ones (`T[]`) are `Vec<T>`.
//!
//! Every mirror implements [`RosMessage`]: its ROS type name and its field list as written in the
//! `.msg` file. A test reads the `.msg` files of the interface package `msg/` and compares them field
//! by field with these lists, so a mirror cannot silently drift from its definition.

pub mod builtin_interfaces;
pub mod diagnostic_msgs;
pub mod fdavar_msgs;
pub mod rosgraph_msgs;
pub mod sensor_msgs;
pub mod std_msgs;

/// A serde mirror of a ROS 2 message type.
///
/// Why: ros2-client needs the exact DDS type name (`pkg::msg::dds_::Type_`), and the field list lets a
/// test check the mirror against the `.msg` text.
pub trait RosMessage {
    /// The ROS package, e.g. `sensor_msgs`.
    const PACKAGE: &'static str;
    /// The type name inside the package, e.g. `Imu`.
    const NAME: &'static str;
    /// The fields in `.msg` order: (ROS type as written in the `.msg` file, field name).
    const FIELDS: &'static [(&'static str, &'static str)];
}
