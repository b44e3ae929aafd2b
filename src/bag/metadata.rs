//! `metadata.yaml`, the index of a rosbag2 directory: read (any version) and write (version 9).
//!
//! Reading keeps only what the storage files cannot tell: which files make up the bag, in which
//! storage, and whether whole files are compressed. Writing produces what rosbag2 Jazzy writes,
//! so `ros2 bag info` and `rosbags` accept the directory.

use super::{BagError, Storage};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The name of the index file inside a bag directory.
pub(crate) const FILE_NAME: &str = "metadata.yaml";

/// The metadata version written (rosbag2 Jazzy).
pub(crate) const VERSION: u32 = 9;

#[derive(Deserialize)]
struct Root {
    rosbag2_bagfile_information: Info,
}

#[derive(Deserialize)]
struct Info {
    #[serde(default)]
    storage_identifier: Option<String>,
    #[serde(default)]
    relative_file_paths: Vec<String>,
    #[serde(default)]
    compression_format: Option<String>,
    #[serde(default)]
    compression_mode: Option<String>,
}

/// Whole-file compression of a bag's storage files (`compression_mode: FILE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FileCompression {
    /// `*.mcap.zstd` / `*.db3.zstd`.
    Zstd,
}

/// One storage file of a bag, as listed by its metadata.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct BagFile {
    pub path: PathBuf,
    pub storage: Storage,
    pub compression: Option<FileCompression>,
}

/// The storage files `metadata.yaml` lists, in order, checked to exist.
pub(crate) fn read(dir: &Path) -> Result<Vec<BagFile>, BagError> {
    let path = dir.join(FILE_NAME);
    let bad = |reason: String| BagError::Metadata {
        path: path.clone(),
        reason,
    };
    let text = std::fs::read_to_string(&path).map_err(BagError::io(&path))?;
    let root: Root = serde_yaml_ng::from_str(&text).map_err(|e| bad(e.to_string()))?;
    let info = root.rosbag2_bagfile_information;
    let compression = match (
        info.compression_mode.as_deref(),
        info.compression_format.as_deref(),
    ) {
        (None | Some("" | "NONE" | "none"), _) => None,
        // Message-mode compression compresses each message body; rosbag2 deprecated it and
        // fdavar does not decode it.
        (Some("FILE" | "file"), Some("zstd")) => Some(FileCompression::Zstd),
        (Some(mode), format) => {
            return Err(BagError::UnknownCompression {
                path,
                compression: format!("{} ({mode} mode)", format.unwrap_or("")),
            })
        }
    };
    if info.relative_file_paths.is_empty() {
        return Err(bad("relative_file_paths is empty".into()));
    }
    info.relative_file_paths
        .iter()
        .map(|rel| {
            let file = dir.join(rel);
            if !file.is_file() {
                return Err(bad(format!("lists {rel}, which does not exist")));
            }
            let storage = storage_of(&file, info.storage_identifier.as_deref())?;
            Ok(BagFile {
                path: file,
                storage,
                compression,
            })
        })
        .collect()
}

/// The storage of a file, from its extension (ignoring a `.zstd` suffix), else from the
/// metadata's `storage_identifier`.
pub(crate) fn storage_of(file: &Path, identifier: Option<&str>) -> Result<Storage, BagError> {
    let name = file
        .file_name()
        .map(|n| n.to_string_lossy())
        .unwrap_or_default();
    let name = name.strip_suffix(".zstd").unwrap_or(&name);
    if name.ends_with(".mcap") {
        return Ok(Storage::Mcap);
    }
    if name.ends_with(".db3") {
        return Ok(Storage::Sqlite3);
    }
    match identifier {
        Some("mcap") => Ok(Storage::Mcap),
        Some("sqlite3") => Ok(Storage::Sqlite3),
        other => Err(BagError::UnknownStorage {
            path: file.to_path_buf(),
            reason: format!("extension not .mcap/.db3, storage_identifier {other:?}"),
        }),
    }
}

