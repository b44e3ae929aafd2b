//! The one path from IMU samples to DAVAR rows, shared by the offline CLI and the live node.
//!
//! `ImuSample` → [`Intake`] (τ0, stamp checks: gaps become missing-sample markers, duplicates and
//! stamps going backwards are dropped and counted — a clock that went back for good is
//! re-anchored —, NaN/∞ values and values beyond 10⁶ counted; the same intake feeds the
//! whole-run analysis of [`crate::analysis`]) → one [`DavarEngine`] and one [`ChangeDetector`] per
//! axis (a non-finite value is a missing sample of its axis) → rows tagged with axis, time and
//! stamp, and change events.
//!
//! Determinism: the pipeline has no clock and no thread of its own. Its output depends only on the
//! sequence of samples pushed, so the node (which pushes samples from its subscription) and the
//! CLI (which pushes them from a file or bag) give the same rows for the same input.
//!
//! τ0 comes from the `tau0` parameter or, when that is 0, from the median of the first
//! [`PERIOD_SETTLE`] positive stamp intervals; samples are held back until then (live, that delays
//! the first rows by that many samples; they are not lost).

use crate::allan::TauGrid;
use crate::davar::{
    ChangeDetector, ChangeEvent, DavarEngine, DavarError, DavarRow,
    DetectorConfig, EngineConfig, FTarget, FixedWindow, ProportionalPolicy, SharedIntervals, SigmaRef,
    SignPolicy, WindowPolicy,
};
use crate::signal::{Axis, ImuSample, Intake, Irregularities, Placed};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// Stamp intervals used to estimate τ0 when it is not given.
pub const PERIOD_SETTLE: usize = 100;

/// The window policy, as configured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum PolicyConfig {
    /// A fixed window of `length` samples.
    Fixed {
        /// W, samples.
        length: usize,
    },
    /// Seed Eq. 3.
    Sign {
        /// λ1.
        min: usize,
        /// λ2.
        max: usize,
        /// ΔW.
        step: usize,
    },
    /// Step growing with |log₂(F/F̃)|.
    Proportional {
        /// λ1.
        min: usize,
        /// λ2.
        max: usize,
        /// ΔW per doubling of F/F̃.
        step: usize,
        /// Largest move per row.
        max_step: usize,
    },
}

impl PolicyConfig {
    /// A fresh policy object.
    pub fn build(&self) -> Box<dyn WindowPolicy> {
        match *self {
            PolicyConfig::Fixed { length } => Box::new(FixedWindow::new(length)),
            PolicyConfig::Sign { min, max, step } => Box::new(SignPolicy::new(min, max, step)),
            PolicyConfig::Proportional {
                min,
                max,
                step,
                max_step,
            } => Box::new(ProportionalPolicy::new(min, max, step, max_step)),
        }
    }

    /// λ2 (the fixed length for `Fixed`).
    pub fn max_window(&self) -> usize {
        match *self {
            PolicyConfig::Fixed { length } => length,
            PolicyConfig::Sign { max, .. } | PolicyConfig::Proportional { max, .. } => max,
        }
    }
}

/// How σ²_ref is obtained, as configured (`sigma_ref.mode`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum SigmaRefMode {
    /// Whole-record variance per axis (offline only: the caller reads the record first, see
    /// [`record_variances`] and [`record_variances_in_two_passes`]).
    Record,
    /// Running variance of all samples so far.
    Running,
    /// Variance of the first `seconds` of data, then frozen.
    Baseline {
        /// Baseline length, seconds.
        seconds: f64,
    },
    /// A given variance.
    Value(f64),
}

/// Everything the pipeline needs; built from a parameter file by [`crate::params`].
#[derive(Debug, Clone, PartialEq)]
pub struct DavarConfig {
    /// Window policy.
    pub policy: PolicyConfig,
    /// F̃.
    pub f_target: FTarget,
    /// σ²_ref.
    pub sigma_ref: SigmaRefMode,
    /// τ grid (cut at λ2/3).
    pub taus: TauGrid,
    /// Nominal period in seconds, or `None` to estimate it from stamps.
    pub tau0: Option<f64>,
    /// Change detection.
    pub events: DetectorConfig,
}

