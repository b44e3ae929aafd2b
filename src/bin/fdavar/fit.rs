//! `fdavar fit BAG --model SPEC [--topic T] [--axis A]... [--json] [--out DIR]`: fit a noise
//! model to each axis's whole-record Allan variance and say where it fails.
//!
//! Also home of what `fdavar diagnose` shares: feeding the bag into a [`fdavar::analysis::Analysis`]
//! (the node's analysis path), the text table, the figures and the results MCAP (`--mcap`).

use crate::davar::Thinning;
use crate::{Outcome, UsageError};
use anyhow::Context;
use fdavar::analysis::{Analysis, AnalysisConfig};
use fdavar::bag::{BagMessage, BagReader};
use fdavar::model::output::{allan_figure, AxisReport, Report};
use fdavar::model::spec::axis_models;
use fdavar::model::record::RecordBuilder;
use fdavar::model::fit::Failing;
use fdavar::model::{FittedModel, ModelSpec};
use fdavar::pipeline::{AxisRow, DavarConfig, SigmaRefMode};
use fdavar::report::fit::{allan_table, spans_table};
pub use fdavar::report::fit::write_fit;
use fdavar::results::{axis_state, ResultsWriter, WholeRun};
use fdavar::signal::Axis;
use std::io::Write;
use std::path::{Path, PathBuf};

/// fit_error or span_fit_error above which a model is reported as failing (a warning; exit 3
/// with `--strict`).
pub const FAILING_FIT_ERROR: f64 = 2.0;

/// Fit a noise model to each axis of a rosbag2 recording.
///
/// Prints per axis the coefficients (SI and the seed's display units), fit_error (RMS of
/// z = (σ²_meas − σ²_model)/(σ²_model·√(2/EDF)); about 1 when the model explains the data) and
/// the τ ranges where |z| > 3, then span_fit_error (the same over spans of the record: whether the
/// model holds in time). A failing model (either above 2) is a warning, exit 0 (exit 3 with
/// --strict); samples left out (gaps, bad stamps, NaN/Inf) exit 3.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// rosbag2 recording: a bag directory, a .mcap or a .db3.
    pub bag: PathBuf,
    /// Model: comma-separated effect ids or aliases, e.g. N,B,K,sinusoid, for every axis; or
    /// AXIS=SPEC for one axis (repeatable; later values win), e.g. --model N,B,K --model
    /// gyro_x=N,B,K,sinusoid. At least one noise (spectral) term: time-domain effects such as
    /// bias_step are removed from the samples before the Allan variance of the rest is fitted.
    #[arg(long, required = true, value_parser = crate::model_spec_arg)]
    pub model: Vec<String>,
    #[command(flatten)]
    pub common: Common,
}

/// Which Imu topic and axes of a bag: flags `fit`, `diagnose` and `analyze` share.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Selection {
    /// Imu topic (default: the only sensor_msgs/msg/Imu topic of the bag).
    #[arg(long)]
    pub topic: Option<String>,
    /// Axis to analyse (repeatable; default: all six).
    #[arg(long)]
    pub axis: Vec<Axis>,
}

impl Selection {
    /// The axes asked for, all six by default.
    pub fn axes(&self) -> Vec<Axis> {
        if self.axis.is_empty() {
            Axis::ALL.to_vec()
        } else {
            self.axis.clone()
        }
    }
}

/// How long a record the whole-run fit keeps at full rate: a flag `fit`, `diagnose` and
/// `analyze` share.
#[derive(Debug, clap::Args, PartialEq)]
pub struct RecordCap {
    /// Values per axis the whole-run record keeps before it averages neighbouring pairs and τ0
    /// doubles (default 1048576 = 2^20: 2.9 h at 100 Hz, 44 min at 400 Hz; at most 16777216 =
    /// 2^24). A longer record keeps the shortest τ of a long recording (a sensor's low-pass near
    /// Nyquist, quantization) at about 160 bytes per value at the peak: 2^21 peaked at 310 MB
    /// where 2^20 peaks at 172 MB. The node's parameter `record_cap` is the same setting.
    #[arg(long = "record-cap", value_name = "VALUES", default_value_t = RecordBuilder::DEFAULT_MAX_SAMPLES, value_parser = RecordBuilder::user_cap)]
    pub values: usize,
}

