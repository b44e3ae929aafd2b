//! Display-unit conversions against hand-computed values, their round trip, Kalibr terms, and the
//! table renderers.
//!
//! Hand computations (180/π = 57.295 779 513…, 3600 s/h):
//! - N = 1e-4 rad/s/√Hz → 1e-4 · 57.2958 · √3600 = 1e-4 · 57.2958 · 60 = 0.343 775 °/√h.
//! - B = 1e-5 rad/s → 1e-5 · 57.2958 · 3600 = 2.062 65 °/h.
//! - K = 1e-6 rad/s/√s → 1e-6 · 57.2958 · 3600^1.5 = 1e-6 · 57.2958 · 216 000 = 12.3759 °/h^1.5.
//! - R = 1e-8 rad/s² → 1e-8 · 57.2958 · 12 960 000 = 7.425 53 °/h².
//! - Q = 2e-6 rad → 2 µrad.
//! - accel N = 2e-3 m/s²/√Hz → 2e-3 · 60 = 0.12 m/s/√h.
//! - imu_noise_params.md: "ARW [deg/sqrt(h)] = N [deg/s/sqrt(Hz)] · 60"; the ADIS16448 gyro
//!   N = 1.6968e-4 rad/s/√Hz → 1.6968e-4 · 57.2958 · 60 = 0.583 317 °/√h.
use fdavar::report::table::{sig, Table};
use fdavar::report::export::{ExportFormat, ImuNoise};
use fdavar::report::units::{Coefficient, KalibrImu, Sensor};
use proptest::prelude::*;

/// Relative tolerance: the hand values above are rounded to 6 significant digits.
const HAND_ROUNDING: f64 = 5e-6;

fn close(got: f64, want: f64) -> bool {
    ((got - want) / want).abs() < HAND_ROUNDING
}

#[test]
fn gyro_to_seed_units_by_hand() {
    let g = Sensor::Gyro;
    let cases = [
        (Coefficient::White, 1e-4, 0.343775),
        (Coefficient::BiasInstability, 1e-5, 2.06265),
        (Coefficient::RandomWalk, 1e-6, 12.3759),
        (Coefficient::Ramp, 1e-8, 7.42553),
        (Coefficient::Quantization, 2e-6, 2.0),
        (Coefficient::White, 1.6968e-4, 0.583317),
    ];
    for (c, si, want) in cases {
        let got = c.to_display(g, si);
        assert!(
            close(got, want),
            "{c:?}: {si} {} → {got}, want {want} {}",
            c.si_unit(g),
            c.display_unit(g)
        );
    }
}

#[test]
fn accel_units_by_hand() {
    let a = Sensor::Accel;
    assert!(close(Coefficient::White.to_display(a, 2e-3), 0.12));
    assert!(close(
        Coefficient::BiasInstability.to_display(a, 1e-4),
        0.36
    ));
    assert!(close(Coefficient::Quantization.to_display(a, 3e-4), 0.3));
    assert!(close(Coefficient::RandomWalk.to_display(a, 1e-5), 2.16));
    assert!(close(Coefficient::Ramp.to_display(a, 1e-7), 1.296));
    assert_eq!(Coefficient::White.display_unit(a), "m/s/√h");
}

#[test]
fn units_and_aliases() {
    assert_eq!(Coefficient::from_effect("N"), Some(Coefficient::White));
    assert_eq!(
        Coefficient::from_effect("bias_instability"),
        Some(Coefficient::BiasInstability)
    );
    assert_eq!(Coefficient::from_effect("sinusoid"), None);
    assert_eq!(Sensor::of_axis("accel_y"), Some(Sensor::Accel));
    assert_eq!(Sensor::of_axis("mag_x"), None);
    let units: Vec<&str> = Coefficient::ALL
        .iter()
        .map(|c| c.display_unit(Sensor::Gyro))
        .collect();
    assert_eq!(units, ["µrad", "°/√h", "°/h", "°/h^1.5", "°/h²"]);
    let aliases: Vec<&str> = Coefficient::ALL.iter().map(|c| c.alias()).collect();
    assert_eq!(aliases, ["Q", "N", "B", "K", "R"]);
}

proptest! {
    #![proptest_config(ProptestConfig {
        rng_seed: proptest::test_runner::RngSeed::Fixed(952),
        ..ProptestConfig::default()
    })]

    /// SI → display → SI returns the value to within a few ulps, for every coefficient and sensor.
    #[test]
    fn round_trip(exp in -12.0f64..3.0, mantissa in 1.0f64..10.0, c in 0usize..5, accel in any::<bool>()) {
        let si = mantissa * 10f64.powf(exp);
        let coef = Coefficient::ALL[c];
        let sensor = if accel { Sensor::Accel } else { Sensor::Gyro };
        let back = coef.from_display(sensor, coef.to_display(sensor, si));
        prop_assert!(((back - si) / si).abs() < 4.0 * f64::EPSILON, "{si} → {back}");
    }
}

#[test]
fn kalibr_terms_are_si_n_and_k() {
    // EuRoC's ADIS16448 gyro config (imu_noise_params.md), at 200 Hz.
    let gyro = KalibrImu::from_si(1.6968e-4, 1.9393e-5);
    assert_eq!(gyro.noise_density, 1.6968e-4);
    // σ_d = 1.6968e-4 · √200 = 2.39964e-3; σ_bd = 1.9393e-5 / √200 = 1.37129e-6.
    assert!(close(gyro.discrete_noise(200.0), 2.39964e-3));
    assert!(close(gyro.discrete_random_walk(200.0), 1.37129e-6));
    // The imu.yaml of these numbers (report::export writes it; tests/export_cli.rs checks the
    // files against their readers' keys and PyYAML).
    let noise = ImuNoise {
        gyro,
        accel: KalibrImu::from_si(2.0e-3, 3.0e-3),
        topic: "/imu0".into(),
        rate_hz: Some(200.0),
        inflation: 1.0,
    };
    let yaml = noise.to_yaml(ExportFormat::Kalibr).unwrap();
    let parsed: serde_yaml_ng::Value = serde_yaml_ng::from_str(&yaml).unwrap();
    assert_eq!(parsed["gyroscope_noise_density"].as_f64(), Some(1.6968e-4), "{yaml}");
    assert_eq!(parsed["gyroscope_random_walk"].as_f64(), Some(1.9393e-5), "{yaml}");
    assert_eq!(parsed["accelerometer_random_walk"].as_f64(), Some(3.0e-3), "{yaml}");
    assert_eq!(parsed["rostopic"].as_str(), Some("/imu0"), "{yaml}");
    assert_eq!(parsed["update_rate"].as_f64(), Some(200.0), "{yaml}");
}

#[test]
fn coefficient_table_in_display_units() {
    // What `fdavar fit` prints: one row per coefficient, both unit systems from one Table.
    let mut t = Table::new(["term", "SI", "unit", "display", "unit"]);
    for (c, si) in [
        (Coefficient::White, 1e-4),
        (Coefficient::BiasInstability, 1e-5),
    ] {
        let g = Sensor::Gyro;
        t.push([
            c.alias().to_string(),
            sig(si, 4),
            c.si_unit(g).to_string(),
            sig(c.to_display(g, si), 4),
            c.display_unit(g).to_string(),
        ]);
    }
    let text = t.to_text();
    assert!(
        text.contains("N     1.000e-4  rad/s/√Hz   0.3438  °/√h"),
        "{text}"
    );
    let csv = t.to_csv();
    assert_eq!(csv.lines().nth(2), Some("B,1.000e-5,rad/s,2.063,°/h"));
}
