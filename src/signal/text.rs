//! Plain-text and CSV series readers: one value per line, or one column of a CSV table.
//!
//! `fdavar allan` and `fdavar davar` read the same files: Stable32-style data files (one value per
//! line, `#` comments, blank lines) and CSV exports from loggers (a header row optional, a column
//! chosen by index or name). Parsing is separate from file access ([`parse_column`] takes any
//! reader) so tests and other callers need no files.
//!
//! Every failure names the file and, for bad data, the line number and its text: a user with a
//! 500 000-line file must be able to find the problem.

use std::fmt;
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// Which CSV column to read: a zero-based index or a header name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ColumnSelector {
    /// Zero-based column index.
    Index(usize),
    /// Column name as written in the header row.
    Name(String),
}

impl FromStr for ColumnSelector {
    type Err = std::convert::Infallible;
    /// A whole number is an index, anything else a name.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(s.parse::<usize>().map_or_else(
            |_| ColumnSelector::Name(s.to_string()),
            ColumnSelector::Index,
        ))
    }
}

impl fmt::Display for ColumnSelector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ColumnSelector::Index(i) => write!(f, "{i}"),
            ColumnSelector::Name(n) => f.write_str(n),
        }
    }
}

/// Longest line read, bytes (a CSV row of an IMU logger is a few hundred): a longer one is an
/// error, so that a file without line breaks (`/dev/zero`, a binary file) cannot be read into
/// memory without end (issue 13).
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Most values read from one file: 2²⁶ (512 MiB as f64; 46 h at 400 Hz). The series is held in
/// memory, so an endless input (`yes 1 |`) stops with an error here instead of exhausting it.
pub const MAX_VALUES: usize = 1 << 26;

/// Why a series could not be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TextError {
    /// The file could not be opened or read (the I/O error is the source, so that a report of
    /// the chain says it once).
    #[error("cannot read {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A data line holds something that is not a number.
    #[error("{path}:{line}: not a number: '{text}'")]
    NotANumber {
        /// The file (`-` for a reader without a path).
        path: PathBuf,
        /// One-based line number.
        line: usize,
        /// The offending field.
        text: String,
    },
    /// A line longer than [`MAX_LINE_BYTES`]: not a text series.
    #[error("{path}:{line}: line longer than {max} bytes: not a text series (one value per line, or CSV)")]
    LineTooLong {
        /// The file.
        path: PathBuf,
        /// One-based line number.
        line: usize,
        /// [`MAX_LINE_BYTES`].
        max: usize,
    },
    /// More than [`MAX_VALUES`] values.
    #[error("{path}: more than {max} values; split the file")]
    TooManyValues {
        /// The file.
        path: PathBuf,
        /// [`MAX_VALUES`].
        max: usize,
    },
    /// A row has fewer fields than the selected column needs.
    #[error("{path}:{line}: no column {column} (the row has {fields} fields)")]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// One-based line number.
        line: usize,
        /// The column asked for.
        column: ColumnSelector,
        /// Fields on that row.
        fields: usize,
    },
    /// A column was selected by name but the header row does not have it (or there is no header).
    #[error("{path}: no column named '{name}' in the header ({header})")]
    UnknownColumnName {
        /// The file.
        path: PathBuf,
        /// The name asked for.
        name: String,
        /// The header row as read, or "no header row".
        header: String,
    },
}

/// Reads one series from a text or CSV file.
///
/// Without a column selector every data line must hold exactly one number; with one, lines are
/// split on commas (or, when there is no comma, on whitespace) and the selected field is read.
/// Lines that are blank or start with `#` are skipped. A first data line whose selected field is
/// not a number is taken as a header row (and is how a named column is found).
///
/// # Errors
/// [`TextError::Io`] for a missing or unreadable file, [`TextError::NotANumber`] naming the line,
/// [`TextError::MissingColumn`] and [`TextError::UnknownColumnName`] for column selections that do
/// not fit the file.
pub fn read_column(path: &Path, column: Option<&ColumnSelector>) -> Result<Vec<f64>, TextError> {
    let io = |source| TextError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    parse_column(std::io::BufReader::new(file), path, column)
}

