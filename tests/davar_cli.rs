//! `fdavar davar` as a user runs it: the real binary, its exit codes and its JSON.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::io::Write;
use std::process::Command;

fn fdavar() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fdavar"))
}

/// 3600 samples of white noise whose deviation triples from sample 1200 to 2400 (the seed's test).
fn seed_signal_file() -> tempfile::NamedTempFile {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut f = tempfile::NamedTempFile::new().unwrap();
    writeln!(f, "rate_rad_s").unwrap();
    for k in 0..3600 {
        let sd = if (1200..2400).contains(&k) { 3e-3 } else { 1e-3 };
        writeln!(f, "{:.9}", 0.01 + sd * rng.sample::<f64, _>(StandardNormal)).unwrap();
    }
    f
}

#[test]
fn json_has_rows_and_the_seed_change() {
    let file = seed_signal_file();
    let params = concat!(env!("CARGO_MANIFEST_DIR"), "/launch_params/seed_2016.yaml");
    let out = fdavar()
        .args(["davar", file.path().to_str().unwrap(), "--params", params, "--json", "--every", "10"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(doc["tau0"].as_f64(), Some(0.03));
    let rows = doc["rows"].as_array().unwrap();
    assert!(rows.iter().all(|r| r["row"]["index"].as_u64().unwrap() % 10 == 0));
    assert!(rows.iter().all(|r| r["row"]["f_target"].as_f64() == Some(3.3)));
    let events = doc["events"].as_array().unwrap();
    let main = events
        .iter()
        .map(|e| &e["event"])
        .find(|e| e["factor"].as_f64().unwrap() > 4.0)
        .expect("the noise change is an event");
    let (start, end) = (main["start_index"].as_u64().unwrap(), main["end_index"].as_u64().unwrap());
    assert!((1150..1260).contains(&start) && (2340..2450).contains(&end), "{start} {end}");
}

#[test]
fn csv_has_one_line_per_row_and_tau() {
    let file = seed_signal_file();
    let out = fdavar()
        .args(["davar", file.path().to_str().unwrap(), "--rate", "100", "--csv", "--every", "500"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    assert!(lines.next().unwrap().starts_with("axis,time_s,stamp_ns,index,window"));
    assert!(lines.all(|l| l.starts_with("gyro_x,") && l.split(',').count() == 16));
}

#[test]
fn errors_exit_non_zero_with_a_message() {
    let file = seed_signal_file();
    let no_rate = fdavar().args(["davar", file.path().to_str().unwrap()]).output().unwrap();
    assert_eq!(no_rate.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&no_rate.stderr).contains("--rate"));

    let mut bad = tempfile::NamedTempFile::new().unwrap();
    writeln!(bad, "fdavar:\n  ros__parameters:\n    window: {{min: 600, max: 501}}").unwrap();
    let bad_params = fdavar()
        .args(["davar", file.path().to_str().unwrap(), "--rate", "100", "--params", bad.path().to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(bad_params.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad_params.stderr).contains("window.min"));

    let usage = fdavar().args(["davar", "x.txt", "--json", "--csv"]).output().unwrap();
    assert_eq!(usage.status.code(), Some(2));
}
