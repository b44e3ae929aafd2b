//! `--ros-args` parsing: remaps, namespace, node name, parameters, parameter files, log level.
//!
//! Why: ros2-client 0.12.1 reads no command-line arguments at all, yet `ros2 run` and `ros2 launch`
//! pass node settings this way (`--ros-args -r __ns:=/robot -p publish_rate_hz:=2.0 --params-file
//! f.yaml`). The rules follow rcl's arguments parser: everything between `--ros-args` and `--` (or
//! the end) is a ROS argument; several `--ros-args` blocks may appear; other arguments are left to
//! the program.

use ros2_client::ParameterValue;
use std::path::PathBuf;

/// What `--ros-args` said.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RosArgs {
    /// Topic/service remaps `from:=to` (without `__ns` / `__node`), in command-line order.
    pub remaps: Vec<(String, String)>,
    /// `-r __ns:=/x`: the node namespace.
    pub namespace: Option<String>,
    /// `-r __node:=x` (or `__name:=x`): the node name.
    pub node_name: Option<String>,
    /// `-p name:=value` overrides, values parsed as YAML scalars or sequences.
    pub params: Vec<(String, ParameterValue)>,
    /// `--params-file F`, in order (later files override earlier ones, `-p` overrides all).
    pub params_files: Vec<PathBuf>,
    /// `--log-level [logger:=]level`.
    pub log_level: Option<String>,
}

/// A malformed `--ros-args` argument.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ArgsError {
    /// A flag that needs a value came last.
    #[error("--ros-args: '{flag}' needs a value")]
    MissingValue {
        /// The flag.
        flag: String,
    },
    /// A rule or parameter without `:=`.
    #[error("--ros-args: '{flag} {value}' is not of the form name:=value")]
    NoAssignment {
        /// The flag.
        flag: String,
        /// What followed it.
        value: String,
    },
    /// A flag rcl does not know.
    #[error("--ros-args: unknown argument '{0}' (known: -r/--remap, -p/--param, --params-file, --log-level, -e/--enclave)")]
    Unknown(String),
    /// A `-p` value that YAML cannot read or ROS cannot hold (nested maps, mixed arrays).
    #[error("--ros-args: parameter '{name}': value '{value}' {reason}")]
    BadValue {
        /// Parameter name.
        name: String,
        /// The text given.
        value: String,
        /// Why it is refused.
        reason: String,
    },
}

impl RosArgs {
    /// Splits `args` (without the program name) into ROS arguments and the program's own.
    ///
    /// # Errors
    /// [`ArgsError`] for a malformed ROS argument; nothing is partly applied.
    pub fn parse<I, S>(args: I) -> Result<(RosArgs, Vec<String>), ArgsError>
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        let mut ros = RosArgs::default();
        let mut rest = Vec::new();
        let mut in_ros = false;
        let mut it = args.into_iter().map(Into::into);
        while let Some(arg) = it.next() {
            if arg == "--ros-args" {
                in_ros = true;
                continue;
            }
            if !in_ros {
                rest.push(arg);
                continue;
            }
            let mut value_of = |flag: &str| {
                it.next().ok_or_else(|| ArgsError::MissingValue {
                    flag: flag.to_string(),
                })
            };
            match arg.as_str() {
                "--" => in_ros = false,
                "-r" | "--remap" => {
                    let rule = value_of(&arg)?;
                    let (from, to) = split_assignment(&arg, &rule)?;
                    // `node:from:=to` applies to one node only; fdavar_node holds one node.
                    let from = from.rsplit_once(':').map_or(from, |(_, f)| f);
                    match from {
                        "__ns" => ros.namespace = Some(to.to_string()),
                        "__node" | "__name" => ros.node_name = Some(to.to_string()),
                        _ => ros.remaps.push((from.to_string(), to.to_string())),
                    }
                }
                "-p" | "--param" => {
                    let rule = value_of(&arg)?;
                    let (name, text) = split_assignment(&arg, &rule)?;
                    let value = parse_param_value(name, text)?;
                    ros.params.push((name.to_string(), value));
                }
                "--params-file" => ros.params_files.push(PathBuf::from(value_of(&arg)?)),
                "--log-level" => ros.log_level = Some(value_of(&arg)?),
                "-e" | "--enclave" => {
                    value_of(&arg)?;
                }
                "--enable-rosout-logs"
                | "--disable-rosout-logs"
                | "--enable-stdout-logs"
                | "--disable-stdout-logs"
                | "--enable-external-lib-logs"
                | "--disable-external-lib-logs" => {}
                other => return Err(ArgsError::Unknown(other.to_string())),
            }
        }
        Ok((ros, rest))
    }
}

fn split_assignment<'a>(flag: &str, rule: &'a str) -> Result<(&'a str, &'a str), ArgsError> {
    rule.split_once(":=")
        .filter(|(name, _)| !name.is_empty())
        .ok_or_else(|| ArgsError::NoAssignment {
            flag: flag.to_string(),
            value: rule.to_string(),
        })
}

/// Parses a `-p` value as rcl does: a YAML scalar (bool, integer, double, string) or a flat
/// YAML sequence of one scalar type.
///
/// # Errors
/// [`ArgsError::BadValue`] for maps, nested or mixed sequences, or unreadable YAML.
pub fn parse_param_value(name: &str, text: &str) -> Result<ParameterValue, ArgsError> {
    let yaml: serde_yaml_ng::Value =
        serde_yaml_ng::from_str(text).map_err(|e| ArgsError::BadValue {
            name: name.to_string(),
            value: text.to_string(),
            reason: format!("is not YAML: {e}"),
        })?;
    yaml_to_param(&yaml).map_err(|reason| ArgsError::BadValue {
        name: name.to_string(),
        value: text.to_string(),
        reason,
    })
}

