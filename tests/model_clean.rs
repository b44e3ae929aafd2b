//! Issue 4, done-when 2 and 3: a clean recording gets no suggestion and fit_error ≤ 2 on every
//! axis; on clean 1 h recordings N, B and K come back within 5 %, 20 % and 35 % (mean over seeds),
//! and the stated 1σ uncertainties cover the truth about as often as they claim.

mod model_common;

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
            assert!(d.fit.fit_error <= 2.0, "seed {seed} {axis}: fit_error {}", d.fit.fit_error);
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
