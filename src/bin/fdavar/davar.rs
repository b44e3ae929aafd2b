//! `fdavar davar FILE|BAG [--axis A] [--params X.yaml] [--json|--csv]`: the F-DAVAR surface offline.
//!
//! Reads the input, validates the parameters into a [`DavarConfig`], runs
//! [`fdavar::pipeline::Pipeline`] (the same path the node runs live) and prints rows and change
//! events. A plain-text reader lives here only until the shared one (`fdavar::signal::text`) lands.

use crate::Outcome;
use anyhow::{bail, Context};
use fdavar::pipeline::{AxisEvent, AxisRow, DavarConfig, Output, Pipeline, SigmaRefMode};
use fdavar::signal::{Axis, ImuSample};
use serde::Serialize;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Compute the adaptive-window dynamic Allan variance (F-DAVAR) and its change events.
///
/// FILE is plain text or CSV of rate samples, one sample per line (blank lines, lines starting
/// with '#' and one header line are skipped; fields split on commas, semicolons or whitespace),
/// read at --rate HZ. BAG is a rosbag2 recording (directory, .mcap or .db3).
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// Input: a text/CSV file of rate samples, or a rosbag2 recording.
    pub input: PathBuf,
    /// Axis: for a text file, the axis its values are (default gyro_x); for a bag, the one axis to
    /// analyse (default: all six).
    #[arg(long)]
    pub axis: Option<Axis>,
    /// ROS 2 parameter file (fdavar: ros__parameters: ...); default: the built-in defaults
    /// (launch_params/default.yaml).
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// Sample rate of a text file, Hz (overrides the parameter tau0; required when tau0 is 0).
    #[arg(long)]
    pub rate: Option<f64>,
    /// Column of a text file holding the rate samples, counted from 0.
    #[arg(long, default_value_t = 0)]
    pub column: usize,
    /// Print one JSON object: rows, change events and irregularity counts.
    #[arg(long, conflicts_with = "csv")]
    pub json: bool,
    /// Print CSV, one line per (row, tau).
    #[arg(long)]
    pub csv: bool,
    /// Print every N-th row only (events are found from all rows).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    pub every: u64,
}

/// A validated run: what to read, how to analyse it.
struct RunConfig {
    config: DavarConfig,
    samples: Vec<ImuSample>,
    axes: Vec<Axis>,
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let run = validate(args)?;
    let record = match run.config.sigma_ref {
        SigmaRefMode::Record => Some(fdavar::pipeline::record_variances(&run.samples)),
        _ => None,
    };
    let mut pipeline = Pipeline::new(run.config.clone(), &run.axes, record)
        .context("cannot start the DAVAR pipeline")?;
    let mut out = Output::default();
    for s in &run.samples {
        pipeline.push(s, &mut out);
    }
    pipeline.finish(&mut out);
    let stdout = std::io::stdout();
    let mut w = BufWriter::new(stdout.lock());
    let rows: Vec<&AxisRow> = out
        .rows
        .iter()
        .filter(|r| r.row.index % args.every == 0)
        .collect();
    let counts = pipeline.irregularities();
    if args.json {
        let doc = JsonDoc {
            tau0: pipeline.tau0(),
            irregularities: counts,
            excluded_terms: pipeline
                .excluded_terms()
                .into_iter()
                .map(|(axis, n)| (axis.name().to_string(), n))
                .collect(),
            rows: &rows,
            events: &out.events,
        };
        serde_json::to_writer(&mut w, &doc).context("writing JSON")?;
        writeln!(w).context("writing JSON")?;
    } else if args.csv {
        write_csv(&mut w, &rows).context("writing CSV")?;
    } else {
        write_summary(&mut w, &pipeline, &out).context("writing the summary")?;
    }
    w.flush().context("writing output")?;
    let irregular = counts.gaps + counts.duplicates + counts.backwards + counts.non_finite;
    if irregular > 0 {
        eprintln!(
            "fdavar: warning: {} gaps, {} duplicate and {} backwards stamps, {} non-finite values (left out and counted)",
            counts.gaps, counts.duplicates, counts.backwards, counts.non_finite
        );
        return Ok(Outcome::Warnings);
    }
    Ok(Outcome::Ok)
}

