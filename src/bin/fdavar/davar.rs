//! `fdavar davar FILE|BAG [--axis A] [--params X.yaml] [--json|--csv] [--every S] [--out DIR]`: the
//! F-DAVAR surface offline.
//!
//! Reads the input, validates the parameters into a [`DavarConfig`], runs
//! [`fdavar::pipeline::Pipeline`] (the same path the node runs live) and prints rows and change
//! events. Text files are read by [`fdavar::signal::text`], bags by [`fdavar::bag`].
//!
//! A bag is streamed: samples go from the reader through the pipeline to the output one by one,
//! so memory does not grow with the recording (issue 9, Build 5). `sigma_ref.mode: record` needs
//! the whole record's variance before the first row; the bag is then read three times (mean,
//! squared deviations, rows) rather than held: the variance is the in-memory two-pass one, bit for
//! bit, and a second read costs less than the analysis. The figures of `--out` are gathered from
//! the same stream in bounded memory ([`fdavar::report::davar::DavarFigures`]).

use crate::Outcome;
use anyhow::{bail, Context};
use fdavar::pipeline::{AxisEvent, AxisRow, DavarConfig, Output, Pipeline, PolicyConfig, RowSummary, SigmaRefMode};
use fdavar::report::davar::DavarFigures;
use fdavar::signal::text::ColumnSelector;
use fdavar::signal::{Axis, ImuSample};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Compute the adaptive-window dynamic Allan variance (F-DAVAR) and its change events.
///
/// FILE is plain text (one rate sample per line, '#' comments) or CSV (see --column), read at
/// --rate HZ. BAG is a rosbag2 recording (directory, .mcap or .db3); its sensor_msgs/msg/Imu
/// topic is analysed with sample times from header.stamp.
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
    /// CSV column of a text file holding the rate samples, by zero-based index or header name
    /// (default: one value per line).
    #[arg(long)]
    pub column: Option<ColumnSelector>,
    /// Imu topic of a bag (default: its only sensor_msgs/msg/Imu topic).
    #[arg(long)]
    pub topic: Option<String>,
    /// Print one JSON object: rows, change events and irregularity counts.
    #[arg(long, conflicts_with = "csv")]
    pub json: bool,
    /// Print CSV, one line per (row, tau).
    #[arg(long)]
    pub csv: bool,
    /// Print one row per axis every SECONDS of analysis time: the first row of each axis in each
    /// interval [k·SECONDS, (k+1)·SECONDS) from the first sample, seconds (default: every row).
    /// Events and the summary are found from all rows.
    #[arg(long, value_name = "SECONDS", value_parser = positive_seconds)]
    pub every: Option<f64>,
    /// Directory for the figures, per axis (PNG + SVG): `davar_surface_<axis>` (σ over analysis
    /// time and τ) and `window_trace_<axis>` (F, F̃ and the window length over time), from every
    /// row (not only those --every prints), binned to at most 1200 times (docs/report.md).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

pub fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("expected a positive number of seconds, got '{s}'")),
    }
}

/// A validated run: what to read, how to analyse it.
struct RunConfig {
    config: DavarConfig,
    input: Input,
    axes: Vec<Axis>,
}

/// Where the samples come from; [`Input::each_sample`] reads them again on every call.
enum Input {
    /// A rosbag2 recording and its Imu topic (resolved).
    Bag { path: PathBuf, topic: String },
    /// The values of a text file (8 B each: the file's one column) as one axis at period `tau0`.
    Text { values: Vec<f64>, axis: Axis, tau0: f64 },
}

