"""Benchmark: maximum-likelihood drift-model fit (gyrodrift.fit_drift_model, AR(2) + white)
against statsmodels SARIMAX(order=(2,0,0), measurement_error=True, trend='c').fit() on the same
record in the same process.

Prints one markdown table (CPU seconds per fit, thread time so that time spent preempted on the
shared machine does not count; median of repeats for ours, one statsmodels fit per size; the
likelihood each reached) and the machine. Not a test: the machine is shared and noisy.

    PYTHONPATH=python:build/<dir>/py python3 benchmarks/bench_fit.py [--sizes 100000 1000000]
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np
from _bench_util import machine, median_seconds
from gyrodrift.filters.drift_model import fit_drift_model
from scipy.signal import lfilter


def record(n: int) -> np.ndarray:
    rng = np.random.default_rng(1)
    x = lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(0.0, 0.5, n + 2000))[2000:]
    return 9.7 + x + rng.normal(0.0, 0.3, n)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--no-statsmodels", action="store_true")
    args = ap.parse_args()
    import statsmodels.api as sm

    print(f"# {machine()}; load average {os.getloadavg()[0]:.1f} at start")
    print("| samples | gyrodrift fit (s CPU) | statsmodels fit (s CPU) | speed-up | "
          "loglike gyrodrift | loglike statsmodels |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: |")
    for n in args.sizes:
        y = record(n)
        ours = median_seconds(lambda y=y: fit_drift_model(y, 100.0), args.repeats,
                              clock=time.thread_time)
        fit = fit_drift_model(y, 100.0)
        if args.no_statsmodels:
            print(f"| {n} | {ours:.3f} | - | - | {fit.loglike:.3f} | - |")
            continue
        m = sm.tsa.SARIMAX(y, order=(2, 0, 0), measurement_error=True, trend="c")
        t0 = time.thread_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = m.fit(disp=False)
        theirs = time.thread_time() - t0
        print(f"| {n} | {ours:.3f} | {theirs:.2f} | {theirs / ours:.0f}x | {fit.loglike:.3f} | "
              f"{res.llf:.3f} |", flush=True)
    print(f"# load average {os.getloadavg()[0]:.1f} at end")


if __name__ == "__main__":
    main()
