//! Power curves and false alarms of the diagnosis (issue 10), shared by `tests/diagnosis_power.rs`
//! (a CI-sized run) and `examples/diagnosis_power.rs` (the full curves of docs/model.md, which
//! includes this file by path).
//!
//! Recordings come from the real simulator (`fdavar::sim`), laid out as a bag is
//! (`Recording::from_samples`); the diagnosis never sees the truth. Base noise mixes are those of
//! common MEMS IMUs (`MIXES`); a hidden effect's strength is in units of that base noise:
//! - spectral effects: the AVAR peak ratio, max over τ ∈ [τ0, T/3] of σ²_effect(τ)/σ²_base(τ);
//! - a sensor's low-pass (`bandwidth`, which replaces white noise rather than adding to it): the
//!   AVAR deficit, max over τ of (N²/τ − σ²_bandwidth(τ))/σ²_base(τ), about 3/(4π·f_c·τ0) at τ0;
//! - time-domain effects: the σ of the diagnosis's own test under the base noise (a step: its size
//!   over √(2σ²_A(W)) at the scan's window; a regression: the coefficient over its GLS σ; a burst:
//!   z with z² = n·[ln(φf² + 1 − φ) − φ·ln f²]/κ, twice the expected effective likelihood ratio of
//!   a span of fraction φ at σ ratio f).
//!
//! Effects are built from their public types, so no effect id is written here: each one's id is
//! read from the effect itself.
#![allow(dead_code)]

use fdavar::model::effects::{
    Bandwidth, BiasStep, Effect, Evidence, GSensitivity, GaussMarkov, NoiseBurst, Quantization, Ramp, Sinusoid,
    Temperature, Vibration, REGISTRY,
};
use fdavar::model::measure::NoiseClass;
use fdavar::model::record::Recording;
use fdavar::model::timedomain::{step_window, trend, NoiseSpectrum, Whitened};
use fdavar::model::{diagnose, FitOptions, ModelSpec};
use fdavar::signal::Axis;
use fdavar::sim::LostMessages;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::fmt::Write;

/// A sensor's base noise: name, gyro (N, B, K), accel (N, B, K), SI.
#[derive(Debug)]
pub struct Mix {
    /// Short name.
    pub name: &'static str,
    /// Gyro N, B, K.
    pub gyro: [f64; 3],
    /// Accel N, B, K.
    pub accel: [f64; 3],
}

/// N and K from `../shared/reference/imu_noise_params.md` (Kalibr noise densities and random
/// walks); B from the datasheets' bias instability where the table gives one (D435i 1.8–4.9 °/h,
/// VN-100 < 10 °/h and 0.04 mg), else a value in the same range (2–10 °/h, 0.01–0.05 mg); K where
/// the table has none, a small one (the sensor's K is below its B floor within the record).
/// `test` is the test suite's own mix (tests/model_common).
pub const MIXES: &[Mix] = &[
    Mix { name: "test", gyro: [1.5e-4, 5.0e-5, 2.7e-6], accel: [2.0e-3, 4.0e-4, 1.2e-4] },
    Mix { name: "d435i", gyro: [1.52e-4, 1.45e-5, 2.66e-6], accel: [6.31e-3, 3.9e-4, 1.17e-4] },
    Mix { name: "euroc", gyro: [1.6968e-4, 1.0e-5, 1.9393e-5], accel: [2.0e-3, 1.0e-4, 3.0e-3] },
    Mix { name: "tumvi", gyro: [1.6e-4, 1.0e-5, 2.2e-5], accel: [2.8e-3, 1.0e-4, 8.6e-4] },
    Mix { name: "vn100", gyro: [6.11e-5, 2.0e-5, 5.0e-7], accel: [1.37e-3, 3.9e-4, 5.0e-5] },
    Mix { name: "mti100", gyro: [1.75e-4, 2.0e-5, 1.0e-6], accel: [5.9e-4, 1.0e-4, 1.0e-5] },
    Mix { name: "adis16405", gyro: [8.7e-4, 5.0e-5, 1.0e-5], accel: [4.9e-3, 5.0e-4, 1.0e-4] },
];

/// One recording's setting: rate (Hz), length (min), base noise, seed.
#[derive(Debug, Clone, Copy)]
pub struct Setting {
    /// Sample rate, Hz.
    pub rate: f64,
    /// Length, minutes.
    pub minutes: f64,
    /// Base noise.
    pub mix: &'static Mix,
    /// Seed of the simulator and of the hidden effect's draw.
    pub seed: u64,
}

impl Setting {
    /// Samples in the record.
    pub fn samples(&self) -> usize {
        (self.minutes * 60.0 * self.rate).round() as usize
    }
    /// Record length, s.
    pub fn seconds(&self) -> f64 {
        self.minutes * 60.0
    }
}