/// Flags `fit` and `diagnose` share.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Common {
    #[command(flatten)]
    pub selection: Selection,
    /// Print one JSON object (docs/design.md §7) instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Directory for figures (PNG + SVG per axis).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Directory for two CSVs per axis: `allan_<axis>.csv`, per τ the measured Allan deviation
    /// with its 68.3 % bounds and EDF, the model's deviation and z; `spans_<axis>.csv`, per span
    /// of the record its fit error and mean z against the whole-record model (columns in
    /// docs/model.md).
    #[arg(long, value_name = "DIR")]
    pub csv: Option<PathBuf>,
    /// Analyse only the first N IMU messages of the recording (counted as recorded, bad ones
    /// included): the cut that reproduces what the node published with `diagnosed_messages: N`.
    #[arg(long, value_name = "N")]
    pub first: Option<u64>,
    #[command(flatten)]
    pub record: RecordCap,
    /// Exit 3 when a model fails (fit_error or span_fit_error > 2), for CI; without it a failing model is the
    /// finding: a warning on stderr and exit 0.
    #[arg(long)]
    pub strict: bool,
    /// Also write the results as an MCAP file (replaced if it exists) with the node's topics: per
    /// axis `/fdavar/<axis>/state` (fdavar_msgs/msg/AxisState), every F-DAVAR row as it comes,
    /// then one message with the whole-run answer; opens in Foxglove and PlotJuggler
    /// (docs/report.md, "Results MCAP").
    #[arg(long, value_name = "OUT")]
    pub mcap: Option<PathBuf>,
    /// F-DAVAR settings of the rows in --mcap: a parameter file like launch_params/default.yaml
    /// (default: the node's defaults, `fdavar_node --help`).
    #[arg(long, value_name = "FILE", requires = "mcap")]
    pub params: Option<PathBuf>,
    /// Rows in --mcap: at most one per axis per SECONDS of analysis time (the first of each
    /// slot, as `fdavar davar --every`); default: every row, one per sample, about 0.5 kB each.
    #[arg(long, value_name = "SECONDS", requires = "mcap", value_parser = crate::davar::positive_seconds)]
    pub mcap_every: Option<f64>,
}


pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let mut results = ResultsOut::create(&args.common)?;
    let mut analysis = load(&Source::of(&args.bag, &args.model, &args.common), results.as_mut())?;
    let mut fits = Vec::new();
    for axis in args.common.selection.axes() {
        let f = analysis
            .fit(axis)
            .with_context(|| format!("cannot fit {axis}"))?;
        fits.push(f);
    }
    if args.common.json {
        let report = Report {
            axes: fits.iter().map(AxisReport::from_fit).collect(),
        };
        print_json(&report)?;
    } else {
        let mut out = std::io::stdout().lock();
        for f in &fits {
            write_fit(&mut out, f, FAILING_FIT_ERROR).context("writing output")?;
        }
    }
    if let Some(results) = results {
        let (messages, until_s) = (analysis.messages(), analysis.duration_s().unwrap_or(0.0));
        results.finish(fits.iter().map(|f| (f.axis, WholeRun::from_fit(f, messages, until_s))))?;
    }
    write_files(args.common.out.as_deref(), args.common.csv.as_deref(), &args.bag, fits.iter())?;
    Ok(outcome(&analysis, &fits, args.common.strict, "`fdavar diagnose` suggests what is missing"))
}

