//! The ROS 2 node: the only module that names ros2-client types.
//!
//! ros2-client 0.12.1 gives DDS entities and parameter services but no command-line handling, no
//! name resolution that works in the root namespace, and a `/clock` subscription of the wrong type.
//! This module adds what the node needs on top, by ROS rules:
//! - [`args`]: `--ros-args` (`-r`, `__ns`, `__node`, `-p`, `--params-file`, `--log-level`);
//! - [`names`]: relative / private / absolute names and remaps, always absolute for ros2-client;
//! - [`params`]: the node's parameter table, validators, parameter files;
//! - [`engine`]: the library's analysis path ([`crate::analysis`]) behind the node's engine trait,
//!   its answers as messages;
//! - [`monitor`]: input checks, counters, levels and the messages (no DDS, tested alone);
//! - [`node`]: context (ROS_DOMAIN_ID), subscriptions, the bounded queue, the analysis and
//!   diagnosis threads,
//!   publishers of `/diagnostics` and `~/<axis>/state`, `/clock` as `rosgraph_msgs/msg/Clock`;
//! - [`play`]: `fdavar play`, a recording replayed over DDS at its recorded pace;
//! - [`dump`]: the `dump_json` file, decimated and size-capped.

pub mod args;
pub mod dump;
pub mod engine;
pub mod monitor;
pub mod names;
pub mod node;
pub mod params;
pub mod play;

pub use node::{run, NodeConfig, NodeError};

/// The engine the node drives for `config`: the library's analysis path, live.
///
/// # Errors
/// [`NodeError::Param`] when the model or the DAVAR settings cannot run live.
pub fn default_engine(
    config: &NodeConfig,
) -> Result<Option<Box<dyn monitor::RowEngine>>, NodeError> {
    let invalid = |name: &str, reason: String| {
        NodeError::Param(params::ParamError::Invalid {
            name: name.to_string(),
            reason,
        })
    };
    // The parameters were validated: each model parameter is a string (axis overrides may be
    // empty), read as the node's other strings are.
    let global = engine::model_spec(&config.text("model")).map_err(|e| invalid("model", e))?;
    let mut overrides: [Option<crate::model::ModelSpec>; 6] = Default::default();
    for axis in crate::signal::Axis::ALL {
        let name = params::axis_model_param(axis);
        let spec = config.text(&name);
        if !spec.trim().is_empty() {
            overrides[axis.index()] =
                Some(engine::model_spec(&spec).map_err(|e| invalid(&name, e))?);
        }
    }
    let engine = engine::AnalysisEngine::new(config.davar_config.clone(), global, overrides, record_cap(config))
        .map_err(|e| invalid("(DAVAR settings)", e.to_string()))?;
    Ok(Some(Box::new(engine)))
}

/// The `record_cap` parameter: values per axis the whole-run record keeps before halving (as
/// `fdavar diagnose --record-cap`). Validated with the other parameters, so always in range.
pub fn record_cap(config: &NodeConfig) -> usize {
    usize::try_from(config.int("record_cap")).unwrap_or(usize::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn record_cap_is_read_from_the_parameters_and_checked_against_its_range() {
        let cap = |args: &[&str]| NodeConfig::from_args(args.iter().copied(), None).map(|(c, _)| record_cap(&c));
        assert_eq!(cap(&["fdavar_node"]).unwrap(), 1 << 20);
        assert_eq!(cap(&["fdavar_node", "--ros-args", "-p", "record_cap:=2097152"]).unwrap(), 1 << 21);
        for bad in ["1048575", "16777217", "1.5e6"] {
            let e = cap(&["fdavar_node", "--ros-args", "-p", &format!("record_cap:={bad}")]).unwrap_err();
            assert!(e.to_string().contains("record_cap"), "{bad}: {e}");
        }
    }
}
