//! Diagnosis: which effect the model lacks, judged by what adding it buys.
//!
//! For each vocabulary effect not in the model, the fit is redone with it, and the gain is scored
//! with a penalised criterion. A suggestion must pass three tests:
//! 1. the model fails: fit_error before > [`COMPLETE_FIT_ERROR`] (a model that explains the
//!    measurement within its scatter gets no suggestion — false alarms cost as much as misses);
//! 2. the extra parameters pay for themselves: Δχ² > [`PENALTY_PER_PARAM`]·p·ln K, a BIC penalty
//!    scaled for the correlation of overlapping estimates at neighbouring τ (about 3 independent
//!    points per 10 — see [`crate::model::fit::tau_correlation`]);
//! 3. effect-size sanity: fit_error falls by at least [`MIN_IMPROVEMENT`]×, and a new spectral
//!    amplitude is at least 2σ from zero.
//!
//! Time-domain effects are tried only with their evidence (DESIGN §6): a temperature topic, the
//! accel axes (gyro axes only), and for `noise_burst` / `bias_step` a DAVAR event or, without
//! events, their own estimator's significant statistic (windowed-variance change, mean contrast).
//! Suggestions are sorted best first (lowest fit_error after).
//!
//! [`diagnose_curve`] is the same criterion on Allan points alone (a live node's whole-run Allan
//! variance): spectral effects only, since the time-domain ones need the samples.

use crate::allan::AllanPoint;
use crate::model::effects::{Domain, EffectKind, Evidence};
use crate::model::fit::{
    fit, fit_curve, prepare, AxisInput, CurveFit, FitError, FitOptions, FittedModel, FittedTerm,
    ParamValue,
};
use crate::model::spec::ModelSpec;
use crate::model::timedomain;
use serde::{Deserialize, Serialize};

/// fit_error at or below which a model counts as complete.
pub const COMPLETE_FIT_ERROR: f64 = 2.0;
/// BIC-like penalty per extra parameter, in units of ln K.
pub const PENALTY_PER_PARAM: f64 = 3.0;
/// Least factor by which fit_error must fall for a suggestion.
pub const MIN_IMPROVEMENT: f64 = 1.5;
/// An effect with a measured driver (temperature, the accel axes) is ranked before a shape-only
/// effect unless the latter's fit_error after is this many times lower: a sinusoid or a
/// Gauss–Markov process can mimic any driven disturbance on the Allan variance, but only the driven
/// effect names its cause.
pub const DRIVER_PREFERENCE: f64 = 1.5;

/// One suggested effect with what it buys.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Suggestion {
    /// Effect id.
    pub effect: String,
    /// Its fitted parameters, SI.
    pub params: Vec<ParamValue>,
    /// fit_error of the model with this effect added.
    pub fit_error_after: f64,
    /// The effect's sentence of physics with the numbers filled in.
    pub explanation: String,
    /// χ² before minus χ² after.
    pub delta_chi2: f64,
    /// The penalty Δχ² had to beat.
    pub threshold: f64,
}

/// The fit of the model asked for, and what to add to it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Diagnosis {
    /// The model as asked.
    pub fit: FittedModel,
    /// Significant gains, best first.
    pub suggestions: Vec<Suggestion>,
    /// The refitted model of each suggestion, same order (for before/after figures).
    pub after: Vec<FittedModel>,
}

