//! Change points: spans of analysis time where the short-τ level of the DAVAR left its band.
//!
//! # The rule (one rule for every window policy)
//! 1. The statistic is the row's Allan variance at the smallest τ of the grid (τ0 for the default
//!    grids): for an IMU that is the white-noise level, which is what a "noise change" changes.
//! 2. Its steady level is the robust median ([`RobustLevel`]) of that statistic over the first
//!    `warmup_rows` rows, then over the rows that are not flagged or are quieter than the level.
//!    Why quieter rows too: disturbances (vibration, interference, a knock) add noise, so the level
//!    is the undisturbed sensor's; a warm-up that caught a disturbance held it too high, and the
//!    undisturbed noise after it was flagged "quieter" and never learned — an event that did not
//!    end (the ADIS16405's first 8 s, issue 10; `a_loud_start_is_not_taken_for_the_normal_noise`
//!    in tests/davar_events.rs). The price: a real fall of the noise is reported only until the
//!    quieter rows outnumber the louder ones learned before it.
//! 3. A row is *flagged* when the steady level lies outside the row's own χ² interval at `z`
//!    standard deviations (two-sided, EDF from [`edf_closed_form`]):
//!    the row is significantly above or below normal, given how many terms it averaged. The closed
//!    form is used, not [`edf_overlapping`](super::edf_overlapping), because at m = 1 it is exact
//!    for white noise (2M/3 for M first differences: adjacent ones correlate at −1/2), while the
//!    general EDF is 17 % high there, which narrows a z = 4 band to about z = 3.7 and multiplies
//!    the per-row false-alarm probability by 3.
//! 4. An event is a maximal run of flagged rows, where runs separated by at most `merge_rows`
//!    unflagged rows are joined; runs of fewer than `min_rows` flagged rows are dropped.
//! 5. *Persistence*: a run counts only when two disjoint windows are flagged in it, i.e. when the
//!    oldest sample of its last flagged window is not before the newest sample of its first one.
//!    Why: consecutive rows share all but one sample, so a single unlucky stretch of stationary
//!    noise flags hundreds of rows in a row and `min_rows` alone cannot tell it from a change;
//!    two disjoint windows of stationary white noise are independent, so a false run now needs
//!    two tail events of probability p each (p ≈ 6·10⁻⁵ at z = 4) instead of one. A real change
//!    longer than the window passes this by construction, and it is what makes end ≥ start.
//! 6. Its onset is estimated as the newest sample of the first flagged window (the first window to
//!    see the change is the one whose leading edge just reached it) and its end as the oldest
//!    sample of the last flagged window. The analysis indices of the first and last flagged rows
//!    are reported too: that is where the change shows in the DAVAR surface, which is what the
//!    seed's Table 1 reads off (and why its long window reports 968 for a change at 1200).
//!
//! Rejected: thresholds on F (F is what the adaptive policy acts on, so a test on it would not be
//! the same rule for fixed and adaptive windows) and fixed-factor thresholds (they ignore how
//! uncertain a short window is).

use super::reference::RobustLevel;
use super::stats::{edf_closed_form, IntervalCache, IntervalMemo};
use super::DavarRow;
use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, Normal};

/// Settings of the change detector.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DetectorConfig {
    /// Band half-width in standard deviations (two-sided normal equivalent), default 4.
    pub z: f64,
    /// Rows learned unconditionally before any row is flagged.
    pub warmup_rows: usize,
    /// Fewest flagged rows that make an event.
    pub min_rows: usize,
    /// Most unflagged rows inside one event.
    pub merge_rows: usize,
}

/// A span where the noise changed.
///
/// `start_index ≤ end_index` always: a run of flagged rows shorter than its windows is not an
/// event (rule 5 of the module doc).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChangeEvent {
    /// Estimated first changed sample (newest sample of the first flagged window), index.
    pub start_index: u64,
    /// Estimated last changed sample (oldest sample of the last flagged window), index.
    pub end_index: u64,
    /// `start_index` in seconds from the first sample.
    pub start_s: f64,
    /// `end_index` in seconds from the first sample.
    pub end_s: f64,
    /// Analysis index of the first flagged row.
    pub first_row_index: u64,
    /// Analysis index of the last flagged row.
    pub last_row_index: u64,
    /// Median, over the flagged rows, of the short-τ Allan variance divided by the steady level
    /// (≈ 9 when the noise deviation triples).
    pub factor: f64,
    /// Flagged rows in the event.
    pub rows: u64,
    /// False when the input ended inside the event.
    pub closed: bool,
}