/// `count` settings cycling through `grid` (rate, minutes) and every mix, seeds from `seed`.
pub fn settings(count: usize, grid: &[(f64, f64)], seed: u64) -> Vec<Setting> {
    (0..count)
        .map(|i| Setting {
            rate: grid[i % grid.len()].0,
            minutes: grid[i % grid.len()].1,
            mix: &MIXES[(i + i / grid.len()) % MIXES.len()],
            seed: seed + i as u64,
        })
        .collect()
}

/// The warm-up temperature profile of the test suite: 20 → 28 °C, 10 min time constant, 0.5 K
/// wobble of period 2π·300 s, published at 10 Hz.
pub const TEMPERATURE: &str = "{ start_c: 20.0, end_c: 28.0, time_constant_s: 600, cycle_amplitude_c: 0.5, cycle_period_s: 1884.9555921538758, rate_hz: 10 }";

/// The YAML of one effect, `id: { name: value, … }`, from the effect itself.
pub fn effect_yaml(e: &dyn Effect) -> String {
    let fields: Vec<String> = e.params().iter().map(|p| format!("{}: {:e}", p.spec.name, p.value)).collect();
    format!("{}: {{ {} }}", e.kind().id(), fields.join(", "))
}

/// The simulator spec: the mix on `axes`, the warm-up temperature, `extra` effects on their axes
/// and `motion` as true accel motion (`vibration`).
pub fn spec_yaml(s: &Setting, axes: &[Axis], extra: &[(Axis, &dyn Effect)], motion: &[(Axis, &dyn Effect)]) -> String {
    let mut y = String::new();
    writeln!(y, "rate_hz: {}\nduration_s: {}\nseed: {}", s.rate, s.seconds(), s.seed).unwrap();
    writeln!(y, "temperature: {TEMPERATURE}").unwrap();
    if !motion.is_empty() {
        y.push_str("vibration:\n");
        for (axis, e) in motion {
            writeln!(y, "  {}: {{ {} }}", axis.name(), effect_yaml(*e)).unwrap();
        }
    }
    y.push_str("axes:\n");
    for &axis in axes {
        let [n, b, k] = if axis.is_gyro() { s.mix.gyro } else { s.mix.accel };
        // A sensor's low-pass filters its white noise: the axis's N is the effect's n.
        let filtered = extra.iter().any(|(a, e)| *a == axis && e.kind().id() == Bandwidth::new(1.0, 1.0).unwrap().kind().id());
        let white = if filtered { String::new() } else { format!("N: {{ n: {n:e} }}, ") };
        write!(y, "  {}: {{ {white}B: {{ b: {b:e} }}, K: {{ k: {k:e} }}", axis.name()).unwrap();
        for (a, e) in extra {
            if *a == axis {
                write!(y, ", {}", effect_yaml(*e)).unwrap();
            }
        }
        y.push_str(" }\n");
    }
    y
}

/// Simulates a spec and lays it out as a bag is read.
pub fn record(yaml: &str) -> Recording {
    record_losing(yaml, None)
}

/// [`record`] of the spec with `loss` (the simulator's `lost_messages:`): the layout marks each
/// missing sample invalid, as it does for a bag.
pub fn record_losing(yaml: &str, loss: Option<LostMessages>) -> Recording {
    record_within(yaml, loss, fdavar::model::record::RecordBuilder::DEFAULT_MAX_SAMPLES)
}

/// [`record_losing`] halved whenever the record would hold more than `max_samples` per axis.
pub fn record_within(yaml: &str, loss: Option<LostMessages>, max_samples: usize) -> Recording {
    let mut spec = fdavar::sim::SimSpec::from_yaml(yaml).unwrap_or_else(|e| panic!("{e}\n{yaml}"));
    spec.lost_messages = loss;
    let sim = fdavar::sim::simulate(&spec).unwrap_or_else(|e| panic!("{e}\n{yaml}"));
    Recording::from_samples_within(&sim.imu, &sim.temperature, max_samples).unwrap()
}

/// The base noise of `axis` under the setting's mix, exact for the three power laws.
pub fn base_noise(s: &Setting, axis: Axis) -> NoiseSpectrum {
    let [n, b, k] = if axis.is_gyro() { s.mix.gyro } else { s.mix.accel };
    let (white, flicker, walk) = ([n * n], [2.0 * std::f64::consts::LN_2 / std::f64::consts::PI * b * b], [k * k / 3.0]);
    NoiseSpectrum::from_curves(
        1.0 / s.rate,
        &[1.0],
        [
            (NoiseClass::WhiteFm, &white[..]),
            (NoiseClass::FlickerFm, &flicker[..]),
            (NoiseClass::RandomWalkFm, &walk[..]),
        ],
    )
}

/// Peak of σ²_effect/σ²_base over τ ∈ [τ0, T/3], ten τ per decade.
pub fn avar_peak_ratio(e: &dyn Effect, s: &Setting, base: &NoiseSpectrum) -> f64 {
    let (lo, hi) = (1.0 / s.rate, s.seconds() / 3.0);
    let steps = ((hi / lo).log10() * 10.0).ceil() as usize;
    (0..=steps)
        .map(|i| lo * (hi / lo).powf(i as f64 / steps as f64))
        .map(|tau| e.avar(tau).unwrap_or(0.0) / base.avar(tau))
        .fold(0.0, f64::max)
}

