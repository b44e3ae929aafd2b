//! IMU noise for state estimators: each sensor's fitted white noise density N and rate random walk
//! K in the config keys of Kalibr, OpenVINS and VINS-Fusion (`fdavar export`).
//!
//! All three want the continuous-time model `ω̃(t) = ω(t) + b(t) + n(t)`, `ḃ(t) = w(t)`, with the
//! white processes n and w given by their densities. Those *are* fdavar's SI N and K
//! ([`KalibrImu`]): N in rad/s/√Hz (= rad/√s; accel m/s²/√Hz) is the noise density, K in
//! rad/s/√s (= rad/s²/√Hz; accel m/s²/√s = m/s³/√Hz) the random walk density — no factor between
//! them. The estimators discretise at their own sample rate (σ_d = N·√rate, σ_bd = K/√rate).
//!
//! Each estimator takes one value per sensor, fdavar fits one per axis: the export takes the
//! largest of the three axes of a sensor, so that no axis is trusted more than it deserves.
//!
//! | format | file | keys |
//! |---|---|---|
//! | `kalibr` | `imu.yaml` | `accelerometer_noise_density`, `accelerometer_random_walk`, `gyroscope_noise_density`, `gyroscope_random_walk`, `rostopic`, `update_rate` |
//! | `openvins` | `kalibr_imu_chain.yaml` | the same six under `imu0:` |
//! | `vins` | VINS-Fusion / VINS-Mono config | `imu_topic`, `acc_n`, `gyr_n`, `acc_w`, `gyr_w` |
//!
//! OpenVINS reads the four noise keys of `imu0` (`VioManagerOptions::print_and_load_noise`) and
//! `rostopic` from that file; the file's other keys (`T_i_b`, `model`, `Tw`, `Ta`, `R_IMUtoACC`,
//! `R_IMUtoGYRO`, `Tg`, `time_offset`) are calibration results fdavar does not estimate: keep yours.
//! VINS-Fusion reads its five keys in `readParameters` when `imu: 1`; its configs call them "noise
//! standard deviation" and take the same continuous-time values (keep your `g_norm`).
//!
//! **Inflation.** Allan-variance densities describe a sensor at rest; in a moving robot vibration,
//! scale and misalignment errors and unmodelled effects add to them. OpenVINS' calibration guide
//! ("IMU Intrinsic Calibration", docs/gs-calibration.dox) says one may need to inflate the
//! calculated values by 10–20 times to get usable sensor values. [`ImuNoise::inflated`] multiplies
//! all four densities by one factor; the default export applies none and the file says which
//! factor it holds.
//!
//! **N of a sensor with a low-pass.** N is the density of the white rate noise: `white`'s `n`, or
//! `bandwidth`'s `n` where the model holds the sensor's own low-pass instead (the ADIS16405 and
//! most MEMS parts, docs/model.md): white noise seen through the filter has that same density below
//! its cut-off, the band an estimator integrates over. A model with both gives √(n_white² + n_bandwidth²).
//!
//! **Format.** Values are rounded to 6 significant digits. The YAML is written by `serde_yaml_ng`. Two adjustments make every reader accept
//! it: floats get a `.` in the mantissa and a signed exponent (`3.0e-6`, not `3e-6`), because YAML
//! 1.1 readers — PyYAML, which Kalibr uses — read `3e-6` as a *string*; and the OpenVINS and VINS
//! files start with `%YAML 1.2` and `---`, because their reader, OpenCV's `cv::FileStorage`,
//! decides a file is YAML by that directive.
//!
//! # References
//! - Kalibr wiki, "IMU Noise Model" and "YAML formats" (the `imu.yaml` keys and units).
//! - OpenVINS: docs/gs-calibration.dox; config/*/kalibr_imu_chain.yaml;
//!   ov_msckf/src/core/VioManagerOptions.h.
//! - VINS-Fusion: config/euroc/*.yaml; vins_estimator/src/estimator/parameters.cpp.
use std::fmt;
use std::str::FromStr;

use serde::Serialize;
use serde_json::Value;

use crate::model::effects::id;
use crate::model::FittedModel;
use crate::report::units::{KalibrImu, Sensor};

/// A state estimator whose IMU noise keys fdavar writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// Kalibr `imu.yaml`.
    Kalibr,
    /// OpenVINS `kalibr_imu_chain.yaml` (`imu0:` block).
    OpenVins,
    /// VINS-Fusion / VINS-Mono config keys.
    Vins,
}

