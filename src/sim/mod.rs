//! A seeded simulator of six-axis IMU recordings whose truth is known, built from model::effects.
//!
//! A [`SimSpec`] (plain data, usually a YAML file) names, per axis, the effects of the vocabulary
//! with their contract parameters; [`simulate`] turns it into an in-memory [`Recording`] — the IMU
//! samples, the temperature samples and the [`Truth`] — so tests need no disk. The CLI
//! (`fdavar simulate`) writes the same recording from [`simulate_columns`] as a rosbag2 MCAP
//! directory and `truth.json`.
//!
//! Every effect simulates itself (the simulator never matches on a concrete effect): for each axis
//! it starts from the true signal (zero rate for a gyro; gravity and `vibration` for an accel axis),
//! applies the axis's additive effects in registry order and then its output effects
//! (quantization). Each (section, axis, effect) draws from its own ChaCha8 stream of the spec's
//! seed, so adding an effect to one axis leaves the noise of every other axis unchanged.
//!
//! All axes are generated in memory before the first message is written: flicker noise needs the
//! whole record (an FFT over it) and every message carries all six axes. Generation therefore
//! holds one f64 column per axis ([`Columns`], 48 B a sample) and no other copy: the writer builds
//! each message from the columns, and only [`simulate`] collects the samples (56 B more a sample).
//! Measured with `fdavar simulate` at 100 Hz for 24 h (8.64 M samples): 417 MB peak RSS without
//! bias instability, 1.49 GB with it on every axis, the peak being its filter (four arrays of
//! 2·N complex values beside the columns; it was 1.83 GB while the writer read a
//! `Vec<ImuSample>`). Rejected: a real-to-complex flicker transform (half that memory, but other
//! last bits in every recording with bias instability), and spilling finished columns to disk.

mod spec;

pub use spec::{EffectMap, LostMessages, ParamValue, ReceiptStamps, SimSpec, TemperatureProfile, Topics, MAX_SAMPLES};

use crate::model::effects::{id, Effect, ParamError, SimContext, SimStage};
use crate::signal::{Axis, ImuSample, TemperatureSample};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use spec::Planned;
use std::collections::BTreeMap;

/// Standard gravity, m/s² (added to `accel_z` when the spec asks for it).
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// Why a spec cannot be simulated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The YAML does not parse into a spec (the message names the line and field).
    #[error("spec does not parse: {0}")]
    Yaml(String),
    /// A field has a value that cannot be simulated.
    #[error("spec field '{field}': {reason}")]
    Field {
        /// Dotted path of the field, e.g. `axes.gyro_x.white`.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// An effect's parameters are invalid (the effect's error, naming the parameter, is the
    /// source: a report of the chain says it after the field).
    #[error("spec field '{field}'")]
    Param {
        /// Dotted path of the effect, e.g. `axes.gyro_x.sinusoid`.
        field: String,
        /// The effect's own error, naming the parameter.
        source: ParamError,
    },
}

/// One effect as it was simulated: contract id, alias and parameters in SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthEffect {
    /// Contract id, e.g. `white`.
    pub effect: String,
    /// Alias, e.g. `N`, if any.
    pub alias: Option<String>,
    /// Parameter name → value (SI; `source` of `g_sensitivity` as 0, 1, 2 = accel_x, y, z).
    pub params: BTreeMap<String, f64>,
    /// Parameter name → unit on the axis it was applied to.
    pub units: BTreeMap<String, String>,
}

impl TruthEffect {
    fn of(effect: &dyn Effect, axis: Axis) -> Self {
        let params = effect.params();
        Self {
            effect: effect.kind().id().into(),
            alias: effect.kind().alias().map(Into::into),
            params: params
                .iter()
                .map(|p| (p.spec.name.into(), p.value))
                .collect(),
            units: params
                .iter()
                .map(|p| (p.spec.name.into(), p.spec.unit_on(axis)))
                .collect(),
        }
    }
}

/// Everything that went into a recording: written beside the bag as `truth.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Duration, s.
    pub duration_s: f64,
    /// Number of IMU samples.
    pub samples: usize,
    /// The seed.
    pub seed: u64,
    /// Stamp of the first sample, ns.
    pub start_time_ns: i64,
    /// `header.frame_id`.
    pub frame_id: String,
    /// Topic names.
    pub topics: Topics,
    /// Gravity added to accel_z, m/s² (0 when none).
    pub gravity_m_s2: f64,
    /// The temperature profile, if any.
    pub temperature: Option<TemperatureProfile>,
    /// Accel axis name → motion effects (true specific force).
    pub vibration: BTreeMap<String, Vec<TruthEffect>>,
    /// Axis name → sensor effects, in the order they were applied.
    pub axes: BTreeMap<String, Vec<TruthEffect>>,
    /// The messages lost on the way, as the spec asked (absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lost_messages: Option<LostMessages>,
    /// How many of the `samples` were lost: the bag holds the others.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub messages_lost: usize,
    /// The stamps given on receipt, as the spec asked (absent: the sensor's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub receipt_stamps: Option<ReceiptStamps>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// A simulated recording, in memory.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// The IMU samples, one per period.
    pub imu: Vec<ImuSample>,
    /// The temperature samples (empty without a temperature profile).
    pub temperature: Vec<TemperatureSample>,
    /// What went in.
    pub truth: Truth,
}

