//! `diagnostic_msgs/msg/{DiagnosticArray, DiagnosticStatus, KeyValue}`: what `/diagnostics` carries.

use super::std_msgs::Header;
use super::RosMessage;
use serde::{Deserialize, Serialize};

/// `diagnostic_msgs/msg/DiagnosticArray`: one status per monitored component.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Publication time.
    pub header: Header,
    /// One status per component (fdavar: one per axis).
    pub status: Vec<DiagnosticStatus>,
}

impl RosMessage for DiagnosticArray {
    const PACKAGE: &'static str = "diagnostic_msgs";
    const NAME: &'static str = "DiagnosticArray";
    const FIELDS: &'static [(&'static str, &'static str)] = &[
        ("std_msgs/Header", "header"),
        ("DiagnosticStatus[]", "status"),
    ];
}

/// The `level` values of [`DiagnosticStatus`] (a `byte` in the `.msg`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum Level {
    /// `OK = 0`.
    Ok = 0,
    /// `WARN = 1`.
    Warn = 1,
    /// `ERROR = 2`.
    Error = 2,
    /// `STALE = 3`.
    Stale = 3,
}

/// `diagnostic_msgs/msg/DiagnosticStatus`: the state of one component.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// 0 OK, 1 WARN, 2 ERROR, 3 STALE (see [`Level`]).
    pub level: u8,
    /// Component name, e.g. `fdavar: gyro_x`.
    pub name: String,
    /// One-line human summary.
    pub message: String,
    /// Hardware identifier (the IMU frame id).
    pub hardware_id: String,
    /// Named values.
    pub values: Vec<KeyValue>,
}

impl RosMessage for DiagnosticStatus {
    const PACKAGE: &'static str = "diagnostic_msgs";
    const NAME: &'static str = "DiagnosticStatus";
    const FIELDS: &'static [(&'static str, &'static str)] = &[
        ("byte", "level"),
        ("string", "name"),
        ("string", "message"),
        ("string", "hardware_id"),
        ("KeyValue[]", "values"),
    ];
}

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct KeyValue {
    /// The key.
    pub key: String,
    /// The value, as text.
    pub value: String,
}

impl KeyValue {
    /// A key/value pair from anything displayable.
    pub fn new(key: &str, value: impl std::fmt::Display) -> KeyValue {
        KeyValue {
            key: key.to_string(),
            value: value.to_string(),
        }
    }
}

impl RosMessage for KeyValue {
    const PACKAGE: &'static str = "diagnostic_msgs";
    const NAME: &'static str = "KeyValue";
    const FIELDS: &'static [(&'static str, &'static str)] =
        &[("string", "key"), ("string", "value")];
}
