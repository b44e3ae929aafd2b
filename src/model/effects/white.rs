//! `white` (N): white rate noise, the angle random walk of IEEE 952.

use super::{
    check_params, params_of, std_normal, Domain, Effect, EffectKind, Evidence, Explanation,
    KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[ParamSpec {
    name: "n",
    unit: "rad/s/sqrt(Hz)",
    bounds: (0.0, 10.0),
    doc: "white rate noise density N (angle random walk)",
}];

/// The effect id (**contract** name) of this file's effect: `white`.
pub const ID: &str = "white";

/// The registry entry of [`White`].
pub(super) static KIND: KindInfo = KindInfo {
    id: ID,
    alias: Some("N"),
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(White::new(v[0])?)),
};

/// White rate noise of density `n` (IEEE 952 "angle random walk", Kalibr's noise density).
///
/// The dominant short-τ term of every MEMS gyro and accelerometer; its integral (the angle or
/// velocity) wanders as a random walk.
///
/// # Formula
/// ```text
/// σ²(τ) = n² / τ          σ_sample = n / √τ0
/// ```
/// where n is the one-sided rate noise density (rad/s/√Hz), τ the averaging time and τ0 the sample
/// period; each simulated sample is an independent normal value of standard deviation σ_sample.
///
/// # References
/// IEEE Std 952-1997, Annex C.2 (angle random walk); Riley, NIST SP 1065, 2008, §5.2.2 (white FM).
///
/// ```
/// use fdavar::model::effects::{Effect, White};
/// let w = White::new(1e-3).unwrap();
/// assert!((w.avar(4.0).unwrap() - 2.5e-7).abs() < 1e-20);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct White {
    n: f64,
}

impl White {
    /// Builds the effect from its density `n` in rad/s/√Hz.
    ///
    /// # Errors
    /// [`ParamError`] naming `n` when it is NaN or outside [0, 10].
    pub fn new(n: f64) -> Result<Self, ParamError> {
        check_params(KIND.id, SCHEMA, &[n])?;
        Ok(Self { n })
    }

    /// The density N, rad/s/√Hz.
    pub fn n(&self) -> f64 {
        self.n
    }
}

impl Effect for White {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.n])
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        Some(self.n * self.n / tau)
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        let sigma = self.n / ctx.dt.sqrt();
        for y in out.iter_mut() {
            *y += sigma * std_normal(rng);
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "white rate noise of density {:.3e} per sqrt(Hz): independent sample-to-sample \
                 jitter whose integral wanders as a random walk (angle random walk)",
                self.n
            ),
            avar_slope: Some(-1.0),
            reference: "IEEE Std 952-1997 Annex C.2; NIST SP 1065 §5.2.2",
        }
    }
}
