//! The node's parameters: one table of names, defaults, validators and whether a change applies live.
//!
//! Why one table: declaration (what `ros2 param list` shows), validation of `-p` / `--params-file`
//! values at startup, validation of `ros2 param set` at run time, and the docs all read it, so they
//! cannot disagree. A refused value leaves everything unchanged and returns the reason to the caller
//! (`SetParameters` answers `successful=False, reason=…`).
//!
//! The node has two groups of parameters: its own ([`NODE_PARAMS`]: rates, queue, QoS, model) and
//! the DAVAR settings of [`crate::params::PARAMS`] (window policy, F̃, σ²_ref, τ grid, …), the same
//! table and validation the offline `fdavar davar --params` uses. A DAVAR change is checked
//! together with the other DAVAR values (e.g. `window.min` ≤ `window.max`) and must give a
//! configuration that runs live.

use super::args::yaml_to_param;
use crate::params::ParamValue as DavarValue;
use crate::model::record::RecordBuilder;
use crate::pipeline::DavarConfig;
use ros2_client::ParameterValue;
use std::collections::BTreeMap;
use std::path::Path;

/// One node parameter.
#[derive(Debug)]
pub struct ParamSpec {
    /// Parameter name as `ros2 param` shows it.
    pub name: &'static str,
    /// One line for the docs.
    pub doc: &'static str,
    /// The default value (also fixes the type).
    pub default: fn() -> ParameterValue,
    /// Checks a candidate value (type and range); `Err` carries the reason.
    pub validate: fn(&ParameterValue) -> Result<(), String>,
    /// True when a change while running takes effect; false: read at startup only.
    pub live: bool,
}

fn positive_double(v: &ParameterValue, max: f64) -> Result<(), String> {
    match v {
        ParameterValue::Double(x) if x.is_finite() && *x > 0.0 && *x <= max => Ok(()),
        ParameterValue::Double(x) => Err(format!("must be in (0, {max}], got {x}")),
        other => Err(format!("must be a double, got {other:?}")),
    }
}

fn non_negative_double(v: &ParameterValue, max: f64) -> Result<(), String> {
    double_in(v, 0.0, max)
}

fn double_in(v: &ParameterValue, min: f64, max: f64) -> Result<(), String> {
    match v {
        ParameterValue::Double(x) if (min..=max).contains(x) => Ok(()),
        ParameterValue::Double(x) => Err(format!("must be in [{min}, {max}], got {x}")),
        other => Err(format!("must be a double, got {other:?}")),
    }
}

fn int_in(v: &ParameterValue, lo: i64, hi: i64) -> Result<(), String> {
    match v {
        ParameterValue::Integer(i) if (lo..=hi).contains(i) => Ok(()),
        ParameterValue::Integer(i) => Err(format!("must be in [{lo}, {hi}], got {i}")),
        other => Err(format!("must be an integer, got {other:?}")),
    }
}

fn boolean(v: &ParameterValue) -> Result<(), String> {
    match v {
        ParameterValue::Boolean(_) => Ok(()),
        other => Err(format!("must be a boolean, got {other:?}")),
    }
}

fn string(v: &ParameterValue) -> Result<(), String> {
    match v {
        ParameterValue::String(_) => Ok(()),
        other => Err(format!("must be a string, got {other:?}")),
    }
}

/// Checks a model spec (comma-separated effect ids or aliases) with the model's own parser.
fn model_spec(v: &ParameterValue) -> Result<(), String> {
    match v {
        ParameterValue::String(spec) => super::engine::model_spec(spec).map(|_| ()),
        other => Err(format!("must be a string like \"N,B,K\", got {other:?}")),
    }
}

/// Checks a per-axis model: a spec, or empty (the axis follows `model`).
fn axis_model_spec(v: &ParameterValue) -> Result<(), String> {
    match v {
        ParameterValue::String(spec) if spec.trim().is_empty() => Ok(()),
        other => model_spec(other),
    }
}

/// The name of the per-axis model parameter of `axis`: `model.<axis>`.
pub fn axis_model_param(axis: crate::signal::Axis) -> String {
    format!("model.{axis}")
}

