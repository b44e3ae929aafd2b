//! `fdavar diagnose` of many recordings (issue 11, "a fleet of robots' bags on one machine"): a
//! directory of bags, or several bags given, each diagnosed exactly as alone, in parallel, one
//! table; an unreadable recording is reported in place and exits 1 once the others are done.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn fdavar(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fdavar")).args(args).output().expect("run fdavar")
}

fn bag(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("bags").join(name)
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let p = entry.unwrap().path();
        std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
    }
}

/// A fleet directory: two robots' bag directories, one bag that is not MCAP, and a directory
/// without any recording (ignored).
fn fleet(dir: &Path) {
    copy_dir(&bag("clean"), &dir.join("robot_a"));
    copy_dir(&bag("effects"), &dir.join("robot_b"));
    std::fs::create_dir_all(dir.join("robot_c")).unwrap();
    std::fs::write(dir.join("robot_c/imu_0.mcap"), b"not an mcap file").unwrap();
    std::fs::create_dir_all(dir.join("notes")).unwrap();
    std::fs::write(dir.join("notes/README.txt"), b"calibration runs of 2026-11-25").unwrap();
}

fn stdout_json(out: &Output) -> Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&out.stdout)))
}

#[test]
fn a_directory_of_bags_is_diagnosed_bag_by_bag_as_alone() {
    let tmp = tempfile::tempdir().unwrap();
    fleet(tmp.path());
    let dir = tmp.path().to_str().unwrap();
    let out = fdavar(&["diagnose", dir, "--json", "--jobs", "2"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    // robot_c cannot be read: exit 1, after the others.
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("1 of 3 recordings could not be diagnosed") && stderr.contains("robot_c"), "{stderr}");
    let doc = stdout_json(&out);
    let recordings = doc["recordings"].as_array().unwrap();
    let names: Vec<&str> = recordings.iter().map(|r| r["bag"].as_str().unwrap()).collect();
    assert_eq!(names, [format!("{dir}/robot_a"), format!("{dir}/robot_b"), format!("{dir}/robot_c")]);
    assert!(recordings[2]["error"].as_str().unwrap().contains("MCAP magic"), "{}", recordings[2]);
    assert!(recordings[2].get("axes").is_none());
    // Each readable recording: the axes `fdavar diagnose BAG --json` prints alone, member for member.
    for (r, name) in recordings[..2].iter().zip(["clean", "effects"]) {
        let alone = fdavar(&["diagnose", bag(name).to_str().unwrap(), "--json"]);
        assert_eq!(r["axes"], stdout_json(&alone)["axes"], "{name}");
        assert!(r.get("error").is_none());
    }
    // bags/effects hides a sinusoid on gyro_x (bags/specs/effects.yaml): the table names it.
    assert_eq!(recordings[1]["axes"][0]["suggestions"][0]["effect"], "sinusoid");
    assert!(recordings[0]["axes"].as_array().unwrap().iter().all(|a| a["suggestions"].as_array().unwrap().is_empty()));
}

#[test]
fn recordings_given_one_by_one_make_one_table_whatever_the_threads() {
    let (clean, effects) = (bag("clean"), bag("effects"));
    let args = |jobs: &'static str| {
        fdavar(&["diagnose", clean.to_str().unwrap(), effects.to_str().unwrap(), "--axis", "gyro_x", "--jobs", jobs])
    };
    let (one, two) = (args("1"), args("2"));
    assert_eq!(one.status.code(), Some(0), "{}", String::from_utf8_lossy(&one.stderr));
    assert_eq!(one.stdout, two.stdout);
    let text = String::from_utf8(one.stdout).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().skip(2).map(|l| l.split_whitespace().collect()).collect();
    assert_eq!(rows.len(), 2, "{text}");
    // recording, axis, model, fit_error, suggestion, fit_error with it
    assert_eq!(&rows[0][1..4], ["gyro_x", "N,B,K", "0.92"], "{text}");
    assert_eq!(rows[0][4], "none", "{text}");
    assert_eq!(&rows[1][1..3], ["gyro_x", "N,B,K"], "{text}");
    assert_eq!(rows[1][4], "FAILS", "{text}");
    assert_eq!(rows[1][5], "sinusoid", "{text}");
    let after: f64 = rows[1][6].parse().unwrap();
    assert!(after < 2.0, "{text}");
    let stderr = String::from_utf8_lossy(&one.stderr);
    assert!(stderr.contains("2 recordings, 2 diagnosed: 1 of 2 axes with a failing model (fit_error or span_fit_error > 2), 1 with a suggestion; samples left out in 0 recordings"), "{stderr}");
}

#[test]
fn per_recording_files_need_one_recording() {
    let (clean, effects) = (bag("clean"), bag("effects"));
    let tmp = tempfile::tempdir().unwrap();
    let out = fdavar(&["diagnose", clean.to_str().unwrap(), effects.to_str().unwrap(), "--out", tmp.path().to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("run `fdavar diagnose BAG` on each one"));
    // A directory without any recording is a usage error too.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(empty.join("notes")).unwrap();
    let out = fdavar(&["diagnose", empty.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("holds no recording"), "{}", String::from_utf8_lossy(&out.stderr));
}
