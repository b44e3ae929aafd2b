//! False alarms of the change detector on stationary noise, and the span convention of an event.
//!
//! Issue 10: a clean recording gave a dozen "noise changed" events, each with its end before its
//! start. Requirement (Build 5): on stationary white, flicker, random-walk and quantized noise at
//! realistic levels, at most 1 false event per 10 axis-hours at the defaults (adaptive `sign`
//! window, F̃ auto, running σ²_ref) and with the fixed 171 window; no event with end < start.
//!
//! Each case simulates the six axes of one IMU with one noise type (levels from
//! /work/shared/reference/imu_noise_params.md) and runs the public pipeline; six axes × 1 h 40 min
//! at 100 Hz is 10 axis-hours, so "≤ 1 per 10 axis-hours" is checked as "≤ 1 event in the case".

use fdavar::pipeline::{AxisEvent, DavarConfig, Output, Pipeline, PolicyConfig};
use fdavar::signal::{Axis, ImuSample};
use fdavar::sim::{simulate, SimSpec};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Seconds simulated per case: 6 axes × 6000 s = 10 axis-hours.
const DURATION_S: f64 = 6000.0;

/// Stationary noise types: name → per-axis effects (gyro, accel), `{dt}` replaced by τ0 in the
/// quantizer's q = LSB·τ0/√12 so that the LSB is the same at every rate.
fn effects(kind: &str, rate_hz: f64) -> [String; 2] {
    let dt = 1.0 / rate_hz;
    // ADIS16405: LSB 0.05 °/s and 3.33 mg.
    let q_gyro = 0.05f64.to_radians() * dt / 12f64.sqrt();
    let q_accel = 3.33e-3 * 9.80665 * dt / 12f64.sqrt();
    match kind {
        // D435i / BMI055.
        "white" => ["N: { n: 1.52e-4 }".into(), "N: { n: 6.31e-3 }".into()],
        // Bias instability of a few °/h (gyro) and 40 µg (accel) over D435i white noise.
        "flicker" => [
            "N: { n: 1.52e-4 }, B: { b: 5.0e-5 }".into(),
            "N: { n: 6.31e-3 }, B: { b: 4.0e-4 }".into(),
        ],
        // EuRoC ADIS16448 (Kalibr figures, inflated vs the datasheet).
        "random_walk" => [
            "N: { n: 1.6968e-4 }, K: { k: 1.9393e-5 }".into(),
            "N: { n: 2.0e-3 }, K: { k: 3.0e-3 }".into(),
        ],
        // ADIS16405: the LSB is visible (0.1 σ on the gyro, 0.7 σ on the accel at 100 Hz).
        "quantized" => [
            format!("N: {{ n: 8.7e-4 }}, Q: {{ q: {q_gyro:e} }}"),
            format!("N: {{ n: 4.9e-3 }}, Q: {{ q: {q_accel:e} }}"),
        ],
        _ => unreachable!("unknown noise type {kind}"),
    }
}

fn recording(kind: &str, rate_hz: f64, duration_s: f64, seed: u64) -> Vec<ImuSample> {
    let [gyro, accel] = effects(kind, rate_hz);
    let mut y = format!("rate_hz: {rate_hz}\nduration_s: {duration_s}\nseed: {seed}\naxes:\n");
    for axis in ["gyro_x", "gyro_y", "gyro_z"] {
        y += &format!("  {axis}: {{ {gyro} }}\n");
    }
    for axis in ["accel_x", "accel_y", "accel_z"] {
        y += &format!("  {axis}: {{ {accel} }}\n");
    }
    simulate(&SimSpec::from_yaml(&y).unwrap()).unwrap().imu
}

fn events(config: &DavarConfig, samples: &[ImuSample]) -> Vec<AxisEvent> {
    events_on(&Axis::ALL, config, samples)
}

fn events_on(axes: &[Axis], config: &DavarConfig, samples: &[ImuSample]) -> Vec<AxisEvent> {
    let mut p = Pipeline::new(config.clone(), axes, None).unwrap();
    let mut out = Output::default();
    for s in samples {
        p.push(s, &mut out);
        out.rows.clear();
    }
    p.finish(&mut out);
    out.events
}

fn assert_spans(events: &[AxisEvent]) {
    for e in events {
        let e = &e.event;
        assert!(
            e.start_index <= e.end_index && e.start_s <= e.end_s,
            "end before start: {e:?}"
        );
    }
}

