//! ROS 2 parameter files → a validated [`DavarConfig`].
//!
//! A parameter file is YAML of the form `fdavar:` (or `/fdavar:`, or the wildcard `/**:`) →
//! `ros__parameters:` → nested keys, flattened with dots exactly as ROS 2 does (`window: {min: 171}`
//! is the parameter `window.min`). Sections for other nodes are ignored.
//!
//! [`PARAMS`] is the one table of parameters (name, type, default, description, validator): the
//! offline CLI reads files through it and the node declares the same names from it, so the two can
//! never disagree on a name, a default or what is valid.

use crate::allan::TauGrid;
use crate::davar::{DetectorConfig, FTarget};
use crate::pipeline::{DavarConfig, PolicyConfig, SigmaRefMode};
use serde_yaml_ng::Value;
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// Errors reading or validating parameters; each names the parameter at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ParamsError {
    /// The file could not be read (the I/O error is the source, so that a report of the chain
    /// says it once).
    #[error("cannot read parameter file {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not YAML.
    #[error("parameter file is not valid YAML: {0}")]
    Yaml(#[from] serde_yaml_ng::Error),
    /// No `fdavar:` / `/**:` section with `ros__parameters:`.
    #[error("no 'fdavar:' or '/**:' section with 'ros__parameters:' in the parameter file")]
    NoSection,
    /// A parameter that fdavar does not have.
    #[error("unknown parameter '{name}' (known: {known})")]
    Unknown {
        /// The flattened name.
        name: String,
        /// The known names, comma-separated.
        known: String,
    },
    /// A value of the wrong type.
    #[error("parameter '{name}' must be {expected}, got {got}")]
    WrongType {
        /// The parameter.
        name: String,
        /// The type it takes.
        expected: &'static str,
        /// What the file had.
        got: String,
    },
    /// A value outside what the parameter accepts.
    #[error("parameter '{name}' = {value}: {reason}")]
    Invalid {
        /// The parameter.
        name: String,
        /// The rejected value.
        value: String,
        /// Why.
        reason: String,
    },
}

/// A parameter value as a ROS 2 parameter file holds it.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    /// `true` / `false`.
    Bool(bool),
    /// A whole number.
    Int(i64),
    /// A real number.
    Float(f64),
    /// A string.
    Str(String),
}

impl fmt::Display for ParamValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamValue::Bool(b) => write!(f, "{b}"),
            ParamValue::Int(i) => write!(f, "{i}"),
            // 1e-300 in full would be a line of 300 digits.
            ParamValue::Float(x) if *x != 0.0 && !(1e-4..1e15).contains(&x.abs()) => {
                write!(f, "{x:e}")
            }
            ParamValue::Float(x) => write!(f, "{x}"),
            ParamValue::Str(s) => write!(f, "'{s}'"),
        }
    }
}

/// The type a parameter takes (as the node declares it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamType {
    /// A whole number (ROS `integer`).
    Int,
    /// A real number (ROS `double`; whole numbers in a file are accepted).
    Float,
    /// A string (ROS `string`; whole numbers in a file are accepted and turned into text).
    Str,
}

impl ParamType {
    fn describe(self) -> &'static str {
        match self {
            ParamType::Int => "an integer",
            ParamType::Float => "a number",
            ParamType::Str => "a string",
        }
    }
}

/// One parameter: the table row both the CLI and the node read.
#[derive(Debug, Clone, Copy)]
pub struct ParamSpec {
    /// Flattened name, e.g. `window.min`.
    pub name: &'static str,
    /// Its type.
    pub kind: ParamType,
    /// Default, as it would be written in a parameter file.
    pub default: &'static str,
    /// One line for `--help`, the node's parameter descriptor and docs/davar.md.
    pub description: &'static str,
    /// Checks one value on its own (cross-parameter checks are in [`config_from_params`]);
    /// `Err` holds the reason.
    pub validate: fn(&ParamValue) -> Result<(), String>,
}

