//! The undithered quantization signature (`Quantization::avar_undithered`) against the real
//! simulator: a Monte Carlo check of the formula before the fitter relies on it.
//!
//! Each recording (`fdavar::sim`, seeded, 100 Hz, 10 min) carries white rate noise N plus angle
//! quantization q on six axes, at dither levels r = N·√τ0/δ from 0.05 to 1 step per sample (δ =
//! q·√12 the angle step), and on `accel_z` with gravity, whose mean sweeps the angle through ~70
//! steps per sample. The measured overlapping AVAR at m = 1…128 is compared with
//! N²/τ + σ²_Q,undithered(τ), where the angle noise is exactly D(τ) = N²·τ and the mean rate is the
//! sample mean (what the fitter uses).
//!
//! Tolerance: the rounding error of an undithered quantizer is correlated over many samples, so no
//! closed-form EDF applies; the statistical error is measured instead, from the scatter of the
//! ratio measured/formula over independent seeds. The mean ratio must lie within 4 standard errors
//! of 1 (plus 0.5 % for the uniform-phase assumption, which a finite record only approaches). The
//! IEEE law 3q²/τ² is printed alongside and must fail the same check at m = 1 for r ≤ 0.2 (the test
//! can fail).
//!
//! `fit_recovers_quantization_in_both_regimes` then runs the whole workbench (diagnose `N,B,K`, fit
//! `N,B,K,Q`) on recordings outside the hidden-effect suite: a deeply undithered gyro (0.04 step of
//! white angle noise per sample) and `accel_z` with gravity (a sweep of 71 and 28 steps per sample).

mod model_common;

use fdavar::allan::oavar_rate;
use fdavar::model::effects::{Effect, Quantization};
use fdavar::signal::Axis;
use std::fmt::Write;

const RATE_HZ: f64 = 100.0;
const MINUTES: f64 = 10.0;
const SEEDS: u64 = 6;
const Q: f64 = 3e-5;
const FACTORS: [usize; 8] = [1, 2, 4, 8, 16, 32, 64, 128];

/// Dither r (steps of angle noise per sample) on each axis, in `Axis::ALL` order.
const DITHER: [f64; 6] = [0.05, 0.1, 0.2, 0.5, 1.0, 0.2];

fn white_n(r: f64) -> f64 {
    let (dt, step) = (1.0 / RATE_HZ, Q * 12f64.sqrt());
    r * step / dt.sqrt()
}

fn spec(seed: u64) -> String {
    let mut y = String::new();
    writeln!(y, "rate_hz: {RATE_HZ}\nduration_s: {}\nseed: {seed}\ngravity: true\naxes:", MINUTES * 60.0).unwrap();
    for (axis, r) in Axis::ALL.iter().zip(DITHER) {
        writeln!(y, "  {}:\n    white: {{ n: {:e} }}\n    quantization: {{ q: {Q:e} }}", axis.name(), white_n(r)).unwrap();
    }
    y
}

#[test]
fn undithered_signature_matches_the_simulator_across_dither_levels() {
    let dt = 1.0 / RATE_HZ;
    let quant = Quantization::new(Q).unwrap();
    // ratios[axis][factor] over seeds: measured / undithered formula, and measured / IEEE law.
    let mut ours = vec![vec![Vec::new(); FACTORS.len()]; 6];
    let mut ieee = vec![vec![Vec::new(); FACTORS.len()]; 6];
    for seed in 0..SEEDS {
        let spec = fdavar::sim::SimSpec::from_yaml(&spec(100 + seed)).unwrap();
        let rec = fdavar::sim::simulate(&spec).unwrap();
        for (a, axis) in Axis::ALL.iter().enumerate() {
            let y = rec.axis(*axis);
            let mean = y.iter().sum::<f64>() / y.len() as f64;
            let n = white_n(DITHER[a]);
            let noise = move |tau: f64| n * n * tau;
            for (i, p) in oavar_rate(&y, dt, &FACTORS).iter().enumerate() {
                let white = n * n / p.tau;
                ours[a][i].push(p.avar / (white + quant.avar_undithered(p.tau, mean, &noise)));
                ieee[a][i].push(p.avar / (white + quant.avar(p.tau).unwrap()));
            }
        }
    }
    let stats = |v: &[f64]| {
        let k = v.len() as f64;
        let mean = v.iter().sum::<f64>() / k;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (k - 1.0)).sqrt();
        (mean, sd / k.sqrt())
    };
    let mut failures = Vec::new();
    for (a, axis) in Axis::ALL.iter().enumerate() {
        for (i, m) in FACTORS.iter().enumerate() {
            let (mo, so) = stats(&ours[a][i]);
            let (mi, si) = stats(&ieee[a][i]);
            println!(
                "{:8} r {:4.2} m {:4}: measured/undithered {:.4} ± {:.4}   measured/IEEE {:.4} ± {:.4}",
                axis.name(),
                DITHER[a],
                m,
                mo,
                so,
                mi,
                si
            );
            if (mo - 1.0).abs() > 4.0 * so + 0.005 {
                failures.push(format!("{} r {} m {m}: {mo:.4} ± {so:.4}", axis.name(), DITHER[a]));
            }
            if *m == 1 && DITHER[a] <= 0.2 {
                assert!(
                    (mi - 1.0).abs() > 4.0 * si + 0.005,
                    "{} r {}: the IEEE law fits too ({mi:.4}): this check cannot tell the formulas apart",
                    axis.name(),
                    DITHER[a]
                );
            }
        }
    }
    assert!(failures.is_empty(), "undithered formula off: {failures:#?}");
}

