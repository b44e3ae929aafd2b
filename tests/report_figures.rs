//! Figure writers: files exist, have the documented size, carry their axis titles, and bad input
//! is a named error, never a panic.
//!
//! The inputs are synthetic: Allan deviations from the IEEE 952 closed forms of docs/design.md §4 with
//! seeded χ²-like scatter, a DAVAR surface of white noise with a ×3 burst, and an F-value trace
//! computed from seeded white noise. Set `FDAVAR_REPORT_GALLERY=DIR` to keep the figures in DIR
//! (that is how `docs/img/` was made); otherwise they go to a temporary directory.
mod common;

use common::shaded;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use fdavar::report::figure::{
    write_allan, write_allan_comparison, write_davar_surface, write_window_trace, AllanComparison,
    AllanFigure, DavarSurface, MeasuredPoint, ModelCurves, SpanScore, Term, WindowTrace,
};
use fdavar::report::ReportError;
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

// ----------------------------------------------------------------------------------------------
// Synthetic inputs.

/// Gyro truth: white N [rad/s/√Hz], bias instability B [rad/s], random walk K [rad/s/√s],
/// and a sinusoid (A [rad/s], f [Hz]) that the "before" model lacks.
const N: f64 = 2e-4;
const B: f64 = 4e-5;
const K: f64 = 3e-6;
const SIN_A: f64 = 3e-4;
const SIN_F: f64 = 0.05;
/// Record length [s] and sample period [s].
const T: f64 = 7200.0;
const TAU0: f64 = 0.01;

fn avar_white(tau: f64) -> f64 {
    N * N / tau
}
fn avar_bias(_tau: f64) -> f64 {
    2.0 * 2f64.ln() / PI * B * B
}
fn avar_rw(tau: f64) -> f64 {
    K * K * tau / 3.0
}
fn avar_sin(tau: f64) -> f64 {
    let x = PI * SIN_F * tau;
    SIN_A * SIN_A * (x.sin().powi(2) / x).powi(2)
}

/// τ grid: 10 per decade from τ0 to T/10.
fn taus() -> Vec<f64> {
    let decades = (T / 10.0 / TAU0).log10();
    let n = (decades * 10.0).round() as usize;
    let mut m: Vec<u64> = (0..=n)
        .map(|i| 10f64.powf(i as f64 / 10.0).round() as u64)
        .collect();
    m.dedup();
    m.into_iter().map(|m| m as f64 * TAU0).collect()
}

/// Overlapping-estimator EDF, white-noise closed form (≈ 3(N−2m)/(4m) for large N/m).
fn edf(tau: f64) -> f64 {
    let n = T / TAU0;
    let m = tau / TAU0;
    (3.0 * (n - 2.0 * m) / (4.0 * m)).max(1.0)
}

/// Measured points: truth (all four terms) scattered by a seeded χ²_edf / edf factor.
fn measured(rng: &mut ChaCha8Rng) -> Vec<MeasuredPoint> {
    taus()
        .into_iter()
        .map(|tau| {
            let truth = avar_white(tau) + avar_bias(tau) + avar_rw(tau) + avar_sin(tau);
            let e = edf(tau);
            let chi2 = rand_distr::ChiSquared::new(e).unwrap().sample(rng);
            let avar = truth * chi2 / e;
            // 68 % interval from the normal approximation of χ² (good enough for a picture).
            let half = (2.0 / e).sqrt();
            MeasuredPoint {
                tau,
                dev: avar.sqrt(),
                dev_low: (avar / (1.0 + half)).sqrt(),
                dev_high: (avar / (1.0 - half).max(0.05)).sqrt(),
                bridged: false,
            }
        })
        .collect()
}

