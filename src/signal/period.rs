//! The nominal sample period τ0, estimated robustly from stamps.
//!
//! docs/design.md §1: τ0 is the median of the positive stamp intervals. The median ignores gaps, duplicates
//! and jitter that a mean would absorb. Live, [`PeriodEstimator`] settles on the median of the first
//! intervals it sees and then keeps it, so that every later row uses one τ0.
//!
//! Messages stamped when a driver reads them come in packets (a serial or USB IMU: 4 messages
//! 20 µs apart, then nothing for 4 periods): most intervals are then a few µs and their median is
//! no period at all (a 200 Hz stream in packets of 4 gave τ0 = 20 µs, and the layout refused the
//! record as one huge gap). So the median of the intervals is checked against the median rate over
//! [`PACKET_SPAN`] intervals; where it is less than half of that, the span's is τ0.

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
    period_of(&mut intervals)
}

/// Intervals summed for the packet check of [`period_of`]: twice the largest packet it sees
/// through.
pub const PACKET_SPAN: usize = 16;

/// τ0 of positive `intervals` (ns, reordered): their median, checked against their sums over
/// [`PACKET_SPAN`] in a row.
///
/// - Packets: where the median is less than half the spans' median per interval (most intervals
///   are the microseconds inside a packet), τ0 is the spans' median per interval.
/// - Jitter: each span over the whole periods it covers (a lost message adds one) is an estimate
///   [`PACKET_SPAN`] times less sensitive to jitter than one interval; where their median is more
///   than [`JITTER_AGREEMENT`] off the plain median, it is τ0. Regular stamps agree to ~10⁻⁶ and
///   keep the plain median, bit for bit.
///
/// Only with at least 4·[`PACKET_SPAN`] intervals: among a few, one long gap is in every span.
fn period_of(intervals: &mut [i64]) -> Option<f64> {
    let mut spans: Vec<i64> = if intervals.len() >= 4 * PACKET_SPAN {
        intervals.windows(PACKET_SPAN).map(|w| w.iter().sum()).collect()
    } else {
        Vec::new()
    };
    // The spans are taken above, before this sorts the intervals.
    let single = median_ns(intervals)?;
    let Some(per_interval) = median_ns(&mut spans).map(|s| s / PACKET_SPAN as f64) else {
        return Some(single);
    };
    if single < 0.5 * per_interval {
        return Some(per_interval);
    }
    // Each span over its whole number of periods (order does not matter to a median).
    let mut per_periods: Vec<i64> = spans
        .iter()
        .map(|&span| {
            let periods = (span as f64 * 1e-9 / single).round().max(1.0);
            (span as f64 / periods).round() as i64
        })
        .collect();
    let refined = median_ns(&mut per_periods)?;
    Some(if (refined / single - 1.0).abs() > JITTER_AGREEMENT { refined } else { single })
}

/// How far the median of single intervals may lie from that of the spans over their whole periods
/// before the latter is τ0 ([`period_of`]). Measured in tests/stamps_on_receipt.rs: stamps
/// jittering uniformly by ±0.25 periods put the plain median of 100 intervals up to 2.3 % off.
pub const JITTER_AGREEMENT: f64 = 0.001;

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
            self.settled = period_of(&mut self.intervals);
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

    /// Messages read in packets of 4, each packet stamped on receipt 20 µs apart: τ0 is the
    /// stream's period, not the 20 µs between the messages of a packet; regular stamps keep the
    /// plain median, bit for bit.
    #[test]
    fn packets_of_messages_keep_their_period() {
        let period = 5_000_000;
        let stamps: Vec<i64> = (0..400).map(|i: i64| (i / 4) * 4 * period + 3 * period + (i % 4) * 20_000).collect();
        assert_eq!(nominal_period(&stamps), Some(0.005));
        let mut live = PeriodEstimator::new(100);
        let settled = stamps.iter().find_map(|&s| live.push(s));
        assert_eq!(settled, Some(0.005));
        // Regular stamps with a jitter of ±1 µs: the median of the intervals, as before.
        let regular: Vec<i64> = (0..400).map(|i: i64| i * period + (i * 7919 % 3 - 1) * 1_000).collect();
        let mut intervals: Vec<i64> = regular.windows(2).map(|w| w[1] - w[0]).collect();
        assert_eq!(nominal_period(&regular), median_ns(&mut intervals));
    }

    /// One message in ten lost (every 10th, and an extra one now and then): τ0 stays the period
    /// exactly, where the spans' plain median per interval would be 6 % long.
    #[test]
    fn lost_messages_leave_the_period_exact() {
        let period = 2_500_000;
        let stamps: Vec<i64> = (0..2000i64).filter(|i| i % 10 != 3 && i % 97 != 5).map(|i| i * period).collect();
        assert_eq!(nominal_period(&stamps), Some(0.0025));
    }

    #[test]
    fn no_interval_no_period() {
        assert_eq!(nominal_period(&[5]), None);
        assert_eq!(nominal_period(&[5, 5, 3]), None);
    }
}
