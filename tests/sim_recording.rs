//! The simulator: determinism, spec validation that names the field, and the recordings' truth.
//!
//! The Allan signatures of single effects are checked in `effects_conformance.rs`; here a whole
//! recording with the base terms N, B, K on one axis is checked against the sum of their
//! signatures, and the seed paper's signal against its definition.

use fdavar::allan::naive::{oavar, phase_from_rate};
use fdavar::model::effects::find;
use fdavar::signal::Axis;
use fdavar::sim::{simulate, SimError, SimSpec};
use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor};

const SPEC: &str = r#"
rate_hz: 100
duration_s: 60
seed: 7
gravity: true
temperature: { start_c: 20, end_c: 35, time_constant_s: 30, rate_hz: 2 }
vibration:
  accel_y: { sinusoid: { amplitude: 0.5, frequency_hz: 3.0 } }
axes:
  gyro_x: { N: { n: 1.0e-3 }, B: { b: 1.0e-4 }, K: { k: 1.0e-4 } }
  gyro_y: { white: { n: 1.0e-3 }, temperature: { coefficient_per_k: 1.0e-3 } }
  gyro_z: { white: { n: 1.0e-3 }, g_sensitivity: { source: accel_y, coefficient: 2.0e-3 } }
  accel_z: { white: { n: 2.0e-3 }, quantization: { q: 1.0e-5 } }
"#;

fn spec() -> SimSpec {
    SimSpec::from_yaml(SPEC).unwrap()
}

fn field_of(err: SimError) -> String {
    match err {
        SimError::Field { field, .. } | SimError::Param { field, .. } => field,
        other => panic!("expected a field error, got {other}"),
    }
}

#[test]
fn same_seed_same_recording_other_seed_other_noise() {
    let a = simulate(&spec()).unwrap();
    assert_eq!(a, simulate(&spec()).unwrap());
    let mut other = spec();
    other.seed = 8;
    let b = simulate(&other).unwrap();
    assert_ne!(a.axis(Axis::GyroX), b.axis(Axis::GyroX));
}

#[test]
fn adding_an_effect_on_one_axis_leaves_the_others_unchanged() {
    let a = simulate(&spec()).unwrap();
    let text = SPEC.replace(
        "  accel_z:",
        "  accel_x: { white: { n: 1.0e-3 } }\n  accel_z:",
    );
    let b = simulate(&SimSpec::from_yaml(&text).unwrap()).unwrap();
    for axis in [
        Axis::GyroX,
        Axis::GyroY,
        Axis::GyroZ,
        Axis::AccelY,
        Axis::AccelZ,
    ] {
        assert_eq!(a.axis(axis), b.axis(axis), "{axis}");
    }
    assert_ne!(a.axis(Axis::AccelX), b.axis(Axis::AccelX));
}

#[test]
fn stamps_rate_gravity_temperature_and_truth() {
    let rec = simulate(&spec()).unwrap();
    assert_eq!(rec.imu.len(), 6000);
    assert!(rec
        .imu
        .windows(2)
        .all(|w| w[1].stamp_ns - w[0].stamp_ns == 10_000_000));
    assert_eq!(rec.imu[0].stamp_ns, 1_700_000_000_000_000_000);
    // accel_z: gravity + white noise + quantization on whole LSBs.
    let z = rec.axis(Axis::AccelZ);
    let mean = z.iter().sum::<f64>() / z.len() as f64;
    assert!((mean - 9.80665).abs() < 1e-3, "{mean}");
    let lsb = 1.0e-5 * 12f64.sqrt() / 0.01;
    assert!(z
        .iter()
        .all(|v| ((v / lsb) - (v / lsb).round()).abs() < 1e-6));
    // Temperature topic at 2 Hz following the warm-up.
    assert_eq!(rec.temperature.len(), 120);
    assert_eq!(rec.temperature[0].celsius, 20.0);
    let last = rec.temperature.last().unwrap().celsius;
    assert!((last - (35.0 - 15.0 * (-59.5f64 / 30.0).exp())).abs() < 1e-9);
    // Truth: contract ids, SI values, quantization applied last.
    let t = &rec.truth;
    assert_eq!(
        (t.rate_hz, t.samples, t.seed, t.gravity_m_s2),
        (100.0, 6000, 7, 9.80665)
    );
    let names =
        |axis: &str| -> Vec<String> { t.axes[axis].iter().map(|e| e.effect.clone()).collect() };
    assert_eq!(
        names("gyro_x"),
        ["white", "bias_instability", "random_walk"]
    );
    assert_eq!(names("accel_z"), ["white", "quantization"]);
    assert_eq!(t.axes["gyro_z"][1].params["source"], 1.0);
    assert_eq!(t.axes["gyro_x"][2].params["k"], 1.0e-4);
    let json = serde_json::to_string(t).unwrap();
    assert_eq!(
        serde_json::from_str::<fdavar::sim::Truth>(&json).unwrap(),
        *t
    );
}

