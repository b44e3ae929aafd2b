//! The simulation spec: what a YAML file asks for, as plain data, and its validation.

use crate::model::effects::{find, id as effect_id, Domain, Effect, SimStage};
use crate::signal::Axis;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

use super::SimError;

/// A simulation spec (the YAML file of `fdavar simulate`): plain data, comparable with `==`.
///
/// Every field but `rate_hz`, `duration_s` and `seed` has a default; unknown fields are refused.
/// `axes` and `vibration` map an axis name to a map of effect name (contract id or alias) to a map
/// of contract parameter names to values (SI units; `source` of `g_sensitivity` also accepts
/// `accel_x`, `accel_y`, `accel_z`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimSpec {
    /// Sample rate, Hz: 1/rate_hz must lie in the `tau0` parameter's range
    /// ([`crate::params::TAU0_RANGE_S`], 10⁻⁵ to 86 400 s).
    pub rate_hz: f64,
    /// Length of the recording, s (samples = round(duration_s·rate_hz)).
    pub duration_s: f64,
    /// Seed of every random stream (ChaCha8): the same spec and seed give the same recording.
    pub seed: u64,
    /// Stamp of the first sample, ns since the Unix epoch (default 1 700 000 000 s).
    #[serde(default = "default_start")]
    pub start_time_ns: i64,
    /// `header.frame_id` of every message (default `imu_link`).
    #[serde(default = "default_frame")]
    pub frame_id: String,
    /// Topic names.
    #[serde(default)]
    pub topics: Topics,
    /// Add standard gravity (9.80665 m/s²) to the true specific force on `accel_z` (default false).
    #[serde(default)]
    pub gravity: bool,
    /// The sensor's temperature profile; required by any `temperature` effect.
    #[serde(default)]
    pub temperature: Option<TemperatureProfile>,
    /// Motion of the accel axes (true specific force), as spectral effects of the vocabulary, in
    /// m/s² — e.g. `sinusoid` for a vibrating mount, `gauss_markov` for band-limited random motion.
    #[serde(default)]
    pub vibration: BTreeMap<String, EffectMap>,
    /// Sensor errors per axis: effect name → parameters.
    #[serde(default)]
    pub axes: BTreeMap<String, EffectMap>,
    /// Messages lost on the way to the recorder (default: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lost_messages: Option<LostMessages>,
    /// Stamps given on receipt by the driver instead of the sensor's clock (default: the sensor's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub receipt_stamps: Option<ReceiptStamps>,
}

/// Stamps that a driver gives when it reads the messages, as many ROS drivers of serial and USB
/// IMUs do, instead of the sensor's sample times.
///
/// Messages are read in packets of `packet`: the k-th message of a packet is stamped at the time
/// of the packet's last sample plus k·`spacing_s`, and each packet's read time moves by a uniform
/// offset in ±`jitter_s` (the reading thread's scheduling), so that stamps keep their order. The values are those of the sensor's grid; only
/// `header.stamp` changes. What the analysis must do with it: lay the messages out on the grid as
/// the sensor's stamps would be (docs/design.md §1, tests/stamps_on_receipt.rs).
///
/// ```
/// use fdavar::sim::ReceiptStamps;
/// let r = ReceiptStamps { packet: 4, spacing_s: 2e-5, jitter_s: 0.0 };
/// let stamps = r.offsets_ns(0.005, 8, 1);
/// // Samples 0–3 are read with sample 3 (at 15 ms), 20 µs apart; 4–7 with sample 7.
/// assert_eq!(stamps, [15_000_000, 15_020_000, 15_040_000, 15_060_000, 35_000_000, 35_020_000, 35_040_000, 35_060_000]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReceiptStamps {
    /// Messages read together, 1 to [`crate::signal::MAX_EARLY_RUN`] (default 1).
    #[serde(default = "one")]
    pub packet: u64,
    /// Time between the stamps of one packet's messages, s (default 20 µs).
    #[serde(default = "default_spacing")]
    pub spacing_s: f64,
    /// Half-width of a uniform jitter of each packet's read time, s (default 0).
    #[serde(default)]
    pub jitter_s: f64,
}

