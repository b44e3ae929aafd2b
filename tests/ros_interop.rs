//! Interop tests of `fdavar_node` against a real ROS 2 peer: rclpy + Fast DDS from PyPI
//! (tests/ros/peer.py). Each test runs the node on a ROS_DOMAIN_ID of its own, so tests in parallel
//! never see each other, and every wait is bounded.
//!
//! Python comes from `FDAVAR_PYTHON` (default `.venv/bin/python`, made by `.ci/setup-ros.sh`). When
//! it or rclpy is missing the test prints why and passes, unless `FDAVAR_REQUIRE_PYTHON=1`.
#![cfg(feature = "ros")]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

// Only `param_as_message` is used here; this binary finds its Python itself.
#[allow(dead_code)]
mod common;

fn crate_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The Python with rclpy, or None (skip) with the reason printed.
fn python() -> Option<PathBuf> {
    let path = std::env::var_os("FDAVAR_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| crate_root().join(".venv/bin/python"));
    let ok = Command::new(&path)
        .args([
            "-c",
            "import rclpy, sensor_msgs.msg, diagnostic_msgs.msg, rosgraph_msgs.msg",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        return Some(path);
    }
    let why = format!(
        "{} cannot import rclpy (run .ci/setup-ros.sh .venv)",
        path.display()
    );
    if std::env::var("FDAVAR_REQUIRE_PYTHON").as_deref() == Ok("1") {
        panic!("{why}");
    }
    eprintln!("skipped: {why}");
    None
}

/// The colcon install tree built by .ci/setup-ros.sh, if present (gives fdavar_msgs to Python).
fn colcon_install() -> Option<PathBuf> {
    let p = crate_root().join("target/colcon_ws/install");
    p.join("fdavar_msgs").is_dir().then_some(p)
}

/// A child process killed when the test ends, whatever happens.
struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The node's reader history for replays that must arrive whole: reliable DDS with keep-last
/// 100 (the default) drops a sample whenever the node's receive thread is 100 behind, which a
/// loaded CI core causes (478 of 12 000 lost, measured with a soak next to the suite).
const LOSSLESS_DEPTH: &str = "qos.depth:=10000";

fn start_node(domain: u16, ros_args: &[&str]) -> Killed {
    let child = Command::new(env!("CARGO_BIN_EXE_fdavar_node"))
        .arg("--ros-args")
        .args(ros_args)
        .env("ROS_DOMAIN_ID", domain.to_string())
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("spawn fdavar_node");
    Killed(child)
}

/// Runs a peer scenario and returns its JSON verdict; panics with the peer's words on failure.
fn peer(
    python: &Path,
    domain: u16,
    scenario: &str,
    timeout: Duration,
    mut watch: Option<&mut Watch>,
) -> serde_json::Value {
    let mut cmd = Command::new(python);
    cmd.arg(crate_root().join("tests/ros/peer.py"))
        .args(scenario.split_whitespace())
        .env("ROS_DOMAIN_ID", domain.to_string())
        .env("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if let Some(install) = colcon_install() {
        let prefix = install.join("fdavar_msgs");
        let py = std::fs::read_dir(prefix.join("lib"))
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path().join("site-packages"))
            .find(|p| p.is_dir());
        if let Some(py) = py {
            let join = |var: &str, add: &Path| {
                let old = std::env::var(var).unwrap_or_default();
                format!("{}:{old}", add.display())
            };
            cmd.env("PYTHONPATH", join("PYTHONPATH", &py));
            cmd.env(
                "LD_LIBRARY_PATH",
                join("LD_LIBRARY_PATH", &prefix.join("lib")),
            );
            cmd.env("AMENT_PREFIX_PATH", join("AMENT_PREFIX_PATH", &prefix));
        }
    }
    let mut child = Killed(cmd.spawn().expect("spawn python"));
    // Lines arrive on a channel so that the node can be watched while the peer runs.
    let stdout = child.0.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::BufReader::new(stdout)
            .lines()
            .map_while(Result::ok)
        {
            let _ = tx.send(line);
        }
    });
    let mut stderr = child.0.stderr.take().unwrap();
    let err_reader = std::thread::spawn(move || {
        let mut err = String::new();
        use std::io::Read;
        let _ = stderr.read_to_string(&mut err);
        err
    });
    let start = Instant::now();
    let mut lines = Vec::new();
    let mut flooding = false;
    loop {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(line) => {
                flooding = match line.as_str() {
                    "flood-start" => true,
                    "flood-end" => false,
                    _ => flooding,
                };
                lines.push(line);
            }
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
        }
        if let (true, Some(pid)) = (flooding, watch.as_deref_mut()) {
            pid.rss_kb.extend(rss_kb(pid.pid));
        }
        assert!(
            start.elapsed() < timeout,
            "peer {scenario} did not finish within {timeout:?}"
        );
    }
    let _ = child.0.wait();
    let err = err_reader.join().unwrap_or_default();
    let last = lines.last().cloned().unwrap_or_default();
    let verdict: serde_json::Value = serde_json::from_str(&last).unwrap_or_else(|_| {
        panic!(
            "peer {scenario} printed no verdict.\nstdout:\n{}\nstderr:\n{err}",
            lines.join("\n")
        )
    });
    assert!(
        verdict["ok"].as_bool().unwrap_or(false),
        "peer {scenario} failed: {verdict}\nstderr:\n{err}"
    );
    verdict
}

/// A process whose resident memory is sampled while the peer floods it.
struct Watch {
    pid: u32,
    rss_kb: Vec<u64>,
}

/// Resident set size of a process, kB, from /proc.
fn rss_kb(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

#[test]
fn rclpy_imu_reaches_the_node_and_diagnostics_come_back() {
    let Some(py) = python() else { return };
    let _node = start_node(61, &["-p", "publish_rate_hz:=2.0"]);
    let v = peer(&py, 61, "diagnostics", Duration::from_secs(60), None);
    eprintln!("diagnostics: {v}");
}

#[test]
fn parameters_are_listed_set_and_refused_through_the_ros_services() {
    let Some(py) = python() else { return };
    let _node = start_node(62, &[]);
    let v = peer(&py, 62, "params", Duration::from_secs(60), None);
    eprintln!("params: {v}");
}

#[test]
fn sim_time_from_clock_drives_the_node() {
    let Some(py) = python() else { return };
    let _node = start_node(
        63,
        &["-p", "use_sim_time:=true", "-p", "publish_rate_hz:=5.0"],
    );
    let v = peer(&py, 63, "sim_time", Duration::from_secs(60), None);
    eprintln!("sim_time: {v}");
}

#[test]
fn bad_input_is_counted_and_silence_is_stale() {
    let Some(py) = python() else { return };
    let _node = start_node(
        64,
        &["-p", "publish_rate_hz:=4.0", "-p", "stale_timeout_s:=1.0"],
    );
    let v = peer(&py, 64, "bad_input", Duration::from_secs(60), None);
    eprintln!("bad_input: {v}");
}

#[test]
fn startup_config_errors_exit_non_zero_with_a_reason() {
    for (args, want) in [
        (vec!["-p", "publish_rate_hz:=-1.0"], "publish_rate_hz"),
        (vec!["-r", "__node:=9bad"], "9bad"),
        (vec!["--bogus"], "bogus"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_fdavar_node"))
            .arg("--ros-args")
            .args(&args)
            .env("ROS_DOMAIN_ID", "65")
            .output()
            .expect("run fdavar_node");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar_node"))
        .env("ROS_DOMAIN_ID", "999")
        .output()
        .expect("run fdavar_node");
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("ROS_DOMAIN_ID"));
}

#[test]
fn a_flood_is_dropped_and_counted_with_bounded_memory() {
    let Some(py) = python() else { return };
    let node = start_node(66, &["-p", "queue_size:=64", "-p", "publish_rate_hz:=4.0"]);
    let mut watch = Watch {
        pid: node.0.id(),
        rss_kb: Vec::new(),
    };
    let v = peer(&py, 66, "flood", Duration::from_secs(90), Some(&mut watch));
    eprintln!(
        "flood: {v}; node RSS during the flood (kB): {:?}",
        watch.rss_kb
    );
    let (first, max) = (watch.rss_kb[0], *watch.rss_kb.iter().max().unwrap());
    // Bounded: the queue holds 64 samples and the DDS reader keeps the last 100 messages, so the
    // flood itself may not grow the node by more than allocator noise (16 MB). What does grow is
    // the whole-run record, by design: 6 axes × 8 bytes per accepted sample (twice that while a
    // vector doubles), up to `max_samples` per axis, after which it halves its rate.
    let accepted = v["samples"].as_u64().unwrap();
    let record_kb = 2 * 6 * 8 * accepted / 1024;
    assert!(
        max - first < 16 * 1024 + record_kb,
        "RSS grew from {first} kB to {max} kB during the flood ({accepted} samples accepted: \
         the record's share is at most {record_kb} kB)"
    );
    assert!(
        v["sent"].as_u64().unwrap() >= 2000,
        "the peer did not flood: {v}"
    );
}

/// `fdavar play`'s exit 3 (tests/exit_codes.rs has 1 and 2; 0 is the replay below): no subscriber
/// matched on a domain where nobody listens, so nothing may have been delivered.
#[test]
fn fdavar_play_without_a_subscriber_exits_3() {
    // Python is not used: the gate says whether this machine has the ROS 2 environment.
    let Some(_py) = python() else { return };
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["play", concat!(env!("CARGO_MANIFEST_DIR"), "/bags/clean"), "--rate", "1000"])
        .args(["--domain-id", "91", "--wait-s", "0.5"])
        .output()
        .expect("run fdavar play");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains("12000 IMU") && err.contains("no subscriber matched"), "{err}");
    // The reason is the subscriber, said once; not a count of zero malformed messages.
    assert_eq!(err.lines().count(), 1, "{err}");
}

