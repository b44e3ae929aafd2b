//! `fdavar_node`: the ROS 2 node (thin: parse `--ros-args`, build the node, run).
//!
//! Exit codes: 0 when stopped; 1 on a startup configuration error (bad `--ros-args`, names,
//! parameter values, `ROS_DOMAIN_ID`, or DDS refusing to start). Bad messages never stop it.

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
             (e.g. fdavar_node --ros-args -p publish_rate_hz:=2.0 -r imu:=/sensors/imu)"
        );
        return ExitCode::from(1);
    }
    let result = fdavar::ros::default_engine(&config)
        .and_then(|engine| fdavar::ros::run(&config, engine, Arc::new(AtomicBool::new(false))));
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("fdavar_node: error: {e}");
            ExitCode::from(1)
        }
    }
}
