"""Helpers shared by the benchmark scripts: the machine line and medians of repeats.

The scripts run as `python3 benchmarks/bench_<area>.py`, so this directory is sys.path[0]
and they import this module as `from _bench_util import ...`.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import time
import tracemalloc
from collections.abc import Callable


def machine() -> str:
    """CPU model and logical CPU count from `lscpu` (what every benchmark table prints)."""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return f"unknown CPU, {os.cpu_count()} CPUs"
    fields = dict(line.split(":", 1) for line in out.splitlines() if ":" in line)
    model = fields.get("Model name", "unknown CPU").strip()
    cpus = fields.get("CPU(s)", str(os.cpu_count())).strip()
    return f"{model}, {cpus} CPUs"


def median_seconds(
    fn: Callable[[], object],
    repeats: int = 5,
    clock: Callable[[], float] = time.perf_counter,
) -> float:
    """Median over `repeats` calls of fn's duration on `clock` (wall time by default; pass
    time.thread_time to not count time spent preempted on the shared machine)."""
    times = []
    for _ in range(repeats):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return statistics.median(times)


def measure_side_by_side(fns: dict[str, Callable[[], object]], repeats: int
                         ) -> dict[str, tuple[float, float, float]]:
    """{name: (median wall s, median CPU s, peak traced bytes)} for several functions timed
    in turns (repeat r runs every function once), so a change in the machine's load hits
    all of them alike; the times are taken with tracemalloc off (its per-allocation hook
    taxes code with many small allocations more than numpy-bulk code), the peak in one
    extra traced call of each.
    """
    walls: dict[str, list[float]] = {k: [] for k in fns}
    cpus: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            c0, t0 = time.process_time(), time.perf_counter()
            fn()
            walls[name].append(time.perf_counter() - t0)
            cpus[name].append(time.process_time() - c0)
    out = {}
    for name, fn in fns.items():
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        fn()
        peak = tracemalloc.get_traced_memory()[1] - base
        tracemalloc.stop()
        out[name] = (statistics.median(walls[name]), statistics.median(cpus[name]), float(peak))
    return out


def measure_wall_cpu_peak(fn: Callable[[], object], repeats: int) -> tuple[float, float, float]:
    """(median wall s, median CPU s of this process, peak traced bytes above the start).

    CPU time is reported too because this machine is shared: under load, wall time mostly
    measures the neighbours; CPU time still includes cache/memory contention.
    """
    walls, cpus = [], []
    peak = 0
    for _ in range(repeats):
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        peak = max(peak, tracemalloc.get_traced_memory()[1] - base)
        tracemalloc.stop()
    return statistics.median(walls), statistics.median(cpus), float(peak)
