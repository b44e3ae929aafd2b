//! A recording laid out for the fitter: six rate series on a regular grid, temperature aligned.
//!
//! Samples arrive placed by the [`Intake`] (the one place that decides τ0, drops duplicate and
//! backwards stamps and finds gaps; the DAVAR pipeline uses the same): a gap becomes NaN samples
//! (so that no Allan term straddles it, docs/design.md §1), a NaN value stays NaN in its axis, and the
//! temperature is interpolated linearly at each sample time. The live node and the CLI grow the
//! same [`RecordBuilder`] sample by sample, so the fitter sees the same numbers in both.
//!
//! Memory is bounded: when an axis holds [`RecordBuilder::max_samples`] values, neighbouring pairs
//! are averaged and τ0 doubles (later samples are averaged in blocks of the new size). Why block
//! means: the Allan variance at τ = m·τ0 of block means of 2 samples is the overlapping estimator at
//! stride 2 — the same expectation for every τ ≥ 2τ0, a little less EDF — so the long-τ end the
//! whole-run fit needs is kept, and only the shortest τ is given up, once the record is long. The
//! default keeps 2²⁰ samples per axis (2.9 h at 100 Hz, 44 min at 400 Hz) at full rate.
//!
//! Why 2²⁰ and not more: a diagnosis in flight holds about six buffers as long as the record, and
//! the record itself is six, so the peak follows the record's length; just short of a halving,
//! `fdavar analyze --jobs 2` of 2²¹ values per axis (5.7 h at 100 Hz) peaked at 310 MB, of 2²⁰
//! (2.9 h) at 169 MB, and a day at 99 MB instead of 170 MB (2026-11-28, bags/specs/clean.yaml,
//! `/usr/bin/time`). A static recording of 10 000 s at 100 Hz (the ADIS16405's) stays whole. No
//! I/O here.
//!
//! A block's mean is that of its valid samples, invalid only when none is: a NaN poisoned its block
//! before (2026-11-25), so a day at 100 Hz that lost 1 % of its messages one by one (three
//! halvings: blocks of 8) held 8 % invalid samples, more than the fit's bridge allows
//! (`allan::BRIDGE_MAX_MISSING`), lost its long τ again and got a false g_sensitivity and
//! bias_step on a gyro (`fdavar analyze` of `bags/specs/clean.yaml` for 24 h with
//! `lost_messages: { probability: 0.01 }`). A block that lost some samples is a slightly noisier
//! sample of the same time; without invalid samples nothing changes.

use crate::model::fit::AxisInput;
use crate::signal::{Axis, ImuSample, Intake, Irregularities, Placed, TemperatureSample};

/// Stamp intervals used to learn τ0 when it is not given (as the DAVAR pipeline does).
pub use crate::pipeline::PERIOD_SETTLE;

/// Six axes of rate samples on a regular grid, with what was irregular.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Nominal period τ0 of the grid, seconds (doubled at each halving of the record).
    pub tau0: f64,
    /// Rate samples per axis ([`Axis::ALL`] order); NaN where missing or bad.
    pub axes: [Vec<f64>; 6],
    /// Temperature at each sample, °C, when the recording has a temperature topic.
    pub temperature_c: Option<Vec<f64>>,
    /// Gaps, duplicates, backwards stamps, non-finite values met.
    pub irregularities: Irregularities,
}

/// Why samples cannot be laid out.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// Fewer than two distinct stamps: no period.
    #[error("{0} IMU samples: cannot estimate a sample period")]
    NoPeriod(usize),
    /// A gap so long that filling it would exceed the memory bound.
    #[error("a gap of {missing} samples after {at_s:.3} s is longer than the recording allows")]
    HugeGap {
        /// Missing samples.
        missing: u64,
        /// Where, seconds from the first sample.
        at_s: f64,
    },
}

impl Recording {
    /// Lays out samples (in the order received) and temperature readings, as the live node does.
    ///
    /// # Errors
    /// [`RecordError::NoPeriod`] with fewer than two distinct stamps; [`RecordError::HugeGap`]
    /// when a gap would more than double the record.
    pub fn from_samples(
        imu: &[ImuSample],
        temps: &[TemperatureSample],
    ) -> Result<Self, RecordError> {
        Self::from_samples_within(imu, temps, RecordBuilder::DEFAULT_MAX_SAMPLES)
    }

