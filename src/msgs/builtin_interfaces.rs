//! `builtin_interfaces/msg/Time`.

use super::RosMessage;
use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since an epoch.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, 0 ≤ nanosec < 10⁹.
    pub nanosec: u32,
}

impl Time {
    /// The time `ns` nanoseconds after the epoch (negative values and overflow saturate).
    pub fn from_nanos(ns: i64) -> Time {
        let ns = ns.max(0);
        let sec = (ns / 1_000_000_000).min(i64::from(i32::MAX)) as i32;
        Time {
            sec,
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    /// Nanoseconds since the epoch.
    pub fn to_nanos(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

impl RosMessage for Time {
    const PACKAGE: &'static str = "builtin_interfaces";
    const NAME: &'static str = "Time";
    const FIELDS: &'static [(&'static str, &'static str)] =
        &[("int32", "sec"), ("uint32", "nanosec")];
}
