//! `gauss_markov`: first-order Gauss–Markov (exponentially correlated) bias.

use super::{
    check_params, params_of, std_normal, Domain, Effect, EffectKind, Evidence, Explanation,
    KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[
    ParamSpec {
        name: "sigma",
        unit: "rad/s",
        bounds: (0.0, 1e3),
        doc: "steady-state standard deviation σ of the bias",
    },
    ParamSpec {
        name: "time_constant_s",
        unit: "s",
        bounds: (1e-6, 1e9),
        doc: "correlation time T",
    },
];

/// The effect id (**contract** name) of this file's effect: `gauss_markov`.
pub const ID: &str = "gauss_markov";

/// The registry entry of [`GaussMarkov`].
pub(super) static KIND: KindInfo = KindInfo {
    id: ID,
    alias: None,
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(GaussMarkov::new(v[0], v[1])?)),
};

/// A first-order Gauss–Markov bias of steady-state deviation `sigma` and correlation time T.
///
/// The exponentially correlated bias many navigation filters model; in the Allan variance it rises
/// like a random walk below T and falls like white noise above it, a hump that the power-law terms
/// fit only badly.
///
/// # Formula
/// ```text
/// σ²(τ) = (q·T)²/τ · [1 − T/(2τ)·(3 − 4·e^(−τ/T) + e^(−2τ/T))],   q² = 2σ²/T
/// simulated (exact AR(1)): b[0] ~ N(0, σ²),  b[n+1] = φ·b[n] + σ·√(1 − φ²)·w[n],  φ = e^(−τ0/T)
/// ```
/// where σ is the steady-state deviation (rad/s), T the time constant (s) and τ0 the sample period.
/// For τ ≪ T it tends to q²τ/3 (a random walk K = q), for τ ≫ T to 2σ²T/τ (white, N² = 2σ²T). For
/// τ/T < 10⁻² the bracket is evaluated by its series x²/3 − x³/4 + 7x⁴/60 − x⁵/24 (x = τ/T) to avoid
/// cancellation.
///
/// # References
/// IEEE Std 952-1997, Annex C (exponentially correlated noise); N. El-Sheimy, H. Hou, X. Niu,
/// "Analysis and modeling of inertial sensors using Allan variance", IEEE Trans. Instrum. Meas.
/// 57(1), 2008.
///
/// ```
/// use fdavar::model::effects::{Effect, GaussMarkov};
/// let g = GaussMarkov::new(1e-3, 10.0).unwrap();
/// // τ ≫ T: white with N² = 2σ²T.
/// let tau = 1e6;
/// assert!((g.avar(tau).unwrap() * tau / (2.0 * 1e-6 * 10.0) - 1.0).abs() < 1e-4);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussMarkov {
    sigma: f64,
    time_constant_s: f64,
}

impl GaussMarkov {
    /// Builds the effect from `sigma` (rad/s) and `time_constant_s` (s).
    ///
    /// # Errors
    /// [`ParamError`] naming the parameter that is NaN or out of bounds.
    pub fn new(sigma: f64, time_constant_s: f64) -> Result<Self, ParamError> {
        check_params(KIND.id, SCHEMA, &[sigma, time_constant_s])?;
        Ok(Self {
            sigma,
            time_constant_s,
        })
    }

    /// The steady-state deviation σ, rad/s.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// The correlation time T, s.
    pub fn time_constant_s(&self) -> f64 {
        self.time_constant_s
    }
}

impl Effect for GaussMarkov {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.sigma, self.time_constant_s])
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        let t = self.time_constant_s;
        let q2 = 2.0 * self.sigma * self.sigma / t;
        let x = tau / t;
        let bracket = if x < 1e-2 {
            x * x * (1.0 / 3.0 - x / 4.0 + 7.0 * x * x / 60.0 - x * x * x / 24.0)
        } else {
            1.0 - (3.0 - 4.0 * (-x).exp() + (-2.0 * x).exp()) / (2.0 * x)
        };
        Some(q2 * t * t / tau * bracket)
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        let phi = (-ctx.dt / self.time_constant_s).exp();
        let drive = self.sigma * (1.0 - phi * phi).sqrt();
        let mut bias = self.sigma * std_normal(rng);
        for y in out.iter_mut() {
            *y += bias;
            bias = phi * bias + drive * std_normal(rng);
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "an exponentially correlated bias of {:.3e} rms with a {:.3} s time constant: a bias \
                 that wanders and is pulled back, rising like a random walk below that time and \
                 averaging out above it",
                self.sigma, self.time_constant_s
            ),
            avar_slope: None,
            reference: "IEEE Std 952-1997 Annex C; El-Sheimy et al. 2008",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn simulation_is_the_stationary_ar1() {
        // Variance σ² from the first sample on, lag-1 correlation φ = e^(−τ0/T). Over 400 seeds of
        // 200 samples, the mean of b[0]² is σ² within 4 standard errors (√(2/400)·σ²), and the
        // pooled lag-1 correlation (mean known to be 0) is φ within 4·√((1 − φ²)/n).
        let (sigma, t, dt) = (2.0, 0.5, 0.01);
        let gm = GaussMarkov::new(sigma, t).unwrap();
        let ctx = SimContext {
            dt,
            white_sigma: 0.0,
            temperature_c: None,
            accel: None,
        };
        let seeds = 400;
        let (mut first_sq, mut sxy, mut sxx, mut pairs) = (0.0, 0.0, 0.0, 0.0_f64);
        for s in 0..seeds {
            let mut b = vec![0.0; 200];
            gm.simulate(&ctx, &mut rand_chacha::ChaCha8Rng::seed_from_u64(s), &mut b);
            first_sq += b[0] * b[0] / seeds as f64;
            for w in b.windows(2) {
                sxy += w[0] * w[1];
                sxx += w[0] * w[0];
                pairs += 1.0;
            }
        }
        let var_se = (2.0 / seeds as f64).sqrt() * sigma * sigma;
        assert!(
            (first_sq - sigma * sigma).abs() < 4.0 * var_se,
            "{first_sq}"
        );
        let phi = (-dt / t).exp();
        let rho = sxy / sxx;
        assert!(
            (rho - phi).abs() < 4.0 * ((1.0 - phi * phi) / pairs).sqrt(),
            "{rho} vs {phi}"
        );
    }
}
