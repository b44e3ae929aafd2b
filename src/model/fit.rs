//! Fitting a noise model to one axis: time-domain effects on the rate, then the Allan variance.
//!
//! The flow follows the data. Effects that are not stationary or that are driven by another signal
//! ([`Domain::TimeDomain`]: a bias step, a noise burst, temperature, g-sensitivity) are estimated on
//! the rate samples and removed from them; the whole-record overlapping Allan variance of what is
//! left is then fitted with the stationary effects ([`Domain::Spectral`]) by weighted non-negative
//! least squares on their squared amplitudes, with a 1-D search for each shape parameter
//! (a frequency, a time constant). Fitting a step or a burst on the Allan variance was rejected: its
//! signature depends on where in the record it sits, so it has no τ-law to fit.
//!
//! Where the model fails is told in τ and in time. The whole-record fit is checked again on eight
//! spans of the cleaned record (and the seven straddling their boundaries), each with its own
//! Allan variance: a step, a burst or a warm-up that the whole-record average hides fails there
//! (`failing_spans`), and `fit_error` is the larger of the whole-record RMS of z and the RMS over
//! all span points. A model with the missing time-domain effect removes it before both checks.
//!
//! The weights are those of the contract's z score: the standard deviation of an AVAR estimate is
//! σ²_model·√(2/EDF), with the EDF of the model's own noise mix at each τ, iterated with the fit.
//!
//! Conventions the fitter relies on (the effect files follow them): a spectral effect's σ²(τ) is
//! proportional to the square of its *first* parameter (the amplitude); its other parameters are
//! shape parameters, searched on a log scale over the range the τ grid can see (unit `s`: τmin
//! to 4·τmax; unit `Hz`: the inverse) unless the kind gives its own ([`EffectKind::search_range`]).
//!
//! # References
//! IEEE Std 952-1997, Annex C; Riley, NIST SP 1065 (2008), §5.2.4, Table 12; Lawson & Hanson (1974).

use crate::allan::{AllanPoint, TauGrid};
use crate::model::effects::{
    unit_on_axis, Domain, Effect, EffectKind, OutputContext, ParamError, SimStage,
};
use crate::allan::oavar_rate_bridged;
use crate::model::measure::{chi2_interval, edf_for_mix, NoiseClass};
use crate::model::nnls::{nnls, NnlsError};
use crate::model::spec::{ModelSpec, SpecError};
use crate::model::timedomain::{self, NoiseSpectrum, Signature};
use crate::signal::Axis;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// |z| above which a τ is "failing" (docs/design.md §5, **contract**).
pub const FAILING_Z: f64 = 3.0;

/// Fewest rate samples a whole-record fit accepts.
pub const MIN_SAMPLES: usize = 64;

/// Spans the record is cut into for the time-resolved check of the model (plus the 7 spans
/// straddling their boundaries).
///
/// Eight spans of a 20–60 min record are 2.5–7.5 min each: long enough for their own Allan
/// variance to reach τ of ten seconds with a useful EDF, short enough that a step, a burst or a
/// warm-up fills a good part of one span instead of a sliver of the record.
pub const DEFAULT_SPANS: usize = 8;

/// Least EDF of a span's τ point for it to count in the span check.
///
/// z of an estimate with ν degrees of freedom has skewness √(8/ν), and at small ν the EDF of a
/// short span's flicker-dominated points is least trustworthy. Measured on 72 clean simulated
/// axes (12 seeds, 200 Hz, 20 min, N+B+K): with ν ≥ 20 the span RMS has median 1.05, p90 1.20,
/// max 1.41; ν ≥ 4 adds nothing to what a step or warm-up shows (4.30 → 4.55 for a 2·10⁻³ rad/s step).
pub const MIN_SPAN_EDF: f64 = 20.0;

/// Fewest samples in one span; a shorter record is cut into fewer spans.
pub const MIN_SPAN_SAMPLES: usize = 1024;

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
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            grid: TauGrid::default(),
            max_m_fraction: 1.0 / 3.0,
            weight_iterations: 6,
            spans: DEFAULT_SPANS,
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
    /// 68.3 % interval of the measurement under that EDF.
    pub ci: (f64, f64),
    /// z = (measured − model) / (model·√(2/EDF)).
    pub z: f64,
    /// True when the measurement bridged missing samples: at this τ the gap rule would have
    /// left out most terms ([`crate::allan::oavar_rate_bridged`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub bridged: bool,
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
    /// **contract**: RMS of z over the τ grid — the larger of the whole record's
    /// ([`FittedModel::whole_fit_error`]) and that over the τ grids of all the spans together
    /// ([`FittedModel::spans`]).
    ///
    /// Why the spans pooled and not the worst one: the points of one span share one noise
    /// realisation, so a span's RMS is about |N(0,1)| of a few modes and the worst of fifteen
    /// is often 2 on a clean record; pooled, a clean record stays near 1 (median 1.05, max 1.41
    /// measured on 72 clean axes) while a burst, a step or a warm-up still lifts it 3–60×.
    pub fit_error: f64,
    /// RMS of z over the τ grid of the whole-record Allan variance alone.
    pub whole_fit_error: f64,
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
    /// The term of effect `id`.
    pub fn term(&self, id: &str) -> Option<&FittedTerm> {
        self.terms.iter().find(|t| t.effect == id)
    }
}

/// The model checked on one span of the record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpanCheck {
    /// The span, seconds from the first sample.
    pub span: Span,
    /// RMS of z over the span's own τ grid, the model being the whole-record fit.
    pub fit_error: f64,
}

/// The Allan variance of one span of the cleaned record.
#[derive(Debug, Clone, PartialEq)]
struct SpanMeasure {
    span: Span,
    points: Vec<AllanPoint>,
}

/// Cuts the cleaned `series` into `opts.spans` equal spans (fewer if a span would hold fewer than
/// [`MIN_SPAN_SAMPLES`]) and measures the Allan variance of each on the record's τ grid.
///
/// Why: the whole-record Allan variance averages over time. A noise burst only raises the white
/// level, a bias step reads as a rate random walk, a warm-up as flicker and random walk; a
/// stationary model then fits the whole record and still fails inside the span where the record
/// is not stationary. The model, fitted once on the whole record, must also explain each span.
/// Spans overlap by half, so that a change on a boundary sits in the middle of another span.
fn measure_spans(series: &[f64], tau0: f64, opts: &FitOptions) -> Vec<SpanMeasure> {
    let n = series.len();
    let count = opts.spans.min(n / MIN_SPAN_SAMPLES);
    if count < 2 {
        return Vec::new();
    }
    // Half-overlapping: a change at a span boundary still falls in the middle of one span.
    (0..2 * count - 1)
        .map(|i| {
            let (a, b) = (i * n / (2 * count), (i + 2) * n / (2 * count));
            let max_m = ((b - a) as f64 * opts.max_m_fraction).floor() as usize;
            SpanMeasure {
                span: Span {
                    start_s: a as f64 * tau0,
                    end_s: b as f64 * tau0,
                },
                points: measure(&series[a..b], tau0, &opts.grid.factors(max_m.max(1))).0,
            }
        })
        .collect()
}

