//! What goes into a fit and what comes out of it: the axis's input, the options, the fitted model
//! with its terms, points and events, and why a fit could not be made.
//!
//! Plain data, kept apart from the solver so that the reports, the node and the diagnosis read the
//! result without seeing how it was computed. Everything here is re-exported as
//! `crate::model::fit::…`.

use super::spans::{SpanCheck, DEFAULT_SPANS};
use crate::allan::TauGrid;
use crate::model::effects::{Domain, Effect, ParamError};
use crate::model::nnls::NnlsError;
use crate::model::spec::{ModelSpec, SpecError};
use crate::signal::Axis;
use serde::{Deserialize, Serialize};

/// A time span in seconds from the first sample (a DAVAR change, a burst).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Span {
    /// Start, seconds from the first sample.
    pub start_s: f64,
    /// End, seconds from the first sample.
    pub end_s: f64,
}

/// Everything the fitter may use about one axis.
#[derive(Debug, Clone, Copy)]
pub struct AxisInput<'a> {
    /// The axis fitted.
    pub axis: Axis,
    /// Sample period τ0, seconds.
    pub tau0: f64,
    /// Rate samples (NaN marks a bad sample; Allan terms across it are left out).
    pub rate: &'a [f64],
    /// Temperature at each rate sample, °C (evidence for `temperature`).
    pub temperature_c: Option<&'a [f64]>,
    /// The three accel axes at each rate sample, m/s² (evidence for `g_sensitivity` on a gyro axis).
    pub accel: Option<[&'a [f64]; 3]>,
    /// Spans where the DAVAR says the noise changed (evidence for `noise_burst`).
    pub events: &'a [Span],
}

/// How the fit is run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// τ grid of the whole-record Allan variance.
    pub grid: TauGrid,
    /// Largest averaging factor as a fraction of the record (docs/design.md §2: W/3).
    pub max_m_fraction: f64,
    /// Rounds of "fit, recompute weights and EDF from the model".
    pub weight_iterations: usize,
    /// Equal time spans on which the model is checked as well as on the whole record (0 or 1:
    /// whole record only). See [`FittedModel::spans`].
    pub spans: usize,
    /// The fourth cumulant of the record's white rate noise, when the caller has measured it
    /// ([`crate::allan::edf::white_fourth_cumulant`] of the rate as recorded); `None`: the fit
    /// measures it on the rate it is given.
    ///
    /// Why given: a diagnosis refits one record many times, some of them on the rate less an
    /// estimate (a driver's regression); the tails are the sensor's, measured once, and every
    /// candidate is scored with the same EDFs.
    pub fourth_cumulant: Option<f64>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            grid: TauGrid::default(),
            max_m_fraction: 1.0 / 3.0,
            weight_iterations: 6,
            spans: DEFAULT_SPANS,
            fourth_cumulant: None,
        }
    }
}

/// Why a fit could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// The model spec names an unknown effect.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// Too few samples for an Allan variance worth fitting.
    #[error("{axis}: {samples} samples, need at least {needed}")]
    TooShort {
        /// Axis name.
        axis: &'static str,
        /// Samples given.
        samples: usize,
        /// Samples needed.
        needed: usize,
    },
    /// The sample period is not a positive finite number.
    #[error("sample period {tau0} s is not a positive finite number")]
    BadPeriod {
        /// The period given.
        tau0: f64,
    },
    /// Fewer τ points than the model has parameters.
    #[error("{points} tau points cannot determine {params} parameters")]
    Underdetermined {
        /// τ points available.
        points: usize,
        /// Free parameters.
        params: usize,
    },
    /// A time-domain effect needs a signal the recording does not have.
    #[error("{axis}: effect '{effect}' needs {needs}, which this recording does not have")]
    MissingEvidence {
        /// Axis name.
        axis: &'static str,
        /// Effect id.
        effect: &'static str,
        /// What is missing, in words.
        needs: &'static str,
    },
    /// A time-domain effect this fitter has no estimator for.
    #[error("no time-domain estimator for effect '{0}'")]
    NoEstimator(&'static str),
    /// The estimated values were rejected by the effect (out of its bounds).
    #[error(transparent)]
    Param(#[from] ParamError),
    /// The least-squares system was degenerate.
    #[error(transparent)]
    Nnls(#[from] NnlsError),
}

/// One fitted parameter value, SI, with its 1σ uncertainty when the fit gives one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParamValue {
    /// Contract parameter name, e.g. `frequency_hz`.
    pub name: String,
    /// SI unit on the fitted axis (`rad` read as `m/s` on an accel axis).
    pub unit: String,
    /// Value, SI.
    pub value: f64,
    /// 1σ uncertainty, SI (from the fit covariance, inflated for correlated τ points).
    pub sigma: Option<f64>,
}

impl ParamValue {
    /// How many σ above zero [`ParamValue::upper_bound`] puts the bound of an unresolved value.
    pub const BOUND_SIGMAS: f64 = 2.0;

    /// The upper bound of a parameter the fit could not resolve: `None` when it is resolved.
    ///
    /// The non-negative least squares set a coefficient to zero when the data cannot tell it from
    /// nothing; its value 0 then says nothing, but its σ still bounds it.
    ///
    /// # Formula
    /// ```text
    /// bound = BOUND_SIGMAS · sigma   when value = 0 and sigma is known
    /// ```
    /// (one-sided, about 97.7 % for a normal estimate).
    pub fn upper_bound(&self) -> Option<f64> {
        if self.value == 0.0 {
            self.sigma.map(|s| Self::BOUND_SIGMAS * s)
        } else {
            None
        }
    }

    /// The axis an axis-valued parameter (unit [`crate::model::effects::AXIS_UNIT`], e.g.
    /// `g_sensitivity`'s `source`) names; `None` for any other parameter.
    pub fn axis(&self) -> Option<Axis> {
        if self.unit == crate::model::effects::AXIS_UNIT {
            crate::model::effects::accel_axis(self.value)
        } else {
            None
        }
    }
}

/// One effect of a fitted model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FittedTerm {
    /// Effect id.
    pub effect: String,
    /// Alias (N, B, K, …) if any.
    pub alias: Option<String>,
    /// Where it was estimated.
    pub domain: Domain,
    /// Parameter values in schema order.
    pub params: Vec<ParamValue>,
    /// σ²(τ) of this term on the fit's τ grid (spectral terms; empty for time-domain ones).
    pub curve: Vec<f64>,
    /// The effect's plain sentence with the numbers filled in.
    pub explanation: String,
}