/// The per-axis model parameter of one axis (see [`NODE_PARAMS`]).
const fn axis_model(name: &'static str) -> ParamSpec {
    ParamSpec {
        name,
        doc: "Noise model of this axis only (as `model`); empty: the axis follows `model`.",
        default: || ParameterValue::String(String::new()),
        validate: axis_model_spec,
        live: true,
    }
}

/// The node's parameter table, in the order of `ros2 param list` and the docs.
pub static NODE_PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "publish_rate_hz",
        doc: "Rate of /diagnostics and ~/<axis>/state, Hz (0, 100].",
        default: || ParameterValue::Double(1.0),
        validate: |v| positive_double(v, 100.0),
        live: true,
    },
    ParamSpec {
        name: "stale_timeout_s",
        doc: "No IMU message for this long (s) turns every status ERROR (stale input).",
        default: || ParameterValue::Double(1.0),
        validate: |v| positive_double(v, 3600.0),
        live: true,
    },
    ParamSpec {
        name: "queue_size",
        doc: "Samples the analysis queue holds; when full, new samples are dropped and counted.",
        default: || ParameterValue::Integer(10_000),
        validate: |v| int_in(v, 1, 1_000_000),
        live: false,
    },
    ParamSpec {
        name: "receive_batch_ms",
        doc: "While IMU messages come faster than one per this many ms, take them off DDS in \
              batches, on a timer set from their arrivals, instead of being woken by DDS for each \
              one (at kHz rates the per-message wake-up was most of the node's CPU); such a \
              message waits at most about this long before its update. Slower topics are taken \
              as they come. 0 = wake for every message. [0, 10].",
        default: || ParameterValue::Double(0.8),
        validate: |v| non_negative_double(v, 10.0),
        live: false,
    },
    ParamSpec {
        name: "qos.reliable",
        doc: "Subscribe `imu` reliable (matches only reliable publishers); default best effort.",
        default: || ParameterValue::Boolean(false),
        validate: boolean,
        live: false,
    },
    ParamSpec {
        name: "qos.depth",
        doc: "Keep-last depth of the `imu` subscription, messages.",
        default: || ParameterValue::Integer(100),
        validate: |v| int_in(v, 1, 100_000),
        live: false,
    },
    ParamSpec {
        name: "temperature",
        doc: "Also subscribe `temperature` (sensor_msgs/msg/Temperature).",
        default: || ParameterValue::Boolean(false),
        validate: boolean,
        live: false,
    },
    ParamSpec {
        name: "use_sim_time",
        doc: "Take the node's time from /clock (rosgraph_msgs/msg/Clock).",
        default: || ParameterValue::Boolean(false),
        validate: boolean,
        live: false,
    },
    ParamSpec {
        name: "model",
        doc: "Noise model fitted to the whole run of every axis: effect ids or aliases, \
              comma-separated (e.g. N,B,K); `model.<axis>` overrides it on one axis.",
        default: || ParameterValue::String("N,B,K".to_string()),
        validate: model_spec,
        live: true,
    },
    axis_model("model.gyro_x"),
    axis_model("model.gyro_y"),
    axis_model("model.gyro_z"),
    axis_model("model.accel_x"),
    axis_model("model.accel_y"),
    axis_model("model.accel_z"),
    ParamSpec {
        name: "diagnosis_period_s",
        doc: "Seconds between two diagnoses of the whole run (coefficients, fit_error, failing \
              τ and spans, suggestions), one axis per publication; 0 turns them off. [0, 3600].",
        default: || ParameterValue::Double(10.0),
        validate: |v| non_negative_double(v, 3600.0),
        live: true,
    },
    ParamSpec {
        name: "diagnosis_cpu_share",
        doc: "Largest share of one core the whole-run diagnosis may take: the diagnosis of an \
              axis that took C seconds starts the next no sooner than C/share seconds after its \
              own start (a diagnosis costs in proportion to the record: about 0.3 s per axis once \
              it holds 2^20 values). 1 = only diagnosis_period_s paces the rounds. (0, 1].",
        default: || ParameterValue::Double(0.005),
        validate: |v| positive_double(v, 1.0),
        live: true,
    },
    ParamSpec {
        name: "record_cap",
        doc: "Values per axis the whole-run record keeps before it averages neighbouring pairs \
              and its period doubles: 2^20 = 2.9 h at 100 Hz, 8.7 min at 2 kHz. Larger keeps the \
              shortest tau of a long run (a low-pass near Nyquist, quantization) for about 160 \
              bytes per value at a round's peak, and each round costs in proportion; the same as \
              `fdavar diagnose --record-cap`. [2^20, 2^24].",
        default: || ParameterValue::Integer(RecordBuilder::DEFAULT_MAX_SAMPLES as i64),
        validate: |v| match v {
            ParameterValue::Integer(i) => RecordBuilder::user_cap(&i.to_string()).map(drop),
            other => Err(format!("must be an integer, got {other:?}")),
        },
        live: false,
    },
    ParamSpec {
        name: "dump_json",
        doc: "If not empty, a file the node writes one JSON line per analysis row to (an \
              AxisState as JSON), bounded by dump_json_max_mb and dump_every_s.",
        default: || ParameterValue::String(String::new()),
        validate: string,
        live: false,
    },
    ParamSpec {
        name: "dump_json_max_mb",
        doc: "Size cap of the dump_json file, MB (10^6 bytes), [1, 1e6]: the line that would \
              pass it first moves the file to <dump_json>.1 (replacing the previous one).",
        default: || ParameterValue::Double(100.0),
        validate: |v| double_in(v, 1.0, 1e6),
        live: false,
    },
    ParamSpec {
        name: "dump_every_s",
        doc: "dump_json keeps at most one row per axis per this many seconds of analysis time, \
              s, [0, 3600]; 0 keeps every row.",
        default: || ParameterValue::Double(0.0),
        validate: |v| non_negative_double(v, 3600.0),
        live: false,
    },
];