/// The whole-record model of `fit` checked on one span: z at each of the span's τ (those with an
/// EDF of at least [`MIN_SPAN_EDF`]), with the EDF of the model's noise mix for the span's length.
/// Returns the span's RMS and its z values (pooled by the caller).
fn check_span(measure: &SpanMeasure, fit: &CurveFit) -> (SpanCheck, Vec<f64>) {
    let z: Vec<f64> = measure
        .points
        .iter()
        .filter(|p| p.avar.is_finite() && p.avar > 0.0)
        .filter_map(|p| {
            let i = fit.points.iter().position(|q| q.m == p.m)?;
            let parts: Vec<(f64, NoiseClass)> = fit
                .terms
                .iter()
                .zip(&fit.classes)
                .map(|(t, &c)| (t.curve[i], c))
                .collect();
            let model = fit.points[i].model;
            let edf = edf_for_mix(&parts, p.terms + 2 * p.m, p.m);
            (edf >= MIN_SPAN_EDF)
                .then(|| z_scores(&[p.avar], &[model], &[edf]))?
                .pop()
        })
        .collect();
    let check = SpanCheck {
        span: measure.span,
        fit_error: rms(&z),
    };
    (check, z)
}

/// Maximal runs of spans whose fit_error exceeds [`FAILING_Z`], merged into time intervals.
fn failing_spans(spans: &[SpanCheck]) -> Vec<Span> {
    let mut out: Vec<Span> = Vec::new();
    for s in spans.iter().filter(|s| s.fit_error > FAILING_Z) {
        match out.last_mut() {
            Some(last) if last.end_s >= s.span.start_s => last.end_s = s.span.end_s,
            _ => out.push(s.span),
        }
    }
    out
}

/// A located change in time: an effect id and its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Event {
    /// `bias_step`, `noise_burst`, or `davar_change` for a span the DAVAR reported.
    pub effect: String,
    /// Its parameters (`time_s`, `start_s`, …), SI.
    pub params: Vec<(String, f64)>,
}

/// **contract**: RMS over the τ grid of z = (σ²_meas − σ²_model)/(σ²_model·√(2/EDF)).
///
/// # Formula
/// ```text
/// zᵢ = (measᵢ − modelᵢ) / (modelᵢ·√(2/edfᵢ)),   fit_error = √(Σ zᵢ² / K)
/// ```
/// where K is the number of τ points. About 1 when the model explains the measurement.
///
/// ```
/// use fdavar::model::fit::fit_error;
/// assert_eq!(fit_error(&[1.0, 1.0], &[1.0, 1.0], &[50.0, 50.0]), 0.0);
/// assert!((fit_error(&[1.2], &[1.0], &[50.0]) - 1.0).abs() < 1e-12);
/// ```
pub fn fit_error(measured: &[f64], model: &[f64], edf: &[f64]) -> f64 {
    let z = z_scores(measured, model, edf);
    rms(&z)
}

/// z scores of the contract (see [`fit_error`]); a non-positive model gives z = ±∞ or 0.
pub fn z_scores(measured: &[f64], model: &[f64], edf: &[f64]) -> Vec<f64> {
    measured
        .iter()
        .zip(model)
        .zip(edf)
        .map(|((&me, &mo), &e)| {
            let d = me - mo;
            let sd = mo * (2.0 / e).sqrt();
            if sd > 0.0 {
                d / sd
            } else if d == 0.0 {
                0.0
            } else {
                f64::INFINITY.copysign(d)
            }
        })
        .collect()
}

