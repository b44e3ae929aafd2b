//! `bias_step`: a sudden jump of the bias at one time.

use super::{
    check_params, first_index_at, params_of, Domain, Effect, EffectKind, Evidence, Explanation,
    Extended, KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage, TimeEstimator,
    WithEstimator,
};
use crate::model::fit::{AxisInput, FitError};
use crate::model::timedomain::{self, find_step, step_size, Estimate, NoiseSpectrum, Signature};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[
    ParamSpec {
        name: "time_s",
        unit: "s",
        bounds: (0.0, 1e9),
        doc: "time of the step, seconds from the first sample",
    },
    ParamSpec {
        name: "size",
        unit: "rad/s",
        bounds: (-1e3, 1e3),
        doc: "size of the step in the mean",
    },
];

/// The effect id (**contract** name) of this file's effect: `bias_step`.
pub const ID: &str = "bias_step";

static INFO: KindInfo = KindInfo {
    id: ID,
    alias: None,
    schema: SCHEMA,
    domain: Domain::TimeDomain,
    evidence: Evidence::Events,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(BiasStep::new(v[0], v[1])?)),
};

/// The registry entry of [`BiasStep`], with its time-domain estimator.
pub(super) static KIND: Extended<WithEstimator> =
    Extended { info: &INFO, extra: WithEstimator(&StepSearch) };

/// The bias step's estimator: the largest contrast between the means of two adjacent windows.
///
/// Why a local contrast ([`find_step`]): a step has no Allan signature of its own (it depends on
/// where the step sits in the record), and windows of n/30 samples average the white noise while
/// a random walk does not look like a step over them. The base noise is not used: the step is
/// located once, and the diagnosis tests it against the base noise. It runs after the
/// regressions (temperature, g-sensitivity), which explain the slow and the vibration parts it
/// would otherwise mistake for a step, and before the burst search.
///
/// # Formula
/// ```text
/// D(i) = mean(y[i..i+W]) − mean(y[i−W..i]),   i* = argmax |D(i)|   (a shorter window on the
///        short side within W of an end)
/// time_s = i*·τ0,   size = D(i*)
/// removed: y[n] −= size   for n ≥ round(time_s/τ0)
/// ```
///
/// # References
/// Galleani L., "The dynamic Allan variance", IEEE TUFFC 56(3), 2009 (steps seen by the DAVAR).
struct StepSearch;

impl TimeEstimator for StepSearch {
    fn estimate(
        &self,
        input: &AxisInput<'_>,
        series: &[f64],
        noise: Option<&NoiseSpectrum>,
        _fourth_cumulant: f64,
    ) -> Result<Estimate, FitError> {
        let (i, size, strength) = find_step(series);
        // With the base noise known, the size again by GLS on the whole record at that time.
        let gls = noise.and_then(|noise| step_size(series, i, noise));
        let mut est = Estimate::event(vec![i as f64 * input.tau0, gls.map_or(size, |g| g.coefficient)], strength, Signature::MeanStep);
        est.sigmas[1] = gls.map(|g| g.sigma);
        Ok(est)
    }
    fn remove(&self, values: &[f64], input: &AxisInput<'_>, series: &mut [f64]) {
        let start = timedomain::index_at(values[0], input.tau0);
        series.iter_mut().skip(start).for_each(|y| *y -= values[1]);
    }
    fn estimation_rank(&self) -> usize {
        2
    }
}

/// A step of `size` in the bias at `time_s`: a shock, a mode switch, a power glitch.
///
/// Not stationary, so it has no Allan signature of its own; it is estimated in the time domain from
/// the DAVAR event that marks it.
///
/// # Formula
/// ```text
/// y[n] += size   for every n with n·τ0 ≥ time_s
/// ```
///
/// # References
/// Galleani L., "The dynamic Allan variance", IEEE TUFFC 56(3), 2009 (steps seen by the DAVAR).
///
/// ```
/// use fdavar::model::effects::{BiasStep, Effect, SimContext};
/// let step = BiasStep::new(0.2, 1.5).unwrap();
/// let ctx = SimContext { dt: 0.1, white_sigma: 0.0, temperature_c: None, accel: None };
/// let mut y = [0.0; 4];
/// let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
/// step.simulate(&ctx, &mut rng, &mut y);
/// assert_eq!(y, [0.0, 0.0, 1.5, 1.5]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasStep {
    time_s: f64,
    size: f64,
}

impl BiasStep {
    /// Builds the effect from the step time `time_s` (s) and its `size` (rad/s).
    ///
    /// # Errors
    /// [`ParamError`] naming the parameter that is NaN or out of bounds.
    pub fn new(time_s: f64, size: f64) -> Result<Self, ParamError> {
        check_params(INFO.id, SCHEMA, &[time_s, size])?;
        Ok(Self { time_s, size })
    }

    /// The step time, seconds from the first sample.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The step size, rad/s.
    pub fn size(&self) -> f64 {
        self.size
    }
}

impl Effect for BiasStep {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.time_s, self.size])
    }
    fn avar(&self, _tau: f64) -> Option<f64> {
        None
    }
    fn simulate(&self, ctx: &SimContext<'_>, _rng: &mut dyn RngCore, out: &mut [f64]) {
        let start = first_index_at(self.time_s, ctx.dt, out.len());
        for y in &mut out[start..] {
            *y += self.size;
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "the bias jumped by {:.3e} at {:.3} s: a shock, a mode switch or a power glitch",
                self.size, self.time_s
            ),
            avar_slope: None,
            reference: "Galleani, IEEE TUFFC 56(3), 2009",
        }
    }
}
