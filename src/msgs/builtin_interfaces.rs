//! `builtin_interfaces`: the ROS 2 time stamp.

use super::{MsgDef, MsgError};
use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since the epoch of the stamping clock.
///
/// Every header carries one; fdavar reads sample times from it (the sensor clock).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds (`int32 sec`).
    pub sec: i32,
    /// Nanoseconds within the second, 0 ≤ nanosec < 10⁹ (`uint32 nanosec`).
    pub nanosec: u32,
}

/// The `.msg` definition of [`Time`].
pub static TIME: MsgDef = MsgDef {
    name: "builtin_interfaces/msg/Time",
    text: "int32 sec\nuint32 nanosec\n",
    deps: &[],
    type_hash: "",
};

impl Time {
    /// The stamp for `ns` nanoseconds since the epoch.
    ///
    /// # Errors
    /// [`MsgError::StampOutOfRange`] when the seconds do not fit `int32` (after 2038-01-19).
    pub fn from_ns(ns: i64) -> Result<Time, MsgError> {
        let sec = i32::try_from(ns.div_euclid(1_000_000_000))
            .map_err(|_| MsgError::StampOutOfRange { stamp_ns: ns })?;
        // rem_euclid of a positive modulus is in 0..1e9, which fits u32.
        let nanosec = ns.rem_euclid(1_000_000_000) as u32;
        Ok(Time { sec, nanosec })
    }

    /// Nanoseconds since the epoch (exact: every `Time` fits an `i64`).
    pub fn to_ns(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }

    /// True for the all-zero stamp that drivers leave when they have no clock.
    pub fn is_zero(self) -> bool {
        self.sec == 0 && self.nanosec == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nanoseconds_round_trip_including_negative() {
        for ns in [
            0,
            1,
            999_999_999,
            1_000_000_000,
            1_700_000_000_123_456_789,
            -1,
            -1_500_000_000,
        ] {
            let t = Time::from_ns(ns).unwrap();
            assert!(t.nanosec < 1_000_000_000);
            assert_eq!(t.to_ns(), ns);
        }
        assert_eq!(
            Time::from_ns(-1).unwrap(),
            Time {
                sec: -1,
                nanosec: 999_999_999
            }
        );
    }

    #[test]
    fn seconds_beyond_int32_are_refused() {
        let ns = (i64::from(i32::MAX) + 1) * 1_000_000_000;
        assert_eq!(
            Time::from_ns(ns),
            Err(MsgError::StampOutOfRange { stamp_ns: ns })
        );
    }
}
