//! The ROS 2 node: the only module that names ros2-client types.
//!
//! ros2-client 0.12.1 gives DDS entities and parameter services but no command-line handling, no
//! name resolution that works in the root namespace, and a `/clock` subscription of the wrong type.
//! This module adds what the node needs on top, by ROS rules:
//! - [`args`]: `--ros-args` (`-r`, `__ns`, `__node`, `-p`, `--params-file`, `--log-level`);
//! - [`names`]: relative / private / absolute names and remaps, always absolute for ros2-client;
//! - [`params`]: the node's parameter table, validators, parameter files;
//! - [`engine`]: the offline F-DAVAR pipeline behind the node's engine trait;
//! - [`monitor`]: input checks, counters, levels and the messages (no DDS, tested alone);
//! - [`node`]: context (ROS_DOMAIN_ID), subscriptions, the bounded queue, the analysis thread,
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
pub mod temperature;

pub use node::{run, NodeConfig, NodeError};

/// The F-DAVAR engine the node drives for `config`: the offline pipeline, live.
///
/// # Errors
/// [`NodeError::Param`] when the DAVAR settings cannot run live.
pub fn default_engine(
    config: &NodeConfig,
) -> Result<Option<Box<dyn monitor::RowEngine>>, NodeError> {
    let model = match config.params.get("model") {
        Some(ros2_client::ParameterValue::String(spec)) => engine::model_kinds(spec),
        _ => Err("model is not a string".to_string()),
    }
    .map_err(|reason| {
        NodeError::Param(params::ParamError::Invalid {
            name: "model".to_string(),
            reason,
        })
    })?;
    let engine = engine::PipelineEngine::new(config.davar_config.clone(), model).map_err(|e| {
        NodeError::Param(params::ParamError::Invalid {
            name: "(DAVAR settings)".to_string(),
            reason: e.to_string(),
        })
    })?;
    Ok(Some(Box::new(engine)))
}
