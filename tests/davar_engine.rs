//! The streaming F-DAVAR engine against brute force (`fdavar::allan::naive` on each row's cut).
//!
//! Every row the engine emits is recomputed from scratch: the cut is taken from the kept input, an
//! offset is removed (an offset changes no Allan variance, and it keeps the oracle's own rounding
//! small when the bias is large), and `naive::oavar` on its phase must agree within relative 1e-9.
//! Windows come from the real policies and from a scripted random sequence through the same trait.

use fdavar::allan::naive;
use fdavar::allan::TauGrid;
use fdavar::davar::{
    DavarEngine, DavarRow, EngineConfig, FTarget, FixedWindow, ProportionalPolicy, SigmaRef,
    SignPolicy, WindowBounds, WindowPolicy,
};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

const TAU0: f64 = 0.01;
const REL: f64 = 1e-9;

/// A policy that returns a seeded random length inside its bounds, ignoring F.
struct Scripted {
    bounds: WindowBounds,
    rng: ChaCha8Rng,
}

impl WindowPolicy for Scripted {
    fn name(&self) -> &'static str {
        "scripted"
    }
    fn bounds(&self) -> WindowBounds {
        self.bounds
    }
    fn initial(&self) -> usize {
        self.bounds.max
    }
    fn next(&mut self, _w: usize, _f: Option<f64>, _t: Option<f64>) -> usize {
        self.rng.random_range(self.bounds.min..=self.bounds.max)
    }
}

/// A policy that starts at its shortest window and grows by 10 each row.
struct Growing(WindowBounds);

impl WindowPolicy for Growing {
    fn name(&self) -> &'static str {
        "growing"
    }
    fn bounds(&self) -> WindowBounds {
        self.0
    }
    fn initial(&self) -> usize {
        self.0.min
    }
    fn next(&mut self, w: usize, _f: Option<f64>, _t: Option<f64>) -> usize {
        w + 10
    }
}

fn config(max: usize, sigma_ref: SigmaRef, f_target: FTarget) -> EngineConfig {
    EngineConfig {
        factors: TauGrid::PerDecade(10).factors(max / 3),
        tau0: TAU0,
        sigma_ref,
        f_target,
    }
}

/// Allan variance of one cut, term by term, leaving out terms that touch a non-finite sample.
fn oracle_avar(cut: &[f64], m: usize) -> Option<(f64, usize)> {
    let offset = cut.iter().copied().find(|v| v.is_finite()).unwrap_or(0.0);
    let centred: Vec<f64> = cut.iter().map(|v| v - offset).collect();
    if centred.iter().all(|v| v.is_finite()) {
        let x = naive::phase_from_rate(&centred, TAU0);
        let avar = naive::oavar(&x, TAU0, m)?;
        return Some((avar, cut.len() + 1 - 2 * m));
    }
    let (mut sum, mut count) = (0.0, 0usize);
    for j in 0..=cut.len() - 2 * m {
        let span = &centred[j..j + 2 * m];
        if span.iter().all(|v| v.is_finite()) {
            let d: f64 = span[m..].iter().sum::<f64>() - span[..m].iter().sum::<f64>();
            sum += d * d;
            count += 1;
        }
    }
    (count > 0).then(|| (sum / (2.0 * (m * m) as f64 * count as f64), count))
}

/// Checks one row against the oracle; `data[k - first]` is sample k.
fn check_row(row: &DavarRow, data: &[f64], first: u64) {
    let start = (row.index - (row.window / 2) as u64 - first) as usize;
    let cut = &data[start..start + row.window];
    for p in row.points() {
        let (want, terms) = oracle_avar(cut, p.m).expect("oracle has a value where the engine has");
        assert_eq!(p.terms, terms, "row {} m {}", row.index, p.m);
        let rel = (p.avar - want).abs() / want.abs().max(f64::MIN_POSITIVE);
        assert!(
            rel <= REL,
            "row {} W {} m {}: {} vs {} (rel {rel:e})",
            row.index,
            row.window,
            p.m,
            p.avar,
            want
        );
        assert!(p.ci_low <= p.avar && p.avar <= p.ci_high);
    }
    let valid: Vec<f64> = cut.iter().copied().filter(|v| v.is_finite()).collect();
    assert_eq!(row.valid_samples, valid.len());
    let mean = valid.iter().sum::<f64>() / valid.len() as f64;
    let var = valid.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / valid.len() as f64;
    assert!(
        (row.variance - var).abs() <= 1e-9 * var.max(1e-300),
        "variance {} vs {var}",
        row.variance
    );
    if let (Some(f), Some(r)) = (row.f, row.sigma2_ref) {
        assert!((f - row.variance / r).abs() <= 1e-12 * f.abs());
    }
}

