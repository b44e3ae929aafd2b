#!/usr/bin/env python3
"""Decode every message of a results MCAP (`fdavar diagnose --mcap OUT`) with mcap-ros2-support.

Used by tests/results_mcap.rs. `mcap_ros2.decoder` builds its decoders from the `ros2msg` schema
text fdavar stored (nested types after `====` / `MSG: pkg/Name` lines), not from any ROS install,
so a message that decodes here is one Foxglove and PlotJuggler read too. Every field of every
message is dumped; non-finite floats as the strings "NaN", "inf", "-inf" (JSON has no such number).

Usage: read_results.py FILE.mcap  (prints one JSON object)
"""
import json
import math
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def plain(v):
    """A decoded message as JSON values, every field by name."""
    if isinstance(v, float):
        if math.isnan(v):
            return "NaN"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return v
    if isinstance(v, (bool, int, str)) or v is None:
        return v
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if isinstance(v, (bytes, bytearray)):
        return list(v)
    slots = getattr(v, "__slots__", None)
    if slots is None:
        raise TypeError(f"cannot dump {type(v)}")
    return {name: plain(getattr(v, name)) for name in slots}


def main(path):
    out = {"profile": None, "channels": {}, "messages": {}, "metadata": []}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        out["profile"] = reader.get_header().profile
        summary = reader.get_summary()
        for cid, ch in summary.channels.items():
            schema = summary.schemas[ch.schema_id]
            out["channels"][ch.topic] = {
                "schema": schema.name,
                "schema_encoding": schema.encoding,
                "message_encoding": ch.message_encoding,
                "count": summary.statistics.channel_message_counts.get(cid, 0),
            }
        for schema, channel, message, msg in reader.iter_decoded_messages(log_time_order=False):
            m = plain(msg)
            m["log_time"] = message.log_time
            out["messages"].setdefault(channel.topic, []).append(m)
        out["metadata"] = [m.name for m in reader.iter_metadata()]
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1])
