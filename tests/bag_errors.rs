//! Every bad input the bag layer can meet is an error that names the place, never a panic.

use fdavar::bag::{BagError, BagMessage, BagReader, BagWriter, ChunkCompression, WriterOptions};
use fdavar::msgs::MsgError;
use fdavar::signal::ImuSample;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn sample(i: i64) -> ImuSample {
    ImuSample {
        stamp_ns: 1_000_000_000 + i * 10_000_000,
        gyro: [0.1, 0.2, 0.3],
        accel: [0.0, 0.0, 9.81],
    }
}

/// A finished fdavar bag of `n` Imu messages on `/imu`.
fn write_bag(dir: &Path, name: &str, compression: ChunkCompression, n: i64) -> PathBuf {
    let path = dir.join(name);
    let mut w = BagWriter::create_with(
        &path,
        &WriterOptions {
            compression,
            overwrite: false,
        },
    )
    .unwrap();
    for i in 0..n {
        w.write_imu("/imu", sample(i).stamp_ns + 500, &sample(i), "imu_link")
            .unwrap();
    }
    w.finish().unwrap();
    path
}

fn mcap_file(bag: &Path) -> PathBuf {
    let name = bag.file_name().unwrap().to_string_lossy();
    bag.join(format!("{name}_0.mcap"))
}

#[test]
fn missing_path() {
    let err = BagReader::open("/nonexistent/fdavar/bag").unwrap_err();
    assert!(matches!(err, BagError::NotFound { .. }), "{err:?}");
    assert!(err.to_string().contains("/nonexistent/fdavar/bag"));
}

#[test]
fn directory_without_a_bag() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "hello").unwrap();
    let err = BagReader::open(dir.path()).unwrap_err();
    assert!(matches!(err, BagError::NotABag { .. }), "{err:?}");
    assert!(err.to_string().contains("not a rosbag2 bag"), "{err}");
}

#[test]
fn file_that_is_not_a_bag() {
    let dir = tempfile::tempdir().unwrap();
    let txt = dir.path().join("data.csv");
    std::fs::write(&txt, "1,2,3\n").unwrap();
    assert!(matches!(
        BagReader::open(&txt).unwrap_err(),
        BagError::UnknownStorage { .. }
    ));
    let fake = dir.path().join("fake.mcap");
    std::fs::write(&fake, b"definitely not mcap").unwrap();
    let err = BagReader::open(&fake).unwrap_err();
    assert!(matches!(err, BagError::UnknownStorage { .. }), "{err:?}");
    assert!(err.to_string().contains("MCAP magic"), "{err}");
}

#[test]
fn bag_without_imu_lists_its_topics() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("temp_only");
    let mut w = BagWriter::create(&path).unwrap();
    let t = fdavar::signal::TemperatureSample {
        stamp_ns: 5,
        celsius: 30.0,
    };
    w.write_temperature("/thermo", 5, &t, "imu_link").unwrap();
    w.finish().unwrap();
    let err = BagReader::open(&path).unwrap().imu_topic(None).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{} holds no sensor_msgs/msg/Imu; topics: /thermo [sensor_msgs/msg/Temperature] (1 msgs)",
            path.display()
        )
    );
}

#[test]
fn several_imu_topics_need_a_choice() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two_imus");
    let mut w = BagWriter::create(&path).unwrap();
    for i in 0..3 {
        w.write_imu("/imu_a", 10 + i, &sample(i), "a").unwrap();
        w.write_imu("/imu_b", 11 + i, &sample(i), "b").unwrap();
    }
    w.finish().unwrap();
    let bag = BagReader::open(&path).unwrap();
    let err = bag.imu_topic(None).unwrap_err();
    assert!(matches!(err, BagError::AmbiguousTopic { .. }), "{err:?}");
    assert!(err.to_string().contains("/imu_a, /imu_b"), "{err}");
    assert_eq!(bag.imu_topic(Some("/imu_b")).unwrap().name, "/imu_b");
    let err = bag.imu_topic(Some("/imu_c")).unwrap_err();
    assert!(
        matches!(err, BagError::NoSuchTopic { ref topic, .. } if topic == "/imu_c"),
        "{err:?}"
    );
    // Only the chosen topic is streamed.
    let n = bag.messages("/imu_b", None).unwrap().count();
    assert_eq!(n, 3);
}

