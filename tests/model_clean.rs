//! Issue 4, done-when 2 and 3: a clean recording gets no suggestion and fit_error ≤ 2 (and
//! span_fit_error ≤ 2) on every axis; on clean 1 h recordings N, B and K come back within 5 %, 20 % and 35 % (mean over seeds),
//! and the stated 1σ uncertainties cover the truth about as often as they claim.

mod model_common;

use fdavar::model::output::AxisReport;
use fdavar::model::{diagnose, fit, FitOptions, ModelSpec};
use fdavar::signal::Axis;
use model_common::{recording, GYRO_NBK, KINDS};

#[test]
fn clean_recordings_get_no_suggestion() {
    let nbk = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
    for (seed, rate, minutes) in [(101, 100.0, 20.0), (102, 200.0, 20.0), (103, 400.0, 20.0)] {
        let rec = recording(seed, rate, minutes, &[], &[]);
        for axis in Axis::ALL {
            let d = diagnose(&rec.input(axis), &nbk, KINDS, &FitOptions::default()).unwrap();
            let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
            assert!(names.is_empty(), "seed {seed} {axis}: {names:?}");
            assert!(d.fit.misfit() <= 2.0, "seed {seed} {axis}: fit_error {}, span_fit_error {:?}", d.fit.fit_error, d.fit.span_fit_error);
            // Gaussian noise: the EDFs are NIST's, and the JSON has no kurtosis key.
            assert_eq!(d.fit.rate_excess_kurtosis, 0.0, "seed {seed} {axis}");
            let json = serde_json::to_value(AxisReport::from_fit(&d.fit)).unwrap();
            assert!(json.get("rate_excess_kurtosis").is_none(), "seed {seed} {axis}: {json}");
        }
    }
}

/// A clean hour that loses 50 ms of every 10 s on all axes (0.5 % of the messages) gets no
/// suggestion. Before the fit bridged such holes (`allan::oavar_rate_bridged`), measured at
/// e7cbf5a: seed 111 accel_x `temperature` (t² 450) and `bias_step` (t² 1052), seed 112 accel_x
/// the same (67, 164) and accel_y `bias_step` (222): no Allan term longer than the holes' spacing
/// survived, B and K were fitted as 0, and the random walk passed for a step and a drift.
/// tests/lost_messages.rs covers more loss patterns, mixes and rates.
#[test]
fn lost_messages_make_no_suggestion() {
    let nbk = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
    for seed in [111, 112] {
        let mut rec = recording(seed, 100.0, 60.0, &[], &[]);
        let n = rec.axes[0].len();
        for at in (500..n - 5).step_by(1000) {
            for axis in rec.axes.iter_mut() {
                axis[at..at + 5].iter_mut().for_each(|v| *v = f64::NAN);
            }
        }
        for axis in Axis::ALL {
            let d = diagnose(&rec.input(axis), &nbk, KINDS, &FitOptions::default()).unwrap();
            let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
            assert!(names.is_empty(), "seed {seed} {axis}: {names:?}");
        }
    }
}

/// Fits N,B,K to the three gyro axes of four clean 1 h, 100 Hz recordings: per coefficient the
/// mean estimate and how many 1σ intervals cover the truth.
fn hour_fits() -> ([f64; 3], [usize; 3], usize) {
    let nbk = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
    let ids = ["white", "bias_instability", "random_walk"];
    let mut mean = [0.0; 3];
    let mut covered = [0usize; 3];
    let mut count = 0usize;
    for seed in 0..4u64 {
        let rec = recording(200 + seed, 100.0, 60.0, &[], &[]);
        for axis in [Axis::GyroX, Axis::GyroY, Axis::GyroZ] {
            let f = fit(&rec.input(axis), &nbk, KINDS, &FitOptions::default()).unwrap();
            count += 1;
            for (k, id) in ids.iter().enumerate() {
                let p = &f.term(id).unwrap().params[0];
                mean[k] += p.value / 12.0;
                if p.sigma.is_some_and(|s| (p.value - GYRO_NBK[k]).abs() <= s) {
                    covered[k] += 1;
                }
            }
        }
    }
    for k in 0..3 {
        println!(
            "{}: mean {:.3e} truth {:.3e} ({:.1} %), 1σ covers {}/{count}",
            ids[k],
            mean[k],
            GYRO_NBK[k],
            (mean[k] - GYRO_NBK[k]).abs() / GYRO_NBK[k] * 100.0,
            covered[k]
        );
    }
    (mean, covered, count)
}