    /// [`Recording::from_samples`] halving the record (blocks of 2, 4, …) whenever it would hold
    /// more than `max_samples` per axis, as a long run is by the default cap.
    ///
    /// # Errors
    /// As [`Recording::from_samples`].
    pub fn from_samples_within(
        imu: &[ImuSample],
        temps: &[TemperatureSample],
        max_samples: usize,
    ) -> Result<Self, RecordError> {
        let mut builder = RecordBuilder::new(None, max_samples);
        for s in imu {
            builder.push(s);
        }
        for t in temps {
            builder.push_temperature(t);
        }
        builder.finish();
        if let Some(e) = builder.error() {
            return Err(e.clone());
        }
        builder
            .recording()
            .cloned()
            .ok_or(RecordError::NoPeriod(imu.len()))
    }

    /// The fitter's view of one axis (accel axes as g-sensitivity evidence, no DAVAR events).
    pub fn input(&self, axis: Axis) -> AxisInput<'_> {
        AxisInput {
            axis,
            tau0: self.tau0,
            rate: &self.axes[axis.index()],
            temperature_c: self.temperature_c.as_deref(),
            accel: Some([&self.axes[3], &self.axes[4], &self.axes[5]]),
            events: &[],
        }
    }

    fn len(&self) -> usize {
        self.axes[0].len()
    }
}

/// Grows a [`Recording`] sample by sample, with bounded memory (see the module doc).
#[derive(Debug, Clone)]
pub struct RecordBuilder {
    intake: Intake,
    max_samples: usize,
    /// The record so far (`None` until τ0 is known).
    record: Option<Recording>,
    /// Input samples averaged into one record sample (a power of two).
    block: usize,
    /// The block being averaged: sums and count of input samples so far, and per axis how many
    /// of them were valid (the sums hold only those).
    pending: ([f64; 6], usize),
    pending_valid: [usize; 6],
    /// Temperature readings kept (thinned by half whenever they outnumber a quarter of the cap).
    temps: Vec<TemperatureSample>,
    /// True when `record.temperature_c` is out of date.
    temps_stale: bool,
    /// Stamp of the last sample placed.
    last_stamp_ns: Option<i64>,
    error: Option<RecordError>,
    /// Scratch: the samples one push placed.
    scratch: Vec<Placed>,
}

impl RecordBuilder {
    /// Samples per axis kept at full rate before the record is halved (2²⁰: 8 MB per axis).
    pub const DEFAULT_MAX_SAMPLES: usize = crate::signal::MAX_GAP_SAMPLES as usize;

    /// The largest cap a user may ask for (`fdavar … --record-cap`, the node's `record_cap`):
    /// 2²⁴ values per axis, 46 h at 100 Hz in 805 MB for six axes before a diagnosis's buffers.
    /// Why no smaller cap than the default: a gap of up to [`crate::signal::MAX_GAP_SAMPLES`]
    /// periods is laid out in the record, which must be able to hold it.
    pub const LARGEST_MAX_SAMPLES: usize = 1 << 24;

    /// A cap a user asked for (`fdavar … --record-cap`, the node's `record_cap`), as written,
    /// checked against [[`Self::DEFAULT_MAX_SAMPLES`], [`Self::LARGEST_MAX_SAMPLES`]]: the one
    /// check and message of the CLI and the node.
    ///
    /// ```
    /// use fdavar::model::record::RecordBuilder;
    /// assert_eq!(RecordBuilder::user_cap("2097152"), Ok(1 << 21));
    /// assert!(RecordBuilder::user_cap("524288").unwrap_err().contains("[1048576, 16777216], got 524288"));
    /// assert!(RecordBuilder::user_cap("lots").is_err());
    /// ```
    ///
    /// # Errors
    /// The range, what was given, and why nothing below the default is accepted.
    pub fn user_cap(given: &str) -> Result<usize, String> {
        let (lo, hi) = (Self::DEFAULT_MAX_SAMPLES, Self::LARGEST_MAX_SAMPLES);
        given.trim().parse::<usize>().ok().filter(|v| (lo..=hi).contains(v)).ok_or_else(|| {
            format!(
                "values per axis, an integer in [{lo}, {hi}], got {given}: not less than the default, which is also the longest gap laid out in the record"
            )
        })
    }