/// Parses one series from any reader (see [`read_column`]); `path` only labels errors.
///
/// ```
/// use fdavar::signal::text::{parse_column, ColumnSelector};
/// let csv = "t,gyro_x\n0.00,0.5\n0.01,0.25\n";
/// let col = ColumnSelector::Name("gyro_x".into());
/// let v = parse_column(csv.as_bytes(), "-".as_ref(), Some(&col)).unwrap();
/// assert_eq!(v, vec![0.5, 0.25]);
/// ```
///
/// # Errors
/// As [`read_column`].
pub fn parse_column<R: BufRead>(
    reader: R,
    path: &Path,
    column: Option<&ColumnSelector>,
) -> Result<Vec<f64>, TextError> {
    let mut values = Vec::new();
    let mut index = match column {
        Some(ColumnSelector::Index(i)) => Some(*i),
        _ => None,
    };
    let mut seen_data = false;
    let mut reader = reader;
    let mut buf = Vec::new();
    let io = |source| TextError::Io {
        path: path.to_path_buf(),
        source,
    };
    for line_no in 1.. {
        buf.clear();
        let limit = (MAX_LINE_BYTES + 1) as u64;
        let n = (&mut reader)
            .take(limit)
            .read_until(b'\n', &mut buf)
            .map_err(io)?;
        if n == 0 {
            break;
        }
        if buf.last() != Some(&b'\n') && n as u64 == limit {
            return Err(TextError::LineTooLong {
                path: path.to_path_buf(),
                line: line_no,
                max: MAX_LINE_BYTES,
            });
        }
        let line = std::str::from_utf8(&buf).map_err(|e| {
            io(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("line {line_no}: {e}"),
            ))
        })?;
        let text = line.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let first_data = !seen_data;
        seen_data = true;
        let fields: Vec<&str> = split_fields(text);
        let field = match (column, index) {
            (None, _) => {
                if fields.len() != 1 {
                    return Err(not_a_number(path, line_no, text));
                }
                fields[0]
            }
            (Some(sel), Some(i)) => *fields.get(i).ok_or_else(|| TextError::MissingColumn {
                path: path.to_path_buf(),
                line: line_no,
                column: sel.clone(),
                fields: fields.len(),
            })?,
            // Selected by name: the first data line must be the header that names the column.
            (Some(sel), None) => {
                let name = sel.to_string();
                match fields.iter().position(|f| unquote(f) == name) {
                    Some(i) if first_data => {
                        index = Some(i);
                        continue;
                    }
                    _ => {
                        let header = first_data && fields.iter().any(|f| f.parse::<f64>().is_err());
                        return Err(TextError::UnknownColumnName {
                            path: path.to_path_buf(),
                            name,
                            header: if header {
                                text.to_string()
                            } else {
                                "no header row".to_string()
                            },
                        });
                    }
                }
            }
        };
        match field.trim().parse::<f64>() {
            Ok(_) if values.len() == MAX_VALUES => {
                return Err(TextError::TooManyValues {
                    path: path.to_path_buf(),
                    max: MAX_VALUES,
                })
            }
            Ok(v) => values.push(v),
            // A non-numeric first row of a CSV is its header.
            Err(_) if first_data && column.is_some() => continue,
            Err(_) => return Err(not_a_number(path, line_no, field)),
        }
    }
    Ok(values)
}

fn not_a_number(path: &Path, line: usize, text: &str) -> TextError {
    TextError::NotANumber {
        path: path.to_path_buf(),
        line,
        text: text.to_string(),
    }
}

fn split_fields(text: &str) -> Vec<&str> {
    if text.contains(',') {
        text.split(',').map(str::trim).collect()
    } else {
        text.split_whitespace().collect()
    }
}

fn unquote(s: &str) -> &str {
    s.trim().trim_matches('"')
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str, c: Option<&ColumnSelector>) -> Result<Vec<f64>, TextError> {
        parse_column(s.as_bytes(), Path::new("f.txt"), c)
    }

    #[test]
    fn plain_text_with_comments_and_blanks() {
        assert_eq!(
            parse("# PHASE.DAT\n#\n1.5\n\n-2e-3\n", None).unwrap(),
            vec![1.5, -2e-3]
        );
    }

    #[test]
    fn bad_line_is_named() {
        let e = parse("1\n2\nabc\n", None).unwrap_err();
        assert!(
            matches!(e, TextError::NotANumber { line: 3, ref text, .. } if text == "abc"),
            "{e}"
        );
        assert_eq!(e.to_string(), "f.txt:3: not a number: 'abc'");
        assert!(matches!(
            parse("1\n2,3\n", None).unwrap_err(),
            TextError::NotANumber { line: 2, .. }
        ));
    }

    #[test]
    fn csv_by_index_and_name_with_optional_header() {
        let idx = ColumnSelector::Index(1);
        assert_eq!(
            parse("a,b\n1,2\n3,4\n", Some(&idx)).unwrap(),
            vec![2.0, 4.0]
        );
        assert_eq!(parse("1,2\n3,4\n", Some(&idx)).unwrap(), vec![2.0, 4.0]);
        assert_eq!(parse("1 2\n3 4\n", Some(&idx)).unwrap(), vec![2.0, 4.0]);
        let name: ColumnSelector = "\"b\"".trim_matches('"').parse().unwrap();
        assert_eq!(
            parse("a,\"b\"\n1,2\n3,4\n", Some(&name)).unwrap(),
            vec![2.0, 4.0]
        );
    }

    #[test]
    fn csv_errors_name_the_problem() {
        let e = parse("1,2\n3\n", Some(&ColumnSelector::Index(1))).unwrap_err();
        assert!(
            matches!(
                e,
                TextError::MissingColumn {
                    line: 2,
                    fields: 1,
                    ..
                }
            ),
            "{e}"
        );
        let e = parse("a,b\n1,2\n", Some(&ColumnSelector::Name("c".into()))).unwrap_err();
        assert!(
            matches!(e, TextError::UnknownColumnName { ref header, .. } if header == "a,b"),
            "{e}"
        );
        let e = parse("1,2\n", Some(&ColumnSelector::Name("c".into()))).unwrap_err();
        assert!(
            matches!(e, TextError::UnknownColumnName { ref header, .. } if header == "no header row"),
            "{e}"
        );
        let e = parse("a,b\n1,x\n", Some(&ColumnSelector::Index(1))).unwrap_err();
        assert!(matches!(e, TextError::NotANumber { line: 2, .. }), "{e}");
    }

    #[test]
    fn missing_file_is_an_io_error_with_the_path() {
        let e = read_column(Path::new("/nonexistent/x.txt"), None).unwrap_err();
        assert!(
            e.to_string().starts_with("cannot read /nonexistent/x.txt"),
            "{e}"
        );
    }

    #[test]
    fn column_selector_parses_numbers_as_indices() {
        assert_eq!(
            "3".parse::<ColumnSelector>().unwrap(),
            ColumnSelector::Index(3)
        );
        assert_eq!(
            "gyro_x".parse::<ColumnSelector>().unwrap(),
            ColumnSelector::Name("gyro_x".into())
        );
    }
}