/// Converts a YAML value to a ROS parameter value (scalars and flat homogeneous sequences).
///
/// # Errors
/// A sentence saying why the value cannot be a ROS parameter.
pub fn yaml_to_param(yaml: &serde_yaml_ng::Value) -> Result<ParameterValue, String> {
    use serde_yaml_ng::Value as Y;
    Ok(match yaml {
        Y::Null => ParameterValue::NotSet,
        Y::Bool(b) => ParameterValue::Boolean(*b),
        Y::Number(n) => match n.as_i64() {
            Some(i) => ParameterValue::Integer(i),
            None => ParameterValue::Double(n.as_f64().unwrap_or(f64::NAN)),
        },
        Y::String(s) => ParameterValue::String(s.clone()),
        Y::Sequence(items) => {
            let values = items
                .iter()
                .map(yaml_to_param)
                .collect::<Result<Vec<_>, _>>()?;
            let all = |f: fn(&ParameterValue) -> bool| values.iter().all(f);
            if values.is_empty() {
                ParameterValue::StringArray(Vec::new())
            } else if all(|v| matches!(v, ParameterValue::Boolean(_))) {
                ParameterValue::BooleanArray(
                    values
                        .iter()
                        .filter_map(|v| match v {
                            ParameterValue::Boolean(b) => Some(*b),
                            _ => None,
                        })
                        .collect(),
                )
            } else if all(|v| matches!(v, ParameterValue::Integer(_))) {
                ParameterValue::IntegerArray(
                    values
                        .iter()
                        .filter_map(|v| match v {
                            ParameterValue::Integer(i) => Some(*i),
                            _ => None,
                        })
                        .collect(),
                )
            } else if all(|v| matches!(v, ParameterValue::Double(_) | ParameterValue::Integer(_))) {
                ParameterValue::DoubleArray(
                    values
                        .iter()
                        .filter_map(|v| match v {
                            ParameterValue::Double(d) => Some(*d),
                            ParameterValue::Integer(i) => Some(*i as f64),
                            _ => None,
                        })
                        .collect(),
                )
            } else if all(|v| matches!(v, ParameterValue::String(_))) {
                ParameterValue::StringArray(
                    values
                        .iter()
                        .filter_map(|v| match v {
                            ParameterValue::String(s) => Some(s.clone()),
                            _ => None,
                        })
                        .collect(),
                )
            } else {
                return Err("is a sequence of mixed or nested types".to_string());
            }
        }
        Y::Mapping(_) => {
            return Err("is a map; ROS parameters are scalars or flat arrays".to_string())
        }
        Y::Tagged(t) => yaml_to_param(&t.value)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros_args_are_split_from_program_args() {
        let (ros, rest) = RosArgs::parse([
            "--dump-json",
            "out.json",
            "--ros-args",
            "-r",
            "__ns:=/robot",
            "-r",
            "__node:=watch",
            "-r",
            "imu:=/sensors/imu",
            "-p",
            "publish_rate_hz:=2.5",
            "--params-file",
            "a.yaml",
            "--log-level",
            "debug",
            "--",
            "extra",
        ])
        .unwrap();
        assert_eq!(rest, vec!["--dump-json", "out.json", "extra"]);
        assert_eq!(ros.namespace.as_deref(), Some("/robot"));
        assert_eq!(ros.node_name.as_deref(), Some("watch"));
        assert_eq!(
            ros.remaps,
            vec![("imu".to_string(), "/sensors/imu".to_string())]
        );
        assert_eq!(
            ros.params,
            vec![("publish_rate_hz".to_string(), ParameterValue::Double(2.5))]
        );
        assert_eq!(ros.params_files, vec![PathBuf::from("a.yaml")]);
        assert_eq!(ros.log_level.as_deref(), Some("debug"));
    }

    #[test]
    fn param_values_are_typed_like_rcl() {
        let p = |t| parse_param_value("x", t).unwrap();
        assert_eq!(p("true"), ParameterValue::Boolean(true));
        assert_eq!(p("3"), ParameterValue::Integer(3));
        assert_eq!(p("3.0"), ParameterValue::Double(3.0));
        assert_eq!(p("N,B,K"), ParameterValue::String("N,B,K".into()));
        assert_eq!(p("[1, 2.5]"), ParameterValue::DoubleArray(vec![1.0, 2.5]));
        assert_eq!(
            p("[a, b]"),
            ParameterValue::StringArray(vec!["a".into(), "b".into()])
        );
        assert!(parse_param_value("x", "{a: 1}").is_err());
        assert!(parse_param_value("x", "[1, a]").is_err());
    }

    #[test]
    fn malformed_ros_args_are_refused() {
        assert!(matches!(
            RosArgs::parse(["--ros-args", "-r"]),
            Err(ArgsError::MissingValue { .. })
        ));
        assert!(matches!(
            RosArgs::parse(["--ros-args", "-p", "x"]),
            Err(ArgsError::NoAssignment { .. })
        ));
        assert!(matches!(
            RosArgs::parse(["--ros-args", "--bogus"]),
            Err(ArgsError::Unknown(_))
        ));
        // Without --ros-args nothing is interpreted.
        let (ros, rest) = RosArgs::parse(["-r", "x:=y"]).unwrap();
        assert_eq!(ros, RosArgs::default());
        assert_eq!(rest.len(), 2);
    }
}
