//! The exit-code contract of `fdavar` (issue 12), one test per subcommand, each code it can give:
//! 0 ok — also when a model fails (the misfit is the finding, a warning line); 1 runtime error,
//! one `fdavar: error: …` line; 2 usage error (clap, or a flag the input needs); 3 finished with
//! warnings — samples left out, or a failing model under `--strict`.
//!
//! Every case checks the code and the stderr line(s) it must print, nothing more and nothing less.
//! Codes a subcommand cannot give are named in its test (e.g. `allan` never warns).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The bundled recording whose N,B,K model fits every axis (fit_error 0.93–1.22).
const CLEAN: &str = "bags/clean";
/// The bundled recording with hidden effects: N,B,K fails on five axes.
const EFFECTS: &str = "bags/effects";

/// Runs `fdavar ARGS` from the repository root; returns the exit code and stderr.
fn fdavar(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run fdavar");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "fdavar {args:?} panicked: {stderr}");
    (out.status.code().expect("exit code"), stderr)
}

/// Asserts the code and that stderr is exactly these lines (each a prefix + fragments it holds).
#[track_caller]
fn expect(args: &[&str], code: i32, lines: &[(&str, &[&str])]) {
    let (got, stderr) = fdavar(args);
    assert_eq!(got, code, "fdavar {args:?}: exit {got}, stderr:\n{stderr}");
    let printed: Vec<&str> = stderr.lines().collect();
    assert_eq!(printed.len(), lines.len(), "fdavar {args:?}: stderr lines:\n{stderr}");
    for (line, (prefix, fragments)) in printed.iter().zip(lines) {
        assert!(line.starts_with(prefix), "fdavar {args:?}: {line:?} should start with {prefix:?}");
        // A cause is said once: an error that is another's source is not also in its message.
        assert!(line.matches("(os error").count() <= 1, "fdavar {args:?}: {line:?} repeats its cause");
        for f in *fragments {
            assert!(line.contains(f), "fdavar {args:?}: {line:?} should contain {f:?}");
        }
    }
}

/// A clap usage error: exit 2, clap's `error: …` (the culprit on that line, or on the indented
/// lines listing missing arguments), then its usage hint.
#[track_caller]
fn expect_usage(args: &[&str], fragments: &[&str]) {
    let (got, stderr) = fdavar(args);
    assert_eq!(got, 2, "fdavar {args:?}: exit {got}, stderr:\n{stderr}");
    assert!(stderr.starts_with("error: "), "fdavar {args:?}: {stderr}");
    let message = stderr.split("\n\n").next().unwrap_or_default();
    for f in fragments {
        assert!(message.contains(f), "fdavar {args:?}: {message:?} should contain {f:?}");
    }
    assert!(stderr.contains("--help"), "fdavar {args:?}: no hint to --help in {stderr}");
}

/// A runtime error: exit 1 and exactly one `fdavar: error:` line holding the fragments.
#[track_caller]
fn expect_error(args: &[&str], fragments: &[&str]) {
    expect(args, 1, &[("fdavar: error: ", fragments)]);
}

/// White noise samples (seeded), one per line.
fn noise_file(dir: &Path, n: usize) -> PathBuf {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let text: String = (0..n)
        .map(|_| format!("{:.9}\n", 1e-3 * rng.sample::<f64, _>(StandardNormal)))
        .collect();
    let path = dir.join("noise.txt");
    std::fs::write(&path, text).unwrap();
    path
}

/// A six-axis white-noise bag `name` with one message per stamp, in the order given.
fn stamped_bag(dir: &Path, name: &str, stamps: impl IntoIterator<Item = i64>) -> PathBuf {
    let bag = dir.join(name);
    let mut writer = fdavar::bag::BagWriter::create(&bag).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for stamp_ns in stamps {
        let mut n = |s: f64| s * rng.sample::<f64, _>(StandardNormal);
        let sample = fdavar::signal::ImuSample {
            stamp_ns,
            gyro: [n(1.7e-3), n(1.7e-3), n(1.7e-3)],
            accel: [n(2e-2), n(2e-2), 9.81 + n(2e-2)],
        };
        writer.write_imu("/imu/data", stamp_ns, &sample, "imu_link").unwrap();
    }
    writer.finish().unwrap();
    bag
}