impl ExportFormat {
    /// All formats, in `--help` order.
    pub const ALL: [ExportFormat; 3] = [ExportFormat::Kalibr, ExportFormat::OpenVins, ExportFormat::Vins];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ExportFormat::Kalibr => "kalibr",
            ExportFormat::OpenVins => "openvins",
            ExportFormat::Vins => "vins",
        }
    }

    /// Whether the file holds the sample rate (`update_rate`).
    pub fn needs_rate(self) -> bool {
        !matches!(self, ExportFormat::Vins)
    }
}

impl fmt::Display for ExportFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ExportFormat {
    type Err = ExportError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ExportFormat::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| ExportError::UnknownFormat(s.to_string()))
    }
}

/// Why IMU noise could not be exported.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// A format name fdavar does not write.
    #[error("unknown export format '{0}' (known: kalibr, openvins, vins)")]
    UnknownFormat(String),
    /// An axis's model has no white rate noise (`white` or `bandwidth`) or no `random_walk` (K).
    #[error("{axis}: the model has no {effect} term; export needs white (N) or bandwidth, and random_walk (K)")]
    MissingTerm {
        /// The axis.
        axis: String,
        /// The effect id that is missing.
        effect: &'static str,
    },
    /// No axis of a sensor was fitted.
    #[error("no {0} axis in the input; export needs at least one gyro and one accel axis")]
    NoSensor(&'static str),
    /// A value is NaN, infinite or negative.
    #[error("{what} = {value} is not a finite non-negative number")]
    BadValue {
        /// Which value (axis and parameter, or the flag).
        what: String,
        /// The value found.
        value: f64,
    },
    /// The inflation factor is not a positive finite number.
    #[error("the inflation factor must be a positive number, got {0}")]
    BadInflation(f64),
    /// Kalibr and OpenVINS files hold the sample rate and none was given.
    #[error("{0} needs the sample rate (update_rate) and none is known")]
    MissingRate(ExportFormat),
    /// The JSON is not what `fdavar fit --json` / `diagnose --json` print.
    #[error("not an fdavar fit/diagnose JSON: {0}")]
    Json(String),
    /// The YAML writer failed.
    #[error("writing YAML: {0}")]
    Yaml(#[from] serde_yaml_ng::Error),
}

/// One axis's fitted white noise density N and random walk K, SI.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisNoise {
    /// Contract axis name (`gyro_x` … `accel_z`).
    pub axis: String,
    /// White noise density N, rad/s/√Hz or m/s²/√Hz.
    pub n: f64,
    /// Rate random walk K, rad/s/√s or m/s²/√s.
    pub k: f64,
}

/// The effects whose `n` is white rate noise density: `white` itself and `bandwidth` (the same noise
/// seen through the sensor's low-pass; module doc).
const WHITE_RATE_NOISE: [&str; 2] = [id::WHITE, id::BANDWIDTH];

