#!/usr/bin/env python3
"""Can GMWM model selection tell the Monte Carlo's case 3 (white + two Gauss-Markov, N+GM+GM:
N = 0.05 deg/sqrt(h), GM 20 deg/h @ 0.1 s and 10 deg/h @ 5 s) from its nearest smaller
competitor, white + random walk + one Gauss-Markov (N+K+GM), at a given record length?
(The companion of scripts/gmwm_monte_carlo.py, in the spirit of
scripts/drift_identifiability.py.)

1. Noncentrality. With the true model's wavelet variance nu_0 and its exact covariance Omega_0
   for the record length (gmwm.wv_covariance), each competitor's pseudo-true fit
   theta* = argmin (nu_0 - nu(theta))' Omega_0^-1 (nu_0 - nu(theta)) leaves the distance
   lambda = that minimum: the competitor's J statistic on records of the true model is
   approximately noncentral chi-squared with noncentrality lambda, and the WIC difference
   WIC(competitor) - WIC(true) has mean about lambda + (p_true - p_comp) - 2 (p_true - p_comp)
   and standard deviation about sqrt(2 |p_true - p_comp| + 4 lambda). lambda grows about in
   proportion to the record length (Omega ~ 1/N) plus what the added scale brings.
2. Two-point Monte Carlo. Records of the true model (H0) and of the competitor at its
   pseudo-true parameters (H1, the closest N+K+GM: the model a selection must also be able to
   pick when it is the truth); on each, both models are fitted as model="auto" fits every
   candidate (three-step efficient weight, J at the candidate's own estimate) and
   Delta = WIC(N+K+GM) - WIC(N+GM+GM) is recorded. Printed: P_H0(Delta > 0), the pairwise
   hit rate of identify_gmwm's rule (the two are not nested, so it compares their WIC) and of
   the plain minimum; P_H0(Delta > 2), that of the earlier rule (fewest parameters within 2
   of the minimum); P_H1(Delta <= 0); and the best balanced accuracy of ANY threshold rule
   on Delta, max_c [P_H0(Delta > c) + P_H1(Delta <= c)] / 2; and, for the threshold c80 at
   which P_H0(Delta > c80) = 80 % (the goal), P_H1(Delta <= c80): how often a rule that
   reaches the goal on case 3 would still pick N+K+GM when N+K+GM is the truth. The
   full selection faces 45
   more candidates, so its hit rate on case 3 is at most about the pairwise one.

    PYTHONPATH=python:build/dev-NAME/py python scripts/gmwm_distinguishability.py
        [--reps 100] [--lengths 14,15,16,17] [--seed 50000]

Seeds: H0 record r of length 2^L uses seed + 1000 L + r, H1 the same + 500 (independent of
the Monte Carlo's seeds 1000-3199 and the tuning seeds 11000-13199).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from gyrodrift.stability import gmwm

RATE_HZ = 100.0
DT = 1.0 / RATE_HZ
TRUE = ("N", "GM", "GM")
COMP = ("N", "K", "GM")
#: per-sample parameters of case 3: N = 0.05 deg/sqrt(h) -> s2 = (60 N)^2 / dt; GM sigma^2, T_c
TRUE_P = np.array([(60.0 * 0.05) ** 2 / DT, 20.0**2, 0.1 / DT, 10.0**2, 5.0 / DT])
OTHERS = ("N+K+GM", "N+GM", "Q+K+GM+GM", "N+R+GM")


def pseudo_true(terms: tuple[str, ...], nu0: np.ndarray, tau: np.ndarray,
                omega0: np.ndarray) -> tuple[np.ndarray, float]:
    """argmin and min of (nu0 - nu(theta))' Omega0^-1 (nu0 - nu(theta)) (log parameters)."""
    fit = gmwm._fit_model(terms, nu0, tau, gmwm._chol(omega0))
    return np.exp(fit.theta), fit.objective


