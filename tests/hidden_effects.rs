//! Issue 4, done-when 1: an effect hidden on one axis is named first by the diagnosis of
//! `N,B,K`, fitting it lowers fit_error at least 3×, its parameters come back (amplitudes,
//! coefficients, frequencies within 10 %, time constants within 25 %, times within 1 % of the
//! record), and the other axes get no suggestion.
//!
//! Recordings come from the real simulator (`fdavar::sim::simulate`, seeded, in memory), 100–400 Hz,
//! 20–40 min, laid out as a bag is. The diagnosis never sees the truth; the truth is used only in
//! the checks.

mod model_common;

use fdavar::model::{diagnose, fit, FitOptions, ModelSpec};
use fdavar::signal::Axis;
use model_common::{low_pass_recording, power_on_recording, recording, KINDS};

/// How a parameter is checked against the truth.
#[derive(Clone, Copy)]
enum Tol {
    /// Relative, e.g. 0.10.
    Rel(f64),
    /// Absolute, as a fraction of the record length (times).
    Record(f64),
    /// Exact (a chosen source axis).
    Exact,
}

struct Case {
    effect: &'static str,
    axis: Axis,
    seed: u64,
    rate_hz: f64,
    minutes: f64,
    values: Vec<f64>,
    tol: Vec<Tol>,
    /// True motion of the accel axis the effect reads (g-sensitivity's source), as `vibration`.
    driver: Option<(Axis, &'static str, Vec<f64>)>,
    /// The cut-off of a low-pass every axis's white noise passes (`bandwidth`), if any.
    cutoff_hz: Option<f64>,
}

fn case(effect: &'static str, axis: Axis, seed: u64, rate_hz: f64, minutes: f64, values: &[f64], tol: &[Tol]) -> Case {
    Case {
        effect,
        axis,
        seed,
        rate_hz,
        minutes,
        values: values.to_vec(),
        tol: tol.to_vec(),
        driver: None,
        cutoff_hz: None,
    }
}

/// [`case`] on a sensor with a first-order low-pass of `cutoff_hz` on every axis.
fn low_pass(cutoff_hz: f64, c: Case) -> Case {
    Case { cutoff_hz: Some(cutoff_hz), ..c }
}

fn run(c: &Case) {
    let extra = [(c.axis, (c.effect, c.values.clone()))];
    let motion: Vec<_> = c.driver.iter().map(|(a, id, v)| (*a, (*id, v.clone()))).collect();
    let rec = match c.cutoff_hz {
        Some(cutoff) => low_pass_recording(c.seed, c.rate_hz, c.minutes, cutoff, &extra, &motion),
        None => recording(c.seed, c.rate_hz, c.minutes, &extra, &motion),
    };
    let record_s = c.minutes * 60.0;
    let nbk = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
    let opts = FitOptions::default();
    let label = format!(
        "{} on {} (seed {}, {} Hz, {} min, low-pass {:?} Hz)",
        c.effect, c.axis, c.seed, c.rate_hz, c.minutes, c.cutoff_hz
    );
    // On a low-pass sensor `bandwidth` is named on every axis (the cut-off is checked below):
    // first, and the hidden effect next, weighed with it (`Suggestion::given`); or second, after
    // a line the periodogram shows (a line is named before the smooth shapes, docs/model.md).
    let base = match c.cutoff_hz {
        Some(_) => nbk.with("bandwidth"),
        None => nbk.clone(),
    };

    for axis in Axis::ALL {
        let d = diagnose(&rec.input(axis), &nbk, KINDS, &opts).unwrap();
        let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
        // Every suggestion after the first was weighed with the first added.
        for s in d.suggestions.iter().skip(1) {
            assert_eq!(s.given, [names[0]], "{label}: {axis} {} weighed beside", s.effect);
        }
        let names: Vec<&str> = match c.cutoff_hz {
            Some(cutoff) => {
                let filter = names.iter().position(|n| *n == "bandwidth").filter(|&i| i < 2);
                let filter = filter.unwrap_or_else(|| panic!("{label}: {axis} got {names:?}"));
                let fitted = d.suggestions[filter].params.iter().find(|p| p.name == "cutoff_hz");
                assert!(
                    fitted.is_some_and(|p| (p.value / cutoff - 1.0).abs() <= 0.10),
                    "{label}: {axis} suggestions {names:?}, cut-off {fitted:?}"
                );
                // Before `bandwidth` only the hidden line, on its own axis.
                assert!(filter == 0 || (axis == c.axis && names[0] == c.effect), "{label}: {axis} got {names:?}");
                names.iter().copied().filter(|n| *n != "bandwidth").collect()
            }
            None => names,
        };
        if axis == c.axis {
            if names.first().copied() != Some(c.effect) {
                for p in &d.fit.points {
                    println!("  tau {:9.3} meas {:.3e} model {:.3e} edf {:8.1} z {:6.2}", p.tau, p.measured, p.model, p.edf, p.z);
                }
                for t in &d.fit.terms {
                    println!("  {} {:?}", t.effect, t.params.iter().map(|p| p.value).collect::<Vec<_>>());
                }
            }
            assert_eq!(names.first().copied(), Some(c.effect), "{label}: suggestions {names:?}, fit_error {:.2}", d.fit.fit_error);
            // One hidden effect, one suggestion: what the second round adds beside it is a false
            // alarm (seed 81 got a ×1.07 "noise_burst with quantization" that raised fit_error).
            assert_eq!(names, [c.effect], "{label}: more than the hidden effect suggested");
        } else if c.driver.as_ref().is_some_and(|d| d.0 == axis) {
            // The driver axis really carries motion; what it is called is not this test's concern.
        } else {
            assert!(names.is_empty(), "{label}: {axis} got {names:?} (fit_error {:.2})", d.fit.fit_error);
        }
    }

    let input = rec.input(c.axis);
    // From the model asked for to the one with every suggestion named: on a low-pass sensor that
    // is `bandwidth` and the effect together.
    let before = fit(&input, &nbk, KINDS, &opts).unwrap();
    let after = fit(&input, &base.with(c.effect), KINDS, &opts).unwrap();
    println!(
        "{label}: fit_error {:.2} -> {:.2}, span_fit_error {:.2?} -> {:.2?}",
        before.fit_error, after.fit_error, before.span_fit_error, after.span_fit_error
    );
    // A step, a burst or a warm-up hardly shows in the whole-record Allan variance; it shows in
    // the spans of the record (span_fit_error, model::fit::DEFAULT_SPANS): the misfit, the larger
    // of the two, falls.
    assert!(
        after.misfit() * 3.0 <= before.misfit(),
        "{label}: misfit {:.2} -> {:.2}",
        before.misfit(),
        after.misfit()
    );
    let term = after.term(c.effect).unwrap();
    for ((p, &truth), &tol) in term.params.iter().zip(&c.values).zip(&c.tol) {
        let got = p.value;
        println!("  {} = {got:.4e} (truth {truth:.4e})", p.name);
        let ok = match tol {
            // Signed: a step, a coefficient or a slope fitted with the wrong sign is wrong.
            Tol::Rel(r) => (got - truth).abs() <= r * truth.abs(),
            Tol::Record(f) => (got - truth).abs() <= f * record_s,
            Tol::Exact => got == truth,
        };
        assert!(ok, "{label}: {} = {got:.4e}, truth {truth:.4e}", p.name);
    }
}

const AMP: Tol = Tol::Rel(0.10);
const TC: Tol = Tol::Rel(0.25);
const TIME: Tol = Tol::Record(0.01);

#[test]
fn sinusoid() {
    run(&case("sinusoid", Axis::GyroX, 11, 100.0, 20.0, &[4e-4, 0.1], &[AMP, AMP]));
    run(&case("sinusoid", Axis::GyroZ, 12, 200.0, 20.0, &[6e-4, 0.5], &[AMP, AMP]));
    run(&case("sinusoid", Axis::AccelY, 13, 100.0, 30.0, &[5e-3, 0.2], &[AMP, AMP]));
}

#[test]
fn gauss_markov() {
    run(&case("gauss_markov", Axis::GyroY, 21, 100.0, 30.0, &[3e-4, 3.0], &[AMP, TC]));
    // 600 correlation times, as the other two cases: on fewer, σ and T scatter beyond 10 % and
    // 25 % in a share of records (tests/power_common GM_CORRELATION_TIMES; T = 8 s here gave σ
    // 12 % high at 30 min and T 33 % high at 40 min).
    run(&case("gauss_markov", Axis::GyroZ, 22, 200.0, 40.0, &[3e-4, 4.0], &[AMP, TC]));
    run(&case("gauss_markov", Axis::AccelX, 23, 100.0, 20.0, &[4e-3, 2.0], &[AMP, TC]));
}

#[test]
fn bias_step() {
    run(&case("bias_step", Axis::GyroX, 31, 100.0, 20.0, &[500.0, 2e-3], &[TIME, AMP]));
    run(&case("bias_step", Axis::AccelZ, 32, 100.0, 40.0, &[1800.0, 2e-2], &[TIME, AMP]));
    run(&case("bias_step", Axis::GyroY, 33, 400.0, 20.0, &[300.0, -3e-3], &[TIME, AMP]));
}

#[test]
fn noise_burst() {
    let cases = [
        case("noise_burst", Axis::GyroZ, 41, 100.0, 20.0, &[400.0, 600.0, 4.0], &[TIME, TIME, AMP]),
        case("noise_burst", Axis::AccelX, 42, 100.0, 30.0, &[900.0, 1300.0, 3.0], &[TIME, TIME, AMP]),
        case("noise_burst", Axis::GyroX, 43, 200.0, 20.0, &[200.0, 320.0, 5.0], &[TIME, TIME, AMP]),
    ];
    for c in &cases {
        run(c);
    }
}

#[test]
fn temperature() {
    run(&case("temperature", Axis::GyroX, 51, 100.0, 20.0, &[1e-3], &[AMP]));
    run(&case("temperature", Axis::GyroZ, 52, 200.0, 30.0, &[-1.5e-3], &[AMP]));
    run(&case("temperature", Axis::AccelY, 53, 100.0, 20.0, &[1.5e-2], &[AMP]));
}

/// A warm-up at power-on: the temperature changes most at the start of the record, where the
/// tapered differences of the temperature test see little. 25 K of warm-up times 10⁻⁴ rad/s/K is
/// a drift of 2.5·10⁻³ rad/s, 17 times the gyro's white N, yet N, B, K absorb it (fit_error
/// 1.13–1.37): the block means find it (docs/model.md, "How the diagnosis decides"; before they
/// were weighed, none of these three was named).
#[test]
fn temperature_warm_up_at_power_on() {
    let nbk = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
    for seed in [61, 62, 63] {
        let truth = 1e-4;
        let rec = power_on_recording(seed, 100.0, 30.0, &[(Axis::GyroX, ("temperature", vec![truth]))]);
        for axis in Axis::ALL {
            let d = diagnose(&rec.input(axis), &nbk, KINDS, &FitOptions::default()).unwrap();
            let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
            if axis == Axis::GyroX {
                assert_eq!(names, ["temperature"], "seed {seed}: fit_error {:.2}", d.fit.fit_error);
                let c = d.suggestions[0].params[0].value;
                assert!((c / truth - 1.0).abs() <= 0.10, "seed {seed}: coefficient {c:.4e}, truth {truth:.1e}");
            } else {
                assert!(names.is_empty(), "seed {seed}: {axis} got {names:?} under the same warm-up");
            }
        }
    }
}

/// A line of three periods in the record (a thermal cycle of 400 s in 20 min): its Allan bump
/// sits at τ ≈ 150 s, where the record holds few degrees of freedom, and N, B, K take much of it
/// in (fit_error only about 2); its Fourier bin does not spread. Named by the periodogram's line
/// test (docs/model.md, "How the diagnosis decides"); by the Allan χ² alone none of these three was.
#[test]
fn a_slow_line_of_three_periods() {
    let nbk = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
    let truth = [SLOW_LINE_AMPLITUDE, 3.0 / 1200.0];
    for seed in [81, 82, 83] {
        let rec = recording(seed, 100.0, 20.0, &[(Axis::GyroZ, ("sinusoid", truth.to_vec()))], &[]);
        for axis in Axis::ALL {
            let d = diagnose(&rec.input(axis), &nbk, KINDS, &FitOptions::default()).unwrap();
            let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
            if axis == Axis::GyroZ {
                assert_eq!(names, ["sinusoid"], "seed {seed}: fit_error {:.2}", d.fit.fit_error);
                for (p, t) in d.suggestions[0].params.iter().zip(truth) {
                    assert!((p.value / t - 1.0).abs() <= 0.10, "seed {seed}: {} {:.4e}, truth {t:.4e}", p.name, p.value);
                }
            } else {
                assert!(names.is_empty(), "seed {seed}: {axis} got {names:?}");
            }
        }
    }
}

/// The slow line's amplitude, rad/s: 2.7 times the gyro's white N·√(rate) per sample, about 8
/// times the noise of its 10 s means.
const SLOW_LINE_AMPLITUDE: f64 = 4e-4;

#[test]
fn g_sensitivity() {
    let motion = |axis, f: f64| Some((axis, "sinusoid", vec![0.5, f]));
    let mut cases = [
        case("g_sensitivity", Axis::GyroX, 61, 100.0, 20.0, &[0.0, 1e-3], &[Tol::Exact, AMP]),
        case("g_sensitivity", Axis::GyroY, 62, 200.0, 20.0, &[2.0, -1.5e-3], &[Tol::Exact, AMP]),
        case("g_sensitivity", Axis::GyroZ, 63, 100.0, 30.0, &[1.0, 2e-3], &[Tol::Exact, AMP]),
    ];
    cases[0].driver = motion(Axis::AccelX, 0.2);
    cases[1].driver = motion(Axis::AccelZ, 0.05);
    cases[2].driver = motion(Axis::AccelY, 0.5);
    for c in &cases {
        run(c);
    }
}

#[test]
fn ramp() {
    run(&case("ramp", Axis::GyroY, 71, 100.0, 20.0, &[1e-5], &[AMP]));
    run(&case("ramp", Axis::GyroZ, 72, 200.0, 30.0, &[5e-6], &[AMP]));
    run(&case("ramp", Axis::AccelX, 73, 100.0, 20.0, &[2e-4], &[AMP]));
}

#[test]
fn quantization() {
    run(&case("quantization", Axis::GyroX, 81, 100.0, 20.0, &[3e-5], &[AMP]));
    run(&case("quantization", Axis::GyroZ, 82, 400.0, 20.0, &[2e-5], &[AMP]));
    run(&case("quantization", Axis::AccelZ, 83, 200.0, 20.0, &[2e-4], &[AMP]));
}

/// The hidden effects on a sensor with a 30 Hz low-pass at 100 Hz (the ADIS16405 and most MEMS
/// parts filter their output): the N,B,K misfit near τ0 is explained by `bandwidth`, and the
/// effect, which N,B,K's misfit everywhere hid, is named next, weighed with it. The clean axes
/// get `bandwidth` alone: no alternative of the same misfit (a Gauss–Markov process of T ≈ τ0, a
/// line near 2 Hz: both were suggested on every axis before `diagnose` weighed again with the best).
/// No noise burst: the simulator's burst scales `white`, which such a sensor does not have.
#[test]
fn effects_on_a_low_pass_sensor() {
    let cases = [
        case("sinusoid", Axis::GyroX, 111, 100.0, 20.0, &[4e-4, 0.1], &[AMP, AMP]),
        case("gauss_markov", Axis::GyroY, 121, 100.0, 30.0, &[3e-4, 3.0], &[AMP, TC]),
        case("bias_step", Axis::AccelZ, 132, 100.0, 40.0, &[1800.0, 2e-2], &[TIME, AMP]),
        case("temperature", Axis::GyroZ, 152, 100.0, 30.0, &[-1.5e-3], &[AMP]),
        case("ramp", Axis::GyroY, 171, 100.0, 20.0, &[1e-5], &[AMP]),
    ];
    for c in cases {
        run(&low_pass(30.0, c));
    }
}