#[test]
fn fdavar_play_replays_a_recording_into_the_node_without_loss() {
    let Some(py) = python() else { return };
    // A recording the test writes: 1000 samples at 200 Hz with the sensor's own stamps.
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rec");
    let mut writer = fdavar::bag::BagWriter::create(&bag).unwrap();
    for k in 0..1000_i64 {
        let sample = fdavar::signal::ImuSample {
            stamp_ns: 1_000_000_000 + k * 5_000_000,
            gyro: [1e-3 * (k as f64 * 0.1).sin(), 0.0, 0.0],
            accel: [0.0, 0.0, 9.81],
        };
        // Log times lag the stamps by 1 ms, as a recorder's would.
        writer
            .write_imu(
                "/imu",
                1_700_000_000_000_000_000 + k * 5_000_000 + 1_000_000,
                &sample,
                "imu_link",
            )
            .unwrap();
    }
    writer.finish().unwrap();
    let _node = start_node(
        67,
        &["-p", "qos.reliable:=true", "-p", LOSSLESS_DEPTH, "-p", "publish_rate_hz:=5.0"],
    );
    let player = std::thread::spawn(move || {
        let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
            .args([
                "play",
                bag.to_str().unwrap(),
                "--reliable",
                "--rate",
                "2",
                "--domain-id",
                "67",
            ])
            .args(["--wait-s", "30"])
            .output()
            .expect("run fdavar play");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    });
    let v = peer(
        &py,
        67,
        "expect_samples 1000",
        Duration::from_secs(90),
        None,
    );
    let (code, err) = player.join().unwrap();
    eprintln!("play: {v}; fdavar play said: {err}");
    assert_eq!(code, Some(0), "fdavar play: {err}");
    assert!(err.contains("1000 IMU"), "{err}");
}

/// A recording with a noise change: 3600 samples at 200 Hz, white noise whose level triples
/// between samples 1200 and 2400 on every axis (the seed's test signal, at a ROS rate).
fn write_recording(bag: &Path, n: i64) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2016);
    let normal = Normal::new(0.0, 1.0).unwrap();
    write_samples(
        bag,
        (0..n).map(|k| {
            let level = if (1200..2400).contains(&k) {
                3e-3
            } else {
                1e-3
            };
            let mut v = [0.0; 6];
            for x in &mut v {
                *x = level * normal.sample(&mut rng);
            }
            sample_at(k, v)
        }),
    );
}

/// Sample k of a 200 Hz recording starting at 1 s, accel_z on top of g.
fn sample_at(k: i64, v: [f64; 6]) -> fdavar::signal::ImuSample {
    fdavar::signal::ImuSample {
        stamp_ns: 1_000_000_000 + k * 5_000_000,
        gyro: [v[0], v[1], v[2]],
        accel: [v[3], v[4], 9.81 + v[5]],
    }
}

/// Writes samples to a bag on `/imu`, log times 0.7 ms after the stamps as a recorder's would be.
fn write_samples(bag: &Path, samples: impl Iterator<Item = fdavar::signal::ImuSample>) {
    let mut writer = fdavar::bag::BagWriter::create(bag).unwrap();
    for s in samples {
        writer
            .write_imu("/imu", log_time_ns(s.stamp_ns), &s, "imu_link")
            .unwrap();
    }
    writer.finish().unwrap();
}

/// The log time [`write_samples`] records for a sample stamped `stamp_ns` (what `/clock` replays).
fn log_time_ns(stamp_ns: i64) -> i64 {
    1_700_000_000_000_000_000 + stamp_ns + 700_000
}

/// A hidden sinusoid: 60 s at 200 Hz of white noise (1e-3 per sample on every axis) with
/// 3e-3·sin(2π·2 Hz·t) added on gyro_x only (seeded).
fn sinusoid_samples() -> Vec<fdavar::signal::ImuSample> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(52);
    let normal = Normal::new(0.0, 1e-3).unwrap();
    (0..12_000_i64)
        .map(|k| {
            let mut v = [0.0; 6];
            for x in &mut v {
                *x = normal.sample(&mut rng);
            }
            v[0] += 3e-3 * (2.0 * std::f64::consts::PI * 2.0 * k as f64 * 0.005).sin();
            sample_at(k, v)
        })
        .collect()
}

/// The node's engine and monitor in process (no DDS), model N,B,K (and `gyro_x` on gyro_x if
/// given), default DAVAR settings.
fn in_process_monitor(
    diagnosis_period_s: f64,
    gyro_x: Option<&str>,
) -> fdavar::ros::monitor::Monitor {
    use fdavar::model::record::RecordBuilder;
    use fdavar::model::ModelSpec;
    use fdavar::ros::engine::AnalysisEngine;
    use fdavar::ros::monitor::{Monitor, MonitorSettings};
    let config = fdavar::params::config_from_params(&Default::default()).unwrap();
    let mut overrides: [Option<ModelSpec>; 6] = Default::default();
    overrides[0] = gyro_x.map(|m| ModelSpec::parse(m).unwrap());
    let engine =
        AnalysisEngine::new(config, ModelSpec::parse("N,B,K").unwrap(), overrides, RecordBuilder::DEFAULT_MAX_SAMPLES)
            .unwrap();
    // Rounds paced by sample time alone (no CPU budget): the samples come faster than real time.
    let settings = MonitorSettings {
        diagnosis_period_s,
        stale_timeout_s: 10.0,
        diagnosis_cpu_share: 1.0,
        ..MonitorSettings::default()
    };
    Monitor::new(settings, Some(Box::new(engine)))
}

#[test]
fn the_live_diagnosis_names_a_hidden_sinusoid_and_nothing_on_a_clean_axis() {
    // In-process (no DDS): the node's engine and monitor, fed the recording, reporting at 10 Hz of
    // sample time with a diagnosis every second.
    let mut monitor = in_process_monitor(1.0, None);
    let mut last = None;
    for (k, s) in sinusoid_samples().into_iter().enumerate() {
        let t = s.stamp_ns;
        monitor.push(s, "imu_link", t);
        if k % 20 == 19 {
            last = Some(monitor.report(t));
        }
    }
    let (array, states, _) = last.unwrap();
    let named = |axis: &str| -> Vec<String> {
        let s = states.iter().find(|s| s.axis == axis).unwrap();
        s.suggestions.iter().map(|x| x.effect.clone()).collect()
    };
    eprintln!(
        "gyro_x: {:?}\ngyro_y: {:?}",
        states[0].suggestions,
        named("gyro_y")
    );
    assert_eq!(
        named("gyro_x").first().map(String::as_str),
        Some("sinusoid")
    );
    let sinusoid = &states[0].suggestions[0];
    // The hidden values (3e-3 peak at 2 Hz) come back: 60 s hold 120 periods, so the estimates
    // are within a few per cent; 10 % leaves room for the seed.
    let param = |name: &str| {
        sinusoid
            .params
            .iter()
            .find(|p| p.name == name)
            .unwrap()
            .value
    };
    assert!(
        (param("frequency_hz") / 2.0 - 1.0).abs() < 0.1,
        "{sinusoid:?}"
    );
    assert!(
        (param("amplitude") / 3e-3 - 1.0).abs() < 0.1,
        "{sinusoid:?}"
    );
    for axis in ["gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"] {
        assert!(named(axis).is_empty(), "{axis}: {:?}", named(axis));
    }
    // /diagnostics names it and warns (level 1) on gyro_x only.
    let gx = &array.status[0];
    let cost = |i: usize| {
        let kv = array.status[i]
            .values
            .iter()
            .find(|kv| kv.key == "diagnosis_ms");
        kv.map(|kv| kv.value.clone())
    };
    eprintln!(
        "diagnosis cost: gyro_x (failing model, every candidate refitted) {:?} ms, gyro_y {:?} ms",
        cost(0),
        cost(1)
    );
    assert_eq!(gx.level, 1, "{gx:?}");
    let listed = gx.values.iter().find(|kv| kv.key == "suggestions").unwrap();
    assert!(listed.value.starts_with("sinusoid"), "{listed:?}");
    assert_eq!(array.status[1].level, 0, "{:?}", array.status[1]);
}