    /// A builder with period `tau0` (seconds; `None`: learned from the first stamps) that keeps
    /// at most `max_samples` (at least 1024) values per axis.
    pub fn new(tau0: Option<f64>, max_samples: usize) -> RecordBuilder {
        RecordBuilder {
            intake: Intake::new(tau0, PERIOD_SETTLE),
            max_samples: max_samples.max(1024),
            record: None,
            block: 1,
            pending: ([0.0; 6], 0),
            pending_valid: [0; 6],
            temps: Vec::new(),
            temps_stale: false,
            last_stamp_ns: None,
            error: None,
            scratch: Vec::new(),
        }
    }

    /// Values kept per axis before halving.
    pub fn max_samples(&self) -> usize {
        self.max_samples
    }

    /// Values per axis in the record so far (0 until the period is known).
    pub fn values(&self) -> usize {
        self.record.as_ref().map_or(0, Recording::len)
    }

    /// Feeds one IMU sample (in the order received).
    pub fn push(&mut self, sample: &ImuSample) {
        let mut placed = std::mem::take(&mut self.scratch);
        self.intake.push(sample, &mut |p| placed.push(p));
        for p in placed.drain(..) {
            self.place(p);
        }
        self.scratch = placed;
    }

    /// Feeds one temperature reading.
    pub fn push_temperature(&mut self, t: &TemperatureSample) {
        if !t.celsius.is_finite() {
            return;
        }
        self.temps.push(*t);
        if self.temps.len() > self.max_samples / 4 {
            // Temperature is slow: every other reading carries the same curve.
            let mut k = 0;
            self.temps.retain(|_| {
                k += 1;
                k % 2 == 1
            });
        }
        self.temps_stale = true;
    }

    /// Ends the input: places a short input whose period was never settled.
    pub fn finish(&mut self) {
        let mut placed = Vec::new();
        self.intake.finish(&mut |p| placed.push(p));
        for p in placed {
            self.place(p);
        }
        // Nothing more comes: the room kept for the samples to come (up to half of a halved
        // record) goes back.
        if let Some(rec) = self.record.as_mut() {
            for axis in rec.axes.iter_mut() {
                axis.shrink_to_fit();
            }
        }
    }

    /// The error that stopped the record growing, if any (a gap too long to fill).
    pub fn error(&self) -> Option<&RecordError> {
        self.error.as_ref()
    }

    /// Irregularities of the input so far.
    pub fn irregularities(&self) -> Irregularities {
        self.intake.irregularities()
    }

    /// Stamp of the last sample placed, ns.
    pub fn last_stamp_ns(&self) -> Option<i64> {
        self.last_stamp_ns
    }

    /// The input's sample period τ0, s, once known (the record's own period doubles when it is
    /// halved; this one does not).
    pub fn input_tau0(&self) -> Option<f64> {
        self.intake.tau0()
    }

    /// Stamp of the first sample placed, ns.
    pub fn first_stamp_ns(&self) -> Option<i64> {
        self.intake.first_stamp_ns()
    }

    /// The record so far, its temperature interpolated at every sample (`None` before τ0 is
    /// known). Samples of an unfinished block are not in it yet.
    pub fn recording(&mut self) -> Option<&Recording> {
        let irregularities = self.intake.irregularities();
        let (first, block) = (self.intake.first_stamp_ns()?, self.block);
        let base_tau0 = self.intake.tau0()?;
        let last = self.last_stamp_ns;
        let rec = self.record.as_mut()?;
        rec.irregularities = irregularities;
        if self.temps_stale
            || rec
                .temperature_c
                .as_ref()
                .is_some_and(|t| t.len() != rec.len())
        {
            // Sample k of the record is the mean of input samples k·block … k·block + block − 1:
            // its time is their centre. Readings after the last IMU sample are not used yet (the
            // same readings live and offline, whatever the order the two topics arrive in).
            let centre = |k: usize| (k * block) as f64 + (block - 1) as f64 / 2.0;
            let usable: Vec<TemperatureSample> = self
                .temps
                .iter()
                .filter(|t| last.is_some_and(|l| t.stamp_ns <= l))
                .copied()
                .collect();
            rec.temperature_c = (!usable.is_empty()).then(|| {
                let times: Vec<i64> = (0..rec.len())
                    .map(|k| first + (centre(k) * base_tau0 * 1e9).round() as i64)
                    .collect();
                interpolate(&usable, &times)
            });
            self.temps_stale = false;
        }
        Some(rec)
    }

