//! The node's engine: the library's [`Analysis`] (the path `fdavar fit/diagnose` run offline)
//! behind [`RowEngine`], its answers turned into `fdavar_msgs` messages.
//!
//! Why no node-specific maths here: what the node publishes — the DAVAR rows, and the whole run's
//! coefficients with their 1σ, fit_error, failing τ and time spans, suggestions — must be the
//! numbers `fdavar diagnose` prints for the same samples (docs/design.md §7). This file only converts.
//! A live change of a DAVAR parameter restarts the rows (half a window later, on the new
//! settings); the whole-run record carries on. A new model applies at the next diagnosis.

use super::monitor::{Change, RowEngine, WholeRun};
use crate::analysis::{Analysis, AnalysisConfig};
use crate::model::fit::ParamValue;
use crate::model::{Diagnosis, ModelSpec};
use crate::msgs::builtin_interfaces::Time;
use crate::msgs::fdavar_msgs::{
    AxisState, Coefficient, DavarPoint, Suggestion, TauInterval, TimeSpan,
};
use crate::msgs::std_msgs::Header;
use crate::pipeline::{AxisRow, DavarConfig, PipelineError};
use crate::signal::{Axis, ImuSample, TemperatureSample};

/// [`Analysis`] as a [`RowEngine`].
#[derive(Debug)]
pub struct AnalysisEngine {
    analysis: Analysis,
    /// The `model` parameter (every axis without an override).
    global: ModelSpec,
    /// The `model.<axis>` parameters.
    overrides: [Option<ModelSpec>; 6],
}

/// Parses a model spec given as a parameter.
///
/// # Errors
/// The spec's parse error (unknown effect, empty name), as text for the parameter service.
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
    ) -> Result<AnalysisEngine, PipelineError> {
        let mut analysis_config = AnalysisConfig::whole_run(&global);
        // The whole run is placed on the grid of the configured τ0, as the rows are.
        analysis_config.tau0 = config.tau0;
        analysis_config.davar = Some(config);
        for axis in Axis::ALL {
            if let Some(m) = &overrides[axis.index()] {
                analysis_config.models[axis.index()] = m.clone();
            }
        }
        Ok(AnalysisEngine {
            analysis: Analysis::new(analysis_config)?,
            global,
            overrides,
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

/// An [`AxisRow`] as the message `~/<axis>/state` carries it (whole-run fields left empty).
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
            .points
            .iter()
            .map(|p| DavarPoint {
                tau_s: p.tau,
                avar: p.avar,
                avar_low: p.ci_low,
                avar_high: p.ci_high,
                edf: p.edf,
            })
            .collect(),
        fit_error: f64::NAN,
        ..AxisState::default()
    }
}

impl RowEngine for AnalysisEngine {
    fn push(&mut self, sample: &ImuSample) -> Vec<(Axis, AxisState)> {
        let rows = self.analysis.push(sample);
        if rows.is_empty() {
            return Vec::new();
        }
        let rows = rows.to_vec();
        let tau0 = self.analysis.row_tau0().unwrap_or(f64::NAN);
        rows.iter()
            .map(|row| (row.axis, axis_state(row, tau0)))
            .collect()
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

    fn diagnose(&mut self, axis: Axis) -> Result<WholeRun, String> {
        let messages = self.analysis.messages();
        let until_s = self.analysis.duration_s().unwrap_or(0.0);
        let d = self.analysis.diagnose(axis).map_err(|e| e.to_string())?;
        Ok(whole_run(&d, messages, until_s))
    }
}

/// A diagnosis as the whole-run fields of `~/<axis>/state`.
pub fn whole_run(d: &Diagnosis, messages: u64, until_s: f64) -> WholeRun {
    let f = &d.fit;
    WholeRun {
        model: f.spec.ids().to_vec(),
        coefficients: f
            .terms
            .iter()
            .flat_map(|t| t.params.iter().map(|p| coefficient(&t.effect, p)))
            .collect(),
        fit_error: f.fit_error,
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
        suggestions: d
            .suggestions
            .iter()
            .map(|s| Suggestion {
                effect: s.effect.clone(),
                params: s.params.iter().map(|p| coefficient(&s.effect, p)).collect(),
                fit_error_after: s.fit_error_after,
                explanation: s.explanation.clone(),
            })
            .collect(),
        messages,
        until_s,
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