/// A value's ROS type name and its text as `--help` and the docs show them (`double`, `1.0`;
/// `string`, `"N,B,K"`).
pub fn type_and_text(value: &ParameterValue) -> (&'static str, String) {
    match value {
        ParameterValue::Boolean(b) => ("bool", b.to_string()),
        ParameterValue::Integer(i) => ("int", i.to_string()),
        ParameterValue::Double(x) => ("double", format!("{x:?}")),
        ParameterValue::String(s) => ("string", format!("{s:?}")),
        other => ("array", format!("{other:?}")),
    }
}

/// A parameter value refused at startup or at run time.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ParamError {
    /// No such parameter.
    #[error("unknown parameter '{name}' (see `ros2 param list`)")]
    Unknown {
        /// The name given.
        name: String,
    },
    /// The validator refused the value.
    #[error("parameter '{name}': {reason}")]
    Invalid {
        /// Parameter name.
        name: String,
        /// The validator's reason.
        reason: String,
    },
    /// A DAVAR value the DAVAR table refused; the reason names the parameter and its value.
    #[error("{reason}")]
    Davar {
        /// The reason, e.g. `parameter 'window.max' = 1000000000: must be in [3, 50001]`.
        reason: String,
    },
    /// A parameter file could not be read.
    #[error("parameter file {path}: {reason}")]
    File {
        /// The file.
        path: String,
        /// What went wrong.
        reason: String,
    },
}

/// Looks a parameter up in [`NODE_PARAMS`].
pub fn spec(name: &str) -> Option<&'static ParamSpec> {
    NODE_PARAMS.iter().find(|p| p.name == name)
}

/// Validates one (name, value) pair against the table; integers are accepted for doubles.
///
/// Returns the value to store (an integer given for a double parameter becomes a double, as a
/// YAML `2` for `publish_rate_hz` means 2.0).
///
/// # Errors
/// [`ParamError::Unknown`] or [`ParamError::Invalid`] with the validator's reason.
pub fn validate(name: &str, value: &ParameterValue) -> Result<ParameterValue, ParamError> {
    let spec = spec(name).ok_or_else(|| ParamError::Unknown {
        name: name.to_string(),
    })?;
    let value = match (value, (spec.default)()) {
        (ParameterValue::Integer(i), ParameterValue::Double(_)) => {
            ParameterValue::Double(*i as f64)
        }
        (v, _) => v.clone(),
    };
    (spec.validate)(&value).map_err(|reason| ParamError::Invalid {
        name: name.to_string(),
        reason,
    })?;
    Ok(value)
}

