//! [`BagReader`]: opens a bag (directory, `.mcap` or `.db3`), lists topics, streams IMU samples.

use super::metadata::{self, BagFile};
use super::{list_topics, mcap, sqlite, BagError, BagMessage, Storage, TopicInfo};
use super::{IMU_TYPE, TEMPERATURE_TYPE};
use crate::msgs::sensor_msgs::{ImuReading, Temperature, IMU};
use crate::msgs::{decode, decode_as, MsgError};
use std::path::{Path, PathBuf};

/// Which decoded message a raw one becomes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Role {
    Imu,
    Temperature,
}

/// One stored message of a wanted topic, not yet decoded.
pub(crate) struct RawMessage {
    pub role: Role,
    pub log_time_ns: i64,
    pub data: Vec<u8>,
}

/// The messages of one storage file, in storage order.
pub(crate) type RawStream = Box<dyn Iterator<Item = Result<RawMessage, BagError>> + Send>;

/// What one storage file holds.
pub(crate) struct FileSummary {
    pub topics: Vec<TopicInfo>,
    /// First and last log time, ns, if the file has messages.
    pub span: Option<(i64, i64)>,
}

/// An opened rosbag2 recording: its files, topics and time span.
///
/// Opening reads only summaries (MCAP summary sections, sqlite `GROUP BY`), or scans an MCAP file
/// that has none; messages are streamed by [`BagReader::messages`].
///
/// ```no_run
/// use fdavar::bag::{BagMessage, BagReader};
/// let bag = BagReader::open("recording")?;
/// let imu = bag.imu_topic(None)?.name.clone();
/// for message in bag.messages(&imu, None)? {
///     if let BagMessage::Imu { sample, .. } = message? {
///         println!("{} {:?}", sample.stamp_ns, sample.gyro);
///     }
/// }
/// # Ok::<(), fdavar::bag::BagError>(())
/// ```
#[derive(Debug)]
pub struct BagReader {
    path: PathBuf,
    files: Vec<BagFile>,
    topics: Vec<TopicInfo>,
    span: Option<(i64, i64)>,
}

