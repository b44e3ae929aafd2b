//! The one place where IMU samples are put on the τ0 grid: τ0, stamp checks, gaps, bad values.
//!
//! Every analysis — the DAVAR rows ([`crate::pipeline`]), the whole-run record the model is fitted
//! to ([`crate::model::record`]), live in the node and offline in the CLI — takes its samples from
//! an [`Intake`], so the same input sequence is placed the same way everywhere:
//! - τ0 is the configured period, or the median of the first `settle` positive stamp intervals
//!   (samples are held back until then, not lost);
//! - a duplicate or backwards stamp is dropped and counted (the sensor clock decides the order;
//!   nothing is re-sorted), until [`REANCHOR_AFTER`] backwards stamps come in a row: the clock went
//!   back for good (a restarted publisher), so that stamp is placed as the new reference, after a
//!   gap of the samples dropped while deciding (counted in `reanchors`, not `backwards`);
//! - a gap (a stamp > 1.5 τ0 after the previous one on the grid, [`StampCheck::check`](super::StampCheck::check)) is reported as the number of missing periods before the sample, so
//!   that no Allan term straddles it;
//! - a NaN or infinite value stays in its axis (each analysis treats it as a missing value of that
//!   axis) and is counted once per value; a value beyond [`MAX_ABS_RATE`] (10⁶ rad/s or m/s²) is
//!   not a measurement: it is placed as NaN and counted the same way, so that it cannot overflow
//!   σ²_ref or F.

use super::{is_usable, Axis, ImuSample, Irregularities, PeriodEstimator, StampCheck, StampClass};
#[cfg(doc)]
use super::{MAX_ABS_RATE, REANCHOR_AFTER};

/// One sample as the intake placed it on the grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placed {
    /// Whole periods missing just before this sample (a gap), 0 normally.
    pub missing_before: u64,
    /// The sample (its values may be NaN or ±∞: missing on that axis; values beyond
    /// [`super::MAX_ABS_RATE`] arrive here as NaN).
    pub sample: ImuSample,
}

/// Puts samples on the τ0 grid (see the module doc).
#[derive(Debug, Clone)]
pub struct Intake {
    given_tau0: Option<f64>,
    period: PeriodEstimator,
    held: Vec<ImuSample>,
    running: Option<(f64, StampCheck)>,
    first_stamp_ns: Option<i64>,
    /// The axes whose non-finite values are counted ([`Axis::ALL`] order).
    counted: [bool; 6],
}

impl Intake {
    /// An intake with the period `tau0` (seconds), or learning it from the first `settle` positive
    /// intervals when `tau0` is `None`.
    pub fn new(tau0: Option<f64>, settle: usize) -> Intake {
        Intake {
            given_tau0: tau0,
            period: PeriodEstimator::new(settle),
            held: Vec::new(),
            running: None,
            first_stamp_ns: None,
            counted: [true; 6],
        }
    }

    /// Counts non-finite values only on `axes` (an analysis of some axes, e.g. of a one-column
    /// text file, does not report the axes it does not read).
    pub fn counting(mut self, axes: &[Axis]) -> Intake {
        self.counted = Axis::ALL.map(|a| axes.contains(&a));
        self
    }

    /// The nominal period in use, once known.
    pub fn tau0(&self) -> Option<f64> {
        self.running.as_ref().map(|(tau0, _)| *tau0)
    }

    /// The stamp of the first sample placed (the origin of every time in seconds).
    pub fn first_stamp_ns(&self) -> Option<i64> {
        self.first_stamp_ns
    }

    /// Irregularities counted so far.
    pub fn irregularities(&self) -> Irregularities {
        self.running
            .as_ref()
            .map(|(_, check)| check.counts())
            .unwrap_or_default()
    }

    /// Feeds one sample; `place` gets every sample placed by this call (none while τ0 is being
    /// learned, all the held ones at once when it is known).
    pub fn push(&mut self, sample: &ImuSample, place: &mut dyn FnMut(Placed)) {
        if self.running.is_some() {
            self.place(sample, place);
            return;
        }
        let tau0 = self
            .given_tau0
            .or_else(|| self.period.push(sample.stamp_ns));
        self.held.push(*sample);
        if let Some(tau0) = tau0 {
            self.start(tau0, place);
        }
    }

