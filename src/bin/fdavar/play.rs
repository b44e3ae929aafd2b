//! `fdavar play`: replay a recording over DDS (feature `ros`).

use crate::Outcome;
use anyhow::Context as _;
use std::path::PathBuf;

/// Replay a recording's IMU (and temperature) messages over ROS 2 / DDS at the recorded pace.
///
/// Messages keep their recorded header stamps; pacing follows the recorder's log times divided by
/// --rate. The domain is --domain-id, else ROS_DOMAIN_ID, else 0. An out-of-range number is a usage
/// error (exit 2).
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The recording: a rosbag2 directory, a .mcap or a .db3.
    pub bag: PathBuf,
    /// Speed factor (2 = twice as fast as recorded), in [1e-6, 1e6]. Default 1.
    #[arg(long, default_value_t = 1.0, value_parser = parse_rate, allow_negative_numbers = true)]
    pub rate: f64,
    /// Also publish /clock (rosgraph_msgs/msg/Clock, reliable, keep last 1) with the recorded log
    /// time, at most every 10 ms of it; waits (--wait-s) for a /clock subscriber too.
    #[arg(long)]
    pub clock: bool,
    /// The bag's IMU topic (default: its only sensor_msgs/msg/Imu topic).
    #[arg(long)]
    pub topic: Option<String>,
    /// Publish on this topic instead of the bag's topic name.
    #[arg(long)]
    pub remap: Option<String>,
    /// DDS domain id, 0..=232 (default: ROS_DOMAIN_ID, else 0).
    #[arg(long, value_parser = clap::value_parser!(u16).range(0..=MAX_DOMAIN_ID))]
    pub domain_id: Option<u16>,
    /// Publish reliable (default best effort, like IMU drivers; a reliable subscriber needs this).
    #[arg(long)]
    pub reliable: bool,
    /// Seconds to wait for a subscriber before sending, in [0, 3600]. Default 10.
    #[arg(long, default_value_t = 10.0, value_parser = parse_wait_s, allow_negative_numbers = true)]
    pub wait_s: f64,
    /// Frame id of the published messages. Default imu_link.
    #[arg(long, default_value = "imu_link")]
    pub frame_id: String,
}

/// The largest DDS domain id ROS 2 accepts (the node's bound too).
const MAX_DOMAIN_ID: i64 = 232;

fn parse_rate(s: &str) -> Result<f64, String> {
    let rate: f64 = s.parse().map_err(|e| format!("{e}"))?;
    fdavar::ros::play::check_rate(rate).map_err(|e| e.to_string())
}

fn parse_wait_s(s: &str) -> Result<f64, String> {
    let seconds: f64 = s.parse().map_err(|e| format!("{e}"))?;
    fdavar::ros::play::check_wait_s(seconds)
        .map(|_| seconds)
        .map_err(|e| e.to_string())
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let domain_id = match args.domain_id {
        Some(d) => d,
        None => match std::env::var("ROS_DOMAIN_ID") {
            Ok(s) if !s.trim().is_empty() => s
                .trim()
                .parse()
                .ok()
                .filter(|d| i64::from(*d) <= MAX_DOMAIN_ID)
                .with_context(|| {
                    format!("ROS_DOMAIN_ID='{s}' is not a domain id (0..={MAX_DOMAIN_ID})")
                })?,
            _ => 0,
        },
    };
    let options = fdavar::ros::play::PlayOptions {
        rate: args.rate,
        clock: args.clock,
        bag_topic: args.topic.clone(),
        out_topic: args.remap.clone(),
        domain_id,
        reliable: args.reliable,
        wait: fdavar::ros::play::check_wait_s(args.wait_s)?,
        frame_id: args.frame_id.clone(),
    };
    let report = fdavar::ros::play::play(&args.bag, &options)
        .with_context(|| format!("playing {}", args.bag.display()))?;
    eprintln!(
        "fdavar play: {} IMU and {} temperature messages published on domain {domain_id}{}",
        report.imu,
        report.temperature,
        if report.matched {
            ""
        } else {
            " (no subscriber matched before sending)"
        }
    );
    if args.clock {
        eprintln!(
            "fdavar play: {} /clock messages published{}",
            report.clock,
            if report.clock_matched {
                ""
            } else {
                " (no /clock subscriber matched before sending)"
            }
        );
    }
    if report.malformed > 0 {
        eprintln!(
            "fdavar play: {} malformed messages skipped",
            report.malformed
        );
    }
    // The lines above said why: malformed messages, or no subscriber matched (nothing may have
    // been delivered).
    if report.malformed > 0 || !report.matched || (args.clock && !report.clock_matched) {
        return Ok(Outcome::Warnings);
    }
    Ok(Outcome::Ok)
}
