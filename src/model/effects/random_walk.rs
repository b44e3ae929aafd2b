//! `random_walk` (K): rate random walk, a bias that wanders as integrated white noise.

use super::{
    check_params, params_of, std_normal, Domain, Effect, EffectKind, Evidence, Explanation,
    KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[ParamSpec {
    name: "k",
    unit: "rad/s/sqrt(s)",
    bounds: (0.0, 10.0),
    doc: "rate random walk K (bias random walk density)",
}];

/// The effect id (**contract** name) of this file's effect: `random_walk`.
pub const ID: &str = "random_walk";

/// The registry entry of [`RandomWalk`].
pub(super) static KIND: KindInfo = KindInfo {
    id: ID,
    alias: Some("K"),
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(RandomWalk::new(v[0])?)),
};

/// Rate random walk of strength `k`: the bias is the integral of white noise.
///
/// The long-τ rise of the Allan deviation of most MEMS sensors (Kalibr's "random walk"); it is
/// what a navigation filter models as the bias process noise.
///
/// # Formula
/// ```text
/// σ²(τ) = k²·τ / 3
/// simulated: b[0] = 0,  b[n+1] = b[n] + k·√τ0·w[n],  w ~ N(0, 1)
/// ```
/// where k is the bias random walk density (rad/s/√s = rad/s²/√Hz) and τ0 the sample period. The
/// discrete walk has σ²(mτ0) = k²τ0·(2m² + 1)/(6m), within 1/(2m²) of k²τ/3.
///
/// # References
/// IEEE Std 952-1997, Annex C.4 (rate random walk); Riley, NIST SP 1065, 2008, Table 5 (RW FM).
///
/// ```
/// use fdavar::model::effects::{Effect, RandomWalk};
/// let k = RandomWalk::new(3e-5).unwrap();
/// assert!((k.avar(100.0).unwrap() - 3e-8).abs() < 1e-20);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomWalk {
    k: f64,
}

impl RandomWalk {
    /// Builds the effect from its strength `k` in rad/s/√s.
    ///
    /// # Errors
    /// [`ParamError`] naming `k` when it is NaN or outside [0, 10].
    pub fn new(k: f64) -> Result<Self, ParamError> {
        check_params(KIND.id, SCHEMA, &[k])?;
        Ok(Self { k })
    }

    /// The strength K, rad/s/√s.
    pub fn k(&self) -> f64 {
        self.k
    }
}

impl Effect for RandomWalk {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.k])
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        Some(self.k * self.k * tau / 3.0)
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        let step = self.k * ctx.dt.sqrt();
        let mut bias = 0.0;
        for y in out.iter_mut() {
            *y += bias;
            bias += step * std_normal(rng);
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "rate random walk of {:.3e} per sqrt(s): the bias itself drifts as integrated white \
                 noise, so the deviation grows at the longest averaging times",
                self.k
            ),
            avar_slope: Some(1.0),
            reference: "IEEE Std 952-1997 Annex C.4",
        }
    }
}
