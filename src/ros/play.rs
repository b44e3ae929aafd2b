//! `fdavar play`: publishes a recording's IMU (and temperature) messages over DDS at the recorded
//! pace, optionally with `/clock`.
//!
//! Why not `ros2 bag play`: it needs a ROS installation; this needs none, and it is how the
//! integration tests replay a recording into `fdavar_node` on a domain of their own. Messages keep
//! their recorded header stamps (the sensor clock the analysis uses); the pacing follows the
//! recorder's log times scaled by `rate`, as `ros2 bag play` does; `/clock` carries the log time.
//!
//! `/clock` is offered reliable (keep last 1): a reliable writer matches every reader, the
//! best-effort one rclpy's and rclcpp's time sources create (depth 1) as well as the reliable
//! default of a plain subscriber, where a best-effort writer would leave the latter unmatched.

use super::node::{peer_node, publish_on, spin_in_background, NodeError};
use crate::bag::{BagMessage, BagReader};
use crate::msgs::rosgraph_msgs::Clock;
use crate::msgs::sensor_msgs::{Imu, Temperature};
use ros2_client::qos::{History, WhenFull};
use ros2_client::QosProfile;
use std::time::{Duration, Instant};

/// The slowest replay speed factor accepted: 10⁻⁶ (a 1 s recording then takes 11.6 days).
///
/// Why a bound: the pacing divides recorded durations by the rate, and below about 10⁻¹⁰ a
/// recording of a few hours no longer fits a [`Duration`]; 10⁻⁶ keeps a recording spanning the
/// whole `i64` nanosecond range (292 years) within it.
pub const MIN_RATE: f64 = 1e-6;
/// The fastest replay speed factor accepted: 10⁶ (beyond, replay runs as fast as DDS takes it anyway).
pub const MAX_RATE: f64 = 1e6;
/// The longest wait for a subscriber accepted, seconds (one hour).
pub const MAX_WAIT_S: f64 = 3600.0;

/// Checks a replay speed factor: finite, in [[`MIN_RATE`], [`MAX_RATE`]].
///
/// # Errors
/// [`PlayError::Rate`] with the value.
pub fn check_rate(rate: f64) -> Result<f64, PlayError> {
    if (MIN_RATE..=MAX_RATE).contains(&rate) {
        Ok(rate)
    } else {
        Err(PlayError::Rate(rate))
    }
}

/// Checks a wait for a subscriber, seconds: finite, in [0, [`MAX_WAIT_S`]].
///
/// # Errors
/// [`PlayError::Wait`] with the value.
pub fn check_wait_s(seconds: f64) -> Result<Duration, PlayError> {
    if (0.0..=MAX_WAIT_S).contains(&seconds) {
        Ok(Duration::from_secs_f64(seconds))
    } else {
        Err(PlayError::Wait(seconds))
    }
}

/// How to replay.
#[derive(Debug, Clone, PartialEq)]
pub struct PlayOptions {
    /// Speed factor: 2.0 plays twice as fast as recorded; in [[`MIN_RATE`], [`MAX_RATE`]].
    pub rate: f64,
    /// Also publish `/clock` (rosgraph_msgs/msg/Clock) with the log time, at most every 10 ms.
    pub clock: bool,
    /// The IMU topic of the bag (None: its only sensor_msgs/msg/Imu topic).
    pub bag_topic: Option<String>,
    /// The topic to publish on (None: the bag's topic name).
    pub out_topic: Option<String>,
    /// DDS domain.
    pub domain_id: u16,
    /// Publish reliable (default best effort, like IMU drivers).
    pub reliable: bool,
    /// How long to wait for a subscriber (of `/clock` too with `clock`) before sending; at most
    /// [`MAX_WAIT_S`].
    pub wait: Duration,
    /// Frame id of the published messages (bags' samples keep no frame).
    pub frame_id: String,
}