#[test]
fn truncated_mcap_is_reported_not_panicked() {
    let dir = tempfile::tempdir().unwrap();
    for compression in [ChunkCompression::Zstd, ChunkCompression::None] {
        let bag = write_bag(
            dir.path(),
            &format!("full_{compression:?}"),
            compression,
            2000,
        );
        let bytes = std::fs::read(mcap_file(&bag)).unwrap();
        // Cut at many places: inside the header, a chunk, the summary, the footer.
        for keep in [
            9,
            100,
            bytes.len() / 3,
            bytes.len() / 2,
            bytes.len() - 40,
            bytes.len() - 1,
        ] {
            let cut = dir.path().join(format!("cut_{compression:?}_{keep}.mcap"));
            std::fs::write(&cut, &bytes[..keep]).unwrap();
            let result = BagReader::open(&cut).and_then(|b| {
                b.messages("/imu", None)?
                    .collect::<Result<Vec<_>, _>>()
                    .map(|_| ())
            });
            let err = result.expect_err("a truncated file must not read cleanly");
            assert!(
                matches!(err, BagError::Truncated { .. }),
                "cut at {keep}: {err:?}"
            );
            assert!(
                err.to_string().contains(&cut.display().to_string()),
                "{err}"
            );
        }
    }
}

#[test]
fn corrupt_sqlite_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.db3");
    std::fs::write(&path, vec![0x5a; 4096]).unwrap();
    let err = BagReader::open(&path).unwrap_err();
    assert!(matches!(err, BagError::CorruptSqlite { .. }), "{err:?}");
    assert!(err.to_string().contains("broken.db3"), "{err}");
}

#[test]
fn unknown_chunk_compression() {
    let dir = tempfile::tempdir().unwrap();
    let bag = write_bag(dir.path(), "lz4", ChunkCompression::Lz4, 100);
    // Rename the compression in every chunk record and chunk index ("lz4" → "xz9", same length).
    let mut bytes = std::fs::read(mcap_file(&bag)).unwrap();
    let from = b"\x03\x00\x00\x00lz4";
    let mut renamed = 0;
    for i in 0..bytes.len() - from.len() {
        if &bytes[i..i + from.len()] == from {
            bytes[i + 4..i + 7].copy_from_slice(b"xz9");
            renamed += 1;
        }
    }
    assert!(renamed >= 1);
    let file = dir.path().join("xz9.mcap");
    std::fs::write(&file, bytes).unwrap();
    let result = BagReader::open(&file).and_then(|b| {
        b.messages("/imu", None)?
            .collect::<Result<Vec<_>, _>>()
            .map(|_| ())
    });
    let err = result.unwrap_err();
    assert!(
        matches!(err, BagError::UnknownCompression { ref compression, .. } if compression == "xz9"),
        "{err:?}"
    );
}

#[test]
fn unknown_file_compression_in_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let bag = write_bag(dir.path(), "b", ChunkCompression::Zstd, 10);
    let meta = bag.join("metadata.yaml");
    let text = std::fs::read_to_string(&meta).unwrap();
    let text = text
        .replace("compression_format: ''", "compression_format: bz2")
        .replace("compression_mode: ''", "compression_mode: FILE");
    std::fs::write(&meta, text).unwrap();
    let err = BagReader::open(&bag).unwrap_err();
    assert!(
        matches!(err, BagError::UnknownCompression { .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("bz2"), "{err}");
}

#[test]
fn malformed_cdr_names_topic_and_log_time() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad_cdr.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(std::io::BufWriter::new(
            std::fs::File::create(&file).unwrap(),
        ))
        .unwrap();
    let schema = w
        .add_schema(
            "sensor_msgs/msg/Imu",
            "ros2msg",
            fdavar::msgs::sensor_msgs::IMU.schema_text().as_bytes(),
        )
        .unwrap();
    let channel = w
        .add_channel(schema, "/imu", "cdr", &BTreeMap::new())
        .unwrap();
    let good = fdavar::msgs::encode(
        &fdavar::msgs::sensor_msgs::Imu::from_sample(&sample(0), "x").unwrap(),
    )
    .unwrap();
    for (seq, (log, data)) in [
        (100u64, good.clone()),
        (200, good[..50].to_vec()),
        (300, good),
    ]
    .into_iter()
    .enumerate()
    {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: seq as u32,
            log_time: log,
            publish_time: log,
        };
        w.write_to_known_channel(&header, &data).unwrap();
    }
    w.finish().unwrap();
    drop(w);
    let bag = BagReader::open(&file).unwrap();
    let items: Vec<_> = bag.messages("/imu", None).unwrap().collect();
    assert_eq!(
        items.len(),
        3,
        "the stream goes on after a malformed message"
    );
    assert!(matches!(
        items[0],
        Ok(BagMessage::Imu {
            log_time_ns: 100,
            ..
        })
    ));
    let err = items[1].as_ref().unwrap_err();
    assert!(
        matches!(err, BagError::Malformed { topic, log_time_ns: 200, source: MsgError::Cdr { .. }, .. } if topic == "/imu"),
        "{err:?}"
    );
    assert!(err.to_string().contains("/imu at log time 200 ns"), "{err}");
    assert!(matches!(
        items[2],
        Ok(BagMessage::Imu {
            log_time_ns: 300,
            ..
        })
    ));
}

