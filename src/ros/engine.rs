//! The node's F-DAVAR engine: the same [`Pipeline`] `fdavar davar` runs offline, behind
//! [`RowEngine`], its rows turned into `fdavar_msgs/AxisState`.
//!
//! Why the offline pipeline and not a node-specific one: the same input sequence must give the same
//! rows live and offline (DESIGN §7). A live change of a DAVAR parameter rebuilds the pipeline from
//! the new configuration: rows restart half a window later, on the new settings.
//!
//! Beside the rows, each axis feeds a streaming whole-run Allan variance
//! ([`OavarAccumulator`], octave factors up to [`WHOLE_RUN_MAX_M`]: O(1) work per sample, bounded
//! memory) on which [`RowEngine::diagnose`] runs the model's diagnosis
//! ([`crate::model::diagnose_curve`]): which spectral effect the model lacks over the whole run.

use super::monitor::{Change, RowEngine};
use super::temperature::TemperatureRegression;
use crate::allan::streaming::OavarAccumulator;
use crate::allan::{AllanPoint, TauGrid};
use crate::model::effects::{unit_on_axis, EffectKind, REGISTRY};
use crate::model::ModelSpec;
use crate::msgs::builtin_interfaces::Time;
use crate::msgs::fdavar_msgs::{AxisState, Coefficient, DavarPoint, Suggestion, TauInterval};
use crate::msgs::std_msgs::Header;
use crate::pipeline::{AxisRow, DavarConfig, Output, Pipeline, PipelineError};
use crate::signal::{Axis, ImuSample, TemperatureSample};

/// [`Pipeline`] as a [`RowEngine`].
pub struct PipelineEngine {
    pipeline: Pipeline,
    out: Output,
    /// The spectral effects of the model in force (fitted per published row).
    model: Vec<&'static dyn EffectKind>,
    /// Whole-run Allan variance per axis ([`Axis::ALL`] order), made once τ0 is known.
    whole_run: Option<Vec<OavarAccumulator>>,
    /// Live temperature coefficient per axis (fed only when the temperature topic is on).
    temperature: TemperatureRegression,
}

impl std::fmt::Debug for PipelineEngine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let model: Vec<&str> = self.model.iter().map(|k| k.id()).collect();
        f.debug_struct("PipelineEngine")
            .field("pipeline", &self.pipeline)
            .field("model", &model)
            .finish_non_exhaustive()
    }
}

/// Weight iterations of the per-row fit (EDF recomputed from the model's noise mix).
const FIT_ITERATIONS: usize = 3;

/// Largest averaging factor of the whole-run Allan variance (2¹⁴: 82 s at 200 Hz). Its ring of
/// 2·m + 1 phase values is the accumulator's memory: about 0.5 MB per axis.
pub const WHOLE_RUN_MAX_M: usize = 1 << 14;

/// Largest factor of the whole-run variance used by the diagnosis, as a fraction of the samples
/// so far: the offline fit's [`crate::model::FitOptions`] default (a third of the record), so
/// that few-term estimates at the longest τ do not lead the fit.
const WHOLE_RUN_M_FRACTION: f64 = 1.0 / 3.0;

/// The effect kinds of a model spec.
///
/// # Errors
/// The spec's parse error (unknown effect, empty name).
pub fn model_kinds(spec: &str) -> Result<Vec<&'static dyn EffectKind>, String> {
    let spec = ModelSpec::parse(spec).map_err(|e| e.to_string())?;
    spec.kinds(REGISTRY).map_err(|e| e.to_string())
}

impl PipelineEngine {
    /// An engine over all six axes.
    ///
    /// # Errors
    /// [`PipelineError`] when the configuration cannot run live (e.g. `sigma_ref.mode: record`,
    /// which needs the whole recording).
    pub fn new(
        config: DavarConfig,
        model: Vec<&'static dyn EffectKind>,
    ) -> Result<PipelineEngine, PipelineError> {
        Ok(PipelineEngine {
            pipeline: Pipeline::new(config, &Axis::ALL, None)?,
            out: Output::default(),
            model,
            whole_run: None,
            temperature: TemperatureRegression::default(),
        })
    }
}

/// An [`AxisRow`] as the message `~/<axis>/state` carries it (model fields left for the fitter).
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