/// A 60 s, 100 Hz six-axis white-noise bag with one gap of five samples at 10 s.
fn gap_bag(dir: &Path) -> PathBuf {
    let stamps = (0..6000i64).filter(|k| !(1000..1005).contains(k));
    stamped_bag(dir, "gap_bag", stamps.map(|k| 1_000_000_000 + k * 10_000_000))
}

const GAP_LINE: (&str, &[&str]) = ("fdavar: warning: ", &["1 gaps", "left out and counted"]);

#[test]
fn allan_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let file = noise_file(dir.path(), 2000);
    let file = file.to_str().unwrap();
    expect(&["allan", file, "--rate", "100"], 0, &[]);
    expect_error(&["allan", "no/such/file.txt", "--rate", "100"], &["no/such/file.txt"]);
    expect_error(&["allan", file, "--rate", "0"], &["--rate", "positive"]);
    expect_usage(&["allan", file], &["--rate"]);
    expect_usage(&["allan", file, "--rate", "100", "--taus", "often"], &["often", "--taus"]);
    // 3: never — a text series has no stamps to be irregular and nothing is fitted.
}

#[test]
fn davar_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let file = noise_file(dir.path(), 3600);
    let file = file.to_str().unwrap();
    let gap = gap_bag(dir.path());
    let gap = gap.to_str().unwrap();
    expect(&["davar", file, "--rate", "33.333333", "--every", "1000"], 0, &[]);
    expect_error(&["davar", file], &["--rate"]);
    expect_error(&["davar", "no/such/file.txt", "--rate", "100"], &["no/such/file.txt"]);
    expect_usage(&["davar", file, "--json", "--csv"], &["--json", "--csv"]);
    expect(&["davar", gap, "--axis", "gyro_x", "--every", "100000"], 3, &[GAP_LINE]);
    // --out: figures from a bag with a gap are still drawn (3), an unwritable directory is 1.
    let figs = dir.path().join("figs");
    expect(&["davar", gap, "--axis", "gyro_x", "--every", "100000", "--out", figs.to_str().unwrap()], 3, &[GAP_LINE]);
    assert!(figs.join("davar_surface_gyro_x.png").is_file() && figs.join("window_trace_gyro_x.svg").is_file());
    let blocked = blocked_dir(dir.path());
    expect_error(&["davar", file, "--rate", "100", "--every", "1000", "--out", &blocked], &["cannot draw", "gyro_x"]);
    // The cause once, at the end of the line (it was printed twice: in the message and as its
    // source).
    let (_, stderr) = fdavar(&["davar", file, "--rate", "100", "--every", "1000", "--out", &blocked]);
    assert_eq!(stderr.matches("Not a directory").count(), 1, "{stderr}");
    assert!(stderr.trim_end().ends_with("Not a directory (os error 20)"), "{stderr}");
}

/// A path below a regular file: no directory can be created there.
fn blocked_dir(dir: &Path) -> String {
    let file = dir.join("a_file");
    std::fs::write(&file, "").unwrap();
    file.join("out").to_str().unwrap().to_string()
}

#[test]
fn fit_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let gap = gap_bag(dir.path());
    let gap = gap.to_str().unwrap();
    expect(&["fit", CLEAN, "--model", "N,B,K"], 0, &[]);
    expect(&["fit", CLEAN, "--model", "N,B,K", "--strict"], 0, &[]);
    // The misfit is the finding: a warning pointing at `diagnose`, exit 0; 3 only with --strict.
    let misfit: (&str, &[&str]) = (
        "fdavar: warning: the model fails on ",
        &["gyro_x", "accel_z", "fit_error > 2", "`fdavar diagnose` suggests"],
    );
    expect(&["fit", EFFECTS, "--model", "N,B,K"], 0, &[misfit]);
    expect(&["fit", EFFECTS, "--model", "N,B,K", "--strict"], 3, &[misfit]);
    expect(&["fit", gap, "--model", "N,B,K", "--axis", "gyro_x"], 3, &[GAP_LINE]);
    expect_error(&["fit", "no/such/bag", "--model", "N"], &["no/such/bag"]);
    let blocked = blocked_dir(dir.path());
    expect_error(&["fit", CLEAN, "--model", "N", "--axis", "gyro_x", "--csv", &blocked], &["cannot write", "allan_gyro_x.csv"]);
    expect_error(&["fit", CLEAN, "--model", "N", "--axis", "gyro_x", "--out", &blocked], &["cannot write the figure of gyro_x"]);
    expect_usage(&["fit", CLEAN, "--model", "N,Bogus"], &["'N,Bogus'", "--model", "unknown effect 'Bogus'"]);
    expect_usage(&["fit", CLEAN], &["--model"]);
}

