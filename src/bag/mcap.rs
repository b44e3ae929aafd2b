//! MCAP storage: the summary (topics, counts, time span) and a streaming message reader.
//!
//! Both read through `std::io` (a buffered file, or a zstd decoder for file-compressed bags):
//! the summary with `mcap`'s sans-io `SummaryReader` (footer and summary section only), the
//! messages with `mcap::io::MessageReader`, whose memory is bounded by the largest chunk. A file
//! without a summary section (a writer that skipped it) is scanned once instead.

use super::metadata::{BagFile, FileCompression};
use super::reader::{FileSummary, RawMessage, RawStream, Role};
use super::{BagError, TopicInfo};
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use mcap::McapError;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

/// The 8 bytes every MCAP file starts (and ends) with.
const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Read buffer: a few chunks' worth, so reads are large and memory stays small.
const BUFFER_BYTES: usize = 1 << 20;

/// Longest record accepted in a zstd-compressed file, whose decompressed size is unknown.
const COMPRESSED_FILE_RECORD_LIMIT: usize = 1 << 30;

/// The longest record the readers may accept: a record cannot be longer than an uncompressed
/// file. Without a limit, a corrupt length field makes the reader allocate that many bytes up
/// front, and an absurd one aborts the process.
fn record_limit(file: &BagFile) -> usize {
    match file.compression {
        Some(FileCompression::Zstd) => COMPRESSED_FILE_RECORD_LIMIT,
        None => std::fs::metadata(&file.path).map_or(COMPRESSED_FILE_RECORD_LIMIT, |m| {
            usize::try_from(m.len()).unwrap_or(usize::MAX)
        }),
    }
}

/// A message reader over the whole file, checking chunk CRCs and record lengths.
fn message_reader(
    file: &BagFile,
) -> Result<mcap::io::MessageReader<Box<dyn Read + Send>>, BagError> {
    let options = mcap::sans_io::LinearReaderOptions::default()
        .with_validate_chunk_crcs(true)
        .with_record_length_limit(record_limit(file));
    Ok(mcap::io::MessageReader::new_with_options(
        open(file)?,
        options,
    ))
}

/// Translates an MCAP reader error into the bag error that explains it to a user.
fn bag_error(path: &Path, e: McapError) -> BagError {
    let path = path.to_path_buf();
    match e {
        McapError::UnsupportedCompression(compression) => {
            BagError::UnknownCompression { path, compression }
        }
        // A record longer than the file (the limit of `record_limit`) ends past its end.
        McapError::UnexpectedEof
        | McapError::BadMagic
        | McapError::BadFooter
        | McapError::RecordTooLarge { .. }
        | McapError::ChunkTooLarge(_) => BagError::Truncated {
            path,
            detail: e.to_string(),
        },
        McapError::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            BagError::Truncated {
                path,
                detail: io.to_string(),
            }
        }
        McapError::Io(source) => BagError::Io { path, source },
        other => BagError::CorruptMcap {
            path,
            detail: other.to_string(),
        },
    }
}

/// The file's bytes, decompressed if the whole file is compressed; checks the MCAP magic.
fn open(file: &BagFile) -> Result<Box<dyn Read + Send>, BagError> {
    let path = &file.path;
    let raw = BufReader::with_capacity(BUFFER_BYTES, File::open(path).map_err(BagError::io(path))?);
    let mut source: Box<dyn Read + Send> = match file.compression {
        None => Box::new(raw),
        Some(FileCompression::Zstd) => Box::new(BufReader::with_capacity(
            BUFFER_BYTES,
            zstd::Decoder::with_buffer(raw).map_err(BagError::io(path))?,
        )),
    };
    let mut magic = [0u8; 8];
    let mut got = 0;
    while got < magic.len() {
        match source.read(&mut magic[got..]).map_err(BagError::io(path))? {
            0 => break,
            n => got += n,
        }
    }
    if got < magic.len() || &magic != MAGIC {
        return Err(BagError::UnknownStorage {
            path: path.clone(),
            reason: "does not start with the MCAP magic bytes".into(),
        });
    }
    // The magic was consumed: hand the reader the rest behind a copy of it.
    Ok(Box::new(std::io::Cursor::new(MAGIC).chain(source)))
}

/// Topics, counts and time span of one MCAP file.
pub(crate) fn summarize(file: &BagFile) -> Result<FileSummary, BagError> {
    // Checks the magic: a file that is not MCAP at all is named so, not "truncated".
    drop(open(file)?);
    if file.compression.is_none() {
        if let Some(summary) = read_summary(file) {
            if let Some(stats) = &summary.stats {
                return Ok(from_summary(&summary, stats));
            }
        }
    }
    scan(file)
}

/// The summary section, if the file has a usable one. `None` when it is absent or unreadable
/// (a file shorter than a footer makes even the first seek fail): then the file is scanned, and
/// the scan reports what is wrong with it.
fn read_summary(file: &BagFile) -> Option<mcap::Summary> {
    let mut f = File::open(&file.path).ok()?;
    let size = f.metadata().ok()?.len();
    let options = SummaryReaderOptions::default()
        .with_file_size(size)
        .with_record_length_limit(record_limit(file));
    let mut reader = SummaryReader::new_with_options(options);
    while let Some(event) = reader.next_event() {
        match event.ok()? {
            SummaryReadEvent::ReadRequest(need) => {
                let n = f.read(reader.insert(need)).ok()?;
                reader.notify_read(n);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let pos = f.seek(to).ok()?;
                reader.notify_seeked(pos);
            }
        }
    }
    let summary = reader.finish()?;
    summary_crc_matches(&mut f, size)?.then_some(summary)
}

