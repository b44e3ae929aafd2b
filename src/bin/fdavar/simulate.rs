//! `fdavar simulate SPEC.yaml --out BAGDIR`: a recording whose truth is known.

use crate::Outcome;
use anyhow::Context;
use fdavar::bag::{BagWriter, WriterOptions};
use fdavar::sim::{simulate_columns, Columns, SimSpec};
use std::path::{Path, PathBuf};

/// Simulate a six-axis IMU recording from a YAML spec and write it as a rosbag2 MCAP directory
/// (zstd chunks) with `truth.json` (every effect and parameter, SI units) inside it.
///
/// The spec format and every effect are described in docs/sim.md. The same spec and seed always
/// give the same recording.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The simulation spec (YAML).
    pub spec: PathBuf,
    /// The bag directory to create (must not exist unless --force).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an existing bag directory at --out.
    #[arg(long)]
    pub force: bool,
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let text = std::fs::read_to_string(&args.spec)
        .with_context(|| format!("reading spec {}", args.spec.display()))?;
    let spec = SimSpec::from_yaml(&text).with_context(|| format!("in {}", args.spec.display()))?;
    let recording =
        simulate_columns(&spec).with_context(|| format!("in {}", args.spec.display()))?;
    // The bag's errors name its path.
    write_bag(&recording, &args.out, args.force).context("writing the bag")?;
    let truth_path = args.out.join("truth.json");
    let json = serde_json::to_string_pretty(&recording.truth).context("encoding truth.json")?;
    std::fs::write(&truth_path, json + "\n")
        .with_context(|| format!("writing {}", truth_path.display()))?;
    eprintln!(
        "fdavar: wrote {} IMU and {} temperature messages to {}",
        recording.len(),
        recording.temperature.len(),
        args.out.display()
    );
    Ok(Outcome::Ok)
}

/// Writes every message at its stamp (log time = header stamp: an ideal recorder).
///
/// Each IMU sample is built from the columns as it is written, so no copy of the record is held.
fn write_bag(recording: &Columns, dir: &Path, overwrite: bool) -> anyhow::Result<()> {
    let options = WriterOptions {
        overwrite,
        ..WriterOptions::default()
    };
    let truth = &recording.truth;
    let mut writer = BagWriter::create_with(dir, &options)?;
    let mut temps = recording.temperature.iter().peekable();
    for sample in recording.imu() {
        while let Some(t) = temps.next_if(|t| t.stamp_ns <= sample.stamp_ns) {
            writer.write_temperature(&truth.topics.temperature, t.stamp_ns, t, &truth.frame_id)?;
        }
        writer.write_imu(&truth.topics.imu, sample.stamp_ns, &sample, &truth.frame_id)?;
    }
    for t in temps {
        writer.write_temperature(&truth.topics.temperature, t.stamp_ns, t, &truth.frame_id)?;
    }
    writer.finish()?;
    Ok(())
}
