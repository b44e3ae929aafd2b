//! `fdavar analyze BAG [--model SPEC] [--params FILE] [--axis A]... [--json] [--jobs N] [--out DIR]
//! [--csv DIR]`: the whole job in one read of the bag: F-DAVAR rows and change events of every
//! axis, the noise model's fit and the diagnosis, and every figure and CSV of them.
//!
//! Why one command: `fdavar davar` and `fdavar diagnose` each decode the bag, and each runs its
//! axes one after the other (issue 11). Here the main thread decodes the bag once and grows the
//! whole-run record (the same [`fdavar::analysis::Analysis`] `fdavar diagnose` fills, so the
//! diagnosis is its answer, bit for bit); chunks of the same samples go to worker threads, each
//! running the node's DAVAR [`Pipeline`] on its share of the axes (an axis's rows depend on its
//! own values and the stamps only, so they are those of `fdavar davar`); once the bag is read the
//! axes are diagnosed in parallel, while the row workers finish. Memory: the record (bounded, see [`fdavar::model::record`]), the
//! pipelines' rings and at most [`CHUNKS_IN_FLIGHT`] chunks per worker.

use crate::diagnose::{diagnose_all, write_diagnosis, write_diagnosis_files};
use crate::fit::{load_with, outcome, print_json, RecordCap, Selection, Source};
use crate::{Outcome, UsageError};
use anyhow::Context;
use fdavar::model::output::{AxisReport, Report};
use fdavar::model::ModelSpec;
use fdavar::davar::SharedIntervals;
use fdavar::pipeline::{AxisEvent, Output, Pipeline, RowSummary, SigmaRefMode};
use fdavar::report::davar::DavarFigures;
use fdavar::signal::{Axis, ImuSample, Irregularities};
use serde::Serialize;
use std::path::PathBuf;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::sync::Arc;

/// Samples per chunk handed to the row workers (about 115 kB: below the 128 kB from which a
/// buffer got fresh pages of its own before `analysis::reuse_buffers_up_to_4_mb`; a chunk of
/// 4096 samples was 88 mappings, each faulted in, for an hour at 100 Hz).
const CHUNK: usize = 2048;
/// Chunks queued per worker before the reader waits (16 of 2048: the 32768 samples of 8 of 4096).
const CHUNKS_IN_FLIGHT: usize = 16;

/// Do the whole job on a recording: F-DAVAR rows and change events, model fit and diagnosis.
///
/// Reads the bag once. Prints per axis the rows' summary (count, time span, window range) and
/// change events as `fdavar davar` does, then the fit and the suggestions as `fdavar diagnose`
/// does (the same numbers). Axes run in parallel on --jobs threads. A failing model
/// (fit_error or span_fit_error > 2) is a warning, exit 0 (exit 3 with --strict); samples left out (gaps, bad
/// stamps, NaN/Inf) exit 3.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// rosbag2 recording: a bag directory, a .mcap or a .db3.
    pub bag: PathBuf,
    /// Model to start from: comma-separated effect ids or aliases for every axis, or AXIS=SPEC for
    /// one axis (repeatable; later values win). Default N,B,K.
    #[arg(long, default_value = ModelSpec::DEFAULT, value_parser = crate::model_spec_arg)]
    pub model: Vec<String>,
    /// F-DAVAR settings: a ROS 2 parameter file like launch_params/default.yaml (default: the
    /// node's defaults). sigma_ref.mode 'record' needs a second read of the bag: use `fdavar
    /// davar` for it.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    #[command(flatten)]
    pub selection: Selection,
    #[command(flatten)]
    pub record: RecordCap,
    /// Print one JSON object: `davar` (rows' summary, events, irregularities) and `axes` (the
    /// object `fdavar diagnose --json` prints, member for member).
    #[arg(long)]
    pub json: bool,
    /// Exit 3 when a model fails (fit_error or span_fit_error > 2), for CI.
    #[arg(long)]
    pub strict: bool,
    /// Threads for the axes (default: the number of CPUs), at least 1.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub jobs: Option<u16>,
    /// Directory for every figure of the job, per axis (PNG + SVG): `davar_surface_<axis>` and
    /// `window_trace_<axis>` as `fdavar davar --out` draws them, `allan_<axis>` and
    /// `suggestion_<axis>_<effect>` as `fdavar diagnose --out` does, from the one read of the bag.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Directory for the fit's CSVs per axis, `allan_<axis>.csv` and `spans_<axis>.csv`, as
    /// `fdavar diagnose --csv` writes them (columns in docs/model.md).
    #[arg(long, value_name = "DIR")]
    pub csv: Option<PathBuf>,
}

