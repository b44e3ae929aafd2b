#!/usr/bin/env python3
"""Writes the real ADIS16405 static recording (../shared/reference/real/, CC BY-NC-SA, not copied
into this repository) as a rosbag2 MCAP of sensor_msgs/Imu, with PyPI `rosbags` as the independent
writer: gyro deg/s -> rad/s, accel g -> m/s^2, sample k stamped at 1 s + k x 10 ms.

    .venv/bin/python scripts/adis16405_to_bag.py [SAMPLES] [OUT_DIR]   # default 360000, /tmp/adis16405
    cargo run --release -- diagnose /tmp/adis16405
"""
import gzip
import math
import sys
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

SOURCE = Path(__file__).resolve().parent.parent / ".." / "shared" / "reference" / "real" / "adis16405_static_run1.csv.gz"


def main() -> None:
    samples = int(sys.argv[1]) if len(sys.argv) > 1 else 360_000
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path("/tmp/adis16405")
    if not SOURCE.exists():
        sys.exit(f"{SOURCE} not found (the recording lives in ../shared/reference/real/)")
    ts = get_typestore(Stores.ROS2_HUMBLE)
    t = ts.types
    imu, header, stamp = t["sensor_msgs/msg/Imu"], t["std_msgs/msg/Header"], t["builtin_interfaces/msg/Time"]
    quat, vec = t["geometry_msgs/msg/Quaternion"], t["geometry_msgs/msg/Vector3"]
    import numpy as np

    unknown = np.zeros(9)
    unknown[0] = -1.0  # orientation not provided, as REP 145 asks
    zeros = np.zeros(9)
    deg, g = math.pi / 180.0, 9.80665
    with Writer(out, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/imu", imu.__msgtype__, typestore=ts)
        with gzip.open(SOURCE, "rt") as f:
            next(f)  # comment line
            next(f)  # column names
            for k, line in enumerate(f):
                if k >= samples:
                    break
                p = line.split(",")
                ns = 1_000_000_000 + k * 10_000_000
                msg = imu(
                    header=header(stamp=stamp(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="imu"),
                    orientation=quat(x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=unknown,
                    angular_velocity=vec(x=float(p[1]) * deg, y=float(p[2]) * deg, z=float(p[3]) * deg),
                    angular_velocity_covariance=zeros,
                    linear_acceleration=vec(x=float(p[4]) * g, y=float(p[5]) * g, z=float(p[6]) * g),
                    linear_acceleration_covariance=zeros,
                )
                w.write(conn, ns, ts.serialize_cdr(msg, imu.__msgtype__))


if __name__ == "__main__":
    main()
