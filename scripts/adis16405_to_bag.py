#!/usr/bin/env python3
"""Writes a real ADIS16405 static recording as a rosbag2 MCAP of sensor_msgs/Imu, with PyPI
`rosbags` as the independent writer: gyro deg/s -> rad/s, accel g -> m/s^2, sample k stamped at
1 s + k x 10 ms.

    .venv/bin/python scripts/adis16405_to_bag.py [SAMPLES] [OUT_DIR] [SOURCE]
    cargo run --release -- diagnose /tmp/adis16405

SAMPLES defaults to 360000 (the first hour), OUT_DIR to /tmp/adis16405. SOURCE defaults to run 1
in ../shared/reference/real/ (CC BY-NC-SA, not copied into this repository). The imudata R
package (github.com/SMAC-Group/imudata, the same licence) holds five more runs of the sensor,
data/adis_16405_imu2.rda ... imu6.rda, 10^6 samples each in the same units and column order
(gyro x y z, accel x y z): give one of those files as SOURCE to read it (needs PyPI `rdata`,
`pip install rdata`; it is not in .venv). docs/model.md, "Five more runs", used them as recordings
nobody tuned for.
"""
import gzip
import itertools
import math
import sys
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

RUN_1 = Path(__file__).resolve().parent.parent / ".." / "shared" / "reference" / "real" / "adis16405_static_run1.csv.gz"


def rows_of_csv(path: Path):
    """Run 1 as the shared CSV holds it: index, gyro x y z [deg/s], accel x y z [g]."""
    with gzip.open(path, "rt") as f:
        next(f)  # comment line
        next(f)  # column names
        for line in f:
            yield [float(v) for v in line.split(",")[1:7]]


def rows_of_rda(path: Path):
    """A run of the imudata package: one 10^6 x 6 matrix, gyro x y z [deg/s], accel x y z [g]."""
    try:
        import rdata
    except ImportError:
        sys.exit("reading an .rda needs PyPI `rdata` (pip install rdata)")
    import warnings

    with warnings.catch_warnings():
        # rdata has no constructor for the package's R classes ("imu", "matrix") and says so; the
        # matrix underneath is what is read.
        warnings.simplefilter("ignore", UserWarning)
        converted = rdata.conversion.convert(rdata.parser.parse_file(path))
    (matrix,) = converted.values()
    for row in matrix.values:
        yield [float(v) for v in row[:6]]


def write_imu_bag(out: Path, samples, period_ns: int) -> None:
    """Writes `samples`, (gx, gy, gz, ax, ay, az) in rad/s and m/s^2, as /imu messages of a rosbag2
    MCAP at `out`, sample k stamped at 1 s + k x `period_ns` (no orientation, as REP 145 asks)."""
    import numpy as np

    ts = get_typestore(Stores.ROS2_HUMBLE)
    t = ts.types
    imu, header, stamp = t["sensor_msgs/msg/Imu"], t["std_msgs/msg/Header"], t["builtin_interfaces/msg/Time"]
    quat, vec = t["geometry_msgs/msg/Quaternion"], t["geometry_msgs/msg/Vector3"]
    unknown = np.zeros(9)
    unknown[0] = -1.0  # orientation not provided, as REP 145 asks
    zeros = np.zeros(9)
    with Writer(out, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/imu", imu.__msgtype__, typestore=ts)
        for k, (gx, gy, gz, ax, ay, az) in enumerate(samples):
            ns = 1_000_000_000 + k * period_ns
            msg = imu(
                header=header(stamp=stamp(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="imu"),
                orientation=quat(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=unknown,
                angular_velocity=vec(x=gx, y=gy, z=gz),
                angular_velocity_covariance=zeros,
                linear_acceleration=vec(x=ax, y=ay, z=az),
                linear_acceleration_covariance=zeros,
            )
            w.write(conn, ns, ts.serialize_cdr(msg, imu.__msgtype__))


def main() -> None:
    samples = int(sys.argv[1]) if len(sys.argv) > 1 else 360_000
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path("/tmp/adis16405")
    source = Path(sys.argv[3]) if len(sys.argv) > 3 else RUN_1
    if not source.exists():
        sys.exit(f"{source} not found (run 1 lives in ../shared/reference/real/)")
    rows = rows_of_rda(source) if source.suffix == ".rda" else rows_of_csv(source)
    deg, g = math.pi / 180.0, 9.80665
    si = ((gx * deg, gy * deg, gz * deg, ax * g, ay * g, az * g) for gx, gy, gz, ax, ay, az in rows)
    write_imu_bag(out, itertools.islice(si, samples), 10_000_000)


if __name__ == "__main__":
    main()
