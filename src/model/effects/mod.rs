//! The effect vocabulary (docs/design.md §4, **contract** names): one file per physical effect.
//!
//! Each effect file holds its parameters, its Allan signature or time-domain form, its simulation
//! and its explanation. The simulator, the fitter, the diagnosis, the messages and the docs all read
//! [`REGISTRY`], so adding a physical effect is one new file and one line in that slice. Nothing
//! outside this folder matches on a concrete effect type.

use crate::model::fit::{AxisInput, FitError};
use crate::model::timedomain::{Estimate, NoiseSpectrum};
use rand::RngCore;
use serde::{Deserialize, Serialize};
use std::fmt::Debug;

mod bandwidth;
mod bias_instability;
mod bias_step;
mod exponential;
mod g_sensitivity;
mod gauss_markov;
mod noise_burst;
mod quantization;
mod ramp;
mod random_walk;
mod sinusoid;
mod temperature;
mod vibration;
mod white;

pub use bandwidth::Bandwidth;
pub use bias_instability::BiasInstability;
pub use bias_step::BiasStep;
pub use g_sensitivity::GSensitivity;
pub use gauss_markov::GaussMarkov;
pub use noise_burst::NoiseBurst;
pub use quantization::{rounding_excess, Quantization};
pub use ramp::Ramp;
pub use random_walk::RandomWalk;
pub use sinusoid::Sinusoid;
pub use temperature::Temperature;
pub use vibration::Vibration;
pub use white::White;

/// The effect ids (**contract** names), one constant per effect file, for the code outside this
/// folder that must name one effect (the terms an export reads, the white noise a burst scales).
///
/// Why constants and not strings: a renamed id then fails to compile where it is used instead of
/// silently matching nothing. Code that can ask a kind ([`EffectKind::id`]) should.
pub mod id {
    pub use super::bandwidth::ID as BANDWIDTH;
    pub use super::bias_instability::ID as BIAS_INSTABILITY;
    pub use super::bias_step::ID as BIAS_STEP;
    pub use super::g_sensitivity::ID as G_SENSITIVITY;
    pub use super::gauss_markov::ID as GAUSS_MARKOV;
    pub use super::noise_burst::ID as NOISE_BURST;
    pub use super::quantization::ID as QUANTIZATION;
    pub use super::ramp::ID as RAMP;
    pub use super::random_walk::ID as RANDOM_WALK;
    pub use super::sinusoid::ID as SINUSOID;
    pub use super::temperature::ID as TEMPERATURE;
    pub use super::vibration::ID as VIBRATION;
    pub use super::white::ID as WHITE;
}

/// The registry: every effect kind, in the order of `--help`, reports and suggestions.
///
/// Base noise terms first (IEEE 952: Q, N, B, K, R), then the effects beyond them. A new kind goes
/// at the end: the simulator draws each effect from the random stream of its index here, so an
/// insertion would change every seeded recording (the committed bags among them).
pub static REGISTRY: &[&dyn EffectKind] = &[
    &quantization::KIND,
    &white::KIND,
    &bias_instability::KIND,
    &random_walk::KIND,
    &ramp::KIND,
    &sinusoid::KIND,
    &bandwidth::KIND,
    &gauss_markov::KIND,
    &bias_step::KIND,
    &noise_burst::KIND,
    &temperature::KIND,
    &g_sensitivity::KIND,
    &vibration::KIND,
];

/// Looks a kind up by id (`white`) or alias (`N`).
pub fn find(name: &str) -> Option<&'static dyn EffectKind> {
    REGISTRY
        .iter()
        .copied()
        .find(|k| k.id() == name || k.alias() == Some(name))
}

/// How an effect shows up, which decides how the fitter estimates it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Domain {
    /// Stationary: has an Allan signature [`Effect::avar`] and is fitted on the Allan variance.
    Spectral,
    /// Non-stationary or driven by another signal: estimated in the time domain.
    TimeDomain,
}

/// When an effect is applied while a recording is simulated.
///
/// Most effects add a signal; a few act on the sensor's output (quantization rounds what the
/// others produced), so the simulator applies every `Additive` effect of an axis first, in
/// registry order, then the `Output` ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SimStage {
    /// Adds a signal to the axis.
    Additive,
    /// Transforms the sum of the additive effects (rounding, saturation).
    Output,
}

/// What evidence the diagnosis needs before it may suggest an effect (docs/design.md §6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Evidence {
    /// The axis's own samples suffice.
    None,
    /// A `sensor_msgs/Temperature` topic.
    Temperature,
    /// The accelerometer axes of the same IMU, which only a gyro axis has (the specific force
    /// drives a gyro's bias; an accel axis is not its own driver).
    Accel,
    /// A DAVAR event (a time span where the noise changed).
    Events,
}