def delta_wic(x: np.ndarray) -> float:
    """WIC(N+K+GM) - WIC(N+GM+GM) as identify_gmwm(model="auto") scores them."""
    wv = gmwm.haar_wv(x, RATE_HZ)
    tau = 2.0 ** wv.level.astype(np.float64)
    w = [gmwm._wic(gmwm._weighted_lsq(t, wv, tau)[0]) for t in (COMP, TRUE)]
    return w[0] - w[1]


def best_balanced(d0: np.ndarray, d1: np.ndarray) -> tuple[float, float]:
    """max over thresholds c of [P(d0 > c) + P(d1 <= c)] / 2, and the c."""
    cuts = np.unique(np.r_[d0, d1, -np.inf])
    acc = [(float(np.mean(d0 > c)) + float(np.mean(d1 <= c))) / 2.0 for c in cuts]
    k = int(np.argmax(acc))
    return acc[k], float(cuts[k])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=100)
    ap.add_argument("--lengths", default="14,15,16,17", help="log2 of the record lengths")
    ap.add_argument("--seed", type=int, default=50000)
    args = ap.parse_args(argv)
    lengths = [int(v) for v in args.lengths.split(",")]
    print(f"# case 3 (N+GM+GM) against N+K+GM, {RATE_HZ:g} Hz, {args.reps} records per "
          f"hypothesis and length")
    print("\n## noncentrality lambda of each competitor (exact Omega of the true model)")
    print("| n | record s | slowest T_c (5 s) spans | " + " | ".join(OTHERS) + " |")
    print("| --- | --- | --- | " + " | ".join("---" for _ in OTHERS) + " |")
    comp_p: dict[int, np.ndarray] = {}
    for lg in lengths:
        n = 1 << lg
        levels = np.arange(1, gmwm._default_levels(n) + 1)
        tau = 2.0 ** levels.astype(np.float64)
        nu0 = gmwm.theoretical_wv(TRUE, TRUE_P, tau)
        omega0 = gmwm.wv_covariance(TRUE, TRUE_P, levels, n)
        lams = []
        for m in OTHERS:
            p, lam = pseudo_true(gmwm.parse_model(m), nu0, tau, omega0)
            lams.append(lam)
            if m == "N+K+GM":
                comp_p[lg] = p
        print(f"| 2^{lg} | {n * DT:g} | {n * DT / 5.0:.0f} T_c | "
              + " | ".join(f"{v:.1f}" for v in lams) + " |")
    print("\n## two-point Monte Carlo: Delta = WIC(N+K+GM) - WIC(N+GM+GM)")
    print("| n | H0 median Delta | P_H0(Delta > 0) | P_H0(Delta > 2) | H1 median Delta | "
          "P_H1(Delta <= 0) | best balanced accuracy (threshold) | c80 | P_H1(Delta <= c80) "
          "| CPU s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for lg in lengths:
        n = 1 << lg
        c0 = time.process_time()
        d0 = np.array([delta_wic(gmwm._simulate_model(
            TRUE, TRUE_P, n, np.random.default_rng(args.seed + 1000 * lg + r)))
            for r in range(args.reps)])
        d1 = np.array([delta_wic(gmwm._simulate_model(
            COMP, comp_p[lg], n, np.random.default_rng(args.seed + 1000 * lg + 500 + r)))
            for r in range(args.reps)])
        acc, cut = best_balanced(d0, d1)
        c80 = float(np.quantile(d0, 0.2))
        print(f"| 2^{lg} | {np.median(d0):.1f} | {100 * np.mean(d0 > 0):.0f} % | "
              f"{100 * np.mean(d0 > 2):.0f} % | {np.median(d1):.1f} | "
              f"{100 * np.mean(d1 <= 0):.0f} % | {100 * acc:.0f} % ({cut:.1f}) | "
              f"{c80:.1f} | {100 * np.mean(d1 <= c80):.0f} % | "
              f"{time.process_time() - c0:.0f} |")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
