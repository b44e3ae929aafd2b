//! Imu messages become per-axis rate samples; stamps are checked and irregularities counted.
//!
//! Irregularities are facts to report, never to hide (docs/design.md §1): a gap, a duplicated stamp, time
//! going backwards is classified by [`StampCheck`] (a [`StampClass`]), which also counts rate changes, a NaN/Inf value counted by
//! [`StampCheck::count_non_finite`], and all of them in [`Irregularities`]; the analysis leaves out the Allan terms that would straddle it.
//!
//! No I/O and no ROS here: bag readers and the node convert their messages into [`ImuSample`].

mod intake;
mod period;
pub mod text;

pub use intake::{Intake, Placed};
pub use period::{nominal_period, PeriodEstimator};

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// One of the six IMU axes (**contract** names: `gyro_x` … `accel_z`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    /// `angular_velocity.x`, rad/s.
    GyroX,
    /// `angular_velocity.y`, rad/s.
    GyroY,
    /// `angular_velocity.z`, rad/s.
    GyroZ,
    /// `linear_acceleration.x`, m/s².
    AccelX,
    /// `linear_acceleration.y`, m/s².
    AccelY,
    /// `linear_acceleration.z`, m/s².
    AccelZ,
}

impl Axis {
    /// All six axes, gyro first, in the order of reports and messages.
    pub const ALL: [Axis; 6] = [
        Axis::GyroX,
        Axis::GyroY,
        Axis::GyroZ,
        Axis::AccelX,
        Axis::AccelY,
        Axis::AccelZ,
    ];

    /// The contract name, e.g. `gyro_x`.
    pub fn name(self) -> &'static str {
        match self {
            Axis::GyroX => "gyro_x",
            Axis::GyroY => "gyro_y",
            Axis::GyroZ => "gyro_z",
            Axis::AccelX => "accel_x",
            Axis::AccelY => "accel_y",
            Axis::AccelZ => "accel_z",
        }
    }

    /// Position in [`Axis::ALL`] and in [`ImuSample::values`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// True for the three gyro axes (rate in rad/s, phase in rad).
    pub fn is_gyro(self) -> bool {
        self.index() < 3
    }

    /// The SI unit of a rate sample on this axis.
    pub fn rate_unit(self) -> &'static str {
        if self.is_gyro() {
            "rad/s"
        } else {
            "m/s^2"
        }
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An axis name that is not one of the six.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown axis '{0}' (expected one of gyro_x, gyro_y, gyro_z, accel_x, accel_y, accel_z)")]
pub struct UnknownAxis(pub String);

impl FromStr for Axis {
    type Err = UnknownAxis;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Axis::ALL
            .into_iter()
            .find(|a| a.name() == s)
            .ok_or_else(|| UnknownAxis(s.to_string()))
    }
}

/// One IMU measurement: the six rates at one sensor time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ImuSample {
    /// Sensor time (`header.stamp`, or the receive time when the stamp is zero), nanoseconds.
    pub stamp_ns: i64,
    /// `angular_velocity` x, y, z in rad/s.
    pub gyro: [f64; 3],
    /// `linear_acceleration` x, y, z in m/s².
    pub accel: [f64; 3],
}

impl ImuSample {
    /// The six rates in [`Axis::ALL`] order.
    pub fn values(&self) -> [f64; 6] {
        let [gx, gy, gz] = self.gyro;
        let [ax, ay, az] = self.accel;
        [gx, gy, gz, ax, ay, az]
    }

    /// The rate on one axis.
    pub fn value(&self, axis: Axis) -> f64 {
        self.values()[axis.index()]
    }
}

/// One temperature reading (`sensor_msgs/Temperature`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TemperatureSample {
    /// Sensor time, nanoseconds.
    pub stamp_ns: i64,
    /// Temperature in degrees Celsius (as the message carries it; differences are kelvin).
    pub celsius: f64,
}