/// Errors of the pipeline.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// `sigma_ref.mode: record` without the whole-record variances.
    #[error("sigma_ref.mode 'record' needs the variance of the whole record (offline only); use running, baseline or value live")]
    RecordVarianceMissing,
    /// The whole record of an axis has fewer than two finite values or no spread.
    #[error("axis {axis}: the whole-record variance is undefined (fewer than two finite values, or all equal)")]
    RecordVarianceUndefined {
        /// The axis.
        axis: Axis,
    },
    /// The engine rejected the configuration.
    #[error(transparent)]
    Engine(#[from] DavarError),
}

/// One DAVAR row of one axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisRow {
    /// The axis.
    pub axis: Axis,
    /// Analysis time, seconds from the first sample (from the stamp of the analysis sample).
    pub time_s: f64,
    /// Stamp of the analysis sample, ns (interpolated inside a gap).
    pub stamp_ns: i64,
    /// The row.
    pub row: DavarRow,
}

/// One change event of one axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisEvent {
    /// The axis.
    pub axis: Axis,
    /// The event.
    pub event: ChangeEvent,
}

/// What one push produced.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Output {
    /// Rows, in order of analysis time per axis, axes interleaved as they completed.
    pub rows: Vec<AxisRow>,
    /// Events that closed.
    pub events: Vec<AxisEvent>,
}

/// What the rows of one axis amount to: how many, over which analysis times, which windows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RowSummary {
    /// The axis.
    pub axis: Axis,
    /// Rows made.
    pub rows: u64,
    /// Analysis time of the first and of the last row, seconds from the first sample.
    pub first_s: f64,
    /// See `first_s`.
    pub last_s: f64,
    /// Shortest window used, samples.
    pub window_min: usize,
    /// Longest window used, samples.
    pub window_max: usize,
}

impl RowSummary {
    /// The summary of the one row `r`.
    pub fn of(r: &AxisRow) -> RowSummary {
        RowSummary {
            axis: r.axis,
            rows: 1,
            first_s: r.time_s,
            last_s: r.time_s,
            window_min: r.row.window,
            window_max: r.row.window,
        }
    }

    /// Counts one more row of the same axis, later than the others.
    pub fn add(&mut self, r: &AxisRow) {
        self.rows += 1;
        self.last_s = r.time_s;
        self.window_min = self.window_min.min(r.row.window);
        self.window_max = self.window_max.max(r.row.window);
    }
}

/// The whole-record variance of each axis ([`SigmaRefMode::Record`]); `None` where undefined.
pub fn record_variances(samples: &[ImuSample]) -> [Option<f64>; 6] {
    let all = record_variances_in_two_passes(|f| {
        samples.iter().for_each(f);
        Ok::<(), std::convert::Infallible>(())
    });
    match all {
        Ok(v) => v,
        Err(never) => match never {},
    }
}

/// The whole-record variance of each axis over a record read twice, in the same order, by `pass`
/// (which feeds every sample to the function it is given): the mean first, then the squared
/// deviations from it. Memory stays constant however long the record; the numbers are those of
/// [`crate::davar::record_variance`] on the values held in memory, operation for operation.
///
/// # Errors
/// The first error `pass` returns.
pub fn record_variances_in_two_passes<E>(
    mut pass: impl FnMut(&mut dyn FnMut(&ImuSample)) -> Result<(), E>,
) -> Result<[Option<f64>; 6], E> {
    let (mut sum, mut n) = ([0.0f64; 6], [0u64; 6]);
    pass(&mut |s| {
        for a in Axis::ALL {
            let v = s.value(a);
            if crate::signal::is_usable(v) {
                sum[a.index()] += v;
                n[a.index()] += 1;
            }
        }
    })?;
    let mean: [f64; 6] = std::array::from_fn(|i| sum[i] / n[i] as f64);
    let mut m2 = [0.0f64; 6];
    pass(&mut |s| {
        for a in Axis::ALL {
            let v = s.value(a);
            if crate::signal::is_usable(v) {
                let d = v - mean[a.index()];
                m2[a.index()] += d * d;
            }
        }
    })?;
    Ok(std::array::from_fn(|i| {
        (n[i] >= 2)
            .then(|| m2[i] / n[i] as f64)
            .filter(|v| *v > 0.0)
    }))
}