/// How a family's strength is counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// AVAR peak ratio (spectral effects).
    AvarPeak,
    /// σ of the diagnosis's test (time-domain effects).
    TestSigma,
    /// AVAR deficit ratio (a low-pass, below the white noise it replaces).
    AvarDeficit,
}

/// A hidden effect on one axis, with the motion it needs.
#[derive(Debug)]
pub struct Hidden {
    /// The axis it is on.
    pub axis: Axis,
    /// The effect.
    pub effect: Box<dyn Effect>,
    /// True motion of an accel axis (g-sensitivity's driver).
    pub motion: Option<(Axis, Box<dyn Effect>)>,
    /// An effect on the same axis that the starting model already holds (the first line, beside
    /// which `vibration` is weighed): the diagnosis starts from N,B,K and it.
    pub beside: Option<Box<dyn Effect>>,
}

impl Hidden {
    /// `effect` alone on `axis`: no motion, nothing beside it.
    pub fn alone(axis: Axis, effect: Box<dyn Effect>) -> Hidden {
        Hidden { axis, effect, motion: None, beside: None }
    }
}

/// One effect family of the power curves: a name (the effect's id), how its strength is counted,
/// and how to hide it at a strength in a setting.
pub struct Family {
    /// The effect's id (read from an instance).
    pub name: &'static str,
    /// Strength unit.
    pub scale: Scale,
    /// Builds the hidden effect.
    pub make: Maker,
    /// The stated visibility: a strength of the measured power curve (docs/model.md,
    /// `examples/diagnosis_power.rs power 10 7`, records of 20–60 min) at which the effect is named
    /// first, with its parameters within tolerance, in at least 90 % of recordings there and in the
    /// CI-sized check on 10–20 min records (tests/diagnosis_power.rs).
    pub visible: f64,
}

/// +1 or −1, equally likely.
fn random_sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.random_bool(0.5) {
        1.0
    } else {
        -1.0
    }
}

fn any_axis(rng: &mut ChaCha8Rng) -> Axis {
    Axis::ALL[rng.random_range(0..6)]
}

/// The spectral effect `build(1.0)` scaled so that its AVAR peak ratio is `strength` (σ² of a
/// spectral effect is proportional to its first parameter squared).
fn at_peak(s: &Setting, axis: Axis, strength: f64, build: impl Fn(f64) -> Box<dyn Effect>) -> Box<dyn Effect> {
    let base = base_noise(s, axis);
    let reference = 1e-3;
    let r1 = avar_peak_ratio(&*build(reference), s, &base);
    build(reference * (strength / r1).sqrt())
}

fn sinusoid(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = any_axis(rng);
    let f = [0.02, 0.1, 0.5, 2.0][rng.random_range(0..4)];
    sinusoid_at(s, axis, strength, f)
}

/// A line at `f` whose AVAR peak is `strength` × the base AVAR.
fn sinusoid_at(s: &Setting, axis: Axis, strength: f64, f: f64) -> Hidden {
    Hidden::alone(axis, at_peak(s, axis, strength, |a| Box::new(Sinusoid::new(a, f).unwrap())))
}

/// A second line (`vibration`) at `strength` beside a first, 32× the base AVAR at its peak, which
/// the starting model's `sinusoid` takes; 3.7 or 7.3 times its frequency (not a harmonic).
fn vibration(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = any_axis(rng);
    let f = [0.05, 0.2, 1.0][rng.random_range(0..3)];
    let ratio = [3.7, 7.3][rng.random_range(0..2)];
    vibration_at(s, axis, strength, f, ratio)
}

/// A second line at `strength`, `ratio` times the frequency `f` of a first line 32× the base AVAR.
fn vibration_at(s: &Setting, axis: Axis, strength: f64, f: f64, ratio: f64) -> Hidden {
    Hidden {
        axis,
        effect: at_peak(s, axis, strength, |a| Box::new(Vibration::new(a, ratio * f).unwrap())),
        motion: None,
        beside: Some(at_peak(s, axis, 32.0, |a| Box::new(Sinusoid::new(a, f).unwrap()))),
    }
}

/// Time constants of 0.5, 2 or 10 s, at most a [`GM_CORRELATION_TIMES`]th of the record: the
/// parameters cannot be measured to their tolerance on fewer correlation times.
fn gauss_markov(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = any_axis(rng);
    let t = [0.5_f64, 2.0, 10.0][rng.random_range(0..3)].min(s.seconds() / GM_CORRELATION_TIMES);
    gauss_markov_at(s, axis, strength, t)
}

