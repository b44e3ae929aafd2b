//! `fdavar export kalibr|openvins|vins` (issue 12): the numbers equal the fit's, the files have
//! exactly the keys each estimator reads, and they load with the estimators' own parsers.
//!
//! Expected keys come from the readers' sources, not from fdavar: Kalibr's imu.yaml (wiki "YAML
//! formats"), OpenVINS' `imu0` block (ov_msckf VioManagerOptions.h `print_and_load_noise` and the
//! ROS node's `rostopic`; `update_rate` as in its kalibr_imu_chain.yaml), VINS-Fusion's
//! `readParameters` (parameters.cpp).
//!
//! Parsers: serde_yaml_ng always; PyYAML (what Kalibr loads imu.yaml with) and OpenCV's
//! `cv::FileStorage` (what OpenVINS and VINS-Fusion read their configs with, via the
//! opencv-python-headless wheel) from `$FDAVAR_PYTHON` (default `<crate>/.venv/bin/python`,
//! `.ci/python-export.txt`); without them those checks print why and pass, unless
//! `FDAVAR_REQUIRE_PYTHON=1`.

use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const CLEAN: &str = "bags/clean";
/// Relative change of a value rounded to 6 significant digits, at most.
const SIG6: f64 = 5e-6;

const KALIBR_KEYS: [&str; 6] = [
    "accelerometer_noise_density",
    "accelerometer_random_walk",
    "gyroscope_noise_density",
    "gyroscope_random_walk",
    "rostopic",
    "update_rate",
];
const VINS_KEYS: [&str; 5] = ["acc_n", "acc_w", "gyr_n", "gyr_w", "imu_topic"];

fn fdavar(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run fdavar")
}

/// Runs an export that must succeed (exit 0, nothing on stderr); returns the file.
fn export(args: &[&str]) -> String {
    let out = fdavar(&[&["export"], args].concat());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "export {args:?}: {stderr}");
    assert!(stderr.is_empty(), "export {args:?}: {stderr}");
    String::from_utf8(out.stdout).unwrap()
}

/// Per sensor, the largest N and K over its axes in the JSON `fdavar fit --json` printed.
/// `noise` is the effect whose `n` is the white noise density: `white`, or `bandwidth` for a model
/// that holds the sensor's low-pass.
fn fitted(json: &Value, noise: &str) -> BTreeMap<&'static str, f64> {
    let mut m = BTreeMap::new();
    for axis in json["axes"].as_array().unwrap() {
        let name = axis["axis"].as_str().unwrap();
        let sensor = if name.starts_with("gyro") { "gyro" } else { "accel" };
        for (param, effect, key) in [("n", noise, "noise_density"), ("k", "random_walk", "random_walk")] {
            let v = axis["coefficients"][effect][param]["value"].as_f64().unwrap();
            let e = m.entry(if sensor == "gyro" { gyro_key(key) } else { accel_key(key) }).or_insert(0.0);
            *e = f64::max(*e, v);
        }
    }
    m
}

fn gyro_key(k: &str) -> &'static str {
    if k == "noise_density" { "gyroscope_noise_density" } else { "gyroscope_random_walk" }
}

fn accel_key(k: &str) -> &'static str {
    if k == "noise_density" { "accelerometer_noise_density" } else { "accelerometer_random_walk" }
}

/// The VINS key of a Kalibr key (same value).
fn vins_key(kalibr: &str) -> &'static str {
    match kalibr {
        "accelerometer_noise_density" => "acc_n",
        "accelerometer_random_walk" => "acc_w",
        "gyroscope_noise_density" => "gyr_n",
        _ => "gyr_w",
    }
}

fn keys(map: &serde_yaml_ng::Mapping) -> Vec<String> {
    let mut k: Vec<String> = map.keys().map(|k| k.as_str().unwrap().to_string()).collect();
    k.sort();
    k
}

#[track_caller]
fn assert_close(what: &str, got: f64, want: f64, rel: f64) {
    assert!((got - want).abs() <= rel * want.abs(), "{what}: {got} vs {want} (rel {rel})");
}

