//! `fdavar_node`: the ROS 2 node (thin: parse `--ros-args`, build the node, run until a signal).
//!
//! Exit codes: 0 when stopped by SIGINT or SIGTERM (after flushing its outputs) and for `--help`;
//! 1 on a startup configuration error (bad `--ros-args`, names, parameter values, `ROS_DOMAIN_ID`,
//! or DDS refusing to start), or when a second signal cuts the shutdown short. Bad messages never
//! stop it.

use std::process::ExitCode;

#[cfg(not(feature = "ros"))]
fn main() -> ExitCode {
    eprintln!("fdavar_node: error: built without the `ros` feature; rebuild with default features");
    ExitCode::from(1)
}

#[cfg(feature = "ros")]
fn main() -> ExitCode {
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    // Before anything else: help starts no DDS and reads no configuration.
    if std::env::args().skip(1).any(|a| a == "--help" || a == "-h") {
        print!("{}", usage());
        return ExitCode::SUCCESS;
    }
    let domain = std::env::var("ROS_DOMAIN_ID").ok();
    let (config, rest) =
        match fdavar::ros::NodeConfig::from_args(std::env::args().skip(1), domain.as_deref()) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("fdavar_node: error: {e}");
                return ExitCode::from(1);
            }
        };
    if let Some(arg) = rest.first() {
        eprintln!(
            "fdavar_node: error: unexpected argument '{arg}'; node settings go after --ros-args \
             (e.g. fdavar_node --ros-args -p publish_rate_hz:=2.0 -r imu:=/sensors/imu); see --help"
        );
        return ExitCode::from(1);
    }
    fdavar::analysis::return_large_buffers_to_kernel();
    let stop = Arc::new(AtomicBool::new(false));
    if let Err(e) = stop_on_signals(&stop) {
        eprintln!("fdavar_node: error: installing the SIGINT/SIGTERM handlers: {e}");
        return ExitCode::from(1);
    }
    let result = fdavar::ros::default_engine(&config)
        .and_then(|engine| fdavar::ros::run(&config, engine, stop));
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("fdavar_node: error: {e}");
            ExitCode::from(1)
        }
    }
}

/// Makes SIGINT and SIGTERM set `stop` (the node then drains its queue, flushes `dump_json` and
/// returns); a second one while stopping exits 1 at once.
///
/// Installing a handler also replaces an inherited "ignore": a shell without job control starts
/// background commands with SIGINT ignored, and `kill -INT` must still stop the node.
#[cfg(feature = "ros")]
fn stop_on_signals(stop: &std::sync::Arc<std::sync::atomic::AtomicBool>) -> std::io::Result<()> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    for signal in [SIGINT, SIGTERM] {
        // Order matters: the conditional exit runs first, so only a signal that finds the flag
        // already set (the second one) exits.
        signal_hook::flag::register_conditional_shutdown(signal, 1, std::sync::Arc::clone(stop))?;
        signal_hook::flag::register(signal, std::sync::Arc::clone(stop))?;
    }
    Ok(())
}

/// The `--help` text: topics, ROS arguments, every parameter with its type, default and unit (read
/// from the parameter tables, so it cannot drift from what the node declares), signals, exit codes.
#[cfg(feature = "ros")]
fn usage() -> String {
    use std::fmt::Write as _;

    let mut out = String::from(
        "fdavar_node: live adaptive-window dynamic Allan variance (F-DAVAR) of IMU noise, a ROS 2 \
         node\n\
         (pure-Rust DDS: no ROS installation needed; interoperates with Fast DDS / rclpy / rclcpp).\n\n\
         Usage: fdavar_node [-h|--help] [--ros-args [-r FROM:=TO]... [-p NAME:=VALUE]...\n\
         \x20                  [--params-file FILE]... [--log-level LEVEL] [--]]\n\n\
         Subscribes (names relative to the node's namespace, remappable):\n\
         \x20 imu              sensor_msgs/msg/Imu; best effort (matches any publisher), keep last\n\
         \x20                  qos.depth; reliable with qos.reliable:=true\n\
         \x20 temperature      sensor_msgs/msg/Temperature, with temperature:=true\n\
         \x20 /clock           rosgraph_msgs/msg/Clock, with use_sim_time:=true (node time = last /clock)\n\
         Publishes (at publish_rate_hz):\n\
         \x20 /diagnostics     diagnostic_msgs/msg/DiagnosticArray, one status per axis (reliable)\n\
         \x20 ~/<axis>/state   fdavar_msgs/msg/AxisState, axis = gyro_x gyro_y gyro_z accel_x accel_y\n\
         \x20                  accel_z: window length, F, F~, the DAVAR row with CIs, coefficients,\n\
         \x20                  fit_error, failing_tau, suggestions\n\
         \x20 /rosout, /parameter_events, and the parameter services ~/list_parameters,\n\
         \x20 ~/get_parameters, ~/set_parameters, ... (what `ros2 param` calls)\n\n\
         ROS arguments (between --ros-args and -- or the end):\n\
         \x20 -r FROM:=TO, -r NODE:FROM:=TO   remap a topic name\n\
         \x20 -r __ns:=/NS, -r __node:=NAME   namespace (default /), node name (default fdavar)\n\
         \x20 -p NAME:=VALUE                  set a parameter (value read as YAML, like rcl)\n\
         \x20 --params-file FILE              YAML with fdavar: / /fdavar: / /**: ros__parameters:\n\
         \x20 --log-level LEVEL               debug, info (default), warn, error, fatal\n\
         \x20 -e ENCLAVE and the --enable/--disable-*-logs flags are accepted and ignored.\n\
         Environment: ROS_DOMAIN_ID, the DDS domain, 0..=232 (default 0).\n\n\
         Node parameters (name, type, default, when a change applies):\n",
    );
    for spec in fdavar::ros::params::NODE_PARAMS {
        let (kind, default) = fdavar::ros::params::type_and_text(&(spec.default)());
        let live = if spec.live { "live" } else { "startup" };
        let _ = writeln!(
            out,
            "  {} ({kind}, default {default}, {live})\n      {}",
            spec.name, spec.doc
        );
    }
    out.push_str(
        "\nDAVAR parameters (all live; the table `fdavar davar --params` and\n\
         launch_params/default.yaml use; a change is checked against the others and restarts the\n\
         rows half a window later):\n",
    );
    for spec in fdavar::params::PARAMS {
        let kind = match spec.kind {
            fdavar::params::ParamType::Int => "int",
            fdavar::params::ParamType::Float => "double",
            fdavar::params::ParamType::Str => "string",
        };
        let _ = writeln!(
            out,
            "  {} ({kind}, default {})\n      {}",
            spec.name, spec.default, spec.description
        );
    }
    out.push_str(
        "\nSignals: SIGINT or SIGTERM stops the node: it analyses the samples already queued,\n\
         flushes dump_json (the last line complete) and exits 0. A second signal exits 1 at once.\n\
         \nExit codes: 0 stopped by SIGINT/SIGTERM, or --help; 1 startup configuration error (bad\n\
         --ros-args, name, parameter value, ROS_DOMAIN_ID, DDS refusing to start), or a second\n\
         signal during the shutdown. Bad messages never stop the node: they are counted on\n\
         /diagnostics.\n",
    );
    out
}
