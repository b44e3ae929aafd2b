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

/// Rows in flight between the query thread and the reader.
const CHANNEL_ROWS: usize = 1024;

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
    let mut stmt = conn
        .prepare(
            "SELECT t.name, t.type, COUNT(m.topic_id) FROM topics t \
             LEFT JOIN messages m ON m.topic_id = t.id GROUP BY t.id ORDER BY t.id",
        )
        .map_err(corrupt(path))?;
    let topics = stmt
        .query_map([], |row| {
            Ok(TopicInfo {
                name: row.get(0)?,
                type_name: row.get(1)?,
                message_count: row.get::<_, i64>(2)? as u64,
            })
        })
        .and_then(|rows| rows.collect::<Result<Vec<_>, _>>())
        .map_err(corrupt(path))?;
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
    let (tx, rx) = mpsc::sync_channel(CHANNEL_ROWS);
    std::thread::Builder::new()
        .name("fdavar-db3".into())
        .spawn(move || {
            if let Err(e) = query_rows(&conn, &ids, &tx) {
                // The receiver may be gone already; then nobody needs the error.
                let _ = tx.send(Err(corrupt(&path)(e)));
            }
        })
        .map_err(BagError::io(&file.path))?;
    Ok(Box::new(rx.into_iter()))
}

/// Runs the one ordered query and sends each row; returns early when the receiver is dropped.
fn query_rows(
    conn: &Connection,
    ids: &[(i64, Role)],
    tx: &mpsc::SyncSender<Result<RawMessage, BagError>>,
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
    while let Some(row) = rows.next()? {
        let topic_id: i64 = row.get(0)?;
        let role = ids.iter().find(|(id, _)| *id == topic_id).map(|(_, r)| *r);
        let Some(role) = role else { continue };
        let message = RawMessage {
            role,
            log_time_ns: row.get(1)?,
            data: row.get(2)?,
        };
        if tx.send(Ok(message)).is_err() {
            return Ok(());
        }
    }
    Ok(())
}