/// What a replay did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PlayReport {
    /// IMU messages published.
    pub imu: u64,
    /// Temperature messages published.
    pub temperature: u64,
    /// Messages of the bag that did not decode (skipped).
    pub malformed: u64,
    /// True when a subscriber matched before the first message.
    pub matched: bool,
    /// `/clock` messages published.
    pub clock: u64,
    /// True when a `/clock` subscriber matched before the first message (with `clock`).
    pub clock_matched: bool,
}

/// Why a replay failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlayError {
    /// The bag could not be opened or read.
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
    /// DDS refused to start.
    #[error(transparent)]
    Ros(#[from] NodeError),
    /// `rate` is outside [[`MIN_RATE`], [`MAX_RATE`]] or not a number.
    #[error("--rate must be a number in [{MIN_RATE:e}, {MAX_RATE:e}], got {0:?}")]
    Rate(f64),
    /// The wait for a subscriber is outside [0, [`MAX_WAIT_S`]] or not a number.
    #[error("--wait-s must be a number of seconds in [0, {MAX_WAIT_S}], got {0:?}")]
    Wait(f64),
}

/// Replays `bag` as [`PlayOptions`] say; returns when the last message is sent.
///
/// # Errors
/// [`PlayError`] for an unreadable bag, a bad rate or wait, or DDS failing to start. Malformed
/// messages are skipped and counted in the report.
pub fn play(bag: &std::path::Path, options: &PlayOptions) -> Result<PlayReport, PlayError> {
    let rate = check_rate(options.rate)?;
    check_wait_s(options.wait.as_secs_f64())?;
    let reader = BagReader::open(bag)?;
    let imu_topic = reader.imu_topic(options.bag_topic.as_deref())?.name.clone();
    let temperature_topic = reader.temperature_topic(None)?.map(|t| t.name.clone());
    let out_imu = options
        .out_topic
        .clone()
        .unwrap_or_else(|| imu_topic.clone());
    let out_imu = if out_imu.starts_with('/') {
        out_imu
    } else {
        format!("/{out_imu}")
    };

    let mut node = peer_node(options.domain_id, "fdavar_play")?;
    let qos = if options.reliable {
        QosProfile::publisher_default()
            .reliability_reliable(WhenFull::Wait(Duration::from_secs(1)))
            .history(History::KeepLast { depth: 1000 })
    } else {
        QosProfile::subscription_default().history(History::KeepLast { depth: 100 })
    };
    let imu_pub = publish_on::<Imu>(&mut node, &out_imu, &qos)?;
    let temp_pub = match &temperature_topic {
        Some(t) => Some(publish_on::<Temperature>(&mut node, t, &qos)?),
        None => None,
    };
    let clock_qos = QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(Duration::from_millis(100)))
        .history(History::KeepLast { depth: 1 });
    let clock_pub = if options.clock {
        Some(publish_on::<Clock>(&mut node, "/clock", &clock_qos)?)
    } else {
        None
    };
    spin_in_background(&mut node)?;

    let deadline = Instant::now() + options.wait;
    let mut report = PlayReport::default();
    // With `clock`, a node on sim time needs /clock matched too, or its first samples get time 0.
    while Instant::now() < deadline {
        report.matched = imu_pub.get_subscription_count(&node) > 0;
        report.clock_matched = clock_pub
            .as_ref()
            .is_some_and(|c| c.get_subscription_count(&node) > 0);
        if report.matched && (clock_pub.is_none() || report.clock_matched) {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    if report.matched {
        // Discovery is two-sided: give the reader's side a moment to match us too.
        std::thread::sleep(Duration::from_millis(500));
    }

    let start = Instant::now();
    let mut first_log: Option<i64> = None;
    // The last log time published on /clock, and the last one seen. (Was `i64::MIN` with
    // `log_ns - last_clock >= 10 ms`: that difference wraps negative for every positive log time
    // in a release build, so no /clock was ever sent; issue 9.)
    let mut last_clock: Option<i64> = None;
    let mut last_log: Option<i64> = None;
    for item in reader.messages(&imu_topic, temperature_topic.as_deref())? {
        let message = match item {
            Ok(m) => m,
            Err(crate::bag::BagError::Malformed { .. }) => {
                report.malformed += 1;
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        let log_ns = match &message {
            BagMessage::Imu { log_time_ns, .. } | BagMessage::Temperature { log_time_ns, .. } => {
                *log_time_ns
            }
        };
        let t0 = *first_log.get_or_insert(log_ns);
        // Saturating: log times are the bag's data, any i64; the rate bounds keep the quotient
        // within a Duration, and a sleep of centuries is still no panic.
        let recorded_s = log_ns.saturating_sub(t0).max(0) as f64 * 1e-9;
        let due = Duration::try_from_secs_f64(recorded_s / rate).unwrap_or(Duration::MAX);
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
        if let Some(clock) = &clock_pub {
            let tick = last_clock.is_none_or(|t| log_ns.saturating_sub(t) >= CLOCK_PERIOD_NS);
            if tick && publish_clock(clock, log_ns) {
                report.clock += 1;
                last_clock = Some(log_ns);
            }
        }
        last_log = Some(log_ns);
        match message {
            BagMessage::Imu { sample, .. } => {
                let Ok(msg) = Imu::from_sample(&sample, &options.frame_id) else {
                    report.malformed += 1;
                    continue;
                };
                if imu_pub.publish(msg).is_ok() {
                    report.imu += 1;
                }
            }
            BagMessage::Temperature { sample, .. } => {
                let msg = Temperature::from_sample(&sample, &options.frame_id);
                if let (Some(p), Ok(msg)) = (&temp_pub, msg) {
                    if p.publish(msg).is_ok() {
                        report.temperature += 1;
                    }
                }
            }
        }
    }
    // The clock ends at the last message's log time.
    if let (Some(clock), Some(log_ns)) = (&clock_pub, last_log) {
        if last_clock.is_some_and(|t| t < log_ns) && publish_clock(clock, log_ns) {
            report.clock += 1;
        }
    }
    // Let a reliable writer deliver what it still holds.
    std::thread::sleep(Duration::from_millis(if options.reliable {
        1000
    } else {
        100
    }));
    node.stop_spinner();
    Ok(report)
}

/// Shortest interval between two `/clock` messages, ns (10 ms, 100 Hz at rate 1).
const CLOCK_PERIOD_NS: i64 = 10_000_000;

/// Publishes `log_ns` on `/clock`; false when it was not sent (a time beyond `builtin_interfaces/Time`,
/// or DDS refused).
fn publish_clock(clock: &ros2_client::Publisher<Clock>, log_ns: i64) -> bool {
    crate::msgs::builtin_interfaces::Time::from_ns(log_ns)
        .is_ok_and(|time| clock.publish(Clock { clock: time }).is_ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_and_waits_outside_their_bounds_are_refused() {
        for rate in [MIN_RATE, 1.0, MAX_RATE] {
            assert_eq!(check_rate(rate).unwrap(), rate);
        }
        // 1e-300 made `Duration::from_secs_f64` panic (issue 13).
        for rate in [
            1e-300,
            0.0,
            -1.0,
            f64::NAN,
            f64::INFINITY,
            MIN_RATE / 2.0,
            MAX_RATE * 2.0,
        ] {
            let e = check_rate(rate).unwrap_err();
            assert!(e.to_string().contains("--rate"), "{e}");
        }
        assert_eq!(check_wait_s(0.0).unwrap(), Duration::ZERO);
        assert_eq!(check_wait_s(MAX_WAIT_S).unwrap(), Duration::from_secs(3600));
        for s in [-1.0, f64::NAN, f64::INFINITY, MAX_WAIT_S + 1.0] {
            assert!(check_wait_s(s).is_err(), "{s}");
        }
        // The slowest rate over the longest recording an i64 of nanoseconds spans still fits a
        // Duration, so the pacing never overflows.
        let longest_s = i64::MAX as f64 * 1e-9;
        assert!(Duration::try_from_secs_f64(longest_s / MIN_RATE).is_ok());
    }
}