#[test]
fn diagnose_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let gap = gap_bag(dir.path());
    let gap = gap.to_str().unwrap();
    expect(&["diagnose", CLEAN], 0, &[]);
    // Its warning must not send the user to the command they just ran.
    let misfit: (&str, &[&str]) = (
        "fdavar: warning: the model fails on ",
        &["gyro_x", "accel_z", "fit_error > 2", "suggestions"],
    );
    expect(&["diagnose", EFFECTS], 0, &[misfit]);
    let (_, stderr) = fdavar(&["diagnose", EFFECTS]);
    assert!(!stderr.contains("fdavar diagnose"), "{stderr}");
    expect(&["diagnose", EFFECTS, "--strict"], 3, &[misfit]);
    expect(&["diagnose", gap, "--axis", "gyro_x"], 3, &[GAP_LINE]);
    expect_error(&["diagnose", "no/such/bag"], &["no/such/bag"]);
    expect_usage(&["diagnose", CLEAN, "--model", "Bogus"], &["unknown effect 'Bogus'"]);
    expect_usage(&["diagnose", CLEAN, "--axis", "gyro_w"], &["gyro_w"]);
    let blocked = blocked_dir(dir.path());
    expect_error(&["diagnose", CLEAN, "--axis", "gyro_x", "--csv", &blocked], &["cannot write", "allan_gyro_x.csv"]);
}

#[test]
fn simulate_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim");
    let out = out.to_str().unwrap();
    let spec = dir.path().join("spec.yaml");
    std::fs::write(&spec, "rate_hz: 100\nduration_s: 20\nseed: 3\naxes:\n  gyro_x: { N: { n: 1.0e-4 } }\n").unwrap();
    let spec = spec.to_str().unwrap();
    expect(&["simulate", spec, "--out", out], 0, &[("fdavar: wrote 2000 IMU", &[out])]);
    // 1: the bag exists (no --force); a spec that names an unknown effect.
    expect_error(&["simulate", spec, "--out", out], &[out]);
    // The path once: the bag's error names it, the command's context does not again.
    let (_, stderr) = fdavar(&["simulate", spec, "--out", out]);
    assert_eq!(stderr.matches(out).count(), 1, "{stderr}");
    let bad = dir.path().join("bad.yaml");
    std::fs::write(&bad, "rate_hz: 100\nduration_s: 20\nseed: 3\naxes:\n  gyro_x: { Bogus: { n: 1.0 } }\n").unwrap();
    expect_error(&["simulate", bad.to_str().unwrap(), "--out", out, "--force"], &["Bogus"]);
    expect_usage(&["simulate", spec], &["--out"]);
    // 3: never — a simulation has nothing left out.
}

#[test]
fn info_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let gap = gap_bag(dir.path());
    // Irregular stamps are what info reports, not a warning: exit 0 with the counts on stdout.
    expect(&["info", gap.to_str().unwrap()], 0, &[]);
    expect(&["info", CLEAN], 0, &[]);
    expect_error(&["info", "no/such/bag"], &["no/such/bag"]);
    expect_error(&["info", CLEAN, "--topic", "/nope"], &["/nope"]);
    expect_usage(&["info"], &["<BAG>"]);
    // 3: never — irregular stamps are its report (above).
}

