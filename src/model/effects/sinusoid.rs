//! `sinusoid`: a periodic disturbance of one frequency.

use super::{
    check_params, params_of, Domain, Effect, EffectKind, Evidence, Explanation, KindInfo, Param,
    ParamError, ParamSpec, SimContext, SimStage,
};
use rand::{Rng, RngCore};
use std::f64::consts::PI;

pub(super) static SCHEMA: &[ParamSpec] = &[
    ParamSpec {
        name: "amplitude",
        unit: "rad/s",
        bounds: (0.0, 1e3),
        doc: "peak amplitude A of the sinusoid",
    },
    ParamSpec {
        name: "frequency_hz",
        unit: "Hz",
        bounds: (1e-9, 1e6),
        doc: "frequency f of the sinusoid",
    },
];

/// The effect id (**contract** name) of this file's effect: `sinusoid`.
pub const ID: &str = "sinusoid";

/// The registry entry of [`Sinusoid`].
pub(super) static KIND: KindInfo = KindInfo {
    id: ID,
    alias: None,
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(Sinusoid::new(v[0], v[1])?)),
};

/// A sinusoidal rate of peak `amplitude` at `frequency_hz`: vibration, a pump, a thermal cycle.
///
/// Its Allan variance is a bump near τ ≈ 0.37/f with nulls at τ = k/f, a shape no power-law term
/// fits, which is how the diagnosis recognises it.
///
/// # Formula
/// ```text
/// σ²(τ) = A²·(sin²(π f τ) / (π f τ))²
/// simulated: y[n] += A·sinc(f τ0)·sin(2π f (n + ½) τ0 + φ),  sinc(x) = sin(πx)/(πx),
///            φ uniform on [0, 2π) from the seed
/// ```
/// where A is the peak amplitude (rad/s) of the rate and f the frequency (Hz). The formula is the
/// average over phase; a record of few periods scatters around it.
///
/// Each sample is the mean of the rate over its period, as an integrating IMU outputs it (Δθ/τ0)
/// and as `bandwidth` assumes: the mean of m samples is then the average over τ = m·τ0 and the
/// formula is exact on the τ grid, so the fitted A is the rate's. Point samples of the rate would
/// have the Allan variance σ²(τ)/sinc²(fτ0) at every τ, and a fit would find A 1/sinc(fτ0) too
/// large: 11 % at f = rate/4, 32 % at 0.4·rate.
///
/// # References
/// IEEE Std 952-1997, Annex C (sinusoidal noise); Riley, NIST SP 1065, 2008, §9 (periodic terms).
///
/// ```
/// use fdavar::model::effects::{Effect, Sinusoid};
/// let s = Sinusoid::new(2.0, 0.25).unwrap();
/// // τ = 2 s: sin²(π/2) / (π/2) = 2/π, squared, times A².
/// assert!((s.avar(2.0).unwrap() - 4.0 * (2.0 / std::f64::consts::PI).powi(2)).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sinusoid {
    amplitude: f64,
    frequency_hz: f64,
}

impl Sinusoid {
    /// Builds the effect from the peak `amplitude` (rad/s) and `frequency_hz` (Hz).
    ///
    /// # Errors
    /// [`ParamError`] naming the parameter that is NaN or out of bounds.
    pub fn new(amplitude: f64, frequency_hz: f64) -> Result<Self, ParamError> {
        check_params(KIND.id, SCHEMA, &[amplitude, frequency_hz])?;
        Ok(Self {
            amplitude,
            frequency_hz,
        })
    }

    /// The peak amplitude A, rad/s.
    pub fn amplitude(&self) -> f64 {
        self.amplitude
    }

    /// The frequency f, Hz.
    pub fn frequency_hz(&self) -> f64 {
        self.frequency_hz
    }
}

impl Effect for Sinusoid {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.amplitude, self.frequency_hz])
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        let x = PI * self.frequency_hz * tau;
        let s = x.sin();
        Some(self.amplitude * self.amplitude * (s * s / x).powi(2))
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        let phase = rng.random::<f64>() * 2.0 * PI;
        let half_turn = PI * self.frequency_hz * ctx.dt;
        // The mean over a period: the sinc attenuation, the phase of the period's middle.
        let mean_gain = if half_turn > 0.0 { half_turn.sin() / half_turn } else { 1.0 };
        let (amplitude, omega) = (self.amplitude * mean_gain, 2.0 * half_turn);
        for (n, y) in out.iter_mut().enumerate() {
            *y += amplitude * (omega * (n as f64 + 0.5) + phase).sin();
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "a periodic disturbance of {:.3e} peak at {:.4} Hz (period {:.3} s): vibration, a \
                 pump, a thermal cycle",
                self.amplitude,
                self.frequency_hz,
                1.0 / self.frequency_hz
            ),
            avar_slope: None,
            reference: "IEEE Std 952-1997 Annex C",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn simulated_period_means_have_the_signature_on_the_tau_grid() {
        // A line at 0.4·rate, where point samples would show 1/sinc²(0.4) = 1.74 times the
        // signature. Over 2¹⁶ samples (26 214 periods) the estimate averages the phase out; 2 %
        // leaves room for the record's edges.
        let (dt, f) = (0.01, 40.0);
        let line = Sinusoid::new(1.0, f).unwrap();
        let ctx = SimContext { dt, white_sigma: 0.0, temperature_c: None, accel: None };
        let mut y = vec![0.0; 1 << 16];
        line.simulate(&ctx, &mut rand_chacha::ChaCha8Rng::seed_from_u64(3), &mut y);
        let phase = crate::allan::naive::phase_from_rate(&y, dt);
        // m = 5 is a null (f·5τ0 = 2).
        for m in 1..=4 {
            let (measured, _) = crate::allan::fast::oavar(&phase, dt, m).unwrap();
            let expected = line.avar(m as f64 * dt).unwrap();
            assert!((measured / expected - 1.0).abs() < 0.02, "m = {m}: {measured} vs {expected}");
        }
    }
}
