//! `fdavar_node`: the ROS 2 node.
fn main() {
    eprintln!("fdavar_node: not built yet");
    std::process::exit(1);
}
