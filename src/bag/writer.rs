//! [`BagWriter`]: writes a rosbag2 MCAP directory that `ros2 bag` and `rosbags` read.
//!
//! What rosbag2 (Jazzy) expects, and this writes: MCAP profile `ros2`; one `ros2msg` schema per
//! type holding the `.msg` text and its dependencies; channels with message encoding `cdr` and
//! metadata `offered_qos_profiles` (and `topic_type_hash`); a `rosbag2` metadata record; and
//! beside the file a `metadata.yaml` of version 9. Chunks are zstd-compressed by default (the
//! `ros2 bag record --storage-preset-profile zstd_fast` layout); rosbag2 reads all variants.

use super::metadata::{self, QosProfile};
use super::BagError;
use crate::msgs::sensor_msgs::{Imu, Temperature};
use crate::msgs::{encode, MsgDef, RosMessage};
use crate::signal::{ImuSample, TemperatureSample};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// How MCAP chunks are compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ChunkCompression {
    /// zstd (default): about 3× smaller for IMU data, fast to read.
    #[default]
    Zstd,
    /// lz4: faster to write, larger.
    Lz4,
    /// Uncompressed chunks (rosbag2's own default).
    None,
}

impl ChunkCompression {
    /// Every chunk compression fdavar writes (and reads).
    pub const ALL: [ChunkCompression; 3] =
        [ChunkCompression::Zstd, ChunkCompression::Lz4, ChunkCompression::None];
}

/// Options of [`BagWriter::create_with`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct WriterOptions {
    /// Chunk compression (default zstd).
    pub compression: ChunkCompression,
    /// Replace an existing bag directory (one holding a `metadata.yaml` or `.mcap`/`.db3`
    /// files, or empty). Anything else at the path is never removed. Default false.
    pub overwrite: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Open,
    Failed,
    Finished,
}

/// One topic written so far.
struct Topic {
    name: String,
    def: &'static MsgDef,
    channel_id: u16,
    count: u64,
}

/// Writes IMU (and temperature) messages into a new rosbag2 MCAP directory.
///
/// Why: `fdavar simulate` produces recordings whose truth is known, and they must replay with
/// `ros2 bag play` like any recording. Call [`BagWriter::finish`] at the end: it completes the
/// MCAP summary and writes `metadata.yaml`; a writer dropped without it leaves a bag without
/// `metadata.yaml` (readable by fdavar, but not a finished rosbag2 bag). After any error the
/// writer refuses further writes.
///
/// ```
/// use fdavar::bag::{BagReader, BagWriter, BagMessage};
/// use fdavar::signal::ImuSample;
/// let dir = tempfile::tempdir()?;
/// let bag = dir.path().join("sim");
/// let mut w = BagWriter::create(&bag)?;
/// let s = ImuSample { stamp_ns: 1_000, gyro: [0.1, 0.2, 0.3], accel: [0.0, 0.0, 9.81] };
/// w.write_imu("/imu", 1_000, &s, "imu_link")?;
/// w.finish()?;
/// let r = BagReader::open(&bag)?;
/// let got: Vec<_> = r.messages("/imu", None)?.collect::<Result<_, _>>()?;
/// assert_eq!(got, [BagMessage::Imu { log_time_ns: 1_000, sample: s }]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct BagWriter {
    dir: PathBuf,
    file_name: String,
    /// False for a bare `.mcap` file ([`BagWriter::create_file`]): no `metadata.yaml` beside it.
    metadata_yaml: bool,
    mcap: mcap::Writer<BufWriter<File>>,
    schemas: HashMap<&'static str, u16>,
    topics: Vec<Topic>,
    span: Option<(i64, i64)>,
    state: State,
}

impl std::fmt::Debug for BagWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BagWriter")
            .field("dir", &self.dir)
            .field("state", &self.state)
            .finish()
    }
}

impl BagWriter {
    /// Creates the bag directory `dir` (which must not exist) with default options.
    ///
    /// # Errors
    /// [`BagError::AlreadyExists`], or [`BagError::Io`] creating the directory or file.
    pub fn create(dir: impl AsRef<Path>) -> Result<BagWriter, BagError> {
        Self::create_with(dir, &WriterOptions::default())
    }

