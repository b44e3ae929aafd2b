//! `temperature`: a bias proportional to the sensor's temperature.

use super::{
    check_params, params_of, Domain, Effect, EffectKind, Evidence, Explanation, KindInfo, Param,
    ParamError, ParamSpec, SimContext, SimStage,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[ParamSpec {
    name: "coefficient_per_k",
    unit: "rad/s/K",
    bounds: (-1e3, 1e3),
    doc: "bias change per kelvin of sensor temperature",
}];

/// The registry entry of [`Temperature`].
pub(super) static KIND: KindInfo = KindInfo {
    id: "temperature",
    alias: None,
    schema: SCHEMA,
    domain: Domain::TimeDomain,
    evidence: Evidence::Temperature,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(Temperature::new(v[0])?)),
};

/// A bias of `coefficient_per_k` per kelvin of temperature change: the warm-up drift of MEMS.
///
/// It follows the temperature, not time, so it is estimated by regressing the axis on the
/// `sensor_msgs/Temperature` topic; in the Allan variance it looks like a ramp or a random walk.
///
/// # Formula
/// ```text
/// y[n] += c·(T[n] − T[0])
/// ```
/// where c is `coefficient_per_k` (rad/s/K) and T\[n\] the temperature (°C) at sample n, so the
/// effect is zero at the first sample. Without a temperature signal the effect adds nothing (the
/// simulator refuses such a spec).
///
/// # References
/// IEEE Std 952-1997, Annex C (temperature sensitivity); El-Sheimy et al., IEEE TIM 57(1), 2008.
///
/// ```
/// use fdavar::model::effects::{Effect, SimContext, Temperature};
/// let t = Temperature::new(0.01).unwrap();
/// let temps = [20.0, 21.0, 25.0];
/// let ctx = SimContext { dt: 1.0, white_sigma: 0.0, temperature_c: Some(&temps), accel: None };
/// let mut y = [0.0; 3];
/// let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
/// t.simulate(&ctx, &mut rng, &mut y);
/// assert!((y[2] - 0.05).abs() < 1e-15);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Temperature {
    coefficient_per_k: f64,
}

impl Temperature {
    /// Builds the effect from its `coefficient_per_k` (rad/s/K).
    ///
    /// # Errors
    /// [`ParamError`] naming `coefficient_per_k` when it is NaN or out of bounds.
    pub fn new(coefficient_per_k: f64) -> Result<Self, ParamError> {
        check_params(KIND.id, SCHEMA, &[coefficient_per_k])?;
        Ok(Self { coefficient_per_k })
    }

    /// The coefficient, rad/s/K.
    pub fn coefficient_per_k(&self) -> f64 {
        self.coefficient_per_k
    }
}

impl Effect for Temperature {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.coefficient_per_k])
    }
    fn avar(&self, _tau: f64) -> Option<f64> {
        None
    }
    fn simulate(&self, ctx: &SimContext<'_>, _rng: &mut dyn RngCore, out: &mut [f64]) {
        let Some(temps) = ctx.temperature_c else {
            return;
        };
        let Some(&t0) = temps.first() else {
            return;
        };
        for (y, &t) in out.iter_mut().zip(temps) {
            *y += self.coefficient_per_k * (t - t0);
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "the bias follows the sensor temperature at {:.3e} per kelvin: thermal drift, \
                 strongest during warm-up",
                self.coefficient_per_k
            ),
            avar_slope: None,
            reference: "IEEE Std 952-1997 Annex C; El-Sheimy et al. 2008",
        }
    }
}
