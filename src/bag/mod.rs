//! rosbag2 recordings in and out: MCAP and sqlite3 behind one reader and one writer.
//!
//! [`BagReader`] opens what `ros2 bag record` leaves behind — a bag directory (`metadata.yaml`
//! and split files `<name>_0.mcap`, `_1`, …), or a bare `.mcap` / `.db3` — lists its topics, picks
//! the `sensor_msgs/msg/Imu` topic (and optionally a `sensor_msgs/msg/Temperature` one) and streams
//! them as [`BagMessage`]s. [`BagWriter`] writes rosbag2 MCAP directories that `ros2 bag` and
//! `rosbags` accept (used by `fdavar simulate`).
//!
//! Choices, and the alternatives left out:
//! - **Streaming, not loading.** MCAP is read through `mcap::io::MessageReader` over a buffered
//!   file (memory bounded by the largest chunk), sqlite3 through one query ordered by timestamp
//!   whose rows a worker thread hands over, in batches, through a bounded channel. Memory-mapping
//!   the whole file for `mcap::MessageStream` was left out: the streaming reader meets the
//!   targets (benches/bag_read.rs) without `unsafe` and also reads zstd-compressed files.
//! - **Damage is an error, never an abort.** Record lengths are capped at the file's size (the
//!   `mcap` crate otherwise allocates whatever a corrupt length field says) and chunk CRCs are
//!   checked.
//! - **The files are the truth.** Topics and counts come from each file (MCAP summary statistics,
//!   or one scan when a recording has no summary; `GROUP BY` in sqlite3), not from
//!   `metadata.yaml`, which a crashed recording lacks or has stale. `metadata.yaml` is used for
//!   what only it knows: the list of split files and their file-level compression.
//! - **Sample time = `header.stamp`** (the sensor clock); the log (receive) time only when the
//!   stamp is zero (docs/design.md §1). Both are handed out: [`BagMessage`] carries the log time too.
//! - **Errors name the place**: the file, the topic, the log time of a malformed message; a bag
//!   without Imu lists what it does hold.

mod mcap;
mod metadata;
mod reader;
mod sqlite;
mod writer;

pub use reader::{BagMessages, BagReader};
pub use writer::{BagWriter, ChunkCompression, WriterOptions};

use crate::msgs::MsgError;
use crate::signal::{ImuSample, TemperatureSample};
use std::fmt;
use std::path::{Path, PathBuf};

/// The ROS type of IMU messages: the topic fdavar analyses has this type.
pub const IMU_TYPE: &str = "sensor_msgs/msg/Imu";
/// The ROS type of temperature messages (for the `temperature` effect).
pub const TEMPERATURE_TYPE: &str = "sensor_msgs/msg/Temperature";

/// The storage format of one bag file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Storage {
    /// MCAP (default since ROS 2 Iron).
    Mcap,
    /// sqlite3 `.db3` (default up to Humble).
    Sqlite3,
}

impl fmt::Display for Storage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Storage::Mcap => "mcap",
            Storage::Sqlite3 => "sqlite3",
        })
    }
}

/// One topic of a bag: name, ROS type and how many messages it holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// Topic name, e.g. `/imu/data`.
    pub name: String,
    /// ROS type, e.g. `sensor_msgs/msg/Imu`.
    pub type_name: String,
    /// Messages on this topic, over all files of the bag.
    pub message_count: u64,
}

impl fmt::Display for TopicInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} [{}] ({} msgs)",
            self.name, self.type_name, self.message_count
        )
    }
}