/// The three files of the bundled clean recording fitted with `model` (its white noise density in
/// `noise`, see [`fitted`]), and the fit they must agree with.
fn clean_exports(model: &str, noise: &str, extra: &[&str]) -> (BTreeMap<&'static str, f64>, [String; 3]) {
    let out = fdavar(&["fit", CLEAN, "--model", model, "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let fit = fitted(&serde_json::from_slice(&out.stdout).unwrap(), noise);
    let files = ["kalibr", "openvins", "vins"].map(|f| export(&[&[f, CLEAN, "--model", model], extra].concat()));
    (fit, files)
}

#[test]
fn bag_export_equals_the_fit_with_exactly_each_readers_keys() {
    let (fit, [kalibr, openvins, vins]) = clean_exports("N,B,K", "white", &[]);
    println!("{kalibr}");
    // Kalibr: six keys at the top level; N and K unchanged (continuous time, SI = Kalibr units).
    let k: serde_yaml_ng::Mapping = serde_yaml_ng::from_str(&kalibr).unwrap();
    assert_eq!(keys(&k), KALIBR_KEYS);
    for (key, want) in &fit {
        assert_close(key, k[*key].as_f64().unwrap(), *want, SIG6);
    }
    assert_eq!(k["rostopic"].as_str(), Some("/imu/data"));
    assert_eq!(k["update_rate"].as_f64(), Some(100.0));
    // OpenVINS: the same under imu0, nothing else; the %YAML directive OpenCV needs.
    assert!(openvins.starts_with("%YAML 1.2\n---\n"), "{openvins}");
    let o: serde_yaml_ng::Mapping = serde_yaml_ng::from_str(&openvins).unwrap();
    assert_eq!(keys(&o), ["imu0"]);
    assert_eq!(o["imu0"].as_mapping().unwrap(), &k);
    // VINS-Fusion: its five keys, the same values.
    assert!(vins.starts_with("%YAML 1.2\n---\n"), "{vins}");
    let v: serde_yaml_ng::Mapping = serde_yaml_ng::from_str(&vins).unwrap();
    assert_eq!(keys(&v), VINS_KEYS);
    for (key, want) in &fit {
        assert_close(vins_key(key), v[vins_key(key)].as_f64().unwrap(), *want, SIG6);
    }
    assert_eq!(v["imu_topic"].as_str(), Some("/imu/data"));
}

#[test]
fn inflation_multiplies_every_density_and_is_stated() {
    let (fit, [kalibr, _, vins]) = clean_exports("N,B,K", "white", &["--inflate", "15"]);
    let k: serde_yaml_ng::Mapping = serde_yaml_ng::from_str(&kalibr).unwrap();
    let v: serde_yaml_ng::Mapping = serde_yaml_ng::from_str(&vins).unwrap();
    for (key, want) in &fit {
        assert_close(key, k[*key].as_f64().unwrap(), 15.0 * want, SIG6);
        assert_close(key, v[vins_key(key)].as_f64().unwrap(), 15.0 * want, SIG6);
    }
    assert!(kalibr.contains("# inflation applied: x15\n"), "{kalibr}");
    let bad = fdavar(&["export", "kalibr", CLEAN, "--inflate", "0"]);
    assert_eq!(bad.status.code(), Some(2));
}

#[test]
fn json_input_gives_the_same_file_as_the_bag() {
    let dir = tempfile::tempdir().unwrap();
    for cmd in ["fit", "diagnose"] {
        let out = fdavar(&[cmd, CLEAN, "--model", "N,B,K", "--json"]);
        let json = dir.path().join(format!("{cmd}.json"));
        std::fs::write(&json, &out.stdout).unwrap();
        let json = json.to_str().unwrap();
        for format in ["kalibr", "openvins", "vins"] {
            let from_bag = export(&[format, CLEAN]);
            let from_json = export(&[format, json, "--topic", "/imu/data", "--rate", "100"]);
            assert_eq!(from_json, from_bag, "{cmd} --json → {format}");
        }
    }
    // The topic is not in the JSON: asking for it is a usage error, as is kalibr without a rate.
    let json = dir.path().join("fit.json");
    let json = json.to_str().unwrap();
    let out = fdavar(&["export", "vins", json]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).starts_with("fdavar: error: --topic is needed"));
    let out = fdavar(&["export", "kalibr", json, "--topic", "/imu0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).starts_with("fdavar: error: --rate HZ is needed for kalibr"));
    assert!(export(&["vins", json, "--topic", "/imu0"]).contains("\nimu_topic: /imu0\n"));
}

/// `{value, sigma, unit}` coefficients (issue 12's JSON) read as well as plain numbers, and a
/// term that every axis of a sensor fits as 0 is written but warned about (exit 3).
#[test]
fn json_with_value_objects_and_an_unresolved_term() {
    let axis = |name: &str, n: f64, k: f64| {
        serde_json::json!({"axis": name, "fit_error": 1.0, "coefficients": {
            "white": {"n": {"value": n, "sigma": 1e-6, "unit": "rad/s/sqrt(Hz)"}},
            "random_walk": {"k": k}}})
    };
    let doc = serde_json::json!({"axes": [
        axis("gyro_x", 1.0e-4, 2.0e-6), axis("gyro_y", 3.0e-4, 1.0e-6), axis("gyro_z", 2.0e-4, 4.0e-6),
        axis("accel_x", 2.0e-3, 0.0), axis("accel_y", 1.0e-3, 0.0), axis("accel_z", 1.5e-3, 0.0),
    ]});
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("report.json");
    std::fs::write(&path, doc.to_string()).unwrap();
    let out = fdavar(&["export", "kalibr", path.to_str().unwrap(), "--topic", "/imu0", "--rate", "200"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("fdavar: warning: accelerometer_random_walk written as 0"), "{stderr}");
    let k: serde_yaml_ng::Mapping = serde_yaml_ng::from_slice(&out.stdout).unwrap();
    assert_eq!(k["gyroscope_noise_density"].as_f64(), Some(3.0e-4));
    assert_eq!(k["gyroscope_random_walk"].as_f64(), Some(4.0e-6));
    assert_eq!(k["accelerometer_noise_density"].as_f64(), Some(2.0e-3));
    assert_eq!(k["accelerometer_random_walk"].as_f64(), Some(0.0));
    assert_eq!(k["update_rate"].as_f64(), Some(200.0));
}

#[test]
fn a_model_without_n_or_k_is_a_usage_error() {
    for (model, needs) in [("N,B", "K (random_walk)"), ("B,K", "N (white) or bandwidth")] {
        let out = fdavar(&["export", "vins", CLEAN, "--model", model]);
        assert_eq!(out.status.code(), Some(2));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.starts_with(&format!("fdavar: error: --model {model}: export needs {needs}")), "{stderr}");
    }
}

/// A model that holds the sensor's low-pass (`bandwidth`, which replaces `white`: the ADIS16405 and
/// most MEMS parts, docs/model.md) exports its `n` as the noise density, from the bag and from the
/// fit's JSON alike. On this white-noise recording it agrees with N,B,K's N (measured: 1.9 % on the
/// accel, 2.0 % on the gyro).
#[test]
fn a_model_with_the_sensor_low_pass_exports_its_noise_density() {
    let (fit, [kalibr, _, vins]) = clean_exports("B,K,bandwidth", "bandwidth", &[]);
    let k: serde_yaml_ng::Mapping = serde_yaml_ng::from_str(&kalibr).unwrap();
    let v: serde_yaml_ng::Mapping = serde_yaml_ng::from_str(&vins).unwrap();
    for (key, want) in &fit {
        assert_close(key, k[*key].as_f64().unwrap(), *want, SIG6);
        assert_close(key, v[vins_key(key)].as_f64().unwrap(), *want, SIG6);
    }
    let (white, [white_kalibr, ..]) = clean_exports("N,B,K", "white", &[]);
    let w: serde_yaml_ng::Mapping = serde_yaml_ng::from_str(&white_kalibr).unwrap();
    for key in ["accelerometer_noise_density", "gyroscope_noise_density"] {
        assert_close(key, k[key].as_f64().unwrap(), white[key], 0.05);
        assert_close(key, w[key].as_f64().unwrap(), white[key], SIG6);
    }
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("fit.json");
    std::fs::write(&json, fdavar(&["fit", CLEAN, "--model", "B,K,bandwidth", "--json"]).stdout).unwrap();
    let from_json = export(&["kalibr", json.to_str().unwrap(), "--topic", "/imu/data", "--rate", "100"]);
    assert_eq!(from_json, kalibr);
}

/// Python with the given modules, or why not (a skip, or a failure under FDAVAR_REQUIRE_PYTHON=1).
fn python(modules: &str) -> Option<PathBuf> {
    let py = std::env::var_os("FDAVAR_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python"));
    let usable = Command::new(&py)
        .args(["-c", &format!("import {modules}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if usable {
        return Some(py);
    }
    let why = format!("{} cannot import {modules} (pip install -r .ci/python-export.txt)", py.display());
    if std::env::var("FDAVAR_REQUIRE_PYTHON").as_deref() == Ok("1") {
        panic!("{why} (FDAVAR_REQUIRE_PYTHON=1)");
    }
    eprintln!("skipping: {why}");
    None
}

/// Runs a Python script over files; returns the JSON list it printed, one document per file.
fn parsed_by(py: &Path, script: &str, files: &[String]) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let paths: Vec<String> = files
        .iter()
        .enumerate()
        .map(|(i, text)| {
            let p = dir.path().join(format!("{i}.yaml"));
            std::fs::write(&p, text).unwrap();
            p.to_str().unwrap().to_string()
        })
        .collect();
    let out = Command::new(py).arg("-c").arg(script).args(&paths).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The three files of the clean bag and the fit; then of a report whose round values serde
/// writes without a `.` (`3e-6`), which YAML 1.1 readers would take for strings.
fn cases() -> Vec<(BTreeMap<&'static str, f64>, [String; 3])> {
    let dir = tempfile::tempdir().unwrap();
    let axis = |name: &str, n: f64, k: f64| serde_json::json!({"axis": name, "coefficients": {"white": {"n": n}, "random_walk": {"k": k}}});
    let doc = serde_json::json!({"axes": [axis("gyro_x", 1e-4, 3e-6), axis("accel_x", 2e-3, 1e-7)]});
    let path = dir.path().join("round.json");
    std::fs::write(&path, doc.to_string()).unwrap();
    let round = ["kalibr", "openvins", "vins"].map(|f| export(&[f, path.to_str().unwrap(), "--topic", "/imu/data", "--rate", "100"]));
    assert!(round[0].contains("gyroscope_random_walk: 3.0e-6\n"), "{}", round[0]);
    let truth = BTreeMap::from([
        ("gyroscope_noise_density", 1e-4),
        ("gyroscope_random_walk", 3e-6),
        ("accelerometer_noise_density", 2e-3),
        ("accelerometer_random_walk", 1e-7),
    ]);
    vec![clean_exports("N,B,K", "white", &[]), (truth, round)]
}

/// Checks what a reader parsed: numbers as numbers (not strings), the fit's values, exact keys.
fn check_parsed(reader: &str, fit: &BTreeMap<&'static str, f64>, doc: &Value) {
    let kalibr = doc[0].as_object().unwrap();
    let openvins = doc[1]["imu0"].as_object().unwrap();
    let vins = doc[2].as_object().unwrap();
    for (name, map, expected) in [("kalibr", kalibr, &KALIBR_KEYS[..]), ("openvins", openvins, &KALIBR_KEYS[..]), ("vins", vins, &VINS_KEYS[..])] {
        let mut got: Vec<&str> = map.keys().map(String::as_str).collect();
        got.sort();
        assert_eq!(got, expected, "{reader} {name}");
    }
    for (key, want) in fit {
        for (name, v) in [("kalibr", &kalibr[*key]), ("openvins", &openvins[*key]), ("vins", &vins[vins_key(key)])] {
            let got = v.as_f64().unwrap_or_else(|| panic!("{reader} {name} {key}: {v} is not a number"));
            assert_close(&format!("{reader} {name} {key}"), got, *want, SIG6);
        }
    }
    assert_eq!(kalibr["rostopic"], "/imu/data", "{reader}");
    assert_eq!(vins["imu_topic"], "/imu/data", "{reader}");
    assert_eq!(openvins["update_rate"].as_f64(), Some(100.0), "{reader}");
}

/// Kalibr reads imu.yaml with PyYAML (YAML 1.1): `3e-6` would be a string there.
#[test]
fn pyyaml_reads_numbers_as_numbers() {
    let Some(py) = python("yaml") else { return };
    let script = "import json, sys, yaml\nprint(json.dumps([yaml.safe_load(open(p)) for p in sys.argv[1:]]))";
    for (fit, files) in cases() {
        check_parsed("PyYAML", &fit, &parsed_by(&py, script, &files));
    }
}

/// OpenVINS and VINS-Fusion read their configs with OpenCV's cv::FileStorage.
#[test]
fn opencv_filestorage_reads_them() {
    let Some(py) = python("cv2") else { return };
    let script = r#"import cv2, json, sys
def dump(n):
    if n.isMap():
        return {k: dump(n.getNode(k)) for k in n.keys()}
    return n.string() if n.isString() else n.real()
docs = []
for p in sys.argv[1:]:
    fs = cv2.FileStorage(p, cv2.FILE_STORAGE_READ)  # keep it open while its nodes are read
    docs.append(dump(fs.root()))
print(json.dumps(docs))"#;
    for (fit, files) in cases() {
        check_parsed("cv2.FileStorage", &fit, &parsed_by(&py, script, &files));
    }
}
