//! The node's analysis state: input checks, counters, staleness, and the messages built from them.
//!
//! Why a type of its own, apart from the ROS plumbing: everything the node decides (what counts as a
//! bad message, when the input is stale, which level each axis gets, what `/diagnostics` and
//! `~/<axis>/state` carry) is a function of the samples pushed in and the time given, so it is
//! tested without DDS. The ROS side only moves messages in and out.
//!
//! Samples reach the F-DAVAR engine through [`RowEngine`]; the engine keeps the latest row of each
//! axis, and the monitor publishes it with the counters.

use crate::model::fit::Failing;
use crate::msgs::builtin_interfaces::Time;
use crate::msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue, Level};
use crate::msgs::fdavar_msgs::AxisState;
use crate::msgs::std_msgs::Header;
/// The whole-run fields of `~/<axis>/state` (see [`RowEngine::lend`]).
pub use crate::results::WholeRun;
use crate::signal::{Axis, ImuSample, PeriodEstimator, StampCheck, StampClass, TemperatureSample};

/// The analysis as the node drives it: samples in, per-axis rows and whole-run answers out.
///
/// Why a trait: the node owns the queue, the counters and the publishing; the engine (the library's
/// [`crate::analysis::Analysis`], the path `fdavar fit/diagnose` run offline) owns the maths. Rows
/// carry their analysis time, which lags the newest sample by half a window.
pub trait RowEngine: Send {
    /// Feeds one checked sample (stamps strictly increasing). The engine keeps the latest row of
    /// each axis ([`RowEngine::latest`]); when `every_row` is given, it also appends there the
    /// state message of each row this sample completed, in order.
    ///
    /// Why not return each row as a message: a row is completed on every axis at every sample,
    /// and the node publishes a few per second; building six messages per sample (their vectors
    /// and strings) cost more than the rows themselves at 2 kHz. Only `dump_json` needs them all.
    fn push(&mut self, sample: &ImuSample, every_row: Option<&mut Vec<AxisState>>);
    /// The state message (row fields filled) of the latest row of `axis`, if any.
    fn latest(&self, axis: Axis) -> Option<AxisState>;
    /// Whether `axis` has a row yet: [`RowEngine::latest`] without building the message.
    fn has_row(&self, axis: Axis) -> bool {
        self.latest(axis).is_some()
    }
    /// Feeds one reading of the temperature topic (only when the node subscribes it).
    fn push_temperature(&mut self, _t: &TemperatureSample) {}
    /// Applies a live parameter change (model, window settings).
    ///
    /// # Errors
    /// A reason when the engine cannot take the value (the node then keeps the old one).
    fn reconfigure(&mut self, change: Change) -> Result<(), String>;

    /// What a diagnosis of `axis` needs, lent out so that it runs on another thread while
    /// samples keep coming in ([`Lent::diagnose`]); `None` when the engine has no whole-run
    /// analysis, or has lent it already. Whatever the engine cannot do without it meanwhile
    /// waits until [`RowEngine::give_back`].
    ///
    /// Why lent rather than run here: a diagnosis is far costlier than a row (one refit per
    /// candidate effect; up to seconds on a long run), and samples that waited behind it made
    /// the node's p99 receive-to-update latency that long (docs/ros.md). The monitor asks every
    /// `diagnosis_period_s`, one axis per publication.
    fn lend(&mut self, _axis: Axis) -> Option<Box<dyn Lent>> {
        None
    }
    /// Takes back what [`RowEngine::lend`] lent.
    fn give_back(&mut self, _lent: Box<dyn Lent>) {}
    /// Values per axis in the whole-run record a diagnosis would be lent now (0: unknown); what
    /// a diagnosis costs is in proportion to it.
    fn record_len(&self) -> usize {
        0
    }
    /// False while the engine holds as many inputs for a lent diagnosis as it may (the caller
    /// then keeps the input until [`RowEngine::give_back`]).
    fn can_take(&self) -> bool {
        true
    }
}

/// A whole-run diagnosis lent out of a [`RowEngine`].
pub trait Lent: Send {
    /// The model fitted to the whole run up to the lending, where it fails and what it lacks:
    /// the answer of `fdavar diagnose` on those samples.
    ///
    /// # Errors
    /// Why there is no answer yet (too few samples, a degenerate record).
    fn diagnose(&mut self) -> Result<WholeRun, String>;
    /// Itself, for the engine that lent it to take back ([`RowEngine::give_back`]).
    fn into_any(self: Box<Self>) -> Box<dyn std::any::Any + Send>;
}

/// A diagnosis the monitor started ([`Monitor::start_diagnosis`]): run it on any thread, then
/// hand what it gives to [`Monitor::finish_diagnosis`].
pub struct DiagnosisJob {
    axis: Axis,
    lent: Box<dyn Lent>,
    /// The record's length when lent ([`RowEngine::record_len`]).
    values: usize,
    /// The monitor's [`Monitor::generation`] when it started.
    generation: u64,
}

/// A diagnosis run: its answer, what it cost, and what goes back to the engine.
pub struct DiagnosisDone {
    axis: Axis,
    values: usize,
    /// `None` after a panic (what it held is not to be trusted).
    lent: Option<Box<dyn Lent>>,
    /// The answer, or the message of the panic the diagnosis raised.
    answer: Result<Result<WholeRun, String>, String>,
    cost_s: f64,
    generation: u64,
}

impl DiagnosisJob {
    /// Runs the diagnosis, timing it; a panic in it (a bug in the analysis) is caught and handed
    /// on, as [`Monitor`] does with the engine's own.
    pub fn run(mut self) -> DiagnosisDone {
        let start = std::time::Instant::now();
        let lent = &mut self.lent;
        let answer = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| lent.diagnose()))
            .map_err(panic_message);
        DiagnosisDone {
            axis: self.axis,
            values: self.values,
            lent: answer.is_ok().then_some(self.lent),
            answer,
            cost_s: start.elapsed().as_secs_f64(),
            generation: self.generation,
        }
    }
}

/// The message a panic was raised with.
fn panic_message(payload: Box<dyn std::any::Any + Send>) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_string())
}

/// A live change for the engine.
#[derive(Debug, Clone, PartialEq)]
pub enum Change {
    /// New DAVAR settings (window policy, F̃, σ²_ref, τ grid, …), already validated.
    Davar(Box<crate::pipeline::DavarConfig>),
    /// A new model spec (comma-separated effects) for every axis (`axis: None`, parameter
    /// `model`) or one axis (`model.<axis>`; an empty spec hands the axis back to `model`).
    Model {
        /// The axis, or all.
        axis: Option<Axis>,
        /// The spec.
        spec: String,
    },
}

/// The kinds of bad input the node meets; each is logged once and counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BadInput {
    /// A NaN or infinite value on some axis.
    NonFinite,
    /// A stamp earlier than the previous one.
    Backwards,
    /// [`crate::signal::REANCHOR_AFTER`] backwards stamps in a row (the clock went back), or a
    /// stamp more than [`crate::signal::MAX_GAP_SAMPLES`] periods ahead (it jumped forward).
    Reanchor,
    /// The same stamp as the previous one.
    Duplicate,
    /// A zero stamp in a stream whose stamps are not zero (dropped).
    ZeroStamp,
    /// A stamp more than 1.5 τ0 after the previous one on the grid.
    Gap,
    /// The measured rate moved more than 20 % from the nominal one.
    RateChange,
    /// The analysis queue was full: samples dropped.
    QueueFull,
}

impl BadInput {
    /// A sentence for the log.
    pub fn describe(self) -> &'static str {
        match self {
            BadInput::NonFinite => {
                "NaN/Inf (or |value| > 1e6) in an IMU message: that axis's sample is dropped"
            }
            BadInput::Backwards => "IMU stamp went backwards: sample dropped",
            BadInput::Reanchor => {
                "IMU clock jumped (back: 50 backwards stamps in a row; or forward: past the \
                 longest gap laid out), re-anchored on the new stamps"
            }
            BadInput::Duplicate => "duplicate IMU stamp: sample dropped",
            BadInput::ZeroStamp => "zero IMU header stamp in a stamped stream: sample dropped",
            BadInput::Gap => {
                "gap in IMU stamps (> 1.5 periods): Allan terms across it are left out"
            }
            BadInput::RateChange => "IMU rate changed by more than 20 % from the nominal rate",
            BadInput::QueueFull => {
                "analysis queue full: IMU samples dropped (input faster than analysis)"
            }
        }
    }
}