impl ParamSpec {
    /// The default as a typed value.
    pub fn default_value(&self) -> ParamValue {
        match self.kind {
            ParamType::Int => ParamValue::Int(self.default.parse().unwrap_or_default()),
            ParamType::Float => ParamValue::Float(self.default.parse().unwrap_or_default()),
            ParamType::Str => ParamValue::Str(self.default.to_string()),
        }
    }

    /// Type-checks and validates a value for this parameter (ints are accepted for numbers and
    /// strings), returning it in the parameter's own type.
    ///
    /// # Errors
    /// [`ParamsError::WrongType`] or [`ParamsError::Invalid`], naming the parameter.
    pub fn check(&self, value: &ParamValue) -> Result<ParamValue, ParamsError> {
        let typed = match (self.kind, value) {
            (ParamType::Int, ParamValue::Int(i)) => ParamValue::Int(*i),
            (ParamType::Float, ParamValue::Int(i)) => ParamValue::Float(*i as f64),
            (ParamType::Float, ParamValue::Float(x)) => ParamValue::Float(*x),
            (ParamType::Str, ParamValue::Str(s)) => ParamValue::Str(s.clone()),
            (ParamType::Str, ParamValue::Int(i)) => ParamValue::Str(i.to_string()),
            (ParamType::Str, ParamValue::Float(x)) if self.name == "f_target" => {
                ParamValue::Str(x.to_string())
            }
            _ => {
                return Err(ParamsError::WrongType {
                    name: self.name.to_string(),
                    expected: self.kind.describe(),
                    got: value.to_string(),
                })
            }
        };
        (self.validate)(&typed).map_err(|reason| ParamsError::Invalid {
            name: self.name.to_string(),
            value: typed.to_string(),
            reason,
        })?;
        Ok(typed)
    }
}

fn int_at_least(v: &ParamValue, low: i64) -> Result<(), String> {
    match v {
        ParamValue::Int(i) if *i >= low => Ok(()),
        ParamValue::Int(_) => Err(format!("must be at least {low}")),
        _ => Err("must be an integer".into()),
    }
}

fn int_in(v: &ParamValue, low: i64, high: i64) -> Result<(), String> {
    match v {
        ParamValue::Int(i) if (low..=high).contains(i) => Ok(()),
        ParamValue::Int(_) => Err(format!("must be in [{low}, {high}]")),
        _ => Err("must be an integer".into()),
    }
}

fn positive(v: &ParamValue) -> Result<(), String> {
    match v {
        ParamValue::Float(x) if *x > 0.0 && x.is_finite() => Ok(()),
        _ => Err("must be a positive number".into()),
    }
}

fn non_negative(v: &ParamValue) -> Result<(), String> {
    match v {
        ParamValue::Float(x) if *x >= 0.0 && x.is_finite() => Ok(()),
        _ => Err("must be zero or a positive number".into()),
    }
}

fn one_of(v: &ParamValue, choices: &[&str]) -> Result<(), String> {
    match v {
        ParamValue::Str(s) if choices.contains(&s.as_str()) => Ok(()),
        _ => Err(format!("must be one of {}", choices.join(", "))),
    }
}

/// Longest window (`window.length`, `window.max`, and so `window.min`), samples.
///
/// Why this number: a window needs a ring of W + 8 samples per axis, and the default τ grid (10 per
/// decade, cut at W/3) keeps 40 τ values at this W; 40 × 50 009 prefix cells fit
/// [`MAX_PREFIX_CELLS`]. At 400 Hz it is a window of 125 s. docs/davar.md "Bounds".
pub const MAX_WINDOW: i64 = 50_001;

/// Most prefix cells per axis: (τ values of the grid with 3m ≤ λ2) × (λ2 + 8).
///
/// Each cell is 16 bytes (a sum and a count), so one axis holds at most 32 MiB of prefix sums and
/// six axes 192 MiB; the per-sample cost is O(τ values), and this bound keeps it at most 834 τ
/// values (K·(3K + 8) ≤ cells). docs/davar.md "Bounds".
pub const MAX_PREFIX_CELLS: usize = 1 << 21;