/// The schema of one parameter: name, unit and bounds, shared by all effects of a kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// Contract name, e.g. `frequency_hz`.
    pub name: &'static str,
    /// SI unit for a gyro axis, e.g. `rad/s`; for an accel axis read `rad` as `m/s`.
    pub unit: &'static str,
    /// Inclusive bounds a value must lie in.
    pub bounds: (f64, f64),
    /// One line for `--help` and docs.
    pub doc: &'static str,
}

impl ParamSpec {
    /// The unit of this parameter on `axis`: as written for a gyro axis, with rad read as m/s on
    /// an accel axis (docs/design.md §4), e.g. `rad/s/sqrt(Hz)` → `m/s^2/sqrt(Hz)`.
    ///
    /// ```
    /// use fdavar::model::effects::find;
    /// use fdavar::signal::Axis;
    /// let n = find("white").unwrap().schema()[0];
    /// assert_eq!(n.unit_on(Axis::AccelX), "m/s^2/sqrt(Hz)");
    /// assert_eq!(find("ramp").unwrap().schema()[0].unit_on(Axis::AccelZ), "m/s^3");
    /// assert_eq!(n.unit_on(Axis::GyroX), "rad/s/sqrt(Hz)");
    /// ```
    pub fn unit_on(&self, axis: crate::signal::Axis) -> String {
        unit_on_axis(self.unit, axis)
    }
}

/// A gyro-axis SI unit as it reads on `axis`: unchanged on a gyro, `rad` → `m/s` on an accel axis
/// (so `rad/s` → `m/s^2`, `rad/s^2` → `m/s^3`).
pub fn unit_on_axis(gyro_unit: &str, axis: crate::signal::Axis) -> String {
    if axis.is_gyro() {
        gyro_unit.to_string()
    } else {
        gyro_unit
            .replace("rad/s^2", "m/s^3")
            .replace("rad/s", "m/s^2")
            .replace("rad", "m/s")
    }
}

/// The unit of a parameter whose value names an accel axis by number (`g_sensitivity`'s `source`):
/// every parameter stays an `f64`, and reports print the axis name ([`accel_axis`]).
pub const AXIS_UNIT: &str = "axis";

/// The accel axis an axis-valued parameter ([`AXIS_UNIT`]) names: 0 = `accel_x`, 1 = `accel_y`,
/// 2 = `accel_z`; `None` for any other value.
///
/// ```
/// use fdavar::model::effects::accel_axis;
/// use fdavar::signal::Axis;
/// assert_eq!(accel_axis(1.0), Some(Axis::AccelY));
/// assert_eq!(accel_axis(0.5), None);
/// ```
pub fn accel_axis(value: f64) -> Option<crate::signal::Axis> {
    use crate::signal::Axis;
    [(0.0, Axis::AccelX), (1.0, Axis::AccelY), (2.0, Axis::AccelZ)]
        .into_iter()
        .find(|&(v, _)| v == value)
        .map(|(_, a)| a)
}

/// One parameter value with its schema.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Param {
    /// The schema.
    pub spec: ParamSpec,
    /// The value in SI units.
    pub value: f64,
}

/// How an effect explains itself to a person.
#[derive(Debug, Clone, PartialEq)]
pub struct Explanation {
    /// One plain sentence of physics, with the numbers filled in.
    pub sentence: String,
    /// Log-log slope of σ²(τ) where the effect dominates (e.g. −1 for white), if it has one.
    pub avar_slope: Option<f64>,
    /// Where the signature comes from (IEEE 952 Annex C, NIST SP 1065, …).
    pub reference: &'static str,
}

/// A parameter value that is NaN, out of bounds, or missing.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ParamError {
    /// The value is NaN or infinite.
    #[error("{effect}: parameter '{param}' must be a finite number, got {value}")]
    NotFinite {
        /// Effect id.
        effect: &'static str,
        /// Parameter name.
        param: &'static str,
        /// The value given.
        value: f64,
    },
    /// The value lies outside the schema's bounds.
    #[error("{effect}: parameter '{param}' = {value} is outside [{low}, {high}] {unit}")]
    OutOfBounds {
        /// Effect id.
        effect: &'static str,
        /// Parameter name.
        param: &'static str,
        /// The value given.
        value: f64,
        /// Lower bound.
        low: f64,
        /// Upper bound.
        high: f64,
        /// Unit of the bounds.
        unit: &'static str,
    },
    /// Wrong number of values for the schema.
    #[error("{effect}: expected {expected} parameter values, got {got}")]
    Arity {
        /// Effect id.
        effect: &'static str,
        /// Values the schema has.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A parameter relation is violated (e.g. a burst that ends before it starts).
    #[error("{effect}: {reason}")]
    Invalid {
        /// Effect id.
        effect: &'static str,
        /// What is wrong, in words.
        reason: String,
    },
}