/// The two configurations every case runs: the defaults and the fixed 171 window.
fn defaults_and_fixed_171() -> [(&'static str, DavarConfig); 2] {
    [
        ("defaults", DavarConfig::default()),
        ("fixed 171", DavarConfig { policy: PolicyConfig::Fixed { length: 171 }, ..DavarConfig::default() }),
    ]
}

/// One noise type at 100 Hz: 10 axis-hours with the defaults and 10 with the fixed 171 window.
fn stationary_case(kind: &str, seed: u64) {
    let samples = recording(kind, 100.0, DURATION_S, seed);
    let axis_hours = 6.0 * DURATION_S / 3600.0;
    let bound = (axis_hours / 10.0).floor() as usize;
    for (name, config) in defaults_and_fixed_171() {
        let found = events(&config, &samples);
        eprintln!("{kind} {name}: {} events in {axis_hours} axis-hours", found.len());
        assert_spans(&found);
        assert!(
            found.len() <= bound,
            "{kind}, {name}: {} false events in {axis_hours} axis-hours (bound {bound}): {found:?}",
            found.len()
        );
    }
}

#[test]
fn white_noise_gives_at_most_one_false_event_per_10_axis_hours() {
    stationary_case("white", 101);
}

#[test]
fn flicker_noise_gives_at_most_one_false_event_per_10_axis_hours() {
    stationary_case("flicker", 102);
}

#[test]
fn random_walk_gives_at_most_one_false_event_per_10_axis_hours() {
    stationary_case("random_walk", 103);
}

#[test]
fn quantized_noise_gives_at_most_one_false_event_per_10_axis_hours() {
    stationary_case("quantized", 104);
}

/// At 400 Hz the windows are 4× shorter in time, so an hour holds 4× more independent windows:
/// 6 axes × 25 min of each noise type, 2.5 axis-hours each, 10 in all; bound 1 over the four.
#[test]
fn at_400_hz_all_four_types_give_at_most_one_false_event_per_10_axis_hours() {
    let mut total = 0;
    for (seed, kind) in ["white", "flicker", "random_walk", "quantized"].iter().enumerate() {
        let samples = recording(kind, 400.0, 1500.0, 200 + seed as u64);
        let found = events(&DavarConfig::default(), &samples);
        eprintln!("400 Hz {kind}: {} events in 2.5 axis-hours", found.len());
        assert_spans(&found);
        total += found.len();
    }
    assert!(total <= 1, "{total} false events in 10 axis-hours at 400 Hz");
}

/// Bursts shorter and longer than the windows: every event has end ≥ start, and a burst of 3σ
/// lasting three longest windows is found on every axis it is on.
#[test]
fn every_event_ends_after_it_starts_and_long_bursts_are_found() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let n = 200_000i64;
    // Bursts of 20 … 3000 samples every 10 000 samples, σ × 3.
    let bursts: Vec<(i64, i64)> = (1..n / 10_000)
        .map(|k| (k * 10_000, k * 10_000 + rng.random_range(20..3000)))
        .collect();
    let samples: Vec<ImuSample> = (0..n)
        .map(|k| {
            let sd = if bursts.iter().any(|&(a, b)| (a..b).contains(&k)) { 3.0 } else { 1.0 };
            let y = sd * rng.sample::<f64, _>(StandardNormal);
            ImuSample {
                stamp_ns: k * 10_000_000,
                gyro: [y, 0.0, 0.0],
                accel: [0.0; 3],
            }
        })
        .collect();
    for (_, config) in defaults_and_fixed_171() {
        let found = events_on(&[Axis::GyroX], &config, &samples);
        assert_spans(&found);
        let max = config.policy.max_window() as i64;
        for &(a, b) in bursts.iter().filter(|(a, b)| b - a >= 3 * max) {
            assert!(
                found.iter().any(|e| {
                    let (s, t) = (e.event.start_index as i64, e.event.end_index as i64);
                    s < b && t >= a
                }),
                "{:?}: burst {a}..{b} not found in {:?}",
                config.policy,
                found
            );
        }
        for e in &found {
            let (s, t) = (e.event.start_index as i64, e.event.end_index as i64);
            assert!(
                bursts.iter().any(|&(a, b)| s < b + max && t + max >= a),
                "{:?}: event away from every burst: {e:?}",
                config.policy
            );
        }
    }
}

/// A loud start is not taken for the sensor's normal noise (issue 10, found on the ADIS16405
/// recording: a knock in its first 8 s sat in the detector's warm-up, and accel_z's undisturbed
/// noise after it was reported "quieter ×0.6" from 11.8 to 142.6 s, in three events).
///
/// Here white noise whose first 8 s are 2.5× louder, then 20 min of the same white noise, at the
/// defaults and with the fixed 171 window: rows quieter than the steady level are learned even
/// when flagged, so the level comes down within about a warm-up's worth of rows. What is asserted:
/// the quieter events after the loud start last at most 10 s in all (measured: 4.8 s with the
/// defaults, 6.3 s with the fixed window; before the change one quieter event ran from 10 s to the
/// end, 1185 s), and no event lies after the first minute.
#[test]
fn a_loud_start_is_not_taken_for_the_normal_noise() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (rate_hz, loud_s, total_s) = (100.0, 8.0, 1200.0);
    let samples: Vec<ImuSample> = (0..(total_s * rate_hz) as i64)
        .map(|k| {
            let sd = if (k as f64) < loud_s * rate_hz { 2.5 } else { 1.0 };
            ImuSample {
                stamp_ns: k * 10_000_000,
                gyro: [sd * rng.sample::<f64, _>(StandardNormal), 0.0, 0.0],
                accel: [0.0; 3],
            }
        })
        .collect();
    for (_, config) in defaults_and_fixed_171() {
        let found = events_on(&[Axis::GyroX], &config, &samples);
        assert_spans(&found);
        let quieter_s: f64 = found
            .iter()
            .filter(|e| e.event.factor < 1.0)
            .map(|e| e.event.end_s - e.event.start_s)
            .sum();
        eprintln!("{:?}: {} events, quieter for {quieter_s:.1} s: {:?}", config.policy, found.len(), found);
        assert!(quieter_s <= 10.0, "{:?}: quieter for {quieter_s} s: {:?}", config.policy, found);
        assert!(
            found.iter().all(|e| e.event.end_s <= 60.0),
            "{:?}: an event after the first minute: {:?}",
            config.policy,
            found
        );
    }
}