#[test]
fn a_played_recording_with_a_hidden_sinusoid_gets_sinusoid_suggested_over_dds() {
    // fdavar play → fdavar_node → /diagnostics and ~/gyro_x/state read by the rclpy peer.
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rec");
    let samples = sinusoid_samples();
    let n = samples.len();
    write_samples(&bag, samples.into_iter());
    let _node = start_node(
        70,
        &[
            "-p",
            "qos.reliable:=true",
            "-p",
            LOSSLESS_DEPTH,
            "-p",
            "publish_rate_hz:=10.0",
            "-p",
            "diagnosis_period_s:=1.0",
            // Every round right after the last (no CPU budget): the checks wait one round.
            "-p",
            "diagnosis_cpu_share:=1.0",
            "-p",
            "stale_timeout_s:=30.0",
        ],
    );
    let player = std::thread::spawn(move || {
        Command::new(env!("CARGO_BIN_EXE_fdavar"))
            .args(["play", bag.to_str().unwrap(), "--reliable", "--rate", "4"])
            .args(["--domain-id", "70", "--wait-s", "30"])
            .output()
            .expect("run fdavar play")
    });
    let v = peer(
        &py,
        70,
        &format!("suggestions {n}"),
        Duration::from_secs(150),
        None,
    );
    let played = player.join().unwrap();
    assert_eq!(
        played.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&played.stderr)
    );
    eprintln!("suggestions: {v}");
    let listed = v["suggestions"]["gyro_x"].as_str().unwrap();
    assert_eq!(listed.split(',').next(), Some("sinusoid"), "{v}");
    assert_eq!(v["levels"]["gyro_x"], 1, "WARN with a suggestion: {v}");
    for axis in ["gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"] {
        assert_eq!(v["suggestions"][axis], "", "{axis}: {v}");
    }
    if v["have_typed"] == true {
        let first = &v["typed"][0];
        assert_eq!(first["effect"], "sinusoid", "{v}");
        let f = first["params"]["frequency_hz"][0].as_f64().unwrap();
        assert!((f / 2.0 - 1.0).abs() < 0.1, "{v}");
        assert!(first["fit_error_after"].as_f64().unwrap() < 2.0, "{v}");
    }
}

#[test]
fn a_temperature_driven_axis_gets_a_live_temperature_coefficient() {
    // In-process: the node's engine and monitor with the temperature topic's readings (2 Hz),
    // gyro_x = 2e-4 rad/s/K·(T − 30 °C) + white noise, T a warm-up from 20 °C towards 40 °C with
    // a 30 s time constant over 100 s. With `model.gyro_x = N,B,K,temperature` the whole-run fit
    // (the path of `fdavar fit`) gives the coefficient with its 1σ; the other axes keep N,B,K.
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let run = |gyro_x: Option<&str>| {
        let mut monitor = in_process_monitor(1.0, gyro_x);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 1e-3).unwrap();
        let n = 20_000_i64;
        let mut last = None;
        for k in 0..n {
            let celsius = 20.0 + 20.0 * (1.0 - (-(k as f64 * 0.005) / 30.0).exp());
            let mut v = [0.0; 6];
            for x in &mut v {
                *x = noise.sample(&mut rng);
            }
            v[0] += 2e-4 * (celsius - 30.0);
            let s = sample_at(k, v);
            let t = s.stamp_ns;
            monitor.push(s, "imu_link", t);
            if k % 100 == 0 {
                monitor.push_temperature(&fdavar::signal::TemperatureSample {
                    stamp_ns: t,
                    celsius,
                });
            }
            if k % 20 == 19 {
                last = Some(monitor.report(t).1);
            }
        }
        last.unwrap()
    };
    let temperature = |c: &[fdavar::msgs::fdavar_msgs::Coefficient]| {
        c.iter()
            .find(|c| c.effect == "temperature" && c.name == "coefficient_per_k")
            .cloned()
    };
    let states = run(Some("N,B,K,temperature"));
    let c = temperature(&states[0].coefficients).expect("no fitted temperature coefficient");
    eprintln!("fitted on gyro_x: {c:?}");
    assert_eq!(c.unit, "rad/s/K");
    assert!((c.value / 2e-4 - 1.0).abs() < 0.1, "{c:?}");
    assert!(c.sigma > 0.0 && c.sigma < 0.05 * c.value, "{c:?}");
    assert!(states[0].fit_error < 2.0, "{}", states[0].fit_error);
    assert!(temperature(&states[1].coefficients).is_none());
}

#[test]
fn the_temperature_topic_from_rclpy_gives_a_live_coefficient_over_dds() {
    let Some(py) = python() else { return };
    let _node = start_node(
        71,
        &[
            "-p",
            "temperature:=true",
            "-p",
            "publish_rate_hz:=4.0",
            "-p",
            "stale_timeout_s:=30.0",
            "-p",
            "diagnosis_period_s:=1.0",
            // Every round right after the last (no CPU budget): the checks wait one round.
            "-p",
            "diagnosis_cpu_share:=1.0",
            "-p",
            "model.gyro_x:=N,B,K,temperature",
        ],
    );
    let v = peer(&py, 71, "temperature", Duration::from_secs(90), None);
    eprintln!("temperature: {v}");
    let gx: f64 = v["coefficient"]["gyro_x"]
        .as_str()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no temperature coefficient on gyro_x: {v}"));
    // 15 s at 200 Hz, 20 K: σ_slope ≈ 1e-3/√3000/5.8 K ≈ 3e-6, so 20 % is > 10 σ and leaves room
    // for the peer's pacing (the ramp follows wall time).
    assert!((gx / 2e-4 - 1.0).abs() < 0.2, "{v}");
    assert!(v["coefficient"]["gyro_y"].is_null(), "{v}");
}

/// What `fdavar davar BAG --json` (the real binary) prints for the recording: its rows and τ0.
fn cli_rows(bag: &Path) -> (Vec<serde_json::Value>, f64) {
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["davar", bag.to_str().unwrap(), "--json"])
        .output()
        .expect("run fdavar davar");
    assert_eq!(
        out.status.code(),
        Some(0),
        "fdavar davar: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let tau0 = json["tau0"].as_f64().unwrap();
    let serde_json::Value::Array(rows) = json["rows"].take() else {
        panic!("no rows array in fdavar davar --json");
    };
    (rows, tau0)
}

/// The node's row (an `AxisState` line of `dump_json`) against the CLI's (an `AxisRow` of
/// `fdavar davar --json`), field by field: the first difference, if any.
///
/// Exact: both programs print the same f64 with serde_json's shortest round-trip formatting, and
/// equal text parses to equal numbers, so any difference in the last bit would show.
fn row_difference(live: &serde_json::Value, cli: &serde_json::Value, tau0: f64) -> Option<String> {
    let stamp = &live["header"]["stamp"];
    let stamp_ns =
        stamp["sec"].as_i64().unwrap() * 1_000_000_000 + stamp["nanosec"].as_i64().unwrap();
    let row = &cli["row"];
    let (live_points, cli_points) = (
        live["row"].as_array().unwrap(),
        row["points"].as_array().unwrap(),
    );
    let mut pairs = vec![
        ("axis", live["axis"].clone(), cli["axis"].clone()),
        ("header.stamp", stamp_ns.into(), cli["stamp_ns"].clone()),
        (
            "analysis_time_s",
            live["analysis_time_s"].clone(),
            cli["time_s"].clone(),
        ),
        (
            "window_length",
            live["window_length"].clone(),
            row["window"].clone(),
        ),
        ("f_value", live["f_value"].clone(), row["f"].clone()),
        (
            "f_reference",
            live["f_reference"].clone(),
            row["f_target"].clone(),
        ),
        (
            "sample_period_s",
            live["sample_period_s"].clone(),
            tau0.into(),
        ),
        (
            "row length",
            live_points.len().into(),
            cli_points.len().into(),
        ),
    ];
    for (l, c) in live_points.iter().zip(cli_points) {
        for (lk, ck) in [
            ("tau_s", "tau"),
            ("avar", "avar"),
            ("avar_low", "ci_low"),
            ("avar_high", "ci_high"),
            ("edf", "edf"),
        ] {
            pairs.push((lk, l[lk].clone(), c[ck].clone()));
        }
    }
    pairs
        .into_iter()
        .find(|(_, l, c)| l != c)
        .map(|(key, l, c)| format!("{key}: node {l}, fdavar davar {c}"))
}