/// Checks `values` against `schema`: arity, finiteness and bounds, naming the failing parameter.
pub fn check_params(
    effect: &'static str,
    schema: &[ParamSpec],
    values: &[f64],
) -> Result<(), ParamError> {
    if schema.len() != values.len() {
        return Err(ParamError::Arity {
            effect,
            expected: schema.len(),
            got: values.len(),
        });
    }
    for (spec, &value) in schema.iter().zip(values) {
        if !value.is_finite() {
            return Err(ParamError::NotFinite {
                effect,
                param: spec.name,
                value,
            });
        }
        let (low, high) = spec.bounds;
        if value < low || value > high {
            return Err(ParamError::OutOfBounds {
                effect,
                param: spec.name,
                value,
                low,
                high,
                unit: spec.unit,
            });
        }
    }
    Ok(())
}

/// A kind of effect: its name, schema, and how to build one from values (the registry's entries).
pub trait EffectKind: Sync {
    /// Contract id, e.g. `white`.
    fn id(&self) -> &'static str;
    /// Short alias, e.g. `N`, if any.
    fn alias(&self) -> Option<&'static str>;
    /// Parameter schema, in the order `build` takes values.
    fn schema(&self) -> &'static [ParamSpec];
    /// Where the effect is estimated.
    fn domain(&self) -> Domain;
    /// What the diagnosis needs before suggesting it.
    fn evidence(&self) -> Evidence;
    /// Builds an effect, validating every value.
    ///
    /// # Errors
    /// [`ParamError`] naming the parameter that is NaN, out of bounds or inconsistent.
    fn build(&self, values: &[f64]) -> Result<Box<dyn Effect>, ParamError>;
    /// When the simulator applies it; [`SimStage::Additive`] unless the kind says otherwise.
    fn sim_stage(&self) -> SimStage {
        SimStage::Additive
    }
    /// The range (lo, hi) the fitter searches shape parameter `index` over, for a τ grid from
    /// `tau_min` to `tau_max` seconds; `None` (the default): the fitter's rule for the unit
    /// (`s`: τmin to 4·τmax; `Hz`: two periods in the record, 2/(3·τmax), to Nyquist, 1/(2·τmin)).
    fn search_range(&self, index: usize, tau_min: f64, tau_max: f64) -> Option<(f64, f64)> {
        let _ = (index, tau_min, tau_max);
        None
    }
    /// The kind's time-domain estimator, in its file ([`TimeEstimator`]); `None` (the default):
    /// none, as for a spectral kind (the fitter then reports `FitError::NoEstimator`).
    fn time_estimator(&self) -> Option<&'static dyn TimeEstimator> {
        None
    }
    /// The kind this one is a further instance of (`vibration`: a second line beside
    /// `sinusoid`'s): the diagnosis weighs it only for a model that holds that kind. `None` (the
    /// default): weighed whenever the model lacks it.
    fn follows(&self) -> Option<&'static dyn EffectKind> {
        None
    }
    /// Whether the effect's spectrum is smooth, without lines (a Gauss–Markov process, a
    /// low-pass): on the Allan variance it can mimic a line's bump, in the periodogram it cannot,
    /// so the diagnosis names a line the periodogram shows before it. `false` (the default): not
    /// known to be (undithered quantization of a slow signal has idle tones).
    fn smooth_spectrum(&self) -> bool {
        false
    }
}

