//! The serde mirrors of fdavar_msgs agree with the `.msg` files of the interface package `msg/`
//! (field names, types and order), and survive a CDR round trip; the standard mirrors have the
//! sizes rosbag2 recordings show (notes/rosbag2.md: Imu with frame "imu_link" is 324 bytes).

use fdavar::msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
use fdavar::msgs::fdavar_msgs::{
    AxisState, Coefficient, DavarPoint, Fields, Suggestion, TauInterval, TimeSpan,
};
use fdavar::msgs::rosgraph_msgs::Clock;
use fdavar::msgs::sensor_msgs::{Imu, Temperature};
use fdavar::msgs::std_msgs::Header;
use fdavar::msgs::RosMessage;
use serde::Serialize;
use std::fmt::Debug;

/// The fields of a `.msg` text: (type, name), comments, blank lines and constants left out.
fn parse_msg(text: &str) -> Vec<(String, String)> {
    text.lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty() && !l.contains('='))
        .map(|l| {
            let mut parts = l.split_whitespace();
            let ty = parts.next().unwrap().to_string();
            let name = parts
                .next()
                .unwrap_or_else(|| panic!("no field name in '{l}'"))
                .to_string();
            (ty, name)
        })
        .collect()
}

/// The field names of a struct in serde (= declaration = CDR) order.
fn serde_field_names<M: Serialize>(msg: &M) -> Vec<String> {
    struct Keys(Vec<String>);
    impl<'de> serde::Deserialize<'de> for Keys {
        fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Keys, D::Error> {
            struct V;
            impl<'de> serde::de::Visitor<'de> for V {
                type Value = Keys;
                fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                    f.write_str("a struct")
                }
                fn visit_map<A: serde::de::MapAccess<'de>>(
                    self,
                    mut map: A,
                ) -> Result<Keys, A::Error> {
                    let mut keys = Vec::new();
                    while let Some((k, _)) = map.next_entry::<String, serde::de::IgnoredAny>()? {
                        keys.push(k);
                    }
                    Ok(Keys(keys))
                }
            }
            d.deserialize_map(V)
        }
    }
    // serde_json writes struct fields in declaration order; read the keys back in that order.
    let json = serde_json::to_string(msg).unwrap();
    serde_json::from_str::<Keys>(&json).unwrap().0
}

fn check_against_msg_file<M: RosMessage + Fields + Default>() {
    let def = M::DEF;
    assert_eq!(def.package(), "fdavar_msgs");
    let path = format!(
        "{}/msg/msg/{}.msg",
        env!("CARGO_MANIFEST_DIR"),
        def.type_name()
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    assert_eq!(def.text, text, "{} MsgDef text is not {path}", def.name);
    let from_file = parse_msg(&text);
    let from_rust: Vec<(String, String)> = M::FIELDS
        .iter()
        .map(|(t, n)| (t.to_string(), n.to_string()))
        .collect();
    assert_eq!(
        from_rust, from_file,
        "{} field list differs from {path}",
        def.name
    );
    let names: Vec<String> = from_file.into_iter().map(|(_, n)| n).collect();
    assert_eq!(
        serde_field_names(&M::default()),
        names,
        "{} struct fields differ from {path}",
        def.name
    );
}

#[test]
fn mirrors_match_the_msg_files_field_by_field() {
    check_against_msg_file::<AxisState>();
    check_against_msg_file::<DavarPoint>();
    check_against_msg_file::<Coefficient>();
    check_against_msg_file::<TauInterval>();
    check_against_msg_file::<TimeSpan>();
    check_against_msg_file::<Suggestion>();
}

#[test]
fn every_msg_file_has_a_mirror_and_is_listed_in_cmake() {
    let dir = format!("{}/msg/msg", env!("CARGO_MANIFEST_DIR"));
    let mirrored = [
        "AxisState",
        "Coefficient",
        "DavarPoint",
        "Suggestion",
        "TauInterval",
        "TimeSpan",
    ];
    let cmake =
        std::fs::read_to_string(format!("{}/msg/CMakeLists.txt", env!("CARGO_MANIFEST_DIR")))
            .unwrap();
    let mut found: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| {
            e.unwrap()
                .file_name()
                .to_string_lossy()
                .trim_end_matches(".msg")
                .to_string()
        })
        .collect();
    found.sort();
    assert_eq!(found, mirrored);
    for name in mirrored {
        assert!(
            cmake.contains(&format!("\"msg/{name}.msg\"")),
            "{name} missing from CMakeLists.txt"
        );
    }
}

