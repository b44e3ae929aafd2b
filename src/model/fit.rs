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
//! The weights are those of the contract's z score: the standard deviation of an AVAR estimate is
//! σ²_model·√(2/EDF), with the EDF of the model's own noise mix at each τ, iterated with the fit.
//!
//! Conventions the fitter relies on (the effect files follow them): a spectral effect's σ²(τ) is
//! proportional to the square of its *first* parameter (the amplitude); its other parameters are
//! shape parameters, searched on a log scale over the range the τ grid can see (unit `s`: τmin/4
//! to 4·τmax; unit `Hz`: the inverse).
//!
//! # References
//! IEEE Std 952-1997, Annex C; Riley, NIST SP 1065 (2008), §5.2.4, Table 12; Lawson & Hanson (1974).

use crate::allan::{AllanPoint, TauGrid};
use crate::model::effects::{unit_on_axis, Domain, Effect, EffectKind, ParamError};
use crate::allan::oavar_rate;
use crate::model::measure::{chi2_interval, edf_for_mix, NoiseClass};
use crate::model::nnls::{nnls, NnlsError};
use crate::model::spec::{ModelSpec, SpecError};
use crate::model::timedomain;
use crate::signal::Axis;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// |z| above which a τ is "failing" (DESIGN §5, **contract**).
pub const FAILING_Z: f64 = 3.0;

/// Fewest rate samples a whole-record fit accepts.
pub const MIN_SAMPLES: usize = 64;

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
    /// Largest averaging factor as a fraction of the record (DESIGN §2: W/3).
    pub max_m_fraction: f64,
    /// Rounds of "fit, recompute weights and EDF from the model".
    pub weight_iterations: usize,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            grid: TauGrid::default(),
            max_m_fraction: 1.0 / 3.0,
            weight_iterations: 6,
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
    /// **contract**: RMS of z over the τ grid.
    pub fit_error: f64,
    /// Σ z².
    pub chi2: f64,
    /// **contract**: maximal τ intervals where |z| > 3, seconds.
    pub failing_tau: Vec<[f64; 2]>,
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

