//! The analysis's answers as `fdavar_msgs/msg/AxisState` messages, live and in a results MCAP.
//!
//! Why a module of its own: what `fdavar_node` publishes on `~/<axis>/state` and what
//! `fdavar diagnose --mcap OUT` writes must be the same messages built by the same code, so that a
//! results file opens in Foxglove or PlotJuggler exactly as a recording of the node would. The node
//! ([`crate::ros`], feature `ros`) and the CLI both convert here; neither builds a message itself.
//!
//! - [`axis_state`]: one DAVAR row ([`AxisRow`]) as a message, whole-run fields empty;
//! - [`WholeRun`] ([`WholeRun::from_fit`], [`WholeRun::from_diagnosis`]): the whole run's model,
//!   coefficients with 1σ, fit_error, failing τ and spans, suggestions, written into a message by
//!   [`WholeRun::fill`];
//! - [`ResultsWriter`]: an MCAP file with one channel `/fdavar/<axis>/state` per axis: every row as
//!   it comes (log time = the row's stamp), then per axis the last row again with the whole-run
//!   fields filled, as the node's latest message after a diagnosis.
//!
//! Rejected alternative: a results file of its own format (JSON, CSV). `--json` already exists;
//! an MCAP with the node's schemas is what robotics viewers plot without any plugin.

use crate::bag::{BagError, BagWriter, WriterOptions};
use crate::model::fit::ParamValue;
use crate::model::{Diagnosis, FittedModel};
use crate::msgs::builtin_interfaces::Time;
use crate::msgs::fdavar_msgs::{
    AxisState, Coefficient, DavarPoint, Suggestion, TauInterval, TimeSpan,
};
use crate::msgs::std_msgs::Header;
use crate::pipeline::AxisRow;
use crate::signal::Axis;
use std::path::Path;

/// The whole-run fields of `~/<axis>/state`: the model in force fitted to the whole run so far.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WholeRun {
    /// The model's effect ids.
    pub model: Vec<String>,
    /// Its fitted coefficients with 1σ.
    pub coefficients: Vec<Coefficient>,
    /// fit_error (docs/design.md §5).
    pub fit_error: f64,
    /// span_fit_error ([`FittedModel::span_fit_error`]); NaN when the run was too short to be
    /// checked on spans.
    pub span_fit_error: f64,
    /// The white rate noise's excess kurtosis where it is heavier-tailed than Gaussian, else 0
    /// ([`FittedModel::rate_excess_kurtosis`]).
    pub rate_excess_kurtosis: f64,
    /// Maximal τ intervals where |z| > 3.
    pub failing_tau: Vec<TauInterval>,
    /// Maximal time spans where the model fails.
    pub failing_spans: Vec<TimeSpan>,
    /// Missing effects, best first.
    pub suggestions: Vec<Suggestion>,
    /// IMU messages the analysis had received.
    pub messages: u64,
    /// Seconds of data covered.
    pub until_s: f64,
}

impl WholeRun {
    /// A fit as the whole-run fields (no suggestions): what `fdavar fit` answers.
    pub fn from_fit(f: &FittedModel, messages: u64, until_s: f64) -> WholeRun {
        WholeRun {
            model: f.spec.ids().to_vec(),
            coefficients: f
                .terms
                .iter()
                .flat_map(|t| t.params.iter().map(|p| coefficient(&t.effect, p)))
                .collect(),
            fit_error: f.fit_error,
            span_fit_error: f.span_fit_error.unwrap_or(f64::NAN),
            rate_excess_kurtosis: f.rate_excess_kurtosis,
            failing_tau: f
                .failing_tau
                .iter()
                .map(|&[low_s, high_s]| TauInterval { low_s, high_s })
                .collect(),
            failing_spans: f
                .failing_spans
                .iter()
                .map(|s| TimeSpan {
                    start_s: s.start_s,
                    end_s: s.end_s,
                })
                .collect(),
            suggestions: Vec::new(),
            messages,
            until_s,
        }
    }

    /// A diagnosis as the whole-run fields: what `fdavar diagnose` answers and the node publishes.
    pub fn from_diagnosis(d: &Diagnosis, messages: u64, until_s: f64) -> WholeRun {
        WholeRun {
            suggestions: d
                .suggestions
                .iter()
                .map(|s| Suggestion {
                    effect: s.effect.clone(),
                    params: s.params.iter().map(|p| coefficient(&s.effect, p)).collect(),
                    fit_error_after: s.fit_error_after,
                    span_fit_error_after: s.span_fit_error_after.unwrap_or(f64::NAN),
                    explanation: s.explanation.clone(),
                    given: s.given.clone(),
                })
                .collect(),
            ..WholeRun::from_fit(&d.fit, messages, until_s)
        }
    }

    /// Writes these fields into a state message (the row fields stay as they are).
    pub fn fill(&self, s: &mut AxisState) {
        s.model.clone_from(&self.model);
        s.coefficients.clone_from(&self.coefficients);
        s.fit_error = self.fit_error;
        s.span_fit_error = self.span_fit_error;
        s.rate_excess_kurtosis = self.rate_excess_kurtosis;
        s.failing_tau.clone_from(&self.failing_tau);
        s.failing_spans.clone_from(&self.failing_spans);
        s.suggestions.clone_from(&self.suggestions);
        s.diagnosed_messages = self.messages;
        s.diagnosed_until_s = self.until_s;
    }
}

