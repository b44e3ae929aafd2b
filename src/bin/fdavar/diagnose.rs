//! `fdavar diagnose BAG [--model SPEC] [--topic T] [--axis A]... [--json] [--out DIR] [--mcap OUT]`: which
//! physical effect the noise model misses, per axis, best first. Several recordings (or a
//! directory of them): one summary table ([`crate::fleet`]).

use crate::fit::{load, outcome, print_json, title, write_files, write_fit, Common, ResultsOut, Source, FAILING_FIT_ERROR};
use crate::Outcome;
use anyhow::Context;
use fdavar::analysis::Analysis;
use fdavar::model::output::{comparison_figure, AxisReport, Report};
use fdavar::model::{Diagnosis, ModelSpec};
use fdavar::report::fit::write_suggestions;
use fdavar::signal::Axis;
use fdavar::results::WholeRun;
use std::path::{Path, PathBuf};

/// Tell which physical effect the noise model misses on each axis.
///
/// Fits the model, refits with each effect of the vocabulary it lacks (time-domain effects only
/// with their evidence: a temperature topic, the accel axes, a noise change) and suggests the
/// gains that pay for their extra parameters, best first, with the fitted parameters and a
/// sentence of physics. A model that already explains the data gets no suggestion but by chance:
/// the tests are calibrated so that at most 2 % of clean axes get one (measured: well under 1 %).
/// A failing model (fit_error or span_fit_error > 2) is the finding: a warning, exit 0 (exit 3 with --strict);
/// samples left out (gaps, bad stamps, NaN/Inf) exit 3.
///
/// Several recordings (a fleet of robots' bags: `fdavar diagnose a.mcap b.mcap …`, or a directory
/// whose subdirectories are bag directories): each diagnosed as alone, --jobs at a time, and one
/// table of every axis (model, fit_error, the best suggestion); --json prints
/// {"recordings": [{"bag", "axes"}, …]}. An unreadable recording is a row with its error, and the
/// exit is 1 once the others are done.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// rosbag2 recording(s): bag directories, .mcap or .db3 files, or directories of them.
    #[arg(required = true, num_args = 1.., value_name = "BAG")]
    pub bags: Vec<PathBuf>,
    /// Model to start from: comma-separated effect ids or aliases for every axis, or AXIS=SPEC for
    /// one axis (repeatable; later values win). Default N,B,K.
    #[arg(long, default_value = ModelSpec::DEFAULT, value_parser = crate::model_spec_arg)]
    pub model: Vec<String>,
    #[command(flatten)]
    pub common: Common,
    /// Threads (default: the number of CPUs), at least 1: with several recordings, recordings in
    /// parallel (each one's record in memory at once); with one, its axes.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub jobs: Option<u16>,
}

/// The diagnosis of each axis of `axes`, on up to `jobs` threads (the same answers as one by one).
pub fn diagnose_all(analysis: &mut Analysis, axes: &[Axis], jobs: usize) -> anyhow::Result<Vec<Diagnosis>> {
    axes.iter()
        .zip(analysis.diagnose_axes(axes, jobs))
        .map(|(axis, d)| d.with_context(|| format!("cannot diagnose {axis}")))
        .collect()
}

/// The readable table of one diagnosed axis: its fit, then the suggestions.
pub fn write_diagnosis(out: &mut dyn std::io::Write, d: &Diagnosis) -> std::io::Result<()> {
    write_fit(out, &d.fit, FAILING_FIT_ERROR)?;
    write_suggestions(out, d)
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let jobs = crate::jobs(args.jobs.map(usize::from));
    let bags = crate::fleet::recordings(&args.bags)?;
    let [bag] = &bags[..] else {
        return crate::fleet::run(args, &bags, jobs);
    };
    let mut results = ResultsOut::create(&args.common)?;
    let mut analysis = load(&Source::of(bag, &args.model, &args.common), results.as_mut())?;
    let diagnoses = diagnose_all(&mut analysis, &args.common.selection.axes(), jobs)?;
    if let Some(results) = results {
        let (messages, until_s) = (analysis.messages(), analysis.duration_s().unwrap_or(0.0));
        let answers = diagnoses.iter().map(|d| (d.fit.axis, WholeRun::from_diagnosis(d, messages, until_s)));
        results.finish(answers)?;
    }
    if args.common.json {
        let report = Report {
            axes: diagnoses.iter().map(AxisReport::from_diagnosis).collect(),
        };
        print_json(&report)?;
    } else {
        let mut out = std::io::stdout().lock();
        for d in &diagnoses {
            write_diagnosis(&mut out, d).context("writing output")?;
        }
    }
    write_diagnosis_files(args.common.out.as_deref(), args.common.csv.as_deref(), bag, &diagnoses)?;
    let fits: Vec<_> = diagnoses.into_iter().map(|d| d.fit).collect();
    Ok(outcome(&analysis, &fits, args.common.strict, "the suggestions per axis name what would explain it"))
}

/// `--out DIR` and `--csv DIR` of a diagnosis (also `fdavar analyze`'s): per axis the Allan
/// figure and CSVs of the fit ([`write_files`]), and one before/after figure per suggestion,
/// `suggestion_<axis>_<effect>`, each from the model of the one before: the error falling step by
/// step, as the rounds added them.
pub fn write_diagnosis_files(
    out: Option<&Path>,
    csv: Option<&Path>,
    bag: &Path,
    diagnoses: &[Diagnosis],
) -> anyhow::Result<()> {
    write_files(out, csv, bag, diagnoses.iter().map(|d| &d.fit))?;
    let Some(dir) = out else { return Ok(()) };
    let name = title(bag);
    for d in diagnoses {
        let axis = d.fit.axis;
        let befores = std::iter::once(&d.fit).chain(&d.after);
        for ((s, after), before) in d.suggestions.iter().zip(&d.after).zip(befores) {
            let stem = dir.join(format!("suggestion_{axis}_{}", s.effect));
            fdavar::report::figure::write_allan_comparison(&comparison_figure(before, after, &name), &stem)
                .with_context(|| format!("cannot write the before/after figure of {axis} with {}", s.effect))?;
        }
    }
    Ok(())
}