/// Warns on stderr about samples left out and failing models (`hint`: what to do next), and
/// decides the exit: 3 when samples were left out, or when a model fails and `strict`; a failing
/// model alone is the finding, not a fault (exit 0).
pub fn outcome(analysis: &Analysis, fits: &[FittedModel], strict: bool, hint: &str) -> Outcome {
    let irr = analysis.irregularities();
    let irregular = irr.total();
    if irregular > 0 {
        eprintln!("fdavar: warning: {}", irr.describe());
    }
    let failing: Vec<String> = fits
        .iter()
        .filter_map(|f| match f.failing(FAILING_FIT_ERROR)? {
            Failing::OverTau => Some(format!("{} ({:.2})", f.axis, f.fit_error)),
            Failing::InTime => Some(format!("{} (in time: span_fit_error {:.2})", f.axis, f.misfit())),
        })
        .collect();
    if !failing.is_empty() {
        eprintln!(
            "fdavar: warning: the model fails on {} (fit_error or span_fit_error > {FAILING_FIT_ERROR}); {hint}",
            failing.join(", ")
        );
    }
    if irregular > 0 || (strict && !failing.is_empty()) {
        Outcome::Warnings
    } else {
        Outcome::Ok
    }
}

/// Writes what `--out` (the Allan figure) and `--csv` (the Allan curve, model and z) ask for, per
/// fitted axis.
pub fn write_files<'a>(
    out: Option<&Path>,
    csv: Option<&Path>,
    bag: &Path,
    fits: impl Iterator<Item = &'a FittedModel>,
) -> anyhow::Result<()> {
    for f in fits {
        if let Some(dir) = out {
            let stem = dir.join(format!("allan_{}", f.axis));
            fdavar::report::figure::write_allan(&allan_figure(f, &title(bag)), &stem)
                .with_context(|| format!("cannot write the figure of {}", f.axis))?;
        }
        if let Some(dir) = csv {
            for (name, table) in [("allan", allan_table(f)), ("spans", spans_table(f))] {
                let path = dir.join(format!("{name}_{}.csv", f.axis));
                std::fs::create_dir_all(dir)
                    .and_then(|()| std::fs::write(&path, table.to_csv()))
                    .with_context(|| format!("cannot write {}", path.display()))?;
            }
        }
    }
    Ok(())
}

