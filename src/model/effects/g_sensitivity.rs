//! `g_sensitivity`: a gyro bias proportional to the specific force on one accel axis.

use super::{
    accel_axis, check_params, params_of, Domain, Effect, EffectKind, Evidence, Explanation,
    Extended, KindInfo, Param, ParamError, ParamSpec, SimContext, SimStage, TimeEstimator,
    WithEstimator,
};
use crate::model::fit::{AxisInput, FitError};
use crate::model::timedomain::{regress, remove_driven, Estimate, NoiseSpectrum, Signature, Whitened};
use crate::signal::Axis;
use rand::RngCore;

static SCHEMA: &[ParamSpec] = &[
    ParamSpec {
        name: "source",
        unit: super::AXIS_UNIT,
        bounds: (0.0, 2.0),
        doc: "accel axis the gyro responds to: 0 = accel_x, 1 = accel_y, 2 = accel_z",
    },
    ParamSpec {
        name: "coefficient",
        unit: "(rad/s)/(m/s^2)",
        bounds: (-1e3, 1e3),
        doc: "gyro bias per unit of specific force on the source axis",
    },
];

/// The effect id (**contract** name) of this file's effect: `g_sensitivity`.
pub const ID: &str = "g_sensitivity";

static INFO: KindInfo = KindInfo {
    id: ID,
    alias: None,
    schema: SCHEMA,
    domain: Domain::TimeDomain,
    evidence: Evidence::Accel,
    stage: SimStage::Additive,
    construct: |v| Ok(Box::new(GSensitivity::new(v[0], v[1])?)),
};

/// The registry entry of [`GSensitivity`], with its time-domain estimator.
pub(super) static KIND: Extended<WithEstimator> =
    Extended { info: &INFO, extra: WithEstimator(&OnAccel) };

/// The g-sensitivity's estimator: the slope of the gyro rate on each accel axis, the strongest kept.
///
/// Why GLS against the base noise when it is known ([`Whitened::regress_measured`]): the ordinary
/// least-squares slope on a wandering record weighs the gyro's and the accelerometer's random
/// walks as heavily as the motion (measured: −19 % on a 60 min record where the GLS was within
/// 3 %). Without the base noise, the ordinary least-squares slope ([`regress`]) is the first
/// guess. It runs second among the time-domain estimators, after temperature and before the step
/// and burst searches, which its vibration part would otherwise mislead.
///
/// # Formula
/// ```text
/// for s in accel_x, accel_y, accel_z:  (c_s, σ_s, t²_s) = GLS (or OLS) slope of y on a_s
/// source = argmax_s t²_s,   coefficient = c_source
/// removed: y[n] −= coefficient·(a_source[n] − ā_source)
/// ```
/// where a_s is the measured specific force on accel axis s and ā_s its mean over the finite
/// samples. On a gyro axis only: an accel axis has no g-sensitivity of its own.
///
/// What it cannot tell: on a sensor that did not move, the accel axis varies only by its own noise
/// and bias drift, so a slope found there is a driver both biases share (temperature without a
/// topic: the real ADIS16405, docs/model.md "Known limits"), not g-sensitivity; the explanation
/// says so.
///
/// # References
/// Whittle P., "Curve and periodogram smoothing", JRSS B 19(1), 1957; Analog Devices AN-1049.
struct OnAccel;

impl TimeEstimator for OnAccel {
    fn estimate(
        &self,
        input: &AxisInput<'_>,
        series: &[f64],
        noise: Option<&NoiseSpectrum>,
        _fourth_cumulant: f64,
    ) -> Result<Estimate, FitError> {
        let acc = input.accel.filter(|_| input.axis.is_gyro()).ok_or_else(|| {
            FitError::MissingEvidence {
                axis: input.axis.name(),
                effect: INFO.id,
                needs: "the accelerometer axes of the same IMU (gyro axes only)",
            }
        })?;
        let whitened = noise.and_then(|n| Whitened::new(series, n));
        let best = (0..3)
            .map(|src| {
                let gls = whitened.as_ref().and_then(|w| w.regress_measured(acc[src]));
                (src, gls.map_or_else(|| regress(series, acc[src]), |g| (g.coefficient, g.sigma, g.t2)))
            })
            .max_by(|a, b| a.1 .2.total_cmp(&b.1 .2))
            .unwrap_or((0, (0.0, 0.0, 0.0)));
        let (src, (c, s, strength)) = best;
        Ok(Estimate::coefficients(vec![src as f64, c], vec![None, Some(s)], strength, Signature::Driven))
    }
    fn remove(&self, values: &[f64], input: &AxisInput<'_>, series: &mut [f64]) {
        if let Some(acc) = input.accel {
            remove_driven(series, acc[(values[0].round() as usize).min(2)], values[1]);
        }
    }
    fn estimation_rank(&self) -> usize {
        1
    }
}