impl Input {
    /// Feeds every sample, in file order, to `f`.
    fn each_sample(
        &self,
        f: &mut dyn FnMut(&ImuSample) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        match self {
            Input::Bag { path, topic } => {
                let bag = fdavar::bag::BagReader::open(path)
                    .with_context(|| format!("cannot open bag {}", path.display()))?;
                let mut count = 0u64;
                for message in bag.messages(topic, None)? {
                    if let fdavar::bag::BagMessage::Imu { sample, .. } =
                        message.with_context(|| format!("reading {topic} from {}", path.display()))?
                    {
                        count += 1;
                        f(&sample)?;
                    }
                }
                if count == 0 {
                    bail!("{}: topic {topic} holds no messages", path.display());
                }
                Ok(())
            }
            Input::Text { values, axis, tau0 } => {
                for (k, &v) in values.iter().enumerate() {
                    let mut s = ImuSample {
                        stamp_ns: (k as f64 * tau0 * 1e9).round() as i64,
                        gyro: [f64::NAN; 3],
                        accel: [f64::NAN; 3],
                    };
                    match axis.index() {
                        i @ 0..=2 => s.gyro[i] = v,
                        i => s.accel[i - 3] = v,
                    }
                    f(&s)?;
                }
                Ok(())
            }
        }
    }
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let run = validate(args)?;
    let record = match run.config.sigma_ref {
        SigmaRefMode::Record => Some(fdavar::pipeline::record_variances_in_two_passes(|f| {
            run.input.each_sample(&mut |s| {
                f(s);
                Ok(())
            })
        })?),
        _ => None,
    };
    let mut pipeline = Pipeline::new(run.config.clone(), &run.axes, record)
        .context("cannot start the DAVAR pipeline")?;
    let stdout = std::io::stdout();
    let format = match (args.json, args.csv) {
        (true, _) => Format::Json,
        (_, true) => Format::Csv,
        _ => Format::Summary,
    };
    let mut printer = Printer {
        w: BufWriter::new(stdout.lock()),
        format,
        thinning: Thinning::new(args.every),
        printed: 0,
        begun: false,
        axes: BTreeMap::new(),
        first_window: run.config.policy.build().initial(),
    };
    let mut figures: Vec<DavarFigures> = match &args.out {
        Some(_) => figures_of(&run.config, &run.axes),
        None => Vec::new(),
    };
    // Samples stream from the input and rows are printed as they come: a long recording is held
    // neither as samples nor as its DAVAR surface.
    let mut out = Output::default();
    let mut events = Vec::new();
    let mut messages = 0u64;
    let mut take = |pipeline: &mut Pipeline, out: &mut Output, events: &mut Vec<AxisEvent>| -> anyhow::Result<()> {
        for row in &out.rows {
            figures.iter_mut().for_each(|f| f.push(row));
            printer.row(row).context("writing output")?;
        }
        // Printed: their memory serves the next rows.
        pipeline.recycle_all(&mut out.rows);
        events.append(&mut out.events);
        Ok(())
    };
    run.input.each_sample(&mut |s| {
        messages += 1;
        pipeline.push(s, &mut out);
        take(&mut pipeline, &mut out, &mut events)
    })?;
    pipeline.finish(&mut out);
    if pipeline.tau0().is_none() {
        // No stamp later than the one before it (all equal, or every one earlier): the period
        // is unknown and nothing can be placed. It exited 0 with zero rows before (issue 13).
        bail!(
            "{}: none of its {messages} IMU stamps is later than the one before it (all equal or \
             going backwards), so the sample period is unknown and nothing was analysed; set the \
             tau0 parameter if the stamps are wrong",
            args.input.display()
        );
    }
    take(&mut pipeline, &mut out, &mut events)?;
    printer.end(&pipeline, &events).context("writing output")?;
    if let Some(dir) = &args.out {
        write_figures(dir, &mut figures, &events, &crate::fit::title(&args.input))?;
    }
    let counts = pipeline.irregularities();
    if counts.total() > 0 {
        eprintln!("fdavar: warning: {}", counts.describe());
        return Ok(Outcome::Warnings);
    }
    Ok(Outcome::Ok)
}

/// The figure gatherers of `axes` under `config`'s window policy (its λ1 and λ2 drawn on the
/// window trace).
pub fn figures_of(config: &DavarConfig, axes: &[Axis]) -> Vec<DavarFigures> {
    let limits = match config.policy {
        PolicyConfig::Fixed { length } => (length, length),
        PolicyConfig::Sign { min, max, .. } | PolicyConfig::Proportional { min, max, .. } => (min, max),
    };
    axes.iter().map(|&a| DavarFigures::new(a, Some(limits))).collect()
}

/// Writes `davar_surface_<axis>` and `window_trace_<axis>` (PNG + SVG) in `dir` for each axis
/// that has rows.
pub fn write_figures(
    dir: &Path,
    figures: &mut [DavarFigures],
    events: &[AxisEvent],
    title: &str,
) -> anyhow::Result<()> {
    for f in figures.iter_mut() {
        for e in events {
            f.push_event(e.axis, &e.event);
        }
        let Some((surface, trace)) = f.figures(title) else {
            continue;
        };
        let axis = &surface.axis;
        fdavar::report::figure::write_davar_surface(&surface, &dir.join(format!("davar_surface_{axis}")))
            .with_context(|| format!("cannot draw the DAVAR surface of {axis}"))?;
        fdavar::report::figure::write_window_trace(&trace, &dir.join(format!("window_trace_{axis}")))
            .with_context(|| format!("cannot draw the window trace of {axis}"))?;
    }
    Ok(())
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Json,
    Csv,
    Summary,
}

/// `--every SECONDS`: keeps the first row of each axis in each interval [k·SECONDS, (k+1)·SECONDS)
/// of analysis time (also `--mcap-every` of `fdavar fit/diagnose`); `None` keeps every row.
#[derive(Debug, Clone, Copy)]
pub struct Thinning {
    every: Option<f64>,
    last_slot: [Option<i64>; 6],
}