fn rms(z: &[f64]) -> f64 {
    if z.is_empty() {
        return 0.0;
    }
    (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt()
}

/// **contract**: the maximal τ intervals [lo, hi] (seconds) where |z| > 3.
///
/// ```
/// use fdavar::model::fit::failing_tau;
/// let tau = [1.0, 2.0, 4.0, 8.0, 16.0];
/// assert_eq!(failing_tau(&tau, &[0.0, 4.0, -5.0, 1.0, 3.5]), vec![[2.0, 4.0], [16.0, 16.0]]);
/// ```
pub fn failing_tau(tau: &[f64], z: &[f64]) -> Vec<[f64; 2]> {
    let mut out: Vec<[f64; 2]> = Vec::new();
    let mut open: Option<[f64; 2]> = None;
    for (&t, &zi) in tau.iter().zip(z) {
        if zi.abs() > FAILING_Z {
            open = Some(match open {
                Some([lo, _]) => [lo, t],
                None => [t, t],
            });
        } else if let Some(span) = open.take() {
            out.push(span);
        }
    }
    out.extend(open);
    out
}

/// Fits `spec` to one axis (the whole-record fit of `fdavar fit`).
///
/// # Errors
/// [`FitError`]: unknown effect, too short a record, missing evidence for a time-domain effect,
/// fewer τ points than parameters.
pub fn fit(
    input: &AxisInput<'_>,
    spec: &ModelSpec,
    registry: &[&'static dyn EffectKind],
    opts: &FitOptions,
) -> Result<FittedModel, FitError> {
    let prepared = prepare(input, spec, registry, opts)?;
    prepared.fit_spectral(spec, &prepared.spectral_kinds, opts)
}

/// The Allan variance the fit reads: [`oavar_rate_bridged`], so that a record losing a message
/// every few seconds keeps its long τ; with the factors that were bridged.
fn measure(series: &[f64], tau0: f64, factors: &[usize]) -> (Vec<AllanPoint>, Vec<usize>) {
    let points = oavar_rate_bridged(series, tau0, factors);
    let bridged = points.iter().filter(|p| p.bridged).map(|p| p.point.m).collect();
    (points.into_iter().map(|p| p.point).collect(), bridged)
}

/// The base noise of `series` as the spectral `kinds` fitted to its Allan variance describe it
/// (what the time-domain regressions are weighed against); `None` without spectral kinds or when
/// the fit fails.
fn noise_of(
    series: &[f64],
    tau0: f64,
    kinds: &[&'static dyn EffectKind],
    opts: &FitOptions,
) -> Option<NoiseSpectrum> {
    if kinds.is_empty() {
        return None;
    }
    let max_m = ((series.len() as f64) * opts.max_m_fraction).floor() as usize;
    let (points, _) = measure(series, tau0, &opts.grid.factors(max_m.max(1)));
    let fit = fit_curve(&points, kinds, opts.weight_iterations).ok()?;
    let taus: Vec<f64> = fit.points.iter().map(|p| p.tau).collect();
    Some(NoiseSpectrum::from_curves(
        tau0,
        &taus,
        fit.terms.iter().zip(&fit.classes).map(|(t, &c)| (c, t.curve.as_slice())),
    ))
}

/// A record with its time-domain effects estimated and removed, and its Allan variance measured.
///
/// Kept so that the diagnosis can try several spectral additions without measuring again.
#[derive(Clone)]
pub struct Prepared {
    axis: Axis,
    /// The measured Allan variance of the cleaned series.
    pub points: Vec<AllanPoint>,
    /// The factors of `points` measured across missing samples.
    bridged: Vec<usize>,
    time_terms: Vec<FittedTerm>,
    events: Vec<Event>,
    spans: Vec<SpanMeasure>,
    /// Spectral kinds of the spec.
    pub spectral_kinds: Vec<&'static dyn EffectKind>,
    /// What the samples tell the spectral fit beyond the Allan points.
    samples: SampleContext,
}

/// Validates the input, removes the spec's time-domain effects and measures the Allan variance.
///
/// # Errors
/// As [`fit`].
pub fn prepare(
    input: &AxisInput<'_>,
    spec: &ModelSpec,
    registry: &[&'static dyn EffectKind],
    opts: &FitOptions,
) -> Result<Prepared, FitError> {
    if !(input.tau0.is_finite() && input.tau0 > 0.0) {
        return Err(FitError::BadPeriod { tau0: input.tau0 });
    }
    if input.rate.len() < MIN_SAMPLES {
        return Err(FitError::TooShort {
            axis: input.axis.name(),
            samples: input.rate.len(),
            needed: MIN_SAMPLES,
        });
    }
    let kinds = spec.kinds(registry)?;
    let (time_kinds, spectral_kinds): (Vec<_>, Vec<_>) = kinds
        .into_iter()
        .partition(|k| k.domain() == Domain::TimeDomain);
    // Copied only when a time-domain term is removed from it: a whole-run record is large.
    let mut series = std::borrow::Cow::Borrowed(input.rate);
    let mut time_terms = Vec::new();
    let mut events: Vec<Event> = input
        .events
        .iter()
        .map(|s| Event {
            effect: "davar_change".into(),
            params: vec![("start_s".into(), s.start_s), ("end_s".into(), s.end_s)],
        })
        .collect();
    let order = timedomain::in_estimation_order(&time_kinds);
    let mut estimates = Vec::with_capacity(order.len());
    for &kind in &order {
        let est = timedomain::estimate(kind, input, &series, None)?;
        timedomain::remove(kind, &est, input, series.to_mut());
        estimates.push(est);
    }
    // A regression (on a driver or on time) is estimated again by GLS against the noise of the
    // rest: the first, ordinary least-squares guess weighs a wandering record's random walk as
    // heavily as the signal (see `timedomain::trend`, `Whitened`).
    let regression = |e: &timedomain::Estimate| matches!(e.signature, Signature::Driven | Signature::Trend);
    if estimates.iter().any(regression) {
        if let Some(noise) = noise_of(&series, input.tau0, &spectral_kinds, opts) {
            series = std::borrow::Cow::Borrowed(input.rate);
            for (&kind, est) in order.iter().zip(estimates.iter_mut()) {
                if regression(est) {
                    if let Ok(gls) = timedomain::estimate(kind, input, &series, Some(&noise)) {
                        *est = gls;
                    }
                }
                timedomain::remove(kind, est, input, series.to_mut());
            }
        }
    }
    for (&kind, est) in order.iter().zip(&estimates) {
        let effect = kind.build(&est.values)?;
        if est.is_event {
            events.push(Event {
                effect: kind.id().into(),
                params: effect
                    .params()
                    .iter()
                    .map(|p| (p.spec.name.to_string(), p.value))
                    .collect(),
            });
        }
        time_terms.push(term_of(&*effect, &est.sigmas, Vec::new()));
    }
    let max_m = ((series.len() as f64) * opts.max_m_fraction).floor() as usize;
    let factors = opts.grid.factors(max_m.max(1));
    let (points, bridged) = measure(&series, input.tau0, &factors);
    Ok(Prepared {
        axis: input.axis,
        points,
        bridged,
        time_terms,
        events,
        spans: measure_spans(&series, input.tau0, opts),
        spectral_kinds,
        samples: SampleContext::of(input.rate),
    })
}

impl std::fmt::Debug for Prepared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ids: Vec<&str> = self.spectral_kinds.iter().map(|k| k.id()).collect();
        f.debug_struct("Prepared")
            .field("axis", &self.axis)
            .field("points", &self.points.len())
            .field("time_terms", &self.time_terms)
            .field("spectral_kinds", &ids)
            .finish()
    }
}

impl Prepared {
    /// Fits `kinds` (spectral) to the measured Allan variance and assembles the fitted model.
    ///
    /// # Errors
    /// [`FitError::Underdetermined`], [`FitError::Param`], [`FitError::Nnls`].
    pub fn fit_spectral(
        &self,
        spec: &ModelSpec,
        kinds: &[&'static dyn EffectKind],
        opts: &FitOptions,
    ) -> Result<FittedModel, FitError> {
        let mut sf = fit_points(&self.points, kinds, opts.weight_iterations, self.samples)?;
        for p in sf.points.iter_mut() {
            p.bridged = self.bridged.contains(&p.m);
        }
        let (spans, span_z): (Vec<SpanCheck>, Vec<Vec<f64>>) =
            self.spans.iter().map(|m| check_span(m, &sf)).unzip();
        let span_fit_error = rms(&span_z.concat());
        let mut terms = self.time_terms.clone();
        terms.extend(sf.terms);
        for p in terms.iter_mut().flat_map(|t| t.params.iter_mut()) {
            p.unit = unit_on_axis(&p.unit, self.axis);
        }
        let n_time: usize = self.time_terms.iter().map(|t| t.params.len()).sum();
        Ok(FittedModel {
            axis: self.axis,
            spec: spec.clone(),
            terms,
            points: sf.points,
            fit_error: sf.fit_error.max(span_fit_error),
            whole_fit_error: sf.fit_error,
            chi2: sf.chi2,
            failing_tau: sf.failing_tau,
            failing_spans: failing_spans(&spans),
            spans,
            events: self.events.clone(),
            n_params: sf.n_params + n_time,
        })
    }
}

/// The spectral part of a fit: terms, points and the contract numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct CurveFit {
    /// Spectral terms in the order of the kinds given.
    pub terms: Vec<FittedTerm>,
    /// Measurement and model per τ.
    pub points: Vec<FitPoint>,
    /// RMS of z.
    pub fit_error: f64,
    /// Σ z².
    pub chi2: f64,
    /// Intervals with |z| > 3.
    pub failing_tau: Vec<[f64; 2]>,
    /// Free parameters (amplitudes and shape parameters).
    pub n_params: usize,
    /// The noise class of each term (same order), which sets the EDF of its share of an estimate.
    pub classes: Vec<NoiseClass>,
}

/// Fits spectral effects to Allan points (one DAVAR row, or a whole record).
///
/// This is the per-row fit of the live node and `src/pipeline.rs`: no time-domain effect, no
/// access to samples, cost O(K·J²) per weight iteration for K τ points and J terms (plus the 1-D
/// searches when a kind has a shape parameter). Time-domain kinds in `kinds` are ignored.
/// The EDF of each point is recomputed from the model's noise mix with n = terms + 2m phase points.
///
/// # Errors
/// [`FitError::Underdetermined`] with fewer τ points than parameters; [`FitError::Param`],
/// [`FitError::Nnls`] on degenerate input (non-finite variances).
///
/// An output effect (quantization) keeps its IEEE signature here: without the samples their mean
/// is unknown, and the undithered signature averaged over an unknown phase of the mean sweep is
/// exactly the IEEE law (the cos(2πkμ) terms of `rounding_excess` average to zero).
pub fn fit_curve(
    points: &[AllanPoint],
    kinds: &[&'static dyn EffectKind],
    weight_iterations: usize,
) -> Result<CurveFit, FitError> {
    fit_points(points, kinds, weight_iterations, SampleContext::default())
}

/// What the samples tell the spectral fit beyond the Allan points (nothing for a DAVAR row).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct SampleContext {
    /// Mean of the valid rate samples; `None` when the samples are not at hand.
    mean_rate: Option<f64>,
}

impl SampleContext {
    fn of(rate: &[f64]) -> Self {
        let (sum, n) = rate
            .iter()
            .filter(|y| y.is_finite())
            .fold((0.0, 0usize), |(s, n), y| (s + y, n + 1));
        SampleContext {
            mean_rate: (n > 0).then(|| sum / n as f64),
        }
    }
}

/// Log step of the scan over an output column's amplitude when no mean sweep is visible.
const SCAN_STEP: f64 = 0.02;
/// Most trial amplitudes in one scan (a strong sweep needs ~2000 for [q₀/2, 3q₀]).
const MAX_SCAN: usize = 4000;
/// Dither per sample (steps²) below which the phase of the mean sweep is visible:
/// exp(−2π²·0.7) ≈ 1e-6.
const PHASE_VISIBLE_V: f64 = 0.7;
/// Rounds of "recompute the dither from the other terms, refit them" at each trial amplitude of
/// an output column (the profile over the other amplitudes).
const PROFILE_ROUNDS: usize = 3;

/// [`fit_curve`] with what the samples tell: with their mean, output effects get their signature
/// on this axis ([`Effect::avar_on`]: quantization undithered by the other terms).
fn fit_points(
    points: &[AllanPoint],
    kinds: &[&'static dyn EffectKind],
    weight_iterations: usize,
    samples: SampleContext,
) -> Result<CurveFit, FitError> {
    let kinds: Vec<&'static dyn EffectKind> = kinds
        .iter()
        .copied()
        .filter(|k| k.domain() == Domain::Spectral)
        .collect();
    let points: Vec<AllanPoint> = points
        .iter()
        .copied()
        .filter(|p| p.avar.is_finite() && p.avar > 0.0 && p.tau > 0.0)
        .collect();
    let n_params: usize = kinds.iter().map(|k| k.schema().len()).sum();
    if points.len() < n_params.max(1) {
        return Err(FitError::Underdetermined {
            points: points.len(),
            params: n_params,
        });
    }
    let mut problem = Problem::new(&points, &kinds)?;
    let mut shapes = problem.initial_shapes();
    let iters = weight_iterations.max(1);
    if !shapes.is_empty() {
        shapes = problem.search_shapes(shapes, iters.min(3))?;
    }
    let mut sol = problem.solve(&shapes, iters)?;
    if let Some(mean_rate) = samples.mean_rate {
        sol = problem.settle_output_columns(mean_rate, &shapes, sol, iters)?;
    }
    problem.assemble(&kinds, &shapes, &sol, n_params)
}

/// One spectral kind as the solver sees it.
struct Column {
    kind: &'static dyn EffectKind,
    /// Reference amplitude used to evaluate the unit basis.
    amp_ref: f64,
    class: NoiseClass,
    /// For each shape parameter: (index in schema, log-range lo, log-range hi).
    shapes: Vec<(usize, f64, f64)>,
}

struct Problem<'a> {
    points: &'a [AllanPoint],
    columns: Vec<Column>,
    /// Set by [`Problem::settle_output_columns`]: what the output columns are computed from
    /// (without it they use [`Effect::avar`]).
    output: Option<OutputState>,
    /// Columns left out of the model (zero basis) while [`Problem::search_shapes`] has not yet
    /// searched their shapes.
    muted: Vec<bool>,
}

/// The state an output column's signature is computed from.
#[derive(Clone)]
struct OutputState {
    /// Mean of the rate samples.
    mean_rate: f64,
    /// Squared amplitudes of all columns (the output ones and the others, which dither them).
    c: Vec<f64>,
    /// True: the output columns are held at `c` (their curves are a fixed part of the model and
    /// their basis columns are zero); false: they are columns per unit amplitude like the others.
    fixed: bool,
    /// While held: ∂(output curves)/∂c_i at `c` for each column i (empty: none), so that a solve
    /// is a Gauss–Newton step on the model's true dependence on the other amplitudes (they
    /// dither the quantizer: with little dither, more white noise *lowers* the quantizer's
    /// short-τ part by about as much as it adds itself).
    jacobian: Vec<Vec<f64>>,
}

/// A weighted NNLS solution at fixed shape parameters.
struct Solution {
    /// Squared amplitudes c_j.
    c: Vec<f64>,
    meas: Vec<f64>,
    model: Vec<f64>,
    edf: Vec<f64>,
    z: Vec<f64>,
    chi2: f64,
    /// Per-column basis values (unit amplitude) at each point.
    basis: Vec<Vec<f64>>,
}

impl<'a> Problem<'a> {
    fn new(points: &'a [AllanPoint], kinds: &[&'static dyn EffectKind]) -> Result<Self, FitError> {
        let tau_min = points.first().map_or(1.0, |p| p.tau);
        let tau_max = points.last().map_or(1.0, |p| p.tau);
        let columns = kinds
            .iter()
            .map(|&kind| {
                let schema = kind.schema();
                let (lo, hi) = schema[0].bounds;
                let amp_ref = if lo <= 1.0 && 1.0 <= hi { 1.0 } else { hi.min(lo.abs().max(hi) * 0.5) };
                let shapes = schema
                    .iter()
                    .enumerate()
                    .skip(1)
                    .map(|(i, s)| {
                        // A time constant shorter than the shortest τ is a filter, not a wandering
                        // bias: that regime belongs to the kinds that say so (`search_range`).
                        let (a, b) = kind.search_range(i, tau_min, tau_max).unwrap_or(match s.unit {
                            "Hz" => (1.0 / (4.0 * tau_max), 1.0 / (2.0 * tau_min)),
                            _ => (tau_min, 4.0 * tau_max),
                        });
                        let a = a.max(s.bounds.0).max(f64::MIN_POSITIVE);
                        let b = b.min(s.bounds.1).max(a);
                        (i, a.ln(), b.ln())
                    })
                    .collect();
                Column {
                    kind,
                    amp_ref,
                    class: NoiseClass::WhiteFm,
                    shapes,
                }
            })
            .collect::<Vec<_>>();
        let mut problem = Problem {
            points,
            columns,
            output: None,
            muted: Vec::new(),
        };
        for j in 0..problem.columns.len() {
            let shapes = problem.initial_shapes();
            let eff = problem.build(j, 1.0, &shapes)?;
            problem.columns[j].class = NoiseClass::from_slope(eff.explain().avar_slope);
        }
        Ok(problem)
    }

    /// Middle of each shape range, flattened over columns, log scale.
    fn initial_shapes(&self) -> Vec<f64> {
        self.columns
            .iter()
            .flat_map(|c| c.shapes.iter().map(|&(_, lo, hi)| 0.5 * (lo + hi)))
            .collect()
    }

    /// Builds column j's effect with amplitude `amp` and the shapes (log) of `shapes`.
    fn build(&self, j: usize, amp: f64, shapes: &[f64]) -> Result<Box<dyn Effect>, FitError> {
        let col = &self.columns[j];
        let offset: usize = self.columns[..j].iter().map(|c| c.shapes.len()).sum();
        let mut values = vec![amp; col.kind.schema().len()];
        for (k, &(i, _, _)) in col.shapes.iter().enumerate() {
            values[i] = shapes[offset + k].exp();
        }
        Ok(col.kind.build(&values)?)
    }

    fn basis(&self, shapes: &[f64]) -> Result<Vec<Vec<f64>>, FitError> {
        (0..self.columns.len())
            .map(|j| {
                if self.muted.get(j).copied().unwrap_or(false) {
                    return Ok(vec![0.0; self.points.len()]);
                }
                if let Some(col) = self.output_basis(j, shapes)? {
                    return Ok(col);
                }
                let a = self.columns[j].amp_ref;
                let eff = self.build(j, a, shapes)?;
                let slope = self.output.as_ref().and_then(|s| s.jacobian.get(j));
                Ok(self
                    .points
                    .iter()
                    .enumerate()
                    .map(|(i, p)| {
                        eff.avar(p.tau).unwrap_or(0.0).max(0.0) / (a * a)
                            + slope.map_or(0.0, |d| d[i])
                    })
                    .collect())
            })
            .collect()
    }

    fn is_output(&self, j: usize) -> bool {
        self.columns[j].kind.sim_stage() == SimStage::Output
    }

    /// Column j per unit squared amplitude when it is an output effect with a current state:
    /// zero while the output columns are held fixed (their curves are then [`Problem::offset`]),
    /// otherwise its curve at the state divided by its squared amplitude.
    fn output_basis(&self, j: usize, shapes: &[f64]) -> Result<Option<Vec<f64>>, FitError> {
        let Some(state) = self.output.as_ref() else {
            return Ok(None);
        };
        if !self.is_output(j) {
            return Ok(None);
        }
        if state.fixed {
            return Ok(Some(vec![0.0; self.points.len()]));
        }
        if state.c[j] <= 0.0 {
            return Ok(None);
        }
        let curve = self.output_curve(j, shapes, state)?;
        Ok(Some(curve.iter().map(|v| v / state.c[j]).collect()))
    }

    /// σ²(τ) of output column j at the state's amplitudes: its signature given the samples' mean
    /// and the other columns' noise (angle structure function D(τ) ≈ τ²·Σ σ²_other(τ), exact for
    /// white noise, whose dither is the one that matters at short τ).
    fn output_curve(&self, j: usize, shapes: &[f64], state: &OutputState) -> Result<Vec<f64>, FitError> {
        let c = &state.c;
        if c[j] <= 0.0 {
            return Ok(vec![0.0; self.points.len()]);
        }
        let others = (0..self.columns.len())
            .filter(|&i| !self.is_output(i) && c[i] > 0.0)
            .map(|i| self.build(i, c[i].sqrt(), shapes))
            .collect::<Result<Vec<_>, _>>()?;
        let noise = |tau: f64| {
            tau * tau * others.iter().map(|e| e.avar(tau).unwrap_or(0.0).max(0.0)).sum::<f64>()
        };
        let rest = OutputContext { mean_rate: state.mean_rate, noise: &noise };
        let eff = self.build(j, c[j].sqrt(), shapes)?;
        Ok(self
            .points
            .iter()
            .map(|p| eff.avar_on(p.tau, &rest).unwrap_or(0.0).max(0.0))
            .collect())
    }

    /// The part of the model held fixed: the output columns' curves while they are held, less
    /// their linear part in the other amplitudes (which [`Problem::basis`] adds to those columns).
    fn offset(&self, shapes: &[f64]) -> Result<Vec<f64>, FitError> {
        let mut sum = vec![0.0; self.points.len()];
        if let Some(state) = self.output.as_ref().filter(|s| s.fixed) {
            sum = self.output_curves(shapes, state)?;
            for (d, c) in state.jacobian.iter().zip(&state.c) {
                for (s, v) in sum.iter_mut().zip(d) {
                    *s -= c * v;
                }
            }
        }
        Ok(sum)
    }

    /// Angle structure function τ²·Σ σ²_i(τ) of the non-output columns at amplitudes √c.
    fn other_noise(&self, shapes: &[f64], c: &[f64], tau: f64) -> Result<f64, FitError> {
        let mut sum = 0.0;
        for i in (0..self.columns.len()).filter(|&i| !self.is_output(i) && c[i] > 0.0) {
            sum += self.build(i, c[i].sqrt(), shapes)?.avar(tau).unwrap_or(0.0).max(0.0);
        }
        Ok(tau * tau * sum)
    }

    /// Σ of the output columns' curves at `state`.
    fn output_curves(&self, shapes: &[f64], state: &OutputState) -> Result<Vec<f64>, FitError> {
        let mut sum = vec![0.0; self.points.len()];
        for j in (0..self.columns.len()).filter(|&j| self.is_output(j)) {
            for (s, v) in sum.iter_mut().zip(self.output_curve(j, shapes, state)?) {
                *s += v;
            }
        }
        Ok(sum)
    }

    /// ∂(output curves)/∂c_i at `state` for every non-output column i, by forward differences of
    /// 5 % of max(c_i, scale_i/100) (zero for a column with no scale).
    fn output_jacobian(&self, shapes: &[f64], state: &OutputState, scale: &[f64]) -> Result<Vec<Vec<f64>>, FitError> {
        let base = self.output_curves(shapes, state)?;
        (0..self.columns.len())
            .map(|i| {
                let h = 0.05 * state.c[i].max(0.01 * scale[i]);
                if self.is_output(i) || h <= 0.0 {
                    return Ok(vec![0.0; self.points.len()]);
                }
                let mut up = state.clone();
                up.c[i] += h;
                let moved = self.output_curves(shapes, &up)?;
                Ok(moved.iter().zip(&base).map(|(a, b)| (a - b) / h).collect())
            })
            .collect()
    }

    /// Fits the output columns (a quantizer), whose signature depends on their own amplitude and
    /// on the other terms (the dither), by a profile search over each one's amplitude q.
    ///
    /// At each trial q the column is held at q² and the other amplitudes are refitted, with the
    /// dither recomputed from them ([`PROFILE_ROUNDS`]); the q of least cost wins (a log scan of
    /// [q₀/2, 3q₀] around the IEEE fit's q₀, then golden section). A plain fixed point (column
    /// from the current fit, refit, repeat) was rejected: it is not the least-squares optimum —
    /// measured, it settled on N = 5.5e-5 instead of 1.5e-4 with q 55 % high on a deeply
    /// undithered gyro, and on the wrong phase of a gravity sweep. The scan step resolves the
    /// phase of a mean sweep: the signature at τ0 changes with frac(mean·τ0/δ), which turns once
    /// per 1/μ₁ in ln q (μ₁ = |mean|·τ0/δ steps per sample). Shape parameters stay those found
    /// with the IEEE columns.
    fn settle_output_columns(
        &mut self,
        mean_rate: f64,
        shapes: &[f64],
        sol: Solution,
        iters: usize,
    ) -> Result<Solution, FitError> {
        let outputs: Vec<usize> = (0..self.columns.len()).filter(|&j| self.is_output(j)).collect();
        let mut best_c = sol.c.clone();
        let scale = sol.c.clone();
        let mut best: Option<(f64, Solution)> = None;
        let tau_min = self.points.first().map_or(1.0, |p| p.tau);
        for &j in &outputs {
            let q0 = best_c[j].sqrt();
            if q0 <= 0.0 {
                continue;
            }
            // The phase of the mean sweep matters only while the dither per sample is below a
            // step (exp(−2π²v₁) is its weight); then the scan must resolve 1/μ₁ in ln q.
            let step_max = 3.0 * q0 * 12f64.sqrt();
            let v1 = self.other_noise(shapes, &best_c, tau_min)? / (step_max * step_max);
            let mu1 = mean_rate.abs() * tau_min / (q0 * 12f64.sqrt());
            let step = if v1 < PHASE_VISIBLE_V {
                SCAN_STEP.min(0.06 / mu1.max(1e-9))
            } else {
                SCAN_STEP
            };
            let (mut lo, mut hi) = ((0.5 * q0).ln(), (3.0 * q0).ln());
            let mut start = best_c.clone();
            let mut scan_best = (f64::INFINITY, lo);
            let mut refine_from = best_c.clone();
            // A fine scan moves q by < 1 % a step, so one round from the previous trial's
            // amplitudes follows the others closely enough (the refinement does all rounds).
            let scan_rounds = if step < SCAN_STEP { 1 } else { PROFILE_ROUNDS };
            // Extend the scan upwards while its best is at the top (a deeply undithered
            // quantizer looks far smaller to the IEEE law than it is), at most to 100·q₀.
            for _ in 0..4 {
                let n = (((hi - lo) / step).ceil() as usize).clamp(1, MAX_SCAN);
                for i in 0..=n {
                    let lq = lo + (hi - lo) * i as f64 / n as f64;
                    let (cost, s) = self.profile(j, lq.exp(), &start, &scale, mean_rate, shapes, iters, scan_rounds)?;
                    start = s.c.clone();
                    if cost < scan_best.0 {
                        scan_best = (cost, lq);
                        refine_from.clone_from(&s.c);
                    }
                }
                if scan_best.1 < hi - 1.5 * step || hi > (100.0 * q0).ln() {
                    break;
                }
                (lo, hi) = (hi, hi + 3f64.ln());
            }
            let mid = golden_section(scan_best.1 - step, scan_best.1 + step, 24, |lq| {
                Ok(self.profile(j, lq.exp(), &refine_from, &scale, mean_rate, shapes, iters, PROFILE_ROUNDS)?.0)
            })?;
            let lq = if self.profile(j, mid.exp(), &refine_from, &scale, mean_rate, shapes, iters, PROFILE_ROUNDS)?.0 <= scan_best.0 {
                mid
            } else {
                scan_best.1
            };
            let (cost, s) = self.profile(j, lq.exp(), &refine_from, &scale, mean_rate, shapes, iters, PROFILE_ROUNDS)?;
            best_c = s.c.clone();
            best = Some((cost, s));
        }
        let Some((_, sol)) = best else {
            return Ok(sol);
        };
        // The output columns stay at the winning state (per unit amplitude, like the others), so
        // that the covariance sees the basis the amplitudes came from.
        self.output = Some(OutputState { mean_rate, c: best_c, fixed: false, jacobian: Vec::new() });
        Ok(sol)
    }

    /// The fit with output column j held at amplitude `q` and the others refitted, the dither
    /// recomputed from them each round; returns its cost and the solution (with c[j] = q²).
    #[allow(clippy::too_many_arguments)]
    fn profile(
        &mut self,
        j: usize,
        q: f64,
        start: &[f64],
        scale: &[f64],
        mean_rate: f64,
        shapes: &[f64],
        iters: usize,
        rounds: usize,
    ) -> Result<(f64, Solution), FitError> {
        let mut c = start.to_vec();
        let mut edf = Vec::new();
        for _ in 0..rounds.max(1) {
            c[j] = q * q;
            let mut state = OutputState { mean_rate, c: c.clone(), fixed: true, jacobian: Vec::new() };
            state.jacobian = self.output_jacobian(shapes, &state, scale)?;
            self.output = Some(state);
            let s = self.solve(shapes, iters)?;
            c = s.c.clone();
            edf = s.edf;
        }
        c[j] = q * q;
        // The model as it is at these amplitudes (not its linearisation), and its cost.
        self.output = Some(OutputState { mean_rate, c: c.clone(), fixed: false, jacobian: Vec::new() });
        let basis = self.basis(shapes)?;
        let meas: Vec<f64> = self.points.iter().map(|p| p.avar).collect();
        let model: Vec<f64> = (0..meas.len())
            .map(|i| c.iter().zip(&basis).map(|(cj, b)| cj * b[i]).sum())
            .collect();
        let cost = log_cost(&meas, &model, &edf);
        let z = z_scores(&meas, &model, &edf);
        let chi2 = z.iter().map(|v| v * v).sum();
        let sol = Solution { c, meas, model, edf, z, chi2, basis };
        Ok((if cost.is_finite() { cost } else { f64::MAX }, sol))
    }

    fn n_phase(p: &AllanPoint) -> usize {
        p.terms + 2 * p.m
    }

    /// Weighted NNLS with the weights and EDF iterated on the model.
    fn solve(&self, shapes: &[f64], iterations: usize) -> Result<Solution, FitError> {
        let basis = self.basis(shapes)?;
        let offset = self.offset(shapes)?;
        let offset_class = (0..self.columns.len())
            .find(|&j| self.is_output(j))
            .map_or(NoiseClass::WhitePm, |j| self.columns[j].class);
        let k = self.points.len();
        let jn = self.columns.len();
        let meas: Vec<f64> = self.points.iter().map(|p| p.avar).collect();
        let mut edf: Vec<f64> = self
            .points
            .iter()
            .map(|p| crate::model::measure::edf_oavar(NoiseClass::WhiteFm, Self::n_phase(p), p.m))
            .collect();
        let mut model = meas.clone();
        let mut c = vec![0.0; jn];
        let mut best_cost = f64::INFINITY;
        for _ in 0..iterations {
            // Iteratively reweighted Gauss–Newton on [`log_cost`], linearised around the current
            // model: target tᵢ = modelᵢ·(1 + ln(measᵢ/modelᵢ)), weight 1/(modelᵢ·√(2/wᵢ)) with
            // wᵢ = edfᵢ/(1 + zᵢ²/C²) ([`robust_edf`]).
            let wedf = robust_edf(&meas, &model, &edf);
            let sd: Vec<f64> = (0..k)
                .map(|i| {
                    let base = if model[i] > 0.0 { model[i] } else { meas[i] };
                    base * (2.0 / wedf[i]).sqrt()
                })
                .collect();
            let target: Vec<f64> = (0..k)
                .map(|i| {
                    if model[i] > 0.0 {
                        model[i] * (1.0 + (meas[i] / model[i]).ln() - log_bias(edf[i]))
                    } else {
                        meas[i]
                    }
                })
                .collect();
            let a = DMatrix::from_fn(k, jn, |i, j| basis[j][i] / sd[i]);
            let b = DVector::from_fn(k, |i, _| (target[i] - offset[i]) / sd[i]);
            let x = nnls(&a, &b)?;
            let mut trial: Vec<f64> = x.iter().copied().collect();
            // Damping: halve the step toward the new solution while the log cost rises.
            for _ in 0..8 {
                let m: Vec<f64> = (0..k)
                    .map(|i| offset[i] + (0..jn).map(|j| trial[j] * basis[j][i]).sum::<f64>())
                    .collect();
                let cost = log_cost(&meas, &m, &edf);
                if cost <= best_cost || best_cost.is_infinite() {
                    break;
                }
                trial = trial.iter().zip(&c).map(|(t, o)| 0.5 * (t + o)).collect();
            }
            c = trial;
            for i in 0..k {
                let parts: Vec<(f64, NoiseClass)> = (0..jn)
                    .map(|j| (c[j] * basis[j][i], self.columns[j].class))
                    .chain((offset[i] > 0.0).then_some((offset[i], offset_class)))
                    .collect();
                model[i] = parts.iter().map(|p| p.0).sum();
                let p = &self.points[i];
                edf[i] = edf_for_mix(&parts, Self::n_phase(p), p.m);
            }
            best_cost = log_cost(&meas, &model, &edf);
        }
        let z = z_scores(&meas, &model, &edf);
        let chi2 = z.iter().map(|v| v * v).sum();
        Ok(Solution { c, meas, model, edf, z, chi2, basis })
    }

    /// Coordinate search over the shape parameters: a log grid scan, then golden-section refinement.
    ///
    /// The first round is stagewise: a column whose shapes have not been searched yet is left out
    /// of the model (muted) while the columns before it are searched, then every column takes part.
    /// Why: an unsearched column sits at the middle of its range, and there it may hold a feature
    /// that another column would otherwise take — a second line (`vibration`) starting at 0.18 Hz
    /// took a 0.2 Hz line before the `sinusoid` was searched, which then went to the other line:
    /// the suggestion read "add vibration at 0.2 Hz" beside a model whose sinusoid was at 0.2 Hz.
    fn search_shapes(&mut self, mut shapes: Vec<f64>, iters: usize) -> Result<Vec<f64>, FitError> {
        let ranges: Vec<(f64, f64)> = self
            .columns
            .iter()
            .flat_map(|c| c.shapes.iter().map(|&(_, lo, hi)| (lo, hi)))
            .collect();
        // The first shape dimension of each column, or None for a column without shapes.
        let mut first_dim = Vec::with_capacity(self.columns.len());
        let mut next = 0;
        for c in &self.columns {
            first_dim.push((!c.shapes.is_empty()).then_some(next));
            next += c.shapes.len();
        }
        let rounds = if shapes.len() > 1 { 2 } else { 1 };
        for round in 0..rounds {
            for (d, &(lo, hi)) in ranges.iter().enumerate() {
                self.muted = first_dim.iter().map(|f| round == 0 && f.is_some_and(|f| f > d)).collect();
                let cost = |s: &[f64]| -> Result<f64, FitError> {
                    let sol = self.solve(s, iters)?;
                    let cost = log_cost(&sol.meas, &sol.model, &sol.edf);
                    Ok(if cost.is_finite() { cost } else { f64::MAX })
                };
                // 40 points per decade: neighbouring candidates differ by 6 %.
                let steps = (((hi - lo) / std::f64::consts::LN_10) * 40.0).ceil().max(8.0) as usize;
                let h = (hi - lo) / steps as f64;
                let mut best = (f64::MAX, shapes[d]);
                for s in 0..=steps {
                    let mut trial = shapes.clone();
                    trial[d] = lo + h * s as f64;
                    let c = cost(&trial)?;
                    if c < best.0 {
                        best = (c, trial[d]);
                    }
                }
                let eval = |v: f64, base: &Vec<f64>| -> Result<f64, FitError> {
                    let mut t = base.clone();
                    t[d] = v;
                    cost(&t)
                };
                let mid = golden_section((best.1 - h).max(lo), (best.1 + h).min(hi), 30, |v| eval(v, &shapes))?;
                shapes[d] = if eval(mid, &shapes)? <= best.0 { mid } else { best.1 };
            }
        }
        self.muted.clear();
        Ok(shapes)
    }

    /// Builds terms, points and uncertainties from a solution.
    fn assemble(
        &self,
        kinds: &[&'static dyn EffectKind],
        shapes: &[f64],
        sol: &Solution,
        n_params: usize,
    ) -> Result<CurveFit, FitError> {
        let cov = self.covariance(shapes, sol);
        let mut terms = Vec::with_capacity(kinds.len());
        let mut offset = 0;
        for (j, col) in self.columns.iter().enumerate() {
            let amp = sol.c[j].max(0.0).sqrt();
            let eff = self.build(j, amp, shapes)?;
            let mut sigmas = vec![None; col.kind.schema().len()];
            if let Some(var_c) = cov.as_ref().and_then(|c| c.get(j).copied().flatten()) {
                sigmas[0] = Some(if amp > 0.0 {
                    var_c.sqrt() / (2.0 * amp)
                } else {
                    var_c.sqrt().sqrt()
                });
            }
            for (k, &(i, _, _)) in col.shapes.iter().enumerate() {
                let idx = self.columns.len() + offset + k;
                if let Some(v) = cov.as_ref().and_then(|c| c.get(idx).copied().flatten()) {
                    sigmas[i] = Some(shapes[offset + k].exp() * v.sqrt());
                }
            }
            offset += col.shapes.len();
            let curve = sol.basis[j].iter().map(|b| b * sol.c[j]).collect();
            terms.push(term_of(&*eff, &sigmas, curve));
        }
        let points: Vec<FitPoint> = self
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| FitPoint {
                m: p.m,
                tau: p.tau,
                measured: p.avar,
                model: sol.model[i],
                edf: sol.edf[i],
                ci: chi2_interval(p.avar, sol.edf[i]),
                z: sol.z[i],
                bridged: false,
            })
            .collect();
        let taus: Vec<f64> = points.iter().map(|p| p.tau).collect();
        Ok(CurveFit {
            failing_tau: failing_tau(&taus, &sol.z),
            fit_error: rms(&sol.z),
            chi2: sol.chi2,
            terms,
            points,
            n_params,
            classes: self.columns.iter().map(|c| c.class).collect(),
        })
    }

    /// Variances of [c_1..c_J, log-shape_1..] from the generalised least-squares normal matrix
    /// Jᵀ·R⁻¹·J at the solution (active amplitudes only), scaled by max(1, χ²/dof), where R is the
    /// correlation of the Allan estimates between τ points ([`tau_correlation`]).
    fn covariance(&self, shapes: &[f64], sol: &Solution) -> Option<Vec<Option<f64>>> {
        // An amplitude at its bound (0) still gets the curvature of the cost there: its σ says how
        // large the term could be (reported as √σ_c). Should that make the matrix singular, the
        // bound terms are left out.
        let at_bound = |j: usize| sol.c[j] <= 0.0 && self.columns[j].shapes.is_empty();
        self.covariance_of(shapes, sol, |j| sol.c[j] > 0.0 || at_bound(j))
            .or_else(|| self.covariance_of(shapes, sol, |j| sol.c[j] > 0.0))
    }

    fn covariance_of(
        &self,
        shapes: &[f64],
        sol: &Solution,
        included: impl Fn(usize) -> bool,
    ) -> Option<Vec<Option<f64>>> {
        let k = self.points.len();
        let jn = self.columns.len();
        let sd: Vec<f64> = (0..k)
            .map(|i| sol.model[i].max(f64::MIN_POSITIVE) * (2.0 / sol.edf[i]).sqrt())
            .collect();
        let active: Vec<usize> = (0..jn).filter(|&j| included(j)).collect();
        let mut cols: Vec<Vec<f64>> = active
            .iter()
            .map(|&j| (0..k).map(|i| sol.basis[j][i] / sd[i]).collect())
            .collect();
        let mut index: Vec<usize> = active.clone();
        // Shape derivatives by central differences of the model, at fixed amplitudes.
        let h = 1e-4;
        for d in 0..shapes.len() {
            let mut up = shapes.to_vec();
            let mut dn = shapes.to_vec();
            up[d] += h;
            dn[d] -= h;
            let (bu, bd) = (self.basis(&up).ok()?, self.basis(&dn).ok()?);
            let col: Vec<f64> = (0..k)
                .map(|i| {
                    let mu: f64 = (0..jn).map(|j| sol.c[j] * bu[j][i]).sum();
                    let md: f64 = (0..jn).map(|j| sol.c[j] * bd[j][i]).sum();
                    (mu - md) / (2.0 * h) / sd[i]
                })
                .collect();
            cols.push(col);
            index.push(jn + d);
        }
        if cols.is_empty() {
            return Some(vec![None; jn + shapes.len()]);
        }
        let jac = DMatrix::from_fn(k, cols.len(), |i, c| cols[c][i]);
        let length: Vec<f64> = (0..k)
            .map(|i| {
                let total: f64 = (0..jn).map(|j| sol.c[j] * sol.basis[j][i]).sum();
                let weighted: f64 = (0..jn)
                    .map(|j| sol.c[j] * sol.basis[j][i] * self.columns[j].class.correlation_length())
                    .sum();
                if total > 0.0 {
                    weighted / total
                } else {
                    NoiseClass::WhiteFm.correlation_length()
                }
            })
            .collect();
        let taus: Vec<f64> = self.points.iter().map(|p| p.tau).collect();
        let r = tau_correlation(&taus, &length).cholesky()?;
        let normal = jac.transpose() * r.solve(&jac);
        let inv = normal.try_inverse()?;
        let dof = k.saturating_sub(cols.len()).max(1) as f64;
        // The generalised χ² (zᵀ R⁻¹ z): residuals that do not follow the smooth correlation of
        // the estimates (a misfit) widen the intervals.
        let z = DVector::from_column_slice(&sol.z);
        let chi2_gls = z.dot(&r.solve(&z));
        let scale = (chi2_gls / dof).max(1.0);
        let mut out = vec![None; jn + shapes.len()];
        for (c, &idx) in index.iter().enumerate() {
            let v = inv[(c, c)] * scale;
            if v.is_finite() && v >= 0.0 {
                out[idx] = Some(v);
            }
        }
        Some(out)
    }
}

/// Golden-section search for the minimum of a unimodal `f` on [a, b]: `iterations` shrinkings of
/// the bracket by 0.618, each with one new evaluation. Returns the final bracket's midpoint.
fn golden_section(
    mut a: f64,
    mut b: f64,
    iterations: usize,
    mut f: impl FnMut(f64) -> Result<f64, FitError>,
) -> Result<f64, FitError> {
    const G: f64 = 0.618_033_988_749_895;
    let mut x1 = b - G * (b - a);
    let mut x2 = a + G * (b - a);
    let (mut f1, mut f2) = (f(x1)?, f(x2)?);
    for _ in 0..iterations {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - G * (b - a);
            f1 = f(x1)?;
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + G * (b - a);
            f2 = f(x2)?;
        }
    }
    Ok(0.5 * (a + b))
}

