//! A mutation fuzzer for what fdavar reads from outside: rosbag2 files (MCAP with every chunk
//! compression, sqlite3) through [`BagReader`], and CDR message bytes through [`decode`].
//!
//! Runs on stable Rust, in a test (a short run, tests/fuzz_bag.rs) and in a bench binary (the long
//! run, `cargo bench --bench fuzz -- EXECUTIONS`). Each execution takes a valid seed, applies one to
//! eight byte-level mutations (bit flips, random bytes, boundary integers written over length
//! fields, truncation, deletion, duplication, splicing with another seed: the moves of AFL's havoc
//! stage) and reads the result the way `fdavar info`/`diagnose` do. A panic is caught, counted
//! and its input kept on disk; an abort (an allocation of absurd size) ends the process, which the
//! caller sees as a failed run. CDR mutants that decode must also survive a round trip
//! (decode ∘ encode ∘ decode = decode), so a decoder that reads garbage as values is caught too.

use fdavar::bag::{BagReader, BagWriter, ChunkCompression, WriterOptions};
use fdavar::msgs::sensor_msgs::{Imu, Temperature};
use fdavar::msgs::{decode, encode};
use fdavar::signal::{ImuSample, TemperatureSample};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};

/// What one input is read as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    Mcap,
    Sqlite,
    Cdr,
}

/// How the reads of one target ended, over a run.
#[derive(Debug, Default, Clone, Copy)]
pub struct Tally {
    pub executions: u64,
    /// Inputs refused with an error at open, topic choice or the first message.
    pub refused: u64,
    /// Inputs from which at least one message was decoded.
    pub decoded: u64,
    /// Messages decoded in all.
    pub messages: u64,
    pub panics: u64,
}

/// The fuzzer: its seeds, a seeded generator, a scratch directory and the tallies.
pub struct Fuzzer {
    seeds: Vec<(Target, Vec<u8>)>,
    rng: ChaCha8Rng,
    dir: PathBuf,
    pub tallies: [(Target, Tally); 3],
    /// Inputs that made the reader panic (the first few), kept in `dir`.
    pub crashes: Vec<PathBuf>,
}

/// Boundary values written over length, count and offset fields.
const INTERESTING: [u64; 12] = [
    0,
    1,
    0x7f,
    0x80,
    0xff,
    0xffff,
    0x7fff_ffff,
    0xffff_ffff,
    1 << 32,
    1 << 40,
    i64::MAX as u64,
    u64::MAX,
];

impl Fuzzer {
    /// Seeds: fdavar bags of IMU + temperature messages with zstd, lz4 and uncompressed chunks,
    /// the rosbag2-written MCAP bags of tests/data, a rosbag2-layout sqlite3 bag, and encoded
    /// `Imu`/`Temperature` messages. `dir` is a scratch directory (a tmpfs makes it faster).
    pub fn new(dir: &Path, seed: u64) -> Fuzzer {
        let mut seeds = Vec::new();
        for (k, compression) in ChunkCompression::ALL.into_iter().enumerate() {
            seeds.push((Target::Mcap, mcap_seed(dir, k, compression)));
        }
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/rosbag2");
        for file in ["mcap_talker/talker.mcap", "mcap_cdr_test/cdr_test_0.mcap"] {
            seeds.push((
                Target::Mcap,
                std::fs::read(data.join(file)).expect("seed bag"),
            ));
        }
        seeds.push((Target::Sqlite, sqlite_seed(dir)));
        for k in 0..4 {
            seeds.push((Target::Cdr, encode(&imu(k)).unwrap()));
        }
        seeds.push((Target::Cdr, encode(&temperature(0)).unwrap()));
        Fuzzer {
            seeds,
            rng: ChaCha8Rng::seed_from_u64(seed),
            dir: dir.to_path_buf(),
            tallies: [
                (Target::Mcap, Tally::default()),
                (Target::Sqlite, Tally::default()),
                (Target::Cdr, Tally::default()),
            ],
            crashes: Vec::new(),
        }
    }

