#!/usr/bin/env python3
"""The re-identification from lag statistics (the C++ LagDriftIdentifier through the gyro
monitor, float state as on the target): its convergence to the offline ML fit and its
tracking of a 2x step of q or r, on the records of `scripts/online_drift_mc.py`.

convergence: both of the papers' pairs, r/q in {1, 3}, seeds 1..SEEDS, each length N: the
record of N + 1000 samples, one fit requested at sample N (cadence N) and applied 1000
samples later, steps not bounded (max_step 100), the default guards, the configured model of
the recursive study (20 % off in a1, a2 / 2 + 0.03, q x1.5, r x0.7); the fit (the
identifier's estimate; the model in use when the guards accept it, else the configured one)
against `gyrodrift.fit_drift_model` on the first N samples: z = (fit - ML) / (offline
standard error) for a1, a2, q, r, mean, and the signed likelihood distance d_LL =
sign(D) sqrt(``|D|``), D = 2 (log L(ML) - log L(fit)), exact log-likelihoods on those
samples; and whether the guards accepted it (status tracking: the model in use is the fit).

tracking: q = r = 1 (r/q 1), r x2 or q x2 halfway through --tracking-samples; the
statistics restarted after each fit (restart_after_fit), cadence --cadence, each fit applied
1000 samples after its request, max_step 1 (a 2x step, log 2 = 0.69, in one retune); for each
fit after the change: its window (the samples since the previous fit) and the model in use
against the new (q, r) in standard errors of `fit_drift_model` on that window. Printed: the
first fit whose window lies wholly after the change, whether q and r are within one and two
standard errors there, the largest |z| of q and r over the fits from there on (against the new
values; the fit itself against the offline fit of each window), and the fits the guards
refused.

    python scripts/lag_identifier_check.py --convergence --samples 240000 960000 --seeds 5
    python scripts/lag_identifier_check.py --tracking --seeds 5
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import gyrodrift
import numpy as np
from gyrodrift._native import core
from online_drift_mc import PAIRS, RATIOS, Case, simulate

NAMES = ("a1", "a2", "q", "r", "mean")
DELAY = 1000
STATUS = {1: "learning", 2: "tracking", 3: "not_identified", 4: "fallback"}


def run_lag(y: np.ndarray, cfg: tuple[float, ...], **settings: Any) -> list[dict[str, Any]]:
    """The C++ lag identifier (float state) over y: each applied fit's sample, status and
    model in use."""
    native = core("imu")
    s = native.GyroMonitorSettings(rate_hz=400.0, octaves=8, reidentify=True, identifier="lag",
                                   **settings)
    mon = native.GyroMonitorRunF32(s, cfg, np.ones(8), np.zeros(8))
    flags = np.zeros(y.size, dtype=bool)
    out = mon.run(np.ascontiguousarray(y, dtype=np.float32), flags, flags, 1, 0.6827)
    applied = np.asarray(out["retunes"]) + np.asarray(out["refused_retunes"])
    rows = np.flatnonzero(np.diff(np.r_[0.0, applied]) > 0)
    return [{"sample": int(out["sample"][i]), "status": STATUS.get(int(out["status"][i]), "?"),
             **{k: float(out[k][i]) for k in NAMES},
             **{"est_" + k: float(out["est_" + k][i]) for k in NAMES}} for i in rows]


def convergence(lengths: list[int], seeds: int) -> None:
    loglike = core("drift").drift_loglike
    print("# samples, pair, r/q, seed; (fit - ML) / offline stderr; d_LL; status")
    summary: dict[tuple[int, tuple[float, float]], list[tuple[float, float, str]]] = {}
    t0 = time.monotonic()
    for n in lengths:
        for a1, a2 in PAIRS:
            for ratio in RATIOS:
                for seed in range(1, seeds + 1):
                    y, _, _, _ = simulate(Case(a1, a2, ratio, "none", n + DELAY, seed))
                    y32 = y.astype(np.float32).astype(np.float64)
                    cfg = (0.8 * a1, 0.5 * a2 + 0.03, 1.5, 0.7 * ratio, 0.0)
                    got = run_lag(y32, cfg, block_samples=n // 100, retune_blocks=100,
                                  min_samples=n, max_step=100.0, fit_delay_samples=DELAY)
                    fit = gyrodrift.fit_drift_model(y32[:n], rate_hz=400.0)
                    g = got[-1]
                    z = [(g["est_" + k] - getattr(fit, k)) / fit.stderr[k] for k in NAMES]
                    ll_ml = loglike(y32[:n], fit.a1, fit.a2, fit.q, fit.r, fit.mean)[0]
                    ll_in = loglike(y32[:n], *(g["est_" + k] for k in NAMES))[0]
                    d = 2.0 * (ll_ml - ll_in)
                    d_ll = math.copysign(math.sqrt(abs(d)), d)
                    summary.setdefault((n, (a1, a2)), []).append(
                        (max(abs(v) for v in z), d_ll, g["status"]))
                    print(f"{n:8d} ({a1}, {a2}) {ratio:3.0f} {seed:3d} "
                          + " ".join(f"{v:+6.3f}" for v in z)
                          + f" {d_ll:+7.3f} a2_ML {fit.a2:+.4f} {g['status']}")
    print("| samples | pair | fit accepted (status tracking) | fit within 1 SE (every "
          "parameter and the mean; of the records with offline standard errors) "
          "| largest abs z | d_LL range |")
    print("| --- | --- | --- | --- | --- | --- |")
    for (n, pair), rows in summary.items():
        zs = [r[0] for r in rows if math.isfinite(r[0])]  # NaN: the offline SE undefined
        ds = [r[1] for r in rows]
        tracking = sum(r[2] == "tracking" for r in rows)
        print(f"| {n} | {pair} | {tracking} of {len(rows)} | {sum(v <= 1.0 for v in zs)} of "
              f"{len(zs)} | {max(zs):.3f} | {min(ds):+.3f} to {max(ds):+.3f} |")
    print(f"# {time.monotonic() - t0:.0f} s")


def tracking(n: int, cadence: int, seeds: int, adapt_ar: bool) -> None:
    print(f"# tracking: {n} samples, the change at {n // 2}; cadence {cadence}, restart after "
          f"each fit, max_step 1, adapt_ar {adapt_ar}")
    print("| pair | change | seed | first fit wholly after the change (applied at) "
          "| cadences after the change | q, r within 1 SE there | within 2 SE "
          "| largest abs z of q, r from there on | the fit against the offline fit of each window "
          "| refused from there on |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    t0 = time.monotonic()
    half = n // 2
    for a1, a2 in PAIRS:
        for change in ("q x2", "r x2"):
            for seed in range(1, seeds + 1):
                y, _, _, (q2, r2) = simulate(Case(a1, a2, 1.0, change, n, seed))
                y32 = y.astype(np.float32).astype(np.float64)
                cfg = (a1, a2, 1.0, 1.0, 9.7)
                got = run_lag(y32, cfg, block_samples=cadence // 100, retune_blocks=100,
                              min_samples=cadence // 2, max_step=1.0, fit_delay_samples=DELAY,
                              restart_after_fit=True, adapt_ar=adapt_ar)
                first, zmax, zoff, refused, w1, w2 = None, 0.0, 0.0, 0, False, False
                start = 0  # the window of the fit applied at g["sample"]
                for g in got:
                    request = g["sample"] - DELAY
                    if start >= half:
                        if g["status"] != "tracking":
                            refused += 1
                        else:
                            fit = gyrodrift.fit_drift_model(y32[start:request], rate_hz=400.0)
                            z = [(g["q"] - q2) / fit.stderr["q"], (g["r"] - r2) / fit.stderr["r"]]
                            if first is None:
                                first = g["sample"]
                                w1 = max(abs(v) for v in z) <= 1.0
                                w2 = max(abs(v) for v in z) <= 2.0
                            zmax = max(zmax, *(abs(v) for v in z))
                            # the fit itself (the model in use is it unless the step was bounded)
                            zoff = max(zoff, *(abs(g["est_" + k] - getattr(fit, k))
                                               / fit.stderr[k] for k in ("q", "r")))
                    start = g["sample"]
                after = "-" if first is None else f"{(first - half) / cadence:.2f}"
                print(f"| ({a1}, {a2}) | {change} | {seed} | {first} | {after} | "
                      f"{'yes' if w1 else 'no'} | {'yes' if w2 else 'no'} | {zmax:.2f} | "
                      f"{zoff:.3f} | {refused} |")
    print(f"# {time.monotonic() - t0:.0f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--convergence", action="store_true")
    ap.add_argument("--tracking", action="store_true")
    ap.add_argument("--samples", type=int, nargs="+", default=[240000],
                    help="--convergence: record lengths (default 240000)")
    ap.add_argument("--seeds", type=int, default=5, help="seeds 1..SEEDS (default 5)")
    ap.add_argument("--tracking-samples", type=int, default=480000)
    ap.add_argument("--cadence", type=int, default=60000, help="--tracking: samples between fits")
    ap.add_argument("--hold-ar", action="store_true", help="--tracking: adapt_ar off")
    args = ap.parse_args()
    if args.convergence:
        convergence(args.samples, args.seeds)
    if args.tracking:
        tracking(args.tracking_samples, args.cadence, args.seeds, not args.hold_ar)


if __name__ == "__main__":
    main()