/// A time-domain estimator that lives in its effect's file: how the fitter estimates the effect
/// on the rate samples and removes it before the Allan fit of the rest.
pub trait TimeEstimator: Sync {
    /// Estimates the effect on `series` (the axis's rate, earlier effects removed): by generalised
    /// least squares against `noise` when the base noise is known, else by a first guess that
    /// needs none. `fourth_cumulant`: the record's white fourth cumulant, 0 when Gaussian
    /// ([`crate::model::timedomain::estimate`]).
    ///
    /// # Errors
    /// [`FitError`] when the series cannot carry an estimate.
    fn estimate(
        &self,
        input: &AxisInput<'_>,
        series: &[f64],
        noise: Option<&NoiseSpectrum>,
        fourth_cumulant: f64,
    ) -> Result<Estimate, FitError>;
    /// Removes the effect given by its values in schema order from `series`.
    fn remove(&self, values: &[f64], input: &AxisInput<'_>, series: &mut [f64]);
    /// Where the estimator runs among an axis's time-domain effects, lowest first (equal ranks in
    /// the order given); the default, [`UNRANKED`], runs after every ranked one.
    ///
    /// Why an order: each estimator sees the series with the earlier ones' effects removed. The
    /// regressions on a driver go first (temperature 0, g-sensitivity 1): they explain the slow
    /// and the vibration parts a step or burst search would otherwise mistake. Then the step (2),
    /// then the burst (3), whose search looks at sample-to-sample differences, which a step
    /// barely touches.
    fn estimation_rank(&self) -> usize {
        UNRANKED
    }
}

/// The [`TimeEstimator::estimation_rank`] of an estimator that states none, and of a kind
/// without an estimator: after every ranked one.
pub const UNRANKED: usize = usize::MAX;

/// The registry entry of one effect file: plain data describing the kind, plus its constructor.
///
/// Every effect file declares one `KindInfo`: its registry entry `KIND`, or the `info` of that
/// entry when the kind adds methods of its own (a search range, a time-domain estimator). Keeping
/// the kind as data (rather than one hand-written `impl EffectKind` per file) keeps the files to
/// their physics.
pub struct KindInfo {
    /// Contract id.
    pub id: &'static str,
    /// Short alias (IEEE 952 letter) if any.
    pub alias: Option<&'static str>,
    /// Parameter schema in `build` order.
    pub schema: &'static [ParamSpec],
    /// Where the effect is estimated.
    pub domain: Domain,
    /// What the diagnosis needs before suggesting it.
    pub evidence: Evidence,
    /// When the simulator applies it.
    pub stage: SimStage,
    /// Builds the effect from values already checked against `schema`.
    pub construct: Constructor,
}

/// What a registry entry adds to its [`KindInfo`]: the [`EffectKind`] methods whose defaults it
/// overrides (a search range, a time-domain estimator), each in its effect's file.
pub(super) trait Extra: Sync {
    /// As [`EffectKind::search_range`].
    fn search_range(&self, index: usize, tau_min: f64, tau_max: f64) -> Option<(f64, f64)> {
        let _ = (index, tau_min, tau_max);
        None
    }
    /// As [`EffectKind::time_estimator`].
    fn time_estimator(&self) -> Option<&'static dyn TimeEstimator> {
        None
    }
    /// As [`EffectKind::follows`].
    fn follows(&self) -> Option<&'static dyn EffectKind> {
        None
    }
    /// As [`EffectKind::smooth_spectrum`].
    fn smooth_spectrum(&self) -> bool {
        false
    }
}

/// The [`Extra`] of a kind whose one addition is its time-domain estimator.
pub(super) struct WithEstimator(pub &'static dyn TimeEstimator);

impl Extra for WithEstimator {
    fn time_estimator(&self) -> Option<&'static dyn TimeEstimator> {
        Some(self.0)
    }
}

/// A registry entry: a [`KindInfo`] with the [`Extra`] methods of its effect.
pub(super) struct Extended<E: 'static> {
    /// The kind as data.
    pub info: &'static KindInfo,
    /// What it overrides.
    pub extra: E,
}

impl<E: Extra> EffectKind for Extended<E> {
    fn id(&self) -> &'static str {
        self.info.id()
    }
    fn alias(&self) -> Option<&'static str> {
        self.info.alias()
    }
    fn schema(&self) -> &'static [ParamSpec] {
        self.info.schema()
    }
    fn domain(&self) -> Domain {
        self.info.domain()
    }
    fn evidence(&self) -> Evidence {
        self.info.evidence()
    }
    fn build(&self, values: &[f64]) -> Result<Box<dyn Effect>, ParamError> {
        self.info.build(values)
    }
    fn sim_stage(&self) -> SimStage {
        self.info.sim_stage()
    }
    fn search_range(&self, index: usize, tau_min: f64, tau_max: f64) -> Option<(f64, f64)> {
        self.extra.search_range(index, tau_min, tau_max)
    }
    fn time_estimator(&self) -> Option<&'static dyn TimeEstimator> {
        self.extra.time_estimator()
    }
    fn follows(&self) -> Option<&'static dyn EffectKind> {
        self.extra.follows()
    }
    fn smooth_spectrum(&self) -> bool {
        self.extra.smooth_spectrum()
    }
}

/// Builds a boxed effect from parameter values in schema order.
pub type Constructor = fn(&[f64]) -> Result<Box<dyn Effect>, ParamError>;

