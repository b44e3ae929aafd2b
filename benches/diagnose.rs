//! `fdavar diagnose`'s library path on 1 h and 4 h, 100 Hz, six-axis recordings (issue 4: < 3 s
//! release for 1 h; issue 11: cost linear in length).
//!
//! Run: `cargo bench --no-default-features --bench diagnose`. Each recording is made once, untimed,
//! by the real simulator (`fdavar::sim`, seeded): N, B, K on every axis and a 0.1 Hz sinusoid
//! hidden on gyro_x, so that one axis takes the full candidate search. Reading the bag is not timed
//! (the bag branch benches it). Compare the 4 h time with 4 × the 1 h time: before the burst
//! search became O(n log n) (issue 11) it was quadratic in length.

use criterion::{criterion_group, criterion_main, Criterion};
use fdavar::model::effects::REGISTRY;
use fdavar::model::record::Recording;
use fdavar::model::{diagnose, FitOptions, ModelSpec};
use fdavar::signal::Axis;

const SPEC: &str = "
rate_hz: 100
duration_s: DURATION
seed: 1
temperature: { start_c: 20.0, end_c: 28.0, time_constant_s: 600, rate_hz: 10 }
axes:
  gyro_x: { N: { n: 1.5e-4 }, B: { b: 5.0e-5 }, K: { k: 2.7e-6 }, sinusoid: { amplitude: 4.0e-4, frequency_hz: 0.1 } }
  gyro_y: { N: { n: 1.5e-4 }, B: { b: 5.0e-5 }, K: { k: 2.7e-6 } }
  gyro_z: { N: { n: 1.5e-4 }, B: { b: 5.0e-5 }, K: { k: 2.7e-6 } }
  accel_x: { N: { n: 2.0e-3 }, B: { b: 4.0e-4 }, K: { k: 1.2e-4 } }
  accel_y: { N: { n: 2.0e-3 }, B: { b: 4.0e-4 }, K: { k: 1.2e-4 } }
  accel_z: { N: { n: 2.0e-3 }, B: { b: 4.0e-4 }, K: { k: 1.2e-4 } }
";

fn bench(c: &mut Criterion) {
    let spec = ModelSpec::parse_in("N,B,K", REGISTRY).unwrap();
    let opts = FitOptions::default();
    let mut group = c.benchmark_group("diagnose");
    group.sample_size(10);
    for hours in [1, 4] {
        let yaml = SPEC.replace("DURATION", &(hours * 3600).to_string());
        let sim = fdavar::sim::simulate(&fdavar::sim::SimSpec::from_yaml(&yaml).unwrap()).unwrap();
        let rec = Recording::from_samples(&sim.imu, &sim.temperature).unwrap();
        drop(sim);
        group.bench_function(format!("{hours}h_100Hz_6axes"), |b| {
            b.iter(|| {
                for axis in Axis::ALL {
                    let d = diagnose(&rec.input(axis), &spec, REGISTRY, &opts).unwrap();
                    std::hint::black_box(d);
                }
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