fn one() -> u64 {
    1
}
fn default_spacing() -> f64 {
    2e-5
}

impl ReceiptStamps {
    /// The stamps of `n` samples at `period_s`, in ns from the first sample's time; the jitter
    /// draws from its own ChaCha8 stream of `seed`.
    pub fn offsets_ns(&self, period_s: f64, n: usize, seed: u64) -> Vec<i64> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(RECEIPT_STAMPS_STREAM);
        let packet = self.packet.max(1) as usize;
        let mut jitter = 0.0;
        (0..n)
            .map(|j| {
                // One read time per packet: its messages keep their order and spacing.
                if j % packet == 0 && self.jitter_s > 0.0 {
                    jitter = rng.random_range(-self.jitter_s..self.jitter_s);
                }
                let read = ((j / packet) * packet + packet - 1).min(n - 1);
                let t = read as f64 * period_s + (j % packet) as f64 * self.spacing_s + jitter;
                (t * 1e9).round() as i64
            })
            .collect()
    }

    fn check(&self, period_s: f64) -> Result<(), SimError> {
        if !(1..=crate::signal::MAX_EARLY_RUN).contains(&self.packet) {
            return Err(field_error(
                "receipt_stamps.packet",
                format!("must lie in [1, {}], got {}", crate::signal::MAX_EARLY_RUN, self.packet),
            ));
        }
        let spread = (self.packet - 1) as f64 * self.spacing_s;
        if !(self.spacing_s >= 0.0 && spread < 0.5 * period_s) {
            return Err(field_error(
                "receipt_stamps.spacing_s",
                format!("must be ≥ 0 with a packet's stamps within half a period ({} s), got {}", 0.5 * period_s, self.spacing_s),
            ));
        }
        if !(self.jitter_s >= 0.0 && self.jitter_s < 0.5 * period_s - spread) {
            return Err(field_error(
                "receipt_stamps.jitter_s",
                format!("must lie in [0, {} s) (half a period, less the packet's spread)", 0.5 * period_s - spread),
            ));
        }
        Ok(())
    }
}

/// ChaCha8 stream of the receipt stamps' jitter.
const RECEIPT_STAMPS_STREAM: u64 = (2 << 16) + 1;

/// Messages lost between the sensor and the recorder, as a robot's network loses them.
///
/// The sensor measured every sample, so the samples that arrive are those of the same spec without
/// losses; the bag leaves the lost ones out (a reader sees a gap of one or more periods) and
/// `truth.json` counts them. Why in the simulator: 0.5–1 % lost messages are common on a robot,
/// and an Allan term that straddles a hole is left out, which at such rates removes every long τ
/// (docs/model.md, "Lost messages").
///
/// ```
/// use fdavar::sim::LostMessages;
/// let runs = LostMessages { probability: 0.0, every_s: Some(10.0), length_s: 0.05 };
/// let lost = runs.lost(100.0, 3000, 7);
/// // 5 messages from 5 s, 15 s and 25 s on: 500..505, 1500..1505, 2500..2505.
/// assert_eq!(lost.iter().filter(|&&l| l).count(), 15);
/// assert!(lost[500..505].iter().all(|&l| l) && !lost[505] && !lost[499]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LostMessages {
    /// Probability that a message is lost on its own, in [0, 0.5] (default 0).
    #[serde(default)]
    pub probability: f64,
    /// Period of runs of lost messages, s; the first run starts at every_s/2 (default: no runs).
    #[serde(default)]
    pub every_s: Option<f64>,
    /// Length of each run, s: round(length_s·rate_hz) messages, at most half of every_s (default 0).
    #[serde(default)]
    pub length_s: f64,
}