/// Reads the `ros__parameters` for `node_fqn` (e.g. `/fdavar`) from a ROS 2 parameter YAML file.
///
/// Sections apply in file order when their key is `/**`, the node's base name, or its fully
/// qualified name (with or without the leading slash); nested maps flatten to dotted names
/// (`qos: {reliable: true}` → `qos.reliable`).
///
/// # Errors
/// [`ParamError::File`] when the file is unreadable or not a map of maps.
pub fn read_params_file(
    path: &Path,
    node_fqn: &str,
) -> Result<Vec<(String, ParameterValue)>, ParamError> {
    let file_err = |reason: String| ParamError::File {
        path: path.display().to_string(),
        reason,
    };
    let text = std::fs::read_to_string(path).map_err(|e| file_err(e.to_string()))?;
    let doc: serde_yaml_ng::Value =
        serde_yaml_ng::from_str(&text).map_err(|e| file_err(e.to_string()))?;
    let serde_yaml_ng::Value::Mapping(nodes) = doc else {
        return Err(file_err(
            "the top level is not a map of node names".to_string(),
        ));
    };
    let base = node_fqn.rsplit('/').next().unwrap_or(node_fqn);
    let mut out = Vec::new();
    for (key, section) in nodes {
        let key = key.as_str().unwrap_or_default();
        let applies = key == "/**"
            || key == base
            || key == node_fqn
            || key.trim_start_matches('/') == node_fqn.trim_start_matches('/');
        if !applies {
            continue;
        }
        let Some(params) = section.get("ros__parameters") else {
            continue;
        };
        flatten(params, "", &mut out).map_err(file_err)?;
    }
    Ok(out)
}

fn flatten(
    v: &serde_yaml_ng::Value,
    prefix: &str,
    out: &mut Vec<(String, ParameterValue)>,
) -> Result<(), String> {
    let serde_yaml_ng::Value::Mapping(map) = v else {
        return Err(format!("'{prefix}' ros__parameters is not a map"));
    };
    for (k, v) in map {
        let k = k.as_str().ok_or("a parameter name is not a string")?;
        let name = if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        };
        if v.is_mapping() {
            flatten(v, &name, out)?;
        } else {
            let value = yaml_to_param(v).map_err(|r| format!("parameter '{name}' {r}"))?;
            out.push((name, value));
        }
    }
    Ok(())
}

/// The node's parameter values: the defaults, then parameter files, then `-p`, each validated.
///
/// Parameters the table does not know are skipped when they come from a file (a shared
/// `launch_params/*.yaml` may hold keys for other tools) but refused from `-p`.
///
/// # Errors
/// The first [`ParamError`]: startup configuration errors stop the node.
pub fn startup_values(
    files: &[std::path::PathBuf],
    overrides: &[(String, ParameterValue)],
    node_fqn: &str,
) -> Result<BTreeMap<String, ParameterValue>, ParamError> {
    let mut values: BTreeMap<String, ParameterValue> = NODE_PARAMS
        .iter()
        .map(|p| (p.name.to_string(), (p.default)()))
        .collect();
    for file in files {
        for (name, value) in read_params_file(file, node_fqn)? {
            if spec(&name).is_some() {
                values.insert(name.clone(), validate(&name, &value)?);
            }
        }
    }
    for (name, value) in overrides {
        if !is_davar(name) {
            values.insert(name.clone(), validate(name, value)?);
        }
    }
    Ok(values)
}

/// True for a DAVAR parameter (a name of [`crate::params::PARAMS`]).
pub fn is_davar(name: &str) -> bool {
    crate::params::spec(name).is_some()
}

/// A ROS parameter value as a parameter-file value (`None` for arrays and unset).
pub fn davar_value(v: &ParameterValue) -> Option<DavarValue> {
    Some(match v {
        ParameterValue::Boolean(b) => DavarValue::Bool(*b),
        ParameterValue::Integer(i) => DavarValue::Int(*i),
        ParameterValue::Double(x) => DavarValue::Float(*x),
        ParameterValue::String(s) => DavarValue::Str(s.clone()),
        _ => return None,
    })
}