impl RowEngine for PipelineEngine {
    fn push(&mut self, sample: &ImuSample) -> Vec<(Axis, AxisState)> {
        self.out.rows.clear();
        self.out.events.clear();
        self.pipeline.push(sample, &mut self.out);
        let tau0 = self.pipeline.tau0().unwrap_or(f64::NAN);
        // The whole run starts once the pipeline knows τ0 (its first few dozen samples).
        if self.whole_run.is_none() && tau0.is_finite() {
            let factors = TauGrid::Octave.factors(WHOLE_RUN_MAX_M);
            self.whole_run = Axis::ALL
                .iter()
                .map(|_| OavarAccumulator::new(tau0, &factors).ok())
                .collect();
        }
        if let Some(whole_run) = self.whole_run.as_mut() {
            for (acc, v) in whole_run.iter_mut().zip(sample.values()) {
                acc.push(v);
            }
        }
        self.temperature.push_rate(sample);
        self.out
            .rows
            .iter()
            .map(|row| (row.axis, axis_state(row, tau0)))
            .collect()
    }

    fn push_temperature(&mut self, t: &TemperatureSample) {
        self.temperature.push_temperature(t);
    }

    fn reconfigure(&mut self, change: Change) -> Result<(), String> {
        match change {
            // The whole-run variance does not depend on the DAVAR settings: it carries on.
            Change::Davar(config) => {
                self.pipeline =
                    Pipeline::new(*config, &Axis::ALL, None).map_err(|e| e.to_string())?;
                Ok(())
            }
            Change::Model(spec) => {
                self.model = model_kinds(&spec)?;
                Ok(())
            }
        }
    }

    fn fit(&self, state: &mut AxisState) {
        let points: Vec<AllanPoint> = state
            .row
            .iter()
            .map(|p| AllanPoint {
                m: (p.tau_s / state.sample_period_s).round() as usize,
                tau: p.tau_s,
                avar: p.avar,
                terms: 0,
                edf: p.edf,
                ci_low: p.avar_low,
                ci_high: p.avar_high,
            })
            .collect();
        let axis = state.axis.parse::<Axis>().ok();
        // Too few τ points or a degenerate row: the model fields stay empty (fit_error NaN).
        let Ok(fit) = crate::model::fit_curve(&points, &self.model, FIT_ITERATIONS) else {
            return;
        };
        state.fit_error = fit.fit_error;
        state.failing_tau = fit
            .failing_tau
            .iter()
            .map(|[low_s, high_s]| TauInterval {
                low_s: *low_s,
                high_s: *high_s,
            })
            .collect();
        state.coefficients = fit
            .terms
            .iter()
            .flat_map(|term| {
                term.params
                    .iter()
                    .map(|p| coefficient(&term.effect, p, axis))
            })
            .collect();
        // The temperature coefficient, when the temperature topic gave a significant slope.
        if let Some((a, (value, _sigma))) =
            axis.and_then(|a| self.temperature.coefficient(a).map(|c| (a, c)))
        {
            state.coefficients.push(Coefficient {
                effect: "temperature".to_string(),
                name: "coefficient_per_k".to_string(),
                value,
                unit: unit_on_axis("rad/s/K", a),
            });
        }
    }

    fn diagnose(&self, axis: Axis) -> Vec<Suggestion> {
        let Some(acc) = self.whole_run.as_ref().map(|w| &w[axis.index()]) else {
            return Vec::new();
        };
        let max_m = acc.samples() as f64 * WHOLE_RUN_M_FRACTION;
        let points: Vec<AllanPoint> = acc
            .points()
            .into_iter()
            .filter(|p| p.m as f64 <= max_m)
            .collect();
        // Too short a run or a degenerate curve: nothing to suggest yet.
        let Ok(found) =
            crate::model::diagnose_curve(&points, &self.model, REGISTRY, FIT_ITERATIONS)
        else {
            return Vec::new();
        };
        found
            .into_iter()
            .map(|s| Suggestion {
                params: s
                    .params
                    .iter()
                    .map(|p| coefficient(&s.effect, p, Some(axis)))
                    .collect(),
                effect: s.effect,
                fit_error_after: s.fit_error_after,
                explanation: s.explanation,
            })
            .collect()
    }
}

/// A fitted parameter as a message, its unit read on `axis` (`rad` is `m/s` on an accel axis).
fn coefficient(effect: &str, p: &crate::model::fit::ParamValue, axis: Option<Axis>) -> Coefficient {
    Coefficient {
        effect: effect.to_string(),
        name: p.name.clone(),
        value: p.value,
        unit: axis.map_or_else(|| p.unit.clone(), |a| unit_on_axis(&p.unit, a)),
    }
}
