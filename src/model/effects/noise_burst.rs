//! `noise_burst`: a span of time in which the white noise is louder.

use super::{
    check_params, first_index_at, params_of, std_normal, Domain, Effect, EffectKind, Evidence,
    Explanation, Extended, KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage,
    TimeEstimator, WithEstimator,
};
use crate::model::fit::{AxisInput, FitError};
use crate::model::timedomain::{
    self, block_len, find_burst, shrink_white, without_spikes, Estimate, NoiseSpectrum, Signature,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[
    ParamSpec {
        name: "start_s",
        unit: "s",
        bounds: (0.0, 1e9),
        doc: "start of the burst, seconds from the first sample",
    },
    ParamSpec {
        name: "end_s",
        unit: "s",
        bounds: (0.0, 1e9),
        doc: "end of the burst (exclusive), seconds from the first sample",
    },
    ParamSpec {
        name: "factor",
        unit: "1",
        bounds: (1.0, 1e3),
        doc: "white noise level inside the span over the level outside (σ ratio, ≥ 1)",
    },
];

/// The effect id (**contract** name) of this file's effect: `noise_burst`.
pub const ID: &str = "noise_burst";

static INFO: KindInfo = KindInfo {
    id: ID,
    alias: None,
    schema: SCHEMA,
    domain: Domain::TimeDomain,
    evidence: Evidence::Events,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(NoiseBurst::new(v[0], v[1], v[2])?)),
};

/// The registry entry of [`NoiseBurst`], with its time-domain estimator.
pub(super) static KIND: Extended<WithEstimator> =
    Extended { info: &INFO, extra: WithEstimator(&BurstSearch) };

/// The noise burst's estimator: the span of blocks whose white level is louder than the rest's.
///
/// Why on first differences ([`find_burst`]): slow effects cancel in them, so a drift or a step
/// left over does not pass for a louder span; a step barely touches them, which is why this
/// search runs last among the ranked estimators (after the regressions and the step). The base
/// noise is not used. In a heavy-tailed record (`fourth_cumulant` > 0) it reads the record without
/// its isolated spikes ([`without_spikes`]): one spike of 30σ adds to its block as much as nine
/// blocks of noise at 100 Hz, and the search found spikes instead of bursts. Removing the burst
/// scales its span's fast part down by the factor around a 30 s moving mean, which keeps the slow
/// part (a drift, a random walk) for the Allan fit.
///
/// # Formula
/// ```text
/// y ← despiked(y)   where the record is heavy-tailed (the search only; the removal acts on y)
/// vₖ = Σ_{block k} (y[i+1] − y[i])² / 2,   (s, e) = argmax LLR(s, e) over louder spans
/// start_s = s·b·τ0,  end_s = e·b·τ0,  factor = max(√((V_in/n_in)/(V_out/n_out)), 1)
/// removed: y[n] = m[n] + (y[n] − m[n])/factor   inside the span, m the 30 s moving mean
/// ```
/// where b is the block length ([`block_len`], about 1 s) and LLR the Gaussian likelihood ratio
/// of [`find_burst`].
///
/// # References
/// Galleani L., "The dynamic Allan variance", IEEE TUFFC 56(3), 2009; Yang H. et al.,
/// Electronics Optics & Control 23(10), 2016.
struct BurstSearch;

impl TimeEstimator for BurstSearch {
    fn estimate(
        &self,
        input: &AxisInput<'_>,
        series: &[f64],
        _noise: Option<&NoiseSpectrum>,
        fourth_cumulant: f64,
    ) -> Result<Estimate, FitError> {
        let b = find_burst(&without_spikes(series, input.tau0, fourth_cumulant), input.tau0);
        let values = vec![b.start as f64 * input.tau0, b.end as f64 * input.tau0, b.factor.max(1.0)];
        Ok(Estimate::event(values, b.strength, Signature::WhiteLevel))
    }
    fn remove(&self, values: &[f64], input: &AxisInput<'_>, series: &mut [f64]) {
        let start = timedomain::index_at(values[0], input.tau0);
        let end = timedomain::index_at(values[1], input.tau0).min(series.len());
        shrink_white(&mut series[start.min(end)..end], values[2], block_len(input.tau0));
    }
    fn estimation_rank(&self) -> usize {
        3
    }
}

/// The white noise level multiplied by `factor` between `start_s` and `end_s`: vibration from a
/// motor that runs for a while, electrical interference — the seed paper's test signal.
///
/// It is what the F-DAVAR window adapts to: the variance ratio F rises inside the span.
///
/// # Formula
/// ```text
/// y[n] += σ_w·√(factor² − 1)·w[n]   for start_s ≤ n·τ0 < end_s,  w ~ N(0, 1)
/// ```
/// where σ_w = N/√τ0 is the per-sample deviation of the axis's `white` term, so that the white
/// deviation inside the span is factor·σ_w. Being additive, a burst can only make the noise louder
/// (factor ≥ 1); a quiet span is a burst over the rest of the record.
///
/// # References
/// Yang H. et al., Electronics Optics & Control 23(10), 2016 (the seed; noise tripled over samples
/// 1200–2400); Galleani L., IEEE TUFFC 56(3), 2009.
///
/// ```
/// use fdavar::model::effects::{Effect, NoiseBurst};
/// assert!(NoiseBurst::new(10.0, 5.0, 3.0).is_err()); // ends before it starts
/// assert!(NoiseBurst::new(36.0, 72.0, 3.0).is_ok());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseBurst {
    start_s: f64,
    end_s: f64,
    factor: f64,
}

impl NoiseBurst {
    /// Builds the effect from the span `start_s`..`end_s` (s) and the σ ratio `factor`.
    ///
    /// # Errors
    /// [`ParamError`] naming the parameter that is NaN or out of bounds, or
    /// [`ParamError::Invalid`] when `end_s` ≤ `start_s`.
    pub fn new(start_s: f64, end_s: f64, factor: f64) -> Result<Self, ParamError> {
        check_params(INFO.id, SCHEMA, &[start_s, end_s, factor])?;
        if end_s <= start_s {
            return Err(ParamError::Invalid {
                effect: INFO.id,
                reason: format!("end_s = {end_s} must be after start_s = {start_s}"),
            });
        }
        Ok(Self {
            start_s,
            end_s,
            factor,
        })
    }

    /// Start of the span, seconds from the first sample.
    pub fn start_s(&self) -> f64 {
        self.start_s
    }

    /// End of the span (exclusive), seconds from the first sample.
    pub fn end_s(&self) -> f64 {
        self.end_s
    }

    /// The σ ratio inside the span.
    pub fn factor(&self) -> f64 {
        self.factor
    }
}

impl Effect for NoiseBurst {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.start_s, self.end_s, self.factor])
    }
    fn avar(&self, _tau: f64) -> Option<f64> {
        None
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        let start = first_index_at(self.start_s, ctx.dt, out.len());
        let end = first_index_at(self.end_s, ctx.dt, out.len());
        let extra = ctx.white_sigma * (self.factor * self.factor - 1.0).sqrt();
        for y in &mut out[start..end] {
            *y += extra * std_normal(rng);
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "the white noise was {:.2} times louder from {:.3} s to {:.3} s: vibration or \
                 interference for a while",
                self.factor, self.start_s, self.end_s
            ),
            avar_slope: None,
            reference: "Yang et al. 2016 (seed); Galleani, IEEE TUFFC 56(3), 2009",
        }
    }
}