#[test]
fn driven_effects_follow_their_drivers() {
    let rec = simulate(&spec()).unwrap();
    // gyro_y = white + 1e-3·(T − T0): regress on the profile (the same one the topic carries).
    let profile = rec.truth.temperature.clone().unwrap();
    let temps: Vec<f64> = (0..rec.imu.len())
        .map(|i| profile.at(i as f64 * 0.01))
        .collect();
    let y = rec.axis(Axis::GyroY);
    let slope = |x: &[f64], y: &[f64]| {
        let n = x.len() as f64;
        let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
        let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
        let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
        (sxy / sxx, (1e-3f64.powi(2) / 0.01 / sxx).sqrt())
    };
    let (beta, se) = slope(&temps, &y);
    assert!((beta - 1e-3).abs() < 4.0 * se, "temperature {beta} ± {se}");
    // gyro_z = white + 2e-3·accel_y (true motion, the 3 Hz sinusoid).
    let ay: Vec<f64> = rec.axis(Axis::AccelY);
    let (beta, se) = slope(&ay, &rec.axis(Axis::GyroZ));
    assert!(
        (beta - 2e-3).abs() < 4.0 * se,
        "g-sensitivity {beta} ± {se}"
    );
}

#[test]
fn base_terms_together_show_the_sum_of_their_signatures() {
    // gyro_x carries N, B and K; its Allan variance must follow N²/τ + (2 ln2/π)B² + K²τ/3 inside
    // the 99 % χ² band (white-FM EDF where N dominates, flicker/RW-FM EDF beyond) at ≥ 90 % of the
    // octave points from m = 8 (where sampled flicker reaches its floor).
    let text = SPEC.replace("duration_s: 60", "duration_s: 1200");
    let rec = simulate(&SimSpec::from_yaml(&text).unwrap()).unwrap();
    let y = rec.axis(Axis::GyroX);
    let x = phase_from_rate(&y, 0.01);
    let model: Vec<_> = [("N", 1.0e-3), ("B", 1.0e-4), ("K", 1.0e-4)]
        .iter()
        .map(|(name, v)| find(name).unwrap().build(&[*v]).unwrap())
        .collect();
    let predicted = |tau: f64| model.iter().map(|e| e.avar(tau).unwrap()).sum::<f64>();
    let (mut inside, mut total) = (0, 0);
    let mut m = 8;
    while 3 * m <= y.len() {
        let tau = m as f64 * 0.01;
        let measured = oavar(&x, 0.01, m).unwrap();
        let (n, mf) = (x.len() as f64, m as f64);
        let white = model[0].avar(tau).unwrap();
        let flicker = model[1].avar(tau).unwrap();
        let edf = if white > flicker {
            (3.0 * (n - 1.0) / (2.0 * mf) - 2.0 * (n - 2.0) / n) * 4.0 * mf * mf
                / (4.0 * mf * mf + 5.0)
        } else {
            5.0 * n * n / (4.0 * mf * (n + 3.0 * mf))
        };
        let chi = ChiSquared::new(edf).unwrap();
        let band = (
            measured * edf / chi.inverse_cdf(0.995),
            measured * edf / chi.inverse_cdf(0.005),
        );
        total += 1;
        if (band.0..=band.1).contains(&predicted(tau)) {
            inside += 1;
        } else {
            eprintln!(
                "tau {tau}: measured {measured:.4e}, predicted {:.4e}",
                predicted(tau)
            );
        }
        m *= 2;
    }
    assert!(
        inside as f64 >= 0.9 * total as f64,
        "{inside}/{total} inside"
    );
}