#[test]
fn writer_refuses_to_overwrite_unless_asked() {
    let dir = tempfile::tempdir().unwrap();
    let bag = write_bag(dir.path(), "once", ChunkCompression::Zstd, 5);
    let err = BagWriter::create(&bag).unwrap_err();
    assert!(matches!(err, BagError::AlreadyExists { .. }), "{err:?}");
    let opts = WriterOptions {
        overwrite: true,
        ..WriterOptions::default()
    };
    let mut w = BagWriter::create_with(&bag, &opts).unwrap();
    w.write_imu("/imu", 1, &sample(0), "x").unwrap();
    w.finish().unwrap();
    assert_eq!(
        BagReader::open(&bag)
            .unwrap()
            .imu_topic(None)
            .unwrap()
            .message_count,
        1
    );
    // Overwrite never removes something that is not a bag.
    let precious = dir.path().join("precious");
    std::fs::create_dir(&precious).unwrap();
    std::fs::write(precious.join("thesis.tex"), "…").unwrap();
    assert!(matches!(
        BagWriter::create_with(&precious, &opts).unwrap_err(),
        BagError::AlreadyExists { .. }
    ));
    assert!(precious.join("thesis.tex").exists());
}

#[test]
fn failed_or_finished_writer_refuses_further_writes() {
    let dir = tempfile::tempdir().unwrap();
    let mut w = BagWriter::create(dir.path().join("w")).unwrap();
    w.write_imu("/imu", 1, &sample(0), "x").unwrap();
    let err = w.write_imu("/imu", -5, &sample(1), "x").unwrap_err();
    assert!(matches!(err, BagError::Unwritable { .. }), "{err:?}");
    let err = w.write_imu("/imu", 10, &sample(2), "x").unwrap_err();
    assert!(
        matches!(
            err,
            BagError::WriterClosed {
                state: "failed",
                ..
            }
        ),
        "{err:?}"
    );
    assert!(w.finish().is_err());

    let mut w = BagWriter::create(dir.path().join("v")).unwrap();
    let beyond_2038 = ImuSample {
        stamp_ns: i64::MAX,
        ..sample(0)
    };
    let err = w.write_imu("/imu", 1, &beyond_2038, "x").unwrap_err();
    assert!(err.to_string().contains("int32"), "{err}");

    let mut w = BagWriter::create(dir.path().join("f")).unwrap();
    w.finish().unwrap();
    let err = w.write_imu("/imu", 1, &sample(0), "x").unwrap_err();
    assert!(
        matches!(
            err,
            BagError::WriterClosed {
                state: "finished",
                ..
            }
        ),
        "{err:?}"
    );
}

#[test]
fn topic_type_conflict() {
    let dir = tempfile::tempdir().unwrap();
    let mut w = BagWriter::create(dir.path().join("c")).unwrap();
    w.write_imu("/x", 1, &sample(0), "x").unwrap();
    let t = fdavar::signal::TemperatureSample {
        stamp_ns: 5,
        celsius: 30.0,
    };
    let err = w.write_temperature("/x", 2, &t, "x").unwrap_err();
    assert!(matches!(err, BagError::TopicTypeConflict { .. }), "{err:?}");
}

