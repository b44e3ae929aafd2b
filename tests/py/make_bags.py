#!/usr/bin/env python3
"""Write rosbag2 test bags with independent tools and dump the values they hold as JSON.

Used by tests/bag_python.rs: every bag here is written by a third-party writer (PyPI `rosbags`,
or PyPI `mcap` + `mcap-ros2-support`), never by fdavar, from values drawn by a seeded generator;
the JSON lists the exact values (floats as IEEE-754 bit patterns, so that nothing is lost in
decimal) for the Rust reader to match bit for bit.

Usage: make_bags.py OUT_DIR  (writes OUT_DIR/<case>/... and OUT_DIR/expected.json)
"""
import json
import random
import sqlite3
import struct
import sys
from pathlib import Path

IMU_MSG = """std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
================================================================================
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
"""

TEMPERATURE_MSG = """std_msgs/Header header
float64 temperature
float64 variance
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""

STRING_MSG = "string data\n"

N_IMU = 400
N_TEMP = 20
START_NS = 1_700_000_000_000_000_000
PERIOD_NS = 10_000_000


def bits(x: float) -> int:
    return struct.unpack("<Q", struct.pack("<d", x))[0]


def draw(seed: int):
    """The messages of one bag: (topic, kind, log_time_ns, fields)."""
    rng = random.Random(seed)
    out = []
    for i in range(N_IMU):
        log = START_NS + i * PERIOD_NS + rng.randrange(0, 2_000_000)
        # Every 50th message has a zero stamp: the reader must fall back to the log time.
        stamp = 0 if i % 50 == 7 else START_NS + i * PERIOD_NS - rng.randrange(0, 500_000)
        gyro = [rng.gauss(0.0, 0.01) for _ in range(3)]
        accel = [rng.gauss(0.0, 0.05) + (9.81 if k == 2 else 0.0) for k in range(3)]
        if i == 3:
            gyro = [5e-324, -0.0, 1.7976931348623157e308]  # subnormal, negative zero, max
        out.append(("/imu/data", "imu", log, dict(stamp=stamp, gyro=gyro, accel=accel)))
    for i in range(N_TEMP):
        log = START_NS + i * 200_000_000 + 1_000
        out.append(("/imu/temperature", "temp", log, dict(stamp=log - 500, celsius=rng.uniform(20, 45))))
    for i in range(5):
        out.append(("/rosout_like", "string", START_NS + i * 1_000_000_000 + 3, dict(data=f"hello {i}")))
    out.sort(key=lambda m: m[2])
    return out


def stamp_dict(ns: int):
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def as_ros_dict(kind: str, f: dict):
    header = {"stamp": stamp_dict(f.get("stamp", 0)), "frame_id": "imu_link"}
    if kind == "imu":
        vec = lambda v: {"x": v[0], "y": v[1], "z": v[2]}
        return {
            "header": header,
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
            "orientation_covariance": [-1.0] + [0.0] * 8,
            "angular_velocity": vec(f["gyro"]),
            "angular_velocity_covariance": [0.0] * 9,
            "linear_acceleration": vec(f["accel"]),
            "linear_acceleration_covariance": [0.0] * 9,
        }
    if kind == "temp":
        return {"header": header, "temperature": f["celsius"], "variance": 0.0}
    return {"data": f["data"]}


def expected(messages):
    imu, temp = [], []
    for topic, kind, log, f in messages:
        if kind == "imu":
            stamp = f["stamp"] or log
            imu.append([log, stamp] + [bits(x) for x in f["gyro"] + f["accel"]])
        elif kind == "temp":
            temp.append([log, f["stamp"] or log, bits(f["celsius"])])
    return {"imu_topic": "/imu/data", "temperature_topic": "/imu/temperature", "imu": imu, "temperature": temp}


# --- rosbags -------------------------------------------------------------------------------------

def write_rosbags(path: Path, messages, version: int, storage: str, file_zstd: bool = False):
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY if version >= 9 else Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    types = {"imu": "sensor_msgs/msg/Imu", "temp": "sensor_msgs/msg/Temperature", "string": "std_msgs/msg/String"}
    w = Writer(path, version=version, storage_plugin=plugin)
    if file_zstd:
        w.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
    with w:
        conns = {}
        for topic, kind, log, f in messages:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, types[kind], typestore=ts)
            msg = to_rosbags(ts, types[kind], as_ros_dict(kind, f))
            w.write(conns[topic], log, ts.serialize_cdr(msg, types[kind]))


def to_rosbags(ts, msgtype: str, d):
    """A rosbags message object from a plain dict, recursively (arrays become numpy arrays)."""
    import numpy as np

    cls = ts.types[msgtype]
    fields = ts.fielddefs[msgtype][1]
    args = []
    for name, desc in fields:
        value = d[name]
        if isinstance(value, dict):
            args.append(to_rosbags(ts, desc[1], value))
        elif isinstance(value, list):
            args.append(np.array(value, dtype=np.float64))
        else:
            args.append(value)
    return cls(*args)


# --- mcap + mcap-ros2-support --------------------------------------------------------------------

def write_mcap(path: Path, messages, compression: str, chunked: bool, summary: bool):
    from mcap.writer import CompressionType, IndexType, Writer
    from mcap_ros2._dynamic import serialize_dynamic

    comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
    schemas = {"imu": ("sensor_msgs/msg/Imu", IMU_MSG), "temp": ("sensor_msgs/msg/Temperature", TEMPERATURE_MSG),
               "string": ("std_msgs/msg/String", STRING_MSG)}
    with open(path, "wb") as f:
        w = Writer(f, compression=comp, use_chunking=chunked, chunk_size=16 * 1024,
                   index_types=IndexType.ALL if summary else IndexType.NONE,
                   repeat_channels=summary, repeat_schemas=summary,
                   use_statistics=summary, use_summary_offsets=summary)
        w.start(profile="ros2", library="make_bags.py")
        channels, encoders = {}, {}
        for topic, kind, log, fields in messages:
            if topic not in channels:
                name, text = schemas[kind]
                sid = w.register_schema(name=name, encoding="ros2msg", data=text.encode())
                channels[topic] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
                encoders[topic] = serialize_dynamic(name, text)[name]
            w.add_message(channel_id=channels[topic], log_time=log, publish_time=log,
                          data=encoders[topic](as_ros_dict(kind, fields)))
        w.finish()


def write_split(path: Path, messages, parts: int, with_metadata: bool):
    """A bag split into `parts` MCAP files `<name>_0.mcap`, `_1`, … (as `ros2 bag record
    --max-bag-size` leaves it), with a hand-written metadata.yaml of version 5 or none at all."""
    path.mkdir()
    names = [f"{path.name}_{k}.mcap" for k in range(parts)]
    per = -(-len(messages) // parts)
    for k, name in enumerate(names):
        write_mcap(path / name, messages[k * per:(k + 1) * per], "zstd", True, True)
    if with_metadata:
        files = "".join(f"    - {n}\n" for n in names)
        (path / "metadata.yaml").write_text(
            "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n"
            f"  relative_file_paths:\n{files}  compression_format: ''\n  compression_mode: ''\n")


def write_sqlite_by_hand(path: Path, messages, layout: str):
    """A .db3 in an older rosbag2 layout that `rosbags` (which writes schema 4) does not produce:
    `none` = before the `schema` table existed (Foxy), `humble` = schema 3. Layouts from rosbag2's
    sqlite3 storage plugin history; no metadata.yaml (a bare directory, as after a crash). CDR
    bodies come from mcap-ros2-support's encoder."""
    from mcap_ros2._dynamic import serialize_dynamic

    path.mkdir()
    db = sqlite3.connect(path / f"{path.name}_0.db3")
    qos = ", offered_qos_profiles TEXT NOT NULL" if layout == "humble" else ""
    db.executescript(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
        f"serialization_format TEXT NOT NULL{qos});"
        "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, "
        "timestamp INTEGER NOT NULL, data BLOB NOT NULL);")
    if layout == "humble":
        db.executescript(
            "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);"
            "INSERT INTO schema VALUES (3, 'humble');"
            "CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL, "
            "metadata TEXT NOT NULL);")
    schemas = {"imu": ("sensor_msgs/msg/Imu", IMU_MSG), "temp": ("sensor_msgs/msg/Temperature", TEMPERATURE_MSG),
               "string": ("std_msgs/msg/String", STRING_MSG)}
    ids = {}
    # Insert in reverse time order: the reader must order by timestamp, not by row id.
    for topic, kind, log, fields in reversed(messages):
        name, text = schemas[kind]
        if topic not in ids:
            ids[topic] = len(ids) + 1
            row = (ids[topic], topic, name, "cdr") + (("- history: 3\n  depth: 5",) if qos else ())
            db.execute(f"INSERT INTO topics VALUES ({', '.join('?' * len(row))})", row)
        data = serialize_dynamic(name, text)[name](as_ros_dict(kind, fields))
        db.execute("INSERT INTO messages(topic_id, timestamp, data) VALUES (?, ?, ?)", (ids[topic], log, data))
    db.commit()
    db.close()


