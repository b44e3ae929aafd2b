//! The committed recordings in bags/ are exactly what their specs give today: if the simulator
//! changes, this fails until they are regenerated with
//! `fdavar simulate bags/specs/NAME.yaml --out bags/NAME --force`.

use fdavar::bag::{BagMessage, BagReader};
use fdavar::sim::{simulate, SimSpec, Truth};
use std::path::Path;

fn check(name: &str) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("bags");
    let text = std::fs::read_to_string(root.join("specs").join(format!("{name}.yaml"))).unwrap();
    let expected = simulate(&SimSpec::from_yaml(&text).unwrap()).unwrap();
    let bag = root.join(name);
    let truth: Truth =
        serde_json::from_str(&std::fs::read_to_string(bag.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth, expected.truth, "{name}: truth.json is stale");
    let reader = BagReader::open(&bag).unwrap();
    let temperature = expected
        .truth
        .temperature
        .as_ref()
        .map(|_| truth.topics.temperature.as_str());
    let (mut imu, mut temps) = (Vec::new(), Vec::new());
    for m in reader.messages(&truth.topics.imu, temperature).unwrap() {
        match m.unwrap() {
            BagMessage::Imu { sample, .. } => imu.push(sample),
            BagMessage::Temperature { sample, .. } => temps.push(sample),
        }
    }
    assert!(imu == expected.imu, "{name}: IMU messages are stale");
    assert!(
        temps == expected.temperature,
        "{name}: temperature messages are stale"
    );
}

#[test]
fn clean_is_current() {
    check("clean");
}

#[test]
fn seed_2016_is_current() {
    check("seed_2016");
}

#[test]
fn effects_is_current() {
    check("effects");
}
