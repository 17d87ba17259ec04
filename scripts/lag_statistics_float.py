#!/usr/bin/env python3
"""The whole-record lag statistics of the C++ core in float (as on the target) against double,
after a long record, and the drift-model fit from each.

For each case (the papers' two correlated AR(2) pairs, q = r, on a bias): simulate a gyro
record in deg/h at 400 Hz (gyrodrift.simulation.records.simulate: angle random walk
0.005 deg/sqrt(h), i.e. 6 deg/h per sample, and an AR(2) drift driven by 6 deg/h), round it to
float32 as a target's sensor interface would, and push the same float32 samples into
gyrodrift.filters.LagStatistics with float state and with double state. Prints:
  dP/P0    - the largest |P_k(float) - P_k(double)| / P_0 over k = 0..32;
  dsum     - |sum w (float) - sum w (double)| / sum |w|;
  plain    - the relative error of P_0 summed plainly in float32 (numpy's cumsum: one
             running float32 sum, as an uncompensated accumulator on the target would);
  fit      - gyrodrift.reference.lag_drift.lag_drift_fit on the float statistics against the
             same fit on the double statistics: the largest difference of a1, a2, q, r, mean
             in units of the offline fit's standard errors (gyrodrift.fit_drift_model on the
             float64 record; --no-offline: not run, the column left empty), and the float
             fit's parameters' log-likelihood on the double statistics minus the double fit's
             (dLL fit; positive: the float fit scores higher);
  ref fit  - the same comparison (SE) between the fits on the C++ double statistics and on
             the numpy reference's statistics of the same samples (LagStatisticsReference):
             the optimiser's own spread when the statistics differ in their last digits;
  dLL stats - the log-likelihood from the float statistics minus the one from the double
             statistics, both at the double fit's parameters (what the float rounding does to
             the likelihood itself).

    python scripts/lag_statistics_float.py                     # the docs run: 10 h, 2 cases
    python scripts/lag_statistics_float.py --samples 1000000   # fast
"""

from __future__ import annotations

import argparse
import time

import gyrodrift
import numpy as np
from gyrodrift.filters import LagStatistics
from gyrodrift.reference.lag_drift import LagStatisticsReference, lag_drift_fit, lag_loglike
from gyrodrift.simulation.records import simulate

CASES = (("(0.6868, -0.0213)", 0.6868, -0.0213, 9.7), ("(0.2297, 0.1638)", 0.2297, 0.1638, 0.0))
CHUNK = 1_000_000


def run_case(label: str, a1: float, a2: float, bias: float, n: int, seed: int,
             offline: bool) -> None:
    rec = simulate(n=n, rate_hz=400.0, n_deg_rt_h=0.005, bias_deg_h=bias,
                   ar2=(a1, a2, 6.0), seed=seed)
    y32 = np.asarray(rec.rate_deg_h, dtype=np.float32)
    del rec
    f32, f64, ref = LagStatistics(dtype=np.float32), LagStatistics(), LagStatisticsReference(32)
    t0 = time.perf_counter()
    for lo in range(0, n, CHUNK):
        f32.push(y32[lo:lo + CHUNK])
    t_f32 = time.perf_counter() - t0
    for lo in range(0, n, CHUNK):
        f64.push(y32[lo:lo + CHUNK].astype(np.float64))
        ref.push(y32[lo:lo + CHUNK].astype(np.float64))
    p0 = float(f64.products[0])
    dp = float(np.max(np.abs(f32.products - f64.products))) / p0
    w = y32.astype(np.float64) - float(y32[0])
    dsum = abs(f32.total - f64.total) / float(np.sum(np.abs(w)))
    w32 = y32 - y32[0]
    plain = abs(float(np.cumsum(w32 * w32, dtype=np.float32)[-1]) - p0) / p0
    del w, w32
    a, b, c = lag_drift_fit(f32), lag_drift_fit(f64), lag_drift_fit(ref)
    dll = lag_loglike(f64, a.a1, a.a2, a.q, a.r, a.mean) - b.loglike
    dll_stats = lag_loglike(f32, b.a1, b.a2, b.q, b.r, b.mean) - b.loglike
    se_text = ref_text = ""
    if offline:
        se = gyrodrift.fit_drift_model(y32.astype(np.float64), rate_hz=400.0).stderr
        keys = ("a1", "a2", "q", "r", "mean")
        se_text = f"{max(abs(getattr(a, k) - getattr(b, k)) / se[k] for k in keys):.1e}"
        ref_text = f"{max(abs(getattr(c, k) - getattr(b, k)) / se[k] for k in keys):.1e}"
    print(f"| {n} | {label} | {bias:g} | {seed} | {dp:.1e} | {dsum:.1e} | {plain:.1e} "
          f"| {se_text} | {dll:+.1e} | {ref_text} | {dll_stats:+.1e} "
          f"| {f32.state_bytes} / {f64.state_bytes} "
          f"| {1e9 * t_f32 / n:.0f} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=14_400_000,
                        help="samples per record (default 10 h at 400 Hz)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--no-offline", action="store_true",
                        help="skip the offline fit (its standard errors scale the fit column)")
    args = parser.parse_args()
    print("| samples | pair | bias deg/h | seed | dP/P0 | dsum | plain float P_0 | fit (SE) "
          "| dLL fit | ref fit (SE) | dLL stats | state bytes float / double "
          "| ns/sample float (host) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for label, a1, a2, bias in CASES:
        run_case(label, a1, a2, bias, args.samples, args.seed, not args.no_offline)


if __name__ == "__main__":
    main()