#[derive(Debug, Clone)]
struct Run {
    start_index: u64,
    start_s: f64,
    first_row: u64,
    last_row: u64,
    end_index: u64,
    end_s: f64,
    rows: u64,
    quiet: usize,
    factor: RobustLevel,
}

/// Turns DAVAR rows into [`ChangeEvent`]s (see the module doc for the rule).
#[derive(Debug, Clone)]
pub struct ChangeDetector {
    config: DetectorConfig,
    level: RobustLevel,
    band: IntervalCache,
    /// The band's factors met lately at the first row's m (the shortest τ; one lookup per row).
    memo: Option<(usize, IntervalMemo)>,
    run: Option<Run>,
}

impl ChangeDetector {
    /// A detector with the given settings.
    pub fn new(config: DetectorConfig) -> Self {
        let p_low = Normal::standard().cdf(-config.z.abs());
        ChangeDetector {
            config,
            level: RobustLevel::new(),
            band: IntervalCache::with_edf(p_low, edf_closed_form),
            memo: None,
            run: None,
        }
    }

    /// The steady short-τ level learned so far.
    pub fn level(&self) -> Option<f64> {
        self.level.median()
    }

    /// Whether `row` is outside the band of the steady level; `None` while warming up or when the
    /// row has no point.
    pub fn flag(&mut self, row: &DavarRow) -> Option<bool> {
        let p = row.first_point()?;
        if self.level.count() < self.config.warmup_rows as u64 {
            return None;
        }
        let level = self.level.median()?;
        let band = &mut self.band;
        let (m, memo) = self.memo.get_or_insert_with(|| (p.m, IntervalMemo::default()));
        let (_, lo, hi) = if *m == p.m {
            memo.get(p.terms, 0, p.terms, || band.factors(p.m, p.terms))
        } else {
            band.factors(p.m, p.terms)
        };
        Some(level < p.avar * lo || level > p.avar * hi)
    }

    /// Feeds one row; returns an event when one has just closed. `time_of` maps a sample index to
    /// seconds from the first sample.
    pub fn push(&mut self, row: &DavarRow, time_of: &dyn Fn(u64) -> f64) -> Option<ChangeEvent> {
        let avar = row.first_point()?.avar;
        let flagged = self.flag(row);
        // Quieter rows are learned even when flagged (rule 2 of the module doc).
        let quieter = self.level.median().is_some_and(|level| avar < level);
        if flagged != Some(true) || quieter {
            self.level.push(avar);
        }
        let half = (row.window / 2) as u64;
        let oldest = row.index - half;
        let newest = oldest + row.window as u64 - 1;
        match (flagged, &mut self.run) {
            (Some(true), Some(run)) => {
                run.last_row = row.index;
                run.end_index = oldest;
                run.end_s = time_of(oldest);
                run.rows += 1;
                run.quiet = 0;
                run.factor.push(avar / self.level.median().unwrap_or(avar));
                None
            }
            (Some(true), None) => {
                let mut factor = RobustLevel::new();
                factor.push(avar / self.level.median().unwrap_or(avar));
                self.run = Some(Run {
                    start_index: newest,
                    start_s: time_of(newest),
                    first_row: row.index,
                    last_row: row.index,
                    end_index: oldest,
                    end_s: time_of(oldest),
                    rows: 1,
                    quiet: 0,
                    factor,
                });
                None
            }
            (_, Some(run)) => {
                run.quiet += 1;
                if run.quiet > self.config.merge_rows {
                    self.close(true)
                } else {
                    None
                }
            }
            (_, None) => None,
        }
    }

    /// Ends the input: returns the event still open, if it is long enough.
    pub fn finish(&mut self) -> Option<ChangeEvent> {
        self.close(false)
    }

    fn close(&mut self, closed: bool) -> Option<ChangeEvent> {
        let run = self.run.take()?;
        if run.rows < self.config.min_rows as u64 || run.end_index < run.start_index {
            return None;
        }
        Some(ChangeEvent {
            start_index: run.start_index,
            end_index: run.end_index,
            start_s: run.start_s,
            end_s: run.end_s,
            first_row_index: run.first_row,
            last_row_index: run.last_row,
            factor: run.factor.median().unwrap_or(f64::NAN),
            rows: run.rows,
            closed,
        })
    }
}