impl Recording {
    /// The rate samples of one axis.
    pub fn axis(&self, axis: Axis) -> Vec<f64> {
        self.imu.iter().map(|s| s.value(axis)).collect()
    }
}

/// A simulated recording whose IMU samples are held as one column per axis.
///
/// What `fdavar simulate` writes from: [`Columns::imu`] builds each [`ImuSample`] as it is
/// consumed, so a writer never holds the samples (56 B each) beside the columns (48 B per
/// sample); at 24 h and 100 Hz that copy was 484 MB. [`simulate`] collects them into a
/// [`Recording`] for callers that want a slice.
#[derive(Debug, Clone, PartialEq)]
pub struct Columns {
    /// The rate samples of each axis, indexed by [`Axis::index`].
    values: [Vec<f64>; 6],
    /// Per sample, true when its message is lost ([`LostMessages`]); empty when none is.
    lost: Vec<bool>,
    /// Per sample, its stamp in ns after the first sample's time ([`ReceiptStamps`]); empty for
    /// the sensor's own stamps.
    receipt_ns: Vec<i64>,
    /// The temperature samples (empty without a temperature profile).
    pub temperature: Vec<TemperatureSample>,
    /// What went in.
    pub truth: Truth,
}

impl Columns {
    /// Number of IMU messages that reach the bag (the samples less the lost messages).
    pub fn len(&self) -> usize {
        self.values[0].len() - self.truth.messages_lost
    }

    /// True when no IMU message reaches the bag.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The IMU samples that reach the bag, in time order, each built from the columns when it is
    /// reached.
    pub fn imu(&self) -> impl Iterator<Item = ImuSample> + '_ {
        let period_ns = 1e9 / self.truth.rate_hz;
        let v = &self.values;
        (0..self.values[0].len())
            .filter(|&j| !self.lost.get(j).copied().unwrap_or(false))
            .map(move |j| ImuSample {
                stamp_ns: match self.receipt_ns.get(j) {
                    Some(offset) => self.truth.start_time_ns + offset,
                    None => stamp_ns(self.truth.start_time_ns, j as f64 * period_ns),
                },
                gyro: [v[0][j], v[1][j], v[2][j]],
                accel: [v[3][j], v[4][j], v[5][j]],
            })
    }

    /// The same recording with its samples collected (the columns are freed afterwards).
    pub fn into_recording(self) -> Recording {
        Recording {
            imu: self.imu().collect(),
            temperature: self.temperature,
            truth: self.truth,
        }
    }
}

/// The stamp of the sample `t_ns` nanoseconds after `start_ns`, rounded to the nearest ns.
fn stamp_ns(start_ns: i64, t_ns: f64) -> i64 {
    start_ns + t_ns.round() as i64
}

/// Applies `effects` to `out` in two passes (additive, then output), each on its own stream.
fn apply(effects: &[Planned], ctx: &SimContext<'_>, seed: u64, stream_base: u64, out: &mut [f64]) {
    for stage in [SimStage::Additive, SimStage::Output] {
        for p in effects
            .iter()
            .filter(|p| p.effect.kind().sim_stage() == stage)
        {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(stream_base + p.registry_index as u64);
            p.effect.simulate(ctx, &mut rng, out);
        }
    }
}

/// Per-sample deviation of the `white` term among `effects` (0 without one).
fn white_sigma(effects: &[Planned], dt: f64) -> f64 {
    effects
        .iter()
        .find(|p| p.effect.kind().id() == id::WHITE)
        .and_then(|p| p.effect.params().first().map(|n| n.value / dt.sqrt()))
        .unwrap_or(0.0)
}

/// Simulates `spec` into an in-memory recording.
///
/// The samples are collected from [`simulate_columns`]; a writer of long recordings should use
/// that directly.
///
/// # Errors
/// [`SimError`] naming the field that cannot be simulated.
///
/// ```
/// let spec = fdavar::sim::SimSpec::from_yaml(
///     "rate_hz: 100\nduration_s: 10\nseed: 1\naxes:\n  gyro_x:\n    white: {n: 1.0e-3}\n",
/// ).unwrap();
/// let rec = fdavar::sim::simulate(&spec).unwrap();
/// assert_eq!(rec.imu.len(), 1000);
/// assert_eq!(rec.imu[1].stamp_ns - rec.imu[0].stamp_ns, 10_000_000);
/// ```
pub fn simulate(spec: &SimSpec) -> Result<Recording, SimError> {
    simulate_columns(spec).map(Columns::into_recording)
}

