"""Independent reference for tests/allan_python.rs: allantools' Greenhall EDF and deviations.

Reads a JSON request on stdin: {"edf": [[alpha, d, m, n, overlapping, modified], ...],
"phase": [...], "taus": [...]} and prints {"edf": [...], "oadev": [...], "mdev": [...]}.
"""
import json
import sys

import allantools
import numpy as np

req = json.load(sys.stdin)


def greenhall(a, d, m, n, o, mo):
    """None where allantools has no formula (its case 4.1, white PM with few terms)."""
    try:
        return float(allantools.edf_greenhall(alpha=a, d=d, m=m, N=n, overlapping=o, modified=mo))
    except NotImplementedError:
        return None


edf = [greenhall(*case) for case in req["edf"]]
x = np.array(req["phase"])
taus = np.array(req["taus"], dtype=float)
_, oadev, _, _ = allantools.oadev(x, rate=1.0, data_type="phase", taus=taus)
_, mdev, _, _ = allantools.mdev(x, rate=1.0, data_type="phase", taus=taus)
print(json.dumps({"edf": edf, "oadev": list(map(float, oadev)), "mdev": list(map(float, mdev))}))
