//! Shared helpers of the model workbench's integration tests: seeded six-axis recordings whose
//! truth is known, made by the real simulator (`fdavar::sim`, the one behind `fdavar simulate`)
//! from a spec built here, then laid out for the fitter exactly as a bag is
//! (`Recording::from_samples`). The fitter only ever sees the samples; the truth stays in the test.
#![allow(dead_code)]

use fdavar::model::effects::REGISTRY;
pub use fdavar::model::record::Recording;
use fdavar::signal::Axis;
use std::fmt::Write;

/// Base noise of a MEMS IMU (D435i-like gyro, with a visible bias instability), SI.
pub const GYRO_NBK: [f64; 3] = [1.5e-4, 5.0e-5, 2.7e-6];
/// Accel base noise, SI (m/s based).
pub const ACCEL_NBK: [f64; 3] = [2.0e-3, 4.0e-4, 1.2e-4];

/// One effect in a spec: its id (or alias) and its values in schema order. A `g_sensitivity`
/// source is given as 0, 1, 2 (accel_x, y, z), as the effect's own parameter is.
pub type EffectValues = (&'static str, Vec<f64>);

/// The YAML of one effect: `id: { name: value, ... }` with the kind's own parameter names.
fn effect_yaml(id: &str, values: &[f64]) -> String {
    let kind = fdavar::model::effects::find(id).unwrap_or_else(|| panic!("no effect kind {id}"));
    let fields: Vec<String> = kind
        .schema()
        .iter()
        .zip(values)
        .map(|(p, v)| {
            if kind.id() == "g_sensitivity" && p.name == "source" {
                format!("{}: {}", p.name, Axis::ALL[3 + v.round() as usize].name())
            } else {
                format!("{}: {v:e}", p.name)
            }
        })
        .collect();
    format!("{}: {{ {} }}", kind.id(), fields.join(", "))
}

/// The spec: N, B, K on all six axes, a warm-up temperature profile (20 °C rising by 8 K with a
/// 10-minute time constant, plus a 0.5 K wobble of period 2π·300 s), `extra` sensor effects on
/// their axes and `motion` as the true specific force of accel axes (`vibration`).
pub fn spec_yaml(
    seed: u64,
    rate_hz: f64,
    minutes: f64,
    extra: &[(Axis, EffectValues)],
    motion: &[(Axis, EffectValues)],
) -> String {
    let mut y = String::new();
    writeln!(y, "rate_hz: {rate_hz}\nduration_s: {}\nseed: {seed}", minutes * 60.0).unwrap();
    writeln!(
        y,
        "temperature: {{ start_c: 20.0, end_c: 28.0, time_constant_s: 600, cycle_amplitude_c: 0.5, cycle_period_s: {}, rate_hz: 10 }}",
        2.0 * std::f64::consts::PI * 300.0
    )
    .unwrap();
    if !motion.is_empty() {
        y.push_str("vibration:\n");
        for (axis, (id, v)) in motion {
            writeln!(y, "  {}: {{ {} }}", axis.name(), effect_yaml(id, v)).unwrap();
        }
    }
    y.push_str("axes:\n");
    for axis in Axis::ALL {
        let nbk = if axis.is_gyro() { GYRO_NBK } else { ACCEL_NBK };
        writeln!(y, "  {}:", axis.name()).unwrap();
        for (id, v) in [("N", nbk[0]), ("B", nbk[1]), ("K", nbk[2])] {
            writeln!(y, "    {}", effect_yaml(id, &[v])).unwrap();
        }
        for (a, (id, v)) in extra {
            if *a == axis {
                writeln!(y, "    {}", effect_yaml(id, v)).unwrap();
            }
        }
    }
    y
}

/// Simulates six axes at `rate_hz` for `minutes` with the real simulator; `extra` adds sensor
/// effects to axes, `motion` true motion to accel axes (a g-sensitivity driver).
pub fn recording(
    seed: u64,
    rate_hz: f64,
    minutes: f64,
    extra: &[(Axis, EffectValues)],
    motion: &[(Axis, EffectValues)],
) -> Recording {
    simulated(&spec_yaml(seed, rate_hz, minutes, extra, motion))
}

/// [`recording`] of a sensor whose white noise passes its own first-order low-pass of cut-off
/// `cutoff_hz` on every axis (`bandwidth` in place of `white`), as real MEMS parts do.
pub fn low_pass_recording(
    seed: u64,
    rate_hz: f64,
    minutes: f64,
    cutoff_hz: f64,
    extra: &[(Axis, EffectValues)],
    motion: &[(Axis, EffectValues)],
) -> Recording {
    let yaml = spec_yaml(seed, rate_hz, minutes, extra, motion);
    let low_pass = yaml
        .lines()
        .map(|line| match line.trim_start().strip_prefix("white: { n: ") {
            Some(rest) => format!("    bandwidth: {{ n: {}, cutoff_hz: {cutoff_hz} }}", rest.trim_end_matches(" }")),
            None => line.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    simulated(&low_pass)
}

/// The temperature profile of [`power_on_recording`]: 20 → 45 °C with a 5-minute time constant
/// from the first sample, no wobble, published at 10 Hz.
pub const POWER_ON_WARM_UP: &str =
    "{ start_c: 20.0, end_c: 45.0, time_constant_s: 300, cycle_amplitude_c: 0.0, cycle_period_s: 100, rate_hz: 10 }";

/// [`recording`] of a sensor switched on with the recording: its temperature rises at once
/// ([`POWER_ON_WARM_UP`]), where the suite's other profile warms up over the whole record with a
/// wobble in its middle.
pub fn power_on_recording(seed: u64, rate_hz: f64, minutes: f64, extra: &[(Axis, EffectValues)]) -> Recording {
    let yaml = spec_yaml(seed, rate_hz, minutes, extra, &[])
        .lines()
        .map(|line| match line.starts_with("temperature: ") {
            true => format!("temperature: {POWER_ON_WARM_UP}"),
            false => line.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    simulated(&yaml)
}

/// The recording the real simulator makes of `yaml`, laid out as a bag is.
fn simulated(yaml: &str) -> Recording {
    let spec = fdavar::sim::SimSpec::from_yaml(yaml).unwrap_or_else(|e| panic!("{e}\n{yaml}"));
    let sim = fdavar::sim::simulate(&spec).unwrap_or_else(|e| panic!("{e}\n{yaml}"));
    let rec = Recording::from_samples(&sim.imu, &sim.temperature).unwrap();
    assert_eq!(rec.axes[0].len(), sim.imu.len(), "a simulated recording has no gaps");
    rec
}

/// The registry the CLI uses.
pub static KINDS: &[&dyn fdavar::model::effects::EffectKind] = REGISTRY;