impl BagReader {
    /// Opens a bag directory (with or without `metadata.yaml`), or a bare `.mcap` / `.db3` file.
    ///
    /// # Errors
    /// [`BagError::NotFound`], [`BagError::NotABag`] (a directory without bag files),
    /// [`BagError::UnknownStorage`], [`BagError::Metadata`], [`BagError::UnknownCompression`],
    /// [`BagError::Truncated`] / [`BagError::CorruptMcap`] / [`BagError::CorruptSqlite`] when a
    /// file's summary cannot be read.
    pub fn open(path: impl AsRef<Path>) -> Result<BagReader, BagError> {
        let path = path.as_ref().to_path_buf();
        let files = bag_files(&path)?;
        let mut topics: Vec<TopicInfo> = Vec::new();
        let mut span: Option<(i64, i64)> = None;
        for file in &files {
            let summary = match file.storage {
                Storage::Mcap => mcap::summarize(file)?,
                Storage::Sqlite3 => sqlite::summarize(file)?,
            };
            for t in summary.topics {
                match topics
                    .iter_mut()
                    .find(|k| k.name == t.name && k.type_name == t.type_name)
                {
                    Some(known) => known.message_count += t.message_count,
                    None => topics.push(t),
                }
            }
            if let Some((lo, hi)) = summary.span {
                span = Some(span.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
            }
        }
        Ok(BagReader {
            path,
            files,
            topics,
            span,
        })
    }

    /// The path the bag was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The storage files, in reading order.
    pub fn files(&self) -> impl Iterator<Item = (&Path, Storage)> {
        self.files.iter().map(|f| (f.path.as_path(), f.storage))
    }

    /// Every topic of the bag, in the order the files list them.
    pub fn topics(&self) -> &[TopicInfo] {
        &self.topics
    }

    /// First and last log time over all messages, ns since the epoch (`None` for an empty bag).
    pub fn time_span_ns(&self) -> Option<(i64, i64)> {
        self.span
    }

    /// The IMU topic to analyse: `choice` if given (it must be a `sensor_msgs/msg/Imu` topic),
    /// else the only `sensor_msgs/msg/Imu` topic of the bag.
    ///
    /// # Errors
    /// [`BagError::NoTopicOfType`] ("holds no sensor_msgs/msg/Imu; topics: …"),
    /// [`BagError::AmbiguousTopic`] listing the candidates, [`BagError::NoSuchTopic`].
    pub fn imu_topic(&self, choice: Option<&str>) -> Result<&TopicInfo, BagError> {
        self.pick(IMU_TYPE, choice)?
            .ok_or_else(|| BagError::NoTopicOfType {
                path: self.path.clone(),
                type_name: IMU_TYPE,
                topics: list_topics(&self.topics),
            })
    }

    /// The temperature topic: `choice` if given, else the only `sensor_msgs/msg/Temperature`
    /// topic, or `None` when the bag has none (temperature is optional evidence).
    ///
    /// # Errors
    /// [`BagError::AmbiguousTopic`], [`BagError::NoSuchTopic`].
    pub fn temperature_topic(&self, choice: Option<&str>) -> Result<Option<&TopicInfo>, BagError> {
        self.pick(TEMPERATURE_TYPE, choice)
    }

    fn pick(
        &self,
        type_name: &'static str,
        choice: Option<&str>,
    ) -> Result<Option<&TopicInfo>, BagError> {
        let of_type = || self.topics.iter().filter(move |t| t.type_name == type_name);
        if let Some(name) = choice {
            return of_type().find(|t| t.name == name).map(Some).ok_or_else(|| {
                BagError::NoSuchTopic {
                    path: self.path.clone(),
                    topic: name.to_string(),
                    type_name,
                    topics: list_topics(&self.topics),
                }
            });
        }
        let mut candidates = of_type();
        match (candidates.next(), candidates.next()) {
            (None, _) => Ok(None),
            (Some(only), None) => Ok(Some(only)),
            (Some(_), Some(_)) => Err(BagError::AmbiguousTopic {
                path: self.path.clone(),
                type_name,
                candidates: of_type()
                    .map(|t| t.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            }),
        }
    }

    /// Streams the messages of `imu_topic` (and of `temperature_topic`, if given), decoded, file
    /// after file; within a file in MCAP file order or sqlite timestamp order.
    ///
    /// Memory does not grow with the recording's length.
    ///
    /// # Errors
    /// [`BagError::NoSuchTopic`] if a topic is not of the right type in this bag; errors opening
    /// the first file. Per item: read errors, and [`BagError::Malformed`] naming the topic and
    /// log time of a message that does not decode (the stream goes on after it). After any other
    /// error the stream ends.
    pub fn messages(
        &self,
        imu_topic: &str,
        temperature_topic: Option<&str>,
    ) -> Result<BagMessages, BagError> {
        let mut wanted = vec![(self.imu_topic(Some(imu_topic))?.name.clone(), Role::Imu)];
        if let Some(t) = temperature_topic {
            let topic = self.temperature_topic(Some(t))?.map(|t| t.name.clone());
            wanted.extend(topic.map(|name| (name, Role::Temperature)));
        }
        let mut files = self.files.clone();
        files.reverse();
        let mut messages = BagMessages {
            files,
            wanted,
            current: None,
            current_path: PathBuf::new(),
            failed: false,
        };
        messages.advance_file()?;
        Ok(messages)
    }
}

/// The storage files of a bag path.
fn bag_files(path: &Path) -> Result<Vec<BagFile>, BagError> {
    if !path.exists() {
        return Err(BagError::NotFound {
            path: path.to_path_buf(),
        });
    }
    if path.is_file() {
        let storage = metadata::storage_of(path, None)?;
        let compression = path
            .extension()
            .is_some_and(|e| e == "zstd")
            .then_some(metadata::FileCompression::Zstd);
        return Ok(vec![BagFile {
            path: path.to_path_buf(),
            storage,
            compression,
        }]);
    }
    if path.join(metadata::FILE_NAME).is_file() {
        return metadata::read(path);
    }
    // No metadata.yaml (a crashed recording, or files copied alone): every storage file in the
    // directory, ordered by split index `_0`, `_1`, … (then by name).
    let mut files = Vec::new();
    for entry in std::fs::read_dir(path).map_err(BagError::io(path))? {
        let file = entry.map_err(BagError::io(path))?.path();
        if let Ok(storage) = metadata::storage_of(&file, None) {
            if super::is_storage_file(&file) {
                files.push(BagFile {
                    path: file,
                    storage,
                    compression: None,
                });
            }
        }
    }
    if files.is_empty() {
        return Err(BagError::NotABag {
            path: path.to_path_buf(),
        });
    }
    files.sort_by_key(|f| (split_index(&f.path), f.path.clone()));
    Ok(files)
}

/// The `N` of `<name>_N.<ext>`, if the file name has one.
fn split_index(file: &Path) -> Option<u64> {
    let stem = file.file_stem()?.to_str()?;
    stem.rsplit_once('_')?.1.parse().ok()
}

/// The decoded messages of a bag, file after file (see [`BagReader::messages`]).
pub struct BagMessages {
    /// Files still to read, last first.
    files: Vec<BagFile>,
    wanted: Vec<(String, Role)>,
    current: Option<RawStream>,
    /// The file `current` reads.
    current_path: PathBuf,
    failed: bool,
}

impl BagMessages {
    /// Opens the next file; `current` is `None` when none is left.
    fn advance_file(&mut self) -> Result<(), BagError> {
        self.current = None;
        if let Some(file) = self.files.pop() {
            let stream = match file.storage {
                Storage::Mcap => mcap::stream(&file, &self.wanted)?,
                Storage::Sqlite3 => sqlite::stream(&file, &self.wanted)?,
            };
            self.current = Some(stream);
            self.current_path = file.path;
        }
        Ok(())
    }

    fn decode(&self, raw: RawMessage) -> Result<BagMessage, BagError> {
        let path = &self.current_path;
        let log_time_ns = raw.log_time_ns;
        let malformed = |source: MsgError| {
            let topic = self
                .wanted
                .iter()
                .find(|(_, r)| *r == raw.role)
                .map(|(t, _)| t.clone());
            BagError::Malformed {
                path: path.to_path_buf(),
                topic: topic.unwrap_or_default(),
                log_time_ns,
                source,
            }
        };
        Ok(match raw.role {
            Role::Imu => BagMessage::Imu {
                log_time_ns,
                sample: decode_as::<ImuReading>(&raw.data, IMU.name)
                    .map_err(malformed)?
                    .to_sample(log_time_ns),
            },
            Role::Temperature => BagMessage::Temperature {
                log_time_ns,
                sample: decode::<Temperature>(&raw.data)
                    .map_err(malformed)?
                    .to_sample(log_time_ns),
            },
        })
    }
}

impl Iterator for BagMessages {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        loop {
            match self.current.as_mut()?.next() {
                // A message that does not decode is reported; the stream itself goes on.
                Some(Ok(raw)) => return Some(self.decode(raw)),
                Some(Err(e)) => {
                    self.failed = true;
                    return Some(Err(e));
                }
                None => {
                    if let Err(e) = self.advance_file() {
                        self.failed = true;
                        return Some(Err(e));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_files_sort_by_index_not_by_name() {
        let names = ["b_10.mcap", "b_2.mcap", "b_0.mcap"];
        let mut paths: Vec<PathBuf> = names.iter().map(PathBuf::from).collect();
        paths.sort_by_key(|p| (split_index(p), p.clone()));
        assert_eq!(
            paths,
            ["b_0.mcap", "b_2.mcap", "b_10.mcap"].map(PathBuf::from)
        );
    }
}