impl LostMessages {
    /// Which of `n` messages at `rate_hz` are lost; the single losses draw from their own ChaCha8
    /// stream of `seed`, so they leave every axis's values unchanged.
    pub fn lost(&self, rate_hz: f64, n: usize, seed: u64) -> Vec<bool> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(LOST_MESSAGES_STREAM);
        let runs = self.every_s.map(|every| {
            let every = ((every * rate_hz).round() as usize).max(1);
            (every, (self.length_s * rate_hz).round() as usize)
        });
        (0..n)
            .map(|i| {
                let in_run = runs.is_some_and(|(every, len)| (i + every - every / 2) % every < len);
                // One draw per message, lost or not, so a run does not shift the later draws.
                let single = self.probability > 0.0 && rng.random_bool(self.probability);
                in_run || single
            })
            .collect()
    }

    fn check(&self) -> Result<(), SimError> {
        if !(0.0..=0.5).contains(&self.probability) {
            return Err(field_error(
                "lost_messages.probability",
                format!("must lie in [0, 0.5], got {}", self.probability),
            ));
        }
        if let Some(every) = self.every_s {
            positive("lost_messages.every_s", every)?;
            if !(self.length_s >= 0.0 && self.length_s <= 0.5 * every) {
                return Err(field_error(
                    "lost_messages.length_s",
                    format!("must lie in [0, every_s/2] = [0, {}], got {}", 0.5 * every, self.length_s),
                ));
            }
        } else if self.length_s != 0.0 {
            return Err(field_error("lost_messages.length_s", "needs every_s, the period of the runs"));
        }
        Ok(())
    }
}

/// ChaCha8 stream of the single message losses (the effects use (section, axis, effect) streams
/// below 2¹⁷).
const LOST_MESSAGES_STREAM: u64 = 2 << 16;

/// Effect name (id or alias) → parameter name → value.
pub type EffectMap = BTreeMap<String, BTreeMap<String, ParamValue>>;

/// A parameter value in a spec: a number, or an axis name for a parameter whose unit is `axis`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ParamValue {
    /// A number in SI units.
    Number(f64),
    /// An axis name (`accel_x` …).
    Name(String),
}

/// Largest recording simulated, e.g. 400 Hz for 13.9 h or 1 kHz for 5.5 h.
///
/// The recording is held in memory: 48 bytes a sample (≈ 1 GB here), and 176 at the peak of the
/// flicker filter when an axis has bias instability (≈ 3.5 GB).
pub const MAX_SAMPLES: usize = 20_000_000;

fn default_start() -> i64 {
    1_700_000_000_000_000_000
}

fn default_frame() -> String {
    "imu_link".into()
}

/// Topic names of the recording.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Topics {
    /// `sensor_msgs/msg/Imu` topic (default `/imu/data`).
    pub imu: String,
    /// `sensor_msgs/msg/Temperature` topic (default `/imu/temperature`), written when the spec has
    /// a temperature profile.
    pub temperature: String,
}

impl Default for Topics {
    fn default() -> Self {
        Self {
            imu: "/imu/data".into(),
            temperature: "/imu/temperature".into(),
        }
    }
}

/// The sensor temperature over time: a first-order warm-up plus an optional slow cycle.
///
/// # Formula
/// ```text
/// T(t) = end_c + (start_c − end_c)·e^(−t/time_constant_s) + cycle_amplitude_c·sin(2π t / cycle_period_s)
/// ```
/// where t is seconds from the first sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemperatureProfile {
    /// Temperature at t = 0, °C.
    pub start_c: f64,
    /// Temperature the warm-up tends to, °C (default: `start_c`).
    #[serde(default)]
    pub end_c: Option<f64>,
    /// Warm-up time constant, s (default 300).
    #[serde(default = "default_warmup")]
    pub time_constant_s: f64,
    /// Peak amplitude of the slow cycle, K (default 0: none).
    #[serde(default)]
    pub cycle_amplitude_c: f64,
    /// Period of the slow cycle, s (default 3600).
    #[serde(default = "default_cycle")]
    pub cycle_period_s: f64,
    /// Rate of the Temperature topic, Hz (default 1).
    #[serde(default = "default_temp_rate")]
    pub rate_hz: f64,
}