impl Thinning {
    pub fn new(every: Option<f64>) -> Thinning {
        Thinning { every, last_slot: [None; 6] }
    }

    /// Whether `r` is the first row of its axis in its interval.
    pub fn keep(&mut self, r: &AxisRow) -> bool {
        let Some(every) = self.every else {
            return true;
        };
        let slot = Some((r.time_s / every).floor() as i64);
        std::mem::replace(&mut self.last_slot[r.axis.index()], slot) != slot
    }
}

/// Writes rows as they arrive, in the chosen format, and the closing part at the end.
struct Printer<W: Write> {
    w: W,
    format: Format,
    thinning: Thinning,
    printed: u64,
    /// Whether the opening part is written (at the first row or the end: a run that fails before
    /// either prints nothing).
    begun: bool,
    axes: BTreeMap<Axis, RowSummary>,
    /// The window of an axis's first row, samples (said when no axis has a row).
    first_window: usize,
}

impl<W: Write> Printer<W> {
    fn begin(&mut self) -> std::io::Result<()> {
        if std::mem::replace(&mut self.begun, true) {
            return Ok(());
        }
        match self.format {
            Format::Json => write!(self.w, "{{\"rows\":["),
            Format::Csv => writeln!(
                self.w,
                "axis,time_s,stamp_ns,index,window,f,f_target,sigma2_ref,m,tau_s,avar,adev,terms,edf,ci_low,ci_high"
            ),
            Format::Summary => Ok(()),
        }
    }

    fn row(&mut self, r: &AxisRow) -> std::io::Result<()> {
        self.begin()?;
        self.axes
            .entry(r.axis)
            .and_modify(|s| s.add(r))
            .or_insert_with(|| RowSummary::of(r));
        if !self.thinning.keep(r) {
            return Ok(());
        }
        match self.format {
            Format::Json => {
                if self.printed > 0 {
                    write!(self.w, ",")?;
                }
                serde_json::to_writer(&mut self.w, r)?;
            }
            Format::Csv => write_csv_row(&mut self.w, r)?,
            Format::Summary => {}
        }
        self.printed += 1;
        Ok(())
    }

    fn end(&mut self, p: &Pipeline, events: &[AxisEvent]) -> std::io::Result<()> {
        self.begin()?;
        match self.format {
            Format::Json => {
                let tail = JsonTail {
                    events,
                    tau0: p.tau0(),
                    irregularities: p.irregularities(),
                    excluded_terms: p
                        .excluded_terms()
                        .into_iter()
                        .map(|(axis, n)| (axis.name().to_string(), n))
                        .collect(),
                };
                let tail = serde_json::to_string(&tail)?;
                // `tail` is an object; splice its members after the rows array.
                writeln!(self.w, "],{}", &tail[1..])?;
            }
            Format::Csv => {}
            Format::Summary => self.write_summary(p, events)?,
        }
        self.w.flush()
    }

    fn write_summary(&mut self, p: &Pipeline, events: &[AxisEvent]) -> std::io::Result<()> {
        let summaries: Vec<RowSummary> = self.axes.values().copied().collect();
        write_summary(&mut self.w, p.tau0(), self.first_window, &summaries, events)
    }
}

/// The summary of the rows: τ0, then per axis its rows' count, time span and window range, and
/// its change events (also `fdavar analyze`'s); when no axis has a row, why: an axis's first row
/// needs `first_window` samples.
pub fn write_summary(
    w: &mut dyn Write,
    tau0: Option<f64>,
    first_window: usize,
    summaries: &[RowSummary],
    events: &[AxisEvent],
) -> std::io::Result<()> {
    match tau0 {
        Some(tau0) => writeln!(w, "tau0: {tau0} s")?,
        None => writeln!(w, "tau0: unknown (too few samples)")?,
    }
    if summaries.is_empty() {
        writeln!(
            w,
            "no rows: an axis gives its first row once {first_window} samples fill its first window \
             (`window` in a --params file sets it)"
        )?;
    }
    for s in summaries {
        writeln!(
            w,
            "{}: {} rows, t = {:.3} .. {:.3} s, window {} .. {} samples",
            s.axis, s.rows, s.first_s, s.last_s, s.window_min, s.window_max
        )?;
        for e in events.iter().filter(|e| e.axis == s.axis) {
            let e = &e.event;
            let open = if e.closed { "" } else { " (still open at the end)" };
            // One sample is no change of the noise: a glitch or a knock (a real XSens MTi-G's
            // gyro gives dozens; docs/model.md, "Heavy tails").
            if e.start_index == e.end_index {
                writeln!(
                    w,
                    "  a spike at {:.3} s (sample {}): one sample, level x{:.2}{open}",
                    e.start_s, e.start_index, e.factor
                )?;
            } else {
                writeln!(
                    w,
                    "  noise changed from {:.3} s to {:.3} s (samples {} .. {}), level x{:.2}{open}",
                    e.start_s, e.end_s, e.start_index, e.end_index, e.factor
                )?;
            }
        }
    }
    Ok(())
}