struct AxisState {
    axis: Axis,
    engine: DavarEngine,
    detector: ChangeDetector,
}

/// Stamps of the most recent sample indices (markers included), to tag rows and events.
struct Stamps {
    tau0: f64,
    first_stamp: i64,
    /// Stamps, index `first` at the front.
    recent: VecDeque<i64>,
    first: u64,
    keep: usize,
}

impl Stamps {
    fn stamp_of(&self, index: u64) -> i64 {
        match index.checked_sub(self.first) {
            Some(i) if (i as usize) < self.recent.len() => self.recent[i as usize],
            _ => self.first_stamp + (index as f64 * self.tau0 * 1e9).round() as i64,
        }
    }

    fn seconds(&self, index: u64) -> f64 {
        (self.stamp_of(index) - self.first_stamp) as f64 * 1e-9
    }

    fn remember(&mut self, stamp: i64) {
        self.recent.push_back(stamp);
        if self.recent.len() > self.keep {
            self.recent.pop_front();
            self.first += 1;
        }
    }

    /// Records `missing` interpolated stamps before `stamp`; only the newest `keep` are kept.
    fn fill_gap(&mut self, missing: u64, stamp: i64) {
        let last = self.recent.back().copied().unwrap_or(self.first_stamp);
        let step = (stamp - last) as f64 / (missing + 1) as f64;
        let skipped = missing - missing.min(self.keep as u64);
        if skipped > 0 {
            self.first += self.recent.len() as u64 + skipped;
            self.recent.clear();
        }
        for i in (skipped + 1)..=missing {
            self.remember(last + (step * i as f64).round() as i64);
        }
    }
}

struct Running {
    stamps: Stamps,
    axes: Vec<AxisState>,
    scratch: Vec<DavarRow>,
}

impl Running {
    fn push(&mut self, placed: Placed, out: &mut Output) {
        let s = placed.sample;
        if placed.missing_before > 0 {
            let missing = placed.missing_before;
            self.stamps.fill_gap(missing, s.stamp_ns);
            for k in 0..self.axes.len() {
                self.axes[k].engine.push_missing(missing, &mut self.scratch);
                self.drain(k, out);
            }
        }
        self.stamps.remember(s.stamp_ns);
        for k in 0..self.axes.len() {
            let value = s.value(self.axes[k].axis);
            self.axes[k].engine.push(Some(value), &mut self.scratch);
            self.drain(k, out);
        }
    }

    fn drain(&mut self, k: usize, out: &mut Output) {
        let stamps = &self.stamps;
        let state = &mut self.axes[k];
        let time_of = |i: u64| stamps.seconds(i);
        let Output { rows, events } = out;
        rows.extend(self.scratch.drain(..).map(|row| {
            if let Some(event) = state.detector.push(&row, &time_of) {
                events.push(AxisEvent {
                    axis: state.axis,
                    event,
                });
            }
            AxisRow {
                axis: state.axis,
                time_s: stamps.seconds(row.index),
                stamp_ns: stamps.stamp_of(row.index),
                row,
            }
        }));
    }
}

/// The streaming pipeline of one IMU topic (see the module doc).
pub struct Pipeline {
    config: DavarConfig,
    axes: Vec<Axis>,
    record: Option<[Option<f64>; 6]>,
    intake: Intake,
    /// Scratch: the samples one push placed.
    placed: Vec<Placed>,
    running: Option<Running>,
    /// The χ² intervals the axes' engines share.
    intervals: SharedIntervals,
    /// Whether rows hold only their shortest τ ([`Pipeline::shortest_tau_only`]).
    shortest_tau_only: bool,
}

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline")
            .field("axes", &self.axes)
            .field("tau0", &self.tau0())
            .finish_non_exhaustive()
    }
}