/// One recording of the workbench check: N, B, K on six axes (tests/model_common), q on `axis`.
fn workbench(seed: u64, rate_hz: f64, minutes: f64, axis: Axis, q: f64, gravity: bool) {
    use fdavar::model::{diagnose, fit, FitOptions, ModelSpec};
    use model_common::KINDS;
    let mut yaml = model_common::spec_yaml(seed, rate_hz, minutes, &[(axis, ("quantization", vec![q]))], &[]);
    if gravity {
        yaml = yaml.replacen("axes:", "gravity: true\naxes:", 1);
    }
    let sim = fdavar::sim::simulate(&fdavar::sim::SimSpec::from_yaml(&yaml).unwrap()).unwrap();
    let rec = model_common::Recording::from_samples(&sim.imu, &sim.temperature).unwrap();
    let nbk = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
    let opts = FitOptions::default();
    let label = format!("q {q:e} on {axis} (seed {seed}, {rate_hz} Hz, {minutes} min, gravity {gravity})");
    for a in Axis::ALL {
        let d = diagnose(&rec.input(a), &nbk, KINDS, &opts).unwrap();
        let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
        if a == axis {
            assert_eq!(names.first().copied(), Some("quantization"), "{label}: {names:?}");
        } else {
            assert!(names.is_empty(), "{label}: {a} got {names:?}");
        }
    }
    let before = fit(&rec.input(axis), &nbk, KINDS, &opts).unwrap();
    let after = fit(&rec.input(axis), &nbk.with("quantization"), KINDS, &opts).unwrap();
    let got = after.term("quantization").unwrap().params[0].value;
    println!("{label}: fit_error {:.2} -> {:.2}, q = {got:.4e}", before.fit_error, after.fit_error);
    assert!(after.fit_error * 3.0 <= before.fit_error, "{label}: fit_error {:.2} -> {:.2}", before.fit_error, after.fit_error);
    assert!((got / q - 1.0).abs() <= 0.10, "{label}: q = {got:.4e}");
}

#[test]
fn fit_recovers_quantization_in_both_regimes() {
    workbench(92, 100.0, 20.0, Axis::GyroX, 1e-4, false);
    workbench(95, 200.0, 20.0, Axis::AccelZ, 2e-4, true);
    workbench(96, 100.0, 20.0, Axis::AccelZ, 1e-3, true);
}

#[test]
fn clean_recording_with_gravity_gets_no_quantization() {
    // The mean sweep of accel_z must not let the undithered signature explain noise patterns.
    use fdavar::model::{diagnose, FitOptions, ModelSpec};
    use model_common::KINDS;
    for seed in [98, 99] {
        let yaml = model_common::spec_yaml(seed, 200.0, 20.0, &[], &[]).replacen("axes:", "gravity: true\naxes:", 1);
        let sim = fdavar::sim::simulate(&fdavar::sim::SimSpec::from_yaml(&yaml).unwrap()).unwrap();
        let rec = model_common::Recording::from_samples(&sim.imu, &sim.temperature).unwrap();
        let nbk = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
        for a in Axis::ALL {
            let d = diagnose(&rec.input(a), &nbk, KINDS, &FitOptions::default()).unwrap();
            let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
            assert!(names.is_empty(), "seed {seed}: {a} got {names:?} (fit_error {:.2})", d.fit.fit_error);
        }
    }
}