#[test]
fn nbk_come_back_on_clean_hour_records() {
    let (mean, _, _) = hour_fits();
    for (k, tol) in [0.05, 0.20, 0.35].into_iter().enumerate() {
        let rel = (mean[k] - GYRO_NBK[k]).abs() / GYRO_NBK[k];
        assert!(rel <= tol, "coefficient {k}: mean {:.3e} vs truth {:.3e}", mean[k], GYRO_NBK[k]);
    }
}

#[test]
fn uncertainties_cover_the_truth() {
    let (_, covered, count) = hour_fits();
    // 1σ claims 68 %: with 12 fits, fewer than 4 or all 12 covered each has p < 1 % (too small or
    // too wide an interval). Measured 2026-11-21 with the GLS covariance: N 10, B 10, K 7 of 12.
    for (k, c) in covered.into_iter().enumerate() {
        assert!((4..=11).contains(&c), "coefficient {k}: 1σ covers {c}/{count}");
    }
}

/// A clean hour whose samples carry isolated spikes (one in 2000, ±30 times the white noise's σ,
/// as a bus glitch or a knock would make: excess kurtosis about 190, as measured on a real
/// XSens MTi-G gyro, 120) gets no suggestion and fits, on every axis: spikes are only more white
/// noise in the Allan variance, and the fit widens each point's EDF for their fourth cumulant
/// (`allan::edf::edf_with_fourth_cumulant`). Measured with the widening switched off (2026-11-29):
/// fit_error 2.12–4.21 on these twelve axes, every one failing in time (the spans that hold a few
/// more or fewer spikes), whole-record 0.34–0.85; with it 0.81–1.15. With spikes one in 1000 at
/// ±15σ, gyro_z of seed 121 got a false `noise_burst` before `timedomain::tail_factor` read the
/// record's kurtosis.
#[test]
fn isolated_spikes_widen_the_intervals_and_make_no_suggestion() {
    use rand::{Rng, SeedableRng};
    let (share, size) = (5e-4, 30.0);
    let nbk = ModelSpec::parse_in("N,B,K", KINDS).unwrap();
    for seed in [121u64, 122] {
        let mut rec = recording(seed, 100.0, 60.0, &[], &[]);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut injected = Vec::new();
        for axis in rec.axes.iter_mut() {
            let n = axis.len() as f64;
            // The white noise's σ per sample, from the differences (√2 σ).
            let sigma = (axis.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>() / (2.0 * n)).sqrt();
            let mut spikes = 0usize;
            for v in axis.iter_mut() {
                if rng.random::<f64>() < share {
                    *v += size * sigma * if rng.random::<bool>() { 1.0 } else { -1.0 };
                    spikes += 1;
                }
            }
            // Excess kurtosis of unit noise plus ±s at a share p: s⁴·p(1 − 3p)/(1 + p·s²)².
            let p = spikes as f64 / n;
            injected.push(size.powi(4) * p * (1.0 - 3.0 * p) / (1.0 + p * size * size).powi(2));
        }
        for (axis, truth) in Axis::ALL.into_iter().zip(injected) {
            let d = diagnose(&rec.input(axis), &nbk, KINDS, &FitOptions::default()).unwrap();
            let names: Vec<&str> = d.suggestions.iter().map(|s| s.effect.as_str()).collect();
            assert!(names.is_empty(), "seed {seed} {axis}: {names:?}");
            assert!(d.fit.misfit() <= 2.0, "seed {seed} {axis}: fit_error {}, span_fit_error {:?}", d.fit.fit_error, d.fit.span_fit_error);
            let kurtosis = d.fit.rate_excess_kurtosis;
            assert!((kurtosis / truth - 1.0).abs() < 0.2, "seed {seed} {axis}: excess kurtosis {kurtosis} vs {truth}");
            let json = serde_json::to_value(AxisReport::from_fit(&d.fit)).unwrap();
            assert_eq!(json["rate_excess_kurtosis"].as_f64(), Some(kurtosis), "seed {seed} {axis}");
        }
    }
}
