#!/usr/bin/env python3
"""GMWM speed: Haar wavelet variance (cumulative sums, all levels) and the full
fit (wavelet variance + two-step GMM with the exact covariance) at 1e6 and 1e7 samples.

    PYTHONPATH=python python3 benchmarks/bench_gmwm.py [--sizes 1e6,1e7] [--repeats 3]

Prints wall and process-CPU medians (the machine is shared: CPU time is the fairer number)
and, as the peer in the same process, the numpy reference route of the wavelet variance
(direct convolution with the Haar filters, O(N L_j)) on the first 2^16 samples scaled per
sample. Goal: fit of 1e7 samples under 5 s.
"""

from __future__ import annotations

import argparse
import os
import time

from _bench_util import machine, median_seconds


def bench_size(n: int, repeats: int) -> None:
    import gyrodrift
    from gyrodrift.reference.gmwm import haar_wv as haar_wv_ref
    from gyrodrift.stability.gmwm import haar_wv, identify_gmwm

    x = gyrodrift.simulate(n=n, rate_hz=100.0, n_deg_rt_h=0.05, k_deg_h_rt_h=50.0,
                           gm=((5.0, 2.0),), seed=1).rate_deg_h
    rows = [("wavelet variance (all levels)", "-", lambda: haar_wv(x, 100.0))]
    for model in ("N+K", "N+K+GM"):
        rows.append(("fit (WV + three-step GMM)", model,
                     lambda m=model: identify_gmwm(x, 100.0, model=m)))
    for step, model, fn in rows:
        wall = median_seconds(fn, repeats)
        cpu = median_seconds(fn, repeats, clock=time.process_time)
        print(f"| {n:.0e} | {step} | {model} | {wall:.3f} | {cpu:.3f} | "
              f"{cpu / n * 1e9:.1f} | {n / cpu:.3g} |", flush=True)
    ref_n, jref = 1 << 16, 15
    head = x[:ref_n]
    ref = median_seconds(lambda: haar_wv_ref(head, jref), 1, clock=time.process_time)
    ours = median_seconds(lambda: haar_wv(head, 100.0, max_level=jref), repeats,
                          clock=time.process_time)
    print(f"| 2^16 (of {n:.0e}) | WV, numpy convolution reference vs ours (15 levels) | "
          f"- | - | {ref:.3f} vs {ours:.4f} | ratio {ref / ours:.0f}x | - |", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1e6,1e7")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print(f"Machine: {machine()}; load average {os.getloadavg()[0]:.2f} at the start")
    print("| N | step | model | wall s | CPU s | CPU ns/sample | samples/s (CPU) |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for n in (int(float(s)) for s in args.sizes.split(",")):
        bench_size(n, args.repeats)
    print(f"load average {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
