//! `temperature`: a bias proportional to the sensor's temperature.

use super::{
    check_params, params_of, Domain, Effect, EffectKind, Evidence, Explanation, Extended,
    KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage, TimeEstimator, WithEstimator,
};
use crate::model::fit::{AxisInput, FitError};
use crate::model::timedomain::{
    block_regression, regress, regress_slow, remove_driven, Estimate, NoiseSpectrum, Signature,
    Whitened,
};
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[ParamSpec {
    name: "coefficient_per_k",
    unit: "rad/s/K",
    bounds: (-1e3, 1e3),
    doc: "bias change per kelvin of sensor temperature",
}];

/// The effect id (**contract** name) of this file's effect: `temperature`.
pub const ID: &str = "temperature";

static INFO: KindInfo = KindInfo {
    id: ID,
    alias: None,
    schema: SCHEMA,
    domain: Domain::TimeDomain,
    evidence: Evidence::Temperature,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(Temperature::new(v[0])?)),
};

/// The registry entry of [`Temperature`], with its time-domain estimator.
pub(super) static KIND: Extended<WithEstimator> =
    Extended { info: &INFO, extra: WithEstimator(&OnTemperature) };

/// The temperature coefficient's estimator: the slope of the rate on the temperature topic.
///
/// Why two GLS estimates: both are unbiased under the base noise, and the one with the smaller σ
/// is kept. The tapered differences ([`Whitened::regress`]) cancel the linear part of a warm-up
/// (its information is in the block means), and block means ([`block_regression`]) average away
/// a driver faster than a block. Without the base noise, the ordinary least-squares slope
/// ([`regress`]) is the first guess. The strength is that of the differenced block means
/// ([`regress_slow`]), which a random walk does not fake. It runs first among the time-domain
/// estimators (with g-sensitivity after it): the regressions explain the slow and the vibration
/// parts a step or burst search would otherwise mistake.
///
/// # Formula
/// ```text
/// with the base noise:   c = the GLS estimate (Whittle or block means) with the smaller σ
/// without (first guess): c = Σ (T−T̄)(y−ȳ) / Σ (T−T̄)²
/// removed: y[n] −= c·(T[n] − T̄)
/// ```
/// where T is the temperature (°C) at each sample and T̄ its mean over the finite samples.
///
/// # References
/// Whittle P., "Curve and periodogram smoothing", JRSS B 19(1), 1957; Kariya T. & Kurata H.,
/// Generalized Least Squares, Wiley 2004, §2.
struct OnTemperature;

impl TimeEstimator for OnTemperature {
    fn estimate(
        &self,
        input: &AxisInput<'_>,
        series: &[f64],
        noise: Option<&NoiseSpectrum>,
        _fourth_cumulant: f64,
    ) -> Result<Estimate, FitError> {
        let t = input.temperature_c.ok_or_else(|| FitError::MissingEvidence {
            axis: input.axis.name(),
            effect: INFO.id,
            needs: "a temperature topic",
        })?;
        let whittle = noise.and_then(|n| Whitened::new(series, n)?.regress(t));
        let blocks = noise.and_then(|n| block_regression(series, Some(t), n));
        let gls = [whittle, blocks].into_iter().flatten().min_by(|a, b| a.sigma.total_cmp(&b.sigma));
        let (c, s) = gls.map_or_else(
            || {
                let (c, s, _) = regress(series, t);
                (c, s)
            },
            |g| (g.coefficient, g.sigma),
        );
        let (_, _, strength) = regress_slow(series, t);
        Ok(Estimate::coefficients(vec![c], vec![Some(s)], strength, Signature::Driven))
    }
    fn remove(&self, values: &[f64], input: &AxisInput<'_>, series: &mut [f64]) {
        if let Some(t) = input.temperature_c {
            remove_driven(series, t, values[0]);
        }
    }
    fn estimation_rank(&self) -> usize {
        0
    }
}

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
        check_params(INFO.id, SCHEMA, &[coefficient_per_k])?;
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
