//! `fdavar allan FILE --rate HZ`: the Allan deviation of a whole record, Stable32-style.

use crate::Outcome;
use anyhow::{bail, Context};
use fdavar::allan::{self, edf, Estimate, Estimator, TauGrid};
use fdavar::signal::text::{self, ColumnSelector};
use std::io::Write;
use std::path::PathBuf;

/// Allan deviation (OADEV, ADEV, MDEV or HDEV) of a text or CSV series, with confidence bounds.
///
/// Prints a table like Stable32's: AF (averaging factor m), Tau (s), # (terms), Alpha (identified
/// noise type, S_y ∝ f^α), Min Sigma, Sigma, Max Sigma (the deviation and its confidence bounds).
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// Data file: one value per line (`#` comments and blank lines ignored) or CSV (see --column).
    pub file: PathBuf,
    /// Sampling rate in Hz (τ0 = 1/rate seconds); must be positive.
    #[arg(long, value_name = "HZ")]
    pub rate: f64,
    /// The values are phase (angle, velocity, time error: the integral of a rate).
    #[arg(long, conflicts_with = "frequency")]
    pub phase: bool,
    /// The values are frequency / rate data (gyro rad/s, accel m/s²). This is the default.
    #[arg(long)]
    pub frequency: bool,
    /// Averaging factors: all, octave, decade (1, 2, 4, 10, 20, …) or N per decade.
    #[arg(long, default_value_t = TauGrid::default(), value_name = "all|octave|decade|N")]
    pub taus: TauGrid,
    /// Estimator: oadev (overlapping Allan), adev (non-overlapping), mdev (modified), hdev (Hadamard).
    #[arg(long, default_value_t = Estimator::Oadev, value_name = "NAME")]
    pub estimator: Estimator,
    /// Two-sided confidence level of the bounds, a fraction (default one sigma, 0.6827).
    #[arg(long, default_value_t = edf::ONE_SIGMA, value_name = "P")]
    pub confidence: f64,
    /// CSV column to read, by zero-based index or header name (default: one value per line).
    #[arg(long, value_name = "N|NAME")]
    pub column: Option<ColumnSelector>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// What the flags ask for, validated before any work.
struct RunConfig {
    tau0: f64,
    phase: Vec<f64>,
    factors: Vec<usize>,
}

fn configure(args: &Args) -> anyhow::Result<RunConfig> {
    if !(args.rate.is_finite() && args.rate > 0.0) {
        bail!("--rate must be a positive number of Hz, got {}", args.rate);
    }
    if !(args.confidence > 0.0 && args.confidence < 1.0) {
        bail!(
            "--confidence must be a fraction strictly between 0 and 1, got {}",
            args.confidence
        );
    }
    let tau0 = 1.0 / args.rate;
    let values = text::read_column(&args.file, args.column.as_ref())
        .with_context(|| format!("reading {}", args.file.display()))?;
    if values.is_empty() {
        // Said here: as rate data, no values would pass on as one phase point (the zero start).
        bail!("{} holds no values (one number per line, '#' comments)", args.file.display());
    }
    let phase = if args.phase {
        values
    } else {
        allan::naive::phase_from_rate(&values, tau0)
    };
    let factors = args.taus.factors(args.estimator.max_factor(phase.len()));
    Ok(RunConfig {
        tau0,
        phase,
        factors,
    })
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let cfg = configure(args)?;
    let estimates = allan::estimate(
        args.estimator,
        &cfg.phase,
        cfg.tau0,
        &cfg.factors,
        args.confidence,
    )
    .with_context(|| format!("{} of {}", args.estimator, args.file.display()))?;
    let kind = if args.phase { "phase" } else { "frequency" };
    let mut out = std::io::stdout().lock();
    if args.json {
        let json = serde_json::json!({
            "estimator": args.estimator.name(),
            "tau0": cfg.tau0,
            "data": kind,
            "confidence": args.confidence,
            "points": estimates.iter().map(point_json).collect::<Vec<_>>(),
        });
        writeln!(out, "{json}")?;
    } else {
        write_table(&mut out, args, kind, cfg.tau0, cfg.phase.len(), &estimates)?;
    }
    out.flush()?;
    Ok(Outcome::Ok)
}

fn point_json(e: &Estimate) -> serde_json::Value {
    let p = &e.point;
    serde_json::json!({
        "m": p.m, "tau": p.tau, "dev": p.adev(), "avar": p.avar, "terms": p.terms, "edf": p.edf,
        "alpha": e.alpha, "ci_low": p.ci_low.sqrt(), "ci_high": p.ci_high.sqrt(),
    })
}

fn write_table(
    out: &mut impl Write,
    args: &Args,
    kind: &str,
    tau0: f64,
    points: usize,
    estimates: &[Estimate],
) -> std::io::Result<()> {
    writeln!(out, "# STATISTICS FOR FILE: {}", args.file.display())?;
    writeln!(
        out,
        "# {points} phase points, tau0 = {} s, input: {kind}",
        sci(tau0)
    )?;
    writeln!(out, "# Sigma Type: {}", args.estimator.long_name())?;
    writeln!(out, "# Confidence Factor = {:.3}", args.confidence)?;
    writeln!(
        out,
        "#  AF        Tau        #    Alpha  Min Sigma      Sigma         Max Sigma"
    )?;
    for e in estimates {
        let p = &e.point;
        let alpha = e.alpha.map_or_else(|| "-".to_string(), |a| a.to_string());
        writeln!(
            out,
            "{:>5}   {}   {:>6}   {:>2}   {}    {}     {}",
            p.m,
            sci(p.tau),
            p.terms,
            alpha,
            sci(p.ci_low.sqrt()),
            sci(p.adev()),
            sci(p.ci_high.sqrt())
        )?;
    }
    Ok(())
}

/// Stable32's number format: four decimals and a signed two-digit exponent, e.g. `2.9223e-01`.
fn sci(v: f64) -> String {
    let s = format!("{v:.4e}");
    match s.split_once('e') {
        Some((mantissa, exp)) => match exp.parse::<i32>() {
            Ok(e) => format!("{mantissa}e{}{:02}", if e < 0 { '-' } else { '+' }, e.abs()),
            Err(_) => s,
        },
        None => s, // NaN, inf
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse_args;

    #[test]
    fn numbers_print_like_stable32() {
        assert_eq!(sci(0.29223), "2.9223e-01");
        assert_eq!(sci(1000.0), "1.0000e+03");
        assert_eq!(sci(3.3171e-10), "3.3171e-10");
        assert_eq!(sci(f64::NAN), "NaN");
    }

    #[test]
    fn defaults_and_flags_parse() {
        let a = parse_args::<Args>(&["x", "f.txt", "--rate", "100"]).unwrap();
        assert_eq!(
            (a.estimator, a.taus, a.phase, a.json),
            (Estimator::Oadev, TauGrid::PerDecade(10), false, false)
        );
        let a = parse_args::<Args>(&[
            "x",
            "f",
            "--rate",
            "1",
            "--phase",
            "--taus",
            "all",
            "--estimator",
            "hdev",
            "--column",
            "gyro_x",
        ]).unwrap();
        assert_eq!(
            (a.estimator, a.taus, a.column),
            (
                Estimator::Hdev,
                TauGrid::All,
                Some(ColumnSelector::Name("gyro_x".into()))
            )
        );
        assert!(parse_args::<Args>(&["x", "f", "--rate", "1", "--phase", "--frequency"]).is_err());
        assert!(parse_args::<Args>(&["x", "f", "--rate", "1", "--estimator", "tdev"]).is_err());
    }
}
