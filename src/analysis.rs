//! The one analysis path, live and offline: IMU samples in; DAVAR rows, the model's fit and the
//! diagnosis out.
//!
//! ```text
//! ImuSample ─┬─ Pipeline (F value → window policy → DAVAR row; optional)  → rows
//!            └─ RecordBuilder (the whole run on the τ0 grid, bounded)      → fit → diagnosis
//! Temperature ──┘
//! ```
//! Why one type: what a user reads — coefficients with their 1σ, fit_error, failing τ and time
//! spans, suggestions — must be the same numbers whether the node computed them while the robot ran
//! or `fdavar diagnose` computed them from the recording afterwards. Both push the same samples, in
//! the order received, into an [`Analysis`] and ask it the same questions; the node only turns the
//! answers into messages ([`crate::ros`]), the CLI into text and JSON.
//!
//! Both stages place samples with the same [`crate::signal::Intake`] rules (τ0, duplicates,
//! backwards stamps, gaps, NaN). The whole run is the horizon of the fit: the record keeps it all,
//! halving its rate when it grows past [`AnalysisConfig::max_samples`] (see [`crate::model::record`]).
//!
//! A live caller can lend the record to a diagnosis running on another thread ([`Analysis::lend`]):
//! rows go on meanwhile, and the samples the record missed are pushed into it, in order, when it
//! comes back ([`Analysis::give_back`]). Why move the record rather than copy it: a copy is up to
//! 2²⁰ values per axis (about 50 MB for six axes) to take while samples wait, where a move costs
//! nothing and the samples that arrive during a diagnosis (a few thousand at 2 kHz) replay in
//! about a millisecond; the diagnosis reads the very record [`Analysis::diagnose`] would, so the
//! answers are the same, bit for bit.

use crate::model::effects::REGISTRY;
use crate::model::record::{RecordBuilder, RecordError};
use crate::model::diagnose::diagnose_planned;
use crate::model::timedomain::Plans;
use crate::model::{diagnose, fit, Diagnosis, FitError, FitOptions, FittedModel, ModelSpec};
use crate::pipeline::{AxisRow, DavarConfig, Output, Pipeline, PipelineError};
use crate::signal::{Axis, ImuSample, Irregularities, TemperatureSample};

/// How an [`Analysis`] runs.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalysisConfig {
    /// The F-DAVAR settings; `None`: no rows (the CLI's `fit` and `diagnose` need none).
    pub davar: Option<DavarConfig>,
    /// Nominal period τ0 of the whole-run record, seconds; `None`: learned from the stamps.
    pub tau0: Option<f64>,
    /// The model of each axis ([`Axis::ALL`] order).
    pub models: [ModelSpec; 6],
    /// How models are fitted.
    pub fit: FitOptions,
    /// Values per axis the whole-run record keeps before halving its rate.
    pub max_samples: usize,
}

impl AnalysisConfig {
    /// No rows, `model` on every axis, τ0 from the stamps, default fit and memory bound.
    pub fn whole_run(model: &ModelSpec) -> AnalysisConfig {
        AnalysisConfig {
            davar: None,
            tau0: None,
            models: std::array::from_fn(|_| model.clone()),
            fit: FitOptions::default(),
            max_samples: RecordBuilder::DEFAULT_MAX_SAMPLES,
        }
    }

    /// This configuration with F-DAVAR rows on `davar`, the whole run placed on the grid of the
    /// same τ0 as the rows (what the node runs, and `fdavar fit/diagnose --mcap`).
    pub fn with_rows(mut self, davar: DavarConfig) -> AnalysisConfig {
        self.tau0 = davar.tau0;
        self.davar = Some(davar);
        self
    }
}

/// Why an analysis question has no answer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AnalysisError {
    /// No sample period yet (fewer than two distinct stamps so far).
    #[error("no samples on a sample-period grid yet (fewer than two distinct stamps)")]
    NoRecord,
    /// The record stopped growing.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// The model could not be fitted.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// The record is lent to a diagnosis that has not given it back yet ([`Analysis::lend`]).
    #[error("the whole-run record is lent to a diagnosis still running")]
    Lent,
}