/// Whether the summary CRC the footer holds matches the bytes it covers (the summary and
/// summary-offset sections and the footer up to the CRC), or the writer left it 0 (not computed).
/// `None` when the footer cannot be read.
///
/// Why: `mcap`'s summary reader does not check it, and a damaged statistics record made `fdavar
/// info` report 9.4·10¹⁸ messages (issue 13). A file that fails is scanned instead, which checks
/// every chunk's CRC and counts what is there.
fn summary_crc_matches(f: &mut File, size: u64) -> Option<bool> {
    // Footer: opcode (1), length (8), summary_start (8), summary_offset_start (8), CRC (4); magic.
    let footer_at = size.checked_sub(1 + 8 + 20 + 8)?;
    f.seek(std::io::SeekFrom::Start(footer_at)).ok()?;
    let mut footer = [0u8; 29];
    f.read_exact(&mut footer).ok()?;
    let summary_start = u64::from_le_bytes(footer[9..17].try_into().ok()?);
    let saved = u32::from_le_bytes(footer[25..29].try_into().ok()?);
    if saved == 0 {
        return Some(true);
    }
    let covered = (footer_at + 25).checked_sub(summary_start)?;
    f.seek(std::io::SeekFrom::Start(summary_start)).ok()?;
    let mut hasher = crc32fast::Hasher::new();
    let mut rest = f.take(covered);
    let mut buf = vec![0u8; 1 << 16];
    loop {
        match rest.read(&mut buf).ok()? {
            0 => break,
            n => hasher.update(&buf[..n]),
        }
    }
    Some(rest.limit() == 0 && hasher.finalize() == saved)
}

fn from_summary(summary: &mcap::Summary, stats: &mcap::records::Statistics) -> FileSummary {
    let mut channels: Vec<_> = summary.channels.values().collect();
    channels.sort_by_key(|c| c.id);
    let topics = channels
        .iter()
        .map(|c| TopicInfo {
            name: c.topic.clone(),
            type_name: c
                .schema
                .as_ref()
                .map(|s| s.name.clone())
                .unwrap_or_default(),
            message_count: stats
                .channel_message_counts
                .get(&c.id)
                .copied()
                .unwrap_or(0),
        })
        .collect();
    let span = (stats.message_count > 0).then_some((
        stats.message_start_time as i64,
        stats.message_end_time as i64,
    ));
    FileSummary { topics, span }
}

/// Counts messages per channel by reading the whole file once (no summary to ask).
fn scan(file: &BagFile) -> Result<FileSummary, BagError> {
    let mut reader = message_reader(file)?;
    let mut counts: BTreeMap<u16, (String, String, u64)> = BTreeMap::new();
    let mut span: Option<(i64, i64)> = None;
    for message in reader.by_ref() {
        let message = message.map_err(|e| bag_error(&file.path, e))?;
        let channel = &message.channel;
        let entry = counts.entry(channel.id).or_insert_with(|| {
            let type_name = channel
                .schema
                .as_ref()
                .map(|s| s.name.clone())
                .unwrap_or_default();
            (channel.topic.clone(), type_name, 0)
        });
        entry.2 += 1;
        let t = message.log_time as i64;
        span = Some(span.map_or((t, t), |(lo, hi)| (lo.min(t), hi.max(t))));
    }
    let topics = counts
        .into_values()
        .map(|(name, type_name, message_count)| TopicInfo {
            name,
            type_name,
            message_count,
        })
        .collect();
    Ok(FileSummary { topics, span })
}

/// Streams the messages of the wanted topics, in file order.
pub(crate) fn stream(file: &BagFile, wanted: &[(String, Role)]) -> Result<RawStream, BagError> {
    let reader = message_reader(file)?;
    Ok(Box::new(McapStream {
        path: file.path.clone(),
        reader,
        wanted: wanted.to_vec(),
        roles: HashMap::new(),
    }))
}

struct McapStream {
    path: std::path::PathBuf,
    reader: mcap::io::MessageReader<Box<dyn Read + Send>>,
    wanted: Vec<(String, Role)>,
    /// Channel id → role (None: a topic not asked for), looked up once per channel.
    roles: HashMap<u16, Option<Role>>,
}

impl Iterator for McapStream {
    type Item = Result<RawMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        for message in self.reader.by_ref() {
            let message = match message {
                Ok(m) => m,
                Err(e) => return Some(Err(bag_error(&self.path, e))),
            };
            let channel = &message.channel;
            let wanted = &self.wanted;
            let role = *self.roles.entry(channel.id).or_insert_with(|| {
                wanted
                    .iter()
                    .find(|(topic, _)| *topic == channel.topic)
                    .map(|(_, role)| *role)
            });
            if let Some(role) = role {
                return Some(Ok(RawMessage {
                    role,
                    log_time_ns: message.log_time as i64,
                    data: message.data.into_owned(),
                }));
            }
        }
        None
    }
}