/// The range of a given `tau0`, seconds (0 = learn it from the stamps).
///
/// Below 10 µs (100 kHz) no IMU samples: a τ0 far below the stamps' own period turns every
/// interval into a gap of period/τ0 missing samples (1e-300 s made that count overflow and the
/// analysis spin). Above one day it is not an IMU rate either.
pub const TAU0_RANGE_S: (f64, f64) = (1e-5, 86_400.0);

/// How far a given `tau0` may lie from the period the stamps show (their median interval): a
/// factor of 10 either way.
///
/// Why: τ0 below the stamps' period makes every interval a gap of period/τ0 missing samples (10⁻⁵ s
/// on 30 ms stamps took 12 s for 3 600 samples instead of 0.1 s); above it, gaps go unseen. Where
/// the period is known before the analysis starts (`fdavar davar` on a bag, a live change of a
/// running node) a τ0 outside this factor is refused; otherwise [`TAU0_RANGE_S`] bounds the cost.
pub const TAU0_PERIOD_FACTOR: f64 = 10.0;

/// Checks a given τ0 against the period measured from the stamps ([`TAU0_PERIOD_FACTOR`]).
///
/// # Errors
/// [`ParamsError::Invalid`] naming `tau0`, with both periods.
pub fn check_tau0_against_period(tau0: f64, measured_s: f64) -> Result<(), ParamsError> {
    let f = TAU0_PERIOD_FACTOR;
    // No usable measurement (none, or not a positive number): nothing to check against.
    let unknown = !measured_s.is_finite() || measured_s <= 0.0;
    if unknown || (measured_s / f..=measured_s * f).contains(&tau0) {
        return Ok(());
    }
    Err(ParamsError::Invalid {
        name: "tau0".to_string(),
        value: ParamValue::Float(tau0).to_string(),
        reason: format!(
            "the stamps' median interval is {} s; tau0 must be within 1/{f}..{f} times it (or 0 \
             to use it)",
            (measured_s * 1e9).round() / 1e9
        ),
    })
}

/// Checks the window and τ grid against [`MAX_PREFIX_CELLS`]; `Err` names `taus` and says why.
///
/// # Errors
/// The reason, with the numbers.
pub fn check_grid_size(taus: &TauGrid, max_window: usize) -> Result<(), String> {
    let k = taus.factors(max_window / 3).len();
    let cells = k.saturating_mul(max_window.saturating_add(8));
    if cells > MAX_PREFIX_CELLS {
        return Err(format!(
            "{k} tau values x a ring of {} samples = {cells} prefix cells per axis, more than \
             {MAX_PREFIX_CELLS} (32 MiB); use fewer tau values (e.g. taus: 10) or a shorter window",
            max_window + 8
        ));
    }
    Ok(())
}

/// Window policies (`window.policy`).
pub const POLICIES: [&str; 3] = ["fixed", "sign", "proportional"];
/// σ²_ref modes (`sigma_ref.mode`).
pub const SIGMA_REF_MODES: [&str; 4] = ["record", "running", "baseline", "value"];