#[test]
fn export_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let gap = gap_bag(dir.path());
    let gap = gap.to_str().unwrap();
    expect(&["export", "kalibr", CLEAN], 0, &[]);
    // A failing model still exports (its numbers are the finding's), with the fit's warning.
    let misfit: (&str, &[&str]) = ("fdavar: warning: the model fails on ", &["gyro_x", "fit_error > 2"]);
    expect(&["export", "vins", EFFECTS], 0, &[misfit]);
    // 3: samples left out; and the bag is white noise only, so no gyro axis resolves K.
    let unresolved: (&str, &[&str]) = ("fdavar: warning: gyroscope_random_walk written as 0", &["set it by hand"]);
    expect(&["export", "openvins", gap, "--inflate", "10"], 3, &[GAP_LINE, unresolved]);
    expect_error(&["export", "kalibr", "no/such/bag"], &["no/such/bag"]);
    expect_error(&["export", "kalibr", CLEAN, "--topic", "/nope"], &["/nope"]);
    expect_usage(&["export", "rovio", CLEAN], &["rovio", "kalibr, openvins, vins"]);
    expect_usage(&["export", "kalibr", CLEAN, "--model", "N,Bogus"], &["unknown effect 'Bogus'"]);
    // Usage errors found once the input is read: one `fdavar: error:` line, exit 2.
    expect(&["export", "kalibr", CLEAN, "--model", "B,K"], 2, &[("fdavar: error: --model B,K", &["N (white)"])]);
    expect(&["export", "kalibr", CLEAN, "--inflate=-1"], 2, &[("fdavar: error: --inflate", &["-1"])]);
}

/// Without DDS only the failures that come before the first publisher: a missing bag (1) and
/// a usage error (2). 0 and 3 need DDS: tests/ros_interop.rs
/// (`fdavar_play_replays_a_recording_into_the_node_without_loss`,
/// `fdavar_play_without_a_subscriber_exits_3`).
#[cfg(feature = "ros")]
#[test]
fn play_exit_codes_before_dds() {
    expect_error(&["play", "no/such/bag"], &["no/such/bag"]);
    expect_usage(&["play", CLEAN, "--rate", "fast"], &["fast", "--rate"]);
}

/// Issue 13, bad input that gave silent wrong results (exit 0): each now gives its exit code and
/// the line that says what happened.
#[test]
fn stamps_that_hid_their_trouble_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let path = |p: PathBuf| p.to_str().unwrap().to_string();
    // All stamps equal, or every stamp earlier than the one before: no period, nothing analysed
    // (it printed zero rows and exited 0).
    let equal = path(stamped_bag(dir, "equal", [5_000_000_000; 300]));
    let reversed = (0..300i64).rev().map(|k| 1_000_000_000 + k * 10_000_000);
    let reversed = path(stamped_bag(dir, "reversed", reversed));
    for bag in [&equal, &reversed] {
        let said = "none of its 300 IMU stamps is later than the one before it";
        expect_error(&["davar", bag], &[bag, said, "tau0"]);
        let (code, _) = fdavar(&["davar", bag, "--json"]);
        assert_eq!(code, 1);
    }
    // 100 Hz for 20 s, then 400 Hz for 20 s: τ0 stays 10 ms, so every later τ is 4× too long.
    let fast = (0..2000i64)
        .map(|k| k * 10_000_000)
        .chain((1..=8000).map(|k| 20_000_000_000 + k * 2_500_000));
    let rate = path(stamped_bag(dir, "rate_change", fast.map(|t| 1_000_000_000 + t)));
    let changed: (&str, &[&str]) = (
        "fdavar: warning: 0 gaps, 0 duplicate and 0 backwards stamps, 0 non-finite values",
        &["; the rate changed 1 times by more than 20 % from 1/tau0"],
    );
    expect(&["davar", &rate, "--axis", "gyro_x", "--every", "100000"], 3, &[changed]);
    expect(&["diagnose", &rate, "--axis", "gyro_x"], 3, &[changed]);
    // 20 late messages, each stamped 0.5 s back: diagnose counts them as davar does (it sorted
    // them away and reported none), and info says the same.
    let late = (0..6000i64).flat_map(|k| {
        let t = 1_000_000_000 + k * 10_000_000;
        if k % 300 == 299 {
            vec![t, t - 500_000_000]
        } else {
            vec![t]
        }
    });
    let late = path(stamped_bag(dir, "late", late));
    let backwards: (&str, &[&str]) = (
        "fdavar: warning: 0 gaps, 0 duplicate and 20 backwards stamps",
        &["left out and counted"],
    );
    expect(&["davar", &late, "--axis", "gyro_x", "--every", "100000"], 3, &[backwards]);
    expect(&["diagnose", &late, "--axis", "gyro_x"], 3, &[backwards]);
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["info", &late])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8_lossy(&out.stdout);
    let counted = "gaps 0, duplicated stamps 0, backward stamps 20, non-finite values 0";
    assert!(text.contains(counted), "{text}");
}

