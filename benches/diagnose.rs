//! `fdavar diagnose`'s library path on a 1 h, 100 Hz, six-axis recording (issue 4: < 3 s release).
//!
//! Run: `cargo bench --no-default-features --bench diagnose`. The recording is simulated once,
//! untimed (seeded): N, B, K on every axis and a 0.1 Hz sinusoid hidden on gyro_x, so that one axis
//! takes the full candidate search. Reading the bag is not timed (the bag branch benches it).

use criterion::{criterion_group, criterion_main, Criterion};
use fdavar::model::effects::{Effect, SimContext};
use fdavar::model::{diagnose, testkit, testkit::KINDS, AxisInput, FitOptions, ModelSpec};
use fdavar::signal::Axis;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn recording() -> (f64, Vec<Vec<f64>>, Vec<f64>) {
    let tau0 = 0.01;
    let n = 360_000;
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let temperature: Vec<f64> = (0..n).map(|i| 20.0 + 8.0 * (1.0 - (-(i as f64) * tau0 / 600.0).exp())).collect();
    let axes = Axis::ALL
        .iter()
        .map(|&axis| {
            let (nn, b, k) = if axis.is_gyro() { (1.5e-4, 5e-5, 2.7e-6) } else { (2e-3, 4e-4, 1.2e-4) };
            let mut effects: Vec<Box<dyn Effect>> =
                vec![testkit::effect("N", &[nn]), testkit::effect("B", &[b]), testkit::effect("K", &[k])];
            if axis == Axis::GyroX {
                effects.push(testkit::effect("sinusoid", &[4e-4, 0.1]));
            }
            let ctx = SimContext { dt: tau0, white_sigma: nn / tau0.sqrt(), temperature_c: Some(&temperature), accel: None };
            testkit::simulate(&effects, &ctx, &mut rng, n)
        })
        .collect();
    (tau0, axes, temperature)
}

fn bench(c: &mut Criterion) {
    let (tau0, axes, temperature) = recording();
    let spec = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
    let opts = FitOptions::default();
    let mut group = c.benchmark_group("diagnose");
    group.sample_size(10);
    group.bench_function("1h_100Hz_6axes", |b| {
        b.iter(|| {
            for axis in Axis::ALL {
                let input = AxisInput {
                    axis,
                    tau0,
                    rate: &axes[axis.index()],
                    temperature_c: Some(&temperature),
                    accel: Some([&axes[3], &axes[4], &axes[5]]),
                    events: &[],
                };
                let d = diagnose(&input, &spec, KINDS, &opts).unwrap();
                std::hint::black_box(d);
            }
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
