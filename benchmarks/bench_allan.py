"""Benchmark: octave-tau overlapping ADEV on float64 records, gyrodrift (C++ kernel) vs
allantools.oadev in the same process. Prints a markdown table (median of repeats) with time,
ns per sample per tau, samples/s, speed-up, and peak extra memory (tracemalloc: numpy
registers its buffers with it) relative to the input array; plus the chunked memmap path.

    PYTHONPATH=python:build/dev-NAME/py python3 benchmarks/bench_allan.py [--sizes 1e6 1e7 1e8]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import allantools
import numpy as np
from gyrodrift import allan


def machine() -> str:
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        model = next(line.split(":", 1)[1].strip() for line in out.splitlines()
                     if line.startswith("Model name"))
    except (OSError, subprocess.CalledProcessError, StopIteration):
        model = "unknown CPU"
    return f"{model}, {os.cpu_count()} logical cores"


def measure(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """(median seconds, peak traced bytes above the start) over `repeats` runs."""
    times = []
    peak = 0
    for _ in range(repeats):
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
        peak = max(peak, tracemalloc.get_traced_memory()[1] - base)
        tracemalloc.stop()
    return statistics.median(times), float(peak)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e6, 1e7, 1e8])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--peer-max", type=float, default=1e8,
                    help="largest size allantools is run at (memory/time on a shared host)")
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    print(f"Machine: {machine()}; numpy {np.__version__}, allantools {allantools.__version__}")
    print()
    print("| N | impl | taus | time s (median) | ns/sample/tau | samples/s | speed-up "
          "| peak extra mem / input |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for size in args.sizes:
        n = int(size)
        y = 15.0 + rng.standard_normal(n)
        input_bytes = y.nbytes
        n_taus = allan.averaging_factors(n, "octave").size
        reps = args.repeats if n <= 10_000_000 else 1
        t_ours, m_ours = measure(lambda y=y: allan.oadev(y, 100.0, taus="octave",
                                                         progress=False), reps)

        def row(impl: str, t: float, mem: float, ratio: str, n: int = n,
                n_taus: int = n_taus, input_bytes: int = input_bytes) -> None:
            print(f"| {n:.0e} | {impl} | {n_taus} | {t:.3f} | {t / n / n_taus * 1e9:.2f} | "
                  f"{n / t:.3g} | {ratio} | {mem / input_bytes:.3f} |")

        if n <= args.peer_max:
            t_peer, m_peer = measure(lambda y=y: allantools.oadev(
                y, rate=100.0, data_type="freq", taus="octave"), reps)
            row("allantools.oadev", t_peer, m_peer, "1.0")
            row("gyrodrift (C++)", t_ours, m_ours, f"{t_peer / t_ours:.1f}x")
        else:
            row("gyrodrift (C++)", t_ours, m_ours, "peer not run")
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "rec.npy"
            np.save(path, y)
            mm = np.load(path, mmap_mode="r")
            t_mm, m_mm = measure(lambda mm=mm: allan.oadev(mm, 100.0, taus="octave",
                                                           progress=False), 1)
            row("gyrodrift memmap, chunked", t_mm, m_mm, "-")
        del y


if __name__ == "__main__":
    main()