/// Every parameter of the DAVAR engine, in the order of docs and `--help`.
pub static PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "window.policy",
        kind: ParamType::Str,
        default: "sign",
        description: "window policy: fixed (window.length), sign (seed Eq. 3) or proportional (step grows with |log2(F/F~)|)",
        validate: |v| one_of(v, &POLICIES),
    },
    ParamSpec {
        name: "window.length",
        kind: ParamType::Int,
        default: "501",
        description: "window length W of the fixed policy, samples, [3, 50001]",
        validate: |v| int_in(v, 3, MAX_WINDOW),
    },
    ParamSpec {
        name: "window.min",
        kind: ParamType::Int,
        default: "171",
        description: "lambda1: shortest adaptive window, samples, [3, 50001]",
        validate: |v| int_in(v, 3, MAX_WINDOW),
    },
    ParamSpec {
        name: "window.max",
        kind: ParamType::Int,
        default: "501",
        description: "lambda2: longest adaptive window, samples, [3, 50001] (memory is O(K*lambda2) per axis, K*(lambda2+8) <= 2^21)",
        validate: |v| int_in(v, 3, MAX_WINDOW),
    },
    ParamSpec {
        name: "window.step",
        kind: ParamType::Int,
        default: "4",
        description: "Delta W: step of the sign policy, and step per doubling of F/F~ of the proportional policy, samples, [1, 50001] (even keeps an odd window centred)",
        validate: |v| int_in(v, 1, MAX_WINDOW),
    },
    ParamSpec {
        name: "window.max_step",
        kind: ParamType::Int,
        default: "32",
        description: "largest move per row of the proportional policy, samples, [1, 50001]",
        validate: |v| int_in(v, 1, MAX_WINDOW),
    },
    ParamSpec {
        name: "f_target",
        kind: ParamType::Str,
        default: "auto",
        description: "F~, the steady target of F: a positive number (the seed uses 3.3) or auto (learned from steady rows)",
        validate: |v| match v {
            ParamValue::Str(s) if s == "auto" => Ok(()),
            ParamValue::Str(s) => match s.parse::<f64>() {
                Ok(x) if x > 0.0 && x.is_finite() => Ok(()),
                _ => Err("must be auto or a positive number".into()),
            },
            _ => Err("must be auto or a positive number".into()),
        },
    },
    ParamSpec {
        name: "f_auto.band_z",
        kind: ParamType::Float,
        default: "2.0",
        description: "auto F~: F~ = steady F level * (1 + band_z*sqrt(2/(n-1))), standard deviations",
        validate: positive,
    },
    ParamSpec {
        name: "f_auto.warmup_rows",
        kind: ParamType::Int,
        default: "500",
        description: "auto F~: rows learned before F~ is used (the window holds until then)",
        validate: |v| int_at_least(v, 1),
    },
    ParamSpec {
        name: "sigma_ref.mode",
        kind: ParamType::Str,
        default: "running",
        description: "sigma^2_ref: record (whole record, offline only, seed-exact), running (all samples so far), baseline (first sigma_ref.baseline_s seconds), value (sigma_ref.value)",
        validate: |v| one_of(v, &SIGMA_REF_MODES),
    },
    ParamSpec {
        name: "sigma_ref.baseline_s",
        kind: ParamType::Float,
        default: "10.0",
        description: "length of the baseline of sigma_ref.mode baseline, seconds",
        validate: positive,
    },
    ParamSpec {
        name: "sigma_ref.value",
        kind: ParamType::Float,
        default: "0.0",
        description: "sigma^2_ref of sigma_ref.mode value, (rad/s)^2 or (m/s^2)^2",
        validate: non_negative,
    },
    ParamSpec {
        name: "taus",
        kind: ParamType::Str,
        default: "10",
        description: "tau grid: all, octave, decade, or N log-spaced factors per decade (cut at window/3; tau values x (window + 8) <= 2^21)",
        validate: |v| match v {
            ParamValue::Str(s) => s.parse::<TauGrid>().map(|_| ()).map_err(|e| e.to_string()),
            _ => Err("must be a string".into()),
        },
    },
    ParamSpec {
        name: "tau0",
        kind: ParamType::Float,
        default: "0.0",
        description: "nominal sample period, seconds, 0 or [1e-5, 86400]; 0 = estimate from stamps (median interval)",
        validate: |v| match v {
            ParamValue::Float(x) if *x == 0.0 => Ok(()),
            ParamValue::Float(x) if (TAU0_RANGE_S.0..=TAU0_RANGE_S.1).contains(x) => Ok(()),
            _ => Err(format!(
                "must be 0 (from the stamps) or in [{:e}, {}] s",
                TAU0_RANGE_S.0, TAU0_RANGE_S.1
            )),
        },
    },
    ParamSpec {
        name: "events.z",
        kind: ParamType::Float,
        default: "4.0",
        description: "change detection band: a row is flagged when the steady short-tau level is outside its z-sigma chi-square interval",
        validate: positive,
    },
    ParamSpec {
        name: "events.warmup_rows",
        kind: ParamType::Int,
        default: "500",
        description: "rows learned before change detection starts",
        validate: |v| int_at_least(v, 1),
    },
    ParamSpec {
        name: "events.min_rows",
        kind: ParamType::Int,
        default: "10",
        description: "fewest flagged rows that make an event",
        validate: |v| int_at_least(v, 1),
    },
    ParamSpec {
        name: "events.merge_rows",
        kind: ParamType::Int,
        default: "100",
        description: "most unflagged rows inside one event (shorter quiet runs are merged)",
        validate: |v| int_at_least(v, 0),
    },
];

