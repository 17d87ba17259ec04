#!/usr/bin/env python3
"""One yardstick for the drift filters: error against the true drift and -3 dB bandwidth.

Simulated record (100 Hz, 60000 samples, 5 seeds): AR(2) drift 0.6868/-0.0213 (paper 002's FOG)
with innovation std 0.5 deg/h on a 9.7 deg/h offset, plus white rate noise std 0.3 deg/h (the
drift-model example). Filters: the offline db8 denoiser (gyrodrift.wavelet_denoise, level 5,
soft universal threshold), the real-time db4 prefilter (RealtimeWavelet db4, N = 256, J = 5,
forced: an exact FIR), the steady-state AR(2)-Kalman with the papers' tuning and with the
maximum-likelihood tuning, and the true-model Kalman (the optimum, for reference).

Columns: MSE against the true drift (what the filter is for), STD of the output (what the
papers report: it falls also when a filter removes drift, i.e. signal), the share of the drift's
variance the output keeps (var(out) / var(drift) ~ 1 means the drift is kept), and the -3 dB
bandwidth measured with sine probes (amplitude 0.7 deg/h, about the drift's std, since the
soft-threshold denoiser is not linear): the first frequency where the output amplitude falls
below 1/sqrt(2) of its low-frequency value.

    python scripts/wavelet_yardstick.py
"""

from __future__ import annotations

import math

import gyrodrift
import numpy as np
from scipy.signal import lfilter

RATE_HZ = 100.0
N = 60000


def filters(y: np.ndarray) -> dict[str, object]:
    papers = gyrodrift.fit_ar2(y)
    ml = gyrodrift.fit_drift_model(y, RATE_HZ)
    true_model = gyrodrift.Ar2Model(a1=0.6868, a2=-0.0213, sigma2=0.25, mean=9.7)
    return {
        "offline db8 denoiser (soft, J=5)":
            lambda x: gyrodrift.wavelet_denoise(x, "db8", 5, "soft"),
        "real-time db4 prefilter (N=256, J=5, forced)":
            lambda x: gyrodrift.RealtimeWavelet("db4", 256, 5, "forced").filter(x),
        "AR(2)-Kalman, papers' tuning":
            lambda x: gyrodrift.kalman_filter(x, papers, steady_state=True),
        "AR(2)-Kalman, ML tuning": lambda x: ml.kalman().process(x),
        "AR(2)-Kalman, true model (optimum)":
            lambda x: gyrodrift.kalman_filter(x, true_model, q=0.25, r=0.09, steady_state=True),
    }


def bandwidth_hz(f: object, mean: float) -> float | None:
    n, skip = 8192, 2048
    t = np.arange(n) / RATE_HZ
    freqs = np.geomspace(0.01, RATE_HZ / 2 * 0.98, 120)
    amps = []
    for fr in freqs:
        x = mean + 0.7 * np.sin(2 * math.pi * fr * t)
        out = np.asarray(f(x))[skip:] - mean  # type: ignore[operator]
        basis = np.column_stack([np.sin(2 * math.pi * fr * t[skip:]),
                                 np.cos(2 * math.pi * fr * t[skip:]), np.ones(n - skip)])
        c = np.linalg.lstsq(basis, out, rcond=None)[0]
        amps.append(math.hypot(c[0], c[1]) / 0.7)
    amps_a = np.array(amps)
    below = np.nonzero(amps_a < amps_a[0] / math.sqrt(2))[0]
    if not below.size:
        return None
    i = int(below[0])
    # log-frequency interpolation between the two probes around the crossing
    a0, a1 = amps_a[i - 1], amps_a[i]
    target = amps_a[0] / math.sqrt(2)
    w = (a0 - target) / (a0 - a1)
    lo, hi = math.log(freqs[i - 1]), math.log(freqs[i])
    return float(math.exp(lo + w * (hi - lo)))


def main() -> None:
    rows: dict[str, list[tuple[float, float, float]]] = {}
    raw: list[tuple[float, float, float]] = []
    bws: dict[str, float | None] = {}
    for seed in range(5):
        rng = np.random.default_rng(seed)
        drift = 9.7 + lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(0, 0.5, N + 2000))[2000:]
        y = drift + rng.normal(0, 0.3, N)
        sl = slice(1000, None)  # start-up of the filters (the db4 window is 256 samples)
        dvar = float(np.var(drift[sl]))
        raw.append((float(np.mean((y[sl] - drift[sl]) ** 2)), float(np.std(y[sl])),
                    float(np.var(y[sl])) / dvar))
        for name, f in filters(y).items():
            out = np.asarray(f(y))  # type: ignore[operator]
            rows.setdefault(name, []).append((float(np.mean((out[sl] - drift[sl]) ** 2)),
                                              float(np.std(out[sl])),
                                              float(np.var(out[sl])) / dvar))
            if seed == 0:
                bws[name] = bandwidth_hz(f, 9.7)
    print(f"# {N} samples at {RATE_HZ:g} Hz, 5 seeds; drift AR(2) 0.6868/-0.0213 innovation std "
          "0.5 deg/h, white noise std 0.3 deg/h (true drift variance ~0.41 (deg/h)^2)")
    print("| filter | MSE vs drift ((deg/h)^2) | STD (deg/h) | var(out)/var(drift) | "
          "-3 dB bandwidth (Hz) |")
    print("| --- | ---: | ---: | ---: | ---: |")
    m = np.mean(raw, axis=0)
    print(f"| raw record | {m[0]:.4f} | {m[1]:.4f} | {m[2]:.3f} | - |")
    for name, vals in rows.items():
        m = np.mean(vals, axis=0)
        bw = bws[name]
        print(f"| {name} | {m[0]:.4f} | {m[1]:.4f} | {m[2]:.3f} | "
              f"{'none below Nyquist' if bw is None else f'{bw:.3g}'} |")


if __name__ == "__main__":
    main()