/// A Gauss–Markov process of time constant `t` whose AVAR peak is `strength` × the base AVAR.
fn gauss_markov_at(s: &Setting, axis: Axis, strength: f64, t: f64) -> Hidden {
    Hidden::alone(axis, at_peak(s, axis, strength, |a| Box::new(GaussMarkov::new(a, t).unwrap())))
}

/// The least record length, in correlation times, of the `gauss_markov` family.
///
/// Why: no estimator measures a Gauss–Markov process better than its Cramér–Rao bound, which for
/// an AR(1) sequence of N samples is var σ̂² = 2σ⁴(1 + φ²)/(N(1 − φ²)) and var φ̂ = (1 − φ²)/N:
/// for τ0 ≪ T, σ̂ scatters by √(T/2L) and T̂ by √(2T/L) of their values over a record of L
/// seconds. At L/T = 120 that is 6.5 % and 13 %: both within tolerance (10 %, 25 %) in at most
/// about 83 % of records. At L/T ≥ 300, 4.1 % and 8.2 %: 98 %. Measured with the Allan fit (16
/// recordings of T = 10 s in 20 min at 16× the base AVAR): σ̂/σ 0.68–1.19, T̂/T 0.68–1.89.
pub const GM_CORRELATION_TIMES: f64 = 300.0;

/// White noise of the mix's N through a first-order low-pass whose AVAR deficit is `strength`
/// (cut-off by bisection: the deficit falls as f_c grows).
fn bandwidth(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = any_axis(rng);
    let n = if axis.is_gyro() { s.mix.gyro[0] } else { s.mix.accel[0] };
    let effect = |fc: f64| Bandwidth::new(n, fc).unwrap();
    let deficit = |fc: f64| avar_deficit_ratio(&effect(fc), s, &base_noise(s, axis));
    let (mut lo, mut hi) = ((1e-3 * s.rate).ln(), (1e3 * s.rate).ln());
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if deficit(mid.exp()) > strength {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Hidden::alone(axis, Box::new(effect(hi.exp())))
}

/// Peak of (N²/τ − σ²_bandwidth(τ))/σ²_base(τ) over τ ∈ [τ0, T/3], ten τ per decade: how far
/// below the white noise it replaces a low-pass puts the Allan variance.
pub fn avar_deficit_ratio(e: &Bandwidth, s: &Setting, base: &NoiseSpectrum) -> f64 {
    let n = e.params()[0].value;
    let (lo, hi) = (1.0 / s.rate, s.seconds() / 3.0);
    let steps = ((hi / lo).log10() * 10.0).ceil() as usize;
    (0..=steps)
        .map(|i| lo * (hi / lo).powf(i as f64 / steps as f64))
        .map(|tau| (n * n / tau - e.avar(tau).unwrap_or(0.0)) / base.avar(tau))
        .fold(0.0, f64::max)
}

fn ramp(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = any_axis(rng);
    let sign = random_sign(rng);
    let zeros = vec![0.0; s.samples()];
    let sigma = trend(&zeros, &base_noise(s, axis)).map_or(f64::NAN, |r| r.sigma);
    Hidden::alone(axis, Box::new(Ramp::new(sign * strength * sigma).unwrap()))
}

fn quantization(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = any_axis(rng);
    Hidden::alone(axis, at_peak(s, axis, strength, |a| Box::new(Quantization::new(a).unwrap())))
}

fn bias_step(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = any_axis(rng);
    let sign = random_sign(rng);
    let fraction = rng.random_range(0.25..0.75);
    bias_step_at(s, axis, sign * strength, fraction)
}

/// How a family hides its effect at a strength in a setting ([`Family::make`]).
pub type Maker = fn(&Setting, f64, &mut ChaCha8Rng) -> Hidden;

/// The id of `e`'s effect.
fn id(e: &dyn Effect) -> &'static str {
    e.kind().id()
}

/// `low` · (`high`/`low`)^u for u uniform in [0, 1).
fn log_uniform(rng: &mut ChaCha8Rng, low: f64, high: f64) -> f64 {
    rng.random_range(low.ln()..high.ln()).exp()
}

/// Rates (Hz) and lengths (min) of [`wide_families`]' checks: 30–400 Hz, 10–90 min, mostly
/// outside the power curves' grid (100–400 Hz, 20–60 min).
pub const WIDE_GRID: &[(f64, f64)] = &[(50.0, 30.0), (100.0, 20.0), (250.0, 15.0), (400.0, 10.0), (100.0, 90.0), (30.0, 60.0)];