/// The spec of a parameter by name.
pub fn spec(name: &str) -> Option<&'static ParamSpec> {
    PARAMS.iter().find(|p| p.name == name)
}

/// Reads a ROS 2 parameter file into a validated configuration.
///
/// # Errors
/// [`ParamsError`], naming the file or the parameter at fault.
pub fn load(path: &Path) -> Result<DavarConfig, ParamsError> {
    let text = std::fs::read_to_string(path).map_err(|source| ParamsError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    from_yaml_str(&text)
}

/// Parses the text of a ROS 2 parameter file into a validated configuration.
///
/// ```
/// let cfg = fdavar::params::from_yaml_str(
///     "fdavar:\n  ros__parameters:\n    window: {policy: fixed, length: 171}\n").unwrap();
/// assert_eq!(cfg.policy, fdavar::pipeline::PolicyConfig::Fixed { length: 171 });
/// ```
///
/// # Errors
/// [`ParamsError`], naming the parameter at fault.
pub fn from_yaml_str(text: &str) -> Result<DavarConfig, ParamsError> {
    config_from_params(&flatten_ros_params(text)?)
}

/// The flattened `name → value` map of the `fdavar` (or `/**`) sections of a parameter file.
///
/// # Errors
/// [`ParamsError::Yaml`], [`ParamsError::NoSection`], or [`ParamsError::WrongType`] for a list or
/// null value.
pub fn flatten_ros_params(text: &str) -> Result<BTreeMap<String, ParamValue>, ParamsError> {
    let doc: Value = serde_yaml_ng::from_str(text)?;
    let mut out = BTreeMap::new();
    let mut found = false;
    if let Value::Mapping(nodes) = &doc {
        for (node, body) in nodes {
            let is_ours = matches!(node.as_str(), Some("fdavar" | "/fdavar" | "/**"));
            let params = body.get("ros__parameters");
            if let (true, Some(params)) = (is_ours, params) {
                found = true;
                flatten_into(params, "", &mut out)?;
            }
        }
    }
    if !found {
        return Err(ParamsError::NoSection);
    }
    Ok(out)
}

fn flatten_into(
    value: &Value,
    prefix: &str,
    out: &mut BTreeMap<String, ParamValue>,
) -> Result<(), ParamsError> {
    let leaf = match value {
        Value::Mapping(map) => {
            for (k, v) in map {
                let key = match k {
                    Value::String(s) => s.clone(),
                    other => serde_yaml_ng::to_string(other)
                        .unwrap_or_default()
                        .trim()
                        .to_string(),
                };
                let name = if prefix.is_empty() {
                    key
                } else {
                    format!("{prefix}.{key}")
                };
                flatten_into(v, &name, out)?;
            }
            return Ok(());
        }
        Value::Bool(b) => ParamValue::Bool(*b),
        Value::Number(n) => match n.as_i64() {
            Some(i) => ParamValue::Int(i),
            None => ParamValue::Float(n.as_f64().unwrap_or(f64::NAN)),
        },
        Value::String(s) => ParamValue::Str(s.clone()),
        Value::Tagged(t) => return flatten_into(&t.value, prefix, out),
        other => {
            return Err(ParamsError::WrongType {
                name: prefix.to_string(),
                expected: "a scalar",
                got: format!("{other:?}"),
            })
        }
    };
    out.insert(prefix.to_string(), leaf);
    Ok(())
}

/// Validates a flattened parameter map (missing names take their defaults) into a configuration.
///
/// # Errors
/// [`ParamsError::Unknown`] for a name not in [`PARAMS`]; [`ParamsError::WrongType`] /
/// [`ParamsError::Invalid`] for a bad value, including the cross-checks `window.min` ≤
/// `window.max` and a positive `sigma_ref.value` when `sigma_ref.mode` is `value`.
pub fn config_from_params(
    params: &BTreeMap<String, ParamValue>,
) -> Result<DavarConfig, ParamsError> {
    for name in params.keys() {
        if spec(name).is_none() {
            return Err(ParamsError::Unknown {
                name: name.clone(),
                known: PARAMS.iter().map(|p| p.name).collect::<Vec<_>>().join(", "),
            });
        }
    }
    let get = |name: &str| -> Result<ParamValue, ParamsError> {
        let spec = spec(name).expect("PARAMS holds every name the builder reads");
        match params.get(name) {
            Some(v) => spec.check(v),
            None => Ok(spec.default_value()),
        }
    };
    let int = |name: &str| -> Result<usize, ParamsError> {
        match get(name)? {
            ParamValue::Int(i) => Ok(i.max(0) as usize),
            _ => unreachable!("check() returns the spec's type"),
        }
    };
    let float = |name: &str| -> Result<f64, ParamsError> {
        match get(name)? {
            ParamValue::Float(x) => Ok(x),
            _ => unreachable!("check() returns the spec's type"),
        }
    };
    let text = |name: &str| -> Result<String, ParamsError> {
        match get(name)? {
            ParamValue::Str(s) => Ok(s),
            _ => unreachable!("check() returns the spec's type"),
        }
    };
    let invalid = |name: &str, value: String, reason: &str| ParamsError::Invalid {
        name: name.to_string(),
        value,
        reason: reason.to_string(),
    };

    let (min, max, step) = (int("window.min")?, int("window.max")?, int("window.step")?);
    let max_step = int("window.max_step")?;
    let length = int("window.length")?;
    let policy = match text("window.policy")?.as_str() {
        "fixed" => PolicyConfig::Fixed { length },
        name => {
            if min > max {
                return Err(invalid(
                    "window.min",
                    min.to_string(),
                    &format!("must not exceed window.max ({max})"),
                ));
            }
            if name == "sign" {
                PolicyConfig::Sign { min, max, step }
            } else {
                if max_step < step {
                    return Err(invalid(
                        "window.max_step",
                        max_step.to_string(),
                        &format!("must be at least window.step ({step})"),
                    ));
                }
                PolicyConfig::Proportional {
                    min,
                    max,
                    step,
                    max_step,
                }
            }
        }
    };
    let f_target = match text("f_target")?.as_str() {
        "auto" => FTarget::Auto {
            band_z: float("f_auto.band_z")?,
            warmup_rows: int("f_auto.warmup_rows")?,
        },
        number => FTarget::Value(number.parse().map_err(|_| {
            invalid(
                "f_target",
                number.to_string(),
                "must be auto or a positive number",
            )
        })?),
    };
    let sigma_ref = match text("sigma_ref.mode")?.as_str() {
        "record" => SigmaRefMode::Record,
        "running" => SigmaRefMode::Running,
        "baseline" => SigmaRefMode::Baseline {
            seconds: float("sigma_ref.baseline_s")?,
        },
        _ => {
            let v = float("sigma_ref.value")?;
            if v <= 0.0 {
                return Err(invalid(
                    "sigma_ref.value",
                    v.to_string(),
                    "must be positive when sigma_ref.mode is value",
                ));
            }
            SigmaRefMode::Value(v)
        }
    };
    let taus: TauGrid = text("taus")?
        .parse()
        .map_err(|e: crate::allan::TauGridError| invalid("taus", e.0.clone(), "not a tau grid"))?;
    check_grid_size(&taus, policy.max_window())
        .map_err(|reason| invalid("taus", taus.to_string(), &reason))?;
    let tau0 = float("tau0")?;
    Ok(DavarConfig {
        policy,
        f_target,
        sigma_ref,
        taus,
        tau0: (tau0 > 0.0).then_some(tau0),
        events: DetectorConfig {
            z: float("events.z")?,
            warmup_rows: int("events.warmup_rows")?,
            min_rows: int("events.min_rows")?,
            merge_rows: int("events.merge_rows")?,
        },
    })
}

impl Default for DavarConfig {
    /// Every parameter at its default in [`PARAMS`].
    fn default() -> Self {
        config_from_params(&BTreeMap::new()).expect("the defaults of PARAMS are valid")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(body: &str) -> Result<DavarConfig, ParamsError> {
        from_yaml_str(&format!("fdavar:\n  ros__parameters:\n{body}"))
    }

    #[test]
    fn defaults_are_valid_and_every_default_passes_its_validator() {
        for p in PARAMS {
            p.check(&p.default_value()).unwrap();
        }
        let d = DavarConfig::default();
        assert_eq!(
            d.policy,
            PolicyConfig::Sign {
                min: 171,
                max: 501,
                step: 4
            }
        );
        assert_eq!(d.sigma_ref, SigmaRefMode::Running);
    }

    #[test]
    fn nested_and_dotted_keys_flatten_alike() {
        let a = parse("    window:\n      policy: proportional\n      min: 11\n      max: 51\n    f_target: 3.3\n").unwrap();
        let b = from_yaml_str("/**:\n  ros__parameters:\n    window.policy: proportional\n    window.min: 11\n    window.max: 51\n    f_target: \"3.3\"\n").unwrap();
        assert_eq!(a, b);
        assert_eq!(a.f_target, FTarget::Value(3.3));
        assert_eq!(
            a.policy,
            PolicyConfig::Proportional {
                min: 11,
                max: 51,
                step: 4,
                max_step: 32
            }
        );
    }

    #[test]
    fn errors_name_the_parameter() {
        let msg = |body: &str| parse(body).unwrap_err().to_string();
        assert!(msg("    window: {policy: wobbly}\n").contains("window.policy"));
        assert!(msg("    window: {min: 600, max: 501}\n").contains("window.min"));
        assert!(msg("    window: {step: -4}\n").contains("window.step"));
        assert!(msg("    f_target: 0\n").contains("f_target"));
        assert!(msg("    f_target: -3.3\n").contains("f_target"));
        assert!(msg("    f_target: often\n").contains("f_target"));
        assert!(msg("    windw: {min: 3}\n").contains("unknown parameter 'windw.min'"));
        assert!(msg("    window: {min: fast}\n").contains("must be an integer"));
        assert!(msg("    sigma_ref: {mode: value}\n").contains("sigma_ref.value"));
        assert!(msg("    taus: many\n").contains("taus"));
        assert!(matches!(
            from_yaml_str("other:\n  ros__parameters: {}\n"),
            Err(ParamsError::NoSection)
        ));
        assert!(matches!(
            from_yaml_str("fdavar: [1"),
            Err(ParamsError::Yaml(_))
        ));
    }

    /// Issue 13: values the validators let through that then overflowed, aborted, took tens of
    /// seconds or spun forever; each is refused, naming the parameter and its bound.
    #[test]
    fn values_beyond_the_memory_and_time_bounds_are_refused() {
        let msg = |body: &str| parse(body).unwrap_err().to_string();
        let cases = [
            (
                "    window: {max: 9223372036854775807}\n",
                "parameter 'window.max'",
                "[3, 50001]",
            ),
            (
                "    window: {max: 1000000000}\n",
                "parameter 'window.max'",
                "[3, 50001]",
            ),
            (
                "    window: {max: 10000000}\n",
                "parameter 'window.max'",
                "[3, 50001]",
            ),
            (
                "    window: {policy: fixed, length: 1000000000}\n",
                "parameter 'window.length'",
                "[3, 50001]",
            ),
            (
                "    window: {min: 50002}\n",
                "parameter 'window.min'",
                "[3, 50001]",
            ),
            (
                "    window: {step: 9223372036854775807}\n",
                "parameter 'window.step'",
                "[1, 50001]",
            ),
            (
                "    window: {max_step: 60000}\n",
                "parameter 'window.max_step'",
                "[1, 50001]",
            ),
            (
                "    window: {policy: fixed, length: 60001}\n    taus: all\n",
                "parameter 'window.length'",
                "[3, 50001]",
            ),
            (
                "    window: {policy: fixed, length: 50001}\n    taus: all\n",
                "parameter 'taus'",
                "16667 tau values",
            ),
            (
                "    window: {max: 3001}\n    taus: all\n",
                "parameter 'taus'",
                "2097152",
            ),
            ("    tau0: 1.0e-300\n", "parameter 'tau0'", "[1e-5, 86400]"),
            ("    tau0: 1.0e-21\n", "parameter 'tau0'", "[1e-5, 86400]"),
            ("    tau0: 1.0e6\n", "parameter 'tau0'", "[1e-5, 86400]"),
        ];
        for (body, name, bound) in cases {
            let m = msg(body);
            assert!(m.contains(name) && m.contains(bound), "{body}: {m}");
        }
        // The edges are accepted: the longest window with the default grid (40 τ values), `all`
        // on the longest window it fits, the τ0 range's ends and 0 (from the stamps).
        let edge = parse("    window: {policy: fixed, length: 50001}\n").unwrap();
        let k = edge.taus.factors(MAX_WINDOW as usize / 3).len();
        assert_eq!(k, 40);
        assert!(k * (MAX_WINDOW as usize + 8) <= MAX_PREFIX_CELLS);
        parse("    window: {policy: fixed, length: 2501}\n    taus: all\n").unwrap();
        parse("    window: {max: 50001, step: 50001, max_step: 50001}\n").unwrap();
        for tau0 in ["1.0e-5", "86400.0", "0.0"] {
            parse(&format!("    tau0: {tau0}\n")).unwrap();
        }
        // Against the stamps' own period: a factor of 10 either way.
        check_tau0_against_period(0.3, 0.03).unwrap();
        check_tau0_against_period(0.003, 0.03).unwrap();
        let e = check_tau0_against_period(1e-5, 0.03)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("parameter 'tau0' = 1e-5") && e.contains("0.03 s"),
            "{e}"
        );
        assert!(check_tau0_against_period(0.31, 0.03).is_err());
    }

    #[test]
    fn launch_files_parse() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("launch_params");
        let seed = load(&root.join("seed_2016.yaml")).unwrap();
        assert_eq!(
            seed.policy,
            PolicyConfig::Sign {
                min: 171,
                max: 501,
                step: 4
            }
        );
        assert_eq!(seed.f_target, FTarget::Value(3.3));
        assert_eq!(seed.tau0, Some(0.03));
        assert_eq!(seed.sigma_ref, SigmaRefMode::Record);
        let default = load(&root.join("default.yaml")).unwrap();
        assert_eq!(default.sigma_ref, SigmaRefMode::Running);
        assert!(matches!(default.f_target, FTarget::Auto { .. }));
    }
}