/// A parameter-file value as a ROS parameter value.
pub fn ros_value(v: &DavarValue) -> ParameterValue {
    match v {
        DavarValue::Bool(b) => ParameterValue::Boolean(*b),
        DavarValue::Int(i) => ParameterValue::Integer(*i),
        DavarValue::Float(x) => ParameterValue::Double(*x),
        DavarValue::Str(s) => ParameterValue::String(s.clone()),
    }
}

/// Checks a change of one DAVAR parameter against the current values of all of them.
///
/// Returns the new values and the configuration they make. The configuration must run live (the
/// offline-only `sigma_ref.mode: record` is refused here).
///
/// # Errors
/// The reason, naming the parameter: wrong type, out of range, inconsistent with another
/// parameter, or not runnable live.
pub fn davar_change(
    current: &BTreeMap<String, DavarValue>,
    name: &str,
    value: &ParameterValue,
) -> Result<(BTreeMap<String, DavarValue>, DavarConfig), String> {
    let spec = crate::params::spec(name).ok_or_else(|| format!("unknown parameter '{name}'"))?;
    let value = davar_value(value)
        .ok_or_else(|| format!("parameter '{name}': arrays and unset values are not accepted"))?;
    let value = spec.check(&value).map_err(|e| e.to_string())?;
    let mut next = current.clone();
    next.insert(name.to_string(), value);
    let config = crate::params::config_from_params(&next).map_err(|e| e.to_string())?;
    crate::pipeline::Pipeline::new(config.clone(), &crate::signal::Axis::ALL, None)
        .map_err(|e| format!("parameter '{name}': {e}"))?;
    Ok((next, config))
}

/// [`davar_change`] on a running node: a given `tau0` must also lie within
/// [`crate::params::TAU0_PERIOD_FACTOR`] of the period the stamps show (`measured_period_s`, once
/// known).
///
/// # Errors
/// As [`davar_change`], and the `tau0` refusal of [`crate::params::check_tau0_against_period`].
pub fn davar_change_live(
    current: &BTreeMap<String, DavarValue>,
    name: &str,
    value: &ParameterValue,
    measured_period_s: Option<f64>,
) -> Result<(BTreeMap<String, DavarValue>, DavarConfig), String> {
    let (next, config) = davar_change(current, name, value)?;
    if let (Some(tau0), Some(measured)) = (config.tau0, measured_period_s) {
        crate::params::check_tau0_against_period(tau0, measured).map_err(|e| e.to_string())?;
    }
    Ok((next, config))
}