/// The share of the input dropped since the last publication (queue full, duplicate, backwards
/// or zero stamps, out of every message offered) above which each axis reports WARN.
///
/// Why 1 %: a healthy stream drops none; a few reordered messages in a second at 100 Hz stay
/// below it, a second publisher or a restarted sensor clock does not. Before, any loss was
/// reported at level OK (a second publisher with an offset clock lost half the messages, issue 13).
pub const DROP_WARN_SHARE: f64 = 0.01;

/// The share of the input dropped since the last publication above which each axis reports
/// ERROR: more than half of what arrives is lost, so the analysis is not of the stream.
pub const DROP_ERROR_SHARE: f64 = 0.5;

/// Counts since start, published as-is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Messages received (before checks).
    pub received: u64,
    /// Samples passed to the engine.
    pub samples: u64,
    /// Samples dropped because the queue was full (counted by the receiver).
    pub drops: u64,
    /// Gaps in the stamps.
    pub gaps: u64,
    /// Duplicated stamps (dropped).
    pub duplicates: u64,
    /// Stamps going backwards (dropped).
    pub backwards: u64,
    /// Times the clock went back for good or jumped forward, and the stamps were re-anchored.
    pub reanchors: u64,
    /// Zero stamps (receive time used).
    pub zero_stamps: u64,
    /// Non-finite values, per axis in [`Axis::ALL`] order.
    pub non_finite: [u64; 6],
    /// Rate changes seen.
    pub rate_changes: u64,
}

/// Settings of the monitor that the node's parameters set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonitorSettings {
    /// No IMU for longer than this (seconds of node time) means stale input: ERROR.
    pub stale_timeout_s: f64,
    /// fit_error or span_fit_error above this is a failing model (over τ or in time): WARN.
    pub fit_error_warn: f64,
    /// Seconds of node time between two diagnoses of each axis (0: no diagnosis).
    pub diagnosis_period_s: f64,
    /// The largest share of one core the diagnosis may take, over any time from the start: a
    /// diagnosis (of one axis) expected to cost C seconds starts once the share has earned C
    /// (wall clock) since what the diagnoses before it spent ([`Monitor::start_diagnosis`]).
    /// 1: only `diagnosis_period_s` and the publications pace them. Default 0.005:
    /// docs/ros.md ("The diagnosis has a CPU budget") says why, and how old an answer gets.
    pub diagnosis_cpu_share: f64,
}

impl Default for MonitorSettings {
    fn default() -> Self {
        MonitorSettings {
            stale_timeout_s: 1.0,
            fit_error_warn: 3.0,
            diagnosis_period_s: 10.0,
            diagnosis_cpu_share: 0.005,
        }
    }
}

/// The node's analysis state (see the module doc).
pub struct Monitor {
    settings: MonitorSettings,
    engine: Option<Box<dyn RowEngine>>,
    period: PeriodEstimator,
    check: Option<StampCheck>,
    last_good_ns: Option<i64>,
    /// Backwards stamps in a row since the last good one (re-anchor at
    /// [`crate::signal::REANCHOR_AFTER`], as the engine's intake does).
    backwards_run: (u32, Option<i64>),
    /// A re-anchor since the last publish (WARN).
    recent_reanchor: bool,
    first_stamp_ns: Option<i64>,
    counters: Counters,
    /// Kinds already logged (each is logged once).
    logged: std::collections::BTreeSet<BadInput>,
    /// Node time of the last message received, ns.
    last_receive_ns: Option<i64>,
    /// Stamps in the current rate window: (first, last, count).
    rate_window: Option<(i64, i64, u64)>,
    rate_hz: Option<f64>,
    frame_id: String,
    /// Bad inputs since the last publish, per axis, for the level.
    recent_non_finite: [u64; 6],
    /// True when the stream's stamps are zero and the receive time stands in (set by the first
    /// message).
    receive_time_stamps: Option<bool>,
    /// Rows kept for [`Monitor::drain_rows`] when recording is on.
    new_rows: Option<Vec<AxisState>>,
    /// The latest whole-run answer of each axis.
    whole_run: [Option<WholeRun>; 6],
    /// What the latest diagnosis of each axis cost, ms of wall time on the thread that ran it.
    diagnosis_ms: [Option<f64>; 6],
    /// Node time the last diagnosis round started, ns.
    last_diagnosis_ns: Option<i64>,
    /// A diagnosis is lent out ([`Monitor::start_diagnosis`]).
    in_flight: bool,
    /// Bumped when a diagnosis running now can no longer be published (a new model, diagnosis
    /// turned off).
    generation: u64,
    /// Axes of the current round still to diagnose (one per publication).
    diagnosis_due: Vec<Axis>,
    /// Diagnosis time the CPU share has earned and the diagnoses not spent, s, as of an instant
    /// (negative: the last cost more than was earned); `None`: the next starts whatever it costs.
    credit: Option<(std::time::Instant, f64)>,
    /// Per axis, the latest diagnosis's cost, s, and the length of the record it ran on (what
    /// the next is expected to cost: [`Monitor::expected_cost`]).
    cost_of: [Option<(f64, usize)>; 6],
    /// The counters at the last publication (the dropped share is of what came since).
    reported: Counters,
    /// Why the engine stopped: the message of the panic it raised. From then on every axis
    /// reports ERROR while the counters, the checks and the publications go on.
    engine_failure: Option<String>,
}

impl Monitor {
    /// A monitor feeding `engine` (None: counters and input checks only, no rows).
    pub fn new(settings: MonitorSettings, engine: Option<Box<dyn RowEngine>>) -> Monitor {
        Monitor {
            settings,
            engine,
            period: PeriodEstimator::new(50),
            check: None,
            last_good_ns: None,
            backwards_run: (0, None),
            recent_reanchor: false,
            first_stamp_ns: None,
            counters: Counters::default(),
            logged: Default::default(),
            last_receive_ns: None,
            rate_window: None,
            rate_hz: None,
            frame_id: String::new(),
            recent_non_finite: [0; 6],
            new_rows: None,
            receive_time_stamps: None,
            whole_run: Default::default(),
            diagnosis_ms: [None; 6],
            last_diagnosis_ns: None,
            in_flight: false,
            generation: 0,
            diagnosis_due: Vec::new(),
            credit: None,
            cost_of: [None; 6],
            reported: Counters::default(),
            engine_failure: None,
        }
    }