/// Samples in, rows and the whole-run model out (see the module doc).
pub struct Analysis {
    rows: Option<Pipeline>,
    out: Output,
    /// The whole-run record; `None` while lent ([`Analysis::lend`]).
    record: Option<RecordBuilder>,
    /// What the record missed while lent, in arrival order.
    deferred: Vec<Deferred>,
    models: [ModelSpec; 6],
    fit: FitOptions,
    messages: u64,
}

/// An input that arrived while the record was lent.
#[derive(Debug, Clone, Copy)]
enum Deferred {
    Imu(ImuSample),
    Temperature(TemperatureSample),
}

/// The whole-run record lent to a diagnosis of one axis, with that axis's model and the fit
/// options as they were when lent ([`Analysis::lend`]); give it back with [`Analysis::give_back`].
#[derive(Debug)]
pub struct Loan {
    record: RecordBuilder,
    axis: Axis,
    model: ModelSpec,
    fit: FitOptions,
    messages: u64,
}

impl Loan {
    /// The axis to diagnose.
    pub fn axis(&self) -> Axis {
        self.axis
    }

    /// IMU messages the record had taken in when lent (the cut `fdavar diagnose --first` makes).
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// Seconds from the first to the last sample in the record.
    pub fn duration_s(&self) -> Option<f64> {
        span_s(&self.record)
    }

    /// [`Analysis::diagnose`] of the lent axis on the lent record: the same answer.
    ///
    /// # Errors
    /// As [`Analysis::diagnose`].
    pub fn diagnose(&mut self) -> Result<Diagnosis, AnalysisError> {
        let rec = laid_out(&mut self.record)?;
        Ok(diagnose(&rec.input(self.axis), &self.model, REGISTRY, &self.fit)?)
    }
}

/// The record's samples laid out for the fitter, or why not.
fn laid_out(record: &mut RecordBuilder) -> Result<&crate::model::record::Recording, AnalysisError> {
    if let Some(e) = record.error() {
        return Err(e.clone().into());
    }
    record.recording().ok_or(AnalysisError::NoRecord)
}

/// Seconds from the first to the last sample placed in `record`.
fn span_s(record: &RecordBuilder) -> Option<f64> {
    Some((record.last_stamp_ns()? - record.first_stamp_ns()?) as f64 * 1e-9)
}

impl std::fmt::Debug for Analysis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Analysis")
            .field("rows", &self.rows)
            .field("models", &self.models)
            .field("messages", &self.messages)
            .finish_non_exhaustive()
    }
}

impl Analysis {
    /// An analysis of all six axes.
    ///
    /// # Errors
    /// [`PipelineError`] when the DAVAR settings cannot run on a stream (e.g.
    /// `sigma_ref.mode: record`, which needs the whole recording first).
    pub fn new(config: AnalysisConfig) -> Result<Analysis, PipelineError> {
        let rows = config
            .davar
            .map(|davar| Pipeline::new(davar, &Axis::ALL, None))
            .transpose()?;
        Ok(Analysis {
            rows,
            out: Output::default(),
            record: Some(RecordBuilder::new(config.tau0, config.max_samples)),
            deferred: Vec::new(),
            models: config.models,
            fit: config.fit,
            messages: 0,
        })
    }

    /// Feeds one IMU message; returns the DAVAR rows it completed (none without DAVAR settings).
    pub fn push(&mut self, sample: &ImuSample) -> &[AxisRow] {
        self.messages += 1;
        match self.record.as_mut() {
            Some(record) => record.push(sample),
            None => self.deferred.push(Deferred::Imu(*sample)),
        }
        self.out.rows.clear();
        self.out.events.clear();
        if let Some(p) = self.rows.as_mut() {
            p.push(sample, &mut self.out);
        }
        &self.out.rows
    }