/// The model curves for a set of terms, with z and failing τ per docs/design.md §5.
/// A named Allan-variance term σ²(τ).
type AvarTerm = (&'static str, fn(f64) -> f64);

fn model(measured: &[MeasuredPoint], terms: &[AvarTerm]) -> ModelCurves {
    let grid: Vec<f64> = measured.iter().map(|p| p.tau).collect();
    let total_avar = |tau: f64| terms.iter().map(|(_, f)| f(tau)).sum::<f64>();
    let z: Vec<(f64, f64)> = measured
        .iter()
        .map(|p| {
            let m = total_avar(p.tau);
            (p.tau, (p.dev * p.dev - m) / (m * (2.0 / edf(p.tau)).sqrt()))
        })
        .collect();
    let mut failing_tau = Vec::new();
    let mut open: Option<(f64, f64)> = None;
    for &(tau, zv) in &z {
        if zv.abs() > 3.0 {
            open = Some(open.map_or((tau, tau), |(lo, _)| (lo, tau)));
        } else if let Some(span) = open.take() {
            failing_tau.push(span);
        }
    }
    failing_tau.extend(open);
    let fit_error = (z.iter().map(|p| p.1 * p.1).sum::<f64>() / z.len() as f64).sqrt();
    ModelCurves {
        label: terms.iter().map(|t| t.0).collect::<Vec<_>>().join(" + "),
        total: grid.iter().map(|&t| (t, total_avar(t).sqrt())).collect(),
        terms: terms
            .iter()
            .map(|(name, f)| Term {
                name: name.to_string(),
                curve: grid.iter().map(|&t| (t, f(t).sqrt())).collect(),
            })
            .collect(),
        z,
        failing_tau,
        fit_error,
        span_fit_error: None,
        spans: Vec::new(),
        failing_spans: Vec::new(),
    }
}

const BEFORE: [AvarTerm; 3] = [
    ("white (N)", avar_white),
    ("bias_instability (B)", avar_bias),
    ("random_walk (K)", avar_rw),
];

fn allan_figure() -> AllanFigure {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let measured = measured(&mut rng);
    let model = model(&measured, &BEFORE);
    AllanFigure {
        axis: "gyro_x".into(),
        unit: "rad/s".into(),
        title: "synthetic gyro, 2 h at 100 Hz".into(),
        measured,
        model,
    }
}

fn comparison() -> AllanComparison {
    let fig = allan_figure();
    let mut after_terms = BEFORE.to_vec();
    after_terms.push(("sinusoid", avar_sin));
    let after = model(&fig.measured, &after_terms);
    AllanComparison {
        axis: fig.axis,
        unit: fig.unit,
        title: "suggestion: add sinusoid".into(),
        measured: fig.measured,
        after_measured: None,
        before: fig.model,
        after,
    }
}

/// The seed's test signal: 3600 samples at 30 ms, white noise ×3 from sample 1200 to 2400.
fn seed_signal() -> (f64, Vec<f64>) {
    let tau0 = 0.03;
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let normal = Normal::new(0.0, 1.0).unwrap();
    let y = (0..3600)
        .map(|i| {
            let factor = if (1200..2400).contains(&i) { 3.0 } else { 1.0 };
            factor * 1e-3 * normal.sample(&mut rng)
        })
        .collect();
    (tau0, y)
}

fn variance(y: &[f64]) -> f64 {
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / y.len() as f64
}

/// F value (Eq. 2) and window (Eq. 3, policy `sign`) over the seed signal, F̃ = 1.
fn window_trace() -> WindowTrace {
    let (tau0, y) = seed_signal();
    let reference = variance(&y);
    let (l1, l2, step, f_ref) = (171usize, 501usize, 4usize, 1.0);
    let mut w = l2;
    let (mut times, mut f_value, mut window) = (vec![], vec![], vec![]);
    for t in (l1 / 2)..(y.len() - l1 / 2) {
        let half = (w / 2).min(t).min(y.len() - 1 - t);
        let f = variance(&y[t - half..=t + half]) / reference;
        times.push(t as f64 * tau0);
        f_value.push(f);
        window.push(w);
        w = if f > f_ref {
            w.saturating_sub(step).max(l1)
        } else {
            (w + step).min(l2)
        };
    }
    let n = times.len();
    WindowTrace {
        axis: "gyro_z".into(),
        title: "seed test signal".into(),
        times,
        f_value,
        f_reference: vec![f_ref; n],
        window,
        window_limits: Some((l1, l2)),
        events: vec![(1200.0 * tau0, 2400.0 * tau0)],
    }
}

/// DAVAR surface of the seed signal: per analysis time, the white-noise deviation of the window
/// σ(τ) = σ_y·√(τ0/τ) for τ ≤ τmax = W·τ0/3, NaN beyond.
fn surface() -> DavarSurface {
    let (tau0, y) = seed_signal();
    let trace = window_trace();
    let taus: Vec<f64> = [1u32, 2, 3, 4, 6, 8, 11, 16, 22, 32, 45, 63, 89, 126, 167]
        .iter()
        .map(|&m| f64::from(m) * tau0)
        .collect();
    let dev = trace
        .times
        .iter()
        .zip(&trace.window)
        .map(|(&t, &w)| {
            let c = (t / tau0).round() as usize;
            let half = (w / 2).min(c).min(y.len() - 1 - c);
            let sigma = variance(&y[c - half..=c + half]).sqrt();
            taus.iter()
                .map(|&tau| {
                    if tau <= w as f64 * tau0 / 3.0 {
                        sigma * (tau0 / tau).sqrt()
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        })
        .collect();
    DavarSurface {
        axis: "gyro_z".into(),
        unit: "rad/s".into(),
        title: "seed test signal".into(),
        times: trace.times,
        taus,
        dev,
        events: trace.events,
    }
}

// ----------------------------------------------------------------------------------------------
// Checks.

/// Where figures go: `$FDAVAR_REPORT_GALLERY` or a fresh temporary directory.
fn out_dir() -> (Option<tempfile::TempDir>, PathBuf) {
    match std::env::var_os("FDAVAR_REPORT_GALLERY") {
        Some(dir) => (None, PathBuf::from(dir)),
        None => {
            let tmp = tempfile::tempdir().unwrap();
            let path = tmp.path().to_path_buf();
            (Some(tmp), path)
        }
    }
}

/// Width and height from a PNG's IHDR chunk (bytes 16..24, big-endian), after checking the
/// signature.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert!(
        bytes.len() > 24,
        "{} is too short to be a PNG",
        path.display()
    );
    assert_eq!(
        &bytes[..8],
        b"\x89PNG\r\n\x1a\n",
        "{} has no PNG signature",
        path.display()
    );
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

/// The SVG's root `width`/`height` attributes.
fn svg_size(svg: &str) -> (u32, u32) {
    let attr = |name: &str| -> u32 {
        let start = svg.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        let end = start + svg[start..].find('"').unwrap();
        svg[start..end].parse().unwrap()
    };
    (attr("width"), attr("height"))
}

/// Both files exist, the PNG has `size`, the SVG has the same size and contains every title.
fn check_written(paths: &[PathBuf], size: (u32, u32), titles: &[&str]) {
    assert_eq!(paths.len(), 2);
    assert_eq!(paths[0].extension().unwrap(), "png");
    assert_eq!(paths[1].extension().unwrap(), "svg");
    assert_eq!(png_size(&paths[0]), size);
    let svg = std::fs::read_to_string(&paths[1]).unwrap();
    assert_eq!(svg_size(&svg), size);
    for title in titles {
        assert!(svg.contains(title), "SVG lacks the text {title:?}");
    }
    // A drawn figure is more than a blank canvas: many elements, and a PNG that does not
    // compress to nothing.
    assert!(svg.matches('<').count() > 100, "SVG has too few elements");
    assert!(std::fs::metadata(&paths[0]).unwrap().len() > 10_000);
}

#[test]
fn allan_figure_writes_png_and_svg_with_titles() {
    let (_keep, dir) = out_dir();
    let fig = allan_figure();
    // The synthetic measurement has a sinusoid the model lacks: the figure must show failures.
    assert!(!fig.model.failing_tau.is_empty() && fig.model.fit_error > 3.0);
    let paths = write_allan(&fig, &dir.join("allan_gyro_x")).unwrap();
    check_written(
        &paths,
        (1200, 900),
        &[
            "τ [s]",
            "Allan deviation σ(τ) [rad/s]",
            "z (symmetric log scale)",
            "gyro_x",
            "failing τ",
        ],
    );
}

#[test]
fn comparison_shows_both_fit_errors() {
    let (_keep, dir) = out_dir();
    let fig = comparison();
    assert!(fig.after.fit_error < fig.before.fit_error / 2.0);
    let paths = write_allan_comparison(&fig, &dir.join("allan_before_after")).unwrap();
    let before = format!("fit error {:.2}", fig.before.fit_error);
    let after = format!("fit error {:.2}", fig.after.fit_error);
    check_written(
        &paths,
        (2150, 900),
        &["before:", "after:", &before, &after, "sinusoid"],
    );
}

#[test]
fn surface_writes_heatmap_with_colour_bar() {
    let (_keep, dir) = out_dir();
    let paths = write_davar_surface(&surface(), &dir.join("davar_gyro_z")).unwrap();
    check_written(
        &paths,
        (1200, 700),
        &[
            "analysis time t [s]",
            "τ [s]",
            "σ [rad/s]",
            "grey: no value",
        ],
    );
}

#[test]
fn window_trace_writes_two_panels() {
    let (_keep, dir) = out_dir();
    let paths = write_window_trace(&window_trace(), &dir.join("window_gyro_z")).unwrap();
    check_written(
        &paths,
        (1250, 780),
        &[
            "F value",
            "window length W [samples]",
            "analysis time t [s]",
            "λ1, λ2",
        ],
    );
}

#[test]
fn stem_with_dots_and_missing_directories() {
    let tmp = tempfile::tempdir().unwrap();
    let stem = tmp.path().join("a/b/run.2024-01-01");
    let paths = write_allan(&allan_figure(), &stem).unwrap();
    assert_eq!(paths[0], tmp.path().join("a/b/run.2024-01-01.png"));
    assert!(paths.iter().all(|p| p.is_file()));
}

// ----------------------------------------------------------------------------------------------
// Bad input: named errors, never a panic, and no file written.

fn stem() -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let stem = tmp.path().join("bad");
    (tmp, stem)
}

/// A time-domain suggestion (temperature) is fitted to the data less that term: the "after" column
/// draws that residual (issue 12: it drew the raw, drifting σ next to a z panel that said the model
/// fits), each of its points once, and says so in its heading.
#[test]
fn comparison_after_column_draws_the_data_it_was_fitted_to() {
    let (_keep, dir) = out_dir();
    let same = comparison();
    let mut residual = same.clone();
    let n = same.measured.len();
    let after: Vec<MeasuredPoint> = same.measured[..n - 5]
        .iter()
        .map(|p| MeasuredPoint { tau: p.tau, dev: p.dev / 2.0, dev_low: p.dev_low / 2.0, dev_high: p.dev_high / 2.0, bridged: false })
        .collect();
    residual.after_measured = Some(after);
    let circles = |fig: &AllanComparison, name: &str| {
        let paths = write_allan_comparison(fig, &dir.join(name)).unwrap();
        let svg = std::fs::read_to_string(&paths[1]).unwrap();
        (svg.matches("<circle").count(), svg)
    };
    let (with_same, svg_same) = circles(&same, "same");
    let (with_residual, svg) = circles(&residual, "residual");
    // Five fewer measured points in the after column, nothing else changed.
    assert_eq!(with_same - with_residual, 5);
    assert!(svg.contains("after: + sinusoid, on the data less its time-domain terms"), "heading");
    assert!(!svg_same.contains("time-domain terms"));

    residual.after_measured.as_mut().unwrap()[3].dev = f64::NAN;
    let err = write_allan_comparison(&residual, &dir.join("bad")).unwrap_err();
    assert!(err.to_string().contains("after_measured.dev[3]"), "{err}");
}

/// Nineteen spans of 20 s overlapping by half (the first 200 s): the fit's span check as the
/// figure gets it, the spans at the indices `failing` with fit error 5 or 8, the others 1–1.9;
/// every third quieter than the model.
fn spans(failing: &[usize]) -> Vec<SpanScore> {
    (0..19)
        .map(|i| SpanScore {
            start_s: 10.0 * i as f64,
            end_s: 10.0 * i as f64 + 20.0,
            fit_error: if failing.contains(&i) { [5.0, 8.0][i % 2] } else { 1.0 + 0.05 * i as f64 },
            louder: i % 3 != 0,
        })
        .collect()
}

#[test]
fn a_span_panel_shows_when_in_the_record_the_model_fails() {
    let (_keep, dir) = out_dir();
    let mut fig = allan_figure();
    fig.model.span_fit_error = Some(fig.model.fit_error + 1.0);
    fig.model.spans = spans(&[]);
    let passing = write_allan(&fig, &dir.join("allan_spans_passing")).unwrap();
    let in_time = format!("(in time {:.2})", fig.model.fit_error + 1.0);
    check_written(
        &passing,
        (1200, 1150),
        &["time of the span [s]", "span fit error (− quieter)", "fit error of a span", &in_time],
    );
    // Spans 3 and 4 overlap: one shaded range (as the fit merges them); span 10 another.
    fig.model.spans = spans(&[3, 4, 10]);
    fig.model.failing_spans = vec![(30.0, 60.0), (100.0, 120.0)];
    let failing = write_allan(&fig, &dir.join("allan_spans_failing")).unwrap();
    let svg = |paths: &[PathBuf]| std::fs::read_to_string(&paths[1]).unwrap();
    assert_eq!(shaded(&svg(&failing)) - shaded(&svg(&passing)), 2);
    // The spans' error is said only when it is above fit_error.
    fig.model.span_fit_error = Some(fig.model.fit_error);
    let same = write_allan(&fig, &dir.join("allan_spans_same")).unwrap();
    assert!(!svg(&same).contains("in time"));
    // Without spans, no panel: the figure keeps its height.
    fig.model.spans.clear();
    assert_eq!(png_size(&write_allan(&fig, &dir.join("allan_no_spans")).unwrap()[0]), (1200, 900));
}

#[test]
fn bad_spans_are_named() {
    let (_tmp, stem) = stem();
    let mut fig = allan_figure();
    fig.model.spans = spans(&[]);
    fig.model.spans[1].fit_error = f64::NAN;
    let err = write_allan(&fig, &stem).unwrap_err();
    assert!(err.to_string().contains("model.spans.fit_error[1]"), "{err}");
    fig.model.spans = spans(&[]);
    fig.model.spans[2].end_s = 0.0;
    let err = write_allan(&fig, &stem).unwrap_err();
    assert!(err.to_string().contains("model.spans.start_s/end_s"), "{err}");
    fig.model.spans = spans(&[3]);
    fig.model.failing_spans = vec![(50.0, 30.0)];
    let err = write_allan(&fig, &stem).unwrap_err();
    assert!(err.to_string().contains("model.failing_spans"), "{err}");
    let mut cmp = comparison();
    cmp.after.spans = spans(&[]);
    cmp.after.spans[0].fit_error = -1.0;
    let err = write_allan_comparison(&cmp, &stem).unwrap_err();
    assert!(err.to_string().contains("after.spans.fit_error[0]"), "{err}");
}

#[test]
fn allan_nan_is_named() {
    let (tmp, stem) = stem();
    let mut fig = allan_figure();
    fig.measured[5].dev = f64::NAN;
    match write_allan(&fig, &stem) {
        Err(ReportError::NotFinite { field, index, .. }) => {
            assert_eq!((field.as_str(), index), ("measured.dev", 5));
        }
        other => panic!("expected NotFinite, got {other:?}"),
    }
    assert_eq!(
        std::fs::read_dir(tmp.path()).unwrap().count(),
        0,
        "no file on error"
    );

    let mut fig = allan_figure();
    fig.model.z[2].1 = f64::INFINITY;
    let err = write_allan(&fig, &stem).unwrap_err();
    assert!(err.to_string().contains("model.z.z[2]"), "{err}");
}

#[test]
fn allan_empty_and_bad_values_are_errors() {
    let (_tmp, stem) = stem();
    let mut fig = allan_figure();
    fig.measured.clear();
    assert!(matches!(
        write_allan(&fig, &stem),
        Err(ReportError::Empty { .. })
    ));

    let mut fig = allan_figure();
    fig.model.z.clear();
    let err = write_allan(&fig, &stem).unwrap_err();
    assert!(err.to_string().contains("`model.z` is empty"), "{err}");

    let mut fig = allan_figure();
    fig.measured[0].tau = 0.0;
    assert!(matches!(
        write_allan(&fig, &stem),
        Err(ReportError::NotPositive { .. })
    ));

    let mut fig = allan_figure();
    fig.measured[3].dev_low = fig.measured[3].dev_high * 2.0;
    assert!(matches!(
        write_allan(&fig, &stem),
        Err(ReportError::Reversed { index: 3, .. })
    ));

    let mut fig = allan_figure();
    fig.model.failing_tau = vec![(10.0, 1.0)];
    assert!(matches!(
        write_allan(&fig, &stem),
        Err(ReportError::Reversed { .. })
    ));

    let mut fig = comparison();
    fig.after.terms[1].curve[4].1 = -1.0;
    let err = write_allan_comparison(&fig, &stem).unwrap_err();
    assert!(err.to_string().contains("after.terms[1].dev[4]"), "{err}");
}

#[test]
fn allan_zero_term_is_drawn_as_absent_not_an_error() {
    let (_tmp, stem) = stem();
    let mut fig = allan_figure();
    for p in &mut fig.model.terms[2].curve {
        p.1 = 0.0;
    }
    let paths = write_allan(&fig, &stem).unwrap();
    let svg = std::fs::read_to_string(&paths[1]).unwrap();
    assert!(svg.contains("random_walk (K) (zero)"));
}

/// Points measured across lost samples are drawn hollow and named in the legend; a figure without
/// them has neither.
#[test]
fn bridged_points_are_hollow_and_named() {
    let (_tmp, stem) = stem();
    let mut fig = allan_figure();
    let plain = std::fs::read_to_string(&write_allan(&fig, &stem).unwrap()[1]).unwrap();
    let hollow = |svg: &str| {
        svg.split("<circle").skip(1).filter(|c| c.split("/>").next().unwrap_or("").contains("fill=\"none\"")).count()
    };
    assert!(!plain.contains("bridged over lost samples"));
    let long = fig.measured.len() - 5;
    for p in &mut fig.measured[long..] {
        p.bridged = true;
    }
    let svg = std::fs::read_to_string(&write_allan(&fig, &stem).unwrap()[1]).unwrap();
    assert!(svg.contains("bridged over lost samples"));
    // Five hollow points and the legend's, where the plain figure drew none.
    assert_eq!(hollow(&svg) - hollow(&plain), 6, "{}", hollow(&plain));
}

#[test]
fn surface_bad_input_is_named() {
    let (_tmp, stem) = stem();
    let mut s = surface();
    s.times.clear();
    assert!(matches!(
        write_davar_surface(&s, &stem),
        Err(ReportError::Empty { .. })
    ));

    let mut s = surface();
    for row in &mut s.dev {
        row.iter_mut().for_each(|v| *v = f64::NAN);
    }
    let err = write_davar_surface(&s, &stem).unwrap_err();
    assert!(err.to_string().contains("every value is NaN"), "{err}");

    let mut s = surface();
    s.dev[10][0] = f64::INFINITY;
    assert!(matches!(
        write_davar_surface(&s, &stem),
        Err(ReportError::NotFinite { index: 0, .. })
    ));

    let mut s = surface();
    s.dev[3].pop();
    assert!(matches!(
        write_davar_surface(&s, &stem),
        Err(ReportError::LengthMismatch {
            expected: 15,
            got: 14,
            ..
        })
    ));

    let mut s = surface();
    s.times[4] = s.times[3];
    assert!(matches!(
        write_davar_surface(&s, &stem),
        Err(ReportError::NotIncreasing { index: 4, .. })
    ));
}

#[test]
fn window_bad_input_is_named() {
    let (_tmp, stem) = stem();
    let mut t = window_trace();
    t.window.pop();
    assert!(matches!(
        write_window_trace(&t, &stem),
        Err(ReportError::LengthMismatch { .. })
    ));

    let mut t = window_trace();
    t.f_value[7] = f64::NEG_INFINITY;
    assert!(matches!(
        write_window_trace(&t, &stem),
        Err(ReportError::NotFinite { index: 7, .. })
    ));

    let mut t = window_trace();
    t.f_value.iter_mut().for_each(|f| *f = f64::NAN);
    t.f_reference.iter_mut().for_each(|f| *f = f64::NAN);
    assert!(matches!(
        write_window_trace(&t, &stem),
        Err(ReportError::Empty { .. })
    ));

    let mut t = window_trace();
    t.f_value[3] = f64::MAX;
    assert!(matches!(
        write_window_trace(&t, &stem),
        Err(ReportError::UnplottableRange { .. })
    ));

    let mut t = window_trace();
    t.window_limits = Some((501, 171));
    assert!(matches!(
        write_window_trace(&t, &stem),
        Err(ReportError::Reversed { .. })
    ));
}

#[test]
fn log_axis_spanning_too_many_decades_is_an_error() {
    let (_tmp, stem) = stem();
    let mut fig = allan_figure();
    fig.measured[0].tau = 1e-200;
    fig.model.total[0].0 = 1e-200;
    let err = write_allan(&fig, &stem).unwrap_err();
    assert!(
        matches!(err, ReportError::UnplottableRange { .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("`tau` from 1e-200"), "{err}");

    // Near the ends of f64: the padded axis would overflow to ∞ (a hang in plotters' ticks).
    let mut fig = allan_figure();
    for p in &mut fig.measured {
        p.dev *= 1e306;
        p.dev_low *= 1e306;
        p.dev_high *= 1e306;
    }
    let err = write_allan(&fig, &stem).unwrap_err();
    assert!(
        matches!(err, ReportError::UnplottableRange { .. }),
        "{err:?}"
    );
}

#[test]
fn window_nan_warmup_is_drawn() {
    let (_tmp, stem) = stem();
    let mut t = window_trace();
    t.f_value[..50].iter_mut().for_each(|f| *f = f64::NAN);
    let paths = write_window_trace(&t, &stem).unwrap();
    check_written(&paths, (1250, 780), &["F value", "window length W [samples]"]);
    // The 50 rows without F are left out of the F line, not drawn as zeros or gaps of NaN: the
    // figure's lines hold 50 vertices fewer than those of the whole trace.
    let vertices = |svg: &str| -> usize {
        svg.split("points=\"").skip(1).map(|rest| rest.split('"').next().unwrap().split_whitespace().count()).sum()
    };
    let (_keep, dir) = out_dir();
    let whole = write_window_trace(&window_trace(), &dir.join("whole")).unwrap();
    let (with_nan, without) = (std::fs::read_to_string(&paths[1]).unwrap(), std::fs::read_to_string(&whole[1]).unwrap());
    assert!(!with_nan.contains("NaN"), "NaN written into the SVG");
    assert_eq!(vertices(&without) - vertices(&with_nan), 50);
}

#[test]
fn unwritable_path_is_a_draw_or_dir_error() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("a_file");
    std::fs::write(&file, b"x").unwrap();
    // The "directory" is a regular file: creating it fails with the path in the error.
    let err = write_allan(&allan_figure(), &file.join("fig")).unwrap_err();
    assert!(
        matches!(
            err,
            ReportError::CreateDir { .. } | ReportError::Draw { .. }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("a_file"), "{err}");
}

#[test]
fn figure_data_survives_json() {
    let fig = comparison();
    let json = serde_json::to_string(&fig).unwrap();
    let back: AllanComparison = serde_json::from_str(&json).unwrap();
    // serde_json parses floats to within 1 ulp (exact only with its `float_roundtrip` feature),
    // so compare the numbers with a relative tolerance of a few ulps and the rest exactly.
    let numbers = |v: &serde_json::Value| -> Vec<f64> {
        fn walk(v: &serde_json::Value, out: &mut Vec<f64>) {
            match v {
                serde_json::Value::Number(n) => out.push(n.as_f64().unwrap()),
                serde_json::Value::Array(a) => a.iter().for_each(|x| walk(x, out)),
                serde_json::Value::Object(o) => o.values().for_each(|x| walk(x, out)),
                _ => {}
            }
        }
        let mut out = Vec::new();
        walk(v, &mut out);
        out
    };
    let (a, b) = (
        serde_json::to_value(&fig).unwrap(),
        serde_json::to_value(&back).unwrap(),
    );
    let (na, nb) = (numbers(&a), numbers(&b));
    assert_eq!(na.len(), nb.len());
    assert!(na
        .iter()
        .zip(&nb)
        .all(|(x, y)| (x - y).abs() <= 4.0 * f64::EPSILON * x.abs().max(y.abs())));
    assert_eq!(
        (back.axis, back.before.label, back.after.terms.len()),
        (fig.axis, fig.before.label, 4)
    );
}

// ----------------------------------------------------------------------------------------------
// Any numbers at all: an error or two files, never a panic.

/// Finite values of any magnitude, plus the specials that user data can hold.
fn any_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => (-300.0f64..300.0).prop_map(|e| 10f64.powf(e)),
        1 => (-300.0f64..300.0).prop_map(|e| -(10f64.powf(e))),
        1 => Just(0.0),
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::MAX),
        1 => Just(f64::MIN_POSITIVE),
    ]
}

proptest! {
    // Seeded: the same 24 cases on every run (STYLE: seeded randomness in tests).
    #![proptest_config(ProptestConfig {
        cases: 24,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x5eed),
        ..ProptestConfig::default()
    })]

    #[test]
    fn allan_never_panics(
        values in prop::collection::vec((any_value(), any_value(), any_value()), 0..6),
        z in prop::collection::vec(any_value(), 1..6),
    ) {
        let measured: Vec<MeasuredPoint> = values
            .iter()
            .map(|&(tau, dev, spread)| MeasuredPoint {
                tau,
                dev,
                dev_low: dev / (1.0 + spread.abs()),
                dev_high: dev * (1.0 + spread.abs()),
                bridged: false,
            })
            .collect();
        let taus: Vec<f64> = measured.iter().map(|p| p.tau).collect();
        let fig = AllanFigure {
            axis: "gyro_y".into(),
            unit: "rad/s".into(),
            title: String::new(),
            model: ModelCurves {
                label: "N".into(),
                total: measured.iter().map(|p| (p.tau, p.dev)).collect(),
                terms: vec![Term { name: "N".into(), curve: measured.iter().map(|p| (p.tau, p.dev_low)).collect() }],
                z: taus.iter().zip(z.iter().cycle()).map(|(&t, &z)| (t, z)).collect(),
                failing_tau: taus.iter().map(|&t| (t, t)).collect(),
                fit_error: 1.0,
                span_fit_error: z.first().copied(),
                spans: z.windows(3).map(|w| SpanScore { start_s: w[0], end_s: w[1], fit_error: w[2], louder: w[0] < w[2] }).collect(),
                failing_spans: z.windows(2).map(|w| (w[0], w[1])).collect(),
            },
            measured,
        };
        let tmp = tempfile::tempdir().unwrap();
        if let Ok(paths) = write_allan(&fig, &tmp.path().join("p")) {
            prop_assert!(paths.iter().all(|p| p.is_file()));
        }
    }

    /// Valid but extreme: any magnitude a double holds draws, as long as each log axis spans at
    /// most MAX_DECADES; wider spans are an UnplottableRange error (never a hang in the tick code).
    #[test]
    fn allan_extreme_valid_values_draw(
        offset in (-280.0f64..280.0, -278.0f64..278.0),
        points in prop::collection::vec((-19.0f64..19.0, -19.0f64..19.0, 0.0f64..3.0), 1..6),
        z in prop::collection::vec(-1e300f64..1e300, 1..6),
        spans in prop::collection::vec((-1e299f64..1e299, 1e-6f64..1.0, 0.0f64..1e300), 0..5),
    ) {
        let mut points = points;
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let measured: Vec<MeasuredPoint> = points
            .iter()
            .map(|&(t, d, spread)| {
                let dev = 10f64.powf(d + offset.1);
                MeasuredPoint { tau: 10f64.powf(t + offset.0), dev, dev_low: dev / (1.0 + spread), dev_high: dev * (1.0 + spread), bridged: false }
            })
            .collect();
        let fig = AllanFigure {
            axis: "gyro_y".into(),
            unit: "rad/s".into(),
            title: String::new(),
            model: ModelCurves {
                label: "N".into(),
                total: measured.iter().map(|p| (p.tau, p.dev)).collect(),
                terms: vec![],
                z: measured.iter().zip(z.iter().cycle()).map(|(p, &z)| (p.tau, z)).collect(),
                failing_tau: vec![],
                fit_error: 1.0,
                span_fit_error: Some(0.5),
                // A span of at least 10⁻⁶ of its start's magnitude: a linear axis resolves it.
                spans: spans
                    .iter()
                    .map(|&(start, len, e)| SpanScore { start_s: start, end_s: start + len * start.abs().max(1.0), fit_error: e, louder: len < 0.5 })
                    .collect(),
                failing_spans: spans.iter().filter(|s| s.2 > 3.0).map(|&(start, len, _)| (start, start + len * start.abs().max(1.0))).collect(),
            },
            measured,
        };
        let tmp = tempfile::tempdir().unwrap();
        let paths = write_allan(&fig, &tmp.path().join("p"));
        prop_assert!(paths.is_ok(), "{:?}", paths.err());
    }

    #[test]
    fn surface_never_panics(
        times in prop::collection::vec(any_value(), 0..4),
        cells in prop::collection::vec(any_value(), 0..12),
    ) {
        let taus = vec![0.1, 1.0, 10.0];
        let dev = times
            .iter()
            .enumerate()
            .map(|(i, _)| (0..3).map(|j| cells.get(3 * i + j).copied().unwrap_or(f64::NAN)).collect())
            .collect();
        let s = DavarSurface {
            axis: "accel_x".into(),
            unit: "m/s²".into(),
            title: String::new(),
            times,
            taus,
            dev,
            events: vec![],
        };
        let tmp = tempfile::tempdir().unwrap();
        let _ = write_davar_surface(&s, &tmp.path().join("p"));
    }
}
