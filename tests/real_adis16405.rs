//! The workbench on a real sensor: the ADIS16405 static recording of `../shared/reference/real/`
//! (read from there, never copied into the repository: CC BY-NC-SA; the test skips, saying so,
//! when it is absent).
//!
//! The first hour (360 000 samples at 100 Hz) of each axis, converted from deg/s to rad/s and g to
//! m/s²; the gyro test also reads the rest of the recording (the second hour and the last 2 800 s),
//! which none of the thresholds was studied on.
//! What it checks (issue 10, Done 2, the part that holds today; gyro_z below): on gyro_x and gyro_y the diagnosis
//! of N,B,K names the sensor's low-pass (`bandwidth`) first in each of the three parts of the
//! recording, the model with it fits with
//! fit_error ≤ 2, its ARW is near the data sheet's (about 2 °/√h: accepted 1.5–3 °/√h) and its
//! cut-off near the 68 Hz of the sensor's default digital filter ([`CUTOFF_HZ`]); where z is
//! green (|z| ≤ 3) the model lies inside the 1σ band of the point (whose
//! width is the model's own √(2/EDF), so |z| ≤ 1 there would be the same test: checked as the
//! share of green points within 1σ, at least 60 % — about 68 % for a model that follows the data;
//! asserted on the first hour, measured 45–96 % over all six gyro parts).

use fdavar::model::diagnose::diagnose;
use fdavar::model::effects::REGISTRY;
use fdavar::model::fit::{fit, AxisInput, FitOptions, FittedModel};
use fdavar::model::spec::ModelSpec;
use fdavar::signal::Axis;
use std::io::{BufRead, BufReader};
use std::path::PathBuf;

const RATE_HZ: f64 = 100.0;
const SAMPLES: usize = 360_000;
/// Rows of the whole recording (10 000 s).
const ALL: usize = 1_000_000;
/// The low-pass cut-offs accepted: 68 Hz ± 25 %. 68 Hz is the −3 dB frequency of the ADIS16405's
/// default digital filter (a Bartlett window of 2^M taps at the internal 819.2 samples/s, M = 2:
/// 819.2/12 Hz, as the Linux IIO driver drivers/iio/imu/adis16400.c computes it); the recording's
/// filter setting is not documented, and every part and axis measured 59–70 Hz (docs/model.md,
/// "On the ADIS16405"). The cut-off search itself reaches 2/τmin = 200 Hz, so a range up to the
/// 330 Hz analog bandwidth (as before) could not fail from above.
const CUTOFF_HZ: std::ops::RangeInclusive<f64> = 51.0..=85.0;

/// The recording, or None after saying the test skips.
fn recording() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/reference/real/adis16405_static_run1.csv.gz");
    if !p.exists() {
        // Through the stderr handle, not println!: the test harness captures the print macros,
        // and a skip that nobody sees reads as a pass.
        use std::io::Write;
        let _ = writeln!(std::io::stderr(), "real_adis16405: skipped: {} is absent", p.display());
    }
    p.exists().then_some(p)
}

/// The six columns of the first `rows` rows: gyro in rad/s, accel in m/s².
fn read(path: &PathBuf, rows: usize) -> [Vec<f64>; 6] {
    let file = std::fs::File::open(path).expect("open recording");
    let reader = BufReader::new(flate2::read::GzDecoder::new(file));
    let mut cols: [Vec<f64>; 6] = Default::default();
    for line in reader.lines().map(|l| l.expect("read line")) {
        if line.starts_with('#') || line.starts_with("index") {
            continue;
        }
        let v: Vec<f64> = line.split(',').map(|f| f.parse().expect("number")).collect();
        for (i, col) in cols.iter_mut().enumerate() {
            let scale = if i < 3 { std::f64::consts::PI / 180.0 } else { 9.80665 };
            col.push(v[1 + i] * scale);
        }
        if cols[0].len() == rows {
            break;
        }
    }
    cols
}

/// All the recording's rows (every column checked to hold them), or None after saying the test
/// skips.
fn whole_recording() -> Option<[Vec<f64>; 6]> {
    let cols = read(&recording()?, ALL);
    assert!(cols.iter().all(|c| c.len() == ALL), "rows of the recording");
    Some(cols)
}