fn default_warmup() -> f64 {
    300.0
}
fn default_cycle() -> f64 {
    3600.0
}
fn default_temp_rate() -> f64 {
    1.0
}

impl TemperatureProfile {
    /// The temperature at `t` seconds from the first sample, °C.
    pub fn at(&self, t: f64) -> f64 {
        let end = self.end_c.unwrap_or(self.start_c);
        end + (self.start_c - end) * (-t / self.time_constant_s).exp()
            + self.cycle_amplitude_c * (2.0 * std::f64::consts::PI * t / self.cycle_period_s).sin()
    }
}

/// One effect of an axis, resolved from the spec.
#[derive(Debug)]
pub(super) struct Planned {
    /// Position of its kind in the registry (part of its random stream id).
    pub registry_index: usize,
    pub effect: Box<dyn Effect>,
}

/// A spec checked and resolved: effects built, sizes computed.
#[derive(Debug)]
pub(super) struct Plan {
    pub samples: usize,
    pub dt: f64,
    /// Per axis (Axis::ALL order): the effects, in registry order.
    pub axes: [Vec<Planned>; 6],
    /// Per accel axis: the motion effects.
    pub vibration: [Vec<Planned>; 3],
}

fn field_error(field: impl Into<String>, reason: impl Into<String>) -> SimError {
    SimError::Field {
        field: field.into(),
        reason: reason.into(),
    }
}

/// Checks a ROS 2 topic name as a bag and `fdavar play` need it: absolute, tokens of letters,
/// digits and underscores, not starting with a digit, separated by single slashes, no trailing
/// slash (issue 13: `/imu data//` was written into the bag).
fn check_topic(field: &str, topic: &str) -> Result<(), SimError> {
    let good_token = |t: &str| {
        t.chars().next().is_some_and(|c| !c.is_ascii_digit())
            && t.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
    };
    match topic.strip_prefix('/') {
        Some(rest) if rest.split('/').all(good_token) => Ok(()),
        _ => Err(field_error(
            field,
            format!(
                "'{topic}' is not a ROS 2 topic name (absolute, e.g. /imu/data: letters, digits \
                 and _ between single slashes)"
            ),
        )),
    }
}

/// Checks that no effect's frequency lies above what samples at `rate_hz` can hold: the highest
/// frequency the fitter searches for its kind at τ0 = 1/rate_hz, which is the Nyquist frequency
/// rate_hz/2 unless the kind says otherwise (a sinusoid above it would alias: issue 13).
fn check_frequencies(
    section: &str,
    axis: &str,
    planned: &[Planned],
    rate_hz: f64,
    duration_s: f64,
) -> Result<(), SimError> {
    let tau0 = 1.0 / rate_hz;
    for p in planned {
        let kind = p.effect.kind();
        for (i, q) in p
            .effect
            .params()
            .iter()
            .enumerate()
            .filter(|(_, q)| q.spec.unit == "Hz")
        {
            let highest = kind
                .search_range(i, tau0, duration_s)
                .map_or(0.5 * rate_hz, |r| r.1);
            if q.value > highest {
                return Err(field_error(
                    format!("{section}.{axis}.{}.{}", kind.id(), q.spec.name),
                    format!(
                        "{} Hz is above the highest frequency samples at rate_hz {rate_hz} can hold \
                         ({highest} Hz{})",
                        q.value,
                        if highest == 0.5 * rate_hz { ", the Nyquist frequency" } else { "" }
                    ),
                ));
            }
        }
    }
    Ok(())
}

fn positive(field: &str, value: f64) -> Result<(), SimError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(field_error(
            field,
            format!("must be a positive number, got {value}"),
        ))
    }
}

