//! `fdavar allan` against Stable32: the real binary on the reference files of tests/data/stable32.
//!
//! PHASE.DAT (1001 points): every averaging factor of the OADEV, ADEV, MDEV and HDEV tables within
//! a relative 1e-4 (the tables' 5 significant figures). Cs5071A (556 990 points, decade grid): the
//! deviations within 1e-4, the noise type (Alpha) identified, and the 68.3 % confidence bounds
//! within 2 % of Stable32's — which checks noise identification, Greenhall's EDF and the χ² quantiles
//! together.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/stable32").join(rel)
}

/// One row of a Stable32 table: AF, Tau, #, Alpha, Min Sigma, Sigma, Max Sigma.
#[derive(Debug)]
struct Row {
    m: usize,
    tau: f64,
    terms: usize,
    alpha: i32,
    min: f64,
    dev: f64,
    max: f64,
}

fn stable32_table(rel: &str) -> Vec<Row> {
    let text = std::fs::read_to_string(data(rel)).unwrap();
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            Row {
                m: f[0].parse().unwrap(),
                tau: f[1].parse().unwrap(),
                terms: f[2].parse().unwrap(),
                alpha: f[3].parse().unwrap(),
                min: f[4].parse().unwrap(),
                dev: f[5].parse().unwrap(),
                max: f[6].parse().unwrap(),
            }
        })
        .collect()
}

/// Runs `fdavar allan FILE --rate 1 --phase --json` with extra flags; returns the `points` array.
fn fdavar_allan(file: &Path, extra: &[&str]) -> (serde_json::Value, Vec<serde_json::Value>) {
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .arg("allan")
        .arg(file)
        .args(["--rate", "1", "--phase", "--json"])
        .args(extra)
        .output()
        .unwrap();
    assert!(out.status.success(), "fdavar failed: {}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let points = v["points"].as_array().unwrap().clone();
    (v, points)
}

fn rel(a: f64, b: f64) -> f64 {
    (a / b - 1.0).abs()
}

fn point_at(points: &[serde_json::Value], m: usize) -> &serde_json::Value {
    points
        .iter()
        .find(|p| p["m"].as_u64() == Some(m as u64))
        .unwrap_or_else(|| panic!("no point at m = {m}"))
}

fn check_phase_dat(estimator: &str, table: &str, taus: &str) {
    let (head, points) = fdavar_allan(&data("PHASE.DAT"), &["--taus", taus, "--estimator", estimator]);
    assert_eq!(head["estimator"], estimator);
    assert_eq!(head["tau0"], 1.0);
    assert_eq!(head["data"], "phase");
    let rows = stable32_table(table);
    assert!(rows.len() >= 8);
    for r in &rows {
        let p = point_at(&points, r.m);
        assert_eq!(p["terms"].as_u64().unwrap() as usize, r.terms, "{estimator} m={}", r.m);
        assert!(rel(p["tau"].as_f64().unwrap(), r.tau) < 1e-12);
        let dev = p["dev"].as_f64().unwrap();
        assert!(rel(dev, r.dev) < 1e-4, "{estimator} m={}: {dev} vs Stable32 {}", r.m, r.dev);
        let (lo, hi) = (p["ci_low"].as_f64().unwrap(), p["ci_high"].as_f64().unwrap());
        assert!(lo < dev && dev < hi, "{estimator} m={}: bounds {lo} {hi} around {dev}", r.m);
    }
}

#[test]
fn phase_dat_oadev_all() {
    check_phase_dat("oadev", "phase_dat_oadev.txt", "all");
}

#[test]
fn phase_dat_oadev_octave() {
    check_phase_dat("oadev", "phase_dat_oadev_octave.txt", "octave");
}

#[test]
fn phase_dat_adev_all() {
    check_phase_dat("adev", "phase_dat_adev.txt", "all");
}

#[test]
fn phase_dat_mdev_all() {
    check_phase_dat("mdev", "phase_dat_mdev.txt", "all");
}

#[test]
fn phase_dat_hdev_all() {
    check_phase_dat("hdev", "phase_dat_hdev.txt", "all");
}

/// The Cs5071A record, decompressed once into a temporary plain-text file.
fn cs5071a_phase() -> &'static Path {
    static FILE: std::sync::OnceLock<tempfile::TempPath> = std::sync::OnceLock::new();
    FILE.get_or_init(|| {
        let gz = std::fs::File::open(data("cs5071a/5071A_phase.txt.gz")).unwrap();
        let mut text = String::new();
        flate2::read::GzDecoder::new(gz).read_to_string(&mut text).unwrap();
        let mut tmp = tempfile::NamedTempFile::new().unwrap();
        std::io::Write::write_all(&mut tmp, text.as_bytes()).unwrap();
        tmp.into_temp_path()
    })
}

fn check_cs5071a(estimator: &str, table: &str) {
    let (_, points) = fdavar_allan(cs5071a_phase(), &["--taus", "decade", "--estimator", estimator]);
    let rows = stable32_table(table);
    assert_eq!(rows.len(), 16);
    let mut report = Vec::new();
    for r in &rows {
        let p = point_at(&points, r.m);
        let dev = p["dev"].as_f64().unwrap();
        let (lo, hi) = (p["ci_low"].as_f64().unwrap(), p["ci_high"].as_f64().unwrap());
        report.push(format!(
            "m={:>6} α={:>2}/{:>2} edf={:>12.2} dev {:+.1e} lo {:+.2e} hi {:+.2e}",
            r.m,
            p["alpha"],
            r.alpha,
            p["edf"].as_f64().unwrap(),
            dev / r.dev - 1.0,
            lo / r.min - 1.0,
            hi / r.max - 1.0
        ));
        assert_eq!(p["terms"].as_u64().unwrap() as usize, r.terms, "{estimator} m={}", r.m);
        assert!(rel(dev, r.dev) < 1e-4, "{estimator} m={}: {dev} vs {}", r.m, r.dev);
    }
    eprintln!("{estimator} vs Stable32 (ours/theirs − 1):\n{}", report.join("\n"));
    for r in &rows {
        let p = point_at(&points, r.m);
        assert_eq!(p["alpha"].as_i64(), Some(i64::from(r.alpha)), "{estimator} m={}: noise id", r.m);
        let (lo, hi) = (p["ci_low"].as_f64().unwrap(), p["ci_high"].as_f64().unwrap());
        assert!(rel(lo, r.min) < 0.02, "{estimator} m={}: low bound {lo} vs {}", r.m, r.min);
        assert!(rel(hi, r.max) < 0.02, "{estimator} m={}: high bound {hi} vs {}", r.m, r.max);
    }
}

#[test]
fn cs5071a_oadev_decade_with_bounds() {
    check_cs5071a("oadev", "cs5071a/oadev_decade.txt");
}

#[test]
fn cs5071a_adev_decade_with_bounds() {
    check_cs5071a("adev", "cs5071a/adev_decade.txt");
}

#[test]
fn cs5071a_mdev_decade_with_bounds() {
    check_cs5071a("mdev", "cs5071a/mdev_decade.txt");
}

#[test]
fn cs5071a_hdev_decade_with_bounds() {
    check_cs5071a("hdev", "cs5071a/hdev_decade.txt");
}
