//! Interoperability with independent rosbag2 tools (PyPI `rosbags`, `mcap` + `mcap-ros2-support`).
//!
//! 1. Python writes bags (rosbags: MCAP and sqlite3, metadata v8 and v9; mcap: zstd, lz4,
//!    unchunked, no summary; hand-made sqlite3 of older layouts) from a seeded generator and dumps
//!    the values; fdavar must read exactly those values (bit for bit).
//! 2. fdavar writes bags; rosbags and mcap-ros2-support must read back exactly what was written.
//!
//! Python: `$FDAVAR_PYTHON` (default `<crate>/.venv/bin/python`) with .ci/python-bag.txt installed.
//! Without it the tests print why and pass, unless `FDAVAR_REQUIRE_PYTHON=1` (CI).

mod common;

use fdavar::bag::{BagMessage, BagReader, BagWriter, ChunkCompression, WriterOptions};
use fdavar::signal::{ImuSample, TemperatureSample};
use rand::{Rng, SeedableRng};
use serde_json::Value;
use std::path::Path;
use std::process::Command;

const MODULES: &str = "import rosbags, mcap, mcap_ros2, numpy";


fn run_script(python: &Path, script: &str, arg: &Path) -> String {
    let script = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/py")
        .join(script);
    let out = Command::new(python)
        .arg(&script)
        .arg(arg)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "{} failed:\n{}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn u(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("not a u64: {v}"))
}

#[test]
fn reads_bags_written_by_independent_tools_exactly() {
    let Some(python) = common::python_with(MODULES, ".ci/python-bag.txt") else { return };
    let dir = tempfile::tempdir().unwrap();
    run_script(&python, "make_bags.py", dir.path());
    let expected: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("expected.json")).unwrap())
            .unwrap();
    let cases = expected.as_object().unwrap();
    assert_eq!(cases.len(), 13, "cases written: {:?}", cases.keys());
    for (name, want) in cases {
        let bag = BagReader::open(dir.path().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let imu = bag
            .imu_topic(None)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(imu.name, want["imu_topic"].as_str().unwrap(), "{name}");
        let want_imu = want["imu"].as_array().unwrap();
        let want_temp = want["temperature"].as_array().unwrap();
        assert_eq!(
            imu.message_count,
            want_imu.len() as u64,
            "{name}: Imu count"
        );
        let temp = bag
            .temperature_topic(None)
            .unwrap()
            .expect("temperature topic");
        assert_eq!(
            temp.message_count,
            want_temp.len() as u64,
            "{name}: Temperature count"
        );
        assert_eq!(bag.topics().len(), 3, "{name}: {:?}", bag.topics());

        let (imu_name, temp_name) = (imu.name.clone(), temp.name.clone());
        let mut got_imu = Vec::new();
        let mut got_temp = Vec::new();
        for m in bag.messages(&imu_name, Some(&temp_name)).unwrap() {
            match m.unwrap_or_else(|e| panic!("{name}: {e}")) {
                BagMessage::Imu {
                    log_time_ns,
                    sample,
                } => got_imu.push((log_time_ns, sample)),
                BagMessage::Temperature {
                    log_time_ns,
                    sample,
                } => got_temp.push((log_time_ns, sample)),
            }
        }
        assert_eq!(got_imu.len(), want_imu.len(), "{name}");
        for (i, ((log, s), w)) in got_imu.iter().zip(want_imu).enumerate() {
            let w = w.as_array().unwrap();
            assert_eq!(*log as u64, u(&w[0]), "{name} imu {i} log time");
            assert_eq!(s.stamp_ns as u64, u(&w[1]), "{name} imu {i} stamp");
            let bits: Vec<u64> = s.values().iter().map(|v| v.to_bits()).collect();
            let want_bits: Vec<u64> = w[2..8].iter().map(u).collect();
            assert_eq!(bits, want_bits, "{name} imu {i} values");
        }
        assert_eq!(got_temp.len(), want_temp.len(), "{name}");
        for (i, ((log, s), w)) in got_temp.iter().zip(want_temp).enumerate() {
            let w = w.as_array().unwrap();
            assert_eq!(
                (*log as u64, s.stamp_ns as u64),
                (u(&w[0]), u(&w[1])),
                "{name} temp {i}"
            );
            assert_eq!(s.celsius.to_bits(), u(&w[2]), "{name} temp {i}");
        }
    }
}

/// Samples with their log times, ns.
type Logged<T> = Vec<(i64, T)>;

/// Seeded IMU and temperature samples, with awkward values in them.
fn samples(seed: u64, n: usize) -> (Logged<ImuSample>, Logged<TemperatureSample>) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let t0 = 1_750_000_000_000_000_000i64;
    let imu = (0..n as i64)
        .map(|i| {
            let stamp = t0 + i * 5_000_000 - rng.random_range(0..100_000);
            let mut gyro = [0.0; 3].map(|_| rng.random_range(-1.0..1.0) * 1e-2);
            if i == 1 {
                gyro = [f64::MIN_POSITIVE / 4.0, -0.0, f64::MAX];
            }
            let accel = [0.0; 3].map(|_| rng.random_range(-1.0..1.0) + 9.81);
            (
                t0 + i * 5_000_000 + rng.random_range(0..1_000_000),
                ImuSample {
                    stamp_ns: stamp,
                    gyro,
                    accel,
                },
            )
        })
        .collect();
    let temp = (0..n as i64 / 10)
        .map(|i| {
            let stamp = t0 + i * 50_000_000;
            (
                stamp + 7,
                TemperatureSample {
                    stamp_ns: stamp,
                    celsius: rng.random_range(20.0..40.0),
                },
            )
        })
        .collect();
    (imu, temp)
}

