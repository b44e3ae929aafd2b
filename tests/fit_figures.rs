//! `fdavar fit BAG --out DIR` as a user runs it: the Allan figure shows where in time the model
//! fails, not only at which τ.
//!
//! The bundled seed recording (bags/seed_2016: the seed paper's test, white noise tripled for a
//! while) fits N,B,K on its whole-record Allan variance and fails on the spans that hold the
//! burst: the figure must say so with the whole record's own error beside fit_error and a panel
//! of the spans, the failing ones shaded. Checked against the library's fit of the same recording.
mod common;

use common::shaded;
use fdavar::analysis::{Analysis, AnalysisConfig};
use fdavar::bag::{BagMessage, BagReader};
use fdavar::model::{FittedModel, ModelSpec};
use fdavar::signal::Axis;
use std::path::Path;
use std::process::Command;

const SEED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/seed_2016");

/// The library's N,B,K fit of gyro_x, fed as `fdavar fit` feeds it.
fn library_fit(bag: &Path) -> FittedModel {
    let reader = BagReader::open(bag).unwrap();
    let imu = reader.imu_topic(None).unwrap().name.clone();
    let mut analysis = Analysis::new(AnalysisConfig::whole_run(&ModelSpec::parse("N,B,K").unwrap())).unwrap();
    for m in reader.messages(&imu, None).unwrap() {
        if let BagMessage::Imu { sample, .. } = m.unwrap() {
            analysis.push(&sample);
        }
    }
    analysis.finish();
    analysis.fit(Axis::GyroX).unwrap()
}

#[test]
fn the_figure_shows_when_the_model_fails() {
    let fit = library_fit(Path::new(SEED));
    // The case this test is about: the whole-record curve fits, the spans do not.
    let spans = fit.span_fit_error.unwrap();
    assert!(fit.fit_error < 2.0 && spans > 3.0, "{} / {spans}", fit.fit_error);
    assert!(fit.failing_tau.is_empty() && !fit.failing_spans.is_empty());
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["fit", SEED, "--model", "N,B,K", "--axis", "gyro_x", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let svg = std::fs::read_to_string(dir.path().join("allan_gyro_x.svg")).unwrap();
    assert!(svg.contains("height=\"1150\""), "the span panel's height");
    let caption = format!("fit error {:.2} (in time {spans:.2})", fit.fit_error);
    assert!(svg.contains(&caption), "{caption}");
    assert!(svg.contains("time of the span [s], from the first sample"));
    // No τ fails, so every shaded range is a run of failing spans, as the fit merges them (and
    // two are the legend's swatches: failing τ, failing span).
    assert_eq!(shaded(&svg), fit.failing_spans.len() + 2);
    // The burst's spans lie above the whole-record model, the quiet ones before and after it
    // below: the figure draws those under the zero line.
    let curves = fdavar::model::output::model_curves(&fit);
    let louder: Vec<bool> = curves.spans.iter().map(|s| s.louder).collect();
    assert_eq!(louder, fit.spans.iter().map(|c| c.mean_z >= 0.0).collect::<Vec<_>>());
    assert!(louder.contains(&true) && louder.contains(&false), "{louder:?}");
    let burst = fit.spans.iter().max_by(|a, b| a.fit_error.total_cmp(&b.fit_error)).unwrap();
    assert!(burst.mean_z > 3.0, "the loudest span is the burst's: {burst:?}");
    // A dot per span, beside two per τ (σ and z panels) and the legend's.
    assert_eq!(svg.matches("<circle").count(), 2 * fit.points.len() + fit.spans.len() + 1);
}