/// Scale C of the robust loss, in units of z: points beyond |z| ≈ C lose their pull on the fit.
///
/// Why robust: with diagonal weights EDF/2 a few τ points of very large EDF (the shortest τ of a long
/// record) or a bump the model cannot follow (a vibration line) pulled a wrong model off *every*
/// point — on the ADIS16405's accel axes N,B,K lay above all points from 1.5 to 20 s. With the
/// Cauchy loss the points the model cannot explain stop dictating it, and it follows the others,
/// failing (large |z|) only where it fails. C = 3 is the contract's failing |z|; for a model that
/// explains the data (|z| ~ N(0,1)) the weights are 0.9 ± 0.1 and the estimates move little.
const ROBUST_C: f64 = 3.0;

/// zᵢ of the log fit: √(edfᵢ/2)·(ln(measᵢ/modelᵢ) − bias(edfᵢ)), the standardised log residual.
fn log_z(y: f64, m: f64, e: f64) -> f64 {
    (0.5 * e).sqrt() * ((y / m).ln() - log_bias(e))
}

/// The fit's objective: Σ C²·ln(1 + zᵢ²/C²) over the log residuals zᵢ ([`log_z`]) — the Cauchy
/// (Lorentzian) loss of the log-normal approximation of the χ² likelihood of AVAR estimates
/// (Σ zᵢ² for small z). In log σ² it weighs over- and under-prediction alike, where the contract's
/// z (scaled by the model) forgives a model that over-predicts where the EDF is small.
///
/// # References
/// P. J. Huber, E. M. Ronchetti, "Robust Statistics", 2nd ed., Wiley 2009, §7 (M-estimators,
/// iteratively reweighted least squares).
fn log_cost(meas: &[f64], model: &[f64], edf: &[f64]) -> f64 {
    meas.iter()
        .zip(model)
        .zip(edf)
        .map(|((&y, &m), &e)| {
            if m > 0.0 {
                ROBUST_C * ROBUST_C * (log_z(y, m, e) / ROBUST_C).powi(2).ln_1p()
            } else {
                f64::MAX / 1e3
            }
        })
        .sum()
}

