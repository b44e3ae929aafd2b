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
/// simulated: y[n] += A·sin(2π f n τ0 + φ),  φ uniform on [0, 2π) from the seed
/// ```
/// where A is the peak amplitude (rad/s) and f the frequency (Hz). The formula is the average over
/// phase; a record of few periods scatters around it.
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
        let omega = 2.0 * PI * self.frequency_hz * ctx.dt;
        for (n, y) in out.iter_mut().enumerate() {
            *y += self.amplitude * (omega * n as f64 + phase).sin();
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
