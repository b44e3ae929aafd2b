//! `fdavar simulate` end to end: the real binary writes a bag and truth.json that read back to
//! exactly the in-memory recording; a bad spec exits 1 with one line naming the field.

use fdavar::bag::{BagMessage, BagReader};
use fdavar::sim::{simulate, SimSpec, Truth};
use std::path::Path;
use std::process::{Command, Output};

fn fdavar(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(args)
        .output()
        .expect("run fdavar")
}

const SPEC: &str = r#"
rate_hz: 50
duration_s: 4
seed: 3
gravity: true
temperature: { start_c: 25, end_c: 30, time_constant_s: 2, rate_hz: 5 }
axes:
  gyro_x: { N: { n: 1.0e-3 }, temperature: { coefficient_per_k: 1.0e-3 } }
  accel_z: { N: { n: 2.0e-3 }, Q: { q: 1.0e-4 } }
"#;

#[test]
fn simulate_writes_a_bag_that_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let spec_path = dir.path().join("spec.yaml");
    std::fs::write(&spec_path, SPEC).unwrap();
    let bag = dir.path().join("rec");
    let out = fdavar(&[
        "simulate",
        spec_path.to_str().unwrap(),
        "--out",
        bag.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let expected = simulate(&SimSpec::from_yaml(SPEC).unwrap()).unwrap();
    let truth: Truth =
        serde_json::from_str(&std::fs::read_to_string(bag.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth, expected.truth);
    assert_eq!(truth.axes["accel_z"][0].units["n"], "m/s^2/sqrt(Hz)");

    let reader = BagReader::open(&bag).unwrap();
    let (mut imu, mut temps) = (Vec::new(), Vec::new());
    for m in reader
        .messages("/imu/data", Some("/imu/temperature"))
        .unwrap()
    {
        match m.unwrap() {
            BagMessage::Imu {
                log_time_ns,
                sample,
            } => {
                assert_eq!(log_time_ns, sample.stamp_ns);
                imu.push(sample);
            }
            BagMessage::Temperature { sample, .. } => temps.push(sample),
        }
    }
    assert_eq!(imu, expected.imu);
    assert_eq!(temps, expected.temperature);

    // An existing bag is kept unless --force.
    let again = fdavar(&[
        "simulate",
        spec_path.to_str().unwrap(),
        "--out",
        bag.to_str().unwrap(),
    ]);
    assert_eq!(again.status.code(), Some(1));
    let forced = fdavar(&[
        "simulate",
        spec_path.to_str().unwrap(),
        "--out",
        bag.to_str().unwrap(),
        "--force",
    ]);
    assert!(forced.status.success());
}

#[test]
fn a_bad_spec_exits_1_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let spec_path = dir.path().join("bad.yaml");
    std::fs::write(&spec_path, SPEC.replace("n: 1.0e-3", "n: -1.0")).unwrap();
    let bag = dir.path().join("rec");
    let out = fdavar(&[
        "simulate",
        spec_path.to_str().unwrap(),
        "--out",
        bag.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("fdavar: error:"), "{stderr}");
    assert!(
        stderr.contains("axes.gyro_x.N") && stderr.contains("'n'"),
        "{stderr}"
    );
    assert!(
        !Path::new(&bag).exists(),
        "no bag is left behind for a bad spec"
    );
}

#[test]
fn a_missing_spec_file_is_named() {
    let out = fdavar(&["simulate", "/nonexistent/spec.yaml", "--out", "/tmp/never"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/spec.yaml"));
}