/// A record with its time-domain effects estimated and removed, and its Allan variance measured.
///
/// Kept so that the diagnosis can try several spectral additions without measuring again.
#[derive(Clone)]
pub struct Prepared {
    axis: Axis,
    /// The measured Allan variance of the cleaned series.
    pub points: Vec<AllanPoint>,
    time_terms: Vec<FittedTerm>,
    events: Vec<Event>,
    /// Spectral kinds of the spec.
    pub spectral_kinds: Vec<&'static dyn EffectKind>,
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
    let mut series = input.rate.to_vec();
    let mut time_terms = Vec::new();
    let mut events: Vec<Event> = input
        .events
        .iter()
        .map(|s| Event {
            effect: "davar_change".into(),
            params: vec![("start_s".into(), s.start_s), ("end_s".into(), s.end_s)],
        })
        .collect();
    for kind in timedomain::in_estimation_order(&time_kinds) {
        let est = timedomain::estimate(kind, input, &series)?;
        let effect = kind.build(&est.values)?;
        timedomain::remove(kind, &est, input, &mut series);
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
    let points = oavar_rate(&series, input.tau0, &factors);
    Ok(Prepared {
        axis: input.axis,
        points,
        time_terms,
        events,
        spectral_kinds,
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
        let sf = fit_curve(&self.points, kinds, opts.weight_iterations)?;
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
            fit_error: sf.fit_error,
            chi2: sf.chi2,
            failing_tau: sf.failing_tau,
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
pub fn fit_curve(
    points: &[AllanPoint],
    kinds: &[&'static dyn EffectKind],
    weight_iterations: usize,
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
    let problem = Problem::new(&points, &kinds)?;
    let mut shapes = problem.initial_shapes();
    let iters = weight_iterations.max(1);
    if !shapes.is_empty() {
        shapes = problem.search_shapes(shapes, iters.min(3))?;
    }
    let sol = problem.solve(&shapes, iters)?;
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
                        let (a, b) = match s.unit {
                            "Hz" => (1.0 / (4.0 * tau_max), 1.0 / (2.0 * tau_min)),
                            _ => (tau_min / 4.0, 4.0 * tau_max),
                        };
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
        let mut problem = Problem { points, columns };
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
                let a = self.columns[j].amp_ref;
                let eff = self.build(j, a, shapes)?;
                Ok(self
                    .points
                    .iter()
                    .map(|p| eff.avar(p.tau).unwrap_or(0.0).max(0.0) / (a * a))
                    .collect())
            })
            .collect()
    }

    fn n_phase(p: &AllanPoint) -> usize {
        p.terms + 2 * p.m
    }

    /// Weighted NNLS with the weights and EDF iterated on the model.
    fn solve(&self, shapes: &[f64], iterations: usize) -> Result<Solution, FitError> {
        let basis = self.basis(shapes)?;
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
            // Gauss–Newton on Σ (edf/2)·ln²(meas/model), linearised around the current model:
            // target tᵢ = modelᵢ·(1 + ln(measᵢ/modelᵢ)), weight 1/(modelᵢ·√(2/edfᵢ)).
            let sd: Vec<f64> = (0..k)
                .map(|i| {
                    let base = if model[i] > 0.0 { model[i] } else { meas[i] };
                    base * (2.0 / edf[i]).sqrt()
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
            let b = DVector::from_fn(k, |i, _| target[i] / sd[i]);
            let x = nnls(&a, &b)?;
            let mut trial: Vec<f64> = x.iter().copied().collect();
            // Damping: halve the step toward the new solution while the log cost rises.
            for _ in 0..8 {
                let m: Vec<f64> = (0..k)
                    .map(|i| (0..jn).map(|j| trial[j] * basis[j][i]).sum())
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
    fn search_shapes(&self, mut shapes: Vec<f64>, iters: usize) -> Result<Vec<f64>, FitError> {
        let ranges: Vec<(f64, f64)> = self
            .columns
            .iter()
            .flat_map(|c| c.shapes.iter().map(|&(_, lo, hi)| (lo, hi)))
            .collect();
        let cost = |s: &[f64]| -> Result<f64, FitError> {
            let sol = self.solve(s, iters)?;
            let cost = log_cost(&sol.meas, &sol.model, &sol.edf);
            Ok(if cost.is_finite() { cost } else { f64::MAX })
        };
        let rounds = if shapes.len() > 1 { 2 } else { 1 };
        for _ in 0..rounds {
            for (d, &(lo, hi)) in ranges.iter().enumerate() {
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
                // Golden section on [best − h, best + h].
                let (mut a, mut b) = ((best.1 - h).max(lo), (best.1 + h).min(hi));
                let g = 0.618_033_988_749_895;
                let eval = |v: f64, base: &Vec<f64>| -> Result<f64, FitError> {
                    let mut t = base.clone();
                    t[d] = v;
                    cost(&t)
                };
                let mut x1 = b - g * (b - a);
                let mut x2 = a + g * (b - a);
                let (mut f1, mut f2) = (eval(x1, &shapes)?, eval(x2, &shapes)?);
                for _ in 0..30 {
                    if f1 < f2 {
                        b = x2;
                        x2 = x1;
                        f2 = f1;
                        x1 = b - g * (b - a);
                        f1 = eval(x1, &shapes)?;
                    } else {
                        a = x1;
                        x1 = x2;
                        f1 = f2;
                        x2 = a + g * (b - a);
                        f2 = eval(x2, &shapes)?;
                    }
                }
                let mid = 0.5 * (a + b);
                shapes[d] = if eval(mid, &shapes)? <= best.0 { mid } else { best.1 };
            }
        }
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
        })
    }

    /// Variances of [c_1..c_J, log-shape_1..] from the Gauss–Newton normal matrix at the
    /// solution (active amplitudes only), scaled by max(1, χ²/dof) and by [`CORRELATION_INFLATION`].
    fn covariance(&self, shapes: &[f64], sol: &Solution) -> Option<Vec<Option<f64>>> {
        let k = self.points.len();
        let jn = self.columns.len();
        let sd: Vec<f64> = (0..k)
            .map(|i| sol.model[i].max(f64::MIN_POSITIVE) * (2.0 / sol.edf[i]).sqrt())
            .collect();
        let active: Vec<usize> = (0..jn).filter(|&j| sol.c[j] > 0.0).collect();
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
        let normal = jac.transpose() * &jac;
        let inv = normal.try_inverse()?;
        let dof = k.saturating_sub(cols.len()).max(1) as f64;
        let scale = (sol.chi2 / dof).max(1.0) * CORRELATION_INFLATION;
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

/// The fit's objective: Σ (edf/2)·(ln(meas/model) − bias(edf))², the log-normal approximation of the χ²
/// likelihood of AVAR estimates. It weighs over- and under-prediction alike, where the contract's z
/// (scaled by the model) forgives a model that over-predicts where the EDF is small.
fn log_cost(meas: &[f64], model: &[f64], edf: &[f64]) -> f64 {
    meas.iter()
        .zip(model)
        .zip(edf)
        .map(|((&y, &m), &e)| {
            if m > 0.0 {
                0.5 * e * ((y / m).ln() - log_bias(e)).powi(2)
            } else {
                f64::MAX / 1e3
            }
        })
        .sum()
}

/// E[ln(σ̂²/σ²)] for an estimate with `edf` degrees of freedom: the log of a χ²_ν/ν variable is
/// biased low, by ψ(ν/2) − ln(ν/2) ≈ −1/ν − 1/(3ν²); without this a log fit would pull the model
/// down where the EDF is small (long τ).
fn log_bias(edf: f64) -> f64 {
    let nu = edf.max(1.0);
    -1.0 / nu - 1.0 / (3.0 * nu * nu)
}

/// Factor on the covariance for the correlation between overlapping estimates at neighbouring τ.
///
/// With ten τ per decade, estimates within a factor of ~2 in τ share most of their terms, so the
/// K points carry roughly a third of K independent pieces of information; treating them as
/// independent understates every uncertainty by about √3. Checked by the coverage test
/// (tests/model_fit.rs).
pub const CORRELATION_INFLATION: f64 = 3.0;

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
