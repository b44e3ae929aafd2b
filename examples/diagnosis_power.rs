//! Calibration and power curves of the diagnosis (issue 10): how often a clean axis gets a
//! suggestion, and how often a hidden effect of a given strength is found.
//!
//! ```text
//! cargo run --release --no-default-features --example diagnosis_power -- null RECORDINGS [SEED]
//! cargo run --release --no-default-features --example diagnosis_power -- power PER_POINT [SEED]
//! ```
//! `null` simulates clean six-axis recordings over the rates, lengths and N/B/K mixes below and
//! prints every candidate the diagnosis weighed (CSV on stdout, a summary on stderr). `power`
//! hides one effect at a ladder of strengths and prints the detection rate per point.
//! Recordings come from the real simulator (`fdavar::sim`) and are laid out as a bag is.

use fdavar::model::effects::{Effect, REGISTRY};
use fdavar::model::record::Recording;
use fdavar::model::{diagnose, FitOptions, ModelSpec};
use fdavar::signal::Axis;
use std::fmt::Write;

/// A sensor's base noise: name, gyro (N, B, K), accel (N, B, K), SI.
pub struct Mix {
    pub name: &'static str,
    pub gyro: [f64; 3],
    pub accel: [f64; 3],
}

/// N and K from /work/shared/reference/imu_noise_params.md; B from the datasheets' bias
/// instability where the table gives one (D435i 1.8–4.9 °/h, VN-100 < 10 °/h and 0.04 mg), else a
/// value in the same range (2–10 °/h, 0.01–0.05 mg).
pub const MIXES: &[Mix] = &[
    Mix { name: "test", gyro: [1.5e-4, 5.0e-5, 2.7e-6], accel: [2.0e-3, 4.0e-4, 1.2e-4] },
    Mix { name: "d435i", gyro: [1.52e-4, 1.45e-5, 2.66e-6], accel: [6.31e-3, 3.9e-4, 1.17e-4] },
    Mix { name: "euroc", gyro: [1.6968e-4, 1.0e-5, 1.9393e-5], accel: [2.0e-3, 1.0e-4, 3.0e-3] },
    Mix { name: "tumvi", gyro: [1.6e-4, 1.0e-5, 2.2e-5], accel: [2.8e-3, 1.0e-4, 8.6e-4] },
    Mix { name: "vn100", gyro: [6.11e-5, 2.0e-5, 5.0e-7], accel: [1.37e-3, 3.9e-4, 5.0e-5] },
    Mix { name: "mti100", gyro: [1.75e-4, 2.0e-5, 1.0e-6], accel: [5.9e-4, 1.0e-4, 1.0e-5] },
    Mix { name: "adis16405", gyro: [8.7e-4, 5.0e-5, 1.0e-5], accel: [4.9e-3, 5.0e-4, 1.0e-4] },
];

/// Rates (Hz) and lengths (min) of the calibration; the cost grows with rate × length, so the
/// longest records are drawn less often (see [`configs`]).
pub fn configs(recordings: usize, seed: u64) -> Vec<(f64, f64, usize, u64)> {
    let grid = [
        (100.0, 20.0),
        (200.0, 20.0),
        (400.0, 20.0),
        (100.0, 60.0),
        (200.0, 60.0),
        (100.0, 120.0),
        (400.0, 60.0),
        (200.0, 120.0),
        (400.0, 120.0),
    ];
    (0..recordings)
        .map(|i| {
            // Short records three times as often as long ones.
            let g = [0, 1, 2, 0, 1, 2, 3, 4, 5, 0, 1, 2, 6, 7, 8, 3][i % 16];
            let (rate, minutes) = grid[g];
            (rate, minutes, (i / 16 + i) % MIXES.len(), seed + i as u64)
        })
        .collect()
}

/// The YAML of one effect, `id: { name: value, … }`, from the effect itself.
pub fn effect_yaml(e: &dyn Effect) -> String {
    let fields: Vec<String> = e.params().iter().map(|p| format!("{}: {:e}", p.spec.name, p.value)).collect();
    format!("{}: {{ {} }}", e.kind().id(), fields.join(", "))
}