    /// Moves each row the last [`Analysis::push`] completed into `keep`, in order; a row `keep`
    /// hands back (one it no longer needs) lends its memory to a later row.
    ///
    /// Why: a caller that keeps the latest row of each axis (the node) would otherwise copy every
    /// row, and every row would allocate its points afresh: one row per axis and sample.
    pub fn hand_rows(&mut self, mut keep: impl FnMut(AxisRow) -> Option<AxisRow>) {
        let mut rows = std::mem::take(&mut self.out.rows);
        for row in rows.drain(..) {
            if let (Some(old), Some(p)) = (keep(row), self.rows.as_mut()) {
                p.recycle(old);
            }
        }
        self.out.rows = rows;
    }

    /// Feeds one temperature reading (evidence for the `temperature` effect).
    pub fn push_temperature(&mut self, reading: &TemperatureSample) {
        match self.record.as_mut() {
            Some(record) => record.push_temperature(reading),
            None => self.deferred.push(Deferred::Temperature(*reading)),
        }
    }

    /// Ends the input (a recording): places a short input whose period was never settled. Not
    /// while the record is lent (a live run never ends this way).
    pub fn finish(&mut self) {
        if let Some(record) = self.record.as_mut() {
            record.finish();
        }
    }

    /// IMU messages pushed so far (the cut that makes an offline run equal to a live answer).
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// The input's sample period τ0, s, once known (and while the record is here).
    pub fn sample_period_s(&self) -> Option<f64> {
        self.record.as_ref()?.input_tau0()
    }

    /// The period of the DAVAR rows, once known.
    pub fn row_tau0(&self) -> Option<f64> {
        self.rows.as_ref().and_then(Pipeline::tau0)
    }

    /// Irregularities of the input so far (none counted while the record is lent).
    pub fn irregularities(&self) -> Irregularities {
        self.record
            .as_ref()
            .map(RecordBuilder::irregularities)
            .unwrap_or_default()
    }

    /// Seconds from the first to the last sample placed in the whole-run record (while it is
    /// here).
    pub fn duration_s(&self) -> Option<f64> {
        span_s(self.record.as_ref()?)
    }

    /// Replaces the DAVAR settings: rows restart, on the new settings, half a window later. The
    /// whole-run record does not depend on them and carries on.
    ///
    /// # Errors
    /// As [`Analysis::new`].
    pub fn set_davar(&mut self, davar: DavarConfig) -> Result<(), PipelineError> {
        self.rows = Some(Pipeline::new(davar, &Axis::ALL, None)?);
        Ok(())
    }

    /// The model of `axis`.
    pub fn model(&self, axis: Axis) -> &ModelSpec {
        &self.models[axis.index()]
    }

    /// Sets the model of `axis` (the next fit or diagnosis uses it).
    pub fn set_model(&mut self, axis: Axis, model: ModelSpec) {
        self.models[axis.index()] = model;
    }

    /// The model of `axis` fitted to the whole run so far.
    ///
    /// # Errors
    /// [`AnalysisError`]: no record yet, a gap too long to lay out, or the fit's own errors.
    pub fn fit(&mut self, axis: Axis) -> Result<FittedModel, AnalysisError> {
        let spec = self.models[axis.index()].clone();
        let opts = self.fit;
        let rec = self.recording()?;
        Ok(fit(&rec.input(axis), &spec, REGISTRY, &opts)?)
    }

    /// The model of `axis` fitted to the whole run so far, and the effects it lacks.
    ///
    /// # Errors
    /// As [`Analysis::fit`].
    pub fn diagnose(&mut self, axis: Axis) -> Result<Diagnosis, AnalysisError> {
        // The path a lent record takes, so that the node's answers are these.
        let mut loan = self.lend(axis)?;
        let answer = loan.diagnose();
        self.give_back(loan);
        answer
    }

