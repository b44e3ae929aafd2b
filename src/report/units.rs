//! Display units: SI noise coefficients to the seed's Table 2 units and to Kalibr's terms.
//!
//! The library computes in SI (lib.rs conventions); only reports convert. Gyro coefficients go to
//! the units of the seed's Table 2 and of IEEE Std 952 datasheets — Q µrad, N °/√h, B °/h,
//! K °/h^1.5, R °/h². Accelerometer coefficients follow the same pattern with the angle replaced by
//! velocity: Q mm/s, N m/s/√h, B m/s/h, K m/s/h^1.5, R m/s/h² (deliberately one rule, not the
//! zoo of mg, µg/√Hz and m/s/√h found in datasheets). Every conversion is one factor, so
//! [`Coefficient::from_display`] is exactly the inverse of [`Coefficient::to_display`].
//!
//! Kalibr (and most VIO configs: OpenVINS, VINS-Mono, ORB-SLAM3) wants the continuous-time noise
//! density and random walk, which *are* the SI N and K: rad/s/√Hz = rad/√s and rad/s²/√Hz =
//! rad/s/√s. [`KalibrImu`] makes that explicit and gives the per-sample discrete values;
//! [`crate::report::export`] writes them in each estimator's config keys.
//!
//! # References
//! - IEEE Std 952-1997, Annex C (gyro noise terms and their units).
//! - Yang et al. 2016 (the seed), Table 2.
//! - Furgale P., Rehder J., Siegwart R., "Unified temporal and spatial calibration for multi-sensor
//!   systems", IROS 2013 (Kalibr); Kalibr wiki "IMU Noise Model".
use std::f64::consts::PI;

use crate::model::effects::{self, id};
use serde::{Deserialize, Serialize};

/// Degrees per radian, 180/π.
const DEG_PER_RAD: f64 = 180.0 / PI;
/// Seconds per hour.
const S_PER_H: f64 = 3600.0;

/// Which sensor a coefficient belongs to; decides angle (°, µrad) or velocity (m/s, mm/s) units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Sensor {
    /// Gyroscope: rate in rad/s, phase in rad.
    Gyro,
    /// Accelerometer: rate in m/s², phase in m/s.
    Accel,
}

impl Sensor {
    /// The sensor of a contract axis name (`gyro_x` … `accel_z`); `None` for anything else.
    pub fn of_axis(axis: &str) -> Option<Sensor> {
        match axis {
            "gyro_x" | "gyro_y" | "gyro_z" => Some(Sensor::Gyro),
            "accel_x" | "accel_y" | "accel_z" => Some(Sensor::Accel),
            _ => None,
        }
    }
}

/// The five IEEE 952 coefficients that have display units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Coefficient {
    /// Quantization noise Q (effect `quantization`, parameter `q`).
    Quantization,
    /// Angle (velocity) random walk N (effect `white`, parameter `n`).
    White,
    /// Bias instability B (effect `bias_instability`, parameter `b`).
    BiasInstability,
    /// Rate random walk K (effect `random_walk`, parameter `k`).
    RandomWalk,
    /// Rate ramp R (effect `ramp`, parameter `r`).
    Ramp,
}

impl Coefficient {
    /// All five, in the order of the effect registry and the seed's Table 2.
    pub const ALL: [Coefficient; 5] = [
        Coefficient::Quantization,
        Coefficient::White,
        Coefficient::BiasInstability,
        Coefficient::RandomWalk,
        Coefficient::Ramp,
    ];

    /// The coefficient of an effect id or alias of docs/design.md §4 (`white` or `N`, …).
    pub fn from_effect(name: &str) -> Option<Coefficient> {
        let kind = effects::find(name)?;
        Coefficient::ALL.into_iter().find(|c| c.effect() == kind.id())
    }