impl FittedTerm {
    /// The value of parameter `name`.
    pub fn param(&self, name: &str) -> Option<&ParamValue> {
        self.params.iter().find(|p| p.name == name)
    }
}

/// The measurement and the model at one τ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitPoint {
    /// Averaging factor.
    pub m: usize,
    /// τ, seconds.
    pub tau: f64,
    /// Measured σ²(τ).
    pub measured: f64,
    /// Model σ²(τ).
    pub model: f64,
    /// EDF of the estimate under the model's noise mix.
    pub edf: f64,
    /// z = (measured − model) / (model·√(2/EDF)).
    pub z: f64,
    /// True when the measurement bridged missing samples: at this τ the gap rule would have
    /// left out most terms ([`crate::allan::oavar_rate_bridged`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub bridged: bool,
}

impl FitPoint {
    /// The 68.3 % interval of the measurement under the point's EDF
    /// ([`crate::model::measure::chi2_interval`]).
    ///
    /// Why computed when asked rather than kept: only the fits a user reads (their CSV and
    /// figures) need it, and the diagnosis makes many more candidate fits than it keeps; the
    /// χ² inversions of every candidate's points were 1 % of `fdavar analyze`'s CPU.
    pub fn ci(&self) -> (f64, f64) {
        crate::model::measure::chi2_interval(self.measured, self.edf)
    }
}

/// A noise model fitted to one axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FittedModel {
    /// The axis.
    pub axis: Axis,
    /// The model asked for.
    pub spec: ModelSpec,
    /// Its effects, time-domain first (in the order they were removed), then spectral.
    pub terms: Vec<FittedTerm>,
    /// Measurement and model on the τ grid.
    pub points: Vec<FitPoint>,
    /// **contract**: RMS of z over the τ grid of the whole record's Allan variance (DESIGN.md §5):
    /// how well the model explains the measured curve.
    pub fit_error: f64,
    /// RMS of z over the τ grids of all the spans together ([`FittedModel::spans`]), each span's
    /// Allan variance against the whole-record model: how well the model holds in time (`None`
    /// when the record was too short to be checked on spans).
    ///
    /// Why apart from `fit_error`: a burst, a bias step or a warm-up hardly changes the
    /// whole-record Allan variance (it averages over time), but inside its span the stationary
    /// model fails by far; the contract's number says whether the curve is explained, this one
    /// whether the record is stationary. Why the spans pooled and not the worst one: the points
    /// of one span share one noise realisation, so a span's RMS is about |N(0,1)| of a few modes
    /// and the worst of fifteen is often 2 on a clean record; pooled, a clean record stays near 1
    /// (median 1.05, max 1.41 measured on 72 clean axes) while a burst, a step or a warm-up still
    /// lifts it 3–60×.
    pub span_fit_error: Option<f64>,
    /// Excess kurtosis of the white rate noise (0: not measurably above Gaussian). When above,
    /// isolated spikes make every Allan estimate scatter more than Gaussian noise would, and the
    /// EDF of each point is widened for it ([`crate::allan::edf::edf_with_fourth_cumulant`]).
    #[serde(default)]
    pub rate_excess_kurtosis: f64,
    /// Σ z² over the whole-record τ grid.
    pub chi2: f64,
    /// **contract**: maximal τ intervals where |z| > 3, seconds.
    pub failing_tau: Vec<[f64; 2]>,
    /// The model checked on each span of the record: where in time it holds.
    pub spans: Vec<SpanCheck>,
    /// Maximal time intervals made of spans whose fit_error exceeds 3: where in time the model fails.
    pub failing_spans: Vec<Span>,
    /// DAVAR change spans and the time-domain effects located in time.
    pub events: Vec<Event>,
    /// Number of fitted parameters (for penalised comparisons).
    pub n_params: usize,
}