/// The DAVAR parameter values at startup: defaults, then the files' DAVAR keys, then `-p`.
///
/// # Errors
/// [`ParamError`] for an unreadable file or a value the DAVAR table refuses.
pub fn davar_startup(
    files: &[std::path::PathBuf],
    overrides: &[(String, ParameterValue)],
) -> Result<(BTreeMap<String, DavarValue>, DavarConfig), ParamError> {
    let mut values: BTreeMap<String, DavarValue> = crate::params::PARAMS
        .iter()
        .map(|p| (p.name.to_string(), p.default_value()))
        .collect();
    let invalid = |reason: String| ParamError::Davar { reason };
    for file in files {
        let text = std::fs::read_to_string(file).map_err(|e| ParamError::File {
            path: file.display().to_string(),
            reason: e.to_string(),
        })?;
        let from_file = match crate::params::flatten_ros_params(&text) {
            Ok(map) => map,
            Err(crate::params::ParamsError::NoSection) => continue,
            Err(e) => {
                return Err(ParamError::File {
                    path: file.display().to_string(),
                    reason: e.to_string(),
                })
            }
        };
        for (name, value) in from_file {
            if let Some(spec) = crate::params::spec(&name) {
                let value = spec.check(&value).map_err(|e| ParamError::Davar {
                    reason: e.to_string(),
                })?;
                values.insert(name, value);
            }
        }
    }
    for (name, value) in overrides.iter().filter(|(n, _)| is_davar(n)) {
        let (next, _) =
            davar_change(&values, name, value).map_err(|reason| ParamError::Davar { reason })?;
        values = next;
    }
    let config = crate::params::config_from_params(&values).map_err(|e| invalid(e.to_string()))?;
    crate::pipeline::Pipeline::new(config.clone(), &crate::signal::Axis::ALL, None)
        .map_err(|e| invalid(e.to_string()))?;
    Ok((values, config))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_values_are_refused_with_a_reason() {
        let e = validate("publish_rate_hz", &ParameterValue::Double(-1.0)).unwrap_err();
        assert!(e.to_string().contains("(0, 100]"), "{e}");
        let e = validate("publish_rate_hz", &ParameterValue::String("x".into())).unwrap_err();
        assert!(e.to_string().contains("publish_rate_hz"), "{e}");
        let e = validate("queue_size", &ParameterValue::Integer(0)).unwrap_err();
        assert!(e.to_string().contains("[1, 1000000], got 0"), "{e}");
        let e = validate("record_cap", &ParameterValue::Integer(1 << 19)).unwrap_err();
        assert!(e.to_string().contains("[1048576, 16777216], got 524288"), "{e}");
        let e = validate("no_such", &ParameterValue::Integer(0)).unwrap_err();
        assert!(e.to_string().contains("no_such"), "{e}");
        assert!(validate("model", &ParameterValue::String("N,B,K,sinusoid".into())).is_ok());
        let e = validate("model", &ParameterValue::String("N,warp_drive".into())).unwrap_err();
        assert!(e.to_string().contains("warp_drive"), "{e}");
        // A model without a noise term would publish an infinite fit_error: refused, saying why.
        let e = validate("model.gyro_x", &ParameterValue::String("bias_step".into())).unwrap_err();
        assert!(e.to_string().contains("has no noise term"), "{e}");
        // The diagnosis period: 0 turns it off, negative or non-finite is refused.
        assert!(validate("diagnosis_period_s", &ParameterValue::Double(0.0)).is_ok());
        assert_eq!(
            validate("diagnosis_period_s", &ParameterValue::Integer(5)).unwrap(),
            ParameterValue::Double(5.0)
        );
        let e = validate("diagnosis_period_s", &ParameterValue::Double(-1.0)).unwrap_err();
        assert!(e.to_string().contains("[0, 3600]"), "{e}");
        assert!(validate("diagnosis_period_s", &ParameterValue::Double(f64::NAN)).is_err());
    }

    #[test]
    fn davar_changes_are_checked_against_the_other_davar_values() {
        let (values, _) = davar_startup(&[], &[]).unwrap();
        let (next, config) =
            davar_change(&values, "window.min", &ParameterValue::Integer(201)).unwrap();
        assert_eq!(next["window.min"], DavarValue::Int(201));
        assert_eq!(config.policy.max_window(), 501);
        let e = davar_change(&values, "window.min", &ParameterValue::Integer(900)).unwrap_err();
        assert!(e.contains("window.max"), "{e}");
        let e = davar_change(
            &values,
            "sigma_ref.mode",
            &ParameterValue::String("record".into()),
        )
        .unwrap_err();
        assert!(e.contains("record"), "{e}");
        let e =
            davar_change(&values, "window.min", &ParameterValue::String("x".into())).unwrap_err();
        assert!(e.contains("window.min"), "{e}");
        // -p of a DAVAR name reaches the DAVAR table, not the node's.
        let (v, _) =
            davar_startup(&[], &[("window.step".into(), ParameterValue::Integer(8))]).unwrap();
        assert_eq!(v["window.step"], DavarValue::Int(8));
        let node = startup_values(
            &[],
            &[("window.step".into(), ParameterValue::Integer(8))],
            "/fdavar",
        )
        .unwrap();
        assert!(!node.contains_key("window.step"), "{node:?}");
        assert_eq!(node["queue_size"], (spec("queue_size").unwrap().default)());
    }

    /// Issue 13: the node validates `-p`, parameter files and SetParameters with the DAVAR table's
    /// bounds: values that panicked the spin thread (capacity overflow), aborted (allocation) or
    /// spun forever (τ0 1e-300) are refused with the reason, and the values in force stay.
    #[test]
    fn davar_values_beyond_the_bounds_are_refused_live_and_at_startup() {
        let (values, _) = davar_startup(&[], &[]).unwrap();
        let cases = [
            (
                "window.max",
                ParameterValue::Integer(i64::MAX),
                "[3, 50001]",
            ),
            (
                "window.max",
                ParameterValue::Integer(1_000_000_000),
                "[3, 50001]",
            ),
            (
                "window.max",
                ParameterValue::Integer(10_000_000),
                "[3, 50001]",
            ),
            (
                "window.length",
                ParameterValue::Integer(1_000_000_000),
                "[3, 50001]",
            ),
            ("tau0", ParameterValue::Double(1e-300), "[1e-5, 86400]"),
        ];
        for (name, value, bound) in &cases {
            let e = davar_change(&values, name, value).unwrap_err();
            assert!(
                e.contains(&format!("parameter '{name}'")) && e.contains(bound),
                "{e}"
            );
            let e = davar_startup(&[], &[(name.to_string(), value.clone())]).unwrap_err();
            let text = e.to_string();
            assert!(text.contains(name) && text.contains(bound), "{text}");
        }
        // `taus: all` is refused against the window in force, and the window against the grid.
        let (fixed, _) = davar_change(
            &values,
            "window.policy",
            &ParameterValue::String("fixed".into()),
        )
        .unwrap();
        let (fixed, _) =
            davar_change(&fixed, "window.length", &ParameterValue::Integer(50_001)).unwrap();
        let e = davar_change(&fixed, "taus", &ParameterValue::String("all".into())).unwrap_err();
        assert!(
            e.contains("parameter 'taus'") && e.contains("prefix cells"),
            "{e}"
        );
        // Live, a τ0 is also checked against the period the stamps show.
        let e = davar_change_live(&values, "tau0", &ParameterValue::Double(1e-5), Some(0.03))
            .unwrap_err();
        assert!(
            e.contains("parameter 'tau0' = 1e-5") && e.contains("0.03 s"),
            "{e}"
        );
        davar_change_live(&values, "tau0", &ParameterValue::Double(0.03), Some(0.03)).unwrap();
        davar_change_live(&values, "tau0", &ParameterValue::Double(1e-5), None).unwrap();
        // A parameter file holding them stops the node at startup with the reason.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.yaml");
        std::fs::write(
            &path,
            "fdavar:\n  ros__parameters:\n    window: {policy: fixed, length: 60001}\n",
        )
        .unwrap();
        let e = davar_startup(&[path], &[]).unwrap_err().to_string();
        assert!(
            e.contains("window.length") && e.contains("[3, 50001]"),
            "{e}"
        );
    }

    #[test]
    fn the_shipped_parameter_files_are_valid_for_the_node() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("launch_params");
        let files = [dir.join("default.yaml"), dir.join("node.yaml")];
        let node = startup_values(&files, &[], "/fdavar").unwrap();
        assert_eq!(node["queue_size"], ParameterValue::Integer(10_000));
        let (davar, _) = davar_startup(&files, &[]).unwrap();
        assert_eq!(davar["window.max"], DavarValue::Int(501));
        // Every default of the node table matches node.yaml, so the file documents the defaults.
        for spec in NODE_PARAMS {
            assert_eq!(node[spec.name], (spec.default)(), "{}", spec.name);
        }
    }

    #[test]
    fn integers_are_accepted_for_doubles() {
        assert_eq!(
            validate("publish_rate_hz", &ParameterValue::Integer(2)).unwrap(),
            ParameterValue::Double(2.0)
        );
    }

    #[test]
    fn params_files_apply_by_node_name_and_flatten() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.yaml");
        std::fs::write(
            &path,
            "/**:\n  ros__parameters:\n    publish_rate_hz: 2\nother:\n  ros__parameters:\n    queue_size: 5\n\
             fdavar:\n  ros__parameters:\n    qos:\n      reliable: true\n    unrelated_key: 3\n",
        )
        .unwrap();
        let v = startup_values(
            &[path],
            &[("queue_size".into(), ParameterValue::Integer(7))],
            "/fdavar",
        )
        .unwrap();
        assert_eq!(v["publish_rate_hz"], ParameterValue::Double(2.0));
        assert_eq!(v["qos.reliable"], ParameterValue::Boolean(true));
        assert_eq!(v["queue_size"], ParameterValue::Integer(7));
        assert!(!v.contains_key("unrelated_key"));
    }
}