fn validate(args: &Args) -> anyhow::Result<RunConfig> {
    let mut config = match &args.params {
        Some(path) => fdavar::params::load(path)
            .with_context(|| format!("invalid parameters in {}", path.display()))?,
        None => DavarConfig::default(),
    };
    if is_bag(&args.input) {
        bail!(
            "{}: reading rosbag2 recordings needs the bag reader (fdavar::bag), which this build does not have yet; export the axis to text and use --rate",
            args.input.display()
        );
    }
    if let Some(rate) = args.rate {
        if !(rate > 0.0 && rate.is_finite()) {
            bail!("--rate must be a positive number of Hz, got {rate}");
        }
        config.tau0 = Some(1.0 / rate);
    }
    let tau0 = config.tau0.context(
        "a text file needs a sample rate: pass --rate HZ (or set tau0 in the parameter file)",
    )?;
    let axis = args.axis.unwrap_or(Axis::GyroX);
    let values = read_text(&args.input, args.column)
        .with_context(|| format!("cannot read {}", args.input.display()))?;
    let samples = values
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            let mut s = ImuSample {
                stamp_ns: (k as f64 * tau0 * 1e9).round() as i64,
                gyro: [f64::NAN; 3],
                accel: [f64::NAN; 3],
            };
            match axis.index() {
                i @ 0..=2 => s.gyro[i] = v,
                i => s.accel[i - 3] = v,
            }
            s
        })
        .collect();
    Ok(RunConfig {
        config,
        samples,
        axes: vec![axis],
    })
}

fn is_bag(path: &Path) -> bool {
    path.is_dir()
        || matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("mcap" | "db3")
        )
}

/// Minimal text reader: one sample per line, the `column`-th field.
fn read_text(path: &Path, column: usize) -> anyhow::Result<Vec<f64>> {
    let text = std::fs::read_to_string(path)?;
    let mut values = Vec::new();
    let mut header_skipped = false;
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let field = line
            .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .nth(column);
        let parsed = field.map(|f| f.trim().parse::<f64>());
        match parsed {
            Some(Ok(v)) => values.push(v),
            _ if values.is_empty() && !header_skipped => header_skipped = true,
            None => bail!("line {}: no column {column}", n + 1),
            Some(Err(_)) => bail!(
                "line {}: '{}' is not a number (column {column})",
                n + 1,
                field.unwrap_or_default()
            ),
        }
    }
    if values.is_empty() {
        bail!("no samples");
    }
    Ok(values)
}

#[derive(Serialize)]
struct JsonDoc<'a> {
    tau0: Option<f64>,
    irregularities: fdavar::signal::Irregularities,
    excluded_terms: std::collections::BTreeMap<String, u64>,
    rows: &'a [&'a AxisRow],
    events: &'a [AxisEvent],
}

fn opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.9e}")).unwrap_or_default()
}

fn write_csv(w: &mut impl Write, rows: &[&AxisRow]) -> std::io::Result<()> {
    writeln!(
        w,
        "axis,time_s,stamp_ns,index,window,f,f_target,sigma2_ref,m,tau_s,avar,adev,terms,edf,ci_low,ci_high"
    )?;
    for r in rows {
        for p in &r.row.points {
            writeln!(
                w,
                "{},{:.6},{},{},{},{},{},{},{},{:.6},{:.9e},{:.9e},{},{:.3},{:.9e},{:.9e}",
                r.axis,
                r.time_s,
                r.stamp_ns,
                r.row.index,
                r.row.window,
                opt(r.row.f),
                opt(r.row.f_target),
                opt(r.row.sigma2_ref),
                p.m,
                p.tau,
                p.avar,
                p.adev(),
                p.terms,
                p.edf,
                p.ci_low,
                p.ci_high
            )?;
        }
    }
    Ok(())
}

fn write_summary(w: &mut impl Write, p: &Pipeline, out: &Output) -> std::io::Result<()> {
    writeln!(w, "tau0: {:?} s", p.tau0())?;
    for axis in Axis::ALL {
        let rows: Vec<&AxisRow> = out.rows.iter().filter(|r| r.axis == axis).collect();
        let (Some(first), Some(last)) = (rows.first(), rows.last()) else {
            continue;
        };
        let wmin = rows.iter().map(|r| r.row.window).min().unwrap_or(0);
        let wmax = rows.iter().map(|r| r.row.window).max().unwrap_or(0);
        writeln!(
            w,
            "{axis}: {} rows, t = {:.3} .. {:.3} s, window {wmin} .. {wmax} samples",
            rows.len(),
            first.time_s,
            last.time_s
        )?;
        for e in out.events.iter().filter(|e| e.axis == axis) {
            let e = &e.event;
            writeln!(
                w,
                "  noise changed from {:.3} s to {:.3} s (samples {} .. {}), level x{:.2}{}",
                e.start_s,
                e.end_s,
                e.start_index,
                e.end_index,
                e.factor,
                if e.closed { "" } else { " (still open at the end)" }
            )?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser, PartialEq)]
    struct Cli {
        #[command(flatten)]
        args: Args,
    }

    #[test]
    fn flags_parse() {
        let cli = Cli::try_parse_from(["x", "f.txt", "--rate", "100", "--json", "--every", "10"]).unwrap();
        assert_eq!(cli.args.rate, Some(100.0));
        assert!(cli.args.json);
        assert!(Cli::try_parse_from(["x", "f.txt", "--json", "--csv"]).is_err());
        assert!(Cli::try_parse_from(["x", "f.txt", "--every", "0"]).is_err());
        assert!(Cli::try_parse_from(["x", "f.txt", "--axis", "gyro_w"]).is_err());
    }
}