/// Consecutive stamps earlier than the last accepted one, each later than the one before it,
/// after which the sensor clock is taken to have gone back for good (a restarted publisher, a
/// reset sensor): the stamp that makes the count becomes the new anchor instead of being dropped.
/// A run must tick forward: repeated stale stamps (e.g. zero stamps in a stamped stream) never
/// re-anchor.
///
/// Why 50: a single late or replayed message is one backwards stamp, and a burst of reordered
/// messages is a few; fifty in a row without one good stamp between them is a clock that went
/// back (0.5 s at 100 Hz, 0.125 s at 400 Hz). Without re-anchoring every later sample was dropped
/// for the rest of the run (issue 13). The 49 samples dropped while deciding become a gap.
pub const REANCHOR_AFTER: u32 = 50;

/// The longest gap laid out as missing samples, in periods (2²⁰: 2.9 h at 100 Hz, 8.7 min at
/// 2 kHz). A stamp further ahead is a clock that jumped forward (a driver restarted with another
/// time base, a wrong epoch): it becomes the new reference like a clock that went back
/// ([`StampClass::Reanchored`], counted in `reanchors`), and the samples after it follow on.
///
/// Why this bound: it is the whole-run record's cap per axis
/// ([`crate::model::record::RecordBuilder::DEFAULT_MAX_SAMPLES`]); a longer gap cannot be laid
/// out in it, and before, such a jump stopped the whole-run record for the rest of the run
/// ("a gap … is longer than the recording allows", issue 13).
pub const MAX_GAP_SAMPLES: u64 = 1 << 20;

/// The largest magnitude a rate sample can have, rad/s or m/s²; beyond it a value is not a
/// measurement and is treated as missing, like NaN or ±∞.
///
/// Why 10⁶: the fastest gyro ranges are a few thousand °/s (≈ 70 rad/s) and high-g accelerometers
/// reach 10⁵ m/s² (≈ 10 000 g); 10⁶ is over ten times either, so no real sample is lost, while a
/// value like ±1e300 (a corrupted message) can no longer overflow σ²_ref (its square is ∞, which
/// turned F into NaN for the rest of the run, issue 13).
pub const MAX_ABS_RATE: f64 = 1e6;

/// True for a value the analysis can use: finite and at most [`MAX_ABS_RATE`] in magnitude.
pub fn is_usable(v: f64) -> bool {
    v.abs() <= MAX_ABS_RATE
}

/// Intervals averaged to tell a rate change ([`Irregularities::rate_changes`]): 1 s at 100 Hz.
pub const RATE_WINDOW: u32 = 100;

/// How far the rate over [`RATE_WINDOW`] intervals may move from 1/τ0 before it counts as a rate
/// change: 20 %, as the node's `rate_changes`. τ0 is settled once, so after a 100 → 400 Hz change
/// every τ is 4× too long (issue 13: `fdavar davar` said nothing of it).
pub const RATE_CHANGE: f64 = 0.2;

/// What a new stamp is, relative to the previous good one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StampClass {
    /// The next sample, about one period after the previous one.
    Next,
    /// More than 1.5 τ0 after the previous stamp on the grid ([`StampCheck::check`]): samples are missing in between.
    Gap {
        /// Whole periods missing (rounded), at least 1.
        missing: u64,
    },
    /// The same stamp as the previous sample.
    Duplicate,
    /// Earlier than the previous sample.
    Backwards,
    /// The [`REANCHOR_AFTER`]th backwards stamp in a row (the clock went back), or a stamp more
    /// than [`MAX_GAP_SAMPLES`] periods ahead (it jumped forward): this stamp is the new
    /// reference (the samples dropped before it count as missing).
    Reanchored {
        /// Backwards samples dropped before this one in the run that ended here.
        dropped: u64,
    },
}

/// Counts of the irregularities met so far on one stream (published as-is).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Irregularities {
    /// Stamps more than 1.5 τ0 after the previous one on the grid.
    pub gaps: u64,
    /// Samples with the same stamp as the previous one (dropped).
    pub duplicates: u64,
    /// Samples stamped earlier than the previous one (dropped).
    pub backwards: u64,
    /// Values that were NaN, infinite or beyond [`MAX_ABS_RATE`] (that axis's sample dropped).
    pub non_finite: u64,
    /// Times the clock went back for good ([`REANCHOR_AFTER`]) or jumped forward past
    /// [`MAX_GAP_SAMPLES`], and the stamps were re-anchored.
    #[serde(default)]
    pub reanchors: u64,
    /// Times the rate over [`RATE_WINDOW`] intervals (gaps aside) moved more than [`RATE_CHANGE`]
    /// from 1/τ0, counted once per change: the τ of the rows after it are off by that factor.
    #[serde(default)]
    pub rate_changes: u64,
}