/// Fits `spec` and scores every effect it lacks.
///
/// # Errors
/// The errors of [`fit`] for the model itself; a candidate whose refit fails is skipped.
pub fn diagnose(
    input: &AxisInput<'_>,
    spec: &ModelSpec,
    registry: &[&'static dyn EffectKind],
    opts: &FitOptions,
) -> Result<Diagnosis, FitError> {
    let base = prepare(input, spec, registry, opts)?;
    let before = base.fit_spectral(spec, &base.spectral_kinds, opts)?;
    let mut scored: Vec<(Suggestion, FittedModel)> = Vec::new();
    for &kind in registry.iter().filter(|k| !spec.contains(k.id())) {
        let own_evidence = matches!(kind.id(), "noise_burst" | "bias_step" | "temperature");
        if before.fit_error > COMPLETE_FIT_ERROR || own_evidence {
            let with = spec.with(kind.id());
            let after = match kind.domain() {
                Domain::Spectral => {
                    let mut kinds = base.spectral_kinds.clone();
                    kinds.push(kind);
                    base.fit_spectral(&with, &kinds, opts)
                }
                Domain::TimeDomain => {
                    if !evidence_present(kind, input) {
                        continue;
                    }
                    fit(input, &with, registry, opts)
                }
            };
            let Ok(after) = after else { continue };
            let s = if own_evidence {
                score_time_domain(kind, input, &before, &after)
            } else {
                score(kind, &before, &after)
            };
            if let Some(s) = s {
                scored.push((s, after));
            }
        }
    }
    best_first(&mut scored, registry);
    let (suggestions, after) = scored.into_iter().unzip();
    Ok(Diagnosis {
        fit: before,
        suggestions,
        after,
    })
}

/// Scores every spectral effect of `registry` that `model` lacks against a curve of Allan points.
///
/// Why apart from [`diagnose`]: a live node keeps a streaming whole-run Allan variance, not the
/// samples, so only the spectral refits are possible; the criterion (gate, penalty, effect size,
/// order) is the same code as [`diagnose`]'s. Time-domain kinds in `model` are ignored, as in
/// [`fit_curve`]. Cost: one [`fit_curve`] per candidate when the model fails, one otherwise.
///
/// # Errors
/// The errors of [`fit_curve`] for the model itself (too few points, degenerate input); a
/// candidate whose refit fails is skipped.
pub fn diagnose_curve(
    points: &[AllanPoint],
    model: &[&'static dyn EffectKind],
    registry: &[&'static dyn EffectKind],
    weight_iterations: usize,
) -> Result<Vec<Suggestion>, FitError> {
    let before = fit_curve(points, model, weight_iterations)?;
    let mut scored: Vec<(Suggestion, ())> = Vec::new();
    if before.fit_error > COMPLETE_FIT_ERROR {
        let lacking = registry
            .iter()
            .filter(|k| k.domain() == Domain::Spectral && !model.iter().any(|m| m.id() == k.id()));
        for &kind in lacking {
            let mut kinds = model.to_vec();
            kinds.push(kind);
            let Ok(after) = fit_curve(points, &kinds, weight_iterations) else {
                continue;
            };
            scored.extend(score(kind, &before, &after).map(|s| (s, ())));
        }
    }
    best_first(&mut scored, registry);
    Ok(scored.into_iter().map(|(s, ())| s).collect())
}

/// Sorts suggestions best first: lowest fit_error after, a driven effect preferred by
/// [`DRIVER_PREFERENCE`].
fn best_first<T>(scored: &mut [(Suggestion, T)], registry: &[&'static dyn EffectKind]) {
    let rank = |s: &Suggestion| {
        let driven = registry
            .iter()
            .find(|k| k.id() == s.effect)
            .is_some_and(|k| matches!(k.evidence(), Evidence::Temperature | Evidence::Accel));
        if driven {
            s.fit_error_after / DRIVER_PREFERENCE
        } else {
            s.fit_error_after
        }
    };
    scored.sort_by(|a, b| rank(&a.0).total_cmp(&rank(&b.0)));
}

/// What the penalised criterion reads from a fit: a whole-record [`FittedModel`] or the
/// [`CurveFit`] of Allan points alone.
trait Scored {
    /// τ points fitted.
    fn points(&self) -> usize;
    /// Free parameters.
    fn n_params(&self) -> usize;
    /// Σ z².
    fn chi2(&self) -> f64;
    /// RMS of z.
    fn fit_error(&self) -> f64;
    /// The term of effect `id`.
    fn term(&self, id: &str) -> Option<&FittedTerm>;
}

impl Scored for FittedModel {
    fn points(&self) -> usize {
        self.points.len()
    }
    fn n_params(&self) -> usize {
        self.n_params
    }
    fn chi2(&self) -> f64 {
        self.chi2
    }
    fn fit_error(&self) -> f64 {
        self.fit_error
    }
    fn term(&self, id: &str) -> Option<&FittedTerm> {
        FittedModel::term(self, id)
    }
}

impl Scored for CurveFit {
    fn points(&self) -> usize {
        self.points.len()
    }
    fn n_params(&self) -> usize {
        self.n_params
    }
    fn chi2(&self) -> f64 {
        self.chi2
    }
    fn fit_error(&self) -> f64 {
        self.fit_error
    }
    fn term(&self, id: &str) -> Option<&FittedTerm> {
        self.terms.iter().find(|t| t.effect == id)
    }
}

/// Whether the recording holds the evidence a time-domain effect needs before it is tried.
fn evidence_present(kind: &'static dyn EffectKind, input: &AxisInput<'_>) -> bool {
    if !timedomain::has_evidence(kind, input) {
        return false;
    }
    match kind.evidence() {
        // Without DAVAR events, the effect's own time-domain statistic stands in for one: a
        // windowed-variance change for a burst, a two-window mean contrast for a step (a burst
        // detector says nothing about a step in the mean).
        Evidence::Events if input.events.is_empty() => timedomain::estimate(kind, input, input.rate)
            .is_ok_and(|est| timedomain::is_significant(kind, &est)),
        _ => true,
    }
}

/// A time-domain effect judged on its own evidence.
///
/// A whole-record Allan variance is linear in the local variances, so a burst of white noise only
/// raises the white level; a single bias step gives a τ¹ law indistinguishable from a rate random
/// walk; a warm-up drift hides in the random walk and flicker terms. Only the span check of
/// fit_error sees them, and only when they are strong, so they are judged by their estimator's own statistic
/// ([`timedomain::is_significant`]), an effect-size check (a burst factor ≥ 1.2), and fit_error
/// must fall at least [`MIN_IMPROVEMENT`]×.
fn score_time_domain(
    kind: &'static dyn EffectKind,
    input: &AxisInput<'_>,
    before: &FittedModel,
    after: &FittedModel,
) -> Option<Suggestion> {
    let est = timedomain::estimate(kind, input, input.rate).ok()?;
    if !timedomain::is_significant(kind, &est) {
        return None;
    }
    if kind.id() == "noise_burst" && est.values.get(2).is_none_or(|&f| f < 1.2) {
        return None;
    }
    // The refit must also explain the record better (its spans, above all): a small "step" found
    // inside a burst is significant on its own statistic and changes nothing.
    if after.fit_error * MIN_IMPROVEMENT > before.fit_error {
        return None;
    }
    let term = after.term(kind.id())?;
    Some(Suggestion {
        effect: kind.id().to_string(),
        params: term.params.clone(),
        fit_error_after: after.fit_error,
        explanation: term.explanation.clone(),
        delta_chi2: before.chi2 - after.chi2,
        threshold: est.strength,
    })
}

/// The suggestion for `kind` if the gain from `before` to `after` passes the criterion.
fn score<F: Scored>(kind: &'static dyn EffectKind, before: &F, after: &F) -> Option<Suggestion> {
    let k = before.points().max(2) as f64;
    let extra = after.n_params().saturating_sub(before.n_params()).max(1) as f64;
    let threshold = PENALTY_PER_PARAM * extra * k.ln();
    let delta = before.chi2() - after.chi2();
    if !(delta > threshold && after.fit_error() * MIN_IMPROVEMENT < before.fit_error()) {
        return None;
    }
    let term = after.term(kind.id())?;
    if kind.domain() == Domain::Spectral {
        let amp = term.params.first()?;
        let significant = amp.value > 0.0 && amp.sigma.is_none_or(|s| amp.value > 2.0 * s);
        if !significant {
            return None;
        }
    }
    Some(Suggestion {
        effect: kind.id().to_string(),
        params: term.params.clone(),
        fit_error_after: after.fit_error(),
        explanation: term.explanation.clone(),
        delta_chi2: delta,
        threshold,
    })
}
