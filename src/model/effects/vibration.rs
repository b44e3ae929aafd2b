//! `vibration`: a second vibration line, beside the one `sinusoid` describes.

use super::{
    check_params, params_of, sinusoid, Domain, Effect, EffectKind, Evidence, Explanation,
    Extended, Extra, KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage, Sinusoid,
};
use rand::RngCore;

/// The schema of a line: `amplitude` and `frequency_hz`, as `sinusoid` has them.
static SCHEMA: &[ParamSpec] = sinusoid::SCHEMA;

/// The effect id (**contract** name) of this file's effect: `vibration`.
pub const ID: &str = "vibration";

static INFO: KindInfo = KindInfo {
    id: ID,
    alias: None,
    schema: SCHEMA,
    domain: Domain::Spectral,
    evidence: Evidence::None,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(Vibration::new(v[0], v[1])?)),
};

/// What the registry entry of [`Vibration`] adds to its [`KindInfo`]: it follows `sinusoid`.
pub(super) struct VibrationExtra;

/// The registry entry of [`Vibration`].
pub(super) static KIND: Extended<VibrationExtra> = Extended { info: &INFO, extra: VibrationExtra };

impl Extra for VibrationExtra {
    /// A second line is looked for only beside a first: on a model without `sinusoid` the two
    /// kinds are the same candidate, and the diagnosis would name one line twice.
    fn follows(&self) -> Option<&'static dyn EffectKind> {
        Some(&sinusoid::KIND)
    }
}

/// A second spectral line of peak `amplitude` at `frequency_hz`, for a sensor that sees two: a
/// mount's resonance and a machine nearby, a motor and its housing.
///
/// A vehicle or a building rarely vibrates at one frequency, and one `sinusoid` per axis cannot
/// hold two lines: the ADIS16405's static accel axes show one at 0.56 Hz and a weaker one near
/// 10.3 Hz (docs/model.md), and the second bends the Allan variance at 0.03–0.1 s where the
/// first one's signature is already down to its tail. Its signature and simulation are those of
/// [`Sinusoid`]; a separate kind (not two instances of one) keeps a model spec plain data with one
/// term per id, as reports, messages and the diagnosis read it.
///
/// # Formula
/// ```text
/// σ²(τ) = A²·(sin²(π f τ) / (π f τ))²
/// simulated: y[n] += A·sin(2π f n τ0 + φ),  φ uniform on [0, 2π) from the seed
/// ```
/// where A is the peak amplitude (rad/s) and f the frequency (Hz).
///
/// # References
/// IEEE Std 952-1997, Annex C (sinusoidal noise); Riley, NIST SP 1065, 2008, §9 (periodic terms).
///
/// ```
/// use fdavar::model::effects::{Effect, Sinusoid, Vibration};
/// let (v, s) = (Vibration::new(2.0, 10.0).unwrap(), Sinusoid::new(2.0, 10.0).unwrap());
/// assert_eq!(v.avar(0.037), s.avar(0.037));
/// assert!(Vibration::new(-1.0, 10.0).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vibration {
    line: Sinusoid,
}

impl Vibration {
    /// Builds the effect from the peak `amplitude` (rad/s) and `frequency_hz` (Hz).
    ///
    /// # Errors
    /// [`ParamError`] naming the parameter that is NaN or out of bounds.
    pub fn new(amplitude: f64, frequency_hz: f64) -> Result<Self, ParamError> {
        check_params(INFO.id, SCHEMA, &[amplitude, frequency_hz])?;
        Ok(Self { line: Sinusoid::new(amplitude, frequency_hz)? })
    }
}

impl Effect for Vibration {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.line.amplitude(), self.line.frequency_hz()])
    }
    fn avar(&self, tau: f64) -> Option<f64> {
        self.line.avar(tau)
    }
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]) {
        self.line.simulate(ctx, rng, out);
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "a second vibration line of {:.3e} peak at {:.4} Hz (period {:.3} s): the sensor \
                 sees two periodic disturbances, a mount's resonance, a machine or a motor nearby",
                self.line.amplitude(),
                self.line.frequency_hz(),
                1.0 / self.line.frequency_hz()
            ),
            avar_slope: None,
            reference: "IEEE Std 952-1997 Annex C",
        }
    }
}