/// The topics of a bag, written one per line-free list for error messages.
pub(crate) fn list_topics(topics: &[TopicInfo]) -> String {
    if topics.is_empty() {
        return "none".to_string();
    }
    topics
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// One message read from a bag, decoded.
#[derive(Debug, Clone, PartialEq)]
pub enum BagMessage {
    /// A `sensor_msgs/msg/Imu` from the chosen IMU topic.
    Imu {
        /// When the recorder received it, ns since the epoch (rosbag2's message timestamp).
        log_time_ns: i64,
        /// Its six rates, timed by `header.stamp` (or `log_time_ns` if the stamp is zero).
        sample: ImuSample,
    },
    /// A `sensor_msgs/msg/Temperature` from the chosen temperature topic.
    Temperature {
        /// When the recorder received it, ns since the epoch.
        log_time_ns: i64,
        /// The reading, timed like the IMU samples.
        sample: TemperatureSample,
    },
}

/// Why a bag could not be opened, read or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BagError {
    /// The path does not exist.
    #[error("{path}: no such file or directory")]
    NotFound {
        /// The path given.
        path: PathBuf,
    },
    /// A directory with neither `metadata.yaml` nor a `.mcap` / `.db3` file in it.
    #[error("{path}: not a rosbag2 bag (no metadata.yaml, .mcap or .db3 inside)")]
    NotABag {
        /// The directory.
        path: PathBuf,
    },
    /// A file whose name or content is neither MCAP nor sqlite3.
    #[error("{path}: not a rosbag2 storage file ({reason})")]
    UnknownStorage {
        /// The file.
        path: PathBuf,
        /// What was found instead.
        reason: String,
    },
    /// `metadata.yaml` that does not parse or names a missing file.
    #[error("{path}: bad metadata.yaml: {reason}")]
    Metadata {
        /// The metadata file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A compression fdavar cannot read (file-level in metadata.yaml, or an MCAP chunk's).
    #[error(
        "{path}: unsupported compression '{compression}' (supported: zstd, lz4 chunks; zstd files)"
    )]
    UnknownCompression {
        /// The file (or metadata.yaml) that names it.
        path: PathBuf,
        /// The compression named.
        compression: String,
    },
    /// An MCAP file that ends early (a recording that crashed, or a partial copy).
    #[error("{path}: truncated MCAP file ({detail}); `mcap recover` may salvage it")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// What the MCAP reader reported.
        detail: String,
    },
    /// An MCAP file whose records do not parse.
    #[error("{path}: corrupt MCAP file: {detail}")]
    CorruptMcap {
        /// The file.
        path: PathBuf,
        /// What the MCAP reader reported.
        detail: String,
    },
    /// An sqlite3 file that sqlite cannot read as a rosbag2 database.
    #[error("{path}: corrupt or unreadable sqlite3 bag: {detail}")]
    CorruptSqlite {
        /// The file.
        path: PathBuf,
        /// What sqlite reported.
        detail: String,
    },
    /// The bag has no topic of the wanted type.
    #[error("{path} holds no {type_name}; topics: {topics}")]
    NoTopicOfType {
        /// The bag.
        path: PathBuf,
        /// The ROS type looked for.
        type_name: &'static str,
        /// The topics it does hold, as `name [type] (count), …`.
        topics: String,
    },
    /// Several topics of the wanted type and no choice made.
    #[error("{path} holds several {type_name} topics ({candidates}); choose one with --topic")]
    AmbiguousTopic {
        /// The bag.
        path: PathBuf,
        /// The ROS type looked for.
        type_name: &'static str,
        /// The topics of that type.
        candidates: String,
    },
    /// The chosen topic is not in the bag, or has another type.
    #[error("{path}: topic '{topic}' is not a {type_name} topic of this bag; topics: {topics}")]
    NoSuchTopic {
        /// The bag.
        path: PathBuf,
        /// The topic asked for.
        topic: String,
        /// The ROS type it should have.
        type_name: &'static str,
        /// The topics the bag holds.
        topics: String,
    },
    /// A message whose bytes do not decode as its type (the decoding failure is the source: a
    /// report of the chain says it after this).
    #[error("{path}: message on {topic} at log time {log_time_ns} ns")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// Its topic.
        topic: String,
        /// Its log time, ns since the epoch.
        log_time_ns: i64,
        /// The decoding failure.
        source: MsgError,
    },
    /// A writer asked to create a bag where one (or anything) already exists.
    #[error("{path} already exists (refusing to overwrite; remove it or ask for overwrite)")]
    AlreadyExists {
        /// The output directory.
        path: PathBuf,
    },
    /// A value the writer cannot store (a negative log time, a stamp beyond 2038, …).
    #[error("cannot write to {topic}: {reason}")]
    Unwritable {
        /// The topic.
        topic: String,
        /// Why.
        reason: String,
    },
    /// A topic written with two different types.
    #[error("topic {topic} was written as {first} and now as {now}")]
    TopicTypeConflict {
        /// The topic.
        topic: String,
        /// Its type so far.
        first: String,
        /// The type now asked for.
        now: String,
    },
    /// A writer that failed earlier, or was finished, refuses further use.
    #[error("bag writer for {path} is {state}; no further writes")]
    WriterClosed {
        /// The output directory.
        path: PathBuf,
        /// `failed` or `finished`.
        state: &'static str,
    },
    /// An I/O failure on a file (the I/O error is the source: a report of the chain says it after
    /// the path).
    #[error("{path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

impl BagError {
    /// An I/O error on `path` (used with `map_err`).
    pub(crate) fn io(path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> BagError {
        let path = path.into();
        move |source| BagError::Io { path, source }
    }
}

/// Whether `path` is a rosbag2 storage file: a `.mcap` or `.db3` file.
pub fn is_storage_file(path: &Path) -> bool {
    path.is_file() && path.extension().is_some_and(|e| e == "mcap" || e == "db3")
}

/// Whether [`BagReader::open`] reads the directory `dir` as one recording: it holds
/// `metadata.yaml` or a storage file ([`is_storage_file`]) directly inside.
///
/// # Errors
/// The directory cannot be listed.
pub fn holds_a_bag(dir: &Path) -> std::io::Result<bool> {
    if dir.join(metadata::FILE_NAME).exists() {
        return Ok(true);
    }
    for entry in std::fs::read_dir(dir)? {
        if is_storage_file(&entry?.path()) {
            return Ok(true);
        }
    }
    Ok(false)
}
