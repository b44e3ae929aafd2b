//! `ramp` (R): rate ramp, a bias that grows linearly with time.

use super::{
    check_params, params_of, Domain, Effect, EffectKind, Evidence, Explanation, KindInfo, Param,
    ParamError, ParamSpec, SimContext, SimStage, TimeEstimator, Extended, WithEstimator,
};
use crate::model::fit::{AxisInput, FitError};
use crate::model::timedomain::{self, Estimate, LineFit, NoiseSpectrum, Signature};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[ParamSpec {
    name: "r",
    unit: "rad/s^2",
    bounds: (-10.0, 10.0),
    doc: "rate ramp R (bias drift rate)",
}];

/// The effect id (**contract** name) of this file's effect: `ramp`.
pub const ID: &str = "ramp";

static INFO: KindInfo = KindInfo {
    id: ID,
    alias: Some("R"),
    schema: SCHEMA,
    domain: Domain::TimeDomain,
    evidence: Evidence::None,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(Ramp::new(v[0])?)),
};

/// The registry entry of [`Ramp`], with its time-domain estimator.
pub(super) static KIND: Extended<WithEstimator> =
    Extended { info: &INFO, extra: WithEstimator(&Trend) };

/// The ramp's estimator: the slope of the rate on time.
///
/// Why in the time domain: on the Allan variance a ramp (R²τ²/2) and a random walk (K²τ/3)
/// differ only over the last octave or two of τ, so the Allan fit hands a ramp to K (measured:
/// named in 0 of 10 recordings up to 16 × the base Allan variance, K fitted 2–5× its truth). A
/// ramp is a deterministic trend, and the slope of the rate on time, weighed against the base
/// noise ([`timedomain::trend`]), sees it at its full information: under a random walk of
/// diffusion q² the slope is known to q/√T, the best any estimator can do.
///
/// # Formula
/// ```text
/// with the base noise:  r = GLS slope of y on t (timedomain::trend)
/// without (first guess): r = Σ (t−t̄)(y−ȳ) / Σ (t−t̄)²
/// removed: y[n] −= r·(n·τ0 − t̄)
/// ```
/// The first guess is unbiased under any stationary-increment noise and keeps 5/6 of the GLS
/// efficiency under a pure random walk (all of it under white noise).
///
/// # References
/// IEEE Std 952-1997, Annex C.5; Grenander U., "On the estimation of regression coefficients in
/// the case of an autocorrelated disturbance", Ann. Math. Stat. 25(2), 1954 (least squares on a
/// polynomial trend).
struct Trend;

impl TimeEstimator for Trend {
    fn estimate(
        &self,
        input: &AxisInput<'_>,
        series: &[f64],
        noise: Option<&NoiseSpectrum>,
        _fourth_cumulant: f64,
    ) -> Result<Estimate, FitError> {
        let gls = noise.and_then(|n| timedomain::trend(series, n));
        let (r, sigma) = match gls {
            Some(g) => (g.coefficient, g.sigma),
            None => {
                let mut line = LineFit::default();
                for (i, y) in series.iter().enumerate().filter(|(_, y)| y.is_finite()) {
                    line.add(i as f64 * input.tau0, *y);
                }
                line.slope().ok_or(FitError::TooShort {
                    axis: input.axis.name(),
                    samples: line.len() as usize,
                    needed: 3,
                })?
            }
        };
        let strength = if sigma > 0.0 { (r / sigma).powi(2) } else { 0.0 };
        let value = r.clamp(SCHEMA[0].bounds.0, SCHEMA[0].bounds.1);
        Ok(Estimate::coefficients(vec![value], vec![Some(sigma)], strength, Signature::Trend))
    }
    fn remove(&self, values: &[f64], input: &AxisInput<'_>, series: &mut [f64]) {
        let mid = 0.5 * series.len().saturating_sub(1) as f64;
        for (i, y) in series.iter_mut().enumerate() {
            *y -= values[0] * (i as f64 - mid) * input.tau0;
        }
    }
}

/// Rate ramp `r`: a bias that changes at a constant rate (slow warm-up, a drifting reference).
///
/// Deterministic, so not noise: it shows in the Allan variance with slope +2 (σ² = r²τ²/2), where
/// a random walk's +1 hides it over all but the last octaves of τ, so it is estimated in the time
/// domain as the slope of the rate on time (GLS against the base noise, `timedomain::trend`) and
/// removed before the Allan fit of the rest; the Hadamard variance is blind to it, which tells it
/// from a random walk.
///
/// # Formula
/// ```text
/// σ²(τ) = r²·τ² / 2   (its Allan signature; estimated in the time domain)
/// simulated: y[n] += r·n·τ0
/// ```
/// where r is the ramp rate (rad/s²); the second difference of the integrated ramp is r·τ² for
/// every τ, so the discrete estimate equals the formula exactly. The sign of r only shows in the
/// time domain.
///
/// # References
/// IEEE Std 952-1997, Annex C.5 (rate ramp).
///
/// ```
/// use fdavar::model::effects::{Effect, Ramp, SimContext};
/// let r = Ramp::new(1e-6).unwrap();
/// let ctx = SimContext { dt: 0.5, white_sigma: 0.0, temperature_c: None, accel: None };
/// let mut y = [0.0; 3];
/// let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
/// r.simulate(&ctx, &mut rng, &mut y);
/// assert!((y[2] - 1e-6).abs() < 1e-20);
/// assert!(r.avar(10.0).is_none()); // time-domain: fitted on the samples, not the Allan curve
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ramp {
    r: f64,
}

impl Ramp {
    /// Builds the effect from the ramp rate `r` in rad/s².
    ///
    /// # Errors
    /// [`ParamError`] naming `r` when it is NaN or outside [−10, 10].
    pub fn new(r: f64) -> Result<Self, ParamError> {
        check_params(INFO.id, SCHEMA, &[r])?;
        Ok(Self { r })
    }

    /// The ramp rate R, rad/s².
    pub fn r(&self) -> f64 {
        self.r
    }
}

impl Effect for Ramp {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.r])
    }
    fn avar(&self, _tau: f64) -> Option<f64> {
        None
    }
    fn simulate(&self, ctx: &SimContext<'_>, _rng: &mut dyn RngCore, out: &mut [f64]) {
        for (n, y) in out.iter_mut().enumerate() {
            *y += self.r * n as f64 * ctx.dt;
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "a rate ramp of {:.3e} per second: the bias drifts steadily (warm-up, ageing), which \
                 dominates the longest averaging times",
                self.r
            ),
            avar_slope: None,
            reference: "IEEE Std 952-1997 Annex C.5",
        }
    }
}
