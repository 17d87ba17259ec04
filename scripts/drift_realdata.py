#!/usr/bin/env python3
"""Drift-model ML fits on the real ring-laser-gyro record (shared/data/lasergyro.imu).

The record is a vehicle with the engine running (see shared/data/README.md): no segment is
truly static. The script picks the 300 s window whose 1 s mean rates vary least (sum over the
three gyros of the variance of 1 s means: vehicle motion shows up there, sensor noise mostly
averages out), reports that measure for the best and the median window, and fits the three
drift models on each gyro axis (rates in deg/h; one count = 0.1 arcsec per 10 ms = 10 deg/h,
so the quantization is the white noise that dominates).

    python scripts/drift_realdata.py [PATH]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from gyrodrift.filters.drift_model import compare_drift_models
from gyrodrift.io.psins import read_psins_imu

RAD_TO_DEG_H = 180.0 / np.pi * 3600.0


#: The shared real record beside the checkout (../shared/data, see its README).
SHARED_RECORD = str(Path(__file__).resolve().parents[2] / "shared" / "data" / "lasergyro.imu")

def static_window(rate_deg_h: np.ndarray, rate_hz: float, window_s: float = 300.0
                  ) -> tuple[int, float, float]:
    """Start index of the quietest window, its motion measure and the median one (deg/h)^2."""
    per_s = round(rate_hz)
    n_s = rate_deg_h.shape[0] // per_s
    means = rate_deg_h[: n_s * per_s].reshape(n_s, per_s, 3).mean(axis=1)
    w = int(window_s)
    scores = np.array([means[i:i + w].var(axis=0).sum() for i in range(0, n_s - w + 1, 5)])
    best = int(np.argmin(scores))
    return best * 5 * per_s, float(scores[best]), float(np.median(scores))


def load_segment(path: str | Path) -> tuple[np.ndarray, float, int, float, float]:
    rec = read_psins_imu(path)
    rate_hz = 1.0 / rec.dt_s
    rate = rec.dtheta / rec.dt_s * RAD_TO_DEG_H
    start, score, median = static_window(rate, rate_hz)
    return rate[start:start + int(300 * rate_hz)], rate_hz, start, score, median


def main() -> None:
    path = sys.argv[1] if len(sys.argv) > 1 else SHARED_RECORD
    seg, rate_hz, start, score, median = load_segment(path)
    print(f"# {path}: quietest 300 s window starts at {start / rate_hz:.0f} s; variance of 1 s "
          f"means summed over gyros {score:.4g} (deg/h)^2 (median window {median:.4g})")
    print("| axis | model | loglike | AIC | BIC | a1 | a2 | q (deg/h)^2 | r (deg/h)^2 | "
          "mean deg/h | Ljung-Box p |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for i, axis in enumerate("xyz"):
        cmp_ = compare_drift_models(seg[:, i], rate_hz, "aic")
        for f in cmp_.fits:
            star = " (chosen)" if f.model == cmp_.chosen else ""
            print(f"| g{axis} | {f.model}{star} | {f.loglike:.1f} | {f.aic:.1f} | {f.bic:.1f} | "
                  f"{f.a1:.4f} | {f.a2:.4f} | {f.q:.4g} | {f.r:.4g} | {f.mean:.3f} | "
                  f"{f.ljung_box.pvalue:.3g} |")
        bic = min(cmp_.fits, key=lambda f: f.bic).model
        print(f"| g{axis} | chosen by AIC: {cmp_.chosen}, by BIC: {bic}; filter "
              f"{cmp_.best.response().as_dict()} | | | | | | | | | |")


if __name__ == "__main__":
    main()
