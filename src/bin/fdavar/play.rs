//! `fdavar play`: replay a recording over DDS (feature `ros`).

use crate::Outcome;
use anyhow::Context as _;
use std::path::PathBuf;
use std::time::Duration;

/// Replay a recording's IMU (and temperature) messages over ROS 2 / DDS at the recorded pace.
///
/// Messages keep their recorded header stamps; pacing follows the recorder's log times divided by
/// --rate. The domain is --domain-id, else ROS_DOMAIN_ID, else 0.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The recording: a rosbag2 directory, a .mcap or a .db3.
    pub bag: PathBuf,
    /// Speed factor (2 = twice as fast as recorded). Default 1.
    #[arg(long, default_value_t = 1.0)]
    pub rate: f64,
    /// Also publish /clock (rosgraph_msgs/msg/Clock) with the recorded log time.
    #[arg(long)]
    pub clock: bool,
    /// The bag's IMU topic (default: its only sensor_msgs/msg/Imu topic).
    #[arg(long)]
    pub topic: Option<String>,
    /// Publish on this topic instead of the bag's topic name.
    #[arg(long)]
    pub remap: Option<String>,
    /// DDS domain id (default: ROS_DOMAIN_ID, else 0).
    #[arg(long)]
    pub domain_id: Option<u16>,
    /// Publish reliable (default best effort, like IMU drivers; a reliable subscriber needs this).
    #[arg(long)]
    pub reliable: bool,
    /// Seconds to wait for a subscriber before sending. Default 10.
    #[arg(long, default_value_t = 10.0)]
    pub wait_s: f64,
    /// Frame id of the published messages. Default imu_link.
    #[arg(long, default_value = "imu_link")]
    pub frame_id: String,
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let domain_id = match args.domain_id {
        Some(d) => d,
        None => match std::env::var("ROS_DOMAIN_ID") {
            Ok(s) if !s.trim().is_empty() => s
                .trim()
                .parse()
                .with_context(|| format!("ROS_DOMAIN_ID='{s}' is not a domain id"))?,
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
        wait: Duration::from_secs_f64(args.wait_s.clamp(0.0, 3600.0)),
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
    if report.malformed > 0 || !report.matched {
        eprintln!(
            "fdavar play: {} malformed messages skipped",
            report.malformed
        );
        return Ok(Outcome::Warnings);
    }
    Ok(Outcome::Ok)
}
