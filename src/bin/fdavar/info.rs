//! `fdavar info BAG`: what a recording holds — files, topics, counts, duration, rates — and, for
//! each IMU topic, the sensor-clock period and the stamp irregularities fdavar will count.

use crate::Outcome;
use anyhow::Context;
use fdavar::bag::{BagMessage, BagReader, TopicInfo, IMU_TYPE};
use fdavar::signal::{nominal_period, Irregularities, StampCheck};
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;

/// Stamps used to estimate the nominal period τ0 (the median of their intervals).
const PERIOD_STAMPS: usize = 1001;

/// Show what a rosbag2 recording holds: topics, counts, duration, rates, and IMU stamp quality.
///
/// Reads the summaries of the bag's files, then streams each sensor_msgs/msg/Imu topic (or only
/// --topic) to measure its sensor-clock period (median interval of the first 1000) and to count
/// gaps (a stamp > 1.5 τ0 after the previous one on the grid), duplicated and backward stamps and NaN/Inf values.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The recording: a rosbag2 directory, a .mcap or a .db3 file.
    pub bag: PathBuf,
    /// Only this IMU topic (default: every sensor_msgs/msg/Imu topic of the bag).
    #[arg(long)]
    pub topic: Option<String>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Report {
    bag: String,
    files: Vec<String>,
    start_ns: Option<i64>,
    duration_s: f64,
    message_count: u64,
    topics: Vec<TopicReport>,
    imu: Vec<ImuReport>,
}

#[derive(Serialize)]
struct TopicReport {
    name: String,
    #[serde(rename = "type")]
    type_name: String,
    message_count: u64,
    /// Messages per second of log time over the bag's duration.
    mean_rate_hz: Option<f64>,
}

#[derive(Serialize)]
struct ImuReport {
    topic: String,
    samples: u64,
    /// Sensor-clock span (last − first stamp), seconds.
    stamp_span_s: f64,
    period_s: Option<f64>,
    rate_hz: Option<f64>,
    irregularities: Irregularities,
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let bag = BagReader::open(&args.bag).context("cannot open the bag")?;
    let (start, end) = bag
        .time_span_ns()
        .map_or((None, None), |(a, b)| (Some(a), Some(b)));
    let duration_s = start.zip(end).map_or(0.0, |(a, b)| (b - a) as f64 * 1e-9);
    let imu_topics: Vec<&TopicInfo> = match &args.topic {
        Some(t) => vec![bag.imu_topic(Some(t))?],
        None => bag
            .topics()
            .iter()
            .filter(|t| t.type_name == IMU_TYPE)
            .collect(),
    };
    let imu = imu_topics
        .iter()
        .map(|t| imu_report(&bag, t))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let report = Report {
        bag: args.bag.display().to_string(),
        files: bag
            .files()
            .map(|(p, s)| format!("{} ({s})", p.display()))
            .collect(),
        start_ns: start,
        duration_s,
        message_count: bag.topics().iter().map(|t| t.message_count).sum(),
        topics: bag
            .topics()
            .iter()
            .map(|t| TopicReport {
                name: t.name.clone(),
                type_name: t.type_name.clone(),
                message_count: t.message_count,
                mean_rate_hz: (duration_s > 0.0).then(|| t.message_count as f64 / duration_s),
            })
            .collect(),
        imu,
    };
    let mut out = std::io::stdout().lock();
    if args.json {
        serde_json::to_writer(&mut out, &report)?;
        writeln!(out)?;
    } else {
        print_text(&mut out, &report)?;
    }
    Ok(Outcome::Ok)
}

/// Streams one IMU topic twice: the first stamps give τ0, the whole topic the irregularities.
fn imu_report(bag: &BagReader, topic: &TopicInfo) -> anyhow::Result<ImuReport> {
    let context = || format!("reading {} from {}", topic.name, bag.path().display());
    let mut first = Vec::with_capacity(PERIOD_STAMPS);
    for m in bag
        .messages(&topic.name, None)
        .with_context(context)?
        .take(PERIOD_STAMPS)
    {
        if let BagMessage::Imu { sample, .. } = m.with_context(context)? {
            first.push(sample.stamp_ns);
        }
    }
    let period_s = nominal_period(&first);
    let mut check = StampCheck::new(period_s.unwrap_or(f64::INFINITY));
    let (mut samples, mut lo, mut hi) = (0u64, i64::MAX, i64::MIN);
    for m in bag.messages(&topic.name, None).with_context(context)? {
        if let BagMessage::Imu { sample, .. } = m.with_context(context)? {
            samples += 1;
            lo = lo.min(sample.stamp_ns);
            hi = hi.max(sample.stamp_ns);
            check.check(sample.stamp_ns);
            for v in sample.values() {
                if !fdavar::signal::is_usable(v) {
                    check.count_non_finite();
                }
            }
        }
    }
    Ok(ImuReport {
        topic: topic.name.clone(),
        samples,
        stamp_span_s: if samples > 0 {
            (hi - lo) as f64 * 1e-9
        } else {
            0.0
        },
        period_s,
        rate_hz: period_s.map(|p| 1.0 / p),
        irregularities: check.counts(),
    })
}

fn print_text(out: &mut impl Write, r: &Report) -> std::io::Result<()> {
    writeln!(out, "bag:       {}", r.bag)?;
    for f in &r.files {
        writeln!(out, "file:      {f}")?;
    }
    match r.start_ns {
        Some(s) => writeln!(
            out,
            "start:     {}.{:09} s (log time)",
            s.div_euclid(1_000_000_000),
            s.rem_euclid(1_000_000_000)
        )?,
        None => writeln!(out, "start:     - (no messages)")?,
    }
    writeln!(out, "duration:  {:.3} s", r.duration_s)?;
    writeln!(out, "messages:  {}", r.message_count)?;
    writeln!(out, "topics:")?;
    let width = r.topics.iter().map(|t| t.name.len()).max().unwrap_or(0);
    let type_width = r
        .topics
        .iter()
        .map(|t| t.type_name.len())
        .max()
        .unwrap_or(0);
    for t in &r.topics {
        let rate = t
            .mean_rate_hz
            .map_or(String::new(), |hz| format!("{hz:9.2} Hz"));
        writeln!(
            out,
            "  {:width$}  {:type_width$}  {:>9} msgs {rate}",
            t.name, t.type_name, t.message_count
        )?;
    }
    if r.imu.is_empty() {
        writeln!(
            out,
            "IMU:       none (the bag holds no {IMU_TYPE}; fdavar has nothing to analyse)"
        )?;
    }
    for i in &r.imu {
        writeln!(out, "IMU {}:", i.topic)?;
        match i.period_s {
            Some(p) => writeln!(
                out,
                "  {} samples over {:.3} s of sensor time, period τ0 = {:.6} s ({:.3} Hz)",
                i.samples,
                i.stamp_span_s,
                p,
                1.0 / p
            )?,
            None => writeln!(
                out,
                "  {} samples: too few distinct stamps for a period",
                i.samples
            )?,
        }
        let n = i.irregularities;
        writeln!(
            out,
            "  gaps {}, duplicated stamps {}, backward stamps {}, non-finite values {}",
            n.gaps, n.duplicates, n.backwards, n.non_finite
        )?;
        if n.reanchors > 0 {
            writeln!(
                out,
                "  the clock jumped {} times (back: 50 backward stamps in a row; forward: more \
                 than {} periods): re-anchored",
                n.reanchors,
                fdavar::signal::MAX_GAP_SAMPLES
            )?;
        }
    }
    Ok(())
}