#[test]
fn seed_paper_signal_triples_its_noise_from_1200_to_2400() {
    let text = r#"
rate_hz: 33.333333333333336
duration_s: 108
seed: 2016
axes:
  gyro_x: { white: { n: 1.0e-3 }, noise_burst: { start_s: 36, end_s: 72, factor: 3 } }
"#;
    let rec = simulate(&SimSpec::from_yaml(text).unwrap()).unwrap();
    assert_eq!(rec.imu.len(), 3600);
    assert!(rec
        .imu
        .windows(2)
        .all(|w| w[1].stamp_ns - w[0].stamp_ns == 30_000_000));
    let y = rec.axis(Axis::GyroX);
    let var = |s: &[f64]| s.iter().map(|v| v * v).sum::<f64>() / s.len() as f64;
    let inside = var(&y[1200..2400]);
    let outside = (var(&y[..1200]) + var(&y[2400..])) / 2.0;
    let f = FisherSnedecor::new(1200.0, 2400.0).unwrap();
    let ratio = inside / outside / 9.0;
    assert!(
        (f.inverse_cdf(0.0005)..=f.inverse_cdf(0.9995)).contains(&ratio),
        "{ratio}"
    );
    // The burst starts exactly at sample 1200: the extra noise is absent before it.
    let quiet = simulate(
        &SimSpec::from_yaml(
            &text.replace(", noise_burst: { start_s: 36, end_s: 72, factor: 3 }", ""),
        )
        .unwrap(),
    )
    .unwrap()
    .axis(Axis::GyroX);
    assert_eq!(y[..1200], quiet[..1200]);
    assert_ne!(y[1200], quiet[1200]);
    assert_eq!(y[2400..], quiet[2400..]);
}

