//! `fdavar`: the offline command-line tool.
//!
//! Thin by design: each subcommand module parses its flags (clap derive, doc comments are the help),
//! validates them into a run configuration, calls the library and returns an [`Outcome`]. This file
//! is the one place that maps outcomes to exit codes.

mod allan;
mod analyze;
mod davar;
mod diagnose;
mod export;
mod fit;
mod fleet;
mod info;
#[cfg(feature = "ros")]
mod play;
mod simulate;

use clap::{Parser, Subcommand};
use fdavar::model::{ModelSpec, SpecError};
use std::process::ExitCode;

/// Exit codes (also listed in `--help`).
const EXIT_OK: u8 = 0;
const EXIT_ERROR: u8 = 1;
const EXIT_USAGE: u8 = 2;
const EXIT_WARNINGS: u8 = 3;

/// How a subcommand finished when it did not fail.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Everything as expected.
    Ok,
    /// Finished, but with warnings already printed (samples left out, a failing model under
    /// `--strict`, …).
    Warnings,
}

/// An error in what the user asked for that only shows once the input is read (e.g. a flag the
/// input does not supply a default for): exit 2 like clap's own usage errors.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// clap value parser of `--model SPEC` and `--model AXIS=SPEC`: an unknown effect or axis is a
/// usage error (exit 2), found before any work starts. Keeps the text, which the subcommand
/// parses again with the others.
pub fn model_spec_arg(s: &str) -> Result<String, SpecError> {
    fdavar::model::spec::axis_models(&[s.to_string()], ModelSpec::DEFAULT).map(|_| s.to_string())
}

/// Adaptive-window dynamic Allan variance (F-DAVAR) of IMU noise, offline.
///
/// Reads rosbag2 recordings (a bag directory, a .mcap or a .db3) or plain text / CSV, computes the
/// Allan variance and the F-DAVAR surface per axis, fits the IMU noise model, and tells which
/// physical effect the model misses.
#[derive(Debug, Parser, PartialEq)]
#[command(
    name = "fdavar",
    version,
    after_help = "Exit codes:\n  \
                  0  ok; also when a model fails to explain the data: the misfit is the finding,\n     \
                  printed as a warning (fit/diagnose --strict make it exit 3, for CI)\n  \
                  1  runtime error (one line on stderr: fdavar: error: ...)\n  \
                  2  usage error (unknown flag or value, e.g. an unknown --model effect, or a\n     \
                  --params value outside its bounds)\n  \
                  3  finished with warnings: samples left out (gaps, duplicate or backward\n     \
                  stamps, NaN/Inf), the warning line on stderr says how many; or --strict and\n     \
                  a model fails (fit_error or span_fit_error > 2)\n\
                  Axes: gyro_x gyro_y gyro_z (rad/s), accel_x accel_y accel_z (m/s^2)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand, PartialEq)]
enum Command {
    Allan(allan::Args),
    Davar(davar::Args),
    Fit(fit::Args),
    Diagnose(diagnose::Args),
    Analyze(analyze::Args),
    Export(export::Args),
    Simulate(simulate::Args),
    #[cfg(feature = "ros")]
    Play(play::Args),
    Info(info::Args),
}

/// One subcommand's flags parsed alone (`argv[0]` is the program name): what each
/// subcommand's tests check its flags with.
#[cfg(test)]
fn parse_args<A: clap::Args + clap::FromArgMatches>(argv: &[&str]) -> Result<A, clap::Error> {
    let mut matches = A::augment_args(clap::Command::new("fdavar")).try_get_matches_from(argv)?;
    A::from_arg_matches_mut(&mut matches)
}

fn main() -> ExitCode {
    fdavar::analysis::reuse_buffers_up_to_4_mb();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { EXIT_USAGE } else { EXIT_OK };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    let result = match &cli.command {
        Command::Allan(a) => allan::run(a),
        Command::Davar(a) => davar::run(a),
        Command::Fit(a) => fit::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Analyze(a) => analyze::run(a),
        Command::Export(a) => export::run(a),
        Command::Simulate(a) => simulate::run(a),
        #[cfg(feature = "ros")]
        Command::Play(a) => play::run(a),
        Command::Info(a) => info::run(a),
    };
    match result {
        Ok(Outcome::Ok) => ExitCode::from(EXIT_OK),
        Ok(Outcome::Warnings) => ExitCode::from(EXIT_WARNINGS),
        Err(e) if is_broken_pipe(&e) => ExitCode::from(EXIT_OK),
        Err(e) if e.chain().any(|c| c.is::<UsageError>()) => {
            eprintln!("fdavar: error: {e:#}");
            ExitCode::from(EXIT_USAGE)
        }
        Err(e) => {
            eprintln!("fdavar: error: {e:#}");
            ExitCode::from(EXIT_ERROR)
        }
    }
}

/// Threads for independent axes: `asked`, or one per CPU.
pub fn jobs(asked: Option<usize>) -> usize {
    asked
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from))
        .max(1)
}

/// A closed stdout (`fdavar … | head`) is not an error.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