    /// Runs `executions` mutants. sqlite3 opens cost about 20× an MCAP read, so they get one
    /// execution in 20; MCAP and CDR share the rest.
    pub fn run(&mut self, executions: u64) {
        for _ in 0..executions {
            let target = match self.rng.random_range(0..40) {
                0 | 1 => Target::Sqlite,
                k if k % 2 == 0 => Target::Mcap,
                _ => Target::Cdr,
            };
            let candidates: Vec<usize> = (0..self.seeds.len())
                .filter(|&i| self.seeds[i].0 == target)
                .collect();
            let base = candidates[self.rng.random_range(0..candidates.len())];
            let input = self.mutate(base);
            let outcome = std::panic::catch_unwind(|| read(target, &input, &self.dir));
            let tally = &mut self.tallies.iter_mut().find(|t| t.0 == target).unwrap().1;
            tally.executions += 1;
            match outcome {
                Ok(Some(0)) => tally.refused += 1,
                Ok(Some(n)) => {
                    tally.decoded += 1;
                    tally.messages += n;
                }
                Ok(None) => tally.refused += 1,
                Err(_) => {
                    tally.panics += 1;
                    if self.crashes.len() < 10 {
                        let path = self.dir.join(format!("crash_{}.bin", self.crashes.len()));
                        std::fs::write(&path, &input).expect("keep the crashing input");
                        self.crashes.push(path);
                    }
                }
            }
        }
    }

    /// The total over the three targets.
    pub fn total(&self) -> Tally {
        self.tallies
            .iter()
            .fold(Tally::default(), |a, (_, t)| Tally {
                executions: a.executions + t.executions,
                refused: a.refused + t.refused,
                decoded: a.decoded + t.decoded,
                messages: a.messages + t.messages,
                panics: a.panics + t.panics,
            })
    }

    /// One to eight havoc moves on a copy of seed `base`.
    fn mutate(&mut self, base: usize) -> Vec<u8> {
        let mut b = self.seeds[base].1.clone();
        let rng = &mut self.rng;
        for _ in 0..rng.random_range(1..=8) {
            if b.is_empty() {
                b.push(rng.random());
            }
            let at = rng.random_range(0..b.len());
            match rng.random_range(0..8) {
                0 => b[at] ^= 1 << rng.random_range(0..8),
                1 => b[at] = rng.random(),
                2 | 3 => {
                    // A boundary integer over a (probable) length field, either byte order.
                    let v = INTERESTING[rng.random_range(0..INTERESTING.len())];
                    let width = [1usize, 2, 4, 8][rng.random_range(0..4)];
                    let bytes = if rng.random() {
                        v.to_le_bytes()
                    } else {
                        v.to_be_bytes()
                    };
                    let bytes = if bytes[0] == 0 && width < 8 {
                        &bytes[8 - width..]
                    } else {
                        &bytes[..width]
                    };
                    let end = (at + width).min(b.len());
                    b[at..end].copy_from_slice(&bytes[..end - at]);
                }
                4 => b.truncate(at),
                5 => {
                    let end = rng.random_range(at..=b.len().min(at + 256));
                    b.drain(at..end);
                }
                6 => {
                    let end = rng.random_range(at..=b.len().min(at + 256));
                    let piece = b[at..end].to_vec();
                    let to = rng.random_range(0..=b.len());
                    b.splice(to..to, piece);
                }
                _ => {
                    // Splice: a piece of another seed at the same offset.
                    let other = &self.seeds[rng.random_range(0..self.seeds.len())].1;
                    if at < other.len() {
                        let end = rng.random_range(at..=other.len().min(at + 512));
                        let piece = &other[at..end];
                        let stop = (at + piece.len()).min(b.len());
                        b[at..stop].copy_from_slice(&piece[..stop - at]);
                    }
                }
            }
        }
        b
    }
}

/// Reads one input as `target`; `Some(messages decoded)` or `None` when refused. Panics are the
/// caller's to catch.
fn read(target: Target, input: &[u8], dir: &Path) -> Option<u64> {
    match target {
        Target::Cdr => {
            let imu = decode::<Imu>(input).ok();
            if let Some(m) = &imu {
                let again = decode::<Imu>(&encode(m).expect("a decoded Imu encodes"))
                    .expect("an encoded Imu decodes");
                assert!(
                    same_imu(m, &again),
                    "Imu round trip changed {m:?} into {again:?}"
                );
            }
            let temp = decode::<Temperature>(input).ok();
            if let Some(t) = &temp {
                let again =
                    decode::<Temperature>(&encode(t).expect("a decoded Temperature encodes"))
                        .expect("an encoded Temperature decodes");
                assert!(
                    t.temperature.to_bits() == again.temperature.to_bits()
                        && t.variance.to_bits() == again.variance.to_bits()
                        && t.header.frame_id == again.header.frame_id,
                    "Temperature round trip changed {t:?} into {again:?}"
                );
            }
            Some(u64::from(imu.is_some()) + u64::from(temp.is_some()))
        }
        Target::Mcap | Target::Sqlite => {
            let name = if target == Target::Mcap {
                "input.mcap"
            } else {
                "input.db3"
            };
            let path = dir.join(name);
            std::fs::write(&path, input).expect("write the input");
            let reader = BagReader::open(&path).ok()?;
            let imu = reader.imu_topic(None).ok()?.name.clone();
            let temperature = reader
                .temperature_topic(None)
                .ok()
                .flatten()
                .map(|t| t.name.clone());
            let messages = reader.messages(&imu, temperature.as_deref()).ok()?;
            // Every item is read to the end: errors after good messages are part of the test.
            Some(messages.filter(Result::is_ok).count() as u64)
        }
    }
}

