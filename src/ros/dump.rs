//! `dump_json`: the node's analysis rows as JSON lines, bounded on disk.
//!
//! Why bounded: the node completes one row per sample and axis, and a row with its DAVAR points is
//! a few kB of JSON, so an unbounded dump grows by tens of MB per second at 200 Hz (issue 9
//! measured 8.8 GB in 4 minutes). Two bounds, both parameters of the node:
//! - `dump_every_s`: at most one row per axis per this many seconds of analysis time (0: every
//!   row, what the live = offline comparison needs);
//! - `dump_json_max_mb`: a line that would take the file past the cap first moves the file to
//!   `<path>.1` (replacing the previous one) and starts a new one, so the dump never takes more
//!   than twice the cap on disk and the newest rows are always in `<path>`.
//!
//! Every line is serialised whole before it is written, so a rotation never splits one, and
//! [`DumpWriter::finish`] (called on shutdown) leaves the last line complete. Rejected: rotating on
//! a timer (the size still depends on the rate) and dropping rows silently (the decimation is a
//! parameter the user sets and sees).

use serde::Serialize;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// A JSON-lines file with decimation per key and a size cap with one rotated file.
#[derive(Debug)]
pub struct DumpWriter {
    path: PathBuf,
    rotated: PathBuf,
    file: BufWriter<File>,
    /// Bytes in the current file (written or buffered).
    written: u64,
    max_bytes: u64,
    every_s: f64,
    /// The analysis time of the last row written, per key (axis).
    last: Vec<(String, f64)>,
    line: Vec<u8>,
    /// Files started by rotation so far.
    rotations: u64,
}

impl DumpWriter {
    /// Creates (truncates) `path` and removes a `<path>.1` left by an earlier run.
    ///
    /// `max_bytes`: the cap of one file; `every_s`: the decimation interval (0: every row).
    ///
    /// # Errors
    /// The I/O error of creating the file or of removing the old rotated one.
    pub fn create(path: &Path, max_bytes: u64, every_s: f64) -> std::io::Result<DumpWriter> {
        let rotated = rotated_path(path);
        match std::fs::remove_file(&rotated) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
            _ => {}
        }
        Ok(DumpWriter {
            path: path.to_path_buf(),
            rotated,
            file: BufWriter::new(File::create(path)?),
            written: 0,
            max_bytes,
            every_s,
            last: Vec::new(),
            line: Vec::new(),
            rotations: 0,
        })
    }

    /// Writes `row` as one JSON line unless a row of `key` was written less than `every_s` of
    /// analysis time before `time_s`. Returns whether it was written.
    ///
    /// # Errors
    /// Serialisation or I/O errors; the caller then stops writing (a failed writer is not reused).
    pub fn write<T: Serialize>(
        &mut self,
        key: &str,
        time_s: f64,
        row: &T,
    ) -> std::io::Result<bool> {
        let slot = match self.last.iter().position(|(k, _)| k == key) {
            Some(i) => {
                // A NaN time compares false: the row is written, not silently skipped.
                if self.every_s > 0.0 && time_s - self.last[i].1 < self.every_s {
                    return Ok(false);
                }
                i
            }
            None => {
                self.last.push((key.to_string(), time_s));
                self.last.len() - 1
            }
        };
        self.line.clear();
        serde_json::to_writer(&mut self.line, row)?;
        self.line.push(b'\n');
        let len = self.line.len() as u64;
        if self.written > 0 && self.written + len > self.max_bytes {
            self.rotate()?;
        }
        self.file.write_all(&self.line)?;
        self.written += len;
        self.last[slot].1 = time_s;
        Ok(true)
    }

    /// Moves the current file to `<path>.1` and starts an empty one.
    fn rotate(&mut self) -> std::io::Result<()> {
        self.file.flush()?;
        std::fs::rename(&self.path, &self.rotated)?;
        self.file = BufWriter::new(File::create(&self.path)?);
        self.written = 0;
        self.rotations += 1;
        Ok(())
    }

    /// Hands the buffered lines to the OS (whole lines only), so the file can be read while the
    /// node runs.
    ///
    /// # Errors
    /// The I/O error.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }

    /// Files started by rotation so far.
    pub fn rotations(&self) -> u64 {
        self.rotations
    }

    /// Flushes and syncs the file: after this the last line on disk is complete.
    ///
    /// # Errors
    /// The I/O error of flushing or syncing.
    pub fn finish(mut self) -> std::io::Result<()> {
        self.file.flush()?;
        self.file.get_ref().sync_all()
    }
}

