//! The seed's change-point experiment as a regression test, through the public pipeline with the
//! default parameters (adaptive `sign`, F̃ auto, default detector) and the whole-record σ²_ref.
//!
//! Truth: noise deviation ×3 from sample 1200 to 2400 of 3600 (τ0 = 30 ms). Aim (docs/design.md §3):
//! median onset and end within ±30 samples; no event outside the change. The full table over 100
//! seeds and all policies is `cargo run --release --example seed_experiment`.

use fdavar::pipeline::{
    record_variances, DavarConfig, Output, Pipeline, PolicyConfig, SigmaRefMode,
};
use fdavar::signal::{Axis, ImuSample};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

fn seed_samples(seed: u64) -> Vec<ImuSample> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..3600i64)
        .map(|k| {
            let sd = if (1200..2400).contains(&k) { 3.0 } else { 1.0 };
            let y = sd * rng.sample::<f64, _>(StandardNormal);
            ImuSample {
                stamp_ns: k * 30_000_000,
                gyro: [y, 0.0, 0.0],
                accel: [0.0; 3],
            }
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn adaptive_window_finds_the_seed_change_within_30_samples() {
    let config = DavarConfig {
        sigma_ref: SigmaRefMode::Record,
        tau0: Some(0.03),
        ..DavarConfig::default()
    };
    assert!(matches!(
        config.policy,
        PolicyConfig::Sign {
            min: 171,
            max: 501,
            step: 4
        }
    ));
    let (mut onsets, mut ends) = (Vec::new(), Vec::new());
    for seed in 0..12 {
        let samples = seed_samples(seed);
        let mut p = Pipeline::new(
            config.clone(),
            &[Axis::GyroX],
            Some(record_variances(&samples)),
        )
        .unwrap();
        let mut out = Output::default();
        for s in &samples {
            p.push(s, &mut out);
        }
        p.finish(&mut out);
        assert_eq!(out.events.len(), 1, "seed {seed}: {:?}", out.events);
        let e = &out.events[0].event;
        assert!(
            e.factor > 6.0 && e.factor < 13.0,
            "seed {seed}: factor {}",
            e.factor
        );
        assert!((e.start_s - e.start_index as f64 * 0.03).abs() < 1e-9);
        onsets.push(e.start_index as f64);
        ends.push(e.end_index as f64 + 1.0);
        let windows: Vec<usize> = out.rows.iter().map(|r| r.row.window).collect();
        assert_eq!(
            windows.iter().min(),
            Some(&171),
            "seed {seed}: the window shrinks in the change"
        );
        assert_eq!(
            windows.last(),
            Some(&501),
            "seed {seed}: and grows back after it"
        );
    }
    let (onset, end) = (median(onsets), median(ends));
    assert!((onset - 1200.0).abs() <= 30.0, "median onset {onset}");
    assert!((end - 2400.0).abs() <= 30.0, "median end {end}");
}