/// Builds the effects of one axis map, in registry order, naming the failing field.
fn resolve(section: &str, axis: &str, map: &EffectMap) -> Result<Vec<Planned>, SimError> {
    let mut planned = Vec::new();
    for (name, values) in map {
        let field = format!("{section}.{axis}.{name}");
        let kind = find(name).ok_or_else(|| {
            field_error(
                &field,
                "unknown effect (see docs/sim.md for the vocabulary and aliases)",
            )
        })?;
        if let Some(extra) = values
            .keys()
            .find(|k| !kind.schema().iter().any(|s| s.name == k.as_str()))
        {
            return Err(field_error(
                format!("{field}.{extra}"),
                format!(
                    "unknown parameter; {} takes {}",
                    kind.id(),
                    kind.schema()
                        .iter()
                        .map(|s| s.name)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        let mut numbers = Vec::new();
        for spec in kind.schema() {
            let pfield = format!("{field}.{}", spec.name);
            let number = match values.get(spec.name) {
                None => return Err(field_error(pfield, format!("missing ({})", spec.doc))),
                Some(ParamValue::Number(v)) => *v,
                Some(ParamValue::Name(s)) if spec.unit == "axis" => match s.parse::<Axis>() {
                    Ok(a) if !a.is_gyro() => (a.index() - 3) as f64,
                    _ => return Err(field_error(pfield, format!("'{s}' is not an accel axis"))),
                },
                Some(ParamValue::Name(s)) => {
                    return Err(field_error(pfield, format!("expected a number, got '{s}'")))
                }
            };
            numbers.push(number);
        }
        let effect = kind.build(&numbers).map_err(|source| SimError::Param {
            field: field.clone(),
            source,
        })?;
        let registry_index = crate::model::effects::REGISTRY
            .iter()
            .position(|k| k.id() == kind.id())
            .unwrap_or(0);
        if planned
            .iter()
            .any(|p: &Planned| p.registry_index == registry_index)
        {
            return Err(field_error(
                field,
                "the same effect is given twice (id and alias)",
            ));
        }
        planned.push(Planned {
            registry_index,
            effect,
        });
    }
    planned.sort_by_key(|p| p.registry_index);
    Ok(planned)
}

fn axis_of(section: &str, name: &str) -> Result<Axis, SimError> {
    name.parse::<Axis>()
        .map_err(|e| field_error(format!("{section}.{name}"), e.to_string()))
}

impl SimSpec {
    /// Parses a YAML spec.
    ///
    /// # Errors
    /// [`SimError::Yaml`] with the parser's message (it names the line and the field).
    pub fn from_yaml(text: &str) -> Result<SimSpec, SimError> {
        serde_yaml_ng::from_str(text).map_err(|e| SimError::Yaml(e.to_string()))
    }

    /// Number of IMU samples: round(duration_s·rate_hz).
    pub fn samples(&self) -> usize {
        (self.duration_s * self.rate_hz).round() as usize
    }

    /// Checks every field and builds the effects.
    pub(super) fn plan(&self) -> Result<Plan, SimError> {
        positive("rate_hz", self.rate_hz)?;
        // Stamps are whole nanoseconds: 10¹² Hz made every stamp a duplicate (issue 13).
        let (tau0_min, tau0_max) = crate::params::TAU0_RANGE_S;
        if !(tau0_min..=tau0_max).contains(&(1.0 / self.rate_hz)) {
            return Err(field_error(
                "rate_hz",
                format!(
                    "{} Hz gives tau0 = {:e} s, outside [{tau0_min:e}, {tau0_max:e}] s (the tau0 \
                     range fdavar analyses)",
                    self.rate_hz,
                    1.0 / self.rate_hz
                ),
            ));
        }
        positive("duration_s", self.duration_s)?;
        let samples = self.samples();
        if !(2..=MAX_SAMPLES).contains(&samples) {
            return Err(field_error(
                "duration_s",
                format!(
                    "gives {samples} samples at rate_hz; the simulator holds a recording in memory \
                     and takes 2 to {MAX_SAMPLES}"
                ),
            ));
        }
        if self.start_time_ns <= 0 {
            return Err(field_error(
                "start_time_ns",
                "must be positive (a zero stamp means 'no stamp' to readers)",
            ));
        }
        if self.frame_id.is_empty() {
            return Err(field_error("frame_id", "must not be empty"));
        }
        for (field, topic) in [
            ("topics.imu", &self.topics.imu),
            ("topics.temperature", &self.topics.temperature),
        ] {
            check_topic(field, topic)?;
        }
        if let Some(lost) = &self.lost_messages {
            lost.check()?;
        }
        if let Some(receipt) = &self.receipt_stamps {
            receipt.check(1.0 / self.rate_hz)?;
        }
        if let Some(t) = &self.temperature {
            for (field, v) in [
                ("temperature.start_c", t.start_c),
                ("temperature.end_c", t.end_c.unwrap_or(t.start_c)),
                ("temperature.cycle_amplitude_c", t.cycle_amplitude_c),
            ] {
                if !v.is_finite() {
                    return Err(field_error(
                        field,
                        format!("must be a finite number, got {v}"),
                    ));
                }
            }
            positive("temperature.time_constant_s", t.time_constant_s)?;
            positive("temperature.cycle_period_s", t.cycle_period_s)?;
            positive("temperature.rate_hz", t.rate_hz)?;
        }
        let mut axes: [Vec<Planned>; 6] = Default::default();
        for (name, map) in &self.axes {
            let axis = axis_of("axes", name)?;
            let planned = resolve("axes", name, map)?;
            check_frequencies("axes", name, &planned, self.rate_hz, self.duration_s)?;
            for p in &planned {
                let id = p.effect.kind().id();
                let field = format!("axes.{name}.{id}");
                let evidence = p.effect.kind().evidence();
                use crate::model::effects::Evidence;
                if evidence == Evidence::Temperature && self.temperature.is_none() {
                    return Err(field_error(
                        field,
                        "needs a `temperature:` profile in the spec",
                    ));
                }
                if evidence == Evidence::Accel && !axis.is_gyro() {
                    return Err(field_error(field, "applies to gyro axes only"));
                }
                if id == effect_id::NOISE_BURST && !planned.iter().any(|q| q.effect.kind().id() == effect_id::WHITE) {
                    return Err(field_error(
                        field,
                        format!("scales the white noise: add `{}` to this axis", effect_id::WHITE),
                    ));
                }
                // A time-domain event must begin inside the recording (its first time parameter:
                // `time_s` of a step, `start_s` of a burst).
                if p.effect.kind().domain() == Domain::TimeDomain {
                    if let Some(start) = p.effect.params().into_iter().find(|q| q.spec.unit == "s")
                    {
                        if start.value >= self.duration_s {
                            return Err(field_error(
                                format!("{field}.{}", start.spec.name),
                                format!(
                                    "{} s is not inside the recording (duration_s = {})",
                                    start.value, self.duration_s
                                ),
                            ));
                        }
                    }
                }
            }
            axes[axis.index()] = planned;
        }
        let mut vibration: [Vec<Planned>; 3] = Default::default();
        for (name, map) in &self.vibration {
            let axis = axis_of("vibration", name)?;
            if axis.is_gyro() {
                return Err(field_error(
                    format!("vibration.{name}"),
                    "vibration is given on accel axes",
                ));
            }
            let planned = resolve("vibration", name, map)?;
            check_frequencies("vibration", name, &planned, self.rate_hz, self.duration_s)?;
            if let Some(p) = planned.iter().find(|p| {
                p.effect.kind().domain() != Domain::Spectral
                    || p.effect.kind().sim_stage() != SimStage::Additive
            }) {
                return Err(field_error(
                    format!("vibration.{name}.{}", p.effect.kind().id()),
                    "motion takes additive spectral effects only (sinusoid, gauss_markov, white, …)",
                ));
            }
            vibration[axis.index() - 3] = planned;
        }
        Ok(Plan {
            samples,
            dt: 1.0 / self.rate_hz,
            axes,
            vibration,
        })
    }
}
