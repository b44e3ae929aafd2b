//! The nominal sample period τ0, estimated robustly from stamps.
//!
//! docs/design.md §1: τ0 is the median of the positive stamp intervals. The median ignores gaps, duplicates
//! and jitter that a mean would absorb. Live, [`PeriodEstimator`] settles on the median of the first
//! intervals it sees and then keeps it, so that every later row uses one τ0.

/// Median of the positive intervals between consecutive stamps, in seconds.
///
/// Returns `None` when fewer than one positive interval exists.
///
/// ```
/// let stamps = [0, 10_000_000, 20_000_000, 20_000_000, 90_000_000, 100_000_000];
/// assert_eq!(fdavar::signal::nominal_period(&stamps), Some(0.01));
/// ```
pub fn nominal_period(stamps_ns: &[i64]) -> Option<f64> {
    let mut intervals: Vec<i64> = stamps_ns
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&d| d > 0)
        .collect();
    median_ns(&mut intervals)
}

fn median_ns(intervals: &mut [i64]) -> Option<f64> {
    if intervals.is_empty() {
        return None;
    }
    intervals.sort_unstable();
    let n = intervals.len();
    let mid = if n % 2 == 1 {
        intervals[n / 2] as f64
    } else {
        (intervals[n / 2 - 1] as f64 + intervals[n / 2] as f64) / 2.0
    };
    Some(mid * 1e-9)
}

/// Learns τ0 live from the first `settle` positive intervals, then holds it.
#[derive(Debug, Clone)]
pub struct PeriodEstimator {
    settle: usize,
    last_ns: Option<i64>,
    intervals: Vec<i64>,
    settled: Option<f64>,
}

impl PeriodEstimator {
    /// An estimator that settles after `settle` positive intervals (at least 1).
    pub fn new(settle: usize) -> Self {
        PeriodEstimator {
            settle: settle.max(1),
            last_ns: None,
            intervals: Vec::new(),
            settled: None,
        }
    }

    /// Feeds one stamp; returns τ0 in seconds once settled.
    pub fn push(&mut self, stamp_ns: i64) -> Option<f64> {
        if self.settled.is_some() {
            return self.settled;
        }
        if let Some(last) = self.last_ns {
            if stamp_ns > last {
                self.intervals.push(stamp_ns - last);
            }
        }
        if self.last_ns.is_none_or(|l| stamp_ns > l) {
            self.last_ns = Some(stamp_ns);
        }
        if self.intervals.len() >= self.settle {
            self.settled = median_ns(&mut self.intervals);
            self.intervals = Vec::new();
        }
        self.settled
    }

    /// τ0 in seconds once settled.
    pub fn period(&self) -> Option<f64> {
        self.settled
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn live_estimate_settles_on_the_median() {
        let mut p = PeriodEstimator::new(5);
        let stamps = [0, 10, 20, 20, 95, 105, 115, 125];
        let got: Vec<_> = stamps.iter().map(|&s| p.push(s * 1_000_000)).collect();
        assert_eq!(got[5], None);
        assert_eq!(got[6], Some(0.01));
        assert_eq!(p.push(1), Some(0.01));
    }

    #[test]
    fn no_interval_no_period() {
        assert_eq!(nominal_period(&[5]), None);
        assert_eq!(nominal_period(&[5, 5, 3]), None);
    }
}
