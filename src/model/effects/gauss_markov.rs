//! `gauss_markov`: first-order Gauss–Markov (exponentially correlated) bias.

use super::{
    check_params, exponential, params_of, Domain, Effect, EffectKind, Evidence, Explanation,
    Extended, Extra, KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage,
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

static INFO: KindInfo = KindInfo {
    id: ID,
    alias: None,
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(GaussMarkov::new(v[0], v[1])?)),
};

/// What the registry entry of [`GaussMarkov`] adds to its [`KindInfo`]: the time constant's
/// search range.
pub(super) struct GaussMarkovExtra;

/// The registry entry of [`GaussMarkov`].
pub(super) static KIND: Extended<GaussMarkovExtra> = Extended { info: &INFO, extra: GaussMarkovExtra };

impl Extra for GaussMarkovExtra {
    /// From [`exponential::FILTER_MEMORY_TAUS`]·τmin (shorter, the same process is the sensor's
    /// low-pass: `bandwidth`) to 4·τmax, the fitter's rule for a time.
    fn search_range(&self, index: usize, tau_min: f64, tau_max: f64) -> Option<(f64, f64)> {
        (index == 1).then_some((exponential::FILTER_MEMORY_TAUS * tau_min, 4.0 * tau_max))
    }
    /// A Lorentzian shoulder, S(f) = 4σ²T/(1 + (2πfT)²): no line.
    fn smooth_spectrum(&self) -> bool {
        true
    }
}

/// A first-order Gauss–Markov bias of steady-state deviation `sigma` and correlation time T.
///
/// The exponentially correlated bias many navigation filters model; in the Allan variance it rises
/// like a random walk below T and falls like white noise above it, a hump that the power-law terms
/// fit only badly.
///
/// # Formula
/// ```text
/// σ²(τ) = (q·T)²/τ · [1 − T/(2τ)·(3 − 4·e^(−τ/T) + e^(−2τ/T))],   q² = 2σ²/T
/// ```
/// where σ is the steady-state deviation (rad/s) and T the time constant (s). For τ ≪ T it tends
/// to q²τ/3 (a random walk K = q), for τ ≫ T to 2σ²T/τ (white, N² = 2σ²T). It is the process
/// `bandwidth` is, explained as a bias rather than a filter: the bracket (with its series for
/// small τ/T) and the simulation are shared (`exponential.rs`). Simulated exactly as the mean of
/// the bias over each sample period (an integrating sensor), which makes the formula exact on the
/// τ grid; point samples of the bias (an AR(1) sequence) would add a term of order τ0/T near τ0.
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
        check_params(ID, SCHEMA, &[sigma, time_constant_s])?;
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
        Some(q2 * t * t / tau * exponential::allan_bracket(tau / t))
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        // Stationary variance σ² = n²/(2T): the drive's density n² = 2σ²T.
        let t = self.time_constant_s;
        exponential::add_period_means(2.0 * self.sigma * self.sigma * t, t, ctx.dt, rng, out);
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
    fn simulated_period_means_have_the_signature_on_the_tau_grid() {
        // T = τ0, where point samples of the bias (AR(1)) would show σ²(1 − e⁻¹) = 0.63σ² at τ0
        // against the signature's 2σ²·b(1) = 0.34σ². Over 2¹⁷ samples OADEV at m ≤ 8 scatters by
        // under 1 %; 4 % leaves room.
        let (sigma, dt) = (2.0, 0.01);
        let gm = GaussMarkov::new(sigma, dt).unwrap();
        let ctx = SimContext { dt, white_sigma: 0.0, temperature_c: None, accel: None };
        let mut y = vec![0.0; 1 << 17];
        gm.simulate(&ctx, &mut rand_chacha::ChaCha8Rng::seed_from_u64(5), &mut y);
        let phase = crate::allan::naive::phase_from_rate(&y, dt);
        for m in [1, 2, 4, 8] {
            let (measured, _) = crate::allan::fast::oavar(&phase, dt, m).unwrap();
            let expected = gm.avar(m as f64 * dt).unwrap();
            assert!((measured / expected - 1.0).abs() < 0.04, "m = {m}: {measured} vs {expected}");
        }
    }
}
