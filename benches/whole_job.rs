//! The whole job against allantools, on the same data, in one run (issue 11).
//!
//! Run: `cargo bench --bench whole_job -- [HOURS] [JOBS] [REPEATS]` (defaults 1, the CPU count, 3).
//!
//! Untimed setup: `fdavar simulate` writes HOURS of bags/specs/clean.yaml at 100 Hz into a
//! temporary directory, and the six axes are exported as raw little-endian f64 for Python.
//! Timed, REPEATS times each, interleaved (fdavar, allantools, fdavar, …), medians printed:
//! - `fdavar analyze BAG --json --jobs JOBS` as a process, wall clock: bag decoded once, F-DAVAR
//!   rows and events of the six axes, the N,B,K fit and the diagnosis;
//! - allantools' static OADEV (`allantools.oadev`, frequency data, rate 100 Hz) of the six axes at
//!   the τ of the fit's grid (ten per decade up to a third of the record), the data already in
//!   memory (only the `oadev` calls are timed; Python from `FDAVAR_PYTHON`, else
//!   `<crate>/.venv/bin/python`, as tests/common finds it).
//!
//! Prints the ratio (allantools / fdavar; above 1: fdavar does the whole job faster than
//! allantools does OADEV alone) of the two medians and the median of the pairs' ratios, and an
//! FNV-1a 64 checksum of fdavar's JSON, the same on every repeat (checked) and the same across
//! builds that change no result.

#[path = "../tests/common/mod.rs"]
mod common;

use fdavar::allan::TauGrid;
use fdavar::bag::{BagMessage, BagReader};
use fdavar::signal::Axis;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const RATE_HZ: f64 = 100.0;

/// allantools over the six axes of a raw file; prints the seconds the `oadev` calls took.
const PYTHON: &str = r#"
import sys, time, numpy as np, allantools
path, n, rate = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
taus = [float(t) for t in sys.argv[4].split(",")]
axes = np.fromfile(path, dtype="<f8").reshape(6, n)
t0 = time.perf_counter()
for y in axes:
    allantools.oadev(y, rate=rate, data_type="freq", taus=taus)
print(time.perf_counter() - t0)
"#;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let hours: f64 = args.first().and_then(|a| a.parse().ok()).unwrap_or(1.0);
    let jobs: Option<usize> = args.get(1).and_then(|a| a.parse().ok());
    let repeats: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(3).max(1);
    let dir = tempfile::tempdir().expect("temporary directory");
    let bag = simulate(dir.path(), hours);
    let (raw, n) = export(&bag, &dir.path().join("axes.f64"));
    let fdavar = env!("CARGO_BIN_EXE_fdavar");

    let mut cmd = Command::new(fdavar);
    cmd.args(["analyze", bag.to_str().unwrap(), "--json"]);
    if let Some(j) = jobs {
        cmd.args(["--jobs", &j.to_string()]);
    }
    let factors = TauGrid::default().factors(n / 3);
    let taus: Vec<String> = factors.iter().map(|m| format!("{:?}", *m as f64 / RATE_HZ)).collect();
    // Without allantools the baseline is left out, python_with saying why.
    let mut python = common::python_with("import numpy, allantools", ".ci/python-allan.txt");
    let (mut ours, mut theirs, mut sums) = (Vec::new(), Vec::new(), Vec::new());
    // Interleaved, one of each per repeat: a host whose speed drifts over the minutes of the run
    // then slows both alike, and each pair's ratio is taken in the same moment.
    for _ in 0..repeats {
        let t0 = Instant::now();
        let out = cmd.output().expect("run fdavar analyze");
        ours.push(t0.elapsed().as_secs_f64());
        assert!(
            out.status.code().is_some_and(|c| c == 0 || c == 3),
            "fdavar analyze failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        sums.push(fnv1a(&out.stdout));
        let Some(py) = &python else { continue };
        let out = Command::new(py)
            .args(["-c", PYTHON, raw.to_str().unwrap(), &n.to_string(), &RATE_HZ.to_string(), &taus.join(",")])
            .output();
        match out {
            Ok(out) if out.status.success() => {
                theirs.push(String::from_utf8_lossy(&out.stdout).trim().parse::<f64>().expect("seconds"))
            }
            Ok(out) => {
                println!("allantools baseline skipped: {}", String::from_utf8_lossy(&out.stderr).trim());
                python = None;
            }
            Err(e) => {
                println!("allantools baseline skipped: {}: {e} (set FDAVAR_PYTHON)", py.display());
                python = None;
            }
        }
    }
    assert!(sums.windows(2).all(|w| w[0] == w[1]), "the JSON differs between repeats");

    println!(
        "{hours} h at {RATE_HZ} Hz ({n} messages), {} jobs",
        jobs.map_or_else(|| "default".to_string(), |j| j.to_string())
    );
    println!("fdavar analyze (whole job, process wall): median {:.3} s of {:?}", median(&ours), ours);
    if !theirs.is_empty() {
        println!(
            "allantools OADEV, 6 axes, {} tau (data in memory): median {:.3} s of {:?}",
            factors.len(),
            median(&theirs),
            theirs
        );
        println!("ratio allantools / fdavar: {:.2}", median(&theirs) / median(&ours));
        if theirs.len() == ours.len() {
            let pairs: Vec<f64> = theirs.iter().zip(&ours).map(|(t, o)| t / o).collect();
            let formatted: Vec<String> = pairs.iter().map(|r| format!("{r:.2}")).collect();
            println!("ratio of each interleaved pair: median {:.2} of [{}]", median(&pairs), formatted.join(", "));
        }
    }
    println!("JSON checksum (FNV-1a 64): {:016x}", sums[0]);
}

/// `fdavar simulate` of `hours` of bags/specs/clean.yaml.
fn simulate(dir: &Path, hours: f64) -> PathBuf {
    let spec = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/bags/specs/clean.yaml"))
        .expect("bags/specs/clean.yaml")
        .replace("duration_s: 120", &format!("duration_s: {}", (hours * 3600.0).round()));
    let spec_path = dir.join("clean.yaml");
    std::fs::write(&spec_path, spec).expect("write the spec");
    let bag = dir.join("bag");
    let made = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["simulate", spec_path.to_str().unwrap(), "--out", bag.to_str().unwrap()])
        .output()
        .expect("run fdavar simulate");
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    bag
}

/// The six axes of the bag's IMU topic, axis after axis, as raw little-endian f64; their length.
fn export(bag: &Path, raw: &Path) -> (PathBuf, usize) {
    let reader = BagReader::open(bag).expect("open the bag");
    let topic = reader.imu_topic(None).expect("an Imu topic").name.clone();
    let mut axes: [Vec<f64>; 6] = Default::default();
    for m in reader.messages(&topic, None).expect("messages") {
        if let BagMessage::Imu { sample, .. } = m.expect("a message") {
            for a in Axis::ALL {
                axes[a.index()].push(sample.value(a));
            }
        }
    }
    let bytes: Vec<u8> = axes.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(raw, bytes).expect("write the raw axes");
    (raw.to_path_buf(), axes[0].len())
}

/// FNV-1a, 64 bits: a checksum that does not depend on the Rust version (unlike `DefaultHasher`).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}