/// The families whose parameters the power curves draw from a few values (`families`), drawn
/// instead from wide continuous ranges (the rest as in `families`): a line anywhere from six
/// periods per record to 0.4 × the rate, a Gauss–Markov time constant from 50 ms to the
/// [`GM_CORRELATION_TIMES`] limit, a second line 2.3–9.5 times a first of 0.02–1 Hz (not within
/// 0.15 of a harmonic), a step anywhere in 10–90 % of the record, a burst over 3–40 % of it, a
/// g-sensitivity moved at 0.02–2 Hz. What the diagnosis was tuned on is the families' values;
/// these check that it holds between and beyond them.
pub fn wide_families() -> Vec<Family> {
    let wide: &[(&str, Maker)] = &[
        (id(&Sinusoid::new(1.0, 1.0).unwrap()), |s, strength, rng| {
            let axis = any_axis(rng);
            sinusoid_at(s, axis, strength, log_uniform(rng, 6.0 / s.seconds(), 0.4 * s.rate))
        }),
        (id(&GaussMarkov::new(1.0, 1.0).unwrap()), |s, strength, rng| {
            let axis = any_axis(rng);
            gauss_markov_at(s, axis, strength, log_uniform(rng, 0.05, s.seconds() / GM_CORRELATION_TIMES))
        }),
        (id(&Vibration::new(1.0, 1.0).unwrap()), |s, strength, rng| {
            let axis = any_axis(rng);
            let mut ratio: f64 = rng.random_range(2.3..9.5);
            if (ratio - ratio.round()).abs() < 0.15 {
                ratio += 0.3;
            }
            let f = log_uniform(rng, 0.02, 1.0_f64.min(0.4 * s.rate / ratio));
            vibration_at(s, axis, strength, f, ratio)
        }),
        (id(&BiasStep::new(1.0, 1.0).unwrap()), |s, strength, rng| {
            let axis = any_axis(rng);
            let sign = random_sign(rng);
            bias_step_at(s, axis, sign * strength, rng.random_range(0.1..0.9))
        }),
        (id(&NoiseBurst::new(0.0, 1.0, 2.0).unwrap()), |s, strength, rng| {
            let axis = any_axis(rng);
            let phi = rng.random_range(0.03..0.4);
            noise_burst_at(s, axis, strength, phi, rng.random_range(0.05..0.95 - phi))
        }),
        (id(&GSensitivity::new(0.0, 1.0).unwrap()), |s, strength, rng| {
            let (axis, source) = (Axis::ALL[rng.random_range(0..3)], rng.random_range(0..3));
            let f = log_uniform(rng, 0.02, 2.0);
            let sign = random_sign(rng);
            g_sensitivity_at(s, axis, source, f, sign * strength)
        }),
    ];
    families()
        .into_iter()
        .map(|family| match wide.iter().find(|(name, _)| *name == family.name) {
            Some(&(_, make)) => Family { make, ..family },
            None => family,
        })
        .collect()
}

/// A step of `strength` σ of the step test (negative: down) at `fraction` of the record.
pub fn bias_step_at(s: &Setting, axis: Axis, strength: f64, fraction: f64) -> Hidden {
    let base = base_noise(s, axis);
    let w = step_window(s.samples(), &base);
    let sigma = (2.0 * base.avar(w as f64 / s.rate)).sqrt();
    let step = BiasStep::new(fraction * s.seconds(), strength * sigma).unwrap();
    Hidden::alone(axis, Box::new(step))
}

fn noise_burst(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = any_axis(rng);
    let start = rng.random_range(0.2..0.7);
    noise_burst_at(s, axis, strength, 0.1, start)
}

