"""Benchmark: octave-tau overlapping ADEV on float64 records, gyrodrift (C++ kernel) vs
allantools.oadev in the same process. Prints a markdown table (median of repeats) with time,
ns per sample per tau, samples/s, speed-up, and peak extra memory (tracemalloc: numpy
registers its buffers with it; the C++ workspaces, a few MB, are not traced) relative to the
input array; plus the memory-mapped path (file reads, bounded memory).

    PYTHONPATH=python:build/dev-NAME/py python3 benchmarks/bench_allan.py [--sizes 1e6 1e7 1e8]
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import allantools
import numpy as np
from _bench_util import machine
from _bench_util import measure_wall_cpu_peak as measure
from gyrodrift.stability import allan


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e6, 1e7, 1e8])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--peer-max", type=float, default=1e8,
                    help="largest size allantools is run at (memory/time on a shared host)")
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    threads = os.cpu_count() or 1  # what oadev(threads=None) uses
    print(f"Machine: {machine()}; numpy {np.__version__}, allantools {allantools.__version__}")
    print()
    print("| N | impl | taus | wall s | CPU s | CPU ns/sample/tau | samples/s (CPU) "
          "| speed-up wall / CPU | peak extra mem / input |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    warm = rng.standard_normal(10_000)  # imports, scipy.stats and first-call costs
    allan.oadev(warm, 1.0)
    allantools.oadev(warm, rate=1.0, data_type="freq", taus="octave")
    for size in args.sizes:
        n = int(size)
        y = 15.0 + rng.standard_normal(n)
        input_bytes = y.nbytes
        n_taus = allan.averaging_factors(n, "octave").size
        reps = args.repeats if n <= 10_000_000 else 1
        ours = measure(lambda y=y: allan.oadev(y, 100.0, taus="octave", progress=False), reps)
        ours1 = measure(lambda y=y: allan.oadev(y, 100.0, taus="octave", progress=False,
                                                threads=1), reps)

        def row(impl: str, r: tuple[float, float, float], ratio: str, n: int = n,
                n_taus: int = n_taus, input_bytes: int = input_bytes) -> None:
            wall, cpu, mem = r
            print(f"| {n:.0e} | {impl} | {n_taus} | {wall:.3f} | {cpu:.3f} | "
                  f"{cpu / n / n_taus * 1e9:.2f} | {n / cpu:.3g} | {ratio} | "
                  f"{mem / input_bytes:.3f} |")

        if n <= args.peer_max:
            peer = measure(lambda y=y: allantools.oadev(y, rate=100.0, data_type="freq",
                                                        taus="octave"), reps)
            row("allantools.oadev", peer, "1.0")
            row(f"gyrodrift (C++ fused, {threads} threads)", ours,
                f"{peer[0] / ours[0]:.1f}x / {peer[1] / ours[1]:.1f}x")
            row("gyrodrift (C++ fused, 1 thread)", ours1,
                f"{peer[0] / ours1[0]:.1f}x / {peer[1] / ours1[1]:.1f}x")
        else:
            row(f"gyrodrift (C++ fused, {threads} threads)", ours, "peer not run")
            row("gyrodrift (C++ fused, 1 thread)", ours1, "peer not run")
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "rec.npy"
            np.save(path, y)
            mm = np.load(path, mmap_mode="r")
            mapped = measure(lambda mm=mm: allan.oadev(mm, 100.0, taus="octave",
                                                       progress=False), 1)
            row("gyrodrift memmap (file reads)", mapped, "-")
        del y


if __name__ == "__main__":
    main()
