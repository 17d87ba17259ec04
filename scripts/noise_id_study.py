"""Monte Carlo of the per-tau noise identification (gyrodrift.stability.noise_type) on the five
power-law noises of allantools' Kasdin generator: the fraction of taus (with >= 128
averages) where the default (lag-1 ACF, slope fallback) and the slope-only method find the
true alpha, and the largest error. Prints a markdown table (the documentation's validation tables).

    PYTHONPATH=python:build/dev-NAME/py python3 scripts/noise_id_study.py [--reps 20]
"""

from __future__ import annotations

import argparse

import gyrodrift
import numpy as np
from allantools.noise_kasdin import Noise

NAMES = {2: "white PM", 1: "flicker PM", 0: "white FM", -1: "flicker FM", -2: "random-walk FM"}


def power_law_rate(alpha: int, n: int, seed: int, rate_hz: float) -> np.ndarray:
    """Rate (frequency) samples with S_y ~ f^alpha: Kasdin phase noise, b = alpha - 2,
    differenced. allantools' generator draws from numpy's global state: seeded here."""
    np.random.seed(seed)  # noqa: NPY002 - the generator uses the global state
    g = Noise(nr=n + 1, qd=1.0, b=alpha - 2)
    g.generateNoise()
    return np.diff(g.time_series) * rate_hz


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--n", type=int, default=1 << 16)
    args = ap.parse_args()
    print(f"{args.reps} records of {args.n} samples per noise type; taus with >= 128 averages")
    print()
    print("| noise (alpha) | default (ACF) correct | max abs error | slope-only correct |")
    print("| --- | --- | --- | --- |")
    for alpha, name in NAMES.items():
        hit, hit_slope, worst = [], [], 0
        for rep in range(args.reps):
            y = power_law_rate(alpha, args.n, 1000 * rep + alpha + 7, 10.0)
            r = gyrodrift.oadev(y, 10.0)
            s = gyrodrift.oadev(y, 10.0, alpha="slope")
            use = args.n // r.m >= 128
            hit.append(np.mean(r.alpha[use] == alpha))
            hit_slope.append(np.mean(s.alpha[use] == alpha))
            worst = max(worst, int(np.max(np.abs(r.alpha[use] - alpha))))
        print(f"| {name} ({alpha:+d}) | {100 * np.mean(hit):.0f} % | {worst} | "
              f"{100 * np.mean(hit_slope):.0f} % |")


if __name__ == "__main__":
    main()