/// The IRLS weights of [`log_cost`] as effective EDFs: edfᵢ/(1 + zᵢ²/C²) at the current model.
fn robust_edf(meas: &[f64], model: &[f64], edf: &[f64]) -> Vec<f64> {
    meas.iter()
        .zip(model)
        .zip(edf)
        .map(|((&y, &m), &e)| {
            let z = if m > 0.0 && y > 0.0 { log_z(y, m, e) } else { 0.0 };
            e / (1.0 + (z / ROBUST_C).powi(2))
        })
        .collect()
}

/// E[ln(σ̂²/σ²)] for an estimate with `edf` degrees of freedom: the log of a χ²_ν/ν variable is
/// biased low, by ψ(ν/2) − ln(ν/2) ≈ −1/ν − 1/(3ν²); without this a log fit would pull the model
/// down where the EDF is small (long τ).
fn log_bias(edf: f64) -> f64 {
    let nu = edf.max(1.0);
    -1.0 / nu - 1.0 / (3.0 * nu * nu)
}

/// Correlation matrix of overlapping Allan estimates at the τ points `taus`, for a local
/// correlation length `length` in ln τ (per point, from the noise mix:
/// [`NoiseClass::correlation_length`]).
///
/// # Formula
/// ```text
/// uᵢ = Σ_{l<i} ln(τ_{l+1}/τ_l) / (½(ℓ_l + ℓ_{l+1}))
/// Rᵢⱼ = (1 − η)·exp(−(uᵢ − uⱼ)²) + η·δᵢⱼ,     η = 0.01
/// ```
/// For a constant ℓ, ρ = exp(−(ln(τ₂/τ₁)/ℓ)²), the measured correlation of two estimates; warping
/// ln τ by the local ℓ keeps R positive definite (a Gaussian kernel on u) when the noise class
/// changes along the grid. η keeps the matrix invertible on a dense grid (the estimates are not
/// exactly a smooth curve of τ: at τ ratio 1.26 they correlate at 0.91–0.985, not 1). Why it
/// matters: with ten τ per decade the points are far from independent, and treating them as
/// independent understated every uncertainty (1σ covered N, B, K 7, 6 and 3 times in 12).
pub fn tau_correlation(taus: &[f64], length: &[f64]) -> DMatrix<f64> {
    const NUGGET: f64 = 0.01;
    let mut u = vec![0.0; taus.len()];
    for i in 1..taus.len() {
        let step = (taus[i] / taus[i - 1]).ln().abs();
        u[i] = u[i - 1] + step / (0.5 * (length[i] + length[i - 1]));
    }
    DMatrix::from_fn(taus.len(), taus.len(), |i, j| {
        let smooth = (-(u[i] - u[j]).powi(2)).exp();
        (1.0 - NUGGET) * smooth + if i == j { NUGGET } else { 0.0 }
    })
}

/// A term from an effect and the uncertainties of its parameters.
fn term_of(effect: &dyn Effect, sigmas: &[Option<f64>], curve: Vec<f64>) -> FittedTerm {
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