    /// Lends the whole-run record for a diagnosis of `axis` ([`Loan::diagnose`]) that runs
    /// without this analysis: rows go on, and what the record misses meanwhile waits
    /// ([`Analysis::deferred`]) until [`Analysis::give_back`].
    ///
    /// Why: the node's whole-run diagnosis takes up to seconds; samples must not wait for it
    /// (see the module doc).
    ///
    /// # Errors
    /// [`AnalysisError::Lent`] when the record is lent already.
    pub fn lend(&mut self, axis: Axis) -> Result<Loan, AnalysisError> {
        let record = self.record.take().ok_or(AnalysisError::Lent)?;
        Ok(Loan {
            record,
            axis,
            model: self.models[axis.index()].clone(),
            fit: self.fit,
            messages: self.messages,
        })
    }

    /// Takes back the record [`Analysis::lend`] lent, and pushes into it what it missed, in the
    /// order received: the record is then the one that never left.
    pub fn give_back(&mut self, loan: Loan) {
        let mut record = loan.record;
        for input in self.deferred.drain(..) {
            match input {
                Deferred::Imu(s) => record.push(&s),
                Deferred::Temperature(t) => record.push_temperature(&t),
            }
        }
        self.record = Some(record);
    }

    /// Values per axis in the whole-run record (0 while it is lent, or before the period is
    /// known).
    pub fn record_len(&self) -> usize {
        self.record.as_ref().map_or(0, RecordBuilder::values)
    }

    /// Inputs waiting for the lent record to come back (0 while it is here).
    pub fn deferred(&self) -> usize {
        self.deferred.len()
    }

    /// [`Analysis::diagnose`] of each axis of `axes`, in that order, on up to `threads` threads.
    ///
    /// Why: the axes are independent, so a recording's six diagnoses can share the machine's
    /// cores; each answer is the one [`Analysis::diagnose`] gives alone, bit for bit (every
    /// diagnosis reads the same record and writes nothing shared). The offline tools use this;
    /// the node keeps its own thread budget and diagnoses one axis at a time.
    pub fn diagnose_axes(
        &mut self,
        axes: &[Axis],
        threads: usize,
    ) -> Vec<Result<Diagnosis, AnalysisError>> {
        let (models, opts) = (self.models.clone(), self.fit);
        let rec = match self.recording() {
            Ok(rec) => rec,
            Err(e) => return axes.iter().map(|_| Err(e.clone())).collect(),
        };
        let plans = Plans::default();
        on_threads(axes, threads, |&axis| {
            let input = rec.input(axis);
            Ok(diagnose_planned(&input, &models[axis.index()], REGISTRY, &opts, &plans)?)
        })
    }

    fn recording(&mut self) -> Result<&crate::model::record::Recording, AnalysisError> {
        laid_out(self.record.as_mut().ok_or(AnalysisError::Lent)?)
    }
}

/// `f` of every item of `items` on up to `threads` threads, answers in the items' order.
///
/// Each thread takes the next item not yet taken, so that a slow one (a long candidate search, a
/// long recording) does not hold up the others; the answers are those `f` gives one by one.
///
/// # Panics
/// When `f` panics on some item.
pub fn on_threads<T: Sync, R: Send>(items: &[T], threads: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut done: Vec<(usize, R)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads.clamp(1, items.len().max(1)))
            .map(|_| {
                scope.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(item) = items.get(i) else {
                            return mine;
                        };
                        mine.push((i, f(item)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("a worker thread panicked"))
            .collect()
    });
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, r)| r).collect()
}

