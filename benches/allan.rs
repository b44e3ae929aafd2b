//! Allan estimator throughput: whole-record estimators, the full chain with EDF, and streaming.
//!
//! Run: `cargo bench --no-default-features --bench allan`. Setup (the random record) is untimed.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use fdavar::allan::streaming::OavarAccumulator;
use fdavar::allan::{edf, estimate, naive, Estimator, TauGrid};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

fn white_rate(n: usize) -> Vec<f64> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
}

fn batch(c: &mut Criterion) {
    let n = 1_000_000;
    let phase = naive::phase_from_rate(&white_rate(n), 0.01);
    let mut g = c.benchmark_group("allan_batch_1e6");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    for est in Estimator::ALL {
        let factors = TauGrid::Decade.factors(est.max_factor(phase.len()));
        g.bench_with_input(
            BenchmarkId::new("variance_decade", est.name()),
            &factors,
            |b, f| {
                b.iter(|| {
                    f.iter()
                        .filter_map(|&m| est.variance(&phase, 0.01, m))
                        .count()
                })
            },
        );
        g.bench_with_input(
            BenchmarkId::new("estimate_with_edf_decade", est.name()),
            &factors,
            |b, f| {
                b.iter(|| {
                    estimate(est, &phase, 0.01, f, edf::ONE_SIGMA)
                        .unwrap()
                        .len()
                })
            },
        );
    }
    g.finish();
}

fn streaming(c: &mut Criterion) {
    let n = 100_000;
    let rate = white_rate(n);
    let factors = TauGrid::PerDecade(10).factors(5000);
    let mut g = c.benchmark_group("allan_streaming");
    g.throughput(Throughput::Elements(n as u64));
    g.sample_size(10);
    g.bench_function(format!("push_1e5_K{}", factors.len()), |b| {
        b.iter(|| {
            let mut acc = OavarAccumulator::new(0.01, &factors).unwrap();
            rate.iter().for_each(|&y| acc.push(y));
            acc.samples()
        })
    });
    g.finish();
}

criterion_group!(benches, batch, streaming);
criterion_main!(benches);