impl Pipeline {
    /// A pipeline over `axes` (usually [`Axis::ALL`]).
    ///
    /// `record` holds the whole-record variances ([`record_variances`]) and is required exactly when
    /// `config.sigma_ref` is [`SigmaRefMode::Record`].
    ///
    /// # Errors
    /// [`PipelineError::RecordVarianceMissing`] / [`PipelineError::RecordVarianceUndefined`] for
    /// record mode without usable variances; [`PipelineError::Engine`] when the engine rejects the
    /// configuration (checked here, before any sample).
    pub fn new(
        config: DavarConfig,
        axes: &[Axis],
        record: Option<[Option<f64>; 6]>,
    ) -> Result<Self, PipelineError> {
        if config.sigma_ref == SigmaRefMode::Record {
            let record = record.ok_or(PipelineError::RecordVarianceMissing)?;
            if let Some(&axis) = axes.iter().find(|a| record[a.index()].is_none()) {
                return Err(PipelineError::RecordVarianceUndefined { axis });
            }
        }
        let pipeline = Pipeline {
            intake: Intake::new(config.tau0, PERIOD_SETTLE).counting(axes),
            config,
            axes: axes.to_vec(),
            record,
            placed: Vec::new(),
            running: None,
            intervals: SharedIntervals::default(),
            shortest_tau_only: false,
        };
        // Validate the engine configuration now, with a placeholder period when none is given.
        pipeline.engine_for(Axis::GyroX, pipeline.config.tau0.unwrap_or(1.0))?;
        Ok(pipeline)
    }

    /// This pipeline with its engines taking their χ² intervals from `intervals`, which other
    /// pipelines may share.
    ///
    /// Why: the intervals depend on (m, terms) only, so pipelines that split one record's axes
    /// between them (`fdavar analyze`, a worker each) meet the same pairs; shared, each pair's χ²
    /// inversions are made once (the same numbers either way).
    pub fn sharing_intervals(mut self, intervals: SharedIntervals) -> Self {
        self.intervals = intervals;
        self
    }

    /// The same pipeline whose rows hold only their shortest τ
    /// ([`DavarEngine::shortest_tau_only`]): for a caller that reads of the rows their windows, F
    /// and events, not their Allan curves. Those are the same as with full rows.
    pub fn shortest_tau_only(mut self) -> Self {
        self.shortest_tau_only = true;
        self
    }

    fn engine_for(&self, axis: Axis, tau0: f64) -> Result<DavarEngine, PipelineError> {
        let sigma_ref = match self.config.sigma_ref {
            SigmaRefMode::Record => SigmaRef::Value(
                self.record
                    .and_then(|r| r[axis.index()])
                    .ok_or(PipelineError::RecordVarianceUndefined { axis })?,
            ),
            SigmaRefMode::Running => SigmaRef::Running,
            SigmaRefMode::Baseline { seconds } => SigmaRef::Baseline {
                samples: ((seconds / tau0).round() as usize).max(2),
            },
            SigmaRefMode::Value(v) => SigmaRef::Value(v),
        };
        let max = self.config.policy.max_window();
        let engine = EngineConfig {
            factors: self.config.taus.factors(max / 3),
            tau0,
            sigma_ref,
            f_target: self.config.f_target,
        };
        let engine = DavarEngine::with_intervals(engine, self.config.policy.build(), self.intervals.clone())?;
        Ok(if self.shortest_tau_only { engine.shortest_tau_only() } else { engine })
    }

    /// The nominal period in use, once known.
    pub fn tau0(&self) -> Option<f64> {
        self.intake.tau0()
    }

    /// Irregularities counted so far (gaps, duplicates, backwards stamps, non-finite values).
    pub fn irregularities(&self) -> Irregularities {
        self.intake.irregularities()
    }

