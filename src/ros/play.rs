//! `fdavar play`: publishes a recording's IMU (and temperature) messages over DDS at the recorded
//! pace, optionally with `/clock`.
//!
//! Why not `ros2 bag play`: it needs a ROS installation; this needs none, and it is how the
//! integration tests replay a recording into `fdavar_node` on a domain of their own. Messages keep
//! their recorded header stamps (the sensor clock the analysis uses); the pacing follows the
//! recorder's log times scaled by `rate`, as `ros2 bag play` does; `/clock` carries the log time.

use super::node::{publish_on, NodeError};
use crate::bag::{BagMessage, BagReader};
use crate::msgs::rosgraph_msgs::Clock;
use crate::msgs::sensor_msgs::{Imu, Temperature};
use ros2_client::qos::{History, WhenFull};
use ros2_client::{Context, ContextOptions, NodeName, NodeOptions, QosProfile};
use std::time::{Duration, Instant};

/// How to replay.
#[derive(Debug, Clone, PartialEq)]
pub struct PlayOptions {
    /// Speed factor: 2.0 plays twice as fast as recorded.
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
    /// How long to wait for a subscriber before sending.
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
    /// `rate` is not a positive finite number.
    #[error("--rate must be a positive number, got {0}")]
    Rate(f64),
}

/// Replays `bag` as [`PlayOptions`] say; returns when the last message is sent.
///
/// # Errors
/// [`PlayError`] for an unreadable bag, a bad rate or DDS failing to start. Malformed messages are
/// skipped and counted in the report.
pub fn play(bag: &std::path::Path, options: &PlayOptions) -> Result<PlayReport, PlayError> {
    if !(options.rate.is_finite() && options.rate > 0.0) {
        return Err(PlayError::Rate(options.rate));
    }
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

    let ros = |what: &str| {
        let what = what.to_string();
        move |e: String| NodeError::Ros { what, reason: e }
    };
    let context = Context::with_options(ContextOptions::new().domain_id(options.domain_id))
        .map_err(|e| ros("context")(format!("{e:?}")))?;
    let mut node = context
        .new_node(
            NodeName::new("/", "fdavar_play").map_err(|e| ros("node name")(format!("{e:?}")))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(|e| ros("node")(format!("{e:?}")))?;
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
    let clock_qos = QosProfile::subscription_default().history(History::KeepLast { depth: 1 });
    let clock_pub = if options.clock {
        Some(publish_on::<Clock>(&mut node, "/clock", &clock_qos)?)
    } else {
        None
    };
    let spinner = node
        .spinner()
        .map_err(|e| ros("spinner")(format!("{e:?}")))?;
    std::thread::spawn(move || futures::executor::block_on(spinner.spin()));

    let deadline = Instant::now() + options.wait;
    let mut report = PlayReport::default();
    while Instant::now() < deadline {
        if imu_pub.get_subscription_count(&node) > 0 {
            report.matched = true;
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
    let mut last_clock = i64::MIN;
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
        let due = Duration::from_secs_f64(((log_ns - t0).max(0) as f64 * 1e-9) / options.rate);
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
        if let Some(clock) = &clock_pub {
            if log_ns - last_clock >= 10_000_000 {
                let time =
                    crate::msgs::builtin_interfaces::Time::from_ns(log_ns).unwrap_or_default();
                let _ = clock.publish(Clock { clock: time });
                last_clock = log_ns;
            }
        }
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
    // Let a reliable writer deliver what it still holds.
    std::thread::sleep(Duration::from_millis(if options.reliable {
        1000
    } else {
        100
    }));
    node.stop_spinner();
    Ok(report)
}