    /// The id of the effect whose first parameter this coefficient is (`white` for N, …).
    pub fn effect(self) -> &'static str {
        match self {
            Coefficient::Quantization => id::QUANTIZATION,
            Coefficient::White => id::WHITE,
            Coefficient::BiasInstability => id::BIAS_INSTABILITY,
            Coefficient::RandomWalk => id::RANDOM_WALK,
            Coefficient::Ramp => id::RAMP,
        }
    }

    /// The one-letter alias (Q, N, B, K, R).
    pub fn alias(self) -> &'static str {
        match self {
            Coefficient::Quantization => "Q",
            Coefficient::White => "N",
            Coefficient::BiasInstability => "B",
            Coefficient::RandomWalk => "K",
            Coefficient::Ramp => "R",
        }
    }

    /// Power of seconds in the SI unit (rad·s^p for gyro), which sets the hour factor 3600^p.
    ///
    /// Q: rad (p = 0); N: rad/√s (p = −½); B: rad/s (−1); K: rad/s^1.5 (−3/2); R: rad/s² (−2).
    fn time_power(self) -> f64 {
        match self {
            Coefficient::Quantization => 0.0,
            Coefficient::White => -0.5,
            Coefficient::BiasInstability => -1.0,
            Coefficient::RandomWalk => -1.5,
            Coefficient::Ramp => -2.0,
        }
    }

    /// The SI unit fdavar computes in.
    pub fn si_unit(self, sensor: Sensor) -> &'static str {
        match (sensor, self) {
            (Sensor::Gyro, Coefficient::Quantization) => "rad",
            (Sensor::Gyro, Coefficient::White) => "rad/s/√Hz",
            (Sensor::Gyro, Coefficient::BiasInstability) => "rad/s",
            (Sensor::Gyro, Coefficient::RandomWalk) => "rad/s/√s",
            (Sensor::Gyro, Coefficient::Ramp) => "rad/s²",
            (Sensor::Accel, Coefficient::Quantization) => "m/s",
            (Sensor::Accel, Coefficient::White) => "m/s²/√Hz",
            (Sensor::Accel, Coefficient::BiasInstability) => "m/s²",
            (Sensor::Accel, Coefficient::RandomWalk) => "m/s²/√s",
            (Sensor::Accel, Coefficient::Ramp) => "m/s³",
        }
    }

    /// The display unit of reports.
    pub fn display_unit(self, sensor: Sensor) -> &'static str {
        match (sensor, self) {
            (Sensor::Gyro, Coefficient::Quantization) => "µrad",
            (Sensor::Gyro, Coefficient::White) => "°/√h",
            (Sensor::Gyro, Coefficient::BiasInstability) => "°/h",
            (Sensor::Gyro, Coefficient::RandomWalk) => "°/h^1.5",
            (Sensor::Gyro, Coefficient::Ramp) => "°/h²",
            (Sensor::Accel, Coefficient::Quantization) => "mm/s",
            (Sensor::Accel, Coefficient::White) => "m/s/√h",
            (Sensor::Accel, Coefficient::BiasInstability) => "m/s/h",
            (Sensor::Accel, Coefficient::RandomWalk) => "m/s/h^1.5",
            (Sensor::Accel, Coefficient::Ramp) => "m/s/h²",
        }
    }

    /// The factor from the SI value to the display value.
    ///
    /// # Formula
    /// ```text
    /// display = si · a · 3600^(−p)
    /// ```
    /// where a = 10⁶ for Q (rad → µrad; m/s → mm/s uses 10³) and a = 180/π for the gyro's other
    /// terms (rad → °), a = 1 for the accelerometer's other terms; p is the power of seconds in
    /// the SI unit (N: −½, B: −1, K: −3/2, R: −2), so 3600^(−p) turns "per s^|p|" into "per h^|p|".
    /// Gyro: Q ×10⁶; N ×(180/π)·60 = 3437.75; B ×(180/π)·3600 = 206 264.8;
    /// K ×(180/π)·3600^1.5 = 1.237 59·10⁷; R ×(180/π)·3600² = 7.425 53·10⁸.
    pub fn display_factor(self, sensor: Sensor) -> f64 {
        let angle = match (sensor, self) {
            (Sensor::Gyro, Coefficient::Quantization) => 1e6,
            (Sensor::Accel, Coefficient::Quantization) => 1e3,
            (Sensor::Gyro, _) => DEG_PER_RAD,
            (Sensor::Accel, _) => 1.0,
        };
        angle * S_PER_H.powf(-self.time_power())
    }

    /// Converts an SI value to the display unit ([`Coefficient::display_factor`]).
    ///
    /// ```
    /// use fdavar::report::units::{Coefficient, Sensor};
    /// // N = 1e-4 rad/s/√Hz is 0.3438 °/√h.
    /// let n = Coefficient::White.to_display(Sensor::Gyro, 1e-4);
    /// assert!((n - 0.343775).abs() < 1e-6);
    /// ```
    pub fn to_display(self, sensor: Sensor, si: f64) -> f64 {
        si * self.display_factor(sensor)
    }

    /// Converts a display-unit value back to SI; the exact inverse of [`Coefficient::to_display`].
    pub fn from_display(self, sensor: Sensor, display: f64) -> f64 {
        display / self.display_factor(sensor)
    }
}

/// One sensor's noise in Kalibr's terms (`*_noise_density`, `*_random_walk`).
///
/// Kalibr's continuous-time model is the same as fdavar's SI one, so the values are the white
/// coefficient N and the rate random walk K unchanged; only the unit names differ
/// (rad/s/√Hz = rad/√s, rad/s²/√Hz = rad/s/√s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KalibrImu {
    /// Noise density \[rad/s/√Hz\] or \[m/s²/√Hz\] = N.
    pub noise_density: f64,
    /// Random walk \[rad/s²/√Hz\] or \[m/s³/√Hz\] = K.
    pub random_walk: f64,
}

impl KalibrImu {
    /// Kalibr's terms from the SI white coefficient `n` and random walk `k`.
    pub fn from_si(n: f64, k: f64) -> KalibrImu {
        KalibrImu {
            noise_density: n,
            random_walk: k,
        }
    }

    /// Standard deviation of one white-noise sample at `rate_hz`.
    ///
    /// # Formula
    /// ```text
    /// σ_d = noise_density · √rate_hz
    /// ```
    pub fn discrete_noise(&self, rate_hz: f64) -> f64 {
        self.noise_density * rate_hz.sqrt()
    }

    /// Standard deviation of the bias increment between two samples at `rate_hz`.
    ///
    /// # Formula
    /// ```text
    /// σ_bd = random_walk / √rate_hz
    /// ```
    pub fn discrete_random_walk(&self, rate_hz: f64) -> f64 {
        self.random_walk / rate_hz.sqrt()
    }
}
