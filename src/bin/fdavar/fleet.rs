//! `fdavar diagnose A B C … [--jobs N]`, or `fdavar diagnose DIR` for a directory of bags: the
//! diagnosis of many recordings (a fleet of robots' bags), one summary table.
//!
//! Each recording is diagnosed exactly as `fdavar diagnose BAG` diagnoses it alone (the same
//! `load` and the same answers); recordings run in parallel, each on one thread, so that at most
//! `--jobs` records are in memory at once. One unreadable recording does not stop the others: it
//! is a row of the table, and the exit is 1 once all are done.

use crate::diagnose::{diagnose_all, Args};
use crate::fit::{load, print_json, Source, FAILING_FIT_ERROR};
use crate::{Outcome, UsageError};
use fdavar::analysis::on_threads;
use fdavar::model::output::AxisReport;
use fdavar::model::fit::Failing;
use fdavar::model::Diagnosis;
use fdavar::report::table::Table;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Whether `dir` is a directory of recordings rather than one recording: a directory
/// [`fdavar::bag::BagReader`] does not open as one bag ([`fdavar::bag::holds_a_bag`]).
fn is_fleet(dir: &Path) -> std::io::Result<bool> {
    Ok(dir.is_dir() && !fdavar::bag::holds_a_bag(dir)?)
}

/// The recordings `paths` name, in the order given: a directory of recordings ([`is_fleet`])
/// stands for every bag directory directly inside it, in name order; any other path is one
/// recording. Loose `.mcap` / `.db3` files side by side are one split recording to rosbag2 (and
/// to [`fdavar::bag::BagReader`]): as many recordings, they are given one by one (`dir/*.mcap`).
///
/// # Errors
/// A directory that cannot be listed, or one that holds no recording.
pub fn recordings(paths: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for path in paths {
        let listing = |e: std::io::Error| anyhow::anyhow!("cannot list {}: {e}", path.display());
        if !is_fleet(path).map_err(listing)? {
            out.push(path.clone());
            continue;
        }
        let mut inside = Vec::new();
        for entry in std::fs::read_dir(path).map_err(listing)? {
            let p = entry.map_err(listing)?.path();
            if p.is_dir() && !is_fleet(&p).map_err(listing)? {
                inside.push(p);
            }
        }
        if inside.is_empty() {
            return Err(UsageError(format!(
                "{}: holds no recording (no metadata.yaml, .mcap or .db3 in it or in its subdirectories)",
                path.display()
            ))
            .into());
        }
        inside.sort();
        out.extend(inside);
    }
    Ok(out)
}

/// One recording of the fleet: its diagnoses and how many samples were left out, or why it has
/// none.
struct Diagnosed {
    bag: PathBuf,
    result: Result<(Vec<Diagnosis>, u64, String), String>,
}

/// The JSON of many recordings: `{"recordings": [{"bag", "axes"} | {"bag", "error"}]}`, each
/// `axes` the array `fdavar diagnose BAG --json` prints for that recording alone.
#[derive(Serialize)]
struct FleetReport {
    recordings: Vec<RecordingReport>,
}

#[derive(Serialize)]
struct RecordingReport {
    bag: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    axes: Option<Vec<AxisReport>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<String>,
}