/// The accel axes of the recording's columns, with their names.
fn accel_axes(cols: &[Vec<f64>; 6]) -> [(Axis, &[f64]); 3] {
    [(Axis::AccelX, &cols[3][..]), (Axis::AccelY, &cols[4][..]), (Axis::AccelZ, &cols[5][..])]
}

/// The accelerometers' data sheet noise density, 0.5 mg/√Hz in m/s²/√Hz (imu_noise_params.md).
const DATASHEET_N: f64 = 0.5e-3 * 9.80665;

fn input(axis: Axis, rate: &[f64]) -> AxisInput<'_> {
    AxisInput { axis, tau0: 1.0 / RATE_HZ, rate, temperature_c: None, accel: None, events: &[] }
}

fn arw_deg_per_sqrt_h(n: f64) -> f64 {
    n.to_degrees() * 60.0
}

fn green_within_one_sigma(f: &FittedModel) -> f64 {
    let green: Vec<_> = f.points.iter().filter(|p| p.z.abs() <= 3.0).collect();
    green.iter().filter(|p| p.z.abs() <= 1.0).count() as f64 / green.len().max(1) as f64
}

#[test]
fn adis16405_gyro_is_white_noise_through_its_low_pass() {
    let Some(cols) = whole_recording() else { return };
    let opts = FitOptions::default();
    let base = ModelSpec::parse("N,B,K").unwrap();
    let spec = ModelSpec::parse("B,K,bandwidth").unwrap();
    // The first hour, on which the diagnosis was studied, then the second and the last 2 800 s:
    // the same sensor, data nobody tuned for.
    for part in [0..SAMPLES, SAMPLES..2 * SAMPLES, 2 * SAMPLES..ALL] {
        for (axis, col) in [(Axis::GyroX, &cols[0]), (Axis::GyroY, &cols[1])] {
            let rate = &col[part.clone()];
            let what = format!("{} over {}-{} s", axis.name(), part.start / 100, part.end / 100);
            let d = diagnose(&input(axis, rate), &base, REGISTRY, &opts).unwrap();
            let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
            println!("{what}: N,B,K fit_error {:.2}, suggestions {names:?}", d.fit.misfit());
            assert_eq!(names.first(), Some(&"bandwidth"), "{what}");
            let f = fit(&input(axis, rate), &spec, REGISTRY, &opts).unwrap();
            let bw = f.term("bandwidth").unwrap();
            let arw = arw_deg_per_sqrt_h(bw.param("n").unwrap().value);
            let fc = bw.param("cutoff_hz").unwrap().value;
            let share = green_within_one_sigma(&f);
            println!(
                "{what}: B,K,bandwidth fit_error {:.2} (whole record {:.2}), ARW {arw:.2} deg/sqrt(h), \
                 cut-off {fc:.1} Hz, green points within 1 sigma {:.0} %",
                f.misfit(),
                f.fit_error,
                100.0 * share
            );
            assert!(f.misfit() <= 2.0, "{what}: fit_error {}", f.misfit());
            assert!((1.5..=3.0).contains(&arw), "{what}: ARW {arw}");
            assert!(CUTOFF_HZ.contains(&fc), "{what}: cut-off {fc}");
            // The share within 1σ is asserted on the first hour only: neighbouring τ points of one
            // record are strongly correlated, so their z move together and the share of one record
            // scatters widely even for a right model (45–96 % over these six parts, 2026-11-26).
            if part.start == 0 {
                assert!(share >= 0.6, "{what}: {share}");
            }
        }
    }
}