/// A burst over the fraction `phi` of the record from `start` (a fraction of it), as loud as makes
/// its test's z equal `strength`.
fn noise_burst_at(s: &Setting, axis: Axis, strength: f64, phi: f64, start: f64) -> Hidden {
    let base = base_noise(s, axis);
    let (n, kappa) = (s.samples() as f64, base.burst_dof_factor());
    let z2 = |f: f64| n * ((phi * f * f + 1.0 - phi).ln() - phi * (f * f).ln()) / kappa;
    let (mut lo, mut hi) = (1.0, 10.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if z2(mid) < strength * strength {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let start = s.seconds() * start;
    let end = start + phi * s.seconds();
    Hidden::alone(axis, Box::new(NoiseBurst::new(start, end, hi).unwrap()))
}

/// The GLS σ of a regression on `x` under `base`, as the diagnosis computes it.
fn regression_sigma(x: &[f64], base: &NoiseSpectrum) -> f64 {
    let zeros = vec![0.0; x.len()];
    Whitened::new(&zeros, base).and_then(|w| w.regress(x)).map_or(f64::NAN, |r| r.sigma)
}

fn temperature(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = any_axis(rng);
    let spec = fdavar::sim::SimSpec::from_yaml(&format!("rate_hz: 1\nduration_s: 1\nseed: 0\ntemperature: {TEMPERATURE}\n")).unwrap();
    let profile = spec.temperature.unwrap();
    let x: Vec<f64> = (0..s.samples()).map(|i| profile.at(i as f64 / s.rate)).collect();
    let sigma = regression_sigma(&x, &base_noise(s, axis));
    let sign = random_sign(rng);
    Hidden::alone(axis, Box::new(Temperature::new(sign * strength * sigma).unwrap()))
}

fn g_sensitivity(s: &Setting, strength: f64, rng: &mut ChaCha8Rng) -> Hidden {
    let axis = Axis::ALL[rng.random_range(0..3)];
    let source = rng.random_range(0..3);
    let f = [0.05, 0.2, 0.5][rng.random_range(0..3)];
    let sign = random_sign(rng);
    g_sensitivity_at(s, axis, source, f, sign * strength)
}

/// A gyro axis's g-sensitivity to accel axis `source` (0–2), moved by a 0.5 m/s² sinusoid of
/// frequency `f`, `strength` σ of its regression (negative: the opposite sign).
fn g_sensitivity_at(s: &Setting, axis: Axis, source: usize, f: f64, strength: f64) -> Hidden {
    let motion = Sinusoid::new(0.5, f).unwrap();
    let x: Vec<f64> = (0..s.samples())
        .map(|i| 0.5 * (2.0 * std::f64::consts::PI * f * i as f64 / s.rate).sin())
        .collect();
    let sigma = regression_sigma(&x, &base_noise(s, axis));
    Hidden {
        axis,
        effect: Box::new(GSensitivity::new(source as f64, strength * sigma).unwrap()),
        motion: Some((Axis::ALL[3 + source], Box::new(motion))),
        beside: None,
    }
}

/// Every effect beyond N, B, K, with the id read from an instance of it.
pub fn families() -> Vec<Family> {
    vec![
        Family { name: id(&Sinusoid::new(1.0, 1.0).unwrap()), scale: Scale::AvarPeak, make: sinusoid, visible: 8.0 },
        Family { name: id(&GaussMarkov::new(1.0, 1.0).unwrap()), scale: Scale::AvarPeak, make: gauss_markov, visible: 16.0 },
        Family { name: id(&Ramp::new(1.0).unwrap()), scale: Scale::TestSigma, make: ramp, visible: 24.0 },
        Family { name: id(&Quantization::new(1.0).unwrap()), scale: Scale::AvarPeak, make: quantization, visible: 0.5 },
        Family { name: id(&BiasStep::new(1.0, 1.0).unwrap()), scale: Scale::TestSigma, make: bias_step, visible: 24.0 },
        Family { name: id(&NoiseBurst::new(0.0, 1.0, 2.0).unwrap()), scale: Scale::TestSigma, make: noise_burst, visible: 16.0 },
        Family { name: id(&Temperature::new(1.0).unwrap()), scale: Scale::TestSigma, make: temperature, visible: 12.0 },
        Family { name: id(&GSensitivity::new(0.0, 1.0).unwrap()), scale: Scale::TestSigma, make: g_sensitivity, visible: 24.0 },
        Family { name: id(&Bandwidth::new(1.0, 1.0).unwrap()), scale: Scale::AvarDeficit, make: bandwidth, visible: 0.2 },
        Family { name: id(&Vibration::new(1.0, 1.0).unwrap()), scale: Scale::AvarPeak, make: vibration, visible: 4.0 },
    ]
}

/// What the diagnosis made of one recording with a hidden effect.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The hidden effect was named first.
    pub detected: bool,
    /// Its parameters were within tolerance (when detected): amplitudes, coefficients and
    /// frequencies 10 %, time constants 25 %, times 1 % of the record, a source axis exactly.
    pub params_ok: bool,
    /// What was named first instead, if anything.
    pub instead: Option<String>,
    /// The worst parameter error, in units of its tolerance (≤ 1 is within).
    pub worst: f64,
    /// Every suggestion, in order, as `effect` or `effect with given`.
    pub suggested: Vec<String>,
}

/// Simulates `hidden` in the setting, diagnoses its axis with N,B,K (and the effect it is beside)
/// and scores the outcome.
pub fn run(s: &Setting, hidden: &Hidden) -> Outcome {
    run_losing(s, hidden, None)
}

/// [`run`] on a recording that lost messages.
pub fn run_losing(s: &Setting, hidden: &Hidden, loss: Option<LostMessages>) -> Outcome {
    run_on(s, hidden, &Sensor { loss, ..Sensor::default() })
}

/// [`run`] on a sensor whose white noise passes a first-order low-pass of cut-off
/// `cutoff_per_rate`·rate on every axis the recording holds. Detected: the effect named first, or
/// second with the low-pass (`bandwidth`) first and weighed beside it (`Suggestion::given`).
pub fn run_low_pass(s: &Setting, hidden: &Hidden, cutoff_per_rate: f64) -> Outcome {
    run_on(s, hidden, &Sensor { cutoff_per_rate: Some(cutoff_per_rate), ..Sensor::default() })
}

/// [`run`] on a sensor whose samples carry isolated spikes on every axis the recording holds.
pub fn run_spiky(s: &Setting, hidden: &Hidden, spikes: Spikes) -> Outcome {
    run_on(s, hidden, &Sensor { spikes: Some(spikes), ..Sensor::default() })
}

/// What the sensor does beyond the setting's base noise, on every axis of a recording.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sensor {
    /// Messages lost (the simulator's `lost_messages:`).
    pub loss: Option<LostMessages>,
    /// A first-order low-pass of the white noise, its cut-off over the rate.
    pub cutoff_per_rate: Option<f64>,
    /// Isolated spikes added to the samples after simulation.
    pub spikes: Option<Spikes>,
}

