//! Per-sample cost of the streaming F-DAVAR engine.
//!
//! - `per_sample/W171` vs `per_sample/W5001`: the same τ grid (factors up to 57 = 171/3), a fixed
//!   window of 171 or 5001 samples: the cost must not depend on W (target: within 1.5×).
//! - `forty_taus/W5001`: about 40 log-spaced τ values up to 5001/3, adaptive `sign` policy over
//!   [1001, 5001]: axis-samples per second (criterion's throughput line).
//!
//! Run: `cargo bench --no-default-features --bench davar`. Setup (data, warm-up) is untimed.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use fdavar::allan::TauGrid;
use fdavar::davar::{DavarEngine, EngineConfig, FTarget, FixedWindow, SigmaRef, SignPolicy, WindowPolicy};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

const BLOCK: usize = 20_000;

fn data(len: usize) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    (0..len).map(|_| 0.01 + 0.002 * rng.sample::<f64, _>(StandardNormal)).collect()
}

fn warmed(factors: Vec<usize>, policy: Box<dyn WindowPolicy>, warm: &[f64]) -> DavarEngine {
    let config = EngineConfig {
        factors,
        tau0: 0.005,
        sigma_ref: SigmaRef::Running,
        f_target: FTarget::Auto { band_z: 2.0, warmup_rows: 500 },
    };
    let mut engine = DavarEngine::new(config, policy).expect("valid bench config");
    let mut rows = Vec::new();
    for &y in warm {
        engine.push(Some(y), &mut rows);
        rows.clear();
    }
    engine
}

fn forty_factors(max: usize) -> Vec<usize> {
    (1..100)
        .map(|n| TauGrid::PerDecade(n).factors(max))
        .find(|f| f.len() >= 40)
        .expect("some density reaches 40 factors")
}

fn bench(c: &mut Criterion) {
    let warm = data(30_000);
    let block = data(BLOCK);
    let mut group = c.benchmark_group("per_sample");
    group.throughput(Throughput::Elements(BLOCK as u64));
    for w in [171usize, 5001] {
        let factors = TauGrid::PerDecade(10).factors(171 / 3);
        let mut engine = warmed(factors, Box::new(FixedWindow::new(w)), &warm);
        let mut rows = Vec::new();
        group.bench_function(BenchmarkId::from_parameter(format!("W{w}")), |b| {
            b.iter(|| {
                for &y in &block {
                    engine.push(Some(y), &mut rows);
                    rows.clear();
                }
            })
        });
    }
    group.finish();

    let factors = forty_factors(5001 / 3);
    let k = factors.len();
    let mut group = c.benchmark_group("forty_taus");
    group.throughput(Throughput::Elements(BLOCK as u64));
    let mut engine = warmed(factors, Box::new(SignPolicy::new(1001, 5001, 4)), &warm);
    let mut rows = Vec::new();
    group.bench_function(BenchmarkId::from_parameter(format!("W5001_K{k}")), |b| {
        b.iter(|| {
            for &y in &block {
                engine.push(Some(y), &mut rows);
                rows.clear();
            }
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