/// Diagnoses every recording of `bags` on `jobs` threads and prints one table (or one JSON
/// document); exit as for one recording, summed over all: 3 when samples were left out anywhere
/// (or, with `--strict`, a model fails); an error (exit 1) when some recording could not be
/// diagnosed, after the others are printed.
pub fn run(args: &Args, bags: &[PathBuf], jobs: usize) -> anyhow::Result<Outcome> {
    let common = &args.common;
    if common.out.is_some() || common.csv.is_some() || common.mcap.is_some() {
        return Err(UsageError(format!(
            "--out, --csv and --mcap write one recording's files; {} recordings were given: run `fdavar diagnose BAG` on each one you want them for",
            bags.len()
        ))
        .into());
    }
    let axes = common.selection.axes();
    let done = on_threads(bags, jobs, |bag| Diagnosed {
        bag: bag.clone(),
        result: (|| {
            let mut analysis = load(&Source::of(bag, &args.model, common), None)?;
            let diagnoses = diagnose_all(&mut analysis, &axes, 1)?;
            let irr = analysis.irregularities();
            Ok::<_, anyhow::Error>((diagnoses, irr.total(), irr.describe()))
        })()
        .map_err(|e| format!("{e:#}")),
    });

    if common.json {
        let recordings = done
            .iter()
            .map(|d| RecordingReport {
                bag: d.bag.display().to_string(),
                axes: d.result.as_ref().ok().map(|(ds, ..)| ds.iter().map(AxisReport::from_diagnosis).collect()),
                error: d.result.as_ref().err().cloned(),
            })
            .collect();
        print_json(&FleetReport { recordings })?;
    } else {
        print!("{}", table(&done).to_text());
    }

    let (mut axes_done, mut failing, mut suggested) = (0, 0, 0);
    let (mut irregular, mut broken) = (Vec::new(), Vec::new());
    for d in &done {
        match &d.result {
            Ok((diagnoses, left_out, description)) => {
                axes_done += diagnoses.len();
                failing += diagnoses.iter().filter(|x| x.fit.failing(FAILING_FIT_ERROR).is_some()).count();
                suggested += diagnoses.iter().filter(|x| !x.suggestions.is_empty()).count();
                if *left_out > 0 {
                    eprintln!("fdavar: warning: {}: {description}", d.bag.display());
                    irregular.push(d.bag.display().to_string());
                }
            }
            Err(e) => broken.push(format!("{}: {e}", d.bag.display())),
        }
    }
    eprintln!(
        "fdavar: {} recordings, {} diagnosed: {failing} of {axes_done} axes with a failing model (fit_error or span_fit_error > {FAILING_FIT_ERROR}), {suggested} with a suggestion; samples left out in {} recordings",
        done.len(),
        done.len() - broken.len(),
        irregular.len()
    );
    if !broken.is_empty() {
        anyhow::bail!("{} of {} recordings could not be diagnosed:\n  {}", broken.len(), done.len(), broken.join("\n  "));
    }
    Ok(if !irregular.is_empty() || (common.strict && failing > 0) {
        Outcome::Warnings
    } else {
        Outcome::Ok
    })
}

/// One row per recording and axis: the model, fit_error, the best suggestion and the fit_error
/// with it, and a note (samples left out); an unreadable recording is one row with its error.
fn table(done: &[Diagnosed]) -> Table {
    let mut t = Table::new(["recording", "axis", "model", "fit_error", "suggestion", "fit_error with it", "note"]);
    for d in done {
        let name = d.bag.display().to_string();
        match &d.result {
            Ok((diagnoses, left_out, _)) => {
                let note = if *left_out > 0 { format!("{left_out} samples left out") } else { String::new() };
                for x in diagnoses {
                    let fails = match x.fit.failing(FAILING_FIT_ERROR) {
                        Some(Failing::OverTau) => " FAILS",
                        Some(Failing::InTime) => " FAILS in time",
                        None => "",
                    };
                    let model: Vec<&str> = x.fit.terms.iter().map(|t| t.alias.as_deref().unwrap_or(&t.effect)).collect();
                    let (suggestion, after) = x
                        .suggestions
                        .first()
                        .map_or(("none".to_string(), String::new()), |s| (s.effect.clone(), format!("{:.2}", s.fit_error_after)));
                    t.push([
                        name.clone(),
                        x.fit.axis.to_string(),
                        model.join(","),
                        format!("{:.2}{fails}", x.fit.fit_error),
                        suggestion,
                        after,
                        note.clone(),
                    ]);
                }
            }
            Err(e) => t.push([name, "-".into(), "-".into(), "-".into(), "-".into(), "-".into(), format!("error: {e}")]),
        }
    }
    t
}