    /// Creates the bag directory `dir` with `options`.
    ///
    /// # Errors
    /// As [`BagWriter::create`]; with `overwrite`, [`BagError::AlreadyExists`] still protects a
    /// path that is not a bag directory.
    pub fn create_with(
        dir: impl AsRef<Path>,
        options: &WriterOptions,
    ) -> Result<BagWriter, BagError> {
        let dir = dir.as_ref().to_path_buf();
        if dir.exists() {
            if !(options.overwrite && is_bag_dir(&dir)) {
                return Err(BagError::AlreadyExists { path: dir });
            }
            std::fs::remove_dir_all(&dir).map_err(BagError::io(&dir))?;
        }
        std::fs::create_dir_all(&dir).map_err(BagError::io(&dir))?;
        let stem = dir.file_name().map(|n| n.to_string_lossy().into_owned());
        let file_name = format!("{}_0.mcap", stem.unwrap_or_else(|| "bag".into()));
        Self::open_mcap(dir, file_name, true, options)
    }

    /// Creates (or replaces) the bare MCAP file `path`, without a bag directory or
    /// `metadata.yaml` (rosbag2, Foxglove and PlotJuggler open a bare `.mcap`); the `rosbag2`
    /// metadata record is still written inside. Used for results files
    /// ([`crate::results::ResultsWriter`]).
    ///
    /// # Errors
    /// [`BagError::Io`] when `path` is a directory or the file cannot be created.
    pub fn create_file(
        path: impl AsRef<Path>,
        options: &WriterOptions,
    ) -> Result<BagWriter, BagError> {
        let path = path.as_ref();
        let (Some(name), false) = (path.file_name(), path.is_dir()) else {
            return Err(BagError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::new(
                    std::io::ErrorKind::IsADirectory,
                    "a directory, not a file name",
                ),
            });
        };
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        Self::open_mcap(dir, name.to_string_lossy().into_owned(), false, options)
    }

    fn open_mcap(
        dir: PathBuf,
        file_name: String,
        metadata_yaml: bool,
        options: &WriterOptions,
    ) -> Result<BagWriter, BagError> {
        let path = dir.join(&file_name);
        let file = File::create(&path).map_err(BagError::io(&path))?;
        let compression = match options.compression {
            ChunkCompression::Zstd => Some(mcap::Compression::Zstd),
            ChunkCompression::Lz4 => Some(mcap::Compression::Lz4),
            ChunkCompression::None => None,
        };
        let mcap = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("fdavar ", env!("CARGO_PKG_VERSION")))
            .compression(compression)
            .create(BufWriter::new(file))
            .map_err(|e| mcap_error(&path, e))?;
        Ok(BagWriter {
            dir,
            file_name,
            metadata_yaml,
            mcap,
            schemas: HashMap::new(),
            topics: Vec::new(),
            span: None,
            state: State::Open,
        })
    }

    /// Writes one `sensor_msgs/msg/Imu` carrying `sample` on `topic`, received at `log_time_ns`.
    ///
    /// The header stamp is `sample.stamp_ns`; see [`Imu::from_sample`] for the other fields.
    ///
    /// # Errors
    /// [`BagError::Unwritable`] (negative log time, stamp beyond 2038),
    /// [`BagError::TopicTypeConflict`], [`BagError::WriterClosed`], I/O errors.
    pub fn write_imu(
        &mut self,
        topic: &str,
        log_time_ns: i64,
        sample: &ImuSample,
        frame_id: &str,
    ) -> Result<(), BagError> {
        self.guarded(|w| {
            let msg = Imu::from_sample(sample, frame_id).map_err(|e| unwritable(topic, e))?;
            w.write(topic, log_time_ns, &msg)
        })
    }

    /// Writes one `sensor_msgs/msg/Temperature` carrying `sample` on `topic`.
    ///
    /// # Errors
    /// As [`BagWriter::write_imu`].
    pub fn write_temperature(
        &mut self,
        topic: &str,
        log_time_ns: i64,
        sample: &TemperatureSample,
        frame_id: &str,
    ) -> Result<(), BagError> {
        self.guarded(|w| {
            let msg =
                Temperature::from_sample(sample, frame_id).map_err(|e| unwritable(topic, e))?;
            w.write(topic, log_time_ns, &msg)
        })
    }

    /// Writes one message of any mirrored type (e.g. `fdavar_msgs/msg/AxisState`) on `topic` at
    /// `log_time_ns`; the topic's channel and the type's schema are added on first use.
    ///
    /// # Errors
    /// As [`BagWriter::write_imu`].
    pub fn write_message<M: RosMessage>(
        &mut self,
        topic: &str,
        log_time_ns: i64,
        msg: &M,
    ) -> Result<(), BagError> {
        self.guarded(|w| w.write(topic, log_time_ns, msg))
    }

    /// Completes the MCAP file (summary, footer) and writes `metadata.yaml` (not beside a bare
    /// file from [`BagWriter::create_file`]).
    ///
    /// # Errors
    /// [`BagError::WriterClosed`] if already finished or failed; I/O errors.
    pub fn finish(&mut self) -> Result<(), BagError> {
        self.guarded(|w| {
            let info = w.info();
            let ros_distro = info.ros_distro.to_string();
            let serialized = serde_yaml_ng::to_string(&info).map_err(|e| unwritable("", e))?;
            let root = metadata::WrittenRoot {
                rosbag2_bagfile_information: info,
            };
            let yaml = serde_yaml_ng::to_string(&root).map_err(|e| unwritable("", e))?;
            let record = mcap::records::Metadata {
                name: "rosbag2".into(),
                metadata: BTreeMap::from([
                    ("ROS_DISTRO".to_string(), ros_distro),
                    ("serialized_metadata".to_string(), serialized),
                ]),
            };
            let path = w.dir.join(&w.file_name);
            w.mcap
                .write_metadata(&record)
                .map_err(|e| mcap_error(&path, e))?;
            w.mcap.finish().map_err(|e| mcap_error(&path, e))?;
            if !w.metadata_yaml {
                return Ok(());
            }
            let meta = w.dir.join(metadata::FILE_NAME);
            std::fs::write(&meta, yaml).map_err(BagError::io(&meta))
        })?;
        self.state = State::Finished;
        Ok(())
    }

    /// Runs `op` if the writer is open; marks it failed if `op` fails.
    fn guarded(
        &mut self,
        op: impl FnOnce(&mut Self) -> Result<(), BagError>,
    ) -> Result<(), BagError> {
        let state = match self.state {
            State::Open => None,
            State::Failed => Some("failed"),
            State::Finished => Some("finished"),
        };
        if let Some(state) = state {
            return Err(BagError::WriterClosed {
                path: self.dir.clone(),
                state,
            });
        }
        let result = op(self);
        if result.is_err() {
            self.state = State::Failed;
        }
        result
    }

    fn write<M: RosMessage>(
        &mut self,
        topic: &str,
        log_time_ns: i64,
        msg: &M,
    ) -> Result<(), BagError> {
        let log_time = u64::try_from(log_time_ns)
            .map_err(|_| unwritable(topic, format!("negative log time {log_time_ns} ns")))?;
        let data = encode(msg).map_err(|e| unwritable(topic, e))?;
        let index = self.topic_index(topic, M::DEF)?;
        let t = &mut self.topics[index];
        let header = mcap::records::MessageHeader {
            channel_id: t.channel_id,
            // MCAP sequence numbers are 32-bit and may wrap.
            sequence: t.count as u32,
            log_time,
            publish_time: log_time,
        };
        t.count += 1;
        let path = self.dir.join(&self.file_name);
        self.mcap
            .write_to_known_channel(&header, &data)
            .map_err(|e| mcap_error(&path, e))?;
        self.span = Some(self.span.map_or((log_time_ns, log_time_ns), |(lo, hi)| {
            (lo.min(log_time_ns), hi.max(log_time_ns))
        }));
        Ok(())
    }

    /// The index of `topic` in `self.topics`, adding its schema and channel on first use.
    fn topic_index(&mut self, topic: &str, def: &'static MsgDef) -> Result<usize, BagError> {
        if let Some(i) = self.topics.iter().position(|t| t.name == topic) {
            let first = self.topics[i].def.name;
            if first != def.name {
                return Err(BagError::TopicTypeConflict {
                    topic: topic.into(),
                    first: first.into(),
                    now: def.name.into(),
                });
            }
            return Ok(i);
        }
        let path = self.dir.join(&self.file_name);
        let schema_id = match self.schemas.get(def.name) {
            Some(id) => *id,
            None => {
                let id = self
                    .mcap
                    .add_schema(def.name, "ros2msg", def.schema_text().as_bytes())
                    .map_err(|e| mcap_error(&path, e))?;
                self.schemas.insert(def.name, id);
                id
            }
        };
        let qos =
            serde_yaml_ng::to_string(&vec![offered_qos(def)]).map_err(|e| unwritable(topic, e))?;
        let mut channel_meta = BTreeMap::from([("offered_qos_profiles".to_string(), qos)]);
        if !def.type_hash.is_empty() {
            channel_meta.insert("topic_type_hash".into(), def.type_hash.into());
        }
        let channel_id = self
            .mcap
            .add_channel(schema_id, topic, "cdr", &channel_meta)
            .map_err(|e| mcap_error(&path, e))?;
        self.topics.push(Topic {
            name: topic.into(),
            def,
            channel_id,
            count: 0,
        });
        Ok(self.topics.len() - 1)
    }

    /// The bag's `metadata.yaml` content (version 9, one file).
    fn info(&self) -> metadata::WrittenInfo<'_> {
        let (start, end) = self.span.unwrap_or((0, 0));
        let (start, duration) = (start.max(0) as u64, (end - start).max(0) as u64);
        let message_count = self.topics.iter().map(|t| t.count).sum();
        metadata::WrittenInfo {
            version: metadata::VERSION,
            storage_identifier: "mcap",
            duration: metadata::Nanoseconds {
                nanoseconds: duration,
            },
            starting_time: metadata::NanosecondsSinceEpoch {
                nanoseconds_since_epoch: start,
            },
            message_count,
            topics_with_message_count: self
                .topics
                .iter()
                .map(|t| metadata::TopicWithCount {
                    topic_metadata: metadata::TopicMetadata {
                        name: &t.name,
                        type_name: t.def.name,
                        serialization_format: "cdr",
                        offered_qos_profiles: vec![offered_qos(t.def)],
                        type_description_hash: t.def.type_hash,
                    },
                    message_count: t.count,
                })
                .collect(),
            compression_format: "",
            compression_mode: "",
            relative_file_paths: vec![self.file_name.clone()],
            files: vec![metadata::FileInfo {
                path: self.file_name.clone(),
                starting_time: metadata::NanosecondsSinceEpoch {
                    nanoseconds_since_epoch: start,
                },
                duration: metadata::Nanoseconds {
                    nanoseconds: duration,
                },
                message_count,
            }],
            custom_data: None,
            ros_distro: "jazzy",
        }
    }
}

/// The QoS a publisher of `def` offers: sensor data for the sensor types, reliable for the rest
/// (what `fdavar_node` offers on `~/<axis>/state`), so that `ros2 bag play` republishes alike.
fn offered_qos(def: &MsgDef) -> QosProfile {
    if def.package() == "sensor_msgs" {
        QosProfile::sensor_data()
    } else {
        QosProfile::reliable()
    }
}

/// True for a path `overwrite` may remove: an empty directory or one holding bag files.
fn is_bag_dir(dir: &Path) -> bool {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return false;
    };
    let names: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    names.is_empty()
        || names.iter().any(|p| {
            p.file_name().is_some_and(|n| n == metadata::FILE_NAME)
                || p.extension().is_some_and(|e| e == "mcap" || e == "db3")
        })
}

fn unwritable(topic: &str, reason: impl ToString) -> BagError {
    BagError::Unwritable {
        topic: topic.into(),
        reason: reason.to_string(),
    }
}

fn mcap_error(path: &Path, e: mcap::McapError) -> BagError {
    match e {
        mcap::McapError::Io(source) => BagError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => BagError::CorruptMcap {
            path: path.to_path_buf(),
            detail: other.to_string(),
        },
    }
}