/// A figure title from the bag's file name.
pub fn title(bag: &Path) -> String {
    bag.file_name().map_or_else(
        || bag.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// `--mcap OUT`: the results file being written, the rows' settings and the axes it carries.
pub struct ResultsOut {
    writer: ResultsWriter,
    path: PathBuf,
    davar: DavarConfig,
    axes: Vec<Axis>,
    /// `--mcap-every`.
    thinning: Thinning,
}

impl ResultsOut {
    /// The results file `--mcap` asks for (`--params`: the rows' settings), if any.
    pub fn create(common: &Common) -> anyhow::Result<Option<ResultsOut>> {
        let Some(path) = &common.mcap else {
            return Ok(None);
        };
        if path.is_dir() {
            return Err(UsageError(format!(
                "--mcap {}: a directory; give a file name, e.g. results.mcap",
                path.display()
            ))
            .into());
        }
        let davar = match &common.params {
            Some(p) => fdavar::params::load(p)
                .with_context(|| format!("invalid parameters in {}", p.display()))?,
            None => DavarConfig::default(),
        };
        if davar.sigma_ref == SigmaRefMode::Record {
            // The whole record's variance needs a first pass; the rows are the node's single pass.
            return Err(UsageError(
                "--params: sigma_ref.mode 'record' needs two passes over the recording; the --mcap rows are the node's (one pass): use running, baseline or value".into(),
            )
            .into());
        }
        let writer =
            ResultsWriter::create(path).context("cannot create the results MCAP")?;
        Ok(Some(ResultsOut {
            writer,
            path: path.clone(),
            davar,
            axes: common.selection.axes(),
            thinning: Thinning::new(common.mcap_every),
        }))
    }

    /// Writes the rows of the axes asked for, with the counters so far (as the node publishes).
    fn write_rows(&mut self, analysis: &Analysis, rows: &[AxisRow]) -> anyhow::Result<()> {
        let tau0 = analysis.row_tau0().unwrap_or(f64::NAN);
        for row in rows.iter().filter(|r| self.axes.contains(&r.axis)) {
            if !self.thinning.keep(row) {
                continue;
            }
            let mut state = axis_state(row, tau0);
            state.samples = analysis.messages();
            state.gaps = analysis.irregularities().gaps;
            self.writer
                .write_row(state)
                .with_context(|| format!("cannot write {}", self.path.display()))?;
        }
        Ok(())
    }

    /// Writes the whole-run answer of each axis and completes the file.
    pub fn finish(mut self, answers: impl Iterator<Item = (Axis, WholeRun)>) -> anyhow::Result<()> {
        let context = || format!("cannot write {}", self.path.display());
        for (axis, whole) in answers {
            self.writer.write_whole_run(axis, &whole).with_context(context)?;
        }
        self.writer.finish().with_context(context)
    }
}

/// What a command analyses: which bag, topic and messages, with which models, in how long a
/// record.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    /// The recording.
    pub path: &'a Path,
    /// The `--model` values.
    pub model: &'a [String],
    /// The Imu topic (`None`: the bag's only one).
    pub topic: Option<&'a str>,
    /// `--first`: at most this many IMU messages.
    pub first: Option<u64>,
    /// `--record-cap`: values per axis before the record halves.
    pub record_cap: usize,
}

impl<'a> Source<'a> {
    /// The source `fit` and `diagnose` read: `path` with `model` and the `common` flags.
    pub fn of(path: &'a Path, model: &'a [String], common: &'a Common) -> Source<'a> {
        Source {
            path,
            model,
            topic: common.selection.topic.as_deref(),
            first: common.first,
            record_cap: common.record.values,
        }
    }

    /// The whole of the bag at `path` on `topic`, in a record of the default cap.
    pub fn whole(path: &'a Path, model: &'a [String], topic: Option<&'a str>) -> Source<'a> {
        Source { path, model, topic, first: None, record_cap: RecordBuilder::DEFAULT_MAX_SAMPLES }
    }
}

/// Feeds the IMU topic (and the temperature topic, if the bag has one) into an analysis with the
/// `--model` values, in recorded order (nothing re-sorted: as `fdavar play` would deliver them to
/// the node), up to `--first` IMU messages. With `results`, the analysis also makes F-DAVAR rows
/// on the node's settings and with the node's τ0 rule, and they are written as they come.
pub fn load(source: &Source<'_>, results: Option<&mut ResultsOut>) -> anyhow::Result<Analysis> {
    load_with(source, results, &mut |_| Ok(()))
}

/// [`load`], also handing every IMU message analysed, in the same order, to `each` (`fdavar
/// analyze` feeds its F-DAVAR rows from the same single read of the bag).
pub fn load_with(
    source: &Source<'_>,
    mut results: Option<&mut ResultsOut>,
    each: &mut dyn FnMut(&fdavar::signal::ImuSample) -> anyhow::Result<()>,
) -> anyhow::Result<Analysis> {
    let Source { path, model, topic, first, record_cap } = *source;
    let models = axis_models(model, ModelSpec::DEFAULT).context("invalid --model")?;
    let bag = BagReader::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let imu_topic = bag.imu_topic(topic)?.name.clone();
    let temp_topic = bag.temperature_topic(None)?.map(|t| t.name.clone());
    let mut config = AnalysisConfig::whole_run(&models[0]);
    config.models = models;
    config.max_samples = record_cap;
    if let Some(r) = &results {
        // As the node (src/ros/engine.rs).
        config = config.with_rows(r.davar.clone());
    }
    let mut analysis = Analysis::new(config).context("cannot start the analysis")?;
    for msg in bag.messages(&imu_topic, temp_topic.as_deref())? {
        match msg.with_context(|| format!("reading {}", path.display()))? {
            BagMessage::Imu { sample, .. } => {
                if first.is_some_and(|n| analysis.messages() >= n) {
                    break;
                }
                each(&sample)?;
                let rows = analysis.push(&sample).to_vec();
                if let Some(r) = results.as_deref_mut() {
                    r.write_rows(&analysis, &rows)?;
                }
            }
            BagMessage::Temperature { sample, .. } => analysis.push_temperature(&sample),
        }
    }
    analysis.finish();
    Ok(analysis)
}

/// Prints a JSON document and a newline.
pub fn print_json<T: serde::Serialize>(doc: &T) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    serde_json::to_writer(&mut out, doc).context("writing JSON")?;
    writeln!(out).context("writing JSON")?;
    Ok(())
}