/// Isolated spikes: one sample in `1/share` moved by ±`size` times the white noise's σ per sample
/// (a bus glitch or a knock; a real XSens MTi-G gyro reads an excess kurtosis of 117, docs/model.md
/// "Heavy tails").
#[derive(Debug, Clone, Copy)]
pub struct Spikes {
    /// Share of the samples that carry a spike.
    pub share: f64,
    /// Size of a spike in units of the white noise's σ per sample.
    pub size: f64,
}

impl Spikes {
    /// Adds spikes to `axis` (σ per sample measured from its differences, √2 σ), drawn from a
    /// stream of `seed`.
    pub fn add(&self, axis: &mut [f64], seed: u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let finite = axis.windows(2).filter(|w| w[0].is_finite() && w[1].is_finite());
        let (sum, count) = finite.fold((0.0, 0usize), |(s, c), w| (s + (w[1] - w[0]).powi(2), c + 1));
        let sigma = (sum / (2.0 * count.max(1) as f64)).sqrt();
        for v in axis.iter_mut() {
            if rng.random::<f64>() < self.share {
                *v += self.size * sigma * random_sign(&mut rng);
            }
        }
    }
}

/// The sensor's low-pass on `axis` in the setting: white noise of the mix's N through a
/// first-order filter of cut-off `cutoff_per_rate`·rate.
fn low_pass(s: &Setting, axis: Axis, cutoff_per_rate: f64) -> Bandwidth {
    let n = if axis.is_gyro() { s.mix.gyro[0] } else { s.mix.accel[0] };
    Bandwidth::new(n, cutoff_per_rate * s.rate).unwrap()
}

/// The recording of `spec_yaml`'s setting as `sensor` gives it.
fn record_by(s: &Setting, yaml: &str, sensor: &Sensor) -> Recording {
    let mut rec = record_losing(yaml, sensor.loss);
    if let Some(spikes) = sensor.spikes {
        for (k, axis) in rec.axes.iter_mut().enumerate() {
            spikes.add(axis, s.seed ^ (0x5b1c_e000 + k as u64));
        }
    }
    rec
}

fn run_on(s: &Setting, hidden: &Hidden, sensor: &Sensor) -> Outcome {
    let mut axes = vec![hidden.axis];
    if hidden.motion.is_some() {
        axes.extend([Axis::AccelX, Axis::AccelY, Axis::AccelZ].into_iter().filter(|a| *a != hidden.axis));
    }
    let motion: Vec<(Axis, &dyn Effect)> = hidden.motion.iter().map(|(a, e)| (*a, e.as_ref())).collect();
    let filters: Vec<(Axis, Bandwidth)> =
        sensor.cutoff_per_rate.map_or(Vec::new(), |r| axes.iter().map(|&a| (a, low_pass(s, a, r))).collect());
    let mut extra = vec![(hidden.axis, hidden.effect.as_ref())];
    extra.extend(hidden.beside.iter().map(|e| (hidden.axis, e.as_ref())));
    extra.extend(filters.iter().map(|(a, f)| (*a, f as &dyn Effect)));
    let rec = record_by(s, &spec_yaml(s, &axes, &extra, &motion), sensor);
    let start = hidden.beside.iter().fold("N,B,K".to_string(), |m, e| format!("{m},{}", e.kind().id()));
    let start = ModelSpec::parse_in(&start, REGISTRY).unwrap();
    let d = diagnose(&rec.input(hidden.axis), &start, REGISTRY, &FitOptions::default()).unwrap();
    let kind = hidden.effect.kind();
    let filter_first = filters.first().zip(d.suggestions.first()).is_some_and(|((_, f), x)| x.effect == f.kind().id());
    // The suggestion that names the hidden effect: the first, or the second beside the filter.
    let at = usize::from(filter_first);
    let named = d.suggestions.get(at).filter(|x| !filter_first || x.given.len() == 1);
    let detected = named.is_some_and(|x| x.effect == kind.id());
    let error = |truth: &fdavar::model::effects::Param, got: f64| match truth.spec.unit {
        "axis" => {
            if got == truth.value {
                0.0
            } else {
                f64::INFINITY
            }
        }
        "s" if kind.evidence() == Evidence::Events => (got - truth.value).abs() / (0.01 * s.seconds()),
        "s" => (got / truth.value - 1.0).abs() / 0.25,
        // Signed: a step, a coefficient or a slope of the wrong sign is off by more than 100 %.
        _ => (got / truth.value - 1.0).abs() / 0.10,
    };
    let worst_of = |truth: &[fdavar::model::effects::Param], got: &[f64]| -> f64 {
        truth.iter().zip(got).map(|(t, &g)| if g.is_finite() { error(t, g) } else { f64::INFINITY }).fold(0.0, f64::max)
    };
    let mut worst: f64 = 0.0;
    if let Some(sugg) = named.filter(|_| detected) {
        let got: Vec<f64> = sugg.params.iter().map(|p| p.value).collect();
        worst = match &hidden.beside {
            None => worst_of(&hidden.effect.params(), &got),
            // Two lines are interchangeable: the model with the suggestion (the diagnosis's own
            // refit) must hold both, each within tolerance, whichever of its two line terms took
            // which.
            Some(beside) => {
                let other: Vec<f64> =
                    d.after[at].term(beside.kind().id()).map_or(vec![f64::NAN; 2], |t| t.params.iter().map(|p| p.value).collect());
                let (mine, theirs) = (hidden.effect.params(), beside.params());
                let as_named = worst_of(&mine, &got).max(worst_of(&theirs, &other));
                let swapped = worst_of(&theirs, &got).max(worst_of(&mine, &other));
                as_named.min(swapped)
            }
        };
    }
    Outcome {
        detected,
        params_ok: detected && worst <= 1.0,
        instead: named.filter(|_| !detected).map(|x| x.effect.clone()),
        suggested: d.suggestions.iter().map(|x| x.given.iter().fold(x.effect.clone(), |n, g| format!("{n} with {g}"))).collect(),
        worst,
    }
}