/// A gyro bias of `coefficient` per m/s² of specific force on the `source` accel axis.
///
/// MEMS gyros are vibrating structures, and acceleration deflects them: vibration on one axis leaks
/// into the rate of another. It is estimated by regressing the gyro axis on the accel axis.
///
/// The `source` parameter is an axis carried as a number in [`Effect::params`] and
/// [`EffectKind::build`] values (0 = `accel_x`, 1 = `accel_y`, 2 = `accel_z`), so that every
/// parameter stays an `f64`; [`GSensitivity::source`] gives it back as an [`Axis`].
///
/// # Formula
/// ```text
/// y[n] += c·a_s[n]
/// ```
/// where c is `coefficient` ((rad/s)/(m/s²)) and a_s the true specific force on the source axis
/// (gravity and vibration, without the accelerometer's own noise).
///
/// # References
/// IEEE Std 952-1997, Annex C (g-sensitivity, "acceleration sensitivity"); Analog Devices
/// AN-1049 (linear acceleration effects on MEMS gyros).
///
/// ```
/// use fdavar::model::effects::{Effect, GSensitivity};
/// use fdavar::signal::Axis;
/// let g = GSensitivity::new(2.0, 1e-3).unwrap();
/// assert_eq!(g.source(), Axis::AccelZ);
/// assert!(GSensitivity::new(0.5, 1e-3).is_err()); // not a whole axis number
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GSensitivity {
    source: usize,
    coefficient: f64,
}

impl GSensitivity {
    /// Builds the effect from the `source` accel axis number (0, 1, 2) and the `coefficient`.
    ///
    /// # Errors
    /// [`ParamError`] naming the parameter that is NaN or out of bounds, or
    /// [`ParamError::Invalid`] when `source` is not a whole number.
    pub fn new(source: f64, coefficient: f64) -> Result<Self, ParamError> {
        check_params(INFO.id, SCHEMA, &[source, coefficient])?;
        if source.fract() != 0.0 {
            return Err(ParamError::Invalid {
                effect: INFO.id,
                reason: format!(
                    "source = {source} must be 0 (accel_x), 1 (accel_y) or 2 (accel_z)"
                ),
            });
        }
        Ok(Self {
            source: source as usize,
            coefficient,
        })
    }

    /// The accel axis the gyro responds to.
    pub fn source(&self) -> Axis {
        // `new` admits only 0, 1 and 2.
        accel_axis(self.source as f64).unwrap_or(Axis::AccelX)
    }

    /// The coefficient, (rad/s)/(m/s²).
    pub fn coefficient(&self) -> f64 {
        self.coefficient
    }
}

impl Effect for GSensitivity {
    fn kind(&self) -> &'static dyn EffectKind {
        &KIND
    }
    fn params(&self) -> Vec<Param> {
        params_of(SCHEMA, &[self.source as f64, self.coefficient])
    }
    fn avar(&self, _tau: f64) -> Option<f64> {
        None
    }
    fn simulate(&self, ctx: &SimContext<'_>, _rng: &mut dyn RngCore, out: &mut [f64]) {
        let Some(accel) = ctx.accel else {
            return;
        };
        for (y, &a) in out.iter_mut().zip(accel[self.source]) {
            *y += self.coefficient * a;
        }
    }
    fn explain(&self) -> Explanation {
        Explanation {
            sentence: format!(
                "the gyro responds to acceleration on {} at {:.3e} (rad/s) per m/s²: vibration or \
                 manoeuvres leak into the rate (if the sensor did not move, a slow driver both \
                 biases share, such as temperature, reads the same)",
                self.source(),
                self.coefficient
            ),
            avar_slope: None,
            reference: "IEEE Std 952-1997 Annex C; ADI AN-1049",
        }
    }
}