impl EffectKind for KindInfo {
    fn id(&self) -> &'static str {
        self.id
    }
    fn alias(&self) -> Option<&'static str> {
        self.alias
    }
    fn schema(&self) -> &'static [ParamSpec] {
        self.schema
    }
    fn domain(&self) -> Domain {
        self.domain
    }
    fn evidence(&self) -> Evidence {
        self.evidence
    }
    fn build(&self, values: &[f64]) -> Result<Box<dyn Effect>, ParamError> {
        check_params(self.id, self.schema, values)?;
        (self.construct)(values)
    }
    fn sim_stage(&self) -> SimStage {
        self.stage
    }
}

/// Pairs a schema with values into [`Param`]s (what [`Effect::params`] returns).
fn params_of(schema: &'static [ParamSpec], values: &[f64]) -> Vec<Param> {
    schema
        .iter()
        .zip(values)
        .map(|(&spec, &value)| Param { spec, value })
        .collect()
}

/// Index of the first sample at or after `time_s`, for samples at `n·dt` (clamped to `len`).
///
/// A tolerance of 10⁻⁶ sample absorbs the rounding of `time_s / dt`, so that a time written as
/// 36 s with dt = 0.03 s lands on sample 1200, not 1201.
fn first_index_at(time_s: f64, dt: f64, len: usize) -> usize {
    let n = (time_s / dt - 1e-6).ceil();
    if n <= 0.0 {
        0
    } else {
        (n as usize).min(len)
    }
}

/// Draws one standard normal value from any `RngCore`.
fn std_normal(rng: &mut dyn RngCore) -> f64 {
    use rand_distr::Distribution;
    rand_distr::StandardNormal.sample(rng)
}

/// What an effect needs from the rest of the recording to simulate itself.
#[derive(Debug, Clone, Copy)]
pub struct SimContext<'a> {
    /// Sample period τ0, seconds.
    pub dt: f64,
    /// Standard deviation of the axis's white noise per sample (for effects that scale it).
    pub white_sigma: f64,
    /// Temperature at each sample, °C, when the recording has one.
    pub temperature_c: Option<&'a [f64]>,
    /// The true specific force on the three accel axes at each sample (gravity and vibration,
    /// without the accelerometer's own noise), m/s², when simulating a gyro axis.
    pub accel: Option<[&'a [f64]; 3]>,
}

/// What the rest of an axis does to its output, for the signature of an output effect.
///
/// See [`Effect::avar_on`]; built by the fitter from the samples and its other fitted terms.
#[derive(Clone, Copy)]
pub struct OutputContext<'a> {
    /// Mean of the rate samples, SI (gravity on an accel axis sweeps the angle steadily).
    pub mean_rate: f64,
    /// Structure function D(τ) = E[(θ(t+τ) − θ(t))²] of the angle (integrated rate) noise of
    /// the other effects, rad² (m² on an accel axis), at τ seconds, without the mean sweep.
    pub noise: &'a dyn Fn(f64) -> f64,
}

impl Debug for OutputContext<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OutputContext")
            .field("mean_rate", &self.mean_rate)
            .finish_non_exhaustive()
    }
}

/// One physical effect with its parameter values.
pub trait Effect: Debug + Send + Sync {
    /// The kind this effect is one of.
    fn kind(&self) -> &'static dyn EffectKind;
    /// The parameter values, in schema order.
    fn params(&self) -> Vec<Param>;
    /// Allan variance contribution at τ seconds for rate data, for [`Domain::Spectral`] effects.
    fn avar(&self, tau: f64) -> Option<f64>;
    /// Allan variance contribution at τ on an axis whose other effects `rest` describes.
    ///
    /// An output effect ([`SimStage::Output`]) acts on what the others produce, so its signature
    /// can depend on them: a quantizer is seen fully (the IEEE law) only when the other noise
    /// dithers it. The fitter calls this for output effects when it knows the samples' mean;
    /// every other effect keeps the default, [`Effect::avar`].
    fn avar_on(&self, tau: f64, rest: &OutputContext<'_>) -> Option<f64> {
        let _ = rest;
        self.avar(tau)
    }
    /// Applies the effect to `out`, one axis of rate samples: additive effects add, quantization
    /// rounds. Deterministic effects ignore `rng`, so simulating on zeros gives their time-domain form.
    fn simulate(&self, ctx: &SimContext<'_>, rng: &mut dyn RngCore, out: &mut [f64]);
    /// A plain sentence of physics with the numbers filled in.
    fn explain(&self) -> Explanation;
}