impl FittedModel {
    /// The larger of [`FittedModel::fit_error`] and [`FittedModel::span_fit_error`]: the model
    /// fails when it is above 2, over τ or in time, and it is what the diagnosis's suggestions
    /// must lower ([`crate::model::diagnose()`]).
    pub fn misfit(&self) -> f64 {
        misfit(self.fit_error, self.span_fit_error)
    }

    /// How the model fails at `level` (the CLI's 2): over τ when fit_error is above it, else in
    /// time when span_fit_error is; `None` when it does not fail.
    pub fn failing(&self, level: f64) -> Option<Failing> {
        Failing::at(level, self.fit_error, self.span_fit_error)
    }

    /// The term of effect `id`.
    pub fn term(&self, id: &str) -> Option<&FittedTerm> {
        self.terms.iter().find(|t| t.effect == id)
    }
}

/// The larger of a model's fit_error and its span_fit_error (`None`: no span was checked): the
/// misfit ([`FittedModel::misfit`], [`crate::model::diagnose::Suggestion::misfit_after`]).
pub fn misfit(fit_error: f64, span_fit_error: Option<f64>) -> f64 {
    span_fit_error.map_or(fit_error, |spans| fit_error.max(spans))
}

/// How a model fails ([`FittedModel::failing`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Failing {
    /// The whole record's curve: fit_error above the level.
    OverTau,
    /// Only the spans of the record: span_fit_error above the level, fit_error not.
    InTime,
}

impl Failing {
    /// How a model of `fit_error` and `span_fit_error` fails at `level`: over τ when fit_error is
    /// above it, else in time when span_fit_error is; `None` when it does not fail (a NaN, a
    /// number not yet known, fails nothing). The CLI's warning, the fleet table and the node's
    /// `/diagnostics` all classify by it.
    pub fn at(level: f64, fit_error: f64, span_fit_error: Option<f64>) -> Option<Failing> {
        if fit_error > level {
            Some(Failing::OverTau)
        } else {
            span_fit_error.filter(|&s| s > level).map(|_| Failing::InTime)
        }
    }
}

/// A located change in time: an effect id and its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Event {
    /// `bias_step`, `noise_burst`, or `davar_change` for a span the DAVAR reported.
    pub effect: String,
    /// Its parameters (`time_s`, `start_s`, …), SI.
    pub params: Vec<(String, f64)>,
}

/// A term from an effect and the uncertainties of its parameters.
pub(super) fn term_of(effect: &dyn Effect, sigmas: &[Option<f64>], curve: Vec<f64>) -> FittedTerm {
    let kind = effect.kind();
    FittedTerm {
        effect: kind.id().to_string(),
        alias: kind.alias().map(str::to_string),
        domain: kind.domain(),
        params: effect
            .params()
            .iter()
            .enumerate()
            .map(|(i, p)| ParamValue {
                name: p.spec.name.to_string(),
                unit: p.spec.unit.to_string(),
                value: p.value,
                sigma: sigmas.get(i).copied().flatten(),
            })
            .collect(),
        curve,
        explanation: effect.explain().sentence,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::{White, AXIS_UNIT};

    fn value(unit: &str, value: f64, sigma: Option<f64>) -> ParamValue {
        ParamValue { name: "x".into(), unit: unit.into(), value, sigma }
    }

    #[test]
    fn an_unresolved_value_is_bounded_by_two_sigma() {
        assert_eq!(value("rad/s", 0.0, Some(1.5e-5)).upper_bound(), Some(3e-5));
        assert_eq!(value("rad/s", 2e-5, Some(1.5e-5)).upper_bound(), None);
        assert_eq!(value("rad/s", 0.0, None).upper_bound(), None);
    }

    #[test]
    fn an_axis_valued_parameter_names_an_accel_axis() {
        assert_eq!(value(AXIS_UNIT, 2.0, None).axis(), Some(Axis::AccelZ));
        assert_eq!(value("rad/s", 2.0, None).axis(), None);
    }

    #[test]
    fn a_term_carries_the_effect_its_values_and_their_sigmas() {
        let white = White::new(1e-3).unwrap();
        let term = term_of(&white, &[Some(2e-5)], vec![1e-6, 5e-7]);
        assert_eq!(term.effect, "white");
        assert_eq!(term.alias.as_deref(), Some("N"));
        assert_eq!(term.domain, Domain::Spectral);
        assert_eq!(
            term.param("n"),
            Some(&ParamValue { name: "n".into(), unit: "rad/s/sqrt(Hz)".into(), value: 1e-3, sigma: Some(2e-5) })
        );
        assert_eq!(term.curve, [1e-6, 5e-7]);
        assert_eq!(term.explanation, white.explain().sentence);
    }

    #[test]
    fn default_options_are_those_of_the_contract() {
        let o = FitOptions::default();
        assert_eq!((o.max_m_fraction, o.weight_iterations, o.spans), (1.0 / 3.0, 6, DEFAULT_SPANS));
    }
}
