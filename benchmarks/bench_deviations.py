"""Benchmark: the deviation family (mdev, tdev, hdev, ohdev, totdev), gyrodrift's C++ kernels
vs allantools' functions of the same name in the same process, octave taus on float64 rate
records (the same taus and term counts on both sides: tests/test_deviation.py). Both
return the deviation per tau; gyrodrift adds the edf and chi-squared interval per tau
(allantools its simple dev/sqrt(n) error). Prints a markdown table (median of repeats, the
implementations timed in turns with tracemalloc off, wall and CPU time, CPU ns per sample
per tau, speed-up, peak extra memory from one traced call relative to the input; the C++
workspaces (std::vector, bounded: at most 8 MiB per factor group) are not traced), plus the
memory-mapped path (chunked file reads).
The deviation kernel alone is timed (alpha=0: no noise identification; the default lag-1
ACF noise ID, timed in its own row, reads at most 16384 averages per tau).

    PYTHONPATH=python:build/dev-NAME/py python3 benchmarks/bench_deviations.py [--sizes 1e6]
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import allantools
import gyrodrift
import numpy as np
from _bench_util import machine, measure_side_by_side
from _bench_util import measure_wall_cpu_peak as measure

NAMES = ("mdev", "tdev", "hdev", "ohdev", "totdev")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e6])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    threads = os.cpu_count() or 1
    with open("/proc/loadavg") as fh:
        load = fh.read().split()[:3]
    print(f"Machine: {machine()}; load average {' '.join(load)}; numpy {np.__version__}, "
          f"allantools {allantools.__version__}")
    print()
    print("| N | deviation | impl | taus | wall s | CPU s | CPU ns/sample/tau | "
          "speed-up wall / CPU | peak extra mem / input |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    warm = rng.standard_normal(10_000)
    for name in NAMES:
        gyrodrift.deviation(warm, 1.0, name)
        getattr(allantools, name)(warm, rate=1.0, data_type="freq", taus="octave")
    for size in args.sizes:
        n = int(size)
        y = 15.0 + rng.standard_normal(n)
        for name in NAMES:
            res = gyrodrift.deviation(y, 100.0, name, alpha=0)
            n_taus = res.m.size

            def row(impl: str, r: tuple[float, float, float], ratio: str, n: int = n,
                    n_taus: int = n_taus, name: str = name, nbytes: int = y.nbytes) -> None:
                wall, cpu, mem = r
                print(f"| {n:.0e} | {name} | {impl} | {n_taus} | {wall:.4f} | {cpu:.4f} | "
                      f"{cpu / n / n_taus * 1e9:.2f} | {ratio} | {mem / nbytes:.3f} |")

            runs = measure_side_by_side({
                "peer": lambda name=name, y=y: getattr(allantools, name)(
                    y, rate=100.0, data_type="freq", taus="octave"),
                "ours": lambda name=name, y=y: gyrodrift.deviation(y, 100.0, name, alpha=0),
                "ours1": lambda name=name, y=y: gyrodrift.deviation(y, 100.0, name, alpha=0,
                                                                    threads=1),
                "full": lambda name=name, y=y: gyrodrift.deviation(y, 100.0, name),
            }, args.repeats)
            peer, ours, ours1, full = (runs[k] for k in ("peer", "ours", "ours1", "full"))
            row("allantools", peer, "1.0")
            row(f"gyrodrift ({threads} threads)", ours,
                f"{peer[0] / ours[0]:.1f}x / {peer[1] / ours[1]:.1f}x")
            row("gyrodrift (1 thread)", ours1,
                f"{peer[0] / ours1[0]:.1f}x / {peer[1] / ours1[1]:.1f}x")
            row("gyrodrift + ACF noise ID + CI", full,
                f"{peer[0] / full[0]:.1f}x / {peer[1] / full[1]:.1f}x")
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / "rec.npy"
                np.save(path, y)
                mm = np.load(path, mmap_mode="r")
                mapped = measure(lambda mm=mm, name=name: gyrodrift.deviation(
                    mm, 100.0, name, alpha=0), 1)
                row("gyrodrift memmap (chunked file reads)", mapped, "-")


if __name__ == "__main__":
    main()
