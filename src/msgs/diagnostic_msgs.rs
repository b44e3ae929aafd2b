//! `diagnostic_msgs/msg/{DiagnosticArray, DiagnosticStatus, KeyValue}`: what `/diagnostics` carries.

use super::std_msgs::{Header, HEADER};
use super::{MsgDef, RosMessage};
use serde::{Deserialize, Serialize};

/// `diagnostic_msgs/msg/DiagnosticArray`: one status per monitored component.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Publication time.
    pub header: Header,
    /// One status per component (fdavar: one per axis).
    pub status: Vec<DiagnosticStatus>,
}

/// The `.msg` definition of [`DiagnosticArray`].
pub static DIAGNOSTIC_ARRAY: MsgDef = MsgDef {
    name: "diagnostic_msgs/msg/DiagnosticArray",
    text: "std_msgs/Header header
DiagnosticStatus[] status
",
    deps: &[&HEADER, &DIAGNOSTIC_STATUS],
    type_hash: "",
};

impl RosMessage for DiagnosticArray {
    const DEF: &'static MsgDef = &DIAGNOSTIC_ARRAY;
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

/// The `.msg` definition of [`DiagnosticStatus`] (its level constants left out).
pub static DIAGNOSTIC_STATUS: MsgDef = MsgDef {
    name: "diagnostic_msgs/msg/DiagnosticStatus",
    text: "byte level
string name
string message
string hardware_id
KeyValue[] values
",
    deps: &[&KEY_VALUE],
    type_hash: "",
};

impl RosMessage for DiagnosticStatus {
    const DEF: &'static MsgDef = &DIAGNOSTIC_STATUS;
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

/// The `.msg` definition of [`KeyValue`].
pub static KEY_VALUE: MsgDef = MsgDef {
    name: "diagnostic_msgs/msg/KeyValue",
    text: "string key
string value
",
    deps: &[],
    type_hash: "",
};

impl RosMessage for KeyValue {
    const DEF: &'static MsgDef = &KEY_VALUE;
}