#[test]
fn live_rows_equal_offline_rows_for_a_replayed_recording() {
    // Rust only: fdavar play → fdavar_node (reliable) → dump_json, against `fdavar davar --json`.
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rec");
    write_recording(&bag, 3600);
    let (expected, tau0) = cli_rows(&bag);
    assert!(
        expected.len() > 6 * 3000,
        "offline gave {} rows",
        expected.len()
    );
    let dump = dir.path().join("rows.jsonl");
    let dump_arg = format!("dump_json:={}", dump.display());
    let _node = start_node(
        68,
        &[
            "-p",
            "qos.reliable:=true",
            "-p",
            LOSSLESS_DEPTH,
            "-p",
            "publish_rate_hz:=10.0",
            "-p",
            &dump_arg,
        ],
    );
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args([
            "play",
            bag.to_str().unwrap(),
            "--reliable",
            "--rate",
            "4",
            "--domain-id",
            "68",
            "--wait-s",
            "30",
        ])
        .output()
        .expect("run fdavar play");
    let said = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "fdavar play: {said}");
    // Wait (bounded) for the node to have written every row.
    let start = Instant::now();
    let mut live: Vec<serde_json::Value> = Vec::new();
    while start.elapsed() < Duration::from_secs(30) {
        let text = std::fs::read_to_string(&dump).unwrap_or_default();
        live = text
            .lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect();
        if live.len() >= expected.len() {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    eprintln!("live rows {}, offline rows {}", live.len(), expected.len());
    assert_eq!(
        live.len(),
        expected.len(),
        "the node did not produce every row"
    );
    // Counters are the node's own (samples so far): compare the analysis, field by field, in
    // order (both emit rows as the samples complete them).
    for (i, (l, o)) in live.iter().zip(&expected).enumerate() {
        assert_eq!(l["header"]["frame_id"], "imu_link", "row {i}");
        if let Some(diff) = row_difference(l, o, tau0) {
            panic!("row {i} ({} at {}) differs: {diff}", o["axis"], o["time_s"]);
        }
    }
}

/// Skips (prints why) or, under `FDAVAR_REQUIRE_PYTHON=1`, panics.
fn skip(why: &str) {
    assert!(
        std::env::var("FDAVAR_REQUIRE_PYTHON").as_deref() != Ok("1"),
        "{why}"
    );
    eprintln!("skipped: {why}");
}

#[test]
fn colcon_build_of_the_workspace_installs_the_node_where_ros2_run_looks_and_the_messages() {
    // The workspace `.ci/setup-ros.sh` prepares: target/colcon_ws/src/{fdavar -> this repository,
    // fdavar_msgs -> msg/}; colcon-ros-cargo's cargo build goes to this crate's target/, so an
    // up-to-date tree builds in seconds.
    let Some(py) = python() else { return };
    let venv = py.parent().and_then(Path::parent).unwrap().to_path_buf();
    let ws = crate_root().join("target/colcon_ws");
    let holds_repo = std::fs::canonicalize(ws.join("src/fdavar"))
        .is_ok_and(|p| Some(p) == std::fs::canonicalize(crate_root()).ok());
    if !holds_repo {
        return skip(&format!(
            "{} does not hold this repository: run .ci/setup-ros.sh .venv",
            ws.display()
        ));
    }
    let has_colcon = Command::new(&py)
        .args(["-c", "import colcon_core, colcon_ros_cargo"])
        .status()
        .is_ok_and(|s| s.success());
    if !has_colcon {
        return skip(&format!("{} cannot import colcon", py.display()));
    }
    let install = ws.join("install");
    let node = install.join("fdavar/lib/fdavar/fdavar_node");
    // Removed first, so that finding it afterwards shows this build installed it (nothing else
    // runs the installed copy: the other tests run cargo's binaries).
    let _ = std::fs::remove_file(&node);
    let start = Instant::now();
    let out = Command::new("bash")
        .arg("-c")
        .arg(format!(
            ". {}/bin/activate && export AMENT_PREFIX_PATH=$VIRTUAL_ENV && cd {} && \
             colcon build --packages-select fdavar_msgs fdavar --event-handlers console_direct- \
             --cargo-args --release",
            venv.display(),
            ws.display()
        ))
        .output()
        .expect("run colcon build");
    let said = String::from_utf8_lossy(&out.stdout);
    eprintln!(
        "colcon build: {:.1} s\n{said}{}",
        start.elapsed().as_secs_f64(),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "colcon build failed");
    assert!(said.contains("2 packages finished"), "{said}");
    assert!(node.is_file(), "{} not installed", node.display());
    // It is our node: a bad argument is refused with our message and exit code 1.
    let out = Command::new(&node)
        .args(["--ros-args", "--bogus"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--ros-args: unknown argument"));
    // fdavar_msgs imports and decodes from the install tree (what `. install/setup.sh` gives).
    let script = "from fdavar_msgs.msg import AxisState, DavarPoint; \
                  m = AxisState(); m.window_length = 171; m.row = [DavarPoint(tau_s=0.03)]; \
                  print(type(m).__name__, m.window_length, len(m.row))";
    let out = Command::new("bash")
        .arg("-c")
        .arg(format!(
            ". {}/setup.sh && {} -c '{script}'",
            install.display(),
            py.display()
        ))
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains("AxisState 171 1"),
        "stdout {said}\nstderr {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn setting_the_model_live_lowers_the_fit_error_of_a_hidden_sinusoid() {
    let Some(py) = python() else { return };
    let _node = start_node(69, &["-p", "publish_rate_hz:=2.0", "-p", "model:=N,B,K"]);
    let v = peer(&py, 69, "model", Duration::from_secs(90), None);
    eprintln!("model: {v}");
}

/// `fdavar play BAG ARGS… --domain-id D` as a child killed when the test ends.
fn start_play(bag: &Path, domain: u16, args: &[&str]) -> Killed {
    let child = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .arg("play")
        .arg(bag)
        .args(args)
        .args(["--domain-id", &domain.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run fdavar play");
    Killed(child)
}

#[test]
fn fdavar_play_clock_reaches_rclpy_and_drives_the_node_on_sim_time() {
    // Issue 9: `fdavar play --clock` sent no /clock at all (its 10 ms spacing test subtracted
    // i64::MIN, which wraps negative in a release build), so neither rclpy nor the node on
    // use_sim_time got a clock and /diagnostics stamps stayed 0.
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rec");
    let n = 4000; // 20 s at 200 Hz
    write_recording(&bag, n);
    let log_times: std::collections::BTreeSet<i64> = (0..n)
        .map(|k| log_time_ns(sample_at(k, [0.0; 6]).stamp_ns))
        .collect();
    let last_log = *log_times.last().unwrap();
    let _node = start_node(
        72,
        &[
            "-p",
            "use_sim_time:=true",
            "-p",
            "qos.reliable:=true",
            "-p",
            LOSSLESS_DEPTH,
            "-p",
            "publish_rate_hz:=10.0",
            "-p",
            "stale_timeout_s:=60.0",
        ],
    );
    let peer_thread =
        std::thread::spawn(move || peer(&py, 72, "play_clock", Duration::from_secs(150), None));
    let mut player = start_play(&bag, 72, &["--clock", "--reliable", "--wait-s", "30"]);
    let status = player.0.wait().unwrap();
    let mut said = String::new();
    std::io::Read::read_to_string(player.0.stderr.as_mut().unwrap(), &mut said).unwrap();
    assert_eq!(status.code(), Some(0), "fdavar play: {said}");
    assert!(said.contains(&format!("{n} IMU")), "{said}");
    let published: usize = said
        .lines()
        .find_map(|l| l.strip_suffix(" /clock messages published"))
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no /clock count in: {said}"));
    let v = peer_thread.join().unwrap();

    // rclpy, as a plain reliable subscriber: increasing log times of the bag, ending at the last.
    let clock: Vec<i64> = v["clock"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_i64().unwrap())
        .collect();
    eprintln!(
        "/clock: {published} published (one per 10 ms of log time: every other 5 ms message), {} \
         received by rclpy (it subscribes while the player starts)",
        clock.len()
    );
    assert!(published >= n as usize / 2, "{said}");
    assert!(
        clock.len() >= published / 2,
        "{} of {published}",
        clock.len()
    );
    assert_eq!(v["clock_increasing"], true);
    assert!(clock.iter().all(|c| log_times.contains(c)), "not log times");
    assert_eq!(
        *clock.last().unwrap(),
        last_log,
        "the clock ends at the last log time"
    );
    // rclpy's own time source (use_sim_time: best effort, depth 1) follows it too.
    assert_eq!(v["sim_now"].as_i64(), Some(last_log), "{}", v["sim_now"]);

    // The node on sim time: /diagnostics stamped with the played clock (non-zero, increasing),
    // and it analysed every sample.
    let diagnostics: Vec<(i64, u64)> = v["diagnostics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| (d[0].as_i64().unwrap(), d[1].as_u64().unwrap()))
        .collect();
    let first = diagnostics
        .iter()
        .position(|d| d.0 != 0)
        .expect("every /diagnostics stamp is 0: the node never got /clock");
    let stamps: Vec<i64> = diagnostics[first..].iter().map(|d| d.0).collect();
    let distinct: std::collections::BTreeSet<i64> = stamps.iter().copied().collect();
    eprintln!(
        "/diagnostics: {} received, {} stamped before the first /clock, {} distinct stamps",
        diagnostics.len(),
        first,
        distinct.len()
    );
    assert!(stamps.iter().all(|s| log_times.contains(s)), "{stamps:?}");
    assert!(stamps.windows(2).all(|w| w[1] >= w[0]), "{stamps:?}");
    // 20 s of replay published at 10 Hz: far more than 20 distinct clock readings.
    assert!(distinct.len() >= 20, "{stamps:?}");
    assert_eq!(diagnostics.last().unwrap().1, n as u64, "samples analysed");
}

#[test]
fn fdavar_play_refuses_out_of_range_numbers_with_exit_2() {
    // Issue 13: `--rate 1e-300` panicked (Duration overflow), `--wait-s nan` would too.
    for (flag, value) in [
        ("--rate", "1e-300"),
        ("--rate", "0"),
        ("--rate", "-1"),
        ("--rate", "nan"),
        ("--rate", "inf"),
        ("--rate", "1e7"),
        ("--wait-s", "nan"),
        ("--wait-s", "-1"),
        ("--wait-s", "1e9"),
        ("--domain-id", "233"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
            .args(["play", "bags/clean", flag, value])
            .current_dir(crate_root())
            .output()
            .expect("run fdavar play");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}: {err}");
        let first = err.lines().next().unwrap_or_default();
        assert!(
            first.starts_with("error: invalid value") && first.contains(flag),
            "{flag} {value}: {err}"
        );
        assert!(!err.contains("panicked"), "{flag} {value}: {err}");
    }
}

/// Waits (bounded) until `path` holds at least `lines` complete lines.
fn wait_for_lines(path: &Path, lines: usize, within: Duration) -> usize {
    let start = Instant::now();
    loop {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        let n = text.matches('\n').count();
        if n >= lines || start.elapsed() > within {
            return n;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Waits (bounded) for a child to exit; its exit status, or None when it is still running.
fn wait_exit(child: &mut Child, within: Duration) -> Option<std::process::ExitStatus> {
    let start = Instant::now();
    while start.elapsed() < within {
        if let Some(status) = child.try_wait().unwrap() {
            return Some(status);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    None
}

/// Every line of a dump parses as JSON and the text ends with a newline; returns the rows.
fn dump_rows(text: &str, what: &str) -> Vec<serde_json::Value> {
    assert!(
        text.is_empty() || text.ends_with('\n'),
        "{what}: the last line is cut: …{}",
        &text[text.len().saturating_sub(80)..]
    );
    text.lines()
        .enumerate()
        .map(|(i, l)| {
            serde_json::from_str(l).unwrap_or_else(|e| panic!("{what} line {}: {e}", i + 1))
        })
        .collect()
}

/// Sends `signal` (e.g. "INT") to `pid` with kill(1).
fn send_signal(pid: u32, signal: &str) {
    let ok = Command::new("kill")
        .args(["-s", signal, &pid.to_string()])
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "kill -s {signal} {pid}");
}

/// Replays a recording into `fdavar_node` (started directly, or by a non-interactive shell in the
/// background), sends `signal` while rows are still coming, and checks the shutdown: exit 0 within
/// a bounded time and a dump whose every line is complete JSON.
fn node_stops_cleanly_on(signal: &str, domain: u16, via_shell: bool) {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rec");
    write_recording(&bag, 3600); // 18 s at 200 Hz
    let dump = dir.path().join("rows.jsonl");
    let log = dir.path().join("node.log");
    let ros_args = [
        "--ros-args".to_string(),
        "-p".into(),
        "qos.reliable:=true".into(),
        "-p".into(),
        LOSSLESS_DEPTH.into(),
        "-p".into(),
        "publish_rate_hz:=10.0".into(),
        "-p".into(),
        format!("dump_json:={}", dump.display()),
    ];
    let node_bin = env!("CARGO_BIN_EXE_fdavar_node");
    let mut command = if via_shell {
        // A shell without job control starts background commands with SIGINT (and SIGQUIT)
        // ignored: the node must install its handler over that.
        let mut c = Command::new("bash");
        c.arg("-c")
            .arg(r#""$0" "$@" & echo $!; wait $!; echo "exit=$?""#)
            .arg(node_bin);
        c
    } else {
        Command::new(node_bin)
    };
    let mut child = Killed(
        command
            .args(&ros_args)
            .env("ROS_DOMAIN_ID", domain.to_string())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .expect("spawn fdavar_node"),
    );
    let mut stdout = std::io::BufReader::new(child.0.stdout.take().unwrap());
    let pid = if via_shell {
        let mut line = String::new();
        std::io::BufRead::read_line(&mut stdout, &mut line).unwrap();
        line.trim()
            .parse::<u32>()
            .expect("the shell printed the node's pid")
    } else {
        child.0.id()
    };
    let _player = start_play(&bag, domain, &["--reliable", "--wait-s", "30"]);
    let before = wait_for_lines(&dump, 600, Duration::from_secs(60));
    assert!(before >= 600, "only {before} rows before the signal");
    send_signal(pid, signal);
    let status = wait_exit(&mut child.0, Duration::from_secs(30))
        .unwrap_or_else(|| panic!("fdavar_node still running 30 s after SIG{signal}"));
    let said = std::fs::read_to_string(&log).unwrap_or_default();
    let code = if via_shell {
        let mut rest = String::new();
        std::io::Read::read_to_string(&mut stdout, &mut rest).unwrap();
        rest.lines()
            .find_map(|l| l.strip_prefix("exit="))
            .and_then(|c| c.parse::<i32>().ok())
    } else {
        status.code()
    };
    assert_eq!(code, Some(0), "SIG{signal}: fdavar_node said:\n{said}");
    assert!(said.contains("stopping"), "{said}");
    let rows = dump_rows(&std::fs::read_to_string(&dump).unwrap(), "dump_json");
    eprintln!(
        "SIG{signal}{}: exit 0, {} dump rows, all complete ({before} on disk at the signal)",
        if via_shell {
            " (background of bash -c)"
        } else {
            ""
        },
        rows.len()
    );
    assert!(rows.len() >= before);
}

#[test]
fn sigint_stops_the_node_with_exit_0_and_a_complete_dump() {
    node_stops_cleanly_on("INT", 73, false);
}

#[test]
fn sigterm_stops_the_node_with_exit_0_and_a_complete_dump() {
    node_stops_cleanly_on("TERM", 74, false);
}

#[test]
fn sigint_stops_the_node_started_in_the_background_of_a_non_interactive_shell() {
    // The premise: such a shell starts background commands with SIGINT ignored (bit 2 of SigIgn).
    // Read once the child runs `sleep`: the forked shell sets the disposition just before its
    // exec, and a read before that (a loaded machine) saw only what the shell itself ignores.
    let out = Command::new("bash")
        .arg("-c")
        .arg(
            "sleep 30 & pid=$!; until [ \"$(cat /proc/$pid/comm 2>/dev/null)\" = sleep ]; do :; done; \
             grep SigIgn /proc/$pid/status; kill $pid",
        )
        .output()
        .unwrap();
    let line = String::from_utf8_lossy(&out.stdout).into_owned();
    let mask = u64::from_str_radix(line.trim().trim_start_matches("SigIgn:").trim(), 16)
        .unwrap_or_else(|_| panic!("SigIgn line: {line}"));
    assert_ne!(mask & (1 << (2 - 1)), 0, "SIGINT not ignored in: {line}");
    node_stops_cleanly_on("INT", 75, true);
}

#[test]
fn dump_json_stays_under_its_size_cap_and_keeps_the_newest_rows() {
    // Issue 9: dump_json wrote 8.8 GB in 4 minutes. With dump_json_max_mb 1 the file rotates into
    // rows.jsonl.1 (one kept) and neither passes 1 MB, however long the run.
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rec");
    let n = 3600;
    write_recording(&bag, n);
    let dump = dir.path().join("rows.jsonl");
    let rotated = dir.path().join("rows.jsonl.1");
    let dump_arg = format!("dump_json:={}", dump.display());
    let mut node = start_node(
        76,
        &[
            "-p",
            "qos.reliable:=true",
            "-p",
            LOSSLESS_DEPTH,
            "-p",
            "publish_rate_hz:=10.0",
            "-p",
            &dump_arg,
            "-p",
            "dump_json_max_mb:=1.0",
        ],
    );
    // The newest analysis time offline: the node has analysed everything once it is on disk.
    let (offline, _) = cli_rows(&bag);
    let last_time = offline
        .iter()
        .filter_map(|r| r["time_s"].as_f64())
        .fold(f64::MIN, f64::max);
    let mut player = start_play(&bag, 76, &["--reliable", "--rate", "4", "--wait-s", "30"]);
    let played = wait_exit(&mut player.0, Duration::from_secs(90)).expect("fdavar play ended");
    assert_eq!(played.code(), Some(0));
    let newest = |path: &Path| -> f64 {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        text.lines()
            .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
            .filter_map(|r| r["analysis_time_s"].as_f64())
            .fold(f64::MIN, f64::max)
    };
    let start = Instant::now();
    while newest(&dump) < last_time && start.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(200));
    }
    // SIGTERM flushes and ends the node.
    send_signal(node.0.id(), "TERM");
    let status = wait_exit(&mut node.0, Duration::from_secs(30)).expect("node stopped");
    assert_eq!(status.code(), Some(0));
    let cap = 1_000_000;
    let mut total = 0;
    for path in [&rotated, &dump] {
        let size = std::fs::metadata(path)
            .unwrap_or_else(|_| panic!("{} missing: no rotation", path.display()))
            .len();
        let rows = dump_rows(&std::fs::read_to_string(path).unwrap(), "dump");
        eprintln!("{}: {size} bytes, {} rows", path.display(), rows.len());
        assert!(size <= cap, "{} is {size} bytes", path.display());
        assert!(!rows.is_empty());
        total += rows.len();
    }
    // Kept: the newest rows, up to the last one; every axis has rows in it.
    assert_eq!(newest(&dump), last_time);
    let rows = dump_rows(&std::fs::read_to_string(&dump).unwrap(), "dump");
    for axis in [
        "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z",
    ] {
        assert!(rows.iter().any(|r| r["axis"] == axis), "{axis}");
    }
    eprintln!("dump_json: {total} rows kept in the two files");
}

#[test]
fn fdavar_node_help_lists_topics_every_parameter_and_exit_codes_without_starting() {
    for flag in ["--help", "-h"] {
        let start = Instant::now();
        // An invalid ROS_DOMAIN_ID would stop a node that read its configuration (exit 1).
        let out = Command::new(env!("CARGO_BIN_EXE_fdavar_node"))
            .arg(flag)
            .env("ROS_DOMAIN_ID", "999")
            .output()
            .expect("run fdavar_node");
        let help = String::from_utf8_lossy(&out.stdout);
        assert_eq!(out.status.code(), Some(0), "{flag}: {help}");
        assert!(
            out.stderr.is_empty(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        eprintln!(
            "{flag}: {} lines in {:?}",
            help.lines().count(),
            start.elapsed()
        );
        for want in [
            "sensor_msgs/msg/Imu",
            "sensor_msgs/msg/Temperature",
            "rosgraph_msgs/msg/Clock",
            "diagnostic_msgs/msg/DiagnosticArray",
            "fdavar_msgs/msg/AxisState",
            "--params-file",
            "__ns:=",
            "__node:=",
            "ROS_DOMAIN_ID",
            "SIGINT",
            "SIGTERM",
            "Exit codes: 0",
        ] {
            assert!(help.contains(want), "{flag}: no '{want}' in\n{help}");
        }
        // Every parameter of both tables, with its type and default.
        for spec in fdavar::ros::params::NODE_PARAMS {
            let (kind, default) = fdavar::ros::params::type_and_text(&(spec.default)());
            let head = format!("  {} ({kind}, default {default}, ", spec.name);
            assert!(help.contains(&head), "{flag}: no '{head}'");
            assert!(help.contains(spec.doc), "{flag}: no doc of {}", spec.name);
        }
        for spec in fdavar::params::PARAMS {
            let head = format!("  {} (", spec.name);
            let line = help.lines().find(|l| l.starts_with(&head));
            assert!(
                line.is_some_and(|l| l.ends_with(&format!("default {})", spec.default))),
                "{flag}: {line:?} for {}",
                spec.name
            );
        }
    }
}

/// Effects hidden on gyro_x (a sinusoid, and a noise burst that only the fit with the sinusoid
/// uncovers) and accel_y (a Gauss–Markov bias); 100 Hz, 120 s.
const HIDDEN_SPEC: &str = "\
rate_hz: 100
duration_s: 120
seed: 909
frame_id: imu_link
topics: { imu: /imu }
gravity: true
axes:
  gyro_x:
    N: { n: 1.7e-4 }
    K: { k: 1.9e-5 }
    sinusoid: { amplitude: 1.5e-3, frequency_hz: 0.2 }
    noise_burst: { start_s: 40, end_s: 60, factor: 3 }
  gyro_y:  { N: { n: 1.7e-4 }, K: { k: 1.9e-5 } }
  gyro_z:  { N: { n: 1.7e-4 }, K: { k: 1.9e-5 } }
  accel_x: { N: { n: 2.0e-3 }, K: { k: 4.0e-4 } }
  accel_y:
    N: { n: 2.0e-3 }
    gauss_markov: { sigma: 2.0e-2, time_constant_s: 1 }
  accel_z: { N: { n: 2.0e-3 }, K: { k: 4.0e-4 } }
";

const AXES: [&str; 6] = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"];

/// `fdavar ARGS…` printing one JSON document; panics with its stderr when it does not.
fn fdavar_json(args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(args)
        .output()
        .expect("run fdavar");
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "fdavar {args:?}: {e}\n{}",
            String::from_utf8_lossy(&out.stderr)
        )
    })
}

/// Where one axis's published whole-run fields (the peer's `whole_run_fields`) differ from the
/// axis object of `fdavar fit/diagnose --json` on the same messages; every number compared exactly.
fn whole_run_differences(live: &serde_json::Value, cli: &serde_json::Value) -> Vec<String> {
    let mut out = Vec::new();
    let mut same = |what: &str, a: &serde_json::Value, b: &serde_json::Value| {
        if a != b {
            out.push(format!("{what}: live {a} offline {b}"));
        }
    };
    same("model", &live["model"], &cli["model"]);
    same("fit_error", &live["fit_error"], &cli["fit_error"]);
    same("span_fit_error", &live["span_fit_error"], &cli["span_fit_error"]);
    // The JSON has the key only where the noise is heavy-tailed; the message says 0 otherwise.
    let kurtosis = cli.get("rate_excess_kurtosis").cloned().unwrap_or(serde_json::json!(0.0));
    same("rate_excess_kurtosis", &live["rate_excess_kurtosis"], &kurtosis);
    same("failing_tau", &live["failing_tau"], &cli["failing_tau"]);
    same("failing_spans", &live["failing_spans"], &cli["failing_spans"]);
    // Coefficients: the message's list of {effect, name, value, sigma, unit} against the JSON's
    // {effect: {name: {value, sigma, unit}}}, both ways.
    let fields = |c: &serde_json::Value| {
        serde_json::json!({"value": c["value"], "sigma": c["sigma"], "unit": c["unit"]})
    };
    let listed = |cs: &serde_json::Value| -> serde_json::Map<String, serde_json::Value> {
        cs.as_array()
            .into_iter()
            .flatten()
            .map(|c| {
                let key = format!("{}.{}", c["effect"].as_str().unwrap(), c["name"].as_str().unwrap());
                (key, fields(c))
            })
            .collect()
    };
    let nested = |m: &serde_json::Value| -> serde_json::Map<String, serde_json::Value> {
        m.as_object()
            .into_iter()
            .flatten()
            .flat_map(|(effect, ps)| {
                ps.as_object().into_iter().flatten().map(move |(name, v)| {
                    (format!("{effect}.{name}"), common::param_as_message(v))
                })
            })
            .collect()
    };
    let coefficients = |m| serde_json::Value::Object(m);
    same(
        "coefficients",
        &coefficients(listed(&live["coefficients"])),
        &coefficients(nested(&cli["coefficients"])),
    );
    if let Some(suggested) = cli.get("suggestions") {
        // Each with the effects it was weighed beside (`given`).
        let effects = |s: &serde_json::Value| -> Vec<serde_json::Value> {
            s.as_array().into_iter().flatten().map(|x| serde_json::json!([x["effect"], x["given"]])).collect()
        };
        same(
            "suggested effects",
            &serde_json::Value::from(effects(&live["suggestions"])),
            &serde_json::Value::from(effects(suggested)),
        );
        if let (Some(l), Some(c)) = (live["suggestions"].get(0), suggested.get(0)) {
            same("first suggestion's fit_error_after", &l["fit_error_after"], &c["fit_error_after"]);
            same(
                "first suggestion's span_fit_error_after",
                &l["span_fit_error_after"],
                &c["span_fit_error_after"],
            );
            let params: serde_json::Map<String, serde_json::Value> = l["params"]
                .as_array()
                .into_iter()
                .flatten()
                .map(|p| (p["name"].as_str().unwrap().to_string(), fields(p)))
                .collect();
            let offline: serde_json::Map<String, serde_json::Value> = c["params"]
                .as_object()
                .into_iter()
                .flatten()
                .map(|(name, p)| (name.clone(), common::param_as_message(p)))
                .collect();
            same(
                "first suggestion's params",
                &serde_json::Value::Object(params),
                &serde_json::Value::Object(offline),
            );
        }
    }
    out
}

/// The axis object of `fdavar fit|diagnose BAG --json --first N --axis AXIS ARGS…`.
fn offline_axis(command: &str, bag: &Path, first: u64, axis: &str, args: &[&str]) -> serde_json::Value {
    let first = first.to_string();
    let mut all = vec![command, bag.to_str().unwrap(), "--json", "--first", &first, "--axis", axis];
    all.extend_from_slice(args);
    fdavar_json(&all)["axes"][0].clone()
}

/// Whether rclpy and the colcon-built `fdavar_msgs` (the typed AxisState) are there; says why
/// not (a failure under `FDAVAR_REQUIRE_PYTHON=1`).
fn typed_peer_ready() -> bool {
    if python().is_none() {
        return false;
    }
    if colcon_install().is_none() {
        skip("fdavar_msgs is not built (target/colcon_ws): run .ci/setup-ros.sh");
        return false;
    }
    true
}

/// The models the replay tests set live: `model`, then `model.gyro_x`.
const LIVE_MODEL: &str = "white,bias_instability,random_walk,sinusoid";
const LIVE_AXIS_MODEL: &str = "white,bias_instability,random_walk,sinusoid,noise_burst";

/// Replays `bag` (`messages` IMU messages) with `fdavar play --clock` into the node on sim time,
/// has the rclpy peer snapshot every axis's typed state at the end, after `model` and after
/// `model.gyro_x` ([`LIVE_MODEL`], [`LIVE_AXIS_MODEL`]), and compares each snapshot with
/// `fdavar diagnose` and `fdavar fit --first N` on the bag, failing on any difference. Returns
/// the peer's verdict.
fn replay_and_compare(bag: &Path, messages: u64, domain: u16) -> serde_json::Value {
    let py = python().expect("checked by the caller");
    let _node = start_node(
        domain,
        &[
            "-p",
            "use_sim_time:=true",
            "-p",
            "qos.reliable:=true",
            "-p",
            LOSSLESS_DEPTH,
            "-p",
            "publish_rate_hz:=10.0",
            "-p",
            "diagnosis_period_s:=1.0",
            // Every round right after the last (no CPU budget): the checks wait one round.
            "-p",
            "diagnosis_cpu_share:=1.0",
            "-p",
            "stale_timeout_s:=600.0",
        ],
    );
    let scenario = format!("whole_run {LIVE_MODEL} {LIVE_AXIS_MODEL}");
    let peer_thread =
        std::thread::spawn(move || peer(&py, domain, &scenario, Duration::from_secs(300), None));
    let mut player = start_play(bag, domain, &["--clock", "--reliable", "--rate", "4", "--wait-s", "30"]);
    let status = player.0.wait().unwrap();
    let mut said = String::new();
    std::io::Read::read_to_string(player.0.stderr.as_mut().unwrap(), &mut said).unwrap();
    assert_eq!(status.code(), Some(0), "fdavar play: {said}");
    assert!(said.contains(&format!("{messages} IMU")), "{said}");
    let v = peer_thread.join().unwrap();
    assert!(v["clock_count"].as_u64().unwrap() > 0, "rclpy received no /clock");

    let diagnosed = |snapshot: &serde_json::Value| snapshot["diagnosed_messages"].as_u64().unwrap();
    let mut differences = Vec::new();
    let mut check = |label: &str, axis: &str, live: &serde_json::Value, cli: &serde_json::Value| {
        eprintln!(
            "{label} {axis}: {} messages, fit_error live {} offline {}, suggestions {}",
            diagnosed(live),
            live["fit_error"],
            cli["fit_error"],
            live["suggestions"].as_array().map_or(0, Vec::len)
        );
        differences.extend(
            whole_run_differences(live, cli)
                .into_iter()
                .map(|d| format!("{label} {axis}: {d}")),
        );
    };
    // As played (model N,B,K): the last round started when sim time last passed a diagnosis
    // period, on whatever the node had taken in by then (on a loaded machine up to a few seconds
    // short of the end); `--first` cuts the bag where the node's round did. The model changes
    // below diagnose every message.
    for axis in AXES {
        let live = &v["played"][axis];
        assert!(diagnosed(live) >= messages / 2, "{axis}: {live}");
        check("played", axis, live, &offline_axis("diagnose", bag, diagnosed(live), axis, &[]));
    }
    // `model` set live: a round at once, on every message.
    for axis in AXES {
        let live = &v["model"][axis];
        assert_eq!(diagnosed(live), messages, "{axis}: {live}");
        let args = ["--model", LIVE_MODEL];
        check("model", axis, live, &offline_axis("diagnose", bag, messages, axis, &args));
        check("model (fit)", axis, live, &offline_axis("fit", bag, messages, axis, &args));
    }
    // `model.gyro_x` set live: gyro_x refitted with the burst too.
    let live = &v["axis_model"]["gyro_x"];
    let per_axis = format!("gyro_x={LIVE_AXIS_MODEL}");
    let args = ["--model", LIVE_MODEL, "--model", per_axis.as_str()];
    check("axis_model", "gyro_x", live, &offline_axis("diagnose", bag, messages, "gyro_x", &args));
    check("axis_model (fit)", "gyro_x", live, &offline_axis("fit", bag, messages, "gyro_x", &args));
    assert!(differences.is_empty(), "live ≠ offline:\n{}", differences.join("\n"));
    v
}

#[test]
fn the_node_on_a_played_recording_publishes_what_fdavar_diagnose_says_and_refits_live() {
    // Issue 9, done 1–3: `fdavar play --clock` into the node on sim time; at the end each axis's
    // published model, coefficients, fit_error, failing τ and spans and suggestions are the numbers
    // of `fdavar diagnose --first N` (N: the node's `diagnosed_messages`); then `model` and
    // `model.gyro_x` set through SetParameters give the refits `fdavar fit` gives, and the second
    // hidden effect (the burst) is suggested once the first (the sinusoid) is in the model.
    if !typed_peer_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("hidden.yaml");
    std::fs::write(&spec, HIDDEN_SPEC).unwrap();
    let bag = dir.path().join("rec");
    let made = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["simulate", spec.to_str().unwrap(), "--out", bag.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    let v = replay_and_compare(&bag, 12_000, 77);

    let first = |s: &serde_json::Value| s["suggestions"][0]["effect"].as_str().map(str::to_string);
    let (played, model, axis_model) = (&v["played"], &v["model"], &v["axis_model"]);
    // Each hidden effect and nothing else: the burst is named second, weighed with the sinusoid
    // (the alternatives of the sinusoid's misfit, a Gauss–Markov process and quantization, are not).
    let named = |s: &serde_json::Value| -> Vec<(String, serde_json::Value)> {
        let list = s["suggestions"].as_array().cloned().unwrap_or_default();
        list.iter().map(|x| (x["effect"].as_str().unwrap_or("").to_string(), x["given"].clone())).collect()
    };
    let given = |ids: &[&str]| serde_json::json!(ids);
    assert_eq!(
        named(&played["gyro_x"]),
        [("sinusoid".to_string(), given(&[])), ("noise_burst".to_string(), given(&["sinusoid"]))],
        "{}",
        played["gyro_x"]
    );
    assert_eq!(named(&played["accel_y"]), [("gauss_markov".to_string(), given(&[]))], "{}", played["accel_y"]);
    assert_eq!(first(&model["gyro_x"]).as_deref(), Some("noise_burst"), "{}", model["gyro_x"]);
    for axis in ["gyro_y", "gyro_z", "accel_x", "accel_z"] {
        assert_eq!(played[axis]["suggestions"], serde_json::json!([]), "{axis}");
    }
    // The sinusoid mends the whole run's curve (fit_error), the burst the spans (span_fit_error):
    // the larger of the two falls at each step, to a model that fits over τ and in time.
    let errors = |s: &serde_json::Value| {
        let e = |k: &str| s["gyro_x"][k].as_f64().unwrap();
        (e("fit_error"), e("span_fit_error"))
    };
    let [before, with_sinusoid, with_burst] = [played, model, axis_model].map(errors);
    eprintln!(
        "gyro_x live (fit_error, span_fit_error): N,B,K {before:.2?} → +sinusoid {with_sinusoid:.2?} → +noise_burst {with_burst:.2?}"
    );
    let misfit = |(whole, spans): (f64, f64)| whole.max(spans);
    assert!(misfit(before) > 2.0 && misfit(with_sinusoid) < misfit(before));
    assert!(misfit(with_burst) < misfit(with_sinusoid) && misfit(with_burst) <= 2.0);
}

#[test]
fn live_equals_offline_on_a_recording_with_nan_a_gap_and_a_backwards_stamp() {
    // Issue 9, done 4: the node and `fdavar diagnose/fit` drop and place the same samples (one
    // intake), so a recording with NaN and Inf samples, a 2 s gap and a stamp going backwards
    // still gives the same numbers live and offline.
    if !typed_peer_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rec");
    let mut samples = sinusoid_samples();
    samples[3000].gyro[1] = f64::NAN;
    samples[5000].accel[0] = f64::INFINITY;
    samples.drain(6000..6400);
    samples[8000].stamp_ns = samples[7999].stamp_ns - 3_000_000;
    // Issue 13: a value no sensor gives (left out like NaN), and the publisher restarting with
    // its clock 20 s back at sample 10 000 (dropped as backwards, re-anchored at the 50th).
    samples[4000].gyro[2] = 1e300;
    // Isolated spikes on accel_z, one sample in 250 at ±30σ (excess kurtosis ≈ 150): the fit
    // widens its EDFs for them, and the node says by how much, as `fdavar diagnose --json` does.
    // At random samples with random signs: spikes at a fixed period would be a line.
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(53);
    for s in &mut samples {
        if rand::Rng::random_bool(&mut rng, 1.0 / 250.0) {
            s.accel[2] += if rand::Rng::random_bool(&mut rng, 0.5) { 0.03 } else { -0.03 };
        }
    }
    let unshifted: Vec<i64> = samples.iter().map(|s| s.stamp_ns).collect();
    for s in &mut samples[10_000..] {
        s.stamp_ns -= 20_000_000_000;
    }
    let messages = samples.len() as u64;
    // Log times in write order, 5 ms apart, as a recorder receiving them would have logged them.
    let mut writer = fdavar::bag::BagWriter::create(&bag).unwrap();
    for (k, s) in samples.iter().enumerate() {
        let log = log_time_ns(unshifted[k].max(unshifted[k.saturating_sub(1)]));
        writer.write_imu("/imu", log, s, "imu_link").unwrap();
    }
    writer.finish().unwrap();
    let v = replay_and_compare(&bag, messages, 78);
    // And says what it left out: 53 messages (NaN, Inf, 1e300, the backwards stamp, the 49
    // dropped before the re-anchor) not counted as samples; five holes in the series (the first
    // four and the 2 s gap; the re-anchor starts a new clock); no queue drops.
    for axis in AXES {
        let s = &v["model"][axis];
        eprintln!("{axis}: samples {} drops {} gaps {}", s["samples"], s["drops"], s["gaps"]);
        assert_eq!(s["samples"].as_u64(), Some(messages - 53), "{axis}");
        assert_eq!(s["gaps"].as_u64(), Some(5), "{axis}");
        assert_eq!(s["drops"].as_u64(), Some(0), "{axis}");
        // The spikes' kurtosis on accel_z (equal to the offline one: compared above), none elsewhere.
        let kurtosis = s["rate_excess_kurtosis"].as_f64().unwrap();
        assert!(if axis == "accel_z" { kurtosis > 75.0 } else { kurtosis == 0.0 }, "{axis}: {kurtosis}");
    }
}

#[test]
fn dropped_input_turns_the_status_warn_or_error_and_the_node_keeps_serving() {
    // Issue 13: a second publisher with an offset clock lost half the messages at level OK, and
    // zero stamps inside a stamped stream were all dropped at level OK. Now the share dropped
    // since the last publication sets WARN (> 1 %) or ERROR (> 50 %) with the count; afterwards
    // the node answers parameters and, on a clean stream, publishes a share of 0 again.
    let Some(py) = python() else { return };
    let _node = start_node(80, &["-p", "publish_rate_hz:=4.0"]);
    let v = peer(&py, 80, "input_loss", Duration::from_secs(90), None);
    eprintln!("input_loss: {v}");
    let phase = |name: &str| -> (Vec<u64>, Vec<String>, Vec<f64>, u64) {
        let p = &v[name];
        let strings = |key: &str| -> Vec<String> {
            let values = p[key].as_array().unwrap().iter();
            values.map(|x| x.as_str().unwrap().to_string()).collect()
        };
        let levels = p["levels"].as_array().unwrap().iter();
        let levels: Vec<u64> = levels.map(|x| x.as_u64().unwrap()).collect();
        let shares = strings("shares").iter().map(|s| s.parse().unwrap()).collect();
        assert!(levels.len() >= 6, "{name}: {p}");
        (levels, strings("messages"), shares, p["samples"].as_u64().unwrap())
    };
    // Half of each publication's messages are the second publisher's (backwards): WARN, or ERROR
    // where a publication caught slightly more than half.
    let (levels, messages, shares, offset_samples) = phase("offset");
    for ((level, message), share) in levels.iter().zip(&messages).zip(&shares) {
        assert!(*level >= 1 && message.contains("input lost: "), "offset: {level} {message}");
        assert!((0.4..0.6).contains(share), "offset: {share}");
    }
    // Three zero stamps to each good message: 75 % dropped, ERROR.
    let (levels, messages, shares, zero_samples) = phase("zero");
    for ((level, message), share) in levels.iter().zip(&messages).zip(&shares) {
        assert!(*level == 2 && message.contains("input lost: "), "zero: {level} {message}");
        assert!((0.7..0.8).contains(share), "zero: {share}");
    }
    assert_eq!(v["answered"].as_f64(), Some(4.0), "get_parameters after the loss");
    let (_, messages, shares, clean_samples) = phase("clean");
    assert!(shares.iter().all(|s| *s == 0.0), "clean: {shares:?}");
    assert!(messages.iter().all(|m| !m.contains("input lost")), "clean: {messages:?}");
    assert!(offset_samples < zero_samples && zero_samples < clean_samples);
}

/// The receive thread's (the node's main thread's) voluntary context switches.
fn voluntary_switches(pid: u32) -> u64 {
    common::voluntary_switches(pid, &pid.to_string()).expect("voluntary_ctxt_switches of the node")
}

/// `receive_batch_ms` (default 0.8): at 2 kHz the receive thread (the node's main thread) takes
/// messages in batches on a timer, about 1 wake-up per 0.8 ms instead of one per message; once the
/// topic falls silent it parks until DDS wakes it, so silence costs no timer wake-ups; a 100 Hz
/// topic is taken as DDS wakes the thread, once per message, not twice. Needs no Python: the IMU
/// publisher is ros2-client in this process, best effort as IMU drivers are.
#[test]
fn the_node_takes_a_fast_topic_in_batches_a_slow_one_per_message_and_parks_when_silent() {
    use fdavar::msgs::sensor_msgs::Imu;
    use fdavar::ros::node::{peer_node, publish_on, spin_in_background, wait_for_subscribers};
    use ros2_client::QosProfile;
    const DOMAIN: u16 = 93;
    let node = start_node(DOMAIN, &["-p", "diagnosis_period_s:=0.0"]);
    let pid = node.0.id();
    let mut peer = peer_node(DOMAIN, "fdavar_batch_test").expect("node");
    let qos = QosProfile::subscription_default()
        .reliability(ros2_client::qos::Reliability::BestEffort)
        .history(ros2_client::qos::History::KeepLast { depth: 100 });
    let imu = publish_on::<Imu>(&mut peer, "/imu", &qos).expect("publisher");
    spin_in_background(&mut peer).expect("spinner");
    assert!(wait_for_subscribers(&imu, &peer, 1, Duration::from_secs(30)), "fdavar_node never matched");
    std::thread::sleep(Duration::from_millis(500));
    let publish = |n: u64, rate_hz: f64| {
        let start = Instant::now();
        for k in 0..n {
            let due = start + Duration::from_secs_f64(k as f64 / rate_hz);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
            let v = ((k * 7919) % 101) as f64 * 1e-5;
            let sample = fdavar::signal::ImuSample {
                stamp_ns: 1_000_000_000 + (k as f64 * 1e9 / rate_hz) as i64,
                gyro: [v, -v, 2.0 * v],
                accel: [v, 0.0, 9.81],
            };
            imu.publish(Imu::from_sample(&sample, "imu_link").unwrap())
                .expect("publish");
        }
    };
    let before = voluntary_switches(pid);
    let sent = 4000;
    publish(sent, 2000.0);
    std::thread::sleep(Duration::from_millis(100));
    let during = voluntary_switches(pid) - before;
    // Woken per message, the thread switched about 1.5 times per message (measured 5 972 for
    // 4 000 with `receive_batch_ms:=0`); in 0.8 ms batches about 0.55 times (measured 2 135–2 270).
    // A slow publisher only makes the batches larger.
    eprintln!("{during} voluntary switches of the receive thread for {sent} messages at 2 kHz");
    assert!(
        during * 4 < sent * 3,
        "{during} wake-ups for {sent} messages: not batched"
    );
    // Silent: parked until DDS wakes it or its 100 ms stop check, about 10 switches a second.
    let silent_from = voluntary_switches(pid);
    std::thread::sleep(Duration::from_secs(2));
    let silent = voluntary_switches(pid) - silent_from;
    eprintln!("{silent} voluntary switches of the receive thread in 2 s of silence");
    assert!(silent < 60, "{silent} wake-ups in 2 s without a message: still on a timer");
    // 100 Hz for 2 s: woken by DDS per message, about 1.25 switches each (measured 269 for 200,
    // with the parked thread's 100 ms checks; woken per message at 2 kHz: 1.5 each, the waker's
    // mutex, docs/ros.md); a timed take after each, which would find nothing, adds one per
    // message (measured 434 with a build that batched every topic).
    let slow_from = voluntary_switches(pid);
    publish(200, 100.0);
    let slow = voluntary_switches(pid) - slow_from;
    eprintln!("{slow} voluntary switches of the receive thread for 200 messages at 100 Hz");
    assert!(slow < 370, "{slow} wake-ups for 200 messages at 100 Hz: batched as a fast topic");
    drop(node);
}