/// N of one axis from the `n` of its white rate noise terms (`param(effect)`, `None` where the model
/// lacks that effect): √(Σ n²) over those it holds.
///
/// # Errors
/// [`ExportError::MissingTerm`] (`white`) when it holds neither.
fn white_density(axis: &str, param: impl Fn(&'static str) -> Option<f64>) -> Result<f64, ExportError> {
    let n: Vec<f64> = WHITE_RATE_NOISE.iter().filter_map(|&effect| param(effect)).collect();
    if n.is_empty() {
        return Err(ExportError::MissingTerm { axis: axis.to_string(), effect: id::WHITE });
    }
    Ok(n.iter().map(|v| v * v).sum::<f64>().sqrt())
}

impl AxisNoise {
    /// N and K of a fitted model: N from its `white` or `bandwidth` term (module doc), K from its
    /// `random_walk`.
    ///
    /// # Errors
    /// [`ExportError::MissingTerm`] when the model lacks one of them.
    pub fn from_fit(fit: &FittedModel) -> Result<Self, ExportError> {
        let axis = fit.axis.name();
        let param = |effect: &str, name: &str| fit.term(effect).and_then(|t| t.param(name)).map(|p| p.value);
        let k = param(id::RANDOM_WALK, "k")
            .ok_or_else(|| ExportError::MissingTerm { axis: axis.to_string(), effect: id::RANDOM_WALK })?;
        Ok(AxisNoise { axis: axis.to_string(), n: white_density(axis, |effect| param(effect, "n"))?, k })
    }

    /// The axes of the JSON that `fdavar fit --json` or `diagnose --json` printed.
    ///
    /// A parameter may be a number or an object with a `value` field (`{value, sigma, unit}`).
    ///
    /// # Errors
    /// [`ExportError::Json`] when the document has no `axes` array or an axis lacks its name;
    /// [`ExportError::MissingTerm`] when an axis lacks both `white.n` and `bandwidth.n`, or
    /// `random_walk.k`.
    pub fn from_report_json(doc: &Value) -> Result<Vec<Self>, ExportError> {
        let axes = doc
            .get("axes")
            .and_then(Value::as_array)
            .ok_or_else(|| ExportError::Json("no \"axes\" array".into()))?;
        axes.iter()
            .enumerate()
            .map(|(i, a)| {
                let axis = a
                    .get("axis")
                    .and_then(Value::as_str)
                    .ok_or_else(|| ExportError::Json(format!("axes[{i}] has no \"axis\" name")))?
                    .to_string();
                let param = |effect: &str, name: &str| {
                    let p = &a["coefficients"][effect][name];
                    p.as_f64().or_else(|| p["value"].as_f64())
                };
                let k = param(id::RANDOM_WALK, "k")
                    .ok_or_else(|| ExportError::MissingTerm { axis: axis.clone(), effect: id::RANDOM_WALK })?;
                Ok(AxisNoise { n: white_density(&axis, |effect| param(effect, "n"))?, k, axis: axis.clone() })
            })
            .collect()
    }
}

/// The IMU noise an estimator needs: one N and K per sensor, the topic and the sample rate.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuNoise {
    /// Gyroscope N \[rad/s/√Hz\] and K \[rad/s/√s\].
    pub gyro: KalibrImu,
    /// Accelerometer N \[m/s²/√Hz\] and K \[m/s²/√s\].
    pub accel: KalibrImu,
    /// The IMU topic the estimator subscribes to.
    pub topic: String,
    /// Sample rate, Hz (Kalibr's and OpenVINS' `update_rate`).
    pub rate_hz: Option<f64>,
    /// The inflation factor already applied (1 = as measured).
    pub inflation: f64,
}

