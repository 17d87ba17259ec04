"""Streaming octave Allan variance (gyrodrift.stability.streaming, the C++ core) against the
offline non-overlapped Allan deviation: the numpy reference from the definition and
allantools.adev at the same octave taus on the same samples (double), and the float state
against the double state after 10 h of simulated gyro data at 400 Hz. Prints the markdown
tables of docs/validation/streaming-allan.md.

    PYTHONPATH=python:build/dev-NAME/py python3 scripts/streaming_allan_validation.py [--seed 4]
"""

from __future__ import annotations

import argparse

import allantools
import numpy as np
from gyrodrift.reference.allan import adev_rate
from gyrodrift.stability.streaming import StreamingAllan


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=4)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)

    # double: 1e5 samples at 400 Hz, white rate + random walk + 15 deg/h offset
    n, rate_hz, octaves = 100_000, 400.0, 15
    y = 15.0 + rng.normal(0.0, 0.05, n) + np.cumsum(rng.normal(0.0, 2e-4, n))
    sa = StreamingAllan(rate_hz, octaves)
    sa.push(y)
    ref = np.array([adev_rate(y, 1 << k)[0] for k in range(octaves)])
    _, at_dev, _, _ = allantools.adev(y, rate=rate_hz, data_type="freq", taus=sa.tau_s)
    print(f"Double, {n} samples at {rate_hz:g} Hz, {octaves} octaves\n")
    print("| tau (s) | terms | adev (deg/h) | rel. diff. to reference | rel. diff. to allantools |")
    print("| --- | --- | --- | --- | --- |")
    for k in range(octaves):
        print(f"| {sa.tau_s[k]:.4g} | {sa.counts[k]} | {sa.adev[k]:.6g} | "
              f"{abs(sa.adev[k] - ref[k]) / ref[k]:.1e} | "
              f"{abs(sa.adev[k] - at_dev[k]) / at_dev[k]:.1e} |")

    # float vs double: 10 h at 400 Hz, float32 samples fed to both
    n, octaves = 14_400_000, 20
    y32 = (10.0 + rng.standard_normal(n) + np.cumsum(rng.normal(0.0, 1e-4, n))).astype(np.float32)
    single = StreamingAllan(rate_hz, octaves, dtype=np.float32)
    double = StreamingAllan(rate_hz, octaves)
    single.push(y32)
    double.push(y32.astype(np.float64))
    rel = np.abs(single.avar - double.avar) / double.avar
    print(f"\nFloat state vs double state, {n} float32 samples (10 h at {rate_hz:g} Hz)\n")
    print("| tau (s) | terms | avar double | rel. error of float avar |")
    print("| --- | --- | --- | --- |")
    for k in range(octaves):
        print(f"| {single.tau_s[k]:.4g} | {single.counts[k]} | {double.avar[k]:.6g} | "
              f"{rel[k]:.1e} |")
    print(f"\nworst relative error of the float avar: {rel.max():.1e}")


if __name__ == "__main__":
    main()