/// gyro_z has a vibration line near 21 Hz on top of the low-pass: with it the model fits (1.98,
/// measured; the line is a narrow band, not one sinusoid, which is why it is not lower).
#[test]
fn adis16405_gyro_z_is_the_low_pass_and_a_21_hz_line() {
    let Some(path) = recording() else { return };
    let cols = read(&path, SAMPLES);
    let spec = ModelSpec::parse("B,K,bandwidth,sinusoid").unwrap();
    let f = fit(&input(Axis::GyroZ, &cols[2]), &spec, REGISTRY, &FitOptions::default()).unwrap();
    let bw = f.term("bandwidth").unwrap();
    let arw = arw_deg_per_sqrt_h(bw.param("n").unwrap().value);
    let fc = bw.param("cutoff_hz").unwrap().value;
    let line = f.term("sinusoid").unwrap().param("frequency_hz").unwrap().value;
    println!("gyro_z: fit_error {:.2}, ARW {arw:.2} deg/sqrt(h), cut-off {fc:.1} Hz, line {line:.2} Hz", f.misfit());
    assert!(f.misfit() <= 2.0, "fit_error {}", f.misfit());
    assert!((1.5..=3.0).contains(&arw), "ARW {arw}");
    assert!(CUTOFF_HZ.contains(&fc), "cut-off {fc}");
    assert!((20.0..=22.0).contains(&line), "line {line}");
}

/// The accel axes (issue 10, Done 2 — the part that holds; see docs/model.md, "On the ADIS16405"):
/// the diagnosis of N,B,K names both the low-pass (`bandwidth`) and the 0.56 Hz vibration line
/// (`sinusoid`) on every axis, and the model B,K,bandwidth,sinusoid has physical parameters — noise
/// density within a factor 2 of the data sheet's 0.5 mg/√Hz (4.9e-3 m/s²/√Hz:
/// ../shared/reference/imu_noise_params.md, "datasheet, approximate"; the README's ADEV of
/// 0.5–0.7 mg at 1 s says the same), cut-off near the default filter's 68 Hz ([`CUTOFF_HZ`]), the
/// line at 0.50–0.65 Hz — and lowers fit_error at least 3× on every axis. The whole-record Allan variance
/// of accel_z fits (whole-record fit_error ≤ 2, green points within 1σ ≥ 60 %: measured 1.51, 76 %;
/// on accel_x/y 45 % and 57 %); fit_error ≤ 2 itself does NOT hold on any accel axis
/// (measured 5.93, 7.36, 3.44): the span check fails because the record is not stationary at the
/// level the large EDF of 100 Hz samples resolves (the 0.56 Hz line's power varies by ±15–20 %
/// between 450 s spans — a resonance driven by ambient vibration has a random amplitude, which one
/// sinusoid of fixed amplitude does not describe; accel_y's white level is 15 % lower in the first
/// half hour than in the second), and accel_x/y carry a second line near 10 Hz (z of +25 / −13 at
/// 0.03–0.1 s), which `vibration` adds (the next test, with what fails after it).
#[test]
fn adis16405_accel_is_the_low_pass_and_a_0_56_hz_line() {
    let Some(path) = recording() else { return };
    let cols = read(&path, SAMPLES);
    let opts = FitOptions::default();
    let base = ModelSpec::parse("N,B,K").unwrap();
    let spec = ModelSpec::parse("B,K,bandwidth,sinusoid").unwrap();
    for (axis, rate) in accel_axes(&cols) {
        let d = diagnose(&input(axis, rate), &base, REGISTRY, &opts).unwrap();
        let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
        println!("{}: N,B,K fit_error {:.2}, suggestions {names:?}", axis.name(), d.fit.misfit());
        assert!(names.contains(&"bandwidth") && names.contains(&"sinusoid"), "{}: {names:?}", axis.name());
        // A second line is weighed only beside a first (`EffectKind::follows`): never from N,B,K.
        assert!(d.weighed.iter().all(|w| w.effect != "vibration"), "{}: {names:?}", axis.name());
        assert!(
            matches!(names.first(), Some(&"bandwidth") | Some(&"sinusoid")),
            "{}: {names:?}",
            axis.name()
        );
        let f = fit(&input(axis, rate), &spec, REGISTRY, &opts).unwrap();
        let bw = f.term("bandwidth").unwrap();
        let n = bw.param("n").unwrap().value;
        let fc = bw.param("cutoff_hz").unwrap().value;
        let line = f.term("sinusoid").unwrap().param("frequency_hz").unwrap().value;
        let share = green_within_one_sigma(&f);
        println!(
            "{}: B,K,bandwidth,sinusoid fit_error {:.2} (whole record {:.2}), n {:.3} mg/sqrt(Hz), \
             cut-off {fc:.1} Hz, line {line:.3} Hz, green points within 1 sigma {:.0} %",
            axis.name(),
            f.misfit(),
            f.fit_error,
            n / 9.80665e-3,
            100.0 * share
        );
        assert!((0.5 * DATASHEET_N..=2.0 * DATASHEET_N).contains(&n), "{}: n {n}", axis.name());
        assert!(CUTOFF_HZ.contains(&fc), "{}: cut-off {fc}", axis.name());
        assert!((0.50..=0.65).contains(&line), "{}: line {line}", axis.name());
        assert!(3.0 * f.misfit() <= d.fit.misfit(), "{}: {} -> {}", axis.name(), d.fit.misfit(), f.misfit());
        if axis == Axis::AccelZ {
            assert!(f.fit_error <= 2.0, "accel_z whole-record fit_error {}", f.fit_error);
            assert!(share >= 0.6, "accel_z: {share}");
        }
    }
}