impl ImuNoise {
    /// Per sensor, the largest N and the largest K over its axes.
    ///
    /// # Errors
    /// [`ExportError::NoSensor`] when the gyro or the accel has no axis; [`ExportError::BadValue`]
    /// for a NaN, infinite or negative value or rate.
    pub fn from_axes(axes: &[AxisNoise], topic: &str, rate_hz: Option<f64>) -> Result<Self, ExportError> {
        let sensor = |which: Sensor, name: &'static str| -> Result<KalibrImu, ExportError> {
            let mine: Vec<&AxisNoise> = axes.iter().filter(|a| Sensor::of_axis(&a.axis) == Some(which)).collect();
            if mine.is_empty() {
                return Err(ExportError::NoSensor(name));
            }
            for a in &mine {
                check(&format!("{} n", a.axis), a.n)?;
                check(&format!("{} k", a.axis), a.k)?;
            }
            let max = |f: fn(&AxisNoise) -> f64| mine.iter().map(|a| f(a)).fold(0.0, f64::max);
            Ok(KalibrImu::from_si(max(|a| a.n), max(|a| a.k)))
        };
        if let Some(r) = rate_hz {
            if !(r.is_finite() && r > 0.0) {
                return Err(ExportError::BadValue { what: "rate".into(), value: r });
            }
        }
        Ok(ImuNoise {
            gyro: sensor(Sensor::Gyro, "gyro")?,
            accel: sensor(Sensor::Accel, "accel")?,
            topic: topic.to_string(),
            rate_hz,
            inflation: 1.0,
        })
    }

    /// Every density multiplied by `factor` (variances by factor²), as the estimators' guides
    /// recommend for real-world use (OpenVINS: 10–20).
    ///
    /// # Errors
    /// [`ExportError::BadInflation`] unless `factor` is positive and finite.
    pub fn inflated(&self, factor: f64) -> Result<Self, ExportError> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(ExportError::BadInflation(factor));
        }
        let scale = |s: &KalibrImu| KalibrImu::from_si(s.noise_density * factor, s.random_walk * factor);
        Ok(ImuNoise {
            gyro: scale(&self.gyro),
            accel: scale(&self.accel),
            inflation: self.inflation * factor,
            ..self.clone()
        })
    }

    /// The keys whose value is zero: the fit did not resolve that term on any axis of the sensor
    /// (typically K on a record too short to see the random walk). An estimator would take that
    /// noise as absent — e.g. a bias that never moves.
    pub fn unresolved(&self) -> Vec<&'static str> {
        [
            ("gyroscope_noise_density", self.gyro.noise_density),
            ("gyroscope_random_walk", self.gyro.random_walk),
            ("accelerometer_noise_density", self.accel.noise_density),
            ("accelerometer_random_walk", self.accel.random_walk),
        ]
        .into_iter()
        .filter(|(_, v)| *v == 0.0)
        .map(|(k, _)| k)
        .collect()
    }

    /// The file (or config fragment) of `format`.
    ///
    /// ```
    /// use fdavar::report::export::{AxisNoise, ExportFormat, ImuNoise};
    /// let axes: Vec<AxisNoise> = ["gyro_x", "accel_x"]
    ///     .iter()
    ///     .map(|a| AxisNoise { axis: a.to_string(), n: 2.0e-4, k: 3.0e-6 })
    ///     .collect();
    /// let noise = ImuNoise::from_axes(&axes, "/imu0", None).unwrap();
    /// let yaml = noise.to_yaml(ExportFormat::Vins).unwrap();
    /// assert!(yaml.contains("\ngyr_w: 3.0e-6\n"), "{yaml}");
    /// ```
    ///
    /// # Errors
    /// [`ExportError::MissingRate`] for Kalibr and OpenVINS without a rate;
    /// [`ExportError::Yaml`] if serialisation fails.
    pub fn to_yaml(&self, format: ExportFormat) -> Result<String, ExportError> {
        let kalibr = || -> Result<KalibrKeys<'_>, ExportError> {
            Ok(KalibrKeys {
                accelerometer_noise_density: sig6(self.accel.noise_density),
                accelerometer_random_walk: sig6(self.accel.random_walk),
                gyroscope_noise_density: sig6(self.gyro.noise_density),
                gyroscope_random_walk: sig6(self.gyro.random_walk),
                rostopic: &self.topic,
                update_rate: sig6(self.rate_hz.ok_or(ExportError::MissingRate(format))?),
            })
        };
        let (directive, body) = match format {
            ExportFormat::Kalibr => ("", serde_yaml_ng::to_string(&kalibr()?)?),
            ExportFormat::OpenVins => (OPENCV_DIRECTIVE, serde_yaml_ng::to_string(&OpenVinsKeys { imu0: kalibr()? })?),
            ExportFormat::Vins => (
                OPENCV_DIRECTIVE,
                serde_yaml_ng::to_string(&VinsKeys {
                    imu_topic: &self.topic,
                    acc_n: sig6(self.accel.noise_density),
                    gyr_n: sig6(self.gyro.noise_density),
                    acc_w: sig6(self.accel.random_walk),
                    gyr_w: sig6(self.gyro.random_walk),
                })?,
            ),
        };
        Ok(format!("{directive}{}{}", self.header(format), yaml11_floats(&body)))
    }

    /// Comment lines: what the numbers are, their units and the inflation applied.
    fn header(&self, format: ExportFormat) -> String {
        let (n, k) = match format {
            ExportFormat::Vins => ("acc_n, gyr_n", "acc_w, gyr_w"),
            _ => ("*_noise_density", "*_random_walk"),
        };
        format!(
            "# IMU noise fitted by fdavar ({format} keys), continuous time, the largest of each sensor's axes.\n\
             # {n}: white noise density N [gyro rad/s/sqrt(Hz), accel m/s^2/sqrt(Hz)]\n\
             # {k}: bias random walk density K [gyro rad/s^2/sqrt(Hz), accel m/s^3/sqrt(Hz)]\n\
             # inflation applied: x{}\n",
            self.inflation
        )
    }
}

/// `x` rounded to 6 significant digits (relative change ≤ 5·10⁻⁶): far below the uncertainty of a
/// fitted density (N's 1σ is 0.75 % on gyro_x of the bundled 120 s `bags/clean`), and readable in a
/// config file.
fn sig6(x: f64) -> f64 {
    format!("{x:.5e}").parse().unwrap_or(x)
}

