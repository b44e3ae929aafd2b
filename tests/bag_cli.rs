//! `fdavar info` through the real binary: what users see, and exit codes on bad input.

use fdavar::bag::BagWriter;
use fdavar::signal::ImuSample;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn fdavar(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fdavar")).args(args).output().expect("run fdavar")
}

fn info(args: &[&str], bag: &Path) -> Output {
    let mut all = vec![std::ffi::OsStr::new("info"), bag.as_os_str()];
    all.extend(args.iter().map(std::ffi::OsStr::new));
    fdavar(&all)
}

fn text(o: &Output) -> (String, String) {
    (String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// 1000 samples at 100 Hz with one gap (5 missing) and one duplicated stamp.
fn recording(dir: &Path) -> PathBuf {
    let path = dir.join("rec");
    let mut w = BagWriter::create(&path).unwrap();
    let mut stamp = 1_700_000_000_000_000_000i64;
    for i in 0..1000 {
        stamp += match i {
            500 => 60_000_000,
            700 => 0,
            _ => 10_000_000,
        };
        let s = ImuSample { stamp_ns: stamp, gyro: [0.01, 0.0, 0.0], accel: [0.0, 0.0, 9.81] };
        w.write_imu("/imu/data", stamp + 1_000, &s, "imu_link").unwrap();
    }
    w.finish().unwrap();
    path
}

#[test]
fn info_describes_a_recording() {
    let dir = tempfile::tempdir().unwrap();
    let bag = recording(dir.path());
    let out = info(&[], &bag);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stdout.contains("/imu/data  sensor_msgs/msg/Imu"), "{stdout}");
    assert!(stdout.contains("period τ0 = 0.010000 s (100.000 Hz)"), "{stdout}");
    assert!(stdout.contains("gaps 1, duplicated stamps 1, backward stamps 0"), "{stdout}");

    let out = info(&["--json"], &bag);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["message_count"], 1000);
    assert_eq!(json["imu"][0]["samples"], 1000);
    assert_eq!(json["imu"][0]["period_s"], 0.01);
    assert_eq!(json["imu"][0]["irregularities"]["gaps"], 1);
    // Sensor span: 999 intervals of 10 ms, one of them 60 ms, one 0 ms.
    assert_eq!(json["imu"][0]["stamp_span_s"], (998.0 * 10.0 + 60.0 - 10.0) * 1e-3);
}

#[test]
fn info_on_a_bag_without_imu_says_so() {
    let bag = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/rosbag2/sqlite3_talker");
    let out = info(&[], &bag);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stdout.contains("holds no sensor_msgs/msg/Imu"), "{stdout}");
    assert!(stdout.contains("/topic"), "{stdout}");
    // Asking for an IMU topic it does not have is an error that lists what is there.
    let out = info(&["--topic", "/imu"], &bag);
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr.starts_with("fdavar: error: "), "{stderr}");
    assert!(stderr.contains("'/imu' is not a sensor_msgs/msg/Imu topic") && stderr.contains("/rosout"), "{stderr}");
}

#[test]
fn bad_inputs_exit_1_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let bag = recording(dir.path());
    let mcap = bag.join("rec_0.mcap");
    let bytes = std::fs::read(&mcap).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let corrupt = dir.path().join("corrupt.db3");
    std::fs::write(&corrupt, vec![0x42; 2048]).unwrap();
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    for (path, needle) in [
        (dir.path().join("missing"), "no such file or directory"),
        (empty, "not a rosbag2 bag"),
        (cut, "truncated MCAP"),
        (corrupt, "corrupt or unreadable sqlite3 bag"),
    ] {
        let out = info(&[], &path);
        let (stdout, stderr) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{}: {stdout}{stderr}", path.display());
        assert!(stderr.contains(needle) && stderr.contains(&path.display().to_string()), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

#[test]
fn usage_error_exits_2() {
    let out = fdavar(&[std::ffi::OsStr::new("info")]);
    assert_eq!(out.status.code(), Some(2));
}
