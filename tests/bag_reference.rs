//! Real rosbag2-written bags (tests/data/rosbag2, from the rosbag2 project) open, list their
//! topics with the counts their metadata.yaml states, and say clearly that they hold no Imu.

use fdavar::bag::{BagError, BagReader, Storage};
use std::path::PathBuf;

fn reference(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/rosbag2")
        .join(name)
}

/// (name, type, count) of each topic, sorted by name.
fn topics(bag: &BagReader) -> Vec<(String, String, u64)> {
    let mut t: Vec<_> = bag
        .topics()
        .iter()
        .map(|t| (t.name.clone(), t.type_name.clone(), t.message_count))
        .collect();
    t.sort();
    t
}

fn owned(v: &[(&str, &str, u64)]) -> Vec<(String, String, u64)> {
    v.iter()
        .map(|(a, b, c)| (a.to_string(), b.to_string(), *c))
        .collect()
}

#[test]
fn mcap_talker_metadata_v4() {
    let bag = BagReader::open(reference("mcap_talker")).unwrap();
    assert_eq!(
        bag.files().map(|(_, s)| s).collect::<Vec<_>>(),
        [Storage::Mcap]
    );
    // metadata.yaml: /topic 10, /rosout 10, /parameter_events 0 (a channel without messages).
    let got = topics(&bag);
    let want = owned(&[
        ("/parameter_events", "rcl_interfaces/msg/ParameterEvent", 0),
        ("/rosout", "rcl_interfaces/msg/Log", 10),
        ("/topic", "std_msgs/msg/String", 10),
    ]);
    // Some rosbag2 versions register no channel for a topic that never got a message.
    let without_empty: Vec<_> = want.iter().filter(|t| t.2 > 0).cloned().collect();
    assert!(got == want || got == without_empty, "{got:?}");
    // metadata.yaml: starting 1585866235112411371, duration 4531096768.
    assert_eq!(
        bag.time_span_ns(),
        Some((
            1_585_866_235_112_411_371,
            1_585_866_235_112_411_371 + 4_531_096_768
        ))
    );
}

#[test]
fn sqlite3_talker_metadata_v4() {
    let bag = BagReader::open(reference("sqlite3_talker")).unwrap();
    assert_eq!(
        bag.files().map(|(_, s)| s).collect::<Vec<_>>(),
        [Storage::Sqlite3]
    );
    assert_eq!(
        topics(&bag),
        owned(&[
            ("/parameter_events", "rcl_interfaces/msg/ParameterEvent", 0),
            ("/rosout", "rcl_interfaces/msg/Log", 10),
            ("/topic", "std_msgs/msg/String", 10),
        ])
    );
    assert_eq!(
        bag.time_span_ns(),
        Some((
            1_585_866_235_112_411_371,
            1_585_866_235_112_411_371 + 4_531_096_768
        ))
    );
}

#[test]
fn mcap_cdr_test_metadata_v7() {
    let bag = BagReader::open(reference("mcap_cdr_test")).unwrap();
    assert_eq!(
        topics(&bag),
        owned(&[
            ("/array_topic", "test_msgs/msg/Arrays", 4),
            ("/test_topic", "test_msgs/msg/BasicTypes", 3)
        ])
    );
}

#[test]
fn mcap_with_service_events_metadata_v8() {
    let bag = BagReader::open(reference("mcap_bag_with_topics_and_service_events")).unwrap();
    let total: u64 = bag.topics().iter().map(|t| t.message_count).sum();
    assert_eq!(total, 10, "metadata.yaml message_count");
    let got = topics(&bag);
    for (name, count) in [
        ("/test_service1/_service_event", 4),
        ("/test_topic1", 1),
        ("/test_topic2", 1),
    ] {
        assert!(
            got.iter().any(|t| t.0 == name && t.2 == count),
            "{name} in {got:?}"
        );
    }
}

#[test]
fn every_reference_bag_says_it_holds_no_imu() {
    for name in [
        "mcap_talker",
        "sqlite3_talker",
        "mcap_cdr_test",
        "mcap_bag_with_topics_and_service_events",
    ] {
        for path in [reference(name)] {
            let bag = BagReader::open(&path).unwrap();
            let err = bag.imu_topic(None).unwrap_err();
            assert!(matches!(err, BagError::NoTopicOfType { .. }), "{err:?}");
            let text = err.to_string();
            assert!(
                text.contains("holds no sensor_msgs/msg/Imu; topics: "),
                "{text}"
            );
            for t in bag.topics() {
                assert!(text.contains(&t.name), "{text} misses {}", t.name);
            }
            assert_eq!(bag.temperature_topic(None).unwrap(), None);
        }
    }
}

#[test]
fn bare_storage_files_open_without_metadata() {
    let bag = BagReader::open(reference("mcap_talker/talker.mcap")).unwrap();
    assert!(bag
        .topics()
        .iter()
        .any(|t| t.name == "/topic" && t.message_count == 10));
    let bag = BagReader::open(reference("sqlite3_talker/talker.db3")).unwrap();
    assert!(bag
        .topics()
        .iter()
        .any(|t| t.name == "/topic" && t.message_count == 10));
}