fn run(engine: &mut DavarEngine, data: &[f64]) -> Vec<DavarRow> {
    let mut rows = Vec::new();
    for &y in data {
        engine.push(Some(y), &mut rows);
    }
    rows
}

fn signal(seed: u64, len: usize, invalid_rate: f64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..len)
        .map(|k| {
            let level = if (len / 3..2 * len / 3).contains(&k) {
                3.0
            } else {
                1.0
            };
            let noise: f64 = rng.sample(StandardNormal);
            if rng.random::<f64>() < invalid_rate {
                f64::NAN
            } else {
                0.2 + level * noise
            }
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, rng_seed: proptest::test_runner::RngSeed::Fixed(0xDA7A), ..ProptestConfig::default() })]

    #[test]
    fn random_window_sequences_match_brute_force(
        seed in any::<u64>(),
        len in 100usize..1500,
        min in 3usize..40,
        extra in 0usize..120,
        invalid in prop_oneof![Just(0.0), 0.0..0.02f64],
    ) {
        let bounds = WindowBounds { min, max: min + extra };
        let data = signal(seed, len, invalid);
        let policy = Scripted { bounds, rng: ChaCha8Rng::seed_from_u64(seed ^ 1) };
        let mut engine = DavarEngine::new(config(bounds.max, SigmaRef::Running, FTarget::Value(1.0)), Box::new(policy)).unwrap();
        let rows = run(&mut engine, &data);
        for row in &rows {
            check_row(row, &data, 0);
        }
        let excluded: usize = rows.iter().map(|r| r.excluded_terms).sum();
        prop_assert_eq!(excluded as u64, engine.excluded_terms());
        if invalid == 0.0 {
            prop_assert_eq!(excluded, 0);
        }
    }

    #[test]
    fn rows_of_the_shortest_tau_only_are_the_full_rows_cut_to_their_first_point(
        seed in any::<u64>(),
        invalid in prop_oneof![Just(0.0), 0.0..0.05f64],
    ) {
        let data = signal(seed, 2500, invalid);
        let engine = || DavarEngine::new(config(151, SigmaRef::Running, FTarget::Auto { band_z: 2.0, warmup_rows: 200 }), Box::new(SignPolicy::new(31, 151, 4))).unwrap();
        let mut full = engine();
        let mut short = engine().shortest_tau_only();
        let (full_rows, short_rows) = (run(&mut full, &data), run(&mut short, &data));
        prop_assert_eq!(full_rows.len(), short_rows.len());
        prop_assert!(full_rows.iter().any(|r| r.points().len() > 1));
        for (a, b) in full_rows.iter().zip(&short_rows) {
            // Bit for bit: the window policy and the change detector read these.
            prop_assert_eq!((a.index, a.window, a.valid_samples, a.excluded_terms), (b.index, b.window, b.valid_samples, b.excluded_terms));
            prop_assert_eq!((a.variance.to_bits(), a.f.map(f64::to_bits)), (b.variance.to_bits(), b.f.map(f64::to_bits)));
            prop_assert_eq!(a.f_target.map(f64::to_bits), b.f_target.map(f64::to_bits));
            prop_assert_eq!(b.points().len(), a.points().len().min(1));
            prop_assert_eq!(a.first_point(), b.first_point());
        }
        prop_assert_eq!(full.excluded_terms(), short.excluded_terms());
    }

    #[test]
    fn real_policies_match_brute_force(seed in any::<u64>(), which in 0usize..3, target in 0.2f64..3.0) {
        let data = signal(seed, 1800, 0.0);
        let policy: Box<dyn WindowPolicy> = match which {
            0 => Box::new(FixedWindow::new(61)),
            1 => Box::new(SignPolicy::new(31, 151, 4)),
            _ => Box::new(ProportionalPolicy::new(31, 151, 4, 24)),
        };
        let sigma = fdavar::davar::record_variance(&data).unwrap();
        let mut engine = DavarEngine::new(config(151, SigmaRef::Value(sigma), FTarget::Value(target)), policy).unwrap();
        let rows = run(&mut engine, &data);
        prop_assert!(!rows.is_empty());
        for row in &rows {
            check_row(row, &data, 0);
        }
        for pair in rows.windows(2) {
            prop_assert_eq!(pair[1].index, pair[0].index + 1);
        }
    }
}

