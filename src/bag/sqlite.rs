//! sqlite3 storage (`.db3`): topics, counts and a streaming, timestamp-ordered message reader.
//!
//! Works for every rosbag2 sqlite3 layout met in practice — Humble (schema 3), Jazzy (schema 4,
//! adds `message_definitions` and a type hash) and older bags without a `schema` table — because
//! it only uses the columns all of them share: `topics(id, name, type)` and
//! `messages(topic_id, timestamp, data)`.
//!
//! The message query runs on a worker thread that owns the connection and hands rows over a
//! bounded channel: one streaming query, memory independent of the recording's length, and no
//! self-borrowing iterator. Dropping the stream stops the worker at its next row.

use super::metadata::BagFile;
use super::reader::{FileSummary, RawMessage, RawStream, Role};
use super::{BagError, TopicInfo};
use rusqlite::{Connection, OpenFlags};
use std::path::Path;
use std::sync::mpsc;

/// Rows handed over at once: one channel operation per batch, not per row.
const BATCH_ROWS: usize = 256;
/// Batches in flight between the query thread and the reader (memory ≈ 4 × 256 messages).
const CHANNEL_BATCHES: usize = 4;

/// What the query thread sends: a batch of rows, or the error that ended the query.
type Batch = Result<Vec<RawMessage>, BagError>;

fn corrupt(path: &Path) -> impl Fn(rusqlite::Error) -> BagError + '_ {
    move |e| BagError::CorruptSqlite {
        path: path.to_path_buf(),
        detail: e.to_string(),
    }
}

fn connect(path: &Path) -> Result<Connection, BagError> {
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    Connection::open_with_flags(path, flags).map_err(corrupt(path))
}

/// Topics (with counts) and the time span of one `.db3` file.
pub(crate) fn summarize(file: &BagFile) -> Result<FileSummary, BagError> {
    if file.compression.is_some() {
        return Err(BagError::UnknownCompression {
            path: file.path.clone(),
            compression: "zstd-compressed .db3 (decompress it first: zstd -d)".into(),
        });
    }
    let path = &file.path;
    let conn = connect(path)?;
    // One pass over `messages` for every topic's count (a join per topic would scan once per
    // topic); topics without messages are listed with 0.
    let mut counts: Vec<(i64, u64)> = Vec::new();
    let mut stmt = conn
        .prepare("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id")
        .map_err(corrupt(path))?;
    let rows = stmt
        .query_map([], |row| {
            Ok((row.get::<_, i64>(0)?, row.get::<_, i64>(1)? as u64))
        })
        .map_err(corrupt(path))?;
    for row in rows {
        counts.push(row.map_err(corrupt(path))?);
    }
    let mut stmt = conn
        .prepare("SELECT id, name, type FROM topics ORDER BY id")
        .map_err(corrupt(path))?;
    let rows = stmt
        .query_map([], |row| {
            Ok((
                row.get::<_, i64>(0)?,
                row.get::<_, String>(1)?,
                row.get::<_, String>(2)?,
            ))
        })
        .map_err(corrupt(path))?;
    let mut topics = Vec::new();
    for row in rows {
        let (id, name, type_name) = row.map_err(corrupt(path))?;
        let message_count = counts.iter().find(|(t, _)| *t == id).map_or(0, |(_, n)| *n);
        topics.push(TopicInfo {
            name,
            type_name,
            message_count,
        });
    }
    let span = conn
        .query_row(
            "SELECT MIN(timestamp), MAX(timestamp) FROM messages",
            [],
            |row| {
                Ok(row
                    .get::<_, Option<i64>>(0)?
                    .zip(row.get::<_, Option<i64>>(1)?))
            },
        )
        .map_err(corrupt(path))?;
    Ok(FileSummary { topics, span })
}

/// Streams the messages of the wanted topics ordered by timestamp (ties by insertion order).
pub(crate) fn stream(file: &BagFile, wanted: &[(String, Role)]) -> Result<RawStream, BagError> {
    let path = file.path.clone();
    let conn = connect(&path)?;
    // Resolve topic names to ids here, so that a bad file fails at open, not mid-stream.
    let mut ids = Vec::new();
    for (topic, role) in wanted {
        let id: Option<i64> = conn
            .query_row("SELECT id FROM topics WHERE name = ?1", [topic], |row| {
                row.get(0)
            })
            .map(Some)
            .or_else(|e| match e {
                rusqlite::Error::QueryReturnedNoRows => Ok(None),
                e => Err(e),
            })
            .map_err(corrupt(&path))?;
        if let Some(id) = id {
            ids.push((id, *role));
        }
    }
    let (tx, rx) = mpsc::sync_channel::<Batch>(CHANNEL_BATCHES);
    std::thread::Builder::new()
        .name("fdavar-db3".into())
        .spawn(move || {
            if let Err(e) = query_rows(&conn, &ids, &tx) {
                // The receiver may be gone already; then nobody needs the error.
                let _ = tx.send(Err(corrupt(&path)(e)));
            }
        })
        .map_err(BagError::io(&file.path))?;
    Ok(Box::new(rx.into_iter().flat_map(|batch| match batch {
        Ok(rows) => rows.into_iter().map(Ok).collect::<Vec<_>>(),
        Err(e) => vec![Err(e)],
    })))
}

/// Runs the one ordered query and sends each row; returns early when the receiver is dropped.
fn query_rows(
    conn: &Connection,
    ids: &[(i64, Role)],
    tx: &mpsc::SyncSender<Batch>,
) -> Result<(), rusqlite::Error> {
    if ids.is_empty() {
        return Ok(());
    }
    let list = ids
        .iter()
        .map(|(id, _)| id.to_string())
        .collect::<Vec<_>>()
        .join(",");
    let mut stmt = conn.prepare(&format!(
        "SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({list}) \
         ORDER BY timestamp, id"
    ))?;
    let mut rows = stmt.query([])?;
    let mut batch = Vec::with_capacity(BATCH_ROWS);
    while let Some(row) = rows.next()? {
        let topic_id: i64 = row.get(0)?;
        let role = ids.iter().find(|(id, _)| *id == topic_id).map(|(_, r)| *r);
        let Some(role) = role else { continue };
        let message = RawMessage {
            role,
            log_time_ns: row.get(1)?,
            data: row.get(2)?,
        };
        batch.push(message);
        if batch.len() == BATCH_ROWS {
            let full = std::mem::replace(&mut batch, Vec::with_capacity(BATCH_ROWS));
            if tx.send(Ok(full)).is_err() {
                return Ok(());
            }
        }
    }
    if !batch.is_empty() {
        let _ = tx.send(Ok(batch));
    }
    Ok(())
}
