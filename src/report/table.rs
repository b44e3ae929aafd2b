//! Text tables and CSV from the same rows, and number formatting to significant digits.
//!
//! The CLIs print the same results three ways: an aligned table for a person, CSV for a
//! spreadsheet, JSON (through `serde_json` on the result types) for a program. A [`Table`] holds
//! the cells once, as strings, so the text and CSV forms cannot disagree.
use std::fmt::Write as _;

/// A table of string cells with a header row.
///
/// Build it with [`Table::new`] and [`Table::push`]; render with [`Table::to_text`] or
/// [`Table::to_csv`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Table {
    headers: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Table {
    /// An empty table with these column headers.
    pub fn new<S: Into<String>>(headers: impl IntoIterator<Item = S>) -> Table {
        Table {
            headers: headers.into_iter().map(Into::into).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row; missing cells are left empty, extra cells are kept (the widest row sets the
    /// column count).
    pub fn push<S: Into<String>>(&mut self, row: impl IntoIterator<Item = S>) {
        self.rows.push(row.into_iter().map(Into::into).collect());
    }

    /// Number of data rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether the table has no data rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    fn columns(&self) -> usize {
        self.rows
            .iter()
            .map(Vec::len)
            .chain([self.headers.len()])
            .max()
            .unwrap_or(0)
    }

    /// The table as aligned text: numbers right-aligned, other cells left-aligned, two spaces
    /// between columns, a dashed rule under the header, no trailing spaces.
    pub fn to_text(&self) -> String {
        let n = self.columns();
        let cell = |row: &[String], j: usize| row.get(j).map_or("", String::as_str).to_string();
        let width: Vec<usize> = (0..n)
            .map(|j| {
                std::iter::once(&self.headers)
                    .chain(&self.rows)
                    .map(|r| cell(r, j).chars().count())
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        let numeric: Vec<bool> = (0..n)
            .map(|j| {
                self.rows.iter().all(|r| {
                    let c = cell(r, j);
                    c.is_empty() || c.parse::<f64>().is_ok()
                })
            })
            .collect();
        let mut out = String::new();
        let mut line = |row: &[String]| {
            let mut s = String::new();
            for j in 0..n {
                let c = cell(row, j);
                let pad = width[j] - c.chars().count();
                if j > 0 {
                    s.push_str("  ");
                }
                if numeric[j] {
                    s.push_str(&" ".repeat(pad));
                    s.push_str(&c);
                } else {
                    s.push_str(&c);
                    s.push_str(&" ".repeat(pad));
                }
            }
            out.push_str(s.trim_end());
            out.push('\n');
        };
        line(&self.headers);
        let rule: Vec<String> = width.iter().map(|&w| "-".repeat(w)).collect();
        line(&rule);
        for row in &self.rows {
            line(row);
        }
        out
    }

    /// The table as CSV (RFC 4180): a header line, then one line per row; cells with a comma,
    /// quote or line break are quoted, quotes doubled. Lines end in `\n`.
    pub fn to_csv(&self) -> String {
        let mut out = String::new();
        for row in std::iter::once(&self.headers).chain(&self.rows) {
            let cells: Vec<String> = row.iter().map(|c| csv_cell(c)).collect();
            // Writing to a String cannot fail.
            let _ = writeln!(out, "{}", cells.join(","));
        }
        out
    }
}

/// One CSV cell, quoted when it must be.
fn csv_cell(c: &str) -> String {
    if c.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", c.replace('"', "\"\""))
    } else {
        c.to_string()
    }
}

/// `x` with `digits` significant digits: plain notation for 10⁻³ ≤ |x| < 10⁶, scientific
/// (`1.23e-7`) otherwise; `NaN`, `inf`, `-inf` spelled out.
///
/// Tables and CSV use it so that a coefficient of 3.1e-6 rad/s is not printed as `0.000003`.
///
/// ```
/// use fdavar::report::table::sig;
/// assert_eq!(sig(0.343775, 4), "0.3438");
/// assert_eq!(sig(206264.8, 3), "206000");
/// assert_eq!(sig(3.14159e-6, 3), "3.14e-6");
/// ```
pub fn sig(x: f64, digits: usize) -> String {
    let digits = digits.max(1);
    if x.is_nan() {
        return "NaN".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf".into() } else { "-inf".into() };
    }
    if x == 0.0 {
        return "0".into();
    }
    let a = x.abs();
    if (1e-3..1e6).contains(&a) {
        // Round to `digits` significant digits first, then print without spurious zeros.
        let s = format!("{:.*e}", digits - 1, x);
        let rounded: f64 = s.parse().unwrap_or(x);
        let exp = rounded.abs().log10().floor() as i32;
        let decimals = (digits as i32 - 1 - exp).max(0) as usize;
        format!("{rounded:.decimals$}")
    } else {
        let s = format!("{:.*e}", digits - 1, x);
        // Rust prints `3.14e-6`; keep it (no `+`, no zero padding).
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_aligns_numbers_right() {
        let mut t = Table::new(["axis", "N [°/√h]"]);
        t.push(["gyro_x", "0.34"]);
        t.push(["gyro_yy", "12.5"]);
        assert_eq!(
            t.to_text(),
            "axis     N [°/√h]\n-------  --------\ngyro_x       0.34\ngyro_yy      12.5\n"
        );
    }

    #[test]
    fn csv_quotes_only_when_needed() {
        let mut t = Table::new(["effect", "note"]);
        t.push(["sinusoid", "a pump, 0.05 Hz"]);
        t.push(["white", "say \"hi\""]);
        assert_eq!(
            t.to_csv(),
            "effect,note\nsinusoid,\"a pump, 0.05 Hz\"\nwhite,\"say \"\"hi\"\"\"\n"
        );
    }

    #[test]
    fn ragged_rows_are_padded() {
        let mut t = Table::new(["a"]);
        t.push(["1", "2"]);
        assert_eq!(t.to_text(), "a\n-  -\n1  2\n");
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(0.343775, 4), "0.3438");
        assert_eq!(sig(99.96, 3), "100");
        assert_eq!(sig(-1.5e-9, 2), "-1.5e-9");
        assert_eq!(sig(1.0, 3), "1.00");
        assert_eq!(sig(f64::NAN, 3), "NaN");
    }
}