/// Diagnoses every axis of a clean six-axis recording; returns per axis the effects suggested.
pub fn clean(s: &Setting) -> Vec<Vec<String>> {
    clean_losing(s, None)
}

/// [`clean`] on a recording that lost messages.
pub fn clean_losing(s: &Setting, loss: Option<LostMessages>) -> Vec<Vec<String>> {
    clean_on(s, &Sensor { loss, ..Sensor::default() })
}

/// [`clean`] of a sensor with a low-pass of cut-off `cutoff_per_rate`·rate on every axis (see
/// [`run_low_pass`]): each axis's suggestions, `bandwidth` first when it is named.
pub fn clean_low_pass(s: &Setting, cutoff_per_rate: f64) -> Vec<Vec<String>> {
    clean_on(s, &Sensor { cutoff_per_rate: Some(cutoff_per_rate), ..Sensor::default() })
}

/// [`clean`] of a sensor whose samples carry isolated spikes (see [`run_spiky`]).
pub fn clean_spiky(s: &Setting, spikes: Spikes) -> Vec<Vec<String>> {
    clean_on(s, &Sensor { spikes: Some(spikes), ..Sensor::default() })
}

fn clean_on(s: &Setting, sensor: &Sensor) -> Vec<Vec<String>> {
    let filters: Vec<(Axis, Bandwidth)> =
        sensor.cutoff_per_rate.map_or(Vec::new(), |r| Axis::ALL.iter().map(|&a| (a, low_pass(s, a, r))).collect());
    let extra: Vec<(Axis, &dyn Effect)> = filters.iter().map(|(a, f)| (*a, f as &dyn Effect)).collect();
    let rec = record_by(s, &spec_yaml(s, &Axis::ALL, &extra, &[]), sensor);
    let nbk = ModelSpec::parse_in("N,B,K", REGISTRY).unwrap();
    Axis::ALL
        .iter()
        .map(|&a| {
            let d = diagnose(&rec.input(a), &nbk, REGISTRY, &FitOptions::default()).unwrap();
            d.suggestions.into_iter().map(|x| x.effect).collect()
        })
        .collect()
}

/// `f` over `items` on `threads` threads, results in order.
pub fn par_map<T: Sync, R: Send>(items: &[T], threads: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = threads.max(1);
    let mut out: Vec<Option<R>> = (0..items.len()).map(|_| None).collect();
    std::thread::scope(|scope| {
        let chunks: Vec<_> = out
            .chunks_mut(items.len().div_ceil(threads).max(1))
            .zip(items.chunks(items.len().div_ceil(threads).max(1)))
            .map(|(o, i)| {
                let f = &f;
                scope.spawn(move || {
                    for (slot, item) in o.iter_mut().zip(i) {
                        *slot = Some(f(item));
                    }
                })
            })
            .collect();
        for c in chunks {
            c.join().unwrap();
        }
    });
    out.into_iter().map(|r| r.unwrap()).collect()
}

/// Detection rate and parameter accuracy of `family` at `strength` over `settings`.
pub fn power_point(family: &Family, strength: f64, settings: &[Setting], threads: usize) -> Vec<Outcome> {
    par_map(settings, threads, |s| {
        let mut rng = ChaCha8Rng::seed_from_u64(s.seed ^ 0x9e37_79b9);
        let hidden = (family.make)(s, strength, &mut rng);
        run(s, &hidden)
    })
}