/// The F-DAVAR settings of a `--params` file, the defaults without one.
pub fn params(path: Option<&Path>) -> anyhow::Result<DavarConfig> {
    match path {
        // A value the parameter table refuses is a usage error (exit 2, issue 13); an unreadable
        // file is not.
        Some(path) => fdavar::params::load(path)
            .map_err(|e| match e {
                fdavar::params::ParamsError::Io { .. } => anyhow::Error::new(e),
                other => anyhow::Error::new(crate::UsageError(other.to_string())),
            })
            .with_context(|| format!("invalid parameters in {}", path.display())),
        None => Ok(DavarConfig::default()),
    }
}

fn validate(args: &Args) -> anyhow::Result<RunConfig> {
    let mut config = params(args.params.as_deref())?;
    if is_bag(&args.input) {
        if let Some(rate) = args.rate {
            bail!("--rate {rate} is for text files; a bag's period comes from its stamps (or the tau0 parameter)");
        }
        let path = args.input.clone();
        let bag = fdavar::bag::BagReader::open(&path)
            .with_context(|| format!("cannot open bag {}", path.display()))?;
        let topic = bag.imu_topic(args.topic.as_deref())?.name.clone();
        if let Some(tau0) = config.tau0 {
            // A given tau0 must fit the stamps (issue 13): their median interval over the first
            // PERIOD_SETTLE intervals, as the pipeline would learn it.
            let mut stamps = Vec::new();
            for message in bag.messages(&topic, None)? {
                if let fdavar::bag::BagMessage::Imu { sample, .. } = message? {
                    stamps.push(sample.stamp_ns);
                    if stamps.len() > fdavar::pipeline::PERIOD_SETTLE {
                        break;
                    }
                }
            }
            if let Some(measured) = fdavar::signal::nominal_period(&stamps) {
                fdavar::params::check_tau0_against_period(tau0, measured)
                    .map_err(|e| crate::UsageError(e.to_string()))
                    .with_context(|| match &args.params {
                        Some(p) => format!("invalid parameters in {}", p.display()),
                        None => "invalid parameters".to_string(),
                    })?;
            }
        }
        let axes = args.axis.map_or_else(|| Axis::ALL.to_vec(), |a| vec![a]);
        return Ok(RunConfig {
            config,
            input: Input::Bag { path, topic },
            axes,
        });
    }
    if let Some(rate) = args.rate {
        if !(rate > 0.0 && rate.is_finite()) {
            bail!("--rate must be a positive number of Hz, got {rate}");
        }
        // The same range as the tau0 parameter.
        fdavar::params::spec("tau0")
            .expect("tau0 is a parameter")
            .check(&fdavar::params::ParamValue::Float(1.0 / rate))
            .map_err(|e| crate::UsageError(format!("--rate {rate}: {e}")))?;
        config.tau0 = Some(1.0 / rate);
    }
    let tau0 = config.tau0.context(
        "a text file needs a sample rate: pass --rate HZ (or set tau0 in the parameter file)",
    )?;
    let axis = args.axis.unwrap_or(Axis::GyroX);
    let values = fdavar::signal::text::read_column(&args.input, args.column.as_ref())?;
    Ok(RunConfig {
        config,
        input: Input::Text { values, axis, tau0 },
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

#[derive(Serialize)]
struct JsonTail<'a> {
    events: &'a [AxisEvent],
    tau0: Option<f64>,
    irregularities: fdavar::signal::Irregularities,
    excluded_terms: BTreeMap<String, u64>,
}

fn opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.9e}")).unwrap_or_default()
}

fn write_csv_row(w: &mut impl Write, r: &AxisRow) -> std::io::Result<()> {
    for p in r.row.points() {
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
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse_args;

    #[test]
    fn flags_parse() {
        let args = parse_args::<Args>(&["x", "f.txt", "--rate", "100", "--json", "--every", "0.5"])
            .unwrap();
        assert_eq!(args.rate, Some(100.0));
        assert_eq!(args.every, Some(0.5));
        assert!(args.json);
        assert!(parse_args::<Args>(&["x", "f.txt", "--json", "--csv"]).is_err());
        for bad in ["0", "-1", "inf", "NaN", "1s"] {
            assert!(parse_args::<Args>(&["x", "f.txt", "--every", bad]).is_err(), "{bad}");
        }
        assert!(parse_args::<Args>(&["x", "f.txt", "--axis", "gyro_w"]).is_err());
    }
}