/// The accel axes with both lines and the louder second half (issue 10, Done 2 — what holds;
/// docs/model-measurements.md, "The real ADIS16405: every measurement"): from
/// B,K,bandwidth,sinusoid the diagnosis names the second line (`vibration`, near 10 Hz) first on
/// accel_x (fit_error after 4.31) and on accel_y the
/// louder second half (`noise_burst` from about 2155 s to the end, ×1.13: 4.44) before the line
/// (7.26: the burst explains more, and a located effect that explains the most comes first); with
/// both the whole-record Allan variance of every
/// accel axis fits (whole-record fit_error ≤ 2; measured 1.49 / 0.99 / 1.49) and fit_error falls
/// to 3.17 / 3.07 on accel_x / accel_y (from 5.93 / 7.36), asserted ≤ 3.5. fit_error ≤ 2 does NOT
/// hold: the spans at 1800–2475 s fail on all three axes (span RMS 4.5–8.8, measured/model 2–4 at
/// τ = 5–25 s) — a common-mode bias excursion of +3.5 / +2 / +3 mm/s² from 2154 s to about 2450 s,
/// up and back, which one `bias_step` per axis cannot hold (accel_z 3.45 → 2.80 with one).
#[test]
fn adis16405_accel_is_two_lines_and_a_louder_second_half() {
    let Some(path) = recording() else { return };
    let cols = read(&path, SAMPLES);
    let opts = FitOptions::default();
    let base = ModelSpec::parse("B,K,bandwidth,sinusoid").unwrap();
    let spec = ModelSpec::parse("B,K,bandwidth,sinusoid,vibration,noise_burst").unwrap();
    for (axis, rate) in accel_axes(&cols) {
        let f = fit(&input(axis, rate), &spec, REGISTRY, &opts).unwrap();
        let value = |id: &str, name: &str| f.term(id).unwrap().param(name).unwrap().value;
        let (n, fc) = (value("bandwidth", "n"), value("bandwidth", "cutoff_hz"));
        let lines = [value("sinusoid", "frequency_hz"), value("vibration", "frequency_hz")];
        let burst = [value("noise_burst", "start_s"), value("noise_burst", "end_s"), value("noise_burst", "factor")];
        println!(
            "{}: {spec} fit_error {:.2} (whole record {:.2}), n {:.3} mg/sqrt(Hz), cut-off {fc:.1} Hz, \
             lines {:.3} Hz and {:.3} Hz, burst {:.0}-{:.0} s x{:.3}, green points within 1 sigma {:.0} %",
            axis.name(),
            f.misfit(),
            f.fit_error,
            n / 9.80665e-3,
            lines[0],
            lines[1],
            burst[0],
            burst[1],
            burst[2],
            100.0 * green_within_one_sigma(&f)
        );
        assert!(f.fit_error <= 2.0, "{}: whole-record fit_error {}", axis.name(), f.fit_error);
        assert!((0.5 * DATASHEET_N..=2.0 * DATASHEET_N).contains(&n), "{}: n {n}", axis.name());
        assert!(CUTOFF_HZ.contains(&fc), "{}: cut-off {fc}", axis.name());
        assert!(lines.iter().any(|f| (0.50..=0.65).contains(f)), "{}: lines {lines:?}", axis.name());
        if axis == Axis::AccelZ {
            continue;
        }
        let d = diagnose(&input(axis, rate), &base, REGISTRY, &opts).unwrap();
        let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
        println!("{}: {base} suggestions {names:?}", axis.name());
        let first = if axis == Axis::AccelX { "vibration" } else { "noise_burst" };
        assert_eq!(names.first(), Some(&first), "{}", axis.name());
        assert!(names.contains(&"vibration"), "{}: {names:?}", axis.name());
        assert!(lines.iter().any(|f| (9.5..=11.0).contains(f)), "{}: lines {lines:?}", axis.name());
        assert!(f.misfit() <= 3.5, "{}: fit_error {}", axis.name(), f.misfit());
        if axis == Axis::AccelY {
            assert!((2000.0..=2300.0).contains(&burst[0]) && burst[1] >= 3500.0, "accel_y burst {burst:?}");
            assert!((1.05..=1.25).contains(&burst[2]), "accel_y burst factor {}", burst[2]);
        }
    }
}