    /// Runs `f` on the engine, supervised: a panic in it (a bug in the analysis) stops the engine
    /// instead of the thread, and is kept as the reason every axis then reports ERROR (issue 13:
    /// the node must keep publishing and answering parameters). None without an engine.
    fn supervised<T>(&mut self, f: impl FnOnce(&mut dyn RowEngine) -> T) -> Option<T> {
        let engine = self.engine.as_mut()?;
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(engine.as_mut()))) {
            Ok(v) => Some(v),
            Err(payload) => {
                self.stop_engine(panic_message(payload));
                None
            }
        }
    }

    /// Stops the engine after a panic (`why`: its message).
    fn stop_engine(&mut self, why: String) {
        self.engine = None;
        self.whole_run = Default::default();
        self.diagnosis_due.clear();
        self.engine_failure = Some(why);
    }

    /// Whether the engine takes another input now (see [`RowEngine::can_take`]).
    pub fn can_take(&self) -> bool {
        self.engine.as_ref().is_none_or(|e| e.can_take())
    }

    /// Keeps every new row for [`Monitor::drain_rows`] (the node's `dump_json`).
    pub fn record_rows(&mut self) {
        self.new_rows.get_or_insert_with(Vec::new);
    }

    /// The rows completed since the last call (empty unless [`Monitor::record_rows`] was called).
    pub fn drain_rows(&mut self) -> Vec<AxisState> {
        self.new_rows
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }

    /// Changes the settings (live parameters).
    pub fn set_settings(&mut self, settings: MonitorSettings) {
        if settings.diagnosis_period_s == 0.0 {
            self.whole_run = Default::default();
            self.diagnosis_due.clear();
            self.generation += 1;
        }
        self.settings = settings;
    }

    /// Passes a live parameter change to the engine.
    ///
    /// # Errors
    /// The engine's reason, or that no engine runs.
    pub fn reconfigure(&mut self, change: Change) -> Result<(), String> {
        let new_model = matches!(change, Change::Model { .. });
        if let Some(why) = &self.engine_failure {
            return Err(format!("the analysis stopped after a panic ({why}); restart the node"));
        }
        match self.supervised(|e| e.reconfigure(change)) {
            Some(result) => result?,
            None if self.engine_failure.is_some() => {
                return Err("the analysis panicked applying the change; restart the node".into());
            }
            None => return Err("no F-DAVAR engine in this build".to_string()),
        }
        if new_model {
            // The published fit is the old model's: diagnose the new one at once (a new round,
            // its first axis whatever the budget: the user asked for it).
            self.last_diagnosis_ns = None;
            self.diagnosis_due.clear();
            self.credit = None;
            self.generation += 1;
        }
        Ok(())
    }

    /// Starts the diagnosis of the next axis due, if any, and none is running: a round of all
    /// six axes starts every `diagnosis_period_s` of node time, one axis per call, so that the
    /// diagnoses spread over the publications. The job runs anywhere ([`DiagnosisJob::run`]; the
    /// node: on a thread of its own, so that samples never wait for it) and its answer is
    /// published once handed to [`Monitor::finish_diagnosis`].
    ///
    /// Why a CPU budget besides the period: a diagnosis costs in proportion to the record, up to
    /// its cap of 2²⁰ values per axis (about 0.28 s per axis there, measured: `fdavar diagnose
    /// --jobs 1` of 1.045·10⁶ samples, 2.3 s of CPU, 0.6 s of it reading the bag); six of them
    /// every 10 s would take 17 % of a core once the record is full (after 2.9 h at 100 Hz,
    /// 8.7 min at 2 kHz). So the diagnoses spend a credit that `diagnosis_cpu_share` earns by
    /// the second of wall clock: one expected to cost C (the latest of its axis, scaled by the
    /// record's growth) starts once the credit holds C, and what it really cost is taken off when
    /// it ends. One per publication and a round per period while the record is short, further
    /// apart as it grows.
    ///
    /// Why the credit is earned before it is spent: a diagnosis followed by a rest of its cost
    /// over the share (as before) spent first, so that a window ending after a diagnosis and
    /// before its rest was over saw that diagnosis beyond the share: 0.72 % of a core over 120 s
    /// at 2 kHz with a share of 0.5 % (`cargo bench --bench node_load -- 2000 120`, the latest
    /// diagnosis 0.32 s). Earned first, the share holds over any time from the start, but for
    /// the error of the expectation (and a first diagnosis of a short record, which starts at
    /// once). No more than one diagnosis's worth is kept: a node whose diagnosis was off for an
    /// hour does not then run a burst of them.
    pub fn start_diagnosis(&mut self, now_ns: i64) -> Option<DiagnosisJob> {
        let period = self.settings.diagnosis_period_s;
        if self.engine.is_none() || period <= 0.0 || self.in_flight {
            return None;
        }
        // Due after a period, at start, and when the node's time went backwards (sim time reset).
        let due = self
            .last_diagnosis_ns
            .is_none_or(|t| now_ns < t || (now_ns - t) as f64 * 1e-9 >= period);
        // A round starts once some axis has a row: before that the run is too short to diagnose.
        let any_row = Axis::ALL.iter().any(|&axis| self.has_row(axis));
        if due && any_row && self.diagnosis_due.is_empty() {
            self.last_diagnosis_ns = Some(now_ns);
            self.diagnosis_due = Axis::ALL.iter().rev().copied().collect();
        }
        // Axes still without a row sit this round out.
        while self.diagnosis_due.last().is_some_and(|&axis| !self.has_row(axis)) {
            self.diagnosis_due.pop();
        }
        let &axis = self.diagnosis_due.last()?;
        let values = self.engine.as_ref().map_or(0, |e| e.record_len());
        let expected = self.expected_cost(axis, values);
        let now = std::time::Instant::now();
        let share = self.settings.diagnosis_cpu_share;
        let credit = self
            .credit
            .map_or(expected, |(at, credit)| credit + share * now.duration_since(at).as_secs_f64());
        // A share of 1 is no budget: only the period and the publications pace the diagnoses.
        if share < 1.0 && credit < expected {
            return None;
        }
        self.diagnosis_due.pop();
        let job = self.supervised(|e| e.lend(axis)).flatten().map(|lent| DiagnosisJob {
            axis,
            lent,
            values,
            generation: self.generation,
        });
        if job.is_some() {
            self.credit = Some((now, credit.min(expected)));
        }
        self.in_flight = job.is_some();
        job
    }

    /// What a diagnosis of `axis` on a record of `values` values per axis is expected to cost,
    /// s: the latest of that axis (else the costliest of any axis), scaled by how much the record
    /// grew since, at most twice; 0 before any.
    ///
    /// Why at most twice: a diagnosis costs in proportion to the record above a fixed part; from
    /// the first diagnosis, of a record of a few hundred values, the proportion alone expected
    /// seconds for the next and starved the diagnosis (0.03 % of a core over 120 s at 2 kHz). A
    /// record grows at most twofold between two rounds once it is a period long.
    fn expected_cost(&self, axis: Axis, values: usize) -> f64 {
        let latest = self.cost_of[axis.index()].or_else(|| {
            self.cost_of.iter().flatten().copied().max_by(|a, b| a.0.total_cmp(&b.0))
        });
        latest.map_or(0.0, |(cost, on)| {
            if on > 0 && values > 0 {
                cost * (values as f64 / on as f64).min(2.0)
            } else {
                cost
            }
        })
    }

    /// Takes back a diagnosis [`Monitor::start_diagnosis`] lent out: what it held goes back to
    /// the engine, and its answer is published from now on, unless the model changed or the
    /// diagnosis was turned off meanwhile. A panic in it stops the engine, as one in a row does.
    pub fn finish_diagnosis(&mut self, done: DiagnosisDone) {
        self.in_flight = false;
        // Spent whatever became of the answer.
        let now = std::time::Instant::now();
        let share = self.settings.diagnosis_cpu_share;
        self.credit = Some(self.credit.map_or((now, -done.cost_s), |(at, credit)| {
            (now, credit + share * now.duration_since(at).as_secs_f64() - done.cost_s)
        }));
        self.cost_of[done.axis.index()] = Some((done.cost_s, done.values));
        let answer = match done.answer {
            Ok(answer) => answer,
            Err(why) => {
                if self.engine.is_some() {
                    self.stop_engine(why);
                }
                return;
            }
        };
        if let Some(lent) = done.lent {
            self.supervised(|e| e.give_back(lent));
        }
        if done.generation != self.generation || self.engine.is_none() {
            return;
        }
        let i = done.axis.index();
        // Too short a run keeps the previous answer (none at first).
        if let Ok(answer) = answer {
            self.whole_run[i] = Some(answer);
        }
        self.diagnosis_ms[i] = Some(done.cost_s * 1e3);
    }

    /// The stamps' median interval over the first 50, s, once seen (what a live `tau0` is
    /// checked against).
    pub fn sample_period_s(&self) -> Option<f64> {
        self.period.period()
    }

    /// The counters so far.
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// Records samples the receiver dropped because the queue was full; returns a line to log the
    /// first time.
    pub fn add_drops(&mut self, n: u64) -> Option<&'static str> {
        if n == 0 {
            return None;
        }
        self.counters.drops += n;
        self.note(BadInput::QueueFull)
    }

    fn note(&mut self, kind: BadInput) -> Option<&'static str> {
        self.logged.insert(kind).then(|| kind.describe())
    }

    /// Checks one received IMU sample and feeds the engine; returns the lines to log (each kind once).
    ///
    /// `receive_ns` is the node time at reception (used when the stream's stamps are zero, and
    /// for staleness). Every message reaches the engine, bad ones included: the engine's
    /// [`crate::signal::Intake`] drops and places them exactly as `fdavar diagnose` does with the
    /// recorded messages, so that live and offline see the same input. The checks here only
    /// count and log.
    pub fn push(
        &mut self,
        mut sample: ImuSample,
        frame_id: &str,
        receive_ns: i64,
    ) -> Vec<&'static str> {
        let mut log = Vec::new();
        self.counters.received += 1;
        self.last_receive_ns = Some(receive_ns);
        if self.frame_id != frame_id {
            self.frame_id = frame_id.to_string();
        }
        // The clock of the stream is chosen by its first message: the sensor's stamps, or the
        // receive time when the driver leaves stamps zero (docs/design.md §1). A zero stamp inside a
        // stamped stream cannot be placed on the sensor clock: the engine drops it (it is earlier
        // than every stamp), and it is counted here.
        let by_receive_time = *self.receive_time_stamps.get_or_insert(sample.stamp_ns == 0);
        if by_receive_time {
            sample.stamp_ns = receive_ns;
        }
        if self.classify(&sample, &mut log) {
            self.counters.samples += 1;
        }
        let mut rows = self.new_rows.take();
        let before = rows.as_ref().map_or(0, Vec::len);
        self.supervised(|e| e.push(&sample, rows.as_mut()));
        if let Some(rows) = rows.as_mut() {
            for state in &mut rows[before..] {
                state.header.frame_id.clone_from(&self.frame_id);
            }
        }
        self.new_rows = rows;
        log
    }

    /// Whether the engine has a row of `axis` yet.
    fn has_row(&self, axis: Axis) -> bool {
        self.engine.as_ref().is_some_and(|e| e.has_row(axis))
    }

    /// The engine's latest row of `axis` as a state message, with the stream's frame id.
    fn latest(&self, axis: Axis) -> Option<AxisState> {
        let mut state = self.engine.as_ref()?.latest(axis)?;
        state.header.frame_id.clone_from(&self.frame_id);
        Some(state)
    }

    /// The stream's clock jumped (back for good, or forward past the longest gap): counted, logged
    /// once, WARN at the next publication, and the rate is measured afresh.
    fn reanchor(&mut self, log: &mut Vec<&'static str>) {
        self.counters.reanchors += 1;
        self.recent_reanchor = true;
        log.extend(self.note(BadInput::Reanchor));
        self.rate_window = None;
    }

    /// Counts what is irregular about `sample`; true when it is a good sample (finite values, a
    /// stamp after the previous good one).
    fn classify(&mut self, sample: &ImuSample, log: &mut Vec<&'static str>) -> bool {
        if sample.stamp_ns == 0 {
            self.counters.zero_stamps += 1;
            log.extend(self.note(BadInput::ZeroStamp));
            return false;
        }
        let values = sample.values();
        if values.iter().any(|&v| !crate::signal::is_usable(v)) {
            for (i, &v) in values.iter().enumerate() {
                if !crate::signal::is_usable(v) {
                    self.counters.non_finite[i] += 1;
                    self.recent_non_finite[i] += 1;
                }
            }
            log.extend(self.note(BadInput::NonFinite));
            return false;
        }
        if let Some(last) = self.last_good_ns {
            if sample.stamp_ns == last {
                self.counters.duplicates += 1;
                log.extend(self.note(BadInput::Duplicate));
                return false;
            }
            if sample.stamp_ns < last {
                self.backwards_run =
                    crate::signal::backwards_run(self.backwards_run, sample.stamp_ns);
                if self.backwards_run.0 < crate::signal::REANCHOR_AFTER {
                    self.counters.backwards += 1;
                    log.extend(self.note(BadInput::Backwards));
                    return false;
                }
                // The clock went back for good: start again from this stamp.
                self.reanchor(log);
                self.check = self.period.period().map(StampCheck::new);
            }
        }
        self.backwards_run = (0, None);
        let period = self.period.push(sample.stamp_ns);
        if let (None, Some(p)) = (&self.check, period) {
            let mut check = StampCheck::new(p);
            if let Some(last) = self.last_good_ns {
                check.check(last);
            }
            self.check = Some(check);
        }
        match self.check.as_mut().map(|c| c.check(sample.stamp_ns)) {
            Some(StampClass::Gap { .. }) => {
                self.counters.gaps += 1;
                log.extend(self.note(BadInput::Gap));
            }
            // Forward past MAX_GAP_SAMPLES (a backwards re-anchor was handled above).
            Some(StampClass::Reanchored { .. }) => self.reanchor(log),
            _ => {}
        }
        self.last_good_ns = Some(sample.stamp_ns);
        self.first_stamp_ns.get_or_insert(sample.stamp_ns);
        self.rate_window = Some(match self.rate_window {
            None => (sample.stamp_ns, sample.stamp_ns, 1),
            Some((first, _, n)) => (first, sample.stamp_ns, n + 1),
        });
        true
    }

    /// Feeds one reading of the temperature topic to the engine (the live temperature
    /// coefficient).
    pub fn push_temperature(&mut self, t: &TemperatureSample) {
        self.supervised(|e| e.push_temperature(t));
    }

    /// Closes the current rate window: updates `rate_hz` and detects a rate change.
    fn close_rate_window(&mut self) -> Option<&'static str> {
        let (first, last, n) = self.rate_window.take()?;
        if n < 3 || last <= first {
            return None;
        }
        let rate = (n - 1) as f64 / ((last - first) as f64 * 1e-9);
        self.rate_hz = Some(rate);
        let nominal = 1.0 / self.check.as_ref()?.period_s();
        if (rate / nominal - 1.0).abs() > 0.2 {
            self.counters.rate_changes += 1;
            return self.note(BadInput::RateChange);
        }
        None
    }

    /// Diagnoses the next axis due, here and now ([`Monitor::start_diagnosis`], run, finished),
    /// then builds the messages ([`Monitor::publication`]): for a caller with no thread to
    /// spare (in-process replays and tests).
    pub fn report(
        &mut self,
        now_ns: i64,
    ) -> (DiagnosticArray, Vec<AxisState>, Option<&'static str>) {
        if let Some(job) = self.start_diagnosis(now_ns) {
            let done = job.run();
            self.finish_diagnosis(done);
        }
        self.publication(now_ns)
    }

    /// Builds `/diagnostics` and the latest `~/<axis>/state` messages at node time `now_ns`, with
    /// the latest whole-run answers.
    ///
    /// Also returns a line to log when the rate changed.
    pub fn publication(
        &mut self,
        now_ns: i64,
    ) -> (DiagnosticArray, Vec<AxisState>, Option<&'static str>) {
        let log = self.close_rate_window();
        let stale = match self.last_receive_ns {
            None => Some("no IMU message received yet".to_string()),
            Some(t) if (now_ns - t) as f64 * 1e-9 > self.settings.stale_timeout_s => Some(format!(
                "stale input: no IMU message for {:.1} s (> stale_timeout_s {})",
                (now_ns - t) as f64 * 1e-9,
                self.settings.stale_timeout_s
            )),
            Some(_) => None,
        };
        let c = self.counters;
        let loss = input_loss(&self.reported, &c);
        self.reported = c;
        let mut status = Vec::with_capacity(6);
        let mut states = Vec::new();
        for axis in Axis::ALL {
            let i = axis.index();
            // The latest row, with the latest whole-run answer of its axis.
            let fitted = self.latest(axis).map(|mut s| {
                if let Some(w) = &self.whole_run[i] {
                    w.fill(&mut s);
                }
                s
            });
            let latest = fitted.as_ref();
            let mut values = vec![
                KeyValue::new("received", c.received),
                KeyValue::new("samples", c.samples),
                KeyValue::new("drops", c.drops),
                KeyValue::new("gaps", c.gaps),
                KeyValue::new("duplicates", c.duplicates),
                KeyValue::new("backwards", c.backwards),
                KeyValue::new("reanchors", c.reanchors),
                KeyValue::new("non_finite", c.non_finite[i]),
                KeyValue::new("zero_stamps", c.zero_stamps),
                KeyValue::new("rate_changes", c.rate_changes),
                KeyValue::new(
                    "rate_hz",
                    self.rate_hz.map_or("".to_string(), |r| format!("{r:.3}")),
                ),
            ];
            values.push(KeyValue::new("dropped_share", format!("{:.4}", loss.share)));
            if let Some(ms) = self.diagnosis_ms[i] {
                values.push(KeyValue::new("diagnosis_ms", format!("{ms:.3}")));
            }
            let (level, message) = if let Some(why) = &self.engine_failure {
                (
                    Level::Error,
                    format!(
                        "analysis stopped: it panicked ({why}); counting goes on, restart the node"
                    ),
                )
            } else if let Some(why) = &stale {
                (Level::Error, why.clone())
            } else if self.recent_non_finite[i] > 0 && latest.is_none() {
                (
                    Level::Error,
                    "broken input: non-finite values on this axis".to_string(),
                )
            } else if let Some(s) = latest {
                values.extend([
                    KeyValue::new("window_length", s.window_length),
                    KeyValue::new("f_value", s.f_value),
                    KeyValue::new("f_reference", s.f_reference),
                    KeyValue::new("fit_error", s.fit_error),
                    KeyValue::new("span_fit_error", s.span_fit_error),
                    KeyValue::new("analysis_time_s", s.analysis_time_s),
                ]);
                // Only where the fit widened its intervals for heavy tails, as the JSON.
                if s.rate_excess_kurtosis > 0.0 {
                    values.push(KeyValue::new("rate_excess_kurtosis", s.rate_excess_kurtosis));
                }
                values.push(KeyValue::new("model", s.model.join(",")));
                for coef in &s.coefficients {
                    values.push(KeyValue::new(
                        &format!("{}.{} [{}]", coef.effect, coef.name, coef.unit),
                        coef.value,
                    ));
                    if coef.sigma.is_finite() {
                        values.push(KeyValue::new(
                            &format!("{}.{}.sigma [{}]", coef.effect, coef.name, coef.unit),
                            coef.sigma,
                        ));
                    }
                }
                let spans: Vec<String> = s
                    .failing_spans
                    .iter()
                    .map(|t| format!("{:.1}-{:.1} s", t.start_s, t.end_s))
                    .collect();
                values.push(KeyValue::new("failing_spans", spans.join(",")));
                values.push(KeyValue::new("diagnosed_messages", s.diagnosed_messages));
                let suggestions: Vec<&str> =
                    s.suggestions.iter().map(|x| x.effect.as_str()).collect();
                values.push(KeyValue::new("suggestions", suggestions.join(",")));
                // NaN (not diagnosed yet, or no span checked) fails nothing.
                let failing = Failing::at(self.settings.fit_error_warn, s.fit_error, Some(s.span_fit_error));
                if failing == Some(Failing::OverTau) {
                    (
                        Level::Warn,
                        format!(
                            "model fails over the whole run: fit_error {:.2}; suggestions: [{}]",
                            s.fit_error,
                            suggestions.join(", ")
                        ),
                    )
                } else if failing == Some(Failing::InTime) {
                    (
                        Level::Warn,
                        format!(
                            "model fails in time: span_fit_error {:.2} (spans {}); suggestions: [{}]",
                            s.span_fit_error,
                            spans.join(","),
                            suggestions.join(", ")
                        ),
                    )
                } else if let Some(best) = s.suggestions.first() {
                    (
                        Level::Warn,
                        format!(
                            "model lacks {} over the whole run (whole-run fit_error {:.2} with \
                             it); suggestions: [{}]",
                            best.effect,
                            best.fit_error_after,
                            suggestions.join(", ")
                        ),
                    )
                } else if s.f_reference.is_finite() && s.f_value > 3.0 * s.f_reference {
                    (
                        Level::Warn,
                        format!(
                            "noise changed: F {:.2} > 3 F̃ ({:.2})",
                            s.f_value, s.f_reference
                        ),
                    )
                } else if self.recent_non_finite[i] > 0 {
                    (
                        Level::Warn,
                        "non-finite or out-of-range values on this axis were dropped".to_string(),
                    )
                } else if self.recent_reanchor {
                    (
                        Level::Warn,
                        "IMU clock jumped: stamps re-anchored".to_string(),
                    )
                } else {
                    (Level::Ok, "ok".to_string())
                }
            } else {
                (
                    Level::Ok,
                    "collecting samples (no analysis row yet)".to_string(),
                )
            };
            // Lost input raises the level (the analysis is then of part of the stream only).
            let (level, message) = match loss.verdict() {
                Some((l, why)) if l > level => (l, why),
                Some((l, why)) if l == level && level != Level::Ok => {
                    (level, format!("{message}; {why}"))
                }
                _ => (level, message),
            };
            status.push(DiagnosticStatus {
                level: level as u8,
                name: format!("fdavar: {axis}"),
                message,
                hardware_id: self.frame_id.clone(),
                values,
            });
            if let Some(mut s) = fitted {
                s.samples = c.samples;
                s.drops = c.drops;
                s.gaps = c.gaps;
                states.push(s);
            }
        }
        self.recent_non_finite = [0; 6];
        self.recent_reanchor = false;
        let array = DiagnosticArray {
            header: Header {
                // A node time past 2038 cannot be a ROS Time: publish zero rather than fail.
                stamp: Time::from_ns(now_ns).unwrap_or_default(),
                frame_id: String::new(),
            },
            status,
        };
        (array, states, log)
    }
}