/// Gives a diagnosis's memory back when it ends: every buffer of 128 kB or more gets a mapping of
/// its own, returned to the kernel when freed, and the heap's free top is trimmed past 128 kB.
///
/// Why: a whole-run diagnosis works on series as long as the record (up to 2²⁰ values per axis,
/// [`crate::model::record`]), so most of a round's memory is in series-sized buffers whose size
/// follows the record's length. glibc's defaults are the same two 128 kB thresholds, but dynamic:
/// the first series-sized buffer freed raises the mapping threshold to its size (up to 32 MB), and
/// later rounds carve their buffers out of the heap, where the objects that live on between rounds
/// pin the holes they leave. Measured (`cargo bench --bench node_soak -- in-process 24 1800`, RSS
/// between rounds): the heap kept for reuse (mapping threshold 32 MB, no trim) grew from 203.6 MB
/// at 6–16 h to 235.1 MB at 17–24 h; with these fixed thresholds it stays at 105.7 MB from 6 h
/// to 24 h, the record and the node's small objects. Offline, `fdavar analyze` of 24 h at
/// 100 Hz peaks at 139 MB instead of 151 MB, in the same time (15.8 s vs 15.4 s). Setting either
/// threshold turns glibc's dynamic adjustment off; one arena keeps the DDS threads' small objects
/// from opening heaps of their own. Each round pays for fresh pages (0.3 s of system time in the
/// 24 h job). Call it first thing in `main`, before any thread starts; on other allocators it does
/// nothing.
pub fn return_large_buffers_to_kernel() {
    set_malloc_thresholds(128 << 10, 128 << 10, 1);
}

/// Gives the kernel back every whole free page of the heap, also those between live objects
/// (glibc's `malloc_trim(0)`); the node calls it after each diagnosis.
///
/// Why: [`return_large_buffers_to_kernel`] returns the series-sized buffers and the heap's free
/// top, but a round also frees many smaller buffers (per τ, per span, per candidate) among
/// objects that live on (DDS samples, rows), and their pages stayed resident: with the record's
/// cap at 2²⁰ values, the hostile 24 h soak at 25× (`cargo bench --bench node_soak -- hostile
/// 24 1800 25`) held 85.7 MB between rounds at 6–12 h and 92.0 MB at 18–24 h (+7.4 %, after a
/// step between 10 h and 17 h), with the high-water mark flat (168.7, 170.1 MB). On other
/// allocators it does nothing.
pub fn give_back_free_heap_pages() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory of glibc's arenas; it takes each arena's
    // lock as malloc does.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Lets a one-shot command reuse its freed buffers of up to 4 MB: they stay in the heap, and so
/// does up to 8 MB of each arena's free top, instead of each such buffer faulting in fresh pages.
///
/// Why: a diagnosis allocates and frees series-sized buffers many times per axis (transforms,
/// phases, prefix sums). With [`return_large_buffers_to_kernel`]'s 128 kB thresholds each is a
/// mapping of its own whose every page is faulted in and zeroed: `fdavar analyze` of 1 h at
/// 100 Hz (2.9 MB per series) took 88 000 page faults, 0.12–0.15 s of system time in 1.45 s of
/// CPU. Buffers above 4 MB (records of more than 2¹⁹ values, 1.5 h at 100 Hz) still get mappings
/// of their own: in the heap they fragment it (24 h with both thresholds at 32 MB: peak 202 MB
/// instead of 184 MB). The node keeps [`return_large_buffers_to_kernel`]: what it must bound is
/// its memory between rounds, for days.
///
/// Up to one arena per CPU, not the node's one: a command's threads (the axes' diagnoses, the
/// DAVAR rows, the bag reader) allocate all the time, and on one arena they queue for its lock.
/// `perf sched` of `fdavar analyze` of 1 h at 100 Hz showed the two diagnosis threads taking
/// turns of 10–100 µs with a core idle between them; with one arena per CPU (2 here), medians of
/// five interleaved runs: 0.826 → 0.678 s wall, 1.38 → 1.25 s user, 0.078 → 0.036 s system, peak
/// RSS 67.6 → 69.8 MB. Each arena keeps its own free top: with the trim threshold at 32 MB (one
/// arena's before) 24 h at 100 Hz peaked at 164–187 MB in six runs (one arena: 163–166 MB), at
/// 8 MB at 165–172 MB in five, the hour as fast (0.678 against 0.670 s). Call it first thing in
/// `main`, before any thread starts; on other allocators it does nothing.
pub fn reuse_buffers_up_to_4_mb() {
    let cpus = std::thread::available_parallelism().map_or(1, usize::from);
    set_malloc_thresholds(4 << 20, 8 << 20, i32::try_from(cpus).unwrap_or(i32::MAX));
}