impl Irregularities {
    /// How many irregularities of any kind were counted.
    pub fn total(&self) -> u64 {
        self.gaps
            + self.duplicates
            + self.backwards
            + self.non_finite
            + self.reanchors
            + self.rate_changes
    }

    /// The counts as the CLI's warning line says them.
    pub fn describe(&self) -> String {
        let mut text = format!(
            "{} gaps, {} duplicate and {} backwards stamps, {} non-finite values (left out and counted)",
            self.gaps, self.duplicates, self.backwards, self.non_finite
        );
        if self.reanchors > 0 {
            text += &format!(
                "; the clock jumped {} times (back: {REANCHOR_AFTER} backwards stamps in a row; \
                 or forward: more than {MAX_GAP_SAMPLES} periods): re-anchored on the new stamps",
                self.reanchors
            );
        }
        if self.rate_changes > 0 {
            text += &format!(
                "; the rate changed {} times by more than {} % from 1/tau0 (tau0 is the first \
                 rate's: tau is off by that factor after each change)",
                self.rate_changes,
                100.0 * RATE_CHANGE
            );
        }
        text
    }
}

/// The run of backwards stamps after one more at `stamp_ns` ([`REANCHOR_AFTER`]): it grows when the
/// stamp is later than the run's last one, and starts again at 1 otherwise.
pub fn backwards_run(run: (u32, Option<i64>), stamp_ns: i64) -> (u32, Option<i64>) {
    match run {
        (n, Some(last)) if stamp_ns > last => (n + 1, Some(stamp_ns)),
        _ => (1, Some(stamp_ns)),
    }
}

/// Classifies each stamp against the previous accepted one.
///
/// Why a separate type: the bag reader, the offline pipeline and the node all need the same rule
/// (docs/design.md §1: a gap is a stamp > 1.5 τ0 after the previous one on the grid), and the same input must give the same counts live
/// and offline.
#[derive(Debug, Clone)]
pub struct StampCheck {
    period_ns: f64,
    /// The last accepted stamp and the grid's reference (see [`StampCheck::check`]).
    last: Option<Accepted>,
    /// Backwards stamps in a row since the last accepted one, each later than the one before, and
    /// the last of them.
    backwards_run: (u32, Option<i64>),
    /// Intervals of the current rate window and their sum, ns.
    rate_window: (u32, f64),
    /// Whether the last full rate window was off the nominal rate.
    off_rate: bool,
    counts: Irregularities,
}

/// The last stamp [`StampCheck`] accepted, and the grid's reference: the last stamp that fell on
/// its own slot, with the samples placed after it.
#[derive(Debug, Clone, Copy)]
struct Accepted {
    stamp_ns: i64,
    reference_ns: i64,
    since: u64,
}

impl Accepted {
    /// A stamp on its own slot: the grid's new reference.
    fn on_time(stamp_ns: i64) -> Accepted {
        Accepted { stamp_ns, reference_ns: stamp_ns, since: 0 }
    }
}

/// Most samples in a row that may come early (a packet of messages stamped on receipt) before the
/// grid's reference moves to the latest of them ([`StampCheck::check`]).
pub const MAX_EARLY_RUN: u64 = 32;

impl StampCheck {
    /// A check for a stream with nominal period `period_s` seconds.
    pub fn new(period_s: f64) -> Self {
        StampCheck {
            period_ns: period_s * 1e9,
            last: None,
            backwards_run: (0, None),
            rate_window: (0, 0.0),
            off_rate: false,
            counts: Irregularities::default(),
        }
    }