#[test]
fn empty_bag_opens_and_says_it_holds_no_imu() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty_bag");
    BagWriter::create(&path).unwrap().finish().unwrap();
    let bag = BagReader::open(&path).unwrap();
    assert!(bag.topics().is_empty());
    assert_eq!(bag.time_span_ns(), None);
    let err = bag.imu_topic(None).unwrap_err().to_string();
    assert!(
        err.ends_with("holds no sensor_msgs/msg/Imu; topics: none"),
        "{err}"
    );
}

#[test]
fn absurd_record_lengths_are_errors_not_aborts() {
    let dir = tempfile::tempdir().unwrap();
    let bag = write_bag(dir.path(), "len", ChunkCompression::None, 50);
    let bytes = std::fs::read(mcap_file(&bag)).unwrap();
    // The header record follows the 8-byte magic: opcode at 8, u64 length at 9..17.
    for len in [1u64 << 50, u64::MAX, 1 << 33] {
        let mut b = bytes.clone();
        b[9..17].copy_from_slice(&len.to_le_bytes());
        let file = dir.path().join(format!("len_{len}.mcap"));
        std::fs::write(&file, b).unwrap();
        let result = BagReader::open(&file).and_then(|r| {
            r.messages("/imu", None)?
                .collect::<Result<Vec<_>, _>>()
                .map(|_| ())
        });
        let err = result.unwrap_err();
        assert!(err.to_string().contains("len_"), "{err}");
    }
}

/// Seeded random damage anywhere in a file (a flipped bit on disk, a bad copy) gives an error or
/// wrong-but-decoded values, never a panic or an abort.
#[test]
fn random_damage_never_panics() {
    use rand::{Rng, SeedableRng};
    let dir = tempfile::tempdir().unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for compression in [
        ChunkCompression::None,
        ChunkCompression::Zstd,
        ChunkCompression::Lz4,
    ] {
        let bag = write_bag(dir.path(), &format!("d_{compression:?}"), compression, 300);
        let bytes = std::fs::read(mcap_file(&bag)).unwrap();
        for k in 0..150 {
            let mut b = bytes.clone();
            for _ in 0..rng.random_range(1..5) {
                let i = rng.random_range(0..b.len());
                b[i] = rng.random();
            }
            let file = dir.path().join(format!("damaged_{compression:?}_{k}.mcap"));
            std::fs::write(&file, &b).unwrap();
            if let Ok(reader) = BagReader::open(&file) {
                if let Ok(topic) = reader.imu_topic(None) {
                    let name = topic.name.clone();
                    if let Ok(messages) = reader.messages(&name, None) {
                        messages.for_each(drop);
                    }
                }
            }
        }
    }
}

/// Issue 13: the MCAP summary CRC was not checked, so a damaged statistics record was believed
/// (`fdavar info` reported 9.4·10¹⁸ messages). A summary whose CRC fails is ignored: the file is
/// scanned (chunk CRCs checked) and the true count is reported.
#[test]
fn a_summary_whose_crc_fails_is_not_believed() {
    let dir = tempfile::tempdir().unwrap();
    let bag = write_bag(dir.path(), "crc", ChunkCompression::None, 120);
    let file = mcap_file(&bag);
    let mut b = std::fs::read(&file).unwrap();
    // Footer: opcode, length, summary_start, summary_offset_start, CRC; then the 8-byte magic.
    let footer = b.len() - 37;
    let u64_at = |b: &[u8], i: usize| u64::from_le_bytes(b[i..i + 8].try_into().unwrap());
    assert_ne!(
        u32::from_le_bytes(b[footer + 25..footer + 29].try_into().unwrap()),
        0,
        "no CRC written"
    );
    // The Statistics record (opcode 0x0B) in the summary section; its per-channel counts map
    // starts 42 bytes into the body (u32 byte length, then u16 channel id and u64 count).
    let mut at = u64_at(&b, footer + 9) as usize;
    while b[at] != 0x0B {
        at += 9 + u64_at(&b, at + 1) as usize;
    }
    let count_at = at + 9 + 42 + 4 + 2;
    assert_eq!(u64_at(&b, count_at), 120);
    b[count_at..count_at + 8].copy_from_slice(&9_400_000_000_000_000_000u64.to_le_bytes());
    std::fs::write(&file, &b).unwrap();
    let reader = BagReader::open(&bag).unwrap();
    assert_eq!(reader.imu_topic(None).unwrap().message_count, 120);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["info", bag.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("messages:  120\n"), "{text}");
}