/// Sets glibc malloc's mapping and trim thresholds (bytes) and its most arenas (see the callers).
fn set_malloc_thresholds(mapping: i32, trim: i32, arenas: i32) {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets three of glibc malloc's parameters; it is called before the
    // process starts any thread, and a refused value leaves the default in place.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, arenas);
        libc::mallopt(libc::M_MMAP_THRESHOLD, mapping);
        libc::mallopt(libc::M_TRIM_THRESHOLD, trim);
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    let _ = (mapping, trim, arenas);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// 100 Hz white noise on every axis, a temperature reading each second.
    fn input(n: i64) -> Vec<(ImuSample, Option<TemperatureSample>)> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let normal = Normal::new(0.0, 1e-3).unwrap();
        (0..n)
            .map(|k| {
                let stamp_ns = 1_000_000_000 + k * 10_000_000;
                let mut v = [0.0; 6];
                for x in &mut v {
                    *x = normal.sample(&mut rng);
                }
                let sample = ImuSample { stamp_ns, gyro: [v[0], v[1], v[2]], accel: [v[3], v[4], v[5]] };
                let reading = (k % 100 == 0).then_some(TemperatureSample { stamp_ns, celsius: 20.0 + k as f64 * 1e-3 });
                (sample, reading)
            })
            .collect()
    }

    fn push(a: &mut Analysis, input: &[(ImuSample, Option<TemperatureSample>)]) {
        for (s, t) in input {
            a.push(s);
            if let Some(t) = t {
                a.push_temperature(t);
            }
        }
    }

    /// The node lends the record to a diagnosis on another thread while samples keep coming:
    /// the lent diagnosis is that of the samples taken in before, and the record given back,
    /// with what it missed, is the record that never left (the next answers are the same, bit
    /// for bit).
    #[test]
    fn a_lent_record_diagnoses_its_samples_and_comes_back_with_those_it_missed() {
        let model = ModelSpec::parse("N,B,K").unwrap();
        let new = || Analysis::new(AnalysisConfig::whole_run(&model)).unwrap();
        let all = input(6_000);
        let (before, after) = all.split_at(4_000);
        let (mut lending, mut staying, mut cut) = (new(), new(), new());
        push(&mut lending, before);
        push(&mut staying, before);
        push(&mut cut, before);
        let mut loan = lending.lend(Axis::GyroX).unwrap();
        assert_eq!(lending.lend(Axis::GyroY).unwrap_err(), AnalysisError::Lent);
        assert_eq!((loan.axis(), loan.messages()), (Axis::GyroX, 4_000));
        push(&mut lending, after);
        push(&mut staying, after);
        assert_eq!(lending.deferred(), 2_000 + 20);
        assert_eq!(lending.diagnose(Axis::GyroX).unwrap_err(), AnalysisError::Lent);
        assert_eq!(loan.duration_s(), cut.duration_s());
        assert_eq!(loan.diagnose().unwrap(), cut.diagnose(Axis::GyroX).unwrap());
        lending.give_back(loan);
        assert_eq!((lending.deferred(), lending.messages()), (0, 6_000));
        assert_eq!(lending.duration_s(), staying.duration_s());
        assert_eq!(lending.irregularities(), staying.irregularities());
        for axis in [Axis::GyroX, Axis::AccelZ] {
            assert_eq!(lending.diagnose(axis).unwrap(), staying.diagnose(axis).unwrap());
        }
    }
}