/// After ten million samples (one million in debug builds) with a bias drifting from 5000 to
/// 10000, rows still equal a from-scratch computation on their cut.
#[test]
fn no_drift_after_ten_million_samples_with_a_drifting_bias() {
    let total: u64 = if cfg!(debug_assertions) {
        1_000_000
    } else {
        10_000_000
    };
    let keep = 6000usize;
    let mut rng = ChaCha8Rng::seed_from_u64(24);
    let mut engine = DavarEngine::new(
        config(501, SigmaRef::Running, FTarget::Value(1.0)),
        Box::new(SignPolicy::new(171, 501, 4)),
    )
    .unwrap();
    let mut tail = Vec::with_capacity(keep);
    let mut rows = Vec::new();
    let mut checked = 0;
    for k in 0..total {
        let bias = 5000.0 + 5000.0 * k as f64 / total as f64;
        let noise: f64 = rng.sample(StandardNormal);
        let y = bias + noise;
        if k >= total - keep as u64 {
            tail.push(y);
        }
        rows.clear();
        engine.push(Some(y), &mut rows);
        for row in &rows {
            let first = total - keep as u64;
            if row.index >= first + 600 && row.index % 97 == 0 {
                check_row(row, &tail, first);
                checked += 1;
            }
        }
    }
    assert!(checked > 40, "checked {checked} rows");
}

#[test]
fn invalid_samples_are_left_out_and_counted_never_panic() {
    let mut data = signal(3, 600, 0.0);
    data[100] = f64::NAN;
    data[101] = f64::INFINITY;
    data[350] = f64::NEG_INFINITY;
    let mut engine = DavarEngine::new(
        config(61, SigmaRef::Running, FTarget::Value(1.0)),
        Box::new(FixedWindow::new(61)),
    )
    .unwrap();
    let rows = run(&mut engine, &data);
    assert_eq!(rows.len(), 600 - 61 + 1);
    let hit = rows.iter().find(|r| r.index == 110).unwrap();
    assert_eq!(hit.valid_samples, 59);
    // m = 1: terms (j, j+1) touching 100 or 101 are j = 99, 100, 101: 3 of 60 left out.
    assert_eq!(hit.first_point().unwrap().terms, 57);
    assert!(hit.excluded_terms > 0);
    for row in &rows {
        check_row(row, &data, 0);
    }
}

#[test]
fn long_gap_is_skipped_like_pushing_each_marker() {
    let data = signal(5, 400, 0.0);
    let make = || {
        DavarEngine::new(
            config(61, SigmaRef::Running, FTarget::Value(1.0)),
            Box::new(SignPolicy::new(21, 61, 4)),
        )
        .unwrap()
    };
    let (mut a, mut b) = (make(), make());
    let (mut ra, mut rb) = (Vec::new(), Vec::new());
    for &y in &data[..200] {
        a.push(Some(y), &mut ra);
        b.push(Some(y), &mut rb);
    }
    a.push_missing(5000, &mut ra);
    for _ in 0..5000 {
        b.push(None, &mut rb);
    }
    for &y in &data[200..] {
        a.push(Some(y), &mut ra);
        b.push(Some(y), &mut rb);
    }
    assert_eq!(ra.len(), rb.len());
    for (x, y) in ra.iter().zip(&rb) {
        assert_eq!(
            (x.index, x.window, x.valid_samples),
            (y.index, y.window, y.valid_samples)
        );
        for (p, q) in x.points().zip(y.points()) {
            assert!((p.avar - q.avar).abs() <= 1e-9 * q.avar);
        }
    }
}

#[test]
fn a_window_never_reaches_before_the_first_sample() {
    let data = signal(9, 800, 0.0);
    let bounds = WindowBounds { min: 11, max: 301 };
    let mut engine = DavarEngine::new(
        config(301, SigmaRef::Running, FTarget::Value(1.0)),
        Box::new(Growing(bounds)),
    )
    .unwrap();
    let rows = run(&mut engine, &data);
    assert_eq!(rows[0].index, 5);
    assert!(rows.iter().all(|r| r.window <= 2 * r.index as usize + 1));
    assert_eq!(rows.last().unwrap().window, 301);
    for row in &rows {
        check_row(row, &data, 0);
    }
}