/// An [`AxisRow`] as the message `~/<axis>/state` carries it (whole-run fields left empty,
/// fit_error NaN), with `tau0` the rows' sample period, s.
pub fn axis_state(row: &AxisRow, tau0: f64) -> AxisState {
    let r = &row.row;
    AxisState {
        header: Header {
            stamp: Time::from_ns(row.stamp_ns).unwrap_or_default(),
            frame_id: String::new(),
        },
        axis: row.axis.name().to_string(),
        analysis_time_s: row.time_s,
        window_length: u32::try_from(r.window).unwrap_or(u32::MAX),
        f_value: r.f.unwrap_or(f64::NAN),
        f_reference: r.f_target.unwrap_or(f64::NAN),
        sample_period_s: tau0,
        row: r
            .points()
            .map(|p| DavarPoint {
                tau_s: p.tau,
                avar: p.avar,
                avar_low: p.ci_low,
                avar_high: p.ci_high,
                edf: p.edf,
            })
            .collect(),
        fit_error: f64::NAN,
        span_fit_error: f64::NAN,
        ..AxisState::default()
    }
}

/// A fitted parameter as a message (its unit is already the one of its axis); a parameter without
/// an uncertainty has σ NaN.
fn coefficient(effect: &str, p: &ParamValue) -> Coefficient {
    Coefficient {
        effect: effect.to_string(),
        name: p.name.clone(),
        value: p.value,
        sigma: p.sigma.unwrap_or(f64::NAN),
        unit: p.unit.clone(),
    }
}

/// The topic of `axis` in a results MCAP: where `fdavar_node` (node name `fdavar`, root
/// namespace) publishes `~/<axis>/state`.
pub fn state_topic(axis: Axis) -> String {
    format!("/fdavar/{axis}/state")
}

/// Writes a results MCAP: `fdavar_msgs/msg/AxisState` on `/fdavar/<axis>/state` (see the module
/// doc), with the `ros2msg` schemas rosbag2, Foxglove, PlotJuggler and `mcap-ros2-support` read.
///
/// Call [`ResultsWriter::finish`] at the end; after any error the writer refuses further writes.
///
/// ```
/// use fdavar::results::{ResultsWriter, WholeRun};
/// use fdavar::signal::Axis;
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("results.mcap");
/// let mut w = ResultsWriter::create(&path)?;
/// w.write_whole_run(Axis::GyroX, &WholeRun { fit_error: 1.25, ..WholeRun::default() })?;
/// w.finish()?;
/// let bag = fdavar::bag::BagReader::open(&path)?;
/// assert_eq!(bag.topics()[0].name, "/fdavar/gyro_x/state");
/// assert_eq!(bag.topics()[0].message_count, 1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct ResultsWriter {
    bag: BagWriter,
    /// The latest row message written per axis ([`Axis::ALL`] order).
    latest: [Option<AxisState>; 6],
    /// Log time of the latest message written, ns.
    last_ns: i64,
}

impl ResultsWriter {
    /// Creates (or replaces) the MCAP file `path`, zstd-compressed.
    ///
    /// # Errors
    /// [`BagError::Io`] when `path` is a directory or the file cannot be created.
    pub fn create(path: impl AsRef<Path>) -> Result<ResultsWriter, BagError> {
        Ok(ResultsWriter {
            bag: BagWriter::create_file(path, &WriterOptions::default())?,
            latest: Default::default(),
            last_ns: 0,
        })
    }

    /// Writes one row message as it came (log time = its header stamp) and keeps it as the axis's
    /// latest.
    ///
    /// # Errors
    /// As [`BagWriter::write_message`].
    pub fn write_row(&mut self, state: AxisState) -> Result<(), BagError> {
        let axis = axis_of(&state)?;
        let log_ns = state.header.stamp.to_ns();
        self.bag.write_message(&state_topic(axis), log_ns, &state)?;
        self.last_ns = self.last_ns.max(log_ns);
        self.latest[axis.index()] = Some(state);
        Ok(())
    }

    /// Writes the final message of `axis`: its latest row with `whole` filled in, at that row's
    /// stamp (an axis without a row: only the whole-run fields, at the latest log time written).
    ///
    /// # Errors
    /// As [`BagWriter::write_message`].
    pub fn write_whole_run(&mut self, axis: Axis, whole: &WholeRun) -> Result<(), BagError> {
        let mut state = self.latest[axis.index()]
            .clone()
            .unwrap_or_else(|| AxisState {
                header: Header {
                    stamp: Time::from_ns(self.last_ns).unwrap_or_default(),
                    frame_id: String::new(),
                },
                axis: axis.name().to_string(),
                f_value: f64::NAN,
                f_reference: f64::NAN,
                sample_period_s: f64::NAN,
                ..AxisState::default()
            });
        whole.fill(&mut state);
        let log_ns = state.header.stamp.to_ns();
        self.bag.write_message(&state_topic(axis), log_ns, &state)
    }

    /// Completes the file (MCAP summary and footer).
    ///
    /// # Errors
    /// As [`BagWriter::finish`].
    pub fn finish(&mut self) -> Result<(), BagError> {
        self.bag.finish()
    }
}

/// The axis a state message names.
fn axis_of(state: &AxisState) -> Result<Axis, BagError> {
    state.axis.parse().map_err(|_| BagError::Unwritable {
        topic: String::new(),
        reason: format!("unknown axis {:?} in an AxisState message", state.axis),
    })
}