    fn place(&mut self, p: Placed) {
        if self.error.is_some() {
            return;
        }
        let Some(tau0) = self.intake.tau0() else {
            return;
        };
        let rec = self.record.get_or_insert_with(|| Recording {
            tau0,
            axes: Default::default(),
            temperature_c: None,
            irregularities: Irregularities::default(),
        });
        let placed_so_far = rec.len() * self.block + self.pending.1;
        if p.missing_before as usize > placed_so_far.max(self.max_samples) {
            let first = self.intake.first_stamp_ns().unwrap_or(p.sample.stamp_ns);
            self.error = Some(RecordError::HugeGap {
                missing: p.missing_before,
                at_s: (p.sample.stamp_ns - first) as f64 * 1e-9,
            });
            return;
        }
        for _ in 0..p.missing_before {
            self.add([f64::NAN; 6]);
        }
        self.add(p.sample.values());
        self.last_stamp_ns = Some(p.sample.stamp_ns);
        self.temps_stale = true;
    }

    /// Adds one input sample to the pending block; a full block becomes one record sample.
    fn add(&mut self, values: [f64; 6]) {
        let (sums, count) = &mut self.pending;
        for ((s, valid), v) in sums.iter_mut().zip(self.pending_valid.iter_mut()).zip(values) {
            if v.is_finite() {
                *s += v;
                *valid += 1;
            }
        }
        *count += 1;
        if *count < self.block {
            return;
        }
        let mean: [f64; 6] = std::array::from_fn(|k| match self.pending_valid[k] {
            0 => f64::NAN,
            valid => sums[k] / valid as f64,
        });
        self.pending = ([0.0; 6], 0);
        self.pending_valid = [0; 6];
        let Some(rec) = self.record.as_mut() else {
            return;
        };
        for (axis, v) in rec.axes.iter_mut().zip(mean) {
            axis.push(v);
        }
        if rec.len() >= self.max_samples {
            for axis in rec.axes.iter_mut() {
                halve(axis);
            }
            rec.tau0 *= 2.0;
            self.block *= 2;
        }
    }
}

/// Replaces `x` by the means of its neighbouring pairs (the valid one of a pair with one invalid
/// value; an odd last value is dropped), in place: the buffer's capacity is kept for the samples
/// to come.
fn halve(x: &mut Vec<f64>) {
    let n = x.len() / 2;
    for k in 0..n {
        let (a, b) = (x[2 * k], x[2 * k + 1]);
        x[k] = match (a.is_finite(), b.is_finite()) {
            (true, true) => 0.5 * (a + b),
            (true, false) => a,
            (false, true) => b,
            (false, false) => f64::NAN,
        };
    }
    x.truncate(n);
}