/// The accel axes where no common-mode event disturbs them (issue 10, Done 2 — what holds beyond
/// the first hour): the last 2 800 s of the recording (7 200–10 000 s), on which nothing was studied
/// or tuned. From N,B,K the diagnosis names the 0.57 Hz line (`sinusoid`), the low-pass
/// (`bandwidth`) and, on accel_x and accel_y, the second line near 10 Hz (`vibration`), and the
/// model so diagnosed fits: fit_error after its last suggestion 2.01 / 1.75 / 1.20 on accel_x / y / z
/// (measured 2026-11-27), asserted ≤ 2 on accel_y and accel_z and ≤ 2.5 on accel_x, whose span at
/// 9 300–9 650 s is just above the failing level; noise density, cut-off and the lines as in the
/// first hour. Where z is green, the diagnosed model's curve lies within the points' 1σ on 57 / 67 /
/// 77 % of them (asserted ≥ 60 % where fit_error ≤ 2, as for the gyro axes). The first hour (the tests above) fails because
/// of its common-mode excursion at 2 153–2 480 s, and the second hour (2.89 / 2.59 / 2.08) because
/// of one at 6 820–7 050 s: the vocabulary has no bias that leaves and comes back.
#[test]
fn adis16405_accel_fits_where_no_event_disturbs_it() {
    let Some(cols) = whole_recording() else { return };
    let last = 2 * SAMPLES..ALL;
    let opts = FitOptions::default();
    let base = ModelSpec::parse("N,B,K").unwrap();
    for (axis, col) in accel_axes(&cols) {
        let rate = &col[last.clone()];
        let d = diagnose(&input(axis, rate), &base, REGISTRY, &opts).unwrap();
        let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
        let after = d.suggestions.last().map_or(d.fit.misfit(), |s| s.misfit_after());
        let param = |id: &str, name: &str| {
            let s = d.suggestions.iter().find(|s| s.effect == id)?;
            s.params.iter().find(|p| p.name == name).map(|p| p.value)
        };
        let (n, fc) = (param("bandwidth", "n"), param("bandwidth", "cutoff_hz"));
        let lines = [param("sinusoid", "frequency_hz"), param("vibration", "frequency_hz")];
        println!(
            "{} over 7200-10000 s: N,B,K fit_error {:.2}, suggestions {names:?}, fit_error after {after:.2}, \
             n {:?} mg/sqrt(Hz), cut-off {fc:?} Hz, lines {lines:?} Hz",
            axis.name(),
            d.fit.misfit(),
            n.map(|n| n / 9.80665e-3)
        );
        assert!(names.contains(&"sinusoid") && names.contains(&"bandwidth"), "{}: {names:?}", axis.name());
        let n = n.unwrap();
        assert!((0.5 * DATASHEET_N..=2.0 * DATASHEET_N).contains(&n), "{}: n {n}", axis.name());
        assert!(CUTOFF_HZ.contains(&fc.unwrap()), "{}: cut-off {fc:?}", axis.name());
        assert!((0.50..=0.65).contains(&lines[0].unwrap()), "{}: line {lines:?}", axis.name());
        // The diagnosed model itself: where its z is green, its curve within the points' 1σ.
        let spec = ModelSpec::parse(&format!("N,B,K,{}", names.join(","))).unwrap();
        let f = fit(&input(axis, rate), &spec, REGISTRY, &opts).unwrap();
        let share = green_within_one_sigma(&f);
        println!("{}: {spec} fit_error {:.2}, green points within 1 sigma {:.0} %", axis.name(), f.misfit(), 100.0 * share);
        if axis != Axis::AccelZ {
            assert!((9.5..=11.0).contains(&lines[1].unwrap_or(0.0)), "{}: lines {lines:?}", axis.name());
        }
        if axis == Axis::AccelX {
            assert!(after <= 2.5, "accel_x: fit_error {after}");
        } else {
            assert!(after <= 2.0, "{}: fit_error {after}", axis.name());
            assert!(share >= 0.6, "{}: {share}", axis.name());
        }
    }
}

