#!/usr/bin/env python3
"""Read a bag written by fdavar with independent readers and dump what they decoded as JSON.

Used by tests/bag_python.rs: `rosbags` (AnyReader: metadata.yaml, MCAP, CDR via its own type
store) and `mcap-ros2-support` (decoding from the schema text fdavar stored). Floats are dumped
as IEEE-754 bit patterns so the comparison is exact.

Usage: read_bag.py BAG_DIR  (prints one JSON object)
"""
import json
import struct
import sys
from pathlib import Path


def bits(x: float) -> int:
    return struct.unpack("<Q", struct.pack("<d", float(x)))[0]


def row(log, msg, kind):
    head = [log, msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id]
    if kind == "sensor_msgs/msg/Imu":
        v = [msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z,
             msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z,
             msg.orientation.w, msg.orientation_covariance[0]]
    else:
        v = [msg.temperature, msg.variance]
    return head + [bits(x) for x in v]


def with_rosbags(path: Path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out = {"topics": {}, "messages": {}, "counts": {}}
    with AnyReader([path], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        for c in reader.connections:
            out["topics"][c.topic] = c.msgtype
            out["counts"][c.topic] = c.msgcount
        for c, log, raw in reader.messages():
            msg = reader.deserialize(raw, c.msgtype)
            out["messages"].setdefault(c.topic, []).append(row(log, msg, c.msgtype))
        out["qos"] = {c.topic: len(c.ext.offered_qos_profiles) for c in reader.connections}
    return out


def with_mcap_ros2(path: Path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    (mcap_file,) = sorted(path.glob("*.mcap"))
    out = {"topics": {}, "messages": {}, "profile": None, "metadata": []}
    with open(mcap_file, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        out["profile"] = reader.get_header().profile
        for schema, channel, message, msg in reader.iter_decoded_messages():
            out["topics"][channel.topic] = schema.name
            out["messages"].setdefault(channel.topic, []).append(row(message.log_time, msg, schema.name))
        out["metadata"] = [m.name for m in reader.iter_metadata()]
    return out


def main():
    path = Path(sys.argv[1])
    print(json.dumps({"rosbags": with_rosbags(path), "mcap_ros2": with_mcap_ros2(path)}))


if __name__ == "__main__":
    main()