#[test]
fn invalid_specs_name_the_field() {
    let x = "gyro_x: { N: { n: 1.0e-3 }";
    let cases = [
        (x, "gyro_w: { N: { n: 1.0e-3 }", "axes.gyro_w"),
        (x, "gyro_x: { wobble: { n: 1.0 }", "axes.gyro_x.wobble"),
        (x, "gyro_x: { N: { m: 1.0 }", "axes.gyro_x.N.m"),
        (
            x,
            "gyro_x: { sinusoid: { amplitude: 1.0 }",
            "axes.gyro_x.sinusoid.frequency_hz",
        ),
        (x, "gyro_x: { N: { n: .nan }", "axes.gyro_x.N"),
        (
            x,
            "gyro_x: { noise_burst: { start_s: 1, end_s: 2, factor: 2 }",
            "axes.gyro_x.noise_burst",
        ),
        (
            "accel_z: { white: { n: 2.0e-3 }",
            "accel_z: { g_sensitivity: { source: accel_x, coefficient: 1 }",
            "axes.accel_z.g_sensitivity",
        ),
        (
            "source: accel_y",
            "source: gyro_x",
            "axes.gyro_z.g_sensitivity.source",
        ),
        ("rate_hz: 100", "rate_hz: -100", "rate_hz"),
        ("duration_s: 60", "duration_s: 0.001", "duration_s"),
        ("duration_s: 60", "duration_s: 1.0e9", "duration_s"),
        ("seed: 7", "seed: 7\nlost_messages: { probability: 0.7 }", "lost_messages.probability"),
        ("seed: 7", "seed: 7\nlost_messages: { every_s: 1, length_s: 0.6 }", "lost_messages.length_s"),
        ("seed: 7", "seed: 7\nlost_messages: { length_s: 0.1 }", "lost_messages.length_s"),
        ("seed: 7", "seed: 7\nlost_messages: { every_s: -1 }", "lost_messages.every_s"),
        ("seed: 7", "seed: 7\nreceipt_stamps: { packet: 0 }", "receipt_stamps.packet"),
        ("seed: 7", "seed: 7\nreceipt_stamps: { packet: 8, spacing_s: 1.0e-3 }", "receipt_stamps.spacing_s"),
        ("seed: 7", "seed: 7\nreceipt_stamps: { packet: 4, jitter_s: 6.0e-3 }", "receipt_stamps.jitter_s"),
        (
            x,
            "gyro_x: { N: { n: 1.0e-3 }, bias_step: { time_s: 60, size: 1 }",
            "axes.gyro_x.bias_step.time_s",
        ),
    ];
    for (from, to, field) in cases {
        let text = SPEC.replacen(from, to, 1);
        assert_ne!(text, SPEC, "case {to} did not apply");
        let err = simulate(&SimSpec::from_yaml(&text).unwrap()).unwrap_err();
        let msg = err.to_string();
        assert_eq!(field_of(err), field, "{msg}");
    }
    // A temperature effect without a profile.
    let text = SPEC.replace(
        "temperature: { start_c: 20, end_c: 35, time_constant_s: 30, rate_hz: 2 }\n",
        "",
    );
    assert_eq!(
        field_of(simulate(&SimSpec::from_yaml(&text).unwrap()).unwrap_err()),
        "axes.gyro_y.temperature"
    );
    // An unknown top-level field is a parse error naming it.
    let err = SimSpec::from_yaml(&format!("{SPEC}\nsed: 3\n")).unwrap_err();
    assert!(
        matches!(&err, SimError::Yaml(m) if m.contains("sed")),
        "{err}"
    );
}

/// Lost messages leave the bag, not the sensor: the messages that arrive carry the values and
/// stamps of the same spec without losses, the lost ones are those the spec asks for, and the
/// truth counts them.
#[test]
fn lost_messages_leave_holes_and_change_no_value() {
    let whole = simulate(&spec()).unwrap();
    let mut lossy = spec();
    lossy.lost_messages = Some(fdavar::sim::LostMessages { probability: 0.02, every_s: Some(10.0), length_s: 0.3 });
    let holed = simulate(&lossy).unwrap();
    let kept: std::collections::HashSet<i64> = holed.imu.iter().map(|m| m.stamp_ns).collect();
    let lost: Vec<usize> = (0..whole.imu.len()).filter(|&i| !kept.contains(&whole.imu[i].stamp_ns)).collect();
    // Runs of 30 messages from 5 s, 15 s, …, 55 s (6 runs: 180), and about 2 % of the rest.
    for start in (500..6000).step_by(1000) {
        assert!((start..start + 30).all(|i| lost.contains(&i)), "run at {start}");
    }
    let single = lost.len() - 180;
    assert!((70..=170).contains(&single), "{single} single losses of 5820 at 2 %");
    assert_eq!(holed.truth.messages_lost, lost.len());
    assert_eq!(holed.imu.len() + lost.len(), whole.imu.len());
    let by_stamp: std::collections::HashMap<i64, _> = whole.imu.iter().map(|m| (m.stamp_ns, m)).collect();
    assert!(holed.imu.iter().all(|m| by_stamp[&m.stamp_ns] == m));
    assert_eq!(holed.temperature, whole.temperature);
}