    /// Squared differences left out so far because they straddled an invalid sample, per axis.
    pub fn excluded_terms(&self) -> Vec<(Axis, u64)> {
        self.running
            .as_ref()
            .map(|r| {
                r.axes
                    .iter()
                    .map(|a| (a.axis, a.engine.excluded_terms()))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// Pushes one IMU sample; rows and closed events are appended to `out`.
    pub fn push(&mut self, sample: &ImuSample, out: &mut Output) {
        let mut placed = std::mem::take(&mut self.placed);
        self.intake.push(sample, &mut |p| placed.push(p));
        self.place(&mut placed, out);
        self.placed = placed;
    }

    /// Hands back a row this pipeline made once its points are no longer needed: the next rows
    /// of that axis reuse their memory ([`DavarEngine::recycle`]).
    pub fn recycle(&mut self, row: AxisRow) {
        if let Some(engine) = self.engine_of(row.axis) {
            engine.recycle(row.row);
        }
    }

    /// [`Pipeline::recycle`] of every row in `rows`, leaving it empty.
    ///
    /// Why not a loop of `recycle(row)` over `rows.drain(..)`: each row (about 150 bytes) would be
    /// copied out of the vector and into the call, a `memmove` per row and axis: 2.7 % of
    /// `fdavar analyze`'s CPU (`perf record --call-graph dwarf`). Here only each row's variance
    /// vector and layout move.
    pub fn recycle_all(&mut self, rows: &mut Vec<AxisRow>) {
        for row in rows.iter_mut() {
            if let Some(engine) = self.engine_of(row.axis) {
                engine.recycle_parts(std::mem::take(&mut row.row.avars), row.row.layout.take());
            }
        }
        rows.clear();
    }

    /// The engine of `axis`, once the pipeline runs.
    fn engine_of(&mut self, axis: Axis) -> Option<&mut DavarEngine> {
        let running = self.running.as_mut()?;
        running.axes.iter_mut().find(|a| a.axis == axis).map(|a| &mut a.engine)
    }

    /// Ends the input: flushes held samples (estimating τ0 from them if needed) and closes open
    /// events (marked `closed: false`).
    pub fn finish(&mut self, out: &mut Output) {
        let mut placed = Vec::new();
        self.intake.finish(&mut |p| placed.push(p));
        self.place(&mut placed, out);
        if let Some(r) = &mut self.running {
            for a in &mut r.axes {
                if let Some(event) = a.detector.finish() {
                    out.events.push(AxisEvent {
                        axis: a.axis,
                        event,
                    });
                }
            }
        }
    }

    /// Runs placed samples through the engines, starting them at the first one.
    ///
    /// `placed` is left empty (a scratch buffer kept across pushes).
    fn place(&mut self, placed: &mut Vec<Placed>, out: &mut Output) {
        if placed.is_empty() {
            return;
        }
        if self.running.is_none() {
            let tau0 = self
                .intake
                .tau0()
                .expect("samples are placed once τ0 is known");
            self.start(tau0, placed[0].sample.stamp_ns);
        }
        let r = self.running.as_mut().expect("just started");
        for p in placed.drain(..) {
            r.push(p, out);
        }
    }

    fn start(&mut self, tau0: f64, first_stamp: i64) {
        let axes: Vec<AxisState> = self
            .axes
            .iter()
            .map(|&axis| AxisState {
                axis,
                engine: self
                    .engine_for(axis, tau0)
                    .expect("configuration validated in Pipeline::new"),
                detector: ChangeDetector::new(self.config.events),
            })
            .collect();
        self.running = Some(Running {
            stamps: Stamps {
                tau0,
                first_stamp,
                recent: VecDeque::new(),
                first: 0,
                keep: self.config.policy.max_window() + 16,
            },
            axes,
            scratch: Vec::new(),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(k: i64, stamp_ns: i64, v: f64) -> ImuSample {
        let w = ((k * 7919) % 101) as f64 / 50.0 - 1.0;
        ImuSample {
            stamp_ns,
            gyro: [v + w, w, -w],
            accel: [w, 2.0 * w, 9.81 + w],
        }
    }

    fn config() -> DavarConfig {
        DavarConfig {
            policy: PolicyConfig::Fixed { length: 31 },
            events: DetectorConfig {
                z: 3.0,
                warmup_rows: 20,
                min_rows: 5,
                merge_rows: 5,
            },
            ..DavarConfig::default()
        }
    }

    #[test]
    fn gaps_become_markers_and_duplicates_are_dropped() {
        let mut p = Pipeline::new(config(), &Axis::ALL, None).unwrap();
        let mut out = Output::default();
        let mut k = 0;
        for i in 0..300i64 {
            if (150..153).contains(&i) {
                continue; // three missing samples
            }
            p.push(&sample(k, i * 10_000_000, 0.0), &mut out);
            k += 1;
            if i == 200 {
                p.push(&sample(k, i * 10_000_000, 0.0), &mut out); // duplicate
            }
        }
        p.finish(&mut out);
        assert_eq!(p.tau0(), Some(0.01));
        let counts = p.irregularities();
        assert_eq!((counts.gaps, counts.duplicates), (1, 1));
        let gx: Vec<&AxisRow> = out.rows.iter().filter(|r| r.axis == Axis::GyroX).collect();
        assert_eq!(gx.len(), 300 - 31 + 1, "indices follow time, gaps included");
        for r in &gx {
            assert_eq!(r.stamp_ns, r.row.index as i64 * 10_000_000);
            assert!((r.time_s - r.row.index as f64 * 0.01).abs() < 1e-12);
        }
        assert!(p.excluded_terms().iter().all(|&(_, n)| n > 0));
    }

    #[test]
    fn a_non_finite_value_is_left_out_on_its_axis_only() {
        let mut p = Pipeline::new(config(), &[Axis::GyroX, Axis::GyroY], None).unwrap();
        let mut out = Output::default();
        for k in 0..200i64 {
            let mut s = sample(k, k * 10_000_000, 0.0);
            if k == 100 {
                s.gyro[1] = f64::NAN;
            }
            p.push(&s, &mut out);
        }
        p.finish(&mut out);
        assert_eq!(p.irregularities().non_finite, 1);
        let excluded: Vec<(Axis, u64)> = p.excluded_terms();
        assert_eq!(excluded[0], (Axis::GyroX, 0));
        assert!(excluded[1].1 > 0);
        let at = |axis| {
            out.rows
                .iter()
                .find(|r| r.axis == axis && r.row.index == 100)
                .unwrap()
                .row
                .valid_samples
        };
        assert_eq!((at(Axis::GyroX), at(Axis::GyroY)), (31, 30));
    }

    #[test]
    fn same_input_same_output_whatever_the_chunking() {
        let samples: Vec<ImuSample> = (0..400)
            .map(|k| {
                sample(
                    k,
                    1_000 + k * 5_000_000,
                    if (200..260).contains(&k) {
                        5.0 * ((k % 3) as f64 - 1.0)
                    } else {
                        0.0
                    },
                )
            })
            .collect();
        let run = |chunk: usize| {
            let mut p = Pipeline::new(config(), &[Axis::GyroX], None).unwrap();
            let mut all = Output::default();
            for c in samples.chunks(chunk) {
                let mut out = Output::default();
                for s in c {
                    p.push(s, &mut out);
                }
                all.rows.extend(out.rows);
                all.events.extend(out.events);
            }
            p.finish(&mut all);
            all
        };
        let (a, b) = (run(1), run(77));
        assert_eq!(a, b);
        assert!(!a.events.is_empty());
    }

    /// Issue 13: ten ±1e300 samples overflowed the running σ²_ref and left F NaN for the rest of
    /// the run. The intake now places them as missing: every later row has a finite F.
    #[test]
    fn absurd_values_do_not_poison_sigma_ref_or_f() {
        let mut p = Pipeline::new(config(), &[Axis::GyroX], None).unwrap();
        let mut out = Output::default();
        for k in 0..600i64 {
            let mut s = sample(k, k * 10_000_000, 0.0);
            if (100..110).contains(&k) {
                s.gyro[0] = if k % 2 == 0 { 1e300 } else { -1e300 };
            }
            p.push(&s, &mut out);
        }
        let late: Vec<&AxisRow> = out.rows.iter().filter(|r| r.row.index > 200).collect();
        assert!(!late.is_empty());
        for r in late {
            let (f, s2) = (r.row.f.unwrap(), r.row.sigma2_ref.unwrap());
            assert!(f.is_finite() && s2.is_finite() && s2 < 1.0, "{f} {s2}");
        }
        assert_eq!(p.irregularities().non_finite, 10);
    }

    #[test]
    fn record_mode_needs_the_record() {
        let cfg = DavarConfig {
            sigma_ref: SigmaRefMode::Record,
            ..config()
        };
        assert_eq!(
            Pipeline::new(cfg.clone(), &Axis::ALL, None).unwrap_err(),
            PipelineError::RecordVarianceMissing
        );
        let mut vars = [Some(1.0); 6];
        vars[4] = None;
        assert!(matches!(
            Pipeline::new(cfg, &Axis::ALL, Some(vars)),
            Err(PipelineError::RecordVarianceUndefined { axis: Axis::AccelY })
        ));
    }
}
