//! `fdavar analyze` is `fdavar davar` and `fdavar diagnose` in one read of the bag (issue 11): its
//! JSON must say what the two commands say on the same recording — the diagnosis member for
//! member, and each axis's rows (count, first and last analysis time, window range) and change
//! events as `fdavar davar` lists them.

use serde_json::Value;
use std::process::Command;

fn json_of(args: &[&str]) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar")).args(args).output().unwrap();
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Events in axis order, each axis's in time order (as `fdavar analyze` lists them).
fn sorted_events(events: &Value) -> Vec<Value> {
    let order = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"];
    let mut events = events.as_array().unwrap().clone();
    events.sort_by_key(|e| {
        let axis = order.iter().position(|a| e["axis"] == *a).unwrap();
        (axis, e["event"]["start_index"].as_u64().unwrap())
    });
    events
}

#[test]
fn analyze_says_what_davar_and_diagnose_say() {
    let bag = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/seed_2016");
    let analyze = json_of(&["analyze", bag, "--json", "--jobs", "2"]);
    let diagnose = json_of(&["diagnose", bag, "--json"]);
    let davar = json_of(&["davar", bag, "--json"]);

    assert_eq!(analyze["axes"], diagnose["axes"]);

    let rows = davar["rows"].as_array().unwrap();
    let summaries = analyze["davar"]["axes"].as_array().unwrap();
    assert_eq!(summaries.len(), 6);
    let mut total = 0;
    for s in summaries {
        let of_axis: Vec<&Value> = rows.iter().filter(|r| r["axis"] == s["axis"]).collect();
        let windows: Vec<u64> = of_axis.iter().map(|r| r["row"]["window"].as_u64().unwrap()).collect();
        assert_eq!(s["rows"].as_u64().unwrap(), of_axis.len() as u64, "{s}");
        assert_eq!(s["first_s"], of_axis[0]["time_s"], "{s}");
        assert_eq!(s["last_s"], of_axis[of_axis.len() - 1]["time_s"], "{s}");
        assert_eq!(s["window_min"].as_u64(), windows.iter().min().copied(), "{s}");
        assert_eq!(s["window_max"].as_u64(), windows.iter().max().copied(), "{s}");
        total += of_axis.len();
    }
    assert_eq!(total, rows.len());
    // The seed recording's noise change is found on every axis.
    let events = sorted_events(&davar["events"]);
    assert!(events.len() >= 6, "{events:?}");
    assert_eq!(analyze["davar"]["events"].as_array().unwrap(), &events);
    assert_eq!(analyze["davar"]["tau0"], davar["tau0"]);
    assert_eq!(analyze["davar"]["irregularities"], davar["irregularities"]);
}

/// `--out` and `--csv`: every figure and CSV of the job from the one read of the bag, the same
/// bytes as `fdavar davar --out` and `fdavar diagnose --out --csv` write from their own reads.
#[test]
fn analyze_writes_the_figures_and_csvs_of_davar_and_diagnose() {
    let bag = concat!(env!("CARGO_MANIFEST_DIR"), "/bags/effects");
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name);
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_fdavar")).args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    };
    let p = |name: &str| path(name).to_str().unwrap().to_string();
    let axes = ["--axis", "gyro_y", "--axis", "accel_z"];
    run(&[&["analyze", bag, "--out", &p("analyze_out"), "--csv", &p("analyze_csv"), "--jobs", "2"][..], &axes].concat());
    run(&[&["diagnose", bag, "--out", &p("diagnose_out"), "--csv", &p("diagnose_csv")][..], &axes].concat());
    run(&["davar", bag, "--out", &p("davar_out")]);
    let files = |d: &str| -> Vec<String> {
        let mut names: Vec<String> =
            std::fs::read_dir(path(d)).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        names
    };
    // Every file diagnose wrote, and davar's of the two axes, the same bytes.
    let mut want: Vec<(String, String)> = files("diagnose_out").into_iter().map(|f| ("diagnose_out".to_string(), f)).collect();
    want.extend(
        files("davar_out")
            .into_iter()
            .filter(|f| f.contains("gyro_y") || f.contains("accel_z"))
            .map(|f| ("davar_out".to_string(), f)),
    );
    let svgs: Vec<&(String, String)> = want.iter().filter(|(_, f)| f.ends_with(".svg")).collect();
    // Per axis: the Allan figure, the DAVAR surface and window trace, and at least one suggestion.
    assert!(svgs.len() >= 8, "{want:?}");
    for (from, name) in &svgs {
        let read = |d: &str| std::fs::read(path(d).join(name)).unwrap();
        assert!(read(from) == read("analyze_out"), "{name} differs from {from}");
    }
    // And nothing else.
    let mut want_names: Vec<String> = want.iter().map(|(_, f)| f.clone()).collect();
    want_names.sort();
    assert_eq!(files("analyze_out"), want_names);
    assert_eq!(files("analyze_csv"), files("diagnose_csv"));
    for name in files("diagnose_csv") {
        let read = |d: &str| std::fs::read(path(d).join(&name)).unwrap();
        assert!(read("diagnose_csv") == read("analyze_csv"), "{name}");
    }
}
