"""Benchmark: real-time wavelet prefilter (C++ core through the bindings) vs the PyWavelets
per-sample window recompute, in the same process; plus the lifting DWT vs pywt.wavedec.

Prints a markdown table (ns/sample/axis, samples/s, speed-up vs the PyWavelets recompute;
medians of repeats) and the machine. Times are thread CPU time (time.thread_time), so time
spent preempted on the shared machine does not count. Not a test.

    PYTHONPATH=python:build/<dir>/py python3 benchmarks/bench_wavelet.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
import pywt
from _bench_util import machine, median_seconds
from gyrodrift import RealtimeWavelet
from gyrodrift.filters.wavelet import wavedec
from gyrodrift.reference.wavelet import realtime_window


def median_cpu_seconds(fn: Callable[[], object], repeats: int) -> float:
    # thread CPU time: time spent preempted on the shared machine does not count
    return median_seconds(fn, repeats, clock=time.thread_time)


def realtime_case(wavelet: str, mode: str, n: int, dtype: type, recompute: bool = False):
    """A started filter (window full); each call streams n more samples through it."""
    x = np.random.default_rng(1).standard_normal(n).astype(dtype)
    f = RealtimeWavelet(wavelet, 256, 5, mode, dtype=dtype)
    f.filter(x[:256])

    def run() -> None:
        f.filter(x, recompute=recompute)

    return run


def pywt_recompute_case(wavelet: str, mode: str, n: int):
    x = np.random.default_rng(1).standard_normal(n + 256)

    def run() -> None:
        for i in range(n):
            realtime_window(x[i : i + 256], wavelet, 5, mode)

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--n-fast", type=int, default=400_000, help="samples, streaming forced")
    parser.add_argument("--n-slow", type=int, default=20_000, help="samples, threshold/recompute")
    parser.add_argument("--n-pywt", type=int, default=400, help="samples, pywt recompute")
    args = parser.parse_args()
    r = args.repeats

    print(f"# Real-time wavelet filter, N=256, J=5 (machine: {machine()})\n")
    print("| wavelet | dtype | path | ns/sample/axis | samples/s | vs PyWavelets recompute |")
    print("| --- | --- | --- | ---: | ---: | ---: |")
    for wavelet in ("db8", "db4"):
        t_py = {
            m: median_cpu_seconds(pywt_recompute_case(wavelet, m, args.n_pywt), r) / args.n_pywt
            for m in ("forced", "soft")
        }
        rows = [
            ("streaming forced", "forced", args.n_fast, np.float64, False),
            ("streaming soft threshold", "soft", args.n_slow, np.float64, False),
            ("C++ full-window recompute (forced)", "forced", args.n_slow, np.float64, True),
            ("streaming forced", "forced", args.n_fast, np.float32, False),
            ("streaming soft threshold", "soft", args.n_slow, np.float32, False),
        ]
        for label, mode, n, dtype, rec in rows:
            t = median_cpu_seconds(realtime_case(wavelet, mode, n, dtype, rec), r) / n
            ratio = t_py[mode] / t
            print(
                f"| {wavelet} | {np.dtype(dtype).name} | {label} | {t * 1e9:,.1f} | "
                f"{1 / t:,.0f} | {ratio:,.0f}x |"
            )
        for m in ("forced", "soft"):
            t = t_py[m]
            print(
                f"| {wavelet} | float64 | PyWavelets per-sample recompute ({m}) | "
                f"{t * 1e9:,.0f} | {1 / t:,.0f} | 1x |"
            )

    print("\n# Lifting DWT (periodization, J=5, n=2**16) vs pywt.wavedec\n")
    print("| wavelet | C++ lifting ns/sample | pywt.wavedec ns/sample | ratio |")
    print("| --- | ---: | ---: | ---: |")
    x = np.random.default_rng(2).standard_normal(1 << 16)
    for wavelet in ("db8", "db4"):
        t_c = median_cpu_seconds(lambda w=wavelet: wavedec(x, w, 5), r) / x.size
        t_p = (
            median_cpu_seconds(
                lambda w=wavelet: pywt.wavedec(x, w, mode="periodization", level=5), r
            )
            / x.size
        )
        print(f"| {wavelet} | {t_c * 1e9:.2f} | {t_p * 1e9:.2f} | {t_p / t_c:.2f}x |")


if __name__ == "__main__":
    main()
