//! `fdavar diagnose BAG --mcap OUT` (issue 12): the results MCAP is read back by PyPI
//! `mcap-ros2-support` with every field of every message decoded, and what it decodes is what the
//! CLI prints: per axis the whole-run answer equals `fdavar diagnose --json` (model, fit_error,
//! coefficients, failing τ and spans, suggestions: exactly), and the rows equal
//! `fdavar davar --json` on the node's default settings (count, stamps, window lengths, F).
//!
//! Python: `$FDAVAR_PYTHON` (default `<crate>/.venv/bin/python`) with `mcap-ros2-support`. Without
//! it the Python half prints why and passes, unless `FDAVAR_REQUIRE_PYTHON=1` (CI); fdavar's own
//! reader checks the channels either way.

mod common;

use fdavar::bag::BagReader;
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

const AXES: [&str; 6] = [
    "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z",
];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}


fn fdavar(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(args)
        .output()
        .expect("run fdavar")
}

/// Runs a subcommand that prints JSON; exit 0, or 3 (samples left out, a failing model).
fn json(args: &[&str]) -> Value {
    let out = fdavar(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        matches!(out.status.code(), Some(0 | 3)),
        "fdavar {args:?}: {:?}\n{stderr}",
        out.status
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("fdavar {args:?}: {e}\n{stderr}"))
}

/// A float as the probe dumps it (non-finite values as strings) or as fdavar's JSON does (null for
/// NaN and for `None`, which the message carries as NaN).
fn f(v: &Value) -> f64 {
    match v {
        Value::Null => f64::NAN,
        Value::String(s) if s == "NaN" => f64::NAN,
        Value::String(s) if s == "inf" => f64::INFINITY,
        Value::String(s) if s == "-inf" => f64::NEG_INFINITY,
        _ => v.as_f64().unwrap_or_else(|| panic!("not a number: {v}")),
    }
}

/// A decoded `Coefficient` message as `{value, sigma, unit}`, NaN as null (as
/// [`common::param_as_message`] gives the JSON's).
fn message_param(c: &Value) -> Value {
    let number = |v: &Value| serde_json::Number::from_f64(f(v)).map_or(Value::Null, Value::Number);
    serde_json::json!({"value": number(&c["value"]), "sigma": number(&c["sigma"]), "unit": c["unit"]})
}

fn u(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("not a u64: {v}"))
}

/// Exact equality, NaN equal to NaN.
fn same(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan())
}

