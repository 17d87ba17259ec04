"""The deviation family and the per-tau noise identification on the real laser-gyro record
(../shared/data/lasergyro.imu beside the checkout, PSINS format, 100 Hz): gyro axis rate
in deg/h, the overlapping Allan deviation with the lag-1 ACF noise ID (default) and with the
old slope rule, the edf ratio between them, and every deviation at the same taus. Prints markdown
tables (the documentation's validation tables); --png writes the figure (not committed).

    PYTHONPATH=python:build/dev-NAME/py python3 scripts/deviation_real_record.py \
        [--path ../shared/data/lasergyro.imu] [--axis z] [--png /tmp/real.png]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import gyrodrift
import numpy as np
from gyrodrift.io.psins import read_psins_imu

RAD_S_TO_DEG_H = 180.0 / math.pi * 3600.0


#: The shared real record beside the checkout (../shared/data, see its README).
SHARED_RECORD = str(Path(__file__).resolve().parents[2] / "shared" / "data" / "lasergyro.imu")

def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--path", default=SHARED_RECORD)
    ap.add_argument("--axis", choices="xyz", default="z")
    ap.add_argument("--png")
    args = ap.parse_args()
    rec = read_psins_imu(args.path)
    k = "xyz".index(args.axis)
    rate_hz = 1.0 / rec.dt_s
    y = rec.dtheta[:, k] / rec.dt_s * RAD_S_TO_DEG_H  # deg/h
    acf = gyrodrift.oadev(y, rate_hz)
    slope = gyrodrift.oadev(y, rate_hz, alpha="slope")
    print(f"{args.path}: gyro {args.axis}, {y.size} samples at {rate_hz:g} Hz, "
          f"mean {y.mean():.3f} deg/h")
    print()
    print("| tau s | adev deg/h | averages | ACF alpha (method) | slope alpha "
          "| edf ACF | edf slope | edf ratio |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for j in range(acf.m.size):
        ratio = max(acf.edf[j], slope.edf[j]) / min(acf.edf[j], slope.edf[j])
        print(f"| {acf.tau_s[j]:.4g} | {acf.adev[j]:.4g} | {y.size // acf.m[j]} | "
              f"{acf.alpha[j]:+d} ({acf.noise_id[j]}) | {slope.alpha[j]:+d} | "
              f"{acf.edf[j]:.4g} | {slope.edf[j]:.4g} | {ratio:.3g} |")
    print()
    names = ("oadev", "mdev", "tdev", "hdev", "ohdev", "totdev")
    res = {n: gyrodrift.deviation(y, rate_hz, n) for n in names}
    taus = res["hdev"].tau_s  # the shortest list (hdev: m <= N/4)
    print("| tau s | " + " | ".join(f"{n} {'deg/h s' if n == 'tdev' else 'deg/h'} [1-sigma]"
                                    for n in names) + " |")
    print("| --- |" + " --- |" * len(names))
    for t in taus[::2]:
        cells = []
        for n in names:
            r = res[n]
            j = int(np.flatnonzero(np.isclose(r.tau_s, t))[0])
            cells.append(f"{r.adev[j]:.4g} [{r.ci_low[j]:.3g}, {r.ci_high[j]:.3g}]")
        print(f"| {t:.4g} | " + " | ".join(cells) + " |")
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 8), sharex=True)
        for n in names:
            if n == "tdev":
                continue
            r = res[n]
            ax1.errorbar(r.tau_s, r.adev, yerr=[r.adev - r.ci_low, r.ci_high - r.adev],
                         label=n, capsize=2, marker=".")
        ax1.set(xscale="log", yscale="log", ylabel="deviation, deg/h",
                title=f"lasergyro.imu gyro {args.axis}")
        ax1.legend()
        ax2.step(acf.tau_s, acf.alpha, where="mid", label="lag-1 ACF (default)")
        ax2.step(slope.tau_s, slope.alpha, where="mid", label="slope rule (old default)")
        ax2.set(xscale="log", xlabel="tau, s", ylabel="alpha (S_y ~ f^alpha)")
        ax2.legend()
        fig.tight_layout()
        fig.savefig(args.png, dpi=110)
        print(f"\nfigure: {args.png}")


if __name__ == "__main__":
    main()