/// Issue 13: `model` read `N,,B` as `N,B`, and asking for `temperature` on a recording without
/// a temperature topic must say so.
#[test]
fn model_specs_that_cannot_be_meant_are_refused() {
    let empty = "empty effect name in model spec";
    expect_usage(&["fit", CLEAN, "--model", "N,,B"], &["'N,,B'", &format!("{empty} 'N,,B'")]);
    expect_usage(&["diagnose", CLEAN, "--model", "N,B,"], &[&format!("{empty} 'N,B,'")]);
    expect_error(
        &["fit", CLEAN, "--model", "N,temperature", "--axis", "gyro_x"],
        &["gyro_x: effect 'temperature' needs a temperature topic, which this recording does not \
           have"],
    );
}

/// Issue 13: `simulate` wrote a bag of duplicate stamps at `rate_hz: 1e12`, aliased a sinusoid
/// above the Nyquist frequency, and wrote the topic `/imu data//`.
#[test]
fn simulate_refuses_what_a_recording_cannot_hold() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim");
    let out = out.to_str().unwrap();
    for (body, fragments) in [
        (
            "rate_hz: 1.0e12\nduration_s: 1.0e-9",
            &["spec field 'rate_hz': 1000000000000 Hz gives tau0 = 1e-12 s, outside [1e-5, 8.64e4] s"]
                [..],
        ),
        (
            "rate_hz: 100\nduration_s: 20\naxes:\n  gyro_x: { sinusoid: { amplitude: 1.0e-3, \
             frequency_hz: 60 } }",
            &[
                "spec field 'axes.gyro_x.sinusoid.frequency_hz': 60 Hz is above",
                "(50 Hz, the Nyquist frequency)",
            ],
        ),
        (
            "rate_hz: 100\nduration_s: 20\ntopics: { imu: /imu data// }",
            &["spec field 'topics.imu': '/imu data//' is not a ROS 2 topic name"],
        ),
    ] {
        let spec = dir.path().join("spec.yaml");
        std::fs::write(&spec, format!("seed: 3\n{body}\n")).unwrap();
        expect_error(&["simulate", spec.to_str().unwrap(), "--out", out], fragments);
        assert!(!Path::new(out).exists(), "{body}: a bag was written");
    }
}

/// The top level: no subcommand or an unknown one is a usage error (2); `--help` and `--version`
/// exit 0 and the help lists the codes; a reader that stops early (`fdavar … | head`) is not an
/// error: exit 0, nothing on stderr.
#[test]
fn top_level_exit_codes() {
    // No subcommand: the help, on stderr, exit 2.
    let (code, stderr) = fdavar(&[]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("Usage: fdavar <COMMAND>"), "{stderr}");
    expect_usage(&["bogus"], &["bogus"]);
    let help = Command::new(env!("CARGO_BIN_EXE_fdavar")).arg("--help").output().unwrap();
    assert_eq!(help.status.code(), Some(0));
    let help = String::from_utf8_lossy(&help.stdout);
    for code in ["0  ok", "1  runtime error", "2  usage error", "3  finished with warnings"] {
        assert!(help.contains(code), "--help lacks {code:?}:\n{help}");
    }
    expect(&["--version"], 0, &[]);

    use std::io::{BufRead, BufReader};
    let dir = tempfile::tempdir().unwrap();
    let file = noise_file(dir.path(), 20_000);
    let mut child = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["davar", file.to_str().unwrap(), "--rate", "100", "--csv"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut first).unwrap();
    assert!(first.starts_with("axis,time_s"), "{first}");
    // The reader is dropped: the rest of the CSV meets a closed pipe.
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.stderr.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));
}
