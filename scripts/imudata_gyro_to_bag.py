#!/usr/bin/env python3
"""Writes a one-gyro recording of the imudata R package as a rosbag2 MCAP of sensor_msgs/Imu
(PyPI `rosbags` as the writer): the recording on gyro_x [rad/s], seeded white noise of the same
level on gyro_y and gyro_z, and 9.81 m/s^2 plus white noise on the accel axes, so that the bag is
a whole IMU; read only gyro_x (`--axis gyro_x`). Sample k is stamped at 1 s + k / RATE.

    python scripts/imudata_gyro_to_bag.py SOURCE.rda [OUT_DIR] [RATE_HZ]
    cargo run --release -- diagnose OUT_DIR --axis gyro_x

SOURCE: e.g. data/cont.imu1.rda of github.com/SMAC-Group/imudata (an XSens MTi-G x gyro, 5e5
samples at 100 Hz, rad/s; CC BY-NC-SA, not copied into this repository). Needs PyPI `rdata`
(`pip install rdata`; not in .venv). docs/model.md, "Heavy tails", used it as a sensor nobody
tuned for. OUT_DIR defaults to /tmp/mtig, RATE_HZ to 100.
"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from adis16405_to_bag import rows_of_rda, write_imu_bag  # noqa: E402  (the same reader and writer)


def main() -> None:
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    source = Path(sys.argv[1])
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path("/tmp/mtig")
    rate = float(sys.argv[3]) if len(sys.argv) > 3 else 100.0
    gyro = np.array([row[0] for row in rows_of_rda(source)])
    sigma = np.std(np.diff(gyro)) / np.sqrt(2.0)
    noise = np.random.default_rng(7).normal(size=(len(gyro), 5))
    samples = (
        (float(g), sigma * n[0], sigma * n[1], 0.01 * n[2], 0.01 * n[3], 9.81 + 0.01 * n[4])
        for g, n in zip(gyro, noise)
    )
    write_imu_bag(out, samples, round(1e9 / rate))


if __name__ == "__main__":
    main()