/// Linear interpolation of temperature readings at `times` (held constant beyond the ends).
fn interpolate(temps: &[TemperatureSample], times: &[i64]) -> Vec<f64> {
    let mut sorted: Vec<&TemperatureSample> =
        temps.iter().filter(|t| t.celsius.is_finite()).collect();
    sorted.sort_by_key(|t| t.stamp_ns);
    let mut k = 0;
    times
        .iter()
        .map(|&t| {
            if sorted.is_empty() {
                return f64::NAN;
            }
            while k + 1 < sorted.len() && sorted[k + 1].stamp_ns <= t {
                k += 1;
            }
            let a = sorted[k];
            match sorted.get(k + 1) {
                Some(b) if t >= a.stamp_ns && b.stamp_ns > a.stamp_ns => {
                    let w = (t - a.stamp_ns) as f64 / (b.stamp_ns - a.stamp_ns) as f64;
                    a.celsius + w * (b.celsius - a.celsius)
                }
                _ => a.celsius,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(stamp_ns: i64, v: f64) -> ImuSample {
        ImuSample {
            stamp_ns,
            gyro: [v; 3],
            accel: [v; 3],
        }
    }

    /// A block's mean is that of its valid samples, at each halving and in the blocks after it;
    /// a block with no valid sample is invalid.
    #[test]
    fn blocks_average_their_valid_samples() {
        let ms = 10_000_000;
        let mut b = RecordBuilder::new(Some(0.01), 1024);
        // 1024 samples fill the record: halved to 512 pairs; then blocks of 2.
        let tail = [1.0, f64::NAN, 3.0, 5.0, f64::NAN, f64::NAN, 7.0, 9.0, 2.0, f64::NAN, f64::NAN, f64::NAN];
        let values = std::iter::repeat_n(0.0, 1016).chain(tail);
        for (k, v) in values.enumerate() {
            b.push(&sample(k as i64 * ms, v));
        }
        b.finish();
        let r = b.recording().unwrap();
        assert_eq!(r.tau0, 0.02);
        let got = &r.axes[0];
        assert_eq!(got.len(), 514);
        assert_eq!(got[508..510], [1.0, 4.0]);
        assert!(got[510].is_nan());
        assert_eq!(got[511..513], [8.0, 2.0]);
        assert!(got[513].is_nan());
    }

    /// Issue 13: a forward clock jump longer than the record can lay out stopped the record for
    /// the rest of the run ("gap too long"); now it re-anchors and the record keeps growing.
    #[test]
    fn a_forward_clock_jump_re_anchors_instead_of_stopping_the_record() {
        let ms = 10_000_000;
        let jump = (crate::signal::MAX_GAP_SAMPLES as i64 + 10) * ms;
        let imu: Vec<ImuSample> = (0..2000)
            .map(|k| sample(k * ms + if k >= 1000 { jump } else { 0 }, k as f64))
            .collect();
        let r = Recording::from_samples(&imu, &[]).unwrap();
        assert_eq!(r.len(), 2000);
        assert_eq!(r.axes[0][999..1001], [999.0, 1000.0]);
        assert_eq!((r.irregularities.reanchors, r.irregularities.gaps), (1, 0));
        // One period less is still a gap, laid out as missing samples.
        let imu: Vec<ImuSample> = (0..20)
            .map(|k| sample(k * ms + if k >= 10 { jump - 11 * ms } else { 0 }, k as f64))
            .collect();
        let r = Recording::from_samples(&imu, &[]).unwrap();
        assert_eq!((r.irregularities.reanchors, r.irregularities.gaps), (0, 1));
        // The 2²⁰th sample fills the record, which is halved to 2¹⁹; the last 19 follow in
        // pairs (9, and one pending).
        assert_eq!(r.len(), (crate::signal::MAX_GAP_SAMPLES as usize) / 2 + 9);
        assert!((r.tau0 - 0.02).abs() < 1e-12);
    }

    #[test]
    fn gaps_become_nan_and_duplicates_are_dropped() {
        let ms = 10_000_000;
        let imu: Vec<ImuSample> = [0, 1, 2, 2, 5, 6]
            .iter()
            .map(|&k| sample(k * ms, k as f64))
            .collect();
        let temps = [
            TemperatureSample {
                stamp_ns: 0,
                celsius: 20.0,
            },
            TemperatureSample {
                stamp_ns: 6 * ms,
                celsius: 26.0,
            },
        ];
        let r = Recording::from_samples(&imu, &temps).unwrap();
        assert!((r.tau0 - 0.01).abs() < 1e-12);
        let x = &r.axes[0];
        assert_eq!(x.len(), 7);
        assert!(x[3].is_nan() && x[4].is_nan() && x[5] == 5.0);
        assert_eq!((r.irregularities.gaps, r.irregularities.duplicates), (1, 1));
        let t = r.temperature_c.unwrap();
        assert!((t[5] - 25.0).abs() < 1e-9 && (t[6] - 26.0).abs() < 1e-9);
    }
}