#[test]
fn results_mcap_decodes_with_mcap_ros2_to_what_the_cli_prints() {
    let bag = root().join("bags/effects");
    let bag_s = bag.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("results.mcap");
    let mcap_s = mcap.to_str().unwrap();

    // The answer printed alongside the file, and the one without --mcap: the same numbers.
    let with = json(&[
        "diagnose",
        bag_s,
        "--json",
        "--mcap",
        mcap_s,
        "--mcap-every",
        "1",
    ]);
    let plain = json(&["diagnose", bag_s, "--json"]);
    assert_eq!(with, plain, "--mcap changed the whole-run answer");

    // fdavar's own reader lists the six channels, typed.
    let reader = BagReader::open(&mcap).unwrap();
    let mut topics: Vec<(String, String)> = reader
        .topics()
        .iter()
        .map(|t| (t.name.clone(), t.type_name.clone()))
        .collect();
    topics.sort();
    let mut want: Vec<(String, String)> = AXES
        .iter()
        .map(|a| {
            (
                format!("/fdavar/{a}/state"),
                "fdavar_msgs/msg/AxisState".to_string(),
            )
        })
        .collect();
    want.sort();
    assert_eq!(topics, want);
    let imu_messages = BagReader::open(&bag)
        .unwrap()
        .imu_topic(None)
        .unwrap()
        .message_count;
    let davar = json(&["davar", bag_s, "--json", "--every", "1"]);
    let davar_rows = davar["rows"].as_array().unwrap();

    let Some(python) = common::python_with("import mcap, mcap_ros2.decoder", ".ci/python-bag.txt") else { return };
    let out = Command::new(&python)
        .arg(root().join("tests/py/read_results.py"))
        .arg(&mcap)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "read_results.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(got["profile"], "ros2");

    for axis in AXES {
        let topic = format!("/fdavar/{axis}/state");
        let channel = &got["channels"][&topic];
        assert_eq!(channel["schema"], "fdavar_msgs/msg/AxisState", "{topic}");
        assert_eq!(channel["schema_encoding"], "ros2msg", "{topic}");
        assert_eq!(channel["message_encoding"], "cdr", "{topic}");
        let msgs = got["messages"][&topic].as_array().unwrap();
        assert_eq!(
            u(&channel["count"]),
            msgs.len() as u64,
            "{topic}: summary count"
        );
        let ours = reader.topics().iter().find(|t| t.name == topic).unwrap();
        assert_eq!(
            ours.message_count,
            msgs.len() as u64,
            "{topic}: BagReader count"
        );

        // The rows: those `fdavar davar` makes on the node's defaults, one message each, in order.
        let rows: Vec<&Value> = davar_rows.iter().filter(|r| r["axis"] == axis).collect();
        let (final_msg, row_msgs) = msgs.split_last().unwrap();
        assert_eq!(
            row_msgs.len(),
            rows.len(),
            "{topic}: one message per DAVAR row"
        );
        assert!(!rows.is_empty(), "{topic}: no rows");
        for (m, r) in row_msgs.iter().zip(&rows) {
            assert_eq!(m["axis"], axis);
            let stamp = m["header"]["stamp"].clone();
            let stamp_ns = u(&stamp["sec"]) * 1_000_000_000 + u(&stamp["nanosec"]);
            assert_eq!(
                u(&m["log_time"]),
                stamp_ns,
                "{topic}: log time = the row's stamp"
            );
            assert_eq!(stamp_ns, u(&r["stamp_ns"]), "{topic}: stamp");
            assert!(
                same(f(&m["analysis_time_s"]), f(&r["time_s"])),
                "{topic}: t {r}"
            );
            let row = &r["row"];
            assert_eq!(m["window_length"], row["window"], "{topic}");
            assert!(same(f(&m["f_value"]), f(&row["f"])), "{topic}: F");
            assert!(
                same(f(&m["f_reference"]), f(&row["f_target"])),
                "{topic}: F~"
            );
            let points = m["row"].as_array().unwrap();
            let want = row["points"].as_array().unwrap();
            assert_eq!(points.len(), want.len(), "{topic}: row length");
            for (p, w) in points.iter().zip(want) {
                for (ours, theirs) in [
                    ("tau_s", "tau"),
                    ("avar", "avar"),
                    ("avar_low", "ci_low"),
                    ("avar_high", "ci_high"),
                    ("edf", "edf"),
                ] {
                    assert!(
                        same(f(&p[ours]), f(&w[theirs])),
                        "{topic}: {ours} {p} vs {w}"
                    );
                }
            }
            assert!(f(&m["fit_error"]).is_nan() && m["model"] == Value::Array(vec![]));
        }

        // The final message: the last row again, with the whole-run answer of `--json`.
        let last = rows.last().unwrap();
        assert_eq!(
            final_msg["window_length"], last["row"]["window"],
            "{topic}: last row's W"
        );
        assert_eq!(final_msg["header"], row_msgs.last().unwrap()["header"]);
        let want = with["axes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|a| a["axis"] == axis)
            .unwrap();
        assert_eq!(final_msg["model"], want["model"], "{topic}");
        assert_eq!(f(&final_msg["fit_error"]), f(&want["fit_error"]), "{topic}");
        assert_eq!(u(&final_msg["diagnosed_messages"]), imu_messages, "{topic}");
        let coefs = final_msg["coefficients"].as_array().unwrap();
        let n_want: usize = want["coefficients"]
            .as_object()
            .unwrap()
            .values()
            .map(|p| p.as_object().unwrap().len())
            .sum();
        assert_eq!(coefs.len(), n_want, "{topic}: coefficients");
        for c in coefs {
            let v =
                &want["coefficients"][c["effect"].as_str().unwrap()][c["name"].as_str().unwrap()];
            assert_eq!(message_param(c), common::param_as_message(v), "{topic}: {c}");
        }
        let pairs = |v: &Value, lo: &str, hi: &str| -> Vec<[f64; 2]> {
            v.as_array()
                .unwrap()
                .iter()
                .map(|x| [f(&x[lo]), f(&x[hi])])
                .collect()
        };
        let arrays = |v: &Value| -> Vec<[f64; 2]> {
            v.as_array()
                .unwrap()
                .iter()
                .map(|x| [f(&x[0]), f(&x[1])])
                .collect()
        };
        assert_eq!(
            pairs(&final_msg["failing_tau"], "low_s", "high_s"),
            arrays(&want["failing_tau"])
        );
        assert_eq!(
            pairs(&final_msg["failing_spans"], "start_s", "end_s"),
            arrays(&want["failing_spans"])
        );
        let suggestions = final_msg["suggestions"].as_array().unwrap();
        let want_s = want["suggestions"].as_array().unwrap();
        let effects = |v: &[Value]| v.iter().map(|s| s["effect"].clone()).collect::<Vec<_>>();
        assert_eq!(
            effects(suggestions),
            effects(want_s),
            "{topic}: suggestions"
        );
        for (s, w) in suggestions.iter().zip(want_s) {
            assert_eq!(
                f(&s["fit_error_after"]),
                f(&w["fit_error_after"]),
                "{topic}"
            );
            assert_eq!(s["explanation"], w["explanation"], "{topic}");
            let names = |ps: &Value| -> Vec<String> {
                ps.as_array().unwrap().iter().map(|p| p["name"].as_str().unwrap().to_string()).collect()
            };
            let mut want_names: Vec<String> = w["params"].as_object().unwrap().keys().cloned().collect();
            let mut got_names = names(&s["params"]);
            want_names.sort();
            got_names.sort();
            assert_eq!(got_names, want_names, "{topic}: suggestion params");
            for p in s["params"].as_array().unwrap() {
                assert_eq!(
                    message_param(p),
                    common::param_as_message(&w["params"][p["name"].as_str().unwrap()]),
                    "{topic}: {p}"
                );
            }
        }
    }
    assert!(davar_rows.len() > 6 * 100, "{} rows", davar_rows.len());
    // The whole recording's answer names something on some axis (the bag hides every effect).
    assert!(
        with["axes"]
            .as_array()
            .unwrap()
            .iter()
            .any(|a| !a["suggestions"].as_array().unwrap().is_empty()),
        "no suggestion anywhere: the comparison above would be vacuous for suggestions"
    );
}

/// Without `--mcap-every`, every row is a message: on the seed's recording (3600 samples) each
/// channel holds `fdavar davar`'s rows of its axis and the final message.
#[test]
fn every_row_is_a_message_by_default() {
    let bag = root().join("bags/seed_2016");
    let bag_s = bag.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("seed.mcap");
    let mcap_s = mcap.to_str().unwrap();
    json(&[
        "diagnose", bag_s, "--json", "--mcap", mcap_s, "--axis", "gyro_x", "--axis", "accel_z",
    ]);
    let davar = json(&["davar", bag_s, "--json"]);
    let reader = BagReader::open(&mcap).unwrap();
    let counts: Vec<(String, u64)> = reader
        .topics()
        .iter()
        .map(|t| (t.name.clone(), t.message_count))
        .collect();
    let rows = |axis: &str| {
        davar["rows"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|r| r["axis"] == axis)
            .count() as u64
    };
    assert!(rows("gyro_x") > 1000, "{} rows", rows("gyro_x"));
    assert_eq!(
        counts,
        [
            ("/fdavar/gyro_x/state".to_string(), rows("gyro_x") + 1),
            ("/fdavar/accel_z/state".to_string(), rows("accel_z") + 1),
        ]
    );
}

/// Usage errors of the results flags exit 2 before any work: `--params` or `--mcap-every` without
/// `--mcap`, a directory as `--mcap`, and DAVAR settings the node's single pass cannot run.
#[test]
fn results_flags_misused_exit_2() {
    let bag = root().join("bags/seed_2016");
    let bag_s = bag.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.mcap");
    let params = root().join("launch_params/seed_2016.yaml");
    // Each misuse with the words its message must name.
    for (args, says) in [
        (vec!["diagnose", bag_s, "--params", params.to_str().unwrap()], "--mcap"),
        (vec!["fit", bag_s, "--model", "N", "--mcap-every", "1"], "--mcap"),
        (vec!["diagnose", bag_s, "--mcap", dir.path().to_str().unwrap()], "a directory"),
        (vec!["diagnose", bag_s, "--mcap", out.to_str().unwrap(), "--mcap-every", "0"], "positive number of seconds"),
        // seed_2016.yaml asks for sigma_ref.mode record (the whole record's variance).
        (vec!["diagnose", bag_s, "--mcap", out.to_str().unwrap(), "--params", params.to_str().unwrap()], "sigma_ref.mode 'record'"),
    ] {
        let o = fdavar(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    }
    assert!(!out.exists(), "a refused run wrote {}", out.display());
}