    /// Ends the input: a short input whose period was never settled is placed with the median of
    /// the intervals it has (nothing when it has none).
    pub fn finish(&mut self, place: &mut dyn FnMut(Placed)) {
        if self.running.is_some() {
            return;
        }
        let stamps: Vec<i64> = self.held.iter().map(|s| s.stamp_ns).collect();
        if let Some(tau0) = self.given_tau0.or_else(|| super::nominal_period(&stamps)) {
            self.start(tau0, place);
        }
    }

    fn start(&mut self, tau0: f64, place: &mut dyn FnMut(Placed)) {
        self.running = Some((tau0, StampCheck::new(tau0)));
        for s in std::mem::take(&mut self.held) {
            self.place(&s, place);
        }
    }

    fn place(&mut self, sample: &ImuSample, place: &mut dyn FnMut(Placed)) {
        let Some((_, check)) = self.running.as_mut() else {
            return;
        };
        let missing_before = match check.check(sample.stamp_ns) {
            StampClass::Duplicate | StampClass::Backwards => return,
            StampClass::Gap { missing } => missing,
            StampClass::Reanchored { dropped } => dropped,
            StampClass::Next => 0,
        };
        let mut sample = *sample;
        let fix = |v: &mut f64, counted: bool, check: &mut StampCheck| {
            if !is_usable(*v) {
                if v.is_finite() {
                    *v = f64::NAN;
                }
                if counted {
                    check.count_non_finite();
                }
            }
        };
        let [c0, c1, c2, c3, c4, c5] = self.counted;
        for (v, counted) in sample.gyro.iter_mut().zip([c0, c1, c2]) {
            fix(v, counted, check);
        }
        for (v, counted) in sample.accel.iter_mut().zip([c3, c4, c5]) {
            fix(v, counted, check);
        }
        self.first_stamp_ns.get_or_insert(sample.stamp_ns);
        place(Placed {
            missing_before,
            sample,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    fn s(stamp_ms: i64, v: f64) -> ImuSample {
        ImuSample {
            stamp_ns: stamp_ms * MS,
            gyro: [v, 0.0, 0.0],
            accel: [0.0; 3],
        }
    }

    #[test]
    fn holds_until_the_period_is_known_then_places_in_order() {
        let mut intake = Intake::new(None, 3);
        let mut placed = Vec::new();
        for (k, t) in [0, 10, 20, 20, 15, 30, 60, 70].into_iter().enumerate() {
            intake.push(&s(t, k as f64), &mut |p| placed.push(p));
            if k < 3 {
                assert!(placed.is_empty(), "held while τ0 is learned");
            }
        }
        assert_eq!(intake.tau0(), Some(0.01));
        let got: Vec<(u64, f64)> = placed
            .iter()
            .map(|p| (p.missing_before, p.sample.gyro[0]))
            .collect();
        // 20 again (duplicate) and 15 (backwards) dropped; 60 after 30 is a gap of 2 periods.
        assert_eq!(
            got,
            vec![(0, 0.0), (0, 1.0), (0, 2.0), (0, 5.0), (2, 6.0), (0, 7.0)]
        );
        let c = intake.irregularities();
        assert_eq!((c.duplicates, c.backwards, c.gaps), (1, 1, 1));
        assert_eq!(intake.first_stamp_ns(), Some(0));
    }

    #[test]
    fn non_finite_values_are_placed_and_counted() {
        let mut intake = Intake::new(Some(0.01), 100);
        let mut placed = Vec::new();
        intake.push(&s(0, 1.0), &mut |p| placed.push(p));
        intake.push(&s(10, f64::NAN), &mut |p| placed.push(p));
        assert_eq!(placed.len(), 2);
        assert!(placed[1].sample.gyro[0].is_nan());
        assert_eq!(intake.irregularities().non_finite, 1);
    }

    /// Issue 13: after the sensor clock went back (a publisher restarted with older stamps) every
    /// later sample was dropped as backwards, forever. Now the 50th backwards stamp in a row
    /// re-anchors: it is placed after a gap of the 49 dropped, and the samples after it flow.
    #[test]
    fn a_clock_that_goes_back_re_anchors_after_50_samples() {
        use crate::signal::REANCHOR_AFTER;
        let mut intake = Intake::new(Some(0.01), 100);
        let mut placed = Vec::new();
        for k in 0..100 {
            intake.push(&s(10_000 + 10 * k, k as f64), &mut |p| placed.push(p));
        }
        // The publisher restarts: its clock starts at 0 ms again.
        for k in 0..200 {
            intake.push(&s(10 * k, 1000.0 + k as f64), &mut |p| placed.push(p));
        }
        let after: Vec<&Placed> = placed[100..].iter().collect();
        assert_eq!(REANCHOR_AFTER, 50);
        assert_eq!(
            after.len(),
            200 - 49,
            "49 dropped while deciding, then every sample"
        );
        assert_eq!(after[0].sample.gyro[0], 1049.0);
        assert_eq!(after[0].sample.stamp_ns, 490 * MS);
        assert_eq!(after[0].missing_before, 49, "the dropped samples are a gap");
        assert!(after[1..].iter().all(|p| p.missing_before == 0));
        let c = intake.irregularities();
        assert_eq!((c.backwards, c.reanchors, c.gaps), (49, 1, 0));
        // A few late or replayed stamps are only dropped: the run resets on a good stamp.
        let mut intake = Intake::new(Some(0.01), 100);
        let mut n = 0;
        let mut t = 1000;
        intake.push(&s(t, 0.0), &mut |_| n += 1);
        for round in 0..10 {
            for _ in 0..40 {
                intake.push(&s(round, 0.0), &mut |_| n += 1);
            }
            t += 10;
            intake.push(&s(t, 0.0), &mut |_| n += 1);
        }
        let c = intake.irregularities();
        assert_eq!((c.backwards, c.reanchors, n), (400, 0, 11));
        // Stale stamps that do not tick forward never re-anchor: 100 zero stamps in a stamped
        // stream, or 100 copies of one old stamp, stay dropped.
        for stale in [0, 500] {
            for _ in 0..100 {
                intake.push(&s(stale, 0.0), &mut |_| n += 1);
            }
        }
        let c = intake.irregularities();
        assert_eq!((c.backwards, c.reanchors, n), (600, 0, 11));
    }

    /// Issue 13: ten ±1e300 samples overflowed σ²_ref (their square is ∞) and left F NaN for the
    /// rest of the run. A value beyond 10⁶ (rad/s or m/s²) is placed as NaN and counted like one;
    /// the largest real one passes.
    #[test]
    fn absurd_values_are_placed_as_missing_and_counted() {
        use crate::signal::MAX_ABS_RATE;
        let mut intake = Intake::new(Some(0.01), 100).counting(&[Axis::GyroX, Axis::AccelZ]);
        let mut placed = Vec::new();
        for (k, v) in [1e300, -1e300, 1.0e6 + 1.0, MAX_ABS_RATE, -MAX_ABS_RATE, 0.5]
            .into_iter()
            .enumerate()
        {
            let mut sample = s(10 * k as i64, v);
            sample.accel[2] = v;
            sample.gyro[1] = v; // not counted (not an analysed axis), still made missing
            intake.push(&sample, &mut |p| placed.push(p));
        }
        let gx: Vec<f64> = placed.iter().map(|p| p.sample.gyro[0]).collect();
        assert!(gx[..3].iter().all(|v| v.is_nan()), "{gx:?}");
        assert_eq!(&gx[3..], &[MAX_ABS_RATE, -MAX_ABS_RATE, 0.5]);
        assert!(placed[0].sample.accel[2].is_nan() && placed[0].sample.gyro[1].is_nan());
        assert_eq!(
            intake.irregularities().non_finite,
            6,
            "3 values on each counted axis"
        );
    }

    #[test]
    fn a_short_input_is_placed_at_finish() {
        let mut intake = Intake::new(None, 100);
        let mut n = 0;
        for t in [0, 10, 20] {
            intake.push(&s(t, 0.0), &mut |_| n += 1);
        }
        assert_eq!(n, 0);
        intake.finish(&mut |_| n += 1);
        assert_eq!((n, intake.tau0()), (3, Some(0.01)));
    }
}