#[test]
fn independent_readers_read_fdavar_bags_exactly() {
    let Some(python) = common::python_with(MODULES, ".ci/python-bag.txt") else { return };
    let dir = tempfile::tempdir().unwrap();
    for (k, compression) in ChunkCompression::ALL.into_iter().enumerate() {
        let (imu, temp) = samples(10 + k as u64, 300);
        let path = dir.path().join(format!("fdavar_{k}"));
        let mut w = BagWriter::create_with(
            &path,
            &WriterOptions {
                compression,
                overwrite: false,
            },
        )
        .unwrap();
        // Interleave as a recorder would: by log time.
        let mut t = temp.iter().peekable();
        for (log, s) in &imu {
            while let Some((tl, ts)) = t.next_if(|(tl, _)| tl <= log) {
                w.write_temperature("/imu/temperature", *tl, ts, "imu_link")
                    .unwrap();
            }
            w.write_imu("/imu/data", *log, s, "imu_link").unwrap();
        }
        for (tl, ts) in t {
            w.write_temperature("/imu/temperature", *tl, ts, "imu_link")
                .unwrap();
        }
        w.finish().unwrap();

        let got: Value = serde_json::from_str(&run_script(&python, "read_bag.py", &path)).unwrap();
        assert_eq!(got["mcap_ros2"]["profile"], "ros2");
        assert!(got["mcap_ros2"]["metadata"]
            .as_array()
            .unwrap()
            .contains(&Value::from("rosbag2")));
        assert_eq!(got["rosbags"]["counts"]["/imu/data"], imu.len() as u64);
        assert_eq!(
            got["rosbags"]["qos"]["/imu/data"], 1,
            "offered_qos_profiles parsed"
        );
        for reader in ["rosbags", "mcap_ros2"] {
            let r = &got[reader];
            assert_eq!(r["topics"]["/imu/data"], "sensor_msgs/msg/Imu", "{reader}");
            assert_eq!(
                r["topics"]["/imu/temperature"], "sensor_msgs/msg/Temperature",
                "{reader}"
            );
            let rows = r["messages"]["/imu/data"].as_array().unwrap();
            assert_eq!(rows.len(), imu.len(), "{reader}");
            for ((log, s), row) in imu.iter().zip(rows) {
                let row = row.as_array().unwrap();
                let stamp = s.stamp_ns;
                assert_eq!(u(&row[0]), *log as u64, "{reader} log time");
                assert_eq!(
                    u(&row[1]) as i64 * 1_000_000_000 + u(&row[2]) as i64,
                    stamp,
                    "{reader}"
                );
                assert_eq!(row[3], "imu_link");
                let want: Vec<u64> = s
                    .values()
                    .iter()
                    .map(|v| v.to_bits())
                    .chain([1f64.to_bits(), (-1f64).to_bits()])
                    .collect();
                let bits: Vec<u64> = row[4..12].iter().map(u).collect();
                assert_eq!(bits, want, "{reader} at log time {log}");
            }
            let rows = r["messages"]["/imu/temperature"].as_array().unwrap();
            assert_eq!(rows.len(), temp.len(), "{reader}");
            for ((log, s), row) in temp.iter().zip(rows) {
                let row = row.as_array().unwrap();
                assert_eq!(u(&row[0]), *log as u64);
                assert_eq!(u(&row[4]), s.celsius.to_bits(), "{reader}");
            }
        }

        // And fdavar reads its own bag back to the same values.
        let bag = BagReader::open(&path).unwrap();
        let back: Vec<_> = bag
            .messages("/imu/data", None)
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        let want: Vec<_> = imu
            .iter()
            .map(|(l, s)| BagMessage::Imu {
                log_time_ns: *l,
                sample: *s,
            })
            .collect();
        assert_eq!(back.len(), want.len());
        assert!(back.iter().zip(&want).all(|(a, b)| same_bits(a, b)));
    }
}

/// Equality that tells −0.0 from 0.0 (PartialEq does not).
fn same_bits(a: &BagMessage, b: &BagMessage) -> bool {
    match (a, b) {
        (
            BagMessage::Imu {
                log_time_ns: la,
                sample: sa,
            },
            BagMessage::Imu {
                log_time_ns: lb,
                sample: sb,
            },
        ) => {
            la == lb
                && sa.stamp_ns == sb.stamp_ns
                && sa
                    .values()
                    .iter()
                    .zip(sb.values())
                    .all(|(x, y)| x.to_bits() == y.to_bits())
        }
        _ => false,
    }
}