/// Rejects NaN, infinities and negative values.
fn check(what: &str, value: f64) -> Result<(), ExportError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ExportError::BadValue { what: what.to_string(), value })
    }
}

/// The first lines OpenCV's `cv::FileStorage` needs to read a file as YAML (1.2 so that libyaml
/// and PyYAML accept the directive as well; OpenCV accepts any `%YAML 1.x`).
const OPENCV_DIRECTIVE: &str = "%YAML 1.2\n---\n";

/// Kalibr's `imu.yaml` keys, in its own example's order.
#[derive(Serialize)]
struct KalibrKeys<'a> {
    accelerometer_noise_density: f64,
    accelerometer_random_walk: f64,
    gyroscope_noise_density: f64,
    gyroscope_random_walk: f64,
    rostopic: &'a str,
    update_rate: f64,
}

/// OpenVINS' `kalibr_imu_chain.yaml`: the same keys under `imu0`.
#[derive(Serialize)]
struct OpenVinsKeys<'a> {
    imu0: KalibrKeys<'a>,
}

/// VINS-Fusion's IMU keys.
#[derive(Serialize)]
struct VinsKeys<'a> {
    imu_topic: &'a str,
    acc_n: f64,
    gyr_n: f64,
    acc_w: f64,
    gyr_w: f64,
}

/// Rewrites `key: 3e-6` as `key: 3.0e-6` and `key: 1e20` as `key: 1.0e+20`: the float syntax
/// of YAML 1.1 (a `.` in the mantissa, a signed exponent), which `serde_yaml_ng` (YAML 1.2) does
/// not emit and without which PyYAML reads the value as a string. Quoted and non-numeric
/// values are left alone.
fn yaml11_floats(yaml: &str) -> String {
    yaml.lines()
        .map(|line| {
            let fixed = line.split_once(": ").and_then(|(key, value)| {
                let (mantissa, exponent) = value.split_once('e')?;
                value.parse::<f64>().ok()?;
                let mantissa = if mantissa.contains('.') { mantissa.to_string() } else { format!("{mantissa}.0") };
                let exponent = if exponent.starts_with(['-', '+']) { exponent.to_string() } else { format!("+{exponent}") };
                Some(format!("{key}: {mantissa}e{exponent}"))
            });
            fixed.unwrap_or_else(|| line.to_string()) + "\n"
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_get_yaml_1_1_syntax_and_strings_stay() {
        let yaml = "a: 3e-6\nb: 0.00016968\nc: 1e20\nd: 2.5e-7\ne: '1e5'\nf: /imu0\n  g: 200.0\n";
        assert_eq!(
            yaml11_floats(yaml),
            "a: 3.0e-6\nb: 0.00016968\nc: 1.0e+20\nd: 2.5e-7\ne: '1e5'\nf: /imu0\n  g: 200.0\n"
        );
    }

    #[test]
    fn a_sensor_takes_its_largest_axis_and_inflation_scales_all() {
        let axes = [("gyro_x", 1.0e-4, 2.0e-6), ("gyro_y", 1.5e-4, 1.0e-6), ("accel_z", 2.0e-3, 0.0)]
            .map(|(a, n, k)| AxisNoise { axis: a.into(), n, k });
        let noise = ImuNoise::from_axes(&axes, "/imu", Some(200.0)).unwrap();
        assert_eq!(noise.gyro, KalibrImu::from_si(1.5e-4, 2.0e-6));
        assert_eq!(noise.accel, KalibrImu::from_si(2.0e-3, 0.0));
        assert_eq!(noise.unresolved(), ["accelerometer_random_walk"]);
        let x10 = noise.inflated(10.0).unwrap();
        assert!((x10.gyro.noise_density - 1.5e-3).abs() <= 1.5e-3 * f64::EPSILON, "{x10:?}");
        assert_eq!(x10.inflation, 10.0);
        assert!(matches!(noise.inflated(0.0), Err(ExportError::BadInflation(_))));
        assert!(matches!(ImuNoise::from_axes(&axes[..2], "/imu", None), Err(ExportError::NoSensor("accel"))));
        assert!(noise.to_yaml(ExportFormat::Kalibr).is_ok());
        let no_rate = ImuNoise { rate_hz: None, ..noise };
        assert!(matches!(no_rate.to_yaml(ExportFormat::OpenVins), Err(ExportError::MissingRate(_))));
    }
}