/// Written form of `metadata.yaml` (version 9).
#[derive(Serialize)]
pub(crate) struct WrittenRoot<'a> {
    pub rosbag2_bagfile_information: WrittenInfo<'a>,
}

#[derive(Serialize)]
pub(crate) struct WrittenInfo<'a> {
    pub version: u32,
    pub storage_identifier: &'static str,
    pub duration: Nanoseconds,
    pub starting_time: NanosecondsSinceEpoch,
    pub message_count: u64,
    pub topics_with_message_count: Vec<TopicWithCount<'a>>,
    pub compression_format: &'static str,
    pub compression_mode: &'static str,
    pub relative_file_paths: Vec<String>,
    pub files: Vec<FileInfo>,
    pub custom_data: Option<()>,
    pub ros_distro: &'static str,
}

#[derive(Serialize)]
pub(crate) struct Nanoseconds {
    pub nanoseconds: u64,
}

#[derive(Serialize)]
pub(crate) struct NanosecondsSinceEpoch {
    pub nanoseconds_since_epoch: u64,
}

#[derive(Serialize)]
pub(crate) struct TopicWithCount<'a> {
    pub topic_metadata: TopicMetadata<'a>,
    pub message_count: u64,
}

#[derive(Serialize)]
pub(crate) struct TopicMetadata<'a> {
    pub name: &'a str,
    #[serde(rename = "type")]
    pub type_name: &'a str,
    pub serialization_format: &'static str,
    pub offered_qos_profiles: Vec<QosProfile>,
    pub type_description_hash: &'a str,
}

#[derive(Serialize)]
pub(crate) struct FileInfo {
    pub path: String,
    pub starting_time: NanosecondsSinceEpoch,
    pub duration: Nanoseconds,
    pub message_count: u64,
}

/// A ROS 2 QoS profile in the Jazzy (string enum) form of rosbag2 metadata.
#[derive(Serialize)]
pub(crate) struct QosProfile {
    pub history: &'static str,
    pub depth: u32,
    pub reliability: &'static str,
    pub durability: &'static str,
    pub deadline: Duration,
    pub lifespan: Duration,
    pub liveliness: &'static str,
    pub liveliness_lease_duration: Duration,
    pub avoid_ros_namespace_conventions: bool,
}

#[derive(Serialize)]
pub(crate) struct Duration {
    pub sec: i64,
    pub nsec: u32,
}

impl QosProfile {
    /// The profile a sensor driver offers (`rclcpp::SensorDataQoS`: best effort, keep last 5),
    /// with rosbag2's "infinite" durations.
    pub(crate) fn sensor_data() -> QosProfile {
        let infinite = || Duration {
            sec: 9_223_372_036,
            nsec: 854_775_807,
        };
        QosProfile {
            history: "keep_last",
            depth: 5,
            reliability: "best_effort",
            durability: "volatile",
            deadline: infinite(),
            lifespan: infinite(),
            liveliness: "automatic",
            liveliness_lease_duration: infinite(),
            avoid_ros_namespace_conventions: false,
        }
    }

    /// The profile of a status publisher (`rclcpp` default: reliable, keep last 10).
    pub(crate) fn reliable() -> QosProfile {
        QosProfile {
            depth: 10,
            reliability: "reliable",
            ..QosProfile::sensor_data()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn message_mode_compression_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(FILE_NAME),
            "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n  \
             relative_file_paths: [a.db3]\n  compression_format: bz2\n  compression_mode: FILE\n",
        )
        .unwrap();
        let err = read(dir.path()).unwrap_err();
        assert!(
            matches!(err, BagError::UnknownCompression { ref compression, .. } if compression.contains("bz2")),
            "{err}"
        );
    }

    #[test]
    fn missing_listed_file_is_named() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(FILE_NAME),
            "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  \
             relative_file_paths: [x_0.mcap]\n",
        )
        .unwrap();
        let err = read(dir.path()).unwrap_err().to_string();
        assert!(err.contains("x_0.mcap"), "{err}");
    }
}
