//! `launch/fdavar.launch.xml` (issue 12): what it names exists, colcon installs what it finds, and
//! the command line launch_ros makes of it starts the node on the topic given.
//!
//! launch_ros is not on PyPI (no `ros2 launch` here), so the test reads the XML itself
//! (quick-xml) and applies the substitutions the file uses — `$(var NAME)` and
//! `$(find-pkg-share fdavar)`, the package's share directory, into which cargo-ament-build copies
//! the `install_to_share` directories of Cargo.toml — then builds the ROS arguments launch_ros
//! passes a `<node>`: `-r __node:=NAME`, `--params-file F` per `<param from>`, `-r FROM:=TO` per
//! `<remap>`.

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};
use std::collections::BTreeMap;
use std::path::Path;

const LAUNCH: &str = "launch/fdavar.launch.xml";

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// One element: its tag and attributes, in document order.
#[derive(Debug)]
struct Element {
    tag: String,
    attrs: BTreeMap<String, String>,
    /// Text content (for `<name>` of package.xml).
    text: String,
}

fn elements(path: &str) -> Vec<Element> {
    let xml = std::fs::read_to_string(root().join(path)).unwrap();
    let mut reader = Reader::from_str(&xml);
    let mut out: Vec<Element> = Vec::new();
    let element = |e: &BytesStart| Element {
        tag: e.name().as_ref().to_string(),
        attrs: e
            .attributes()
            .map(|a| {
                let a = a.unwrap();
                let key = a.key.as_ref().to_string();
                (key, a.normalized_value(XmlVersion::Implicit1_0).unwrap().into_owned())
            })
            .collect(),
        text: String::new(),
    };
    loop {
        match reader.read_event().unwrap_or_else(|e| panic!("{path}: {e}")) {
            Event::Start(e) | Event::Empty(e) => out.push(element(&e)),
            Event::Text(t) => {
                if let Some(last) = out.last_mut() {
                    last.text.push_str(t.xml10_content().trim());
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    out
}

/// `$(var NAME)` from `args`, `$(find-pkg-share fdavar)` = `share` (anything else is an error).
fn substitute(value: &str, args: &BTreeMap<String, String>, share: &Path) -> String {
    let mut s = value.to_string();
    while let Some(start) = s.find("$(var ") {
        let end = start + s[start..].find(')').unwrap();
        let name = &s[start + 6..end];
        let v = args.get(name).unwrap_or_else(|| panic!("{LAUNCH}: no arg {name}")).clone();
        s.replace_range(start..=end, &v);
    }
    // An argument's default may itself hold a substitution: resolve it after the variables.
    let s = s.replace("$(find-pkg-share fdavar)", share.to_str().unwrap());
    assert!(!s.contains("$("), "{LAUNCH}: a substitution this test does not know: {s}");
    s
}

/// The ROS arguments launch_ros gives the file's one node, for `imu:=…`, with the share
/// directory at `share`.
fn node_command(share: &Path, imu: &str) -> (String, Vec<String>) {
    let elements = elements(LAUNCH);
    let mut args: BTreeMap<String, String> =
        elements.iter().filter(|e| e.tag == "arg").map(|e| (e.attrs["name"].clone(), e.attrs["default"].clone())).collect();
    args.insert("imu".into(), imu.into());
    let nodes: Vec<&Element> = elements.iter().filter(|e| e.tag == "node").collect();
    assert_eq!(nodes.len(), 1, "{LAUNCH}: one node");
    let node = &nodes[0].attrs;
    let mut ros_args = vec!["--ros-args".to_string(), "-r".into(), format!("__node:={}", node["name"])];
    for e in &elements {
        match e.tag.as_str() {
            "param" => ros_args.extend(["--params-file".into(), substitute(&e.attrs["from"], &args, share)]),
            "remap" => ros_args.extend([
                "-r".into(),
                format!("{}:={}", e.attrs["from"], substitute(&e.attrs["to"], &args, share)),
            ]),
            _ => {}
        }
    }
    (node["exec"].clone(), ros_args)
}

#[test]
fn the_launch_file_names_what_the_package_builds_and_installs() {
    let launch = elements(LAUNCH);
    assert_eq!(launch[0].tag, "launch");
    let node = &launch.iter().find(|e| e.tag == "node").unwrap().attrs;
    // pkg = package.xml's name; exec = a [[bin]] of Cargo.toml (what colcon installs in lib/fdavar).
    let package = elements("package.xml");
    assert_eq!(package.iter().find(|e| e.tag == "name").unwrap().text, node["pkg"]);
    let cargo = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    assert!(cargo.contains(&format!("[[bin]]\nname = \"{}\"", node["exec"])), "no [[bin]] {}", node["exec"]);
    // The node name is the section the parameter files configure.
    assert_eq!(node["name"], "fdavar");
    // The imu argument remaps the node's `imu` subscription.
    let imu = launch.iter().find(|e| e.tag == "arg" && e.attrs["name"] == "imu").expect("an imu arg");
    // Its default is the identity remap: without imu:=…, the node watches the relative `imu`.
    assert_eq!(imu.attrs["default"], "imu");
    assert!(imu.attrs["description"].contains("sensor_msgs/msg/Imu"), "{:?}", imu.attrs);
    let remap = &launch.iter().find(|e| e.tag == "remap").unwrap().attrs;
    assert_eq!((remap["from"].as_str(), remap["to"].as_str()), ("imu", "$(var imu)"));
    // colcon-ros-cargo copies launch/ and launch_params/ into share/fdavar/.
    assert!(cargo.contains("[package.metadata.ros]\ninstall_to_share = [\"launch\", \"launch_params\"]"), "Cargo.toml");
    // Every file the defaults name exists there (the repository root stands for share/fdavar/) and
    // configures the node by its name.
    let (_, ros_args) = node_command(root(), "/my/imu");
    let files: Vec<&String> = ros_args.iter().skip_while(|a| *a != "--params-file").skip(1).step_by(2).take(2).collect();
    assert_eq!(files.len(), 2, "{ros_args:?}");
    for f in files {
        let text = std::fs::read_to_string(f).unwrap_or_else(|e| panic!("{f}: {e}"));
        let yaml: serde_yaml_ng::Value = serde_yaml_ng::from_str(&text).unwrap();
        assert!(yaml["fdavar"]["ros__parameters"].is_mapping(), "{f}");
        assert!(Path::new(f).starts_with(root().join("launch_params")), "{f}");
    }
}

/// The node started with the launch file's ROS arguments accepts them (no startup error, exit 1)
/// and subscribes to the topic given as `imu:=`. Needs DDS on localhost, like tests/ros_interop.rs.
#[cfg(feature = "ros")]
#[test]
fn the_node_starts_on_the_imu_topic_given() {
    // Here, not at the top: without the `ros` feature this test, their only user, is not built.
    use std::io::{BufRead, BufReader};
    let (exec, ros_args) = node_command(root(), "/my/imu");
    assert_eq!(exec, "fdavar_node");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_fdavar_node"))
        .args(&ros_args)
        .env("ROS_DOMAIN_ID", "83")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    // The first line says what the node subscribed to; a startup error would end the stream.
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut seen = Vec::new();
    let found = loop {
        match rx.recv_timeout(std::time::Duration::from_secs(20)) {
            Ok(line) if line.contains("imu '") => break Some(line),
            Ok(line) => seen.push(line),
            Err(_) => break None,
        }
    };
    let status = child.try_wait().unwrap();
    let _ = child.kill();
    let _ = child.wait();
    let line = found.unwrap_or_else(|| panic!("fdavar_node {ros_args:?}: no subscription line; status {status:?}; stderr: {seen:?}"));
    assert!(line.contains("fdavar_node /fdavar") && line.contains("imu '/my/imu'"), "{line}");
    assert!(status.is_none(), "fdavar_node exited: {status:?}");
}

#[test]
fn docs_show_the_launch_line() {
    let line = "ros2 launch fdavar fdavar.launch.xml imu:=/my/imu";
    for doc in ["README.md", "docs/ros.md"] {
        let text = std::fs::read_to_string(root().join(doc)).unwrap();
        assert!(text.contains(line), "{doc} lacks `{line}`");
    }
}