/// `<path>.1`: where the rotated file goes (`rows.jsonl` → `rows.jsonl.1`).
pub fn rotated_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_os_string();
    name.push(".1");
    PathBuf::from(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Row {
        axis: &'static str,
        t: f64,
        pad: String,
    }

    fn lines(path: &Path) -> Vec<serde_json::Value> {
        std::fs::read_to_string(path)
            .unwrap_or_default()
            .lines()
            .map(|l| serde_json::from_str(l).expect("every line parses"))
            .collect()
    }

    #[test]
    fn the_cap_rotates_into_one_kept_file_and_never_splits_a_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rows.jsonl");
        std::fs::write(rotated_path(&path), "stale from an earlier run\n").unwrap();
        let cap = 10_000;
        let mut dump = DumpWriter::create(&path, cap, 0.0).unwrap();
        assert!(!rotated_path(&path).exists(), "an old .1 is removed");
        let pad = "x".repeat(300);
        let n = 1000;
        for k in 0..n {
            let row = Row {
                axis: "gyro_x",
                t: k as f64,
                pad: pad.clone(),
            };
            assert!(dump.write("gyro_x", k as f64, &row).unwrap());
        }
        let rotations = dump.rotations();
        dump.finish().unwrap();
        // ~330 bytes a line: 1000 lines are 33 caps, so the writer rotated about 33 times.
        assert!(rotations >= 30, "{rotations}");
        for p in [path.clone(), rotated_path(&path)] {
            let size = std::fs::metadata(&p).unwrap().len();
            assert!(size <= cap, "{} is {size} bytes", p.display());
        }
        let (old, new) = (lines(&rotated_path(&path)), lines(&path));
        // The two files hold the newest rows, consecutive, ending with the last one.
        let t: Vec<f64> = old
            .iter()
            .chain(&new)
            .map(|v| v["t"].as_f64().unwrap())
            .collect();
        assert_eq!(*t.last().unwrap(), (n - 1) as f64);
        assert!(t.windows(2).all(|w| w[1] == w[0] + 1.0), "{t:?}");
        assert!(t.len() > 30, "{}", t.len());
    }

    #[test]
    fn decimation_keeps_one_row_per_axis_per_interval() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rows.jsonl");
        let mut dump = DumpWriter::create(&path, u64::MAX, 1.0).unwrap();
        let mut written = 0;
        // 200 Hz for 10 s on two axes.
        for k in 0..2000 {
            let t = k as f64 * 0.005;
            for axis in ["gyro_x", "accel_z"] {
                let row = Row {
                    axis,
                    t,
                    pad: String::new(),
                };
                written += usize::from(dump.write(axis, t, &row).unwrap());
            }
        }
        dump.finish().unwrap();
        let rows = lines(&path);
        assert_eq!(rows.len(), written);
        let times = |axis: &str| -> Vec<f64> {
            rows.iter()
                .filter(|r| r["axis"] == axis)
                .map(|r| r["t"].as_f64().unwrap())
                .collect()
        };
        // t = 0, 1, …, 9 s, each within one sample period (5 ms: k·0.005 is not exact in binary).
        for axis in ["gyro_x", "accel_z"] {
            let t = times(axis);
            assert_eq!(t.len(), 10, "{axis}: {t:?}");
            assert!(
                t.iter()
                    .enumerate()
                    .all(|(i, x)| (x - i as f64).abs() <= 0.005),
                "{t:?}"
            );
        }
    }
}