/// Encodes and decodes `msg` as a ROS 2 payload; returns its size with the 4-byte header.
fn round_trip<M: RosMessage + PartialEq + Debug>(msg: &M) -> usize {
    let bytes = fdavar::msgs::encode(msg).unwrap();
    assert_eq!(&fdavar::msgs::decode::<M>(&bytes).unwrap(), msg);
    bytes.len()
}

fn header() -> Header {
    Header {
        stamp: fdavar::msgs::builtin_interfaces::Time::from_ns(1_700_000_000_123_456_789).unwrap(),
        frame_id: "imu_link".into(),
    }
}

#[test]
fn axis_state_survives_a_cdr_round_trip() {
    let coefficient = Coefficient {
        effect: "white".into(),
        name: "n".into(),
        value: 1.5e-4,
        sigma: 2.0e-6,
        unit: "rad/s/sqrt(Hz)".into(),
    };
    let state = AxisState {
        header: header(),
        axis: "gyro_z".into(),
        analysis_time_s: 12.5,
        window_length: 171,
        f_value: 2.75,
        f_reference: 3.3,
        sample_period_s: 0.03,
        row: (1..=3)
            .map(|m| DavarPoint {
                tau_s: 0.03 * f64::from(m),
                avar: 1e-6 / f64::from(m),
                avar_low: 0.8e-6 / f64::from(m),
                avar_high: 1.3e-6 / f64::from(m),
                edf: 40.0 / f64::from(m),
            })
            .collect(),
        model: vec!["white".into(), "sinusoid".into()],
        coefficients: vec![coefficient.clone()],
        fit_error: 1.1,
        span_fit_error: 3.4,
        rate_excess_kurtosis: 116.6,
        failing_tau: vec![TauInterval {
            low_s: 0.3,
            high_s: 1.2,
        }],
        failing_spans: vec![TimeSpan {
            start_s: 600.0,
            end_s: 900.0,
        }],
        suggestions: vec![Suggestion {
            effect: "sinusoid".into(),
            params: vec![coefficient],
            fit_error_after: 0.9,
            span_fit_error_after: 1.2,
            explanation: "a periodic disturbance".into(),
            given: vec!["bandwidth".into()],
        }],
        diagnosed_messages: 3590,
        diagnosed_until_s: 107.7,
        samples: 3600,
        drops: 2,
        gaps: 1,
    };
    let size = round_trip(&state);
    assert!(
        size < 4096,
        "AxisState should stay small (KBs), got {size} bytes"
    );
    round_trip(&AxisState::default());
}

#[test]
fn standard_mirrors_have_the_recorded_cdr_sizes() {
    let sample = fdavar::signal::ImuSample {
        stamp_ns: 1_700_000_000_123_456_789,
        gyro: [0.1, 0.2, 0.3],
        accel: [0.0, 0.0, 9.81],
    };
    let imu = Imu::from_sample(&sample, "imu_link").unwrap();
    // 324 bytes including the 4-byte encapsulation header (notes/rosbag2.md).
    assert_eq!(round_trip(&imu), 324);
    let temperature = Temperature {
        header: header(),
        temperature: 21.5,
        variance: 0.0,
    };
    assert_eq!(round_trip(&temperature), 44);
    // The 4-byte header, then int32 sec and uint32 nanosec (rosgraph_msgs/msg/Clock).
    assert_eq!(
        round_trip(&Clock {
            clock: fdavar::msgs::builtin_interfaces::Time { sec: 5, nanosec: 7 },
        }),
        12
    );
    round_trip(&DiagnosticArray {
        header: header(),
        status: vec![DiagnosticStatus {
            level: 1,
            name: "fdavar: gyro_x".into(),
            message: "model fails".into(),
            hardware_id: "imu_link".into(),
            values: vec![KeyValue::new("window_length", 171)],
        }],
    });
}