/// What was dropped of the input between two publications.
#[derive(Debug, Clone, Copy)]
struct InputLoss {
    /// Messages dropped (queue full, duplicate, backwards or zero stamp).
    dropped: u64,
    /// Messages offered: received plus dropped by the full queue.
    offered: u64,
    /// dropped / offered, 0 when nothing came.
    share: f64,
}

/// The loss between the counters `before` (the last publication) and `now`.
fn input_loss(before: &Counters, now: &Counters) -> InputLoss {
    let dropped = |c: &Counters| c.drops + c.duplicates + c.backwards + c.zero_stamps;
    let offered = |c: &Counters| c.received + c.drops;
    let (dropped, offered) = (dropped(now) - dropped(before), offered(now) - offered(before));
    let share = if offered > 0 {
        dropped as f64 / offered as f64
    } else {
        0.0
    };
    InputLoss { dropped, offered, share }
}

impl InputLoss {
    /// ERROR above [`DROP_ERROR_SHARE`], WARN above [`DROP_WARN_SHARE`], with the reason.
    fn verdict(&self) -> Option<(Level, String)> {
        let level = if self.share > DROP_ERROR_SHARE {
            Level::Error
        } else if self.share > DROP_WARN_SHARE {
            Level::Warn
        } else {
            return None;
        };
        let limit = if level == Level::Error {
            DROP_ERROR_SHARE
        } else {
            DROP_WARN_SHARE
        };
        Some((
            level,
            format!(
                "input lost: {} of {} IMU messages since the last report dropped ({:.1} % > {} %; \
                 see drops, duplicates, backwards, zero_stamps)",
                self.dropped,
                self.offered,
                100.0 * self.share,
                100.0 * limit
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::fdavar_msgs::Suggestion;

    const MS: i64 = 1_000_000;

    fn sample(stamp_ns: i64, v: f64) -> ImuSample {
        ImuSample {
            stamp_ns,
            gyro: [v, 0.0, 0.0],
            accel: [0.0, 0.0, 9.81],
        }
    }

    fn level(array: &DiagnosticArray, axis: usize) -> u8 {
        array.status[axis].level
    }

    fn value<'a>(array: &'a DiagnosticArray, axis: usize, key: &str) -> &'a str {
        &array.status[axis]
            .values
            .iter()
            .find(|kv| kv.key == key)
            .unwrap()
            .value
    }

    /// The latest state of each axis, kept as an engine keeps its rows (for the test engines).
    #[derive(Default)]
    struct Kept([Option<AxisState>; 6]);
    impl Kept {
        fn keep(&mut self, made: Vec<(Axis, AxisState)>, every_row: Option<&mut Vec<AxisState>>) {
            if let Some(rows) = every_row {
                rows.extend(made.iter().map(|(_, s)| s.clone()));
            }
            for (axis, state) in made {
                self.0[axis.index()] = Some(state);
            }
        }
    }

    /// One engine row per sample, so that the tests see what reaches the engine.
    #[derive(Default)]
    struct Echo(Kept);
    impl RowEngine for Echo {
        fn push(&mut self, s: &ImuSample, every_row: Option<&mut Vec<AxisState>>) {
            let state = AxisState {
                axis: "gyro_x".into(),
                analysis_time_s: s.stamp_ns as f64 * 1e-9,
                window_length: 171,
                f_value: 1.0,
                f_reference: 1.0,
                fit_error: 1.0,
                ..AxisState::default()
            };
            self.0.keep(vec![(Axis::GyroX, state)], every_row);
        }
        fn latest(&self, axis: Axis) -> Option<AxisState> {
            self.0 .0[axis.index()].clone()
        }
        fn reconfigure(&mut self, _: Change) -> Result<(), String> {
            Ok(())
        }
    }

    #[test]
    fn each_bad_input_kind_is_counted_and_logged_once() {
        let mut m = Monitor::new(MonitorSettings::default(), Some(Box::new(Echo::default())));
        m.record_rows();
        let mut logged = Vec::new();
        let mut t = 0;
        for _ in 0..100 {
            t += 10 * MS;
            logged.extend(m.push(sample(t, 0.1), "imu", t));
        }
        assert!(logged.is_empty(), "{logged:?}");
        for _ in 0..2 {
            logged.extend(m.push(sample(t + 5 * MS, f64::NAN), "imu", t)); // non-finite
            logged.extend(m.push(sample(t, 0.1), "imu", t)); // duplicate
            logged.extend(m.push(sample(t - 50 * MS, 0.1), "imu", t)); // backwards
            logged.extend(m.push(sample(0, 0.1), "imu", t + 10 * MS)); // zero stamp: dropped
            t += 10 * MS;
            t += 100 * MS; // gap
            logged.extend(m.push(sample(t, 0.1), "imu", t));
        }
        let c = m.counters();
        assert_eq!(c.non_finite[0], 2);
        assert_eq!(c.duplicates, 2);
        assert_eq!(c.backwards, 2);
        assert_eq!(c.zero_stamps, 2);
        assert_eq!(c.gaps, 2);
        assert_eq!(logged.len(), 5, "each kind once: {logged:?}");
        // 100 + 2 after gaps were good; every message reached the engine (its intake drops the
        // bad ones as `fdavar diagnose` does): 110.
        assert_eq!(c.samples, 102);
        assert_eq!(m.drain_rows().len(), 110);
        assert!(m.drain_rows().is_empty());
    }

    /// Issue 13: after the publisher restarted with older stamps the node counted every later
    /// sample as backwards, forever, with status "ok". Now it re-anchors after 50 in a row, as the
    /// engine's intake does, logs it once and reports WARN at the next publication.
    #[test]
    fn a_clock_that_goes_back_re_anchors_with_a_warning() {
        let mut m = Monitor::new(MonitorSettings::default(), Some(Box::new(Echo::default())));
        let mut logged = Vec::new();
        let mut t = 1_000 * MS;
        for _ in 0..100 {
            t += 10 * MS;
            logged.extend(m.push(sample(t, 0.1), "imu", t));
        }
        let (a, _, _) = m.report(t);
        assert_eq!(level(&a, 0), Level::Ok as u8, "{a:?}");
        for k in 1..=200 {
            logged.extend(m.push(sample(k * 10 * MS, 0.1), "imu", t + k * 10 * MS));
        }
        let c = m.counters();
        assert_eq!((c.backwards, c.reanchors), (49, 1));
        assert_eq!(c.samples, 100 + 151);
        assert!(
            logged.iter().any(|l| l.contains("re-anchored")),
            "{logged:?}"
        );
        let (a, _, _) = m.report(t + 2_000 * MS);
        assert_eq!(level(&a, 0), Level::Warn as u8, "{a:?}");
        assert!(a.status[0].message.contains("clock jumped"), "{a:?}");
        assert_eq!(value(&a, 0, "reanchors"), "1");
        let (a, _, _) = m.report(t + 2_000 * MS);
        assert_eq!(level(&a, 0), Level::Ok as u8, "one warning per re-anchor");
    }

    /// Issue 13: a clock that jumps forward further than the longest gap laid out (here 2²² periods,
    /// 11.7 h at 100 Hz) re-anchors as one that went back: counted, WARN once, nothing dropped.
    #[test]
    fn a_clock_that_jumps_forward_re_anchors_with_a_warning() {
        let mut m = Monitor::new(MonitorSettings::default(), Some(Box::new(Echo::default())));
        let mut t = 1_000 * MS;
        for _ in 0..100 {
            t += 10 * MS;
            m.push(sample(t, 0.1), "imu", t);
        }
        t += (1 << 22) * 10 * MS;
        for _ in 0..100 {
            t += 10 * MS;
            m.push(sample(t, 0.1), "imu", t);
        }
        let c = m.counters();
        assert_eq!((c.reanchors, c.gaps, c.backwards, c.samples), (1, 0, 0, 200));
        let (a, _, _) = m.report(t);
        assert_eq!(level(&a, 0), Level::Warn as u8, "{a:?}");
        assert!(a.status[0].message.contains("clock jumped"), "{a:?}");
    }

    /// Issue 13: ±1e300 values count as dropped values (WARN), like NaN.
    #[test]
    fn absurd_values_are_counted_like_non_finite_ones() {
        let mut m = Monitor::new(MonitorSettings::default(), Some(Box::new(Echo::default())));
        let mut t = 0;
        for k in 0..100 {
            t += 10 * MS;
            let v = if k % 10 == 0 {
                1e300 * (-1f64).powi(k)
            } else {
                0.1
            };
            m.push(sample(t, v), "imu", t);
        }
        assert_eq!(m.counters().non_finite[0], 10);
        let (a, _, _) = m.report(t);
        assert_eq!(level(&a, 0), Level::Warn as u8, "{a:?}");
        assert!(a.status[0].message.contains("out-of-range"), "{a:?}");
    }

    /// Issue 13: a second publisher whose clock is 10 s behind lost every message of its own as
    /// backwards at level OK; zero stamps inside a stamped stream were dropped at level OK. Now
    /// the share dropped since the last publication sets WARN (> 1 %) or ERROR (> 50 %), and a
    /// clean stream afterwards is OK again.
    #[test]
    fn dropped_input_above_its_share_warns_or_errs_and_clears() {
        let mut m = Monitor::new(MonitorSettings::default(), Some(Box::new(Echo::default())));
        let mut t = 1_000_000 * MS;
        let good = |m: &mut Monitor, t: &mut i64, n: usize| {
            for _ in 0..n {
                *t += 10 * MS;
                m.push(sample(*t, 0.1), "imu", *t);
            }
        };
        good(&mut m, &mut t, 100);
        let (a, _, _) = m.report(t);
        assert_eq!((level(&a, 0), value(&a, 0, "dropped_share")), (Level::Ok as u8, "0.0000"));
        // Two publishers, one each 10 ms, the second's clock 10 s behind: half is backwards.
        for _ in 0..100 {
            t += 10 * MS;
            m.push(sample(t, 0.1), "imu", t);
            m.push(sample(t - 10_000 * MS, 0.1), "imu", t);
        }
        let (a, _, _) = m.report(t);
        assert_eq!(m.counters().backwards, 100);
        assert_eq!(value(&a, 0, "dropped_share"), "0.5000");
        for i in 0..6 {
            assert_eq!(level(&a, i), Level::Warn as u8, "{:?}", a.status[i]);
            assert!(
                a.status[i].message.contains("input lost: 100 of 200 IMU messages"),
                "{:?}",
                a.status[i]
            );
        }
        // Zero stamps inside the stamped stream: 3 of every 4 messages.
        for _ in 0..100 {
            for _ in 0..3 {
                m.push(sample(0, 0.1), "imu", t);
            }
            good(&mut m, &mut t, 1);
        }
        let (a, _, _) = m.report(t);
        assert_eq!(m.counters().zero_stamps, 300);
        assert_eq!(level(&a, 0), Level::Error as u8, "{:?}", a.status[0]);
        assert!(a.status[0].message.contains("300 of 400"), "{:?}", a.status[0]);
        assert_eq!(value(&a, 0, "dropped_share"), "0.7500");
        // Queue drops count too (offered = received + drops): 2 of 102 is over 1 %.
        good(&mut m, &mut t, 100);
        m.add_drops(2);
        let (a, _, _) = m.report(t);
        assert_eq!(level(&a, 0), Level::Warn as u8, "{:?}", a.status[0]);
        assert!(a.status[0].message.contains("2 of 102"), "{:?}", a.status[0]);
        // One reordered message in 200 is not a loss worth a warning; nothing lost is OK.
        good(&mut m, &mut t, 199);
        m.push(sample(t - 5 * MS, 0.1), "imu", t);
        let (a, _, _) = m.report(t);
        assert_eq!((level(&a, 0), value(&a, 0, "dropped_share")), (Level::Ok as u8, "0.0050"));
        good(&mut m, &mut t, 100);
        let (a, states, _) = m.report(t);
        assert_eq!((level(&a, 0), a.status[0].message.as_str()), (Level::Ok as u8, "ok"));
        assert_eq!(states.len(), 1, "still publishing the analysis");
    }

    /// Panics on the `at`th sample pushed, and in `diagnose`.
    struct PanicsAt(u64, Echo);
    impl RowEngine for PanicsAt {
        fn push(&mut self, s: &ImuSample, every_row: Option<&mut Vec<AxisState>>) {
            self.0 -= 1;
            assert!(self.0 > 0, "engine bug at stamp {}", s.stamp_ns);
            self.1.push(s, every_row);
        }
        fn latest(&self, axis: Axis) -> Option<AxisState> {
            self.1.latest(axis)
        }
        fn reconfigure(&mut self, _: Change) -> Result<(), String> {
            Ok(())
        }
    }

    /// Issue 13: a panic in the analysis killed the node's analysis thread (publications stopped).
    /// Supervised, it stops the engine only: every axis reports ERROR with the panic's message,
    /// the counters and publications go on, and a live change is answered with the reason.
    #[test]
    fn a_panicking_engine_is_reported_as_error_and_the_monitor_keeps_serving() {
        let mut m = Monitor::new(MonitorSettings::default(), Some(Box::new(PanicsAt(150, Echo::default()))));
        let mut t = 0;
        for _ in 0..100 {
            t += 10 * MS;
            m.push(sample(t, 0.1), "imu", t);
        }
        let (a, states, _) = m.report(t);
        assert_eq!((level(&a, 0), states.len()), (Level::Ok as u8, 1));
        for _ in 0..100 {
            t += 10 * MS;
            m.push(sample(t, 0.1), "imu", t);
        }
        let (a, states, _) = m.report(t);
        assert!(states.is_empty(), "no rows from a stopped engine");
        for i in 0..6 {
            assert_eq!(level(&a, i), Level::Error as u8, "{:?}", a.status[i]);
            let message = &a.status[i].message;
            let want = "analysis stopped: it panicked (engine bug at stamp 1500000000)";
            assert!(message.starts_with(want), "{message}");
        }
        assert_eq!(value(&a, 0, "samples"), "200");
        let refused = m.reconfigure(Change::Model { axis: None, spec: "N".into() });
        assert!(refused.unwrap_err().contains("engine bug at stamp 1500000000"));
        t += 10 * MS;
        m.push(sample(t, 0.1), "imu", t);
        let (a, _, _) = m.report(t + 100 * MS);
        assert_eq!((level(&a, 0), value(&a, 0, "samples")), (Level::Error as u8, "201"));
    }

    /// A diagnosis that panics on the diagnosis thread: caught there, and once handed back the
    /// engine stops as after a panic in a row (every axis ERROR with the message).
    #[test]
    fn a_panicking_diagnosis_stops_the_engine_as_a_panicking_row_does() {
        struct Panics;
        impl Lent for Panics {
            fn diagnose(&mut self) -> Result<WholeRun, String> {
                panic!("diagnosis bug")
            }
            fn into_any(self: Box<Self>) -> Box<dyn std::any::Any + Send> {
                self
            }
        }
        struct LendsPanics(Echo);
        impl RowEngine for LendsPanics {
            fn push(&mut self, s: &ImuSample, every_row: Option<&mut Vec<AxisState>>) {
                self.0.push(s, every_row);
            }
            fn latest(&self, axis: Axis) -> Option<AxisState> {
                self.0.latest(axis)
            }
            fn reconfigure(&mut self, _: Change) -> Result<(), String> {
                Ok(())
            }
            fn lend(&mut self, _: Axis) -> Option<Box<dyn Lent>> {
                Some(Box::new(Panics))
            }
        }
        let mut m = Monitor::new(MonitorSettings::default(), Some(Box::new(LendsPanics(Echo::default()))));
        let mut t = 0;
        for _ in 0..10 {
            t += 10 * MS;
            m.push(sample(t, 0.1), "imu", t);
        }
        let job = m.start_diagnosis(t).expect("a round starts once rows exist");
        let done = std::thread::spawn(move || job.run()).join().expect("the panic is caught");
        m.finish_diagnosis(done);
        let (a, states, _) = m.publication(t);
        assert!(states.is_empty(), "no rows from a stopped engine");
        let message = &a.status[0].message;
        assert!(message.starts_with("analysis stopped: it panicked (diagnosis bug)"), "{message}");
        assert_eq!(value(&a, 0, "samples"), "10");
    }

    #[test]
    fn a_stream_of_zero_stamps_runs_on_the_receive_time() {
        let mut m = Monitor::new(MonitorSettings::default(), None);
        for k in 1..=100 {
            assert!(m.push(sample(0, 0.0), "imu", k * 10 * MS).is_empty());
        }
        let c = m.counters();
        assert_eq!((c.samples, c.zero_stamps, c.duplicates), (100, 0, 0));
    }

    #[test]
    fn silence_turns_every_axis_error_and_data_clears_it() {
        let mut m = Monitor::new(MonitorSettings::default(), None);
        let (a, _, _) = m.report(0);
        assert!((0..6).all(|i| level(&a, i) == Level::Error as u8));
        let mut t = 0;
        for _ in 0..200 {
            t += 5 * MS;
            m.push(sample(t, 0.0), "imu_link", t);
        }
        let (a, states, _) = m.report(t + 100 * MS);
        assert!((0..6).all(|i| level(&a, i) == Level::Ok as u8), "{a:?}");
        assert!(states.is_empty(), "no engine, no rows");
        assert_eq!(a.status[3].name, "fdavar: accel_x");
        assert_eq!(a.status[0].hardware_id, "imu_link");
        assert_eq!(value(&a, 0, "rate_hz"), "200.000");
        assert_eq!(value(&a, 0, "samples"), "200");
        let (a, _, _) = m.report(t + 1_500 * MS);
        assert_eq!(level(&a, 0), Level::Error as u8);
        assert!(
            a.status[0].message.contains("stale"),
            "{}",
            a.status[0].message
        );
    }

    #[test]
    fn drops_and_rate_changes_are_counted() {
        let mut m = Monitor::new(MonitorSettings::default(), None);
        let mut t = 0;
        for _ in 0..100 {
            t += 10 * MS;
            m.push(sample(t, 0.0), "imu", t);
        }
        m.report(t);
        assert_eq!(m.add_drops(5), Some(BadInput::QueueFull.describe()));
        assert!(m.add_drops(5).is_none(), "logged once");
        for _ in 0..100 {
            t += MS; // 10× faster
            m.push(sample(t, 0.0), "imu", t);
        }
        let (a, _, line) = m.report(t);
        assert_eq!(line, Some(BadInput::RateChange.describe()));
        assert_eq!(value(&a, 0, "drops"), "10");
        assert_eq!(value(&a, 0, "rate_changes"), "1");
    }

    #[test]
    fn rows_carry_the_counters_and_set_the_level() {
        let mut m = Monitor::new(MonitorSettings::default(), Some(Box::new(Echo::default())));
        let mut t = 0;
        for _ in 0..10 {
            t += 10 * MS;
            m.push(sample(t, 0.0), "imu", t);
        }
        let (a, states, _) = m.report(t);
        assert_eq!(states.len(), 1);
        assert_eq!(states[0].samples, 10);
        assert_eq!(states[0].header.frame_id, "imu");
        assert_eq!(value(&a, 0, "window_length"), "171");
        assert_eq!(level(&a, 0), Level::Ok as u8);
    }

    /// Rows on every axis; a diagnosis that names `sinusoid` on gyro_x and counts its calls.
    /// The second field is what each diagnosis costs (a sleep).
    struct Diagnosing(
        std::sync::Arc<std::sync::Mutex<Vec<Axis>>>,
        std::time::Duration,
        Kept,
    );
    impl RowEngine for Diagnosing {
        fn push(&mut self, s: &ImuSample, every_row: Option<&mut Vec<AxisState>>) {
            let made = Axis::ALL
                .iter()
                .map(|&a| {
                    let state = AxisState {
                        axis: a.name().into(),
                        analysis_time_s: s.stamp_ns as f64 * 1e-9,
                        fit_error: 1.0,
                        ..AxisState::default()
                    };
                    (a, state)
                })
                .collect();
            self.2.keep(made, every_row);
        }
        fn latest(&self, axis: Axis) -> Option<AxisState> {
            self.2 .0[axis.index()].clone()
        }
        fn reconfigure(&mut self, _: Change) -> Result<(), String> {
            Ok(())
        }
        fn lend(&mut self, axis: Axis) -> Option<Box<dyn Lent>> {
            Some(Box::new(DiagnosingLent(self.0.clone(), self.1, axis)))
        }
    }
    /// What [`Diagnosing`] lends: the calls, the cost, the axis.
    struct DiagnosingLent(
        std::sync::Arc<std::sync::Mutex<Vec<Axis>>>,
        std::time::Duration,
        Axis,
    );
    impl Lent for DiagnosingLent {
        fn into_any(self: Box<Self>) -> Box<dyn std::any::Any + Send> {
            self
        }
        fn diagnose(&mut self) -> Result<WholeRun, String> {
            let axis = self.2;
            self.0.lock().unwrap().push(axis);
            std::thread::sleep(self.1);
            let suggestions = if axis == Axis::GyroX {
                vec![Suggestion {
                    effect: "sinusoid".into(),
                    fit_error_after: 0.9,
                    ..Suggestion::default()
                }]
            } else {
                Vec::new()
            };
            // gyro_y's noise heavy-tailed: the fit widened its intervals for it.
            let rate_excess_kurtosis = if axis == Axis::GyroY { 116.5 } else { 0.0 };
            // gyro_z's whole-run curve fits, its spans do not: a model failing in time.
            let span_fit_error = if axis == Axis::GyroZ { 5.0 } else { 1.2 };
            Ok(WholeRun {
                fit_error: 1.0,
                span_fit_error,
                rate_excess_kurtosis,
                suggestions,
                ..WholeRun::default()
            })
        }
    }

    #[test]
    fn the_diagnosis_runs_one_axis_per_report_each_period_and_warns_with_a_suggestion() {
        let calls = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        // No CPU budget (share 1): the rounds are paced by the period alone, whatever the clock
        // (the budget's own test is below).
        let settings = MonitorSettings {
            diagnosis_period_s: 2.0,
            stale_timeout_s: 100.0,
            diagnosis_cpu_share: 1.0,
            ..MonitorSettings::default()
        };
        let mut m = Monitor::new(settings, Some(Box::new(Diagnosing(calls.clone(), std::time::Duration::ZERO, Kept::default()))));
        let mut t = 0;
        let mut reports = Vec::new();
        // 10 s of samples at 100 Hz, a report every 0.1 s.
        for k in 1..=1000 {
            t += 10 * MS;
            m.push(sample(t, 0.0), "imu", t);
            if k % 10 == 0 {
                reports.push(m.report(t).0);
            }
        }
        let calls = calls.lock().unwrap().clone();
        // A round of six every 2 s over 10 s: five rounds, one axis per report, in axis order.
        assert_eq!(calls.len(), 30, "{calls:?}");
        assert_eq!(&calls[..6], &Axis::ALL);
        let last = reports.last().unwrap();
        assert_eq!(level(last, 0), Level::Warn as u8, "{:?}", last.status[0]);
        assert_eq!(value(last, 0, "suggestions"), "sinusoid");
        assert!(last.status[0].message.contains("sinusoid"));
        assert_eq!(level(last, 1), Level::Ok as u8);
        assert_eq!(value(last, 1, "suggestions"), "");
        // The kurtosis where the noise is heavy-tailed (gyro_y), and no key where it is Gaussian.
        assert_eq!(value(last, 1, "rate_excess_kurtosis"), "116.5");
        assert!(!last.status[0].values.iter().any(|kv| kv.key == "rate_excess_kurtosis"), "{:?}", last.status[0]);
        // Failing in time only: WARN, and the message says so (the fit over τ is fine).
        assert_eq!(value(last, 2, "fit_error"), "1");
        assert_eq!(value(last, 2, "span_fit_error"), "5");
        assert_eq!(level(last, 2), Level::Warn as u8, "{:?}", last.status[2]);
        assert!(last.status[2].message.starts_with("model fails in time: span_fit_error 5.00"), "{}", last.status[2].message);
        assert_eq!(value(last, 1, "span_fit_error"), "1.2");
        // Period 0: off, and the whole-run answers are cleared.
        m.set_settings(MonitorSettings {
            diagnosis_period_s: 0.0,
            ..settings
        });
        let (a, states, _) = m.report(t);
        assert_eq!(level(&a, 0), Level::Ok as u8);
        assert!(states.iter().all(|s| s.suggestions.is_empty()));
    }

    /// The node runs each diagnosis on a thread of its own: samples and publications go on while
    /// it runs, one runs at a time, and the answer of a model changed meanwhile is not published
    /// (a round of the new one starts once it is back).
    #[test]
    fn a_diagnosis_runs_apart_one_at_a_time_and_a_stale_answer_is_dropped() {
        let (mut m, calls, _) = diagnosing(1.0, 1.0, std::time::Duration::ZERO);
        let mut t = 0;
        let step = |m: &mut Monitor, t: &mut i64| {
            *t += 10 * MS;
            m.push(sample(*t, 0.0), "imu", *t);
        };
        step(&mut m, &mut t);
        let job = m.start_diagnosis(t).expect("a round starts once rows exist");
        for _ in 0..10 {
            step(&mut m, &mut t);
            assert!(m.start_diagnosis(t).is_none(), "one diagnosis at a time");
            let (a, states, _) = m.publication(t);
            assert_eq!((value(&a, 0, "suggestions"), states.len()), ("", 6));
        }
        let done = std::thread::spawn(move || job.run()).join().unwrap();
        m.finish_diagnosis(done);
        step(&mut m, &mut t);
        let (a, _, _) = m.publication(t);
        assert_eq!(value(&a, 0, "suggestions"), "sinusoid");
        assert_eq!(value(&a, 0, "samples"), "12");
        // gyro_y's diagnosis is out when the model changes: its answer is left out.
        let job = m.start_diagnosis(t).expect("gyro_y");
        m.reconfigure(Change::Model { axis: None, spec: "N".into() }).unwrap();
        assert!(m.start_diagnosis(t).is_none(), "one diagnosis at a time");
        m.finish_diagnosis(job.run());
        let (a, _, _) = m.publication(t);
        assert!(!a.status[1].values.iter().any(|kv| kv.key == "diagnosis_ms"), "{:?}", a.status[1]);
        let job = m.start_diagnosis(t).expect("a round of the new model at once");
        m.finish_diagnosis(job.run());
        assert_eq!(calls.lock().unwrap().as_slice(), &[Axis::GyroX, Axis::GyroY, Axis::GyroX]);
    }

    /// A monitor on [`Diagnosing`] (each diagnosis costing `cost`), diagnosing every `period_s`
    /// within `share`; the calls it records, and its settings.
    #[allow(clippy::type_complexity)]
    fn diagnosing(
        period_s: f64,
        share: f64,
        cost: std::time::Duration,
    ) -> (Monitor, std::sync::Arc<std::sync::Mutex<Vec<Axis>>>, MonitorSettings) {
        let calls = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let settings = MonitorSettings {
            diagnosis_period_s: period_s,
            stale_timeout_s: 100.0,
            diagnosis_cpu_share: share,
            ..MonitorSettings::default()
        };
        let engine = Diagnosing(calls.clone(), cost, Kept::default());
        (Monitor::new(settings, Some(Box::new(engine))), calls, settings)
    }

    #[test]
    fn a_diagnosis_starts_once_the_cpu_share_has_earned_what_it_is_expected_to_cost() {
        use std::time::{Duration, Instant};
        let (mut m, calls, settings) = diagnosing(0.001, 0.1, Duration::from_millis(10));
        let mut t = 0;
        // Reports as fast as they come, 10 ms of node time apart: the period never holds back.
        let mut step = |m: &mut Monitor| {
            t += 10 * MS;
            m.push(sample(t, 0.0), "imu", t);
            m.report(t);
        };
        let count = || calls.lock().unwrap().len();
        while count() < 1 {
            step(&mut m);
        }
        // The first started at once and cost at least 10 ms, of which a 10 % share had earned
        // 1 ms while it ran: 9 ms to pay back, then the next one's expected 10 ms to earn, 190 ms
        // from its end (resting after each diagnosis, as before, waited 90 ms).
        let done = Instant::now();
        while done.elapsed() < Duration::from_millis(150) {
            step(&mut m);
        }
        assert_eq!(count(), 1);
        let deadline = Instant::now() + Duration::from_secs(10);
        while count() < 2 && Instant::now() < deadline {
            step(&mut m);
        }
        assert_eq!(count(), 2);
        // (`done` was taken a little after the end the credit counts from: a loaded machine may
        // take it late.)
        assert!(done.elapsed() >= Duration::from_millis(150), "{:?}", done.elapsed());
        // Share 1, live: no budget, each diagnosis may start as soon as the last one has ended.
        m.set_settings(MonitorSettings { diagnosis_cpu_share: 1.0, ..settings });
        let deadline = Instant::now() + Duration::from_secs(10);
        while count() < 12 && Instant::now() < deadline {
            step(&mut m);
        }
        assert_eq!(count(), 12);
        assert_eq!(&calls.lock().unwrap()[6..], &Axis::ALL);
    }

    #[test]
    fn a_diagnosis_is_expected_to_cost_its_axis_last_scaled_by_the_record_at_most_twofold() {
        let (mut m, _, _) = diagnosing(1.0, 0.005, std::time::Duration::ZERO);
        assert_eq!(m.expected_cost(Axis::GyroX, 1000), 0.0);
        m.cost_of[Axis::GyroX.index()] = Some((0.2, 1000));
        m.cost_of[Axis::AccelZ.index()] = Some((0.3, 1000));
        // In proportion to the record: 1.5 times as long, 1.5 times the cost.
        assert!((m.expected_cost(Axis::GyroX, 1500) - 0.3).abs() < 1e-12);
        // A record halved at its cap: half.
        assert!((m.expected_cost(Axis::GyroX, 500) - 0.1).abs() < 1e-12);
        // From a first diagnosis of a short record (its fixed part): at most twice.
        assert!((m.expected_cost(Axis::GyroX, 100_000) - 0.4).abs() < 1e-12);
        // An axis not diagnosed yet: the costliest other's.
        assert!((m.expected_cost(Axis::GyroY, 1000) - 0.3).abs() < 1e-12);
        // Without the record's length (an engine that cannot tell): the last cost as it was.
        assert!((m.expected_cost(Axis::GyroX, 0) - 0.2).abs() < 1e-12);
    }
}