def main():
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    cases = {}

    def case(name, seed, writer):
        messages = draw(seed)
        writer(out / name, messages)
        cases[name] = expected(messages)

    case("rosbags_mcap_v8", 1, lambda p, m: write_rosbags(p, m, 8, "mcap"))
    case("rosbags_mcap_v9", 2, lambda p, m: write_rosbags(p, m, 9, "mcap"))
    case("rosbags_sqlite_v8", 3, lambda p, m: write_rosbags(p, m, 8, "sqlite3"))
    case("rosbags_sqlite_v9", 4, lambda p, m: write_rosbags(p, m, 9, "sqlite3"))
    case("mcap_zstd.mcap", 5, lambda p, m: write_mcap(p, m, "zstd", True, True))
    case("mcap_lz4.mcap", 6, lambda p, m: write_mcap(p, m, "lz4", True, True))
    case("mcap_unchunked.mcap", 7, lambda p, m: write_mcap(p, m, "none", False, True))
    case("mcap_no_summary.mcap", 8, lambda p, m: write_mcap(p, m, "zstd", True, False))
    case("rosbags_mcap_v9_file_zstd", 11, lambda p, m: write_rosbags(p, m, 9, "mcap", file_zstd=True))
    case("split_with_metadata", 12, lambda p, m: write_split(p, m, 3, True))
    case("split_without_metadata", 13, lambda p, m: write_split(p, m, 3, False))
    case("sqlite_no_schema_table", 9, lambda p, m: write_sqlite_by_hand(p, m, "none"))
    case("sqlite_humble_schema3", 10, lambda p, m: write_sqlite_by_hand(p, m, "humble"))
    (out / "expected.json").write_text(json.dumps(cases))


if __name__ == "__main__":
    main()
