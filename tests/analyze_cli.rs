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
