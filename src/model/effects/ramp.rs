//! `ramp` (R): rate ramp, a bias that grows linearly with time.

use super::{
    check_params, params_of, Domain, Effect, EffectKind, Evidence, Explanation, KindInfo, Param,
    ParamError, ParamSpec, SimContext, SimStage,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[ParamSpec {
    name: "r",
    unit: "rad/s^2",
    bounds: (-10.0, 10.0),
    doc: "rate ramp R (bias drift rate)",
}];

/// The registry entry of [`Ramp`].
pub(super) static KIND: KindInfo = KindInfo {
    id: "ramp",
    alias: Some("R"),
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(Ramp::new(v[0])?)),
};

/// Rate ramp `r`: a bias that changes at a constant rate (slow warm-up, a drifting reference).
///
/// Deterministic, so not noise, but it shows in the Allan variance with slope +2 and is fitted with
/// the other terms; the Hadamard variance is blind to it, which tells it from a random walk.
///
/// # Formula
/// ```text
/// σ²(τ) = r²·τ² / 2
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
/// use fdavar::model::effects::{Effect, Ramp};
/// let r = Ramp::new(1e-6).unwrap();
/// assert!((r.avar(10.0).unwrap() - 5e-11).abs() < 1e-24);
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
        check_params(KIND.id, SCHEMA, &[r])?;
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
    fn avar(&self, tau: f64) -> Option<f64> {
        Some(self.r * self.r * tau * tau / 2.0)
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
            avar_slope: Some(2.0),
            reference: "IEEE Std 952-1997 Annex C.5",
        }
    }
}