/// The simulator spec: the mix on `axes`, the warm-up temperature profile of the test suite,
/// `extra` effects on their axes and `motion` as true accel motion.
pub fn spec_yaml(
    rate: f64,
    minutes: f64,
    mix: &Mix,
    seed: u64,
    axes: &[Axis],
    extra: &[(Axis, &dyn Effect)],
    motion: &[(Axis, &dyn Effect)],
) -> String {
    let mut y = String::new();
    writeln!(y, "rate_hz: {rate}\nduration_s: {}\nseed: {seed}", minutes * 60.0).unwrap();
    writeln!(
        y,
        "temperature: {{ start_c: 20.0, end_c: 28.0, time_constant_s: 600, cycle_amplitude_c: 0.5, cycle_period_s: {}, rate_hz: 10 }}",
        2.0 * std::f64::consts::PI * 300.0
    )
    .unwrap();
    if !motion.is_empty() {
        y.push_str("vibration:\n");
        for (axis, e) in motion {
            writeln!(y, "  {}: {{ {} }}", axis.name(), effect_yaml(*e)).unwrap();
        }
    }
    y.push_str("axes:\n");
    for &axis in axes {
        let [n, b, k] = if axis.is_gyro() { mix.gyro } else { mix.accel };
        write!(y, "  {}: {{ N: {{ n: {n:e} }}, B: {{ b: {b:e} }}, K: {{ k: {k:e} }}", axis.name()).unwrap();
        for (a, e) in extra {
            if *a == axis {
                write!(y, ", {}", effect_yaml(*e)).unwrap();
            }
        }
        y.push_str(" }\n");
    }
    y
}

pub fn record(yaml: &str) -> Recording {
    let spec = fdavar::sim::SimSpec::from_yaml(yaml).unwrap_or_else(|e| panic!("{e}\n{yaml}"));
    let sim = fdavar::sim::simulate(&spec).unwrap_or_else(|e| panic!("{e}\n{yaml}"));
    Recording::from_samples(&sim.imu, &sim.temperature).unwrap()
}

fn null(recordings: usize, seed: u64) {
    let nbk = ModelSpec::parse_in("N,B,K", REGISTRY).unwrap();
    let opts = FitOptions::default();
    let (mut axes, mut flagged) = (0usize, 0usize);
    println!("rate,minutes,mix,seed,axis,effect,statistic,threshold,p,significant,seconds");
    for (rate, minutes, m, s) in configs(recordings, seed) {
        let mix = &MIXES[m];
        let rec = record(&spec_yaml(rate, minutes, mix, s, &Axis::ALL, &[], &[]));
        for axis in Axis::ALL {
            let t = std::time::Instant::now();
            let d = diagnose(&rec.input(axis), &nbk, REGISTRY, &opts).unwrap();
            let secs = t.elapsed().as_secs_f64();
            axes += 1;
            if !d.suggestions.is_empty() {
                flagged += 1;
                eprintln!("{rate} Hz {minutes} min {} seed {s} {axis}: {:?}", mix.name,
                    d.suggestions.iter().map(|x| x.effect.as_str()).collect::<Vec<_>>());
            }
            for w in &d.weighed {
                println!(
                    "{rate},{minutes},{},{s},{axis},{},{:.4},{:.4},{},{},{secs:.3}",
                    mix.name,
                    w.effect,
                    w.statistic,
                    w.threshold,
                    w.p_value.map_or(String::new(), |p| format!("{p:.3e}")),
                    w.significant
                );
            }
        }
    }
    eprintln!("clean axes with a suggestion: {flagged}/{axes}");
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let count = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(16);
    let seed = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(1000);
    match args.get(1).map(String::as_str) {
        Some("null") => null(count, seed),
        _ => eprintln!("usage: diagnosis_power null|power COUNT [SEED]"),
    }
}