/// Issue 10, Done 2, on the whole recording (10 000 s, none of it left out): on every axis the
/// diagnosis of N,B,K ends at a model that fits — fit_error (the contract's: the whole record's τ
/// grid) ≤ 2 after its last suggestion — with physical parameters: the low-pass named on every
/// axis, its noise density near the data sheet's (gyro ARW 1.5–3 °/√h for about 2; accel within a
/// factor 2 of 0.5 mg/√Hz) and its cut-off near the default filter's 68 Hz ([`CUTOFF_HZ`]); where
/// z is green, the curve within the points' 1σ on at least half of them.
///
/// Measured 2026-11-29 (`cargo test --release --test real_adis16405 -- --nocapture`): fit_error
/// 1.60 / 0.99 / 1.89 / 1.92 / 1.09 / 1.99 (gyro x, y, z, accel x, y, z), green points within 1σ
/// 56 / 76 / 73 / 84 / 68 / 62 %. Why half and not the 68 % a right model gives on average:
/// neighbouring τ of one record share their noise, so their z move together and one record's
/// share scatters widely (45–96 % over the six one-hour gyro parts above, each fitting). What does not hold is
/// printed, not hidden: span_fit_error stays 1.27 / 1.22 / 3.12 / 4.19 / 3.12 / 3.22 — the record
/// is not stationary in time (gyro_z's line moves from 21 Hz to 20 Hz after the first hour; the
/// accel biases leave and come back together at 2 153 s and 6 820 s; docs/model-measurements.md),
/// which no stationary model mends and the diagnosis says (its warning, `failing_spans`).
#[test]
fn adis16405_every_axis_fits_with_its_diagnosed_model_over_the_whole_recording() {
    let Some(cols) = whole_recording() else { return };
    let opts = FitOptions::default();
    let base = ModelSpec::parse("N,B,K").unwrap();
    for (axis, col) in Axis::ALL.into_iter().zip(&cols) {
        let d = diagnose(&input(axis, col), &base, REGISTRY, &opts).unwrap();
        let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
        // The refit with every suggestion: the diagnosed model.
        let f = d.after.last().unwrap_or(&d.fit);
        let bw = f.term("bandwidth").unwrap_or_else(|| panic!("{axis}: no low-pass in {names:?}"));
        let (n, fc) = (bw.param("n").unwrap().value, bw.param("cutoff_hz").unwrap().value);
        let share = green_within_one_sigma(f);
        println!(
            "{axis}: N,B,K + {names:?}: fit_error {:.2}, span_fit_error {:.2?}, n {n:.4e}, cut-off {fc:.1} Hz, \
             green points within 1 sigma {:.0} %",
            f.fit_error,
            f.span_fit_error,
            100.0 * share
        );
        assert!(f.fit_error <= 2.0, "{axis}: fit_error {} with {names:?}", f.fit_error);
        if axis.is_gyro() {
            let arw = arw_deg_per_sqrt_h(n);
            assert!((1.5..=3.0).contains(&arw), "{axis}: ARW {arw}");
        } else {
            assert!((0.5 * DATASHEET_N..=2.0 * DATASHEET_N).contains(&n), "{axis}: n {n}");
        }
        assert!(CUTOFF_HZ.contains(&fc), "{axis}: cut-off {fc}");
        assert!(share >= 0.5, "{axis}: green points within 1 sigma {share}");
    }
}