/// Simulates `spec` into one column per axis (see [`Columns`]).
///
/// Every column must exist before the first sample can be written, because flicker noise is
/// filtered over the whole record; what is avoidable is not held: each accel axis starts from its
/// true specific force by taking it (the gyros, simulated first, are done with it).
///
/// # Errors
/// [`SimError`] naming the field that cannot be simulated.
///
/// ```
/// let spec = fdavar::sim::SimSpec::from_yaml(
///     "rate_hz: 100\nduration_s: 10\nseed: 1\naxes:\n  gyro_x:\n    white: {n: 1.0e-3}\n",
/// ).unwrap();
/// let columns = fdavar::sim::simulate_columns(&spec).unwrap();
/// assert_eq!(columns.len(), 1000);
/// let first: Vec<_> = columns.imu().take(2).collect();
/// assert_eq!(first[1].stamp_ns - first[0].stamp_ns, 10_000_000);
/// ```
pub fn simulate_columns(spec: &SimSpec) -> Result<Columns, SimError> {
    let plan = spec.plan()?;
    let (n, dt) = (plan.samples, plan.dt);
    let time = |i: usize| i as f64 * dt;
    let temperature_c: Option<Vec<f64>> = spec
        .temperature
        .as_ref()
        .map(|profile| (0..n).map(|i| profile.at(time(i))).collect());

    // True specific force on the accel axes: gravity plus motion.
    let mut force: [Vec<f64>; 3] = Default::default();
    for (k, f) in force.iter_mut().enumerate() {
        *f = vec![0.0; n];
        if k == 2 && spec.gravity {
            f.iter_mut().for_each(|v| *v = STANDARD_GRAVITY);
        }
        let ctx = SimContext {
            dt,
            white_sigma: 0.0,
            temperature_c: None,
            accel: None,
        };
        apply(
            &plan.vibration[k],
            &ctx,
            spec.seed,
            (1 << 16) | ((k as u64 + 3) << 8),
            f,
        );
    }

    let mut values: [Vec<f64>; 6] = Default::default();
    for axis in Axis::ALL {
        let i = axis.index();
        // Axis::ALL lists the gyros, which read every force, before the accel axes.
        let mut out = if axis.is_gyro() {
            vec![0.0; n]
        } else {
            std::mem::take(&mut force[i - 3])
        };
        let ctx = SimContext {
            dt,
            white_sigma: white_sigma(&plan.axes[i], dt),
            temperature_c: temperature_c.as_deref(),
            accel: axis.is_gyro().then(|| {
                [
                    force[0].as_slice(),
                    force[1].as_slice(),
                    force[2].as_slice(),
                ]
            }),
        };
        apply(&plan.axes[i], &ctx, spec.seed, (i as u64) << 8, &mut out);
        values[i] = out;
    }

    let temperature = match &spec.temperature {
        Some(profile) => {
            let count = (spec.duration_s * profile.rate_hz).ceil() as usize;
            (0..count)
                .map(|j| {
                    let t = j as f64 / profile.rate_hz;
                    TemperatureSample {
                        stamp_ns: stamp_ns(spec.start_time_ns, t * 1e9),
                        celsius: profile.at(t),
                    }
                })
                .collect()
        }
        None => Vec::new(),
    };

    let truth_of = |planned: &[Planned], axis: Axis| -> Vec<TruthEffect> {
        let mut ordered: Vec<&Planned> = planned.iter().collect();
        ordered.sort_by_key(|p| p.effect.kind().sim_stage() == SimStage::Output);
        ordered
            .iter()
            .map(|p| TruthEffect::of(p.effect.as_ref(), axis))
            .collect()
    };
    let truth = Truth {
        rate_hz: spec.rate_hz,
        duration_s: spec.duration_s,
        samples: n,
        seed: spec.seed,
        start_time_ns: spec.start_time_ns,
        frame_id: spec.frame_id.clone(),
        topics: spec.topics.clone(),
        gravity_m_s2: if spec.gravity { STANDARD_GRAVITY } else { 0.0 },
        temperature: spec.temperature.clone(),
        vibration: (0..3)
            .filter(|&k| !plan.vibration[k].is_empty())
            .map(|k| {
                (
                    Axis::ALL[k + 3].name().to_string(),
                    truth_of(&plan.vibration[k], Axis::ALL[k + 3]),
                )
            })
            .collect(),
        axes: Axis::ALL
            .into_iter()
            .filter(|a| !plan.axes[a.index()].is_empty())
            .map(|a| (a.name().to_string(), truth_of(&plan.axes[a.index()], a)))
            .collect(),
        lost_messages: spec.lost_messages,
        messages_lost: 0,
        receipt_stamps: spec.receipt_stamps,
    };
    let receipt_ns = spec
        .receipt_stamps
        .map(|r| r.offsets_ns(dt, n, spec.seed))
        .unwrap_or_default();
    let lost = spec
        .lost_messages
        .map(|l| l.lost(spec.rate_hz, n, spec.seed))
        .unwrap_or_default();
    let truth = Truth {
        messages_lost: lost.iter().filter(|&&l| l).count(),
        ..truth
    };
    Ok(Columns {
        values,
        lost,
        receipt_ns,
        temperature,
        truth,
    })
}