/// The `davar` member of the JSON.
#[derive(Debug, Serialize)]
struct RowsReport {
    tau0: Option<f64>,
    axes: Vec<RowSummary>,
    events: Vec<AxisEvent>,
    irregularities: Irregularities,
}

#[derive(Debug, Serialize)]
struct AnalyzeReport {
    davar: RowsReport,
    #[serde(flatten)]
    diagnosis: Report,
}

/// What one row worker found.
struct Rows {
    pipeline: Pipeline,
    summaries: Vec<RowSummary>,
    events: Vec<AxisEvent>,
    /// The figures of its axes' rows, when `--out` asks for them.
    figures: Vec<DavarFigures>,
}

/// Runs `pipeline` on every chunk `rx` delivers, keeping the summary and events of its rows (and
/// gathering them into `figures`, one per axis the figures are asked for).
fn run_rows(mut pipeline: Pipeline, rx: Receiver<Arc<[ImuSample]>>, mut figures: Vec<DavarFigures>) -> Rows {
    let mut out = Output::default();
    let mut summaries: Vec<RowSummary> = Vec::new();
    let mut events = Vec::new();
    let mut take = |pipeline: &mut Pipeline, out: &mut Output| {
        for r in &out.rows {
            match summaries.iter_mut().find(|s| s.axis == r.axis) {
                Some(s) => s.add(r),
                None => summaries.push(RowSummary::of(r)),
            }
            figures.iter_mut().for_each(|f| f.push(r));
        }
        pipeline.recycle_all(&mut out.rows);
        events.append(&mut out.events);
    };
    for chunk in rx {
        for s in chunk.iter() {
            pipeline.push(s, &mut out);
            take(&mut pipeline, &mut out);
        }
    }
    pipeline.finish(&mut out);
    take(&mut pipeline, &mut out);
    Rows { pipeline, summaries, events, figures }
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let davar = crate::davar::params(args.params.as_deref())?;
    if davar.sigma_ref == SigmaRefMode::Record {
        return Err(UsageError(
            "--params: sigma_ref.mode 'record' needs a first read of the whole bag; `fdavar analyze` reads it once: use running, baseline or value (or `fdavar davar`)".into(),
        )
        .into());
    }
    let axes = args.selection.axes();
    let jobs = crate::jobs(args.jobs.map(usize::from));
    // Axis k goes to worker k mod jobs.
    let groups: Vec<Vec<Axis>> = (0..jobs.min(axes.len()))
        .map(|w| axes.iter().copied().skip(w).step_by(jobs).collect())
        .collect();
    // One χ² interval cache for all workers: their axes meet the same (m, terms).
    let intervals = SharedIntervals::default();
    let pipelines = groups
        .iter()
        .map(|g| {
            Pipeline::new(davar.clone(), g, None).map(|p| {
                let p = p.sharing_intervals(intervals.clone());
                // Without figures only the rows' windows and events are read.
                if args.out.is_some() { p } else { p.shortest_tau_only() }
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .context("cannot start the DAVAR pipeline")?;
    let (analysis, diagnoses, rows) = std::thread::scope(|scope| -> anyhow::Result<_> {
        let (senders, workers): (Vec<SyncSender<Arc<[ImuSample]>>>, Vec<_>) = pipelines
            .into_iter()
            .zip(&groups)
            .map(|(p, group)| {
                let figures = match args.out {
                    Some(_) => crate::davar::figures_of(&davar, group),
                    None => Vec::new(),
                };
                let (tx, rx) = sync_channel(CHUNKS_IN_FLIGHT);
                (tx, scope.spawn(move || run_rows(p, rx, figures)))
            })
            .unzip();
        let mut chunk = Vec::with_capacity(CHUNK);
        let send = |chunk: &mut Vec<ImuSample>| -> anyhow::Result<()> {
            let shared: Arc<[ImuSample]> = chunk.drain(..).collect();
            for tx in &senders {
                tx.send(Arc::clone(&shared)).context("a DAVAR worker stopped")?;
            }
            Ok(())
        };
        let source = Source {
            record_cap: args.record.values,
            ..Source::whole(&args.bag, &args.model, args.selection.topic.as_deref())
        };
        let mut analysis = load_with(&source, None, &mut |s| {
            chunk.push(*s);
            if chunk.len() == CHUNK {
                send(&mut chunk)?;
            }
            Ok(())
        })?;
        send(&mut chunk)?;
        drop(senders);
        // The record is complete: the diagnosis starts while the row workers finish their
        // queues (both need the cores; neither waits for the other).
        let diagnoses = diagnose_all(&mut analysis, &axes, jobs)?;
        let rows: Vec<Rows> = workers
            .into_iter()
            .map(|w| w.join().expect("a DAVAR worker panicked"))
            .collect();
        Ok((analysis, diagnoses, rows))
    })?;
    let mut summaries: Vec<RowSummary> = rows.iter().flat_map(|r| r.summaries.iter().copied()).collect();
    summaries.sort_by_key(|s| s.axis);
    let mut events: Vec<AxisEvent> = rows.iter().flat_map(|r| r.events.iter().cloned()).collect();
    // Per axis in axis order, each axis's events in time order (as `fdavar davar` lists them).
    events.sort_by_key(|e| e.axis);
    let tau0 = rows.first().and_then(|r| r.pipeline.tau0());
    if args.json {
        print_json(&AnalyzeReport {
            davar: RowsReport { tau0, axes: summaries, events, irregularities: analysis.irregularities() },
            diagnosis: Report { axes: diagnoses.iter().map(AxisReport::from_diagnosis).collect() },
        })?;
    } else {
        let mut out = std::io::stdout().lock();
        crate::davar::write_summary(&mut out, tau0, davar.policy.build().initial(), &summaries, &events).context("writing output")?;
        for d in &diagnoses {
            write_diagnosis(&mut out, d).context("writing output")?;
        }
    }
    if let Some(dir) = &args.out {
        let title = crate::fit::title(&args.bag);
        for mut r in rows {
            crate::davar::write_figures(dir, &mut r.figures, &r.events, &title)?;
        }
    }
    write_diagnosis_files(args.out.as_deref(), args.csv.as_deref(), &args.bag, &diagnoses)?;
    let fits: Vec<_> = diagnoses.into_iter().map(|d| d.fit).collect();
    Ok(outcome(&analysis, &fits, args.strict, "the suggestions per axis name what would explain it"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse_args;

    #[test]
    fn flags_parse() {
        let args = parse_args::<Args>(&["x", "b.mcap", "--jobs", "2", "--axis", "gyro_x", "--json"]).unwrap();
        assert_eq!(args.jobs, Some(2));
        assert_eq!(args.selection.axis, vec![Axis::GyroX]);
        assert!(parse_args::<Args>(&["x", "b.mcap", "--jobs", "0"]).is_err());
        assert!(parse_args::<Args>(&["x", "b.mcap", "--model", "N,nope"]).is_err());
    }
}
