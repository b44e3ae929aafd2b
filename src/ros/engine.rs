//! The node's engine: the library's [`Analysis`] (the path `fdavar fit/diagnose` run offline)
//! behind [`RowEngine`], its answers turned into `fdavar_msgs` messages by [`crate::results`]
//! (the code `fdavar diagnose --mcap` writes its results file with).
//!
//! Why no node-specific maths here: what the node publishes — the DAVAR rows, and the whole run's
//! coefficients with their 1σ, fit_error, failing τ and time spans, suggestions — must be the
//! numbers `fdavar diagnose` prints for the same samples (docs/design.md §7). This file only adapts.
//! A live change of a DAVAR parameter restarts the rows (half a window later, on the new
//! settings); the whole-run record carries on. A new model applies at the next diagnosis.

use super::monitor::{Change, Lent, RowEngine, WholeRun};
use crate::analysis::{Analysis, AnalysisConfig, Loan};
use crate::model::ModelSpec;
use crate::msgs::fdavar_msgs::AxisState;
use crate::pipeline::{AxisRow, DavarConfig, PipelineError};
use crate::results::axis_state;
use crate::signal::{Axis, ImuSample, TemperatureSample};

/// Inputs the engine holds for a lent record ([`RowEngine::lend`]) before it takes no more:
/// the node then queues the input, and drops and counts what its full queue cannot take.
///
/// Why 2¹⁶ (64 bytes each, 4 MB): the longest diagnosis, of a full record (2²⁰ values per axis),
/// takes well under the 1.6 s a record twice as long took on the slowest host measured (`fdavar
/// diagnose --jobs 1`), 3 200 samples at 2 kHz; 2¹⁶ is 33 s at 2 kHz, so that only a stalled
/// machine meets the cap.
pub const DEFERRED_CAP: usize = 1 << 16;

/// [`Analysis`] as a [`RowEngine`].
#[derive(Debug)]
pub struct AnalysisEngine {
    analysis: Analysis,
    /// The `model` parameter (every axis without an override).
    global: ModelSpec,
    /// The `model.<axis>` parameters.
    overrides: [Option<ModelSpec>; 6],
    /// The latest row of each axis, with the rows' τ0 when it was made.
    latest: [Option<(AxisRow, f64)>; 6],
}

/// Parses a model spec given as a parameter.
///
/// # Errors
/// The spec's parse error (unknown effect, empty name, no noise term), as text for the
/// parameter service.
pub fn model_spec(spec: &str) -> Result<ModelSpec, String> {
    ModelSpec::parse(spec).map_err(|e| e.to_string())
}

impl AnalysisEngine {
    /// An engine over all six axes: the model `global` on every axis but those `overrides` name.
    ///
    /// # Errors
    /// [`PipelineError`] when the DAVAR settings cannot run live (e.g. `sigma_ref.mode: record`,
    /// which needs the whole recording).
    pub fn new(
        config: DavarConfig,
        global: ModelSpec,
        overrides: [Option<ModelSpec>; 6],
        record_cap: usize,
    ) -> Result<AnalysisEngine, PipelineError> {
        let mut analysis_config = AnalysisConfig::whole_run(&global).with_rows(config);
        analysis_config.max_samples = record_cap;
        for axis in Axis::ALL {
            if let Some(m) = &overrides[axis.index()] {
                analysis_config.models[axis.index()] = m.clone();
            }
        }
        Ok(AnalysisEngine {
            analysis: Analysis::new(analysis_config)?,
            global,
            overrides,
            latest: Default::default(),
        })
    }

    fn apply_models(&mut self) {
        for axis in Axis::ALL {
            let m = self.overrides[axis.index()]
                .clone()
                .unwrap_or_else(|| self.global.clone());
            self.analysis.set_model(axis, m);
        }
    }
}

impl RowEngine for AnalysisEngine {
    fn push(&mut self, sample: &ImuSample, mut every_row: Option<&mut Vec<AxisState>>) {
        if self.analysis.push(sample).is_empty() {
            return;
        }
        let tau0 = self.analysis.row_tau0().unwrap_or(f64::NAN);
        let latest = &mut self.latest;
        self.analysis.hand_rows(|row| {
            if let Some(rows) = every_row.as_mut() {
                rows.push(axis_state(&row, tau0));
            }
            latest[row.axis.index()]
                .replace((row, tau0))
                .map(|(old, _)| old)
        });
    }

    fn latest(&self, axis: Axis) -> Option<AxisState> {
        self.latest[axis.index()]
            .as_ref()
            .map(|(row, tau0)| axis_state(row, *tau0))
    }

    fn push_temperature(&mut self, t: &TemperatureSample) {
        self.analysis.push_temperature(t);
    }

    fn reconfigure(&mut self, change: Change) -> Result<(), String> {
        match change {
            Change::Davar(config) => self.analysis.set_davar(*config).map_err(|e| e.to_string()),
            Change::Model { axis: None, spec } => {
                self.global = model_spec(&spec)?;
                self.apply_models();
                Ok(())
            }
            Change::Model {
                axis: Some(axis),
                spec,
            } => {
                // An empty per-axis model hands the axis back to the global one.
                self.overrides[axis.index()] = if spec.trim().is_empty() {
                    None
                } else {
                    Some(model_spec(&spec)?)
                };
                self.apply_models();
                Ok(())
            }
        }
    }

    fn has_row(&self, axis: Axis) -> bool {
        self.latest[axis.index()].is_some()
    }

    fn lend(&mut self, axis: Axis) -> Option<Box<dyn Lent>> {
        let loan = self.analysis.lend(axis).ok()?;
        Some(Box::new(LentRecord(loan)))
    }

    fn give_back(&mut self, lent: Box<dyn Lent>) {
        // Only this engine's loans come back here (the monitor hands back what it was lent).
        if let Ok(lent) = lent.into_any().downcast::<LentRecord>() {
            self.analysis.give_back(lent.0);
        }
    }

    fn record_len(&self) -> usize {
        self.analysis.record_len()
    }

    fn can_take(&self) -> bool {
        self.analysis.deferred() < DEFERRED_CAP
    }
}

/// The whole-run record lent by [`AnalysisEngine`]: its diagnosis is [`Loan::diagnose`], the
/// path of `fdavar diagnose`.
struct LentRecord(Loan);

impl Lent for LentRecord {
    fn diagnose(&mut self) -> Result<WholeRun, String> {
        let messages = self.0.messages();
        let until_s = self.0.duration_s().unwrap_or(0.0);
        let d = self.0.diagnose().map_err(|e| e.to_string())?;
        Ok(WholeRun::from_diagnosis(&d, messages, until_s))
    }

    fn into_any(self: Box<Self>) -> Box<dyn std::any::Any + Send> {
        self
    }
}