    /// Adds one interval (not a gap) to the rate window; a full window off the nominal rate by
    /// more than [`RATE_CHANGE`] counts a rate change, unless the one before was off too.
    fn note_interval(&mut self, dt_ns: f64) {
        self.rate_window = (self.rate_window.0 + 1, self.rate_window.1 + dt_ns);
        if self.rate_window.0 == RATE_WINDOW {
            let mean_ns = self.rate_window.1 / f64::from(RATE_WINDOW);
            let off = (self.period_ns / mean_ns - 1.0).abs() > RATE_CHANGE;
            if off && !self.off_rate {
                self.counts.rate_changes += 1;
            }
            self.off_rate = off;
            self.rate_window = (0, 0.0);
        }
    }

    /// Classifies `stamp_ns`, counts it, and remembers it unless it was a duplicate or went
    /// backwards; the [`REANCHOR_AFTER`]th backwards stamp in a row, or a stamp more than
    /// [`MAX_GAP_SAMPLES`] periods ahead, is remembered as the new reference
    /// ([`StampClass::Reanchored`]).
    ///
    /// A gap is measured from the last stamp that fell on its own slot, not from the previous
    /// stamp: a sample k slots after that one is missing nothing before it unless its stamp is
    /// more than k + ½ periods later. Why: a driver that stamps messages when it reads them gets
    /// them in packets (a serial or USB IMU: 4 messages 20 µs apart, then nothing for 4 periods).
    /// Measured from the previous stamp, every packet opened with a gap of 3 and the record grew
    /// by 3 invalid samples per 4; now the packet's messages take the next slots and the packet
    /// after it is on time. A sample more than half a period early keeps the reference (for at
    /// most [`MAX_EARLY_RUN`] samples, so that a clock faster than τ0 cannot hide a gap for long).
    /// With every stamp on its own slot (regular stamps, jitter below half a period) the
    /// reference is the previous stamp, and the classes are those of the previous stamp's rule.
    pub fn check(&mut self, stamp_ns: i64) -> StampClass {
        let Some(Accepted { stamp_ns: last, reference_ns: reference, since }) = self.last else {
            self.last = Some(Accepted::on_time(stamp_ns));
            return StampClass::Next;
        };
        let class = match stamp_ns.cmp(&last) {
            std::cmp::Ordering::Equal => StampClass::Duplicate,
            std::cmp::Ordering::Less => {
                self.backwards_run = backwards_run(self.backwards_run, stamp_ns);
                if self.backwards_run.0 >= REANCHOR_AFTER {
                    StampClass::Reanchored {
                        dropped: u64::from(REANCHOR_AFTER - 1),
                    }
                } else {
                    StampClass::Backwards
                }
            }
            std::cmp::Ordering::Greater => {
                let expected = since + 1;
                let dt = (stamp_ns - reference) as f64;
                if dt > (expected as f64 + 0.5) * self.period_ns {
                    let missing = ((dt / self.period_ns).round() as u64)
                        .saturating_sub(expected)
                        .max(1);
                    if missing > MAX_GAP_SAMPLES {
                        StampClass::Reanchored { dropped: 0 }
                    } else {
                        StampClass::Gap { missing }
                    }
                } else {
                    self.note_interval((stamp_ns - last) as f64);
                    StampClass::Next
                }
            }
        };
        match class {
            StampClass::Duplicate => self.counts.duplicates += 1,
            StampClass::Backwards => self.counts.backwards += 1,
            StampClass::Gap { .. } => self.counts.gaps += 1,
            StampClass::Reanchored { .. } => self.counts.reanchors += 1,
            StampClass::Next => {}
        }
        // A stamp that moves the stream on ends a backwards run; it is the grid's reference unless
        // it came early (a message of a packet) after one that was on time.
        if !matches!(class, StampClass::Duplicate | StampClass::Backwards) {
            self.backwards_run = (0, None);
            let early = matches!(class, StampClass::Next)
                && since < MAX_EARLY_RUN
                && ((stamp_ns - reference) as f64) < (since as f64 + 0.5) * self.period_ns;
            self.last = Some(if early {
                Accepted { stamp_ns, reference_ns: reference, since: since + 1 }
            } else {
                Accepted::on_time(stamp_ns)
            });
        }
        class
    }

    /// Counts a non-finite value seen on some axis.
    pub fn count_non_finite(&mut self) {
        self.counts.non_finite += 1;
    }

