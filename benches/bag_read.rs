//! End-to-end read benchmark: a 1 h, 100 Hz IMU recording (360 000 messages) from disk to samples.
//!
//! Writes the recording with [`BagWriter`] into a temporary directory (untimed), then opens it and
//! streams every Imu message through [`BagReader`], printing messages/s, seconds and the peak RSS
//! (VmHWM from /proc/self/status). Targets (issue 3): under 1 s and under 100 MB RSS in release.
//!
//! Run: `cargo bench --no-default-features --bench bag_read`
//! (options: `-- --storage mcap|sqlite --messages N`).

use fdavar::bag::{BagMessage, BagReader, BagWriter};
use fdavar::signal::ImuSample;
use rand::{Rng, SeedableRng};
use std::path::Path;
use std::time::Instant;

/// Peak resident set size of this process, MB, from `VmHWM` (Linux).
fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

fn write_recording(path: &Path, n: u64) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2016);
    let mut w = BagWriter::create(path).expect("create bag");
    let t0 = 1_700_000_000_000_000_000i64;
    for i in 0..n as i64 {
        let stamp = t0 + i * 10_000_000;
        let sample = ImuSample {
            stamp_ns: stamp,
            gyro: [0.0; 3].map(|_| rng.random_range(-1e-3..1e-3)),
            accel: [0.0, 0.0, 9.81].map(|g| g + rng.random_range(-1e-2..1e-2)),
        };
        w.write_imu("/imu/data", stamp + 200_000, &sample, "imu_link")
            .expect("write");
    }
    w.finish().expect("finish");
}

/// The same recording as a Humble-style sqlite3 bag (schema 3 tables), written with rusqlite.
fn write_sqlite(path: &Path, n: u64) {
    let mcap_dir = path.with_extension("src");
    write_recording(&mcap_dir, n);
    let bag = BagReader::open(&mcap_dir).unwrap();
    std::fs::create_dir_all(path).unwrap();
    let mut db = rusqlite::Connection::open(path.join("rec_0.db3")).unwrap();
    db.execute_batch(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
         serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
         CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
         timestamp INTEGER NOT NULL, data BLOB NOT NULL);
         CREATE INDEX timestamp_idx ON messages (timestamp ASC);
         INSERT INTO topics VALUES (1, '/imu/data', 'sensor_msgs/msg/Imu', 'cdr', '');",
    )
    .unwrap();
    let tx = db.transaction().unwrap();
    for m in bag.messages("/imu/data", None).unwrap() {
        let BagMessage::Imu {
            log_time_ns,
            sample,
        } = m.unwrap()
        else {
            continue;
        };
        let msg = fdavar::msgs::sensor_msgs::Imu::from_sample(&sample, "imu_link").unwrap();
        let data = fdavar::msgs::encode(&msg).unwrap();
        tx.execute(
            "INSERT INTO messages(topic_id, timestamp, data) VALUES (1, ?1, ?2)",
            rusqlite::params![log_time_ns, data],
        )
        .unwrap();
    }
    tx.commit().unwrap();
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
    };
    let storage = arg("--storage").map_or("mcap", |s| s.as_str()).to_string();
    let n: u64 = arg("--messages").map_or(360_000, |s| s.parse().expect("--messages N"));

    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("rec");
    let t = Instant::now();
    match storage.as_str() {
        "mcap" => write_recording(&path, n),
        "sqlite" => write_sqlite(&path, n),
        other => panic!("--storage mcap|sqlite, not {other}"),
    }
    let write_s = t.elapsed().as_secs_f64();
    let rss_before = peak_rss_mb();
    // Reset the high-water mark so that it measures the read alone (Linux ≥ 4.0).
    let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();

    let t = Instant::now();
    let bag = BagReader::open(&path).expect("open");
    let topic = bag.imu_topic(None).expect("imu topic").name.clone();
    let mut count = 0u64;
    let mut checksum = 0.0;
    for m in bag.messages(&topic, None).expect("messages") {
        if let BagMessage::Imu { sample, .. } = m.expect("message") {
            count += 1;
            checksum += sample.gyro[0];
        }
    }
    let read_s = t.elapsed().as_secs_f64();
    assert_eq!(count, n, "messages read");
    let bytes: u64 = bag
        .files()
        .map(|(p, _)| std::fs::metadata(p).map_or(0, |m| m.len()))
        .sum();
    println!(
        "bag_read/{storage}: {count} Imu messages ({:.1} MB on disk, written in {write_s:.2} s)",
        bytes as f64 / 1e6
    );
    println!(
        "  read end to end: {read_s:.3} s, {:.0} messages/s (checksum {checksum:.6e})",
        count as f64 / read_s
    );
    match (rss_before, peak_rss_mb()) {
        (Some(before), Some(after)) => println!(
            "  peak RSS (VmHWM) while reading: {after:.1} MB{} (peak while writing: {before:.1} MB)",
            if reset { "" } else { " (reset failed: includes writing)" }
        ),
        _ => println!("  peak RSS: unavailable (no /proc/self/status)"),
    }
}