/// Bitwise equality of the fields an Imu carries (NaN payloads included).
fn same_imu(a: &Imu, b: &Imu) -> bool {
    let bits = |m: &Imu| {
        let v = [
            m.orientation.x,
            m.orientation.y,
            m.orientation.z,
            m.orientation.w,
            m.angular_velocity.x,
            m.angular_velocity.y,
            m.angular_velocity.z,
            m.linear_acceleration.x,
            m.linear_acceleration.y,
            m.linear_acceleration.z,
        ];
        let cov = [
            m.orientation_covariance,
            m.angular_velocity_covariance,
            m.linear_acceleration_covariance,
        ];
        (
            v.map(f64::to_bits),
            cov.map(|c| c.map(f64::to_bits)),
            m.header.stamp.sec,
            m.header.stamp.nanosec,
            m.header.frame_id.clone(),
        )
    };
    bits(a) == bits(b)
}

fn sample(k: i64) -> ImuSample {
    let x = k as f64;
    ImuSample {
        stamp_ns: 1_700_000_000_000_000_000 + k * 10_000_000,
        gyro: [1e-3 * x.sin(), -2e-3 * x.cos(), 5e-4],
        accel: [0.01 * x, -0.02, 9.81],
    }
}

fn imu(k: i64) -> Imu {
    Imu::from_sample(&sample(k), "imu_link").unwrap()
}

fn temperature(k: i64) -> Temperature {
    let t = TemperatureSample {
        stamp_ns: sample(k).stamp_ns,
        celsius: 25.0 + 0.01 * k as f64,
    };
    Temperature::from_sample(&t, "imu_link").unwrap()
}

/// An fdavar MCAP of 60 Imu and 6 Temperature messages (several chunks' worth of records).
fn mcap_seed(dir: &Path, k: usize, compression: ChunkCompression) -> Vec<u8> {
    let bag = dir.join(format!("seed_{k}"));
    let mut w = BagWriter::create_with(
        &bag,
        &WriterOptions {
            compression,
            overwrite: true,
        },
    )
    .expect("seed writer");
    for i in 0..60 {
        let s = sample(i);
        w.write_imu("/imu", s.stamp_ns + 500, &s, "imu_link")
            .unwrap();
        if i % 10 == 0 {
            w.write_message("/temperature", s.stamp_ns + 700, &temperature(i))
                .unwrap();
        }
    }
    w.finish().unwrap();
    let file = std::fs::read_dir(&bag)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "mcap"))
        .expect("the seed's .mcap");
    std::fs::read(file).unwrap()
}

/// A rosbag2 (Humble layout) sqlite3 bag of 30 Imu messages.
fn sqlite_seed(dir: &Path) -> Vec<u8> {
    let path = dir.join("seed.db3");
    let _ = std::fs::remove_file(&path);
    let db = rusqlite::Connection::open(&path).unwrap();
    db.execute_batch(
        "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
         INSERT INTO schema VALUES (3, 'humble');
         CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
             serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
         CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
             timestamp INTEGER NOT NULL, data BLOB NOT NULL);
         CREATE INDEX timestamp_idx ON messages (timestamp ASC);
         INSERT INTO topics VALUES (1, '/imu', 'sensor_msgs/msg/Imu', 'cdr', '');",
    )
    .unwrap();
    for k in 0..30 {
        db.execute(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES (1, ?1, ?2)",
            rusqlite::params![sample(k).stamp_ns + 500, encode(&imu(k)).unwrap()],
        )
        .unwrap();
    }
    drop(db);
    std::fs::read(&path).unwrap()
}