    /// The counts so far.
    pub fn counts(&self) -> Irregularities {
        self.counts
    }

    /// The nominal period this check uses, seconds.
    pub fn period_s(&self) -> f64 {
        self.period_ns * 1e-9
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_names_round_trip() {
        for a in Axis::ALL {
            assert_eq!(a.name().parse::<Axis>().unwrap(), a);
            assert_eq!(Axis::ALL[a.index()], a);
        }
        assert!("gyro_w".parse::<Axis>().is_err());
    }

    #[test]
    fn stamps_are_classified_and_counted() {
        let mut c = StampCheck::new(0.01);
        assert_eq!(c.check(0), StampClass::Next);
        assert_eq!(c.check(10_000_000), StampClass::Next);
        assert_eq!(c.check(10_000_000), StampClass::Duplicate);
        assert_eq!(c.check(5_000_000), StampClass::Backwards);
        assert_eq!(c.check(50_000_000), StampClass::Gap { missing: 3 });
        assert_eq!(c.check(60_000_000), StampClass::Next);
        let n = c.counts();
        assert_eq!((n.gaps, n.duplicates, n.backwards), (1, 1, 1));
    }

    /// Messages read in packets of 4 and stamped on receipt (20 µs apart, then 4 periods later
    /// the next packet) are consecutive samples: no gap. A real gap after a packet is still
    /// counted, with the right number of missing samples, and so is a gap after regular stamps.
    #[test]
    fn packets_stamped_on_receipt_leave_no_gap() {
        let p = 10_000_000;
        let mut c = StampCheck::new(0.01);
        let mut classes = Vec::new();
        for i in 0..40i64 {
            classes.push(c.check((i / 4) * 4 * p + 3 * p + (i % 4) * 20_000));
        }
        assert!(classes.iter().all(|k| *k == StampClass::Next), "{classes:?}");
        // The next packet comes 2 packets late: 8 samples missing before it.
        assert_eq!(c.check(10 * 4 * p + 8 * p + 3 * p), StampClass::Gap { missing: 8 });
        for k in 1..4 {
            assert_eq!(c.check(10 * 4 * p + 8 * p + 3 * p + k * 20_000), StampClass::Next);
        }
        assert_eq!(c.check(11 * 4 * p + 8 * p + 3 * p), StampClass::Next);
        assert_eq!(c.counts().gaps, 1);
        // Jitter of 0.4 τ0 back and forth: no gap (the previous-stamp rule saw 1.8 τ0 as one).
        let mut c = StampCheck::new(0.01);
        for (i, j) in [0i64, 4, -4, 4, -4, 0].iter().enumerate() {
            assert_eq!(c.check(i as i64 * p + j * p / 10), StampClass::Next, "sample {i}");
        }
    }

    /// Issue 13: a 100 → 400 Hz change kept τ0 = 10 ms without a word. One change is counted
    /// when a window of 100 intervals runs 4× fast, once however long it lasts, and again after
    /// the rate came back and changed anew; jitter of ±10 % is no change.
    #[test]
    fn a_rate_change_is_counted_once_per_change() {
        let mut c = StampCheck::new(0.01);
        let mut t = 0;
        let mut run = |c: &mut StampCheck, n: usize, dt: i64| {
            for k in 0..n {
                t += dt + if k % 2 == 0 { dt / 10 } else { -dt / 10 };
                c.check(t);
            }
        };
        run(&mut c, 1000, 10_000_000);
        assert_eq!(c.counts().rate_changes, 0, "jitter");
        run(&mut c, 1000, 2_500_000);
        assert_eq!(c.counts().rate_changes, 1);
        run(&mut c, 300, 10_000_000);
        run(&mut c, 300, 7_000_000);
        let n = c.counts();
        assert_eq!((n.rate_changes, n.gaps, n.total()), (2, 0, 2));
        assert!(
            n.describe().ends_with(
                "; the rate changed 2 times by more than 20 % from 1/tau0 (tau0 is the first \
                 rate's: tau is off by that factor after each change)"
            ),
            "{}",
            n.describe()
        );
    }
}
