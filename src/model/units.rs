//! Display units: the seed's Table 2 (Q µrad, N °/√h, B °/h, K °/h^1.5, R °/h²) and Kalibr's terms.
//!
//! SI is the only unit inside the crate (lib.rs); these conversions exist for reports and the CLI.
//! They apply to gyro axes; an accel axis keeps SI (m/s-based) values, with Kalibr's names.

use crate::model::fit::FittedModel;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

const DEG: f64 = 180.0 / PI;

/// A value in a display unit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Display {
    /// The value in `unit`.
    pub value: f64,
    /// The unit, e.g. `deg/sqrt(h)`.
    pub unit: &'static str,
}

/// The seed's display value of a base-term coefficient given in SI, by alias (gyro axes).
///
/// # Formula
/// ```text
/// Q [µrad]     = q·1e6
/// N [°/√h]     = n·(180/π)·60          (1 h = 3600 s, √3600 = 60)
/// B [°/h]      = b·(180/π)·3600
/// K [°/h^1.5]  = k·(180/π)·3600^1.5
/// R [°/h²]     = r·(180/π)·3600²
/// ```
///
/// ```
/// let d = fdavar::model::units::seed_display("N", 1.0e-4).unwrap();
/// assert!((d.value - 0.343775).abs() < 1e-6 && d.unit == "deg/sqrt(h)");
/// ```
pub fn seed_display(alias: &str, si: f64) -> Option<Display> {
    let (factor, unit) = match alias {
        "Q" => (1e6, "urad"),
        "N" => (DEG * 60.0, "deg/sqrt(h)"),
        "B" => (DEG * 3600.0, "deg/h"),
        "K" => (DEG * 3600f64.powf(1.5), "deg/h^1.5"),
        "R" => (DEG * 3600.0 * 3600.0, "deg/h^2"),
        _ => return None,
    };
    Some(Display { value: si * factor, unit })
}

/// Kalibr's IMU noise terms (continuous time), from a fitted model's N and K.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Kalibr {
    /// White noise density, rad/s/√Hz (gyro) or m/s²/√Hz (accel) = N.
    pub noise_density: Option<f64>,
    /// Random walk, rad/s²/√Hz (gyro) or m/s³/√Hz (accel) = K.
    pub random_walk: Option<f64>,
}

/// Kalibr's terms of a fitted model (None for a term the model lacks).
pub fn kalibr(model: &FittedModel) -> Kalibr {
    let first = |id: &str| {
        model
            .term(id)
            .and_then(|t| t.params.first())
            .map(|p| p.value)
    };
    Kalibr {
        noise_density: first("white"),
        random_walk: first("random_walk"),
    }
}
