"""Benchmark: AR(2)-Kalman speed, C++ step / batch binding vs numpy reference and FilterPy.

Prints one markdown table (ns per sample per axis, M samples/s, speed-up vs FilterPy and vs
the numpy reference, all measured in this process, medians of repeats) and the machine.
The C++-only step timings come from cpp/bench/bench_kalman.cpp (taken from
$GYRODRIFT_CPP_BUILD_DIR/cpp/bench_kalman, else compiled here with g++ -O3).
Not a test: the machine is shared and noisy.

    PYTHONPATH=python:build/<dir>/py python3 benchmarks/bench_kalman.py [--n 10000000]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path

import gyrodrift
import gyrodrift.reference as ref
import numpy as np
from _bench_util import machine, median_seconds
from filterpy.kalman import KalmanFilter as FilterPyKF

REPO = Path(__file__).resolve().parent.parent


def filterpy_run(x: np.ndarray, m: gyrodrift.Ar2Model) -> np.ndarray:
    kf = FilterPyKF(dim_x=2, dim_z=1)
    kf.F = np.array([[m.a1, m.a2], [1.0, 0.0]])
    kf.H = np.array([[1.0, 0.0]])
    kf.Q = np.diag([m.sigma2, 0.0])
    kf.R = np.array([[m.r]])
    kf.P = np.eye(2)
    kf.x = np.zeros((2, 1))
    out = np.empty_like(x)
    for k, y in enumerate(x):
        kf.predict()
        kf.update(y - m.mean)
        out[k] = kf.x[0, 0] + m.mean
    return out


def cpp_bench_rows(n: int, repeats: int) -> list[tuple[str, float]]:
    exe = None
    build = os.environ.get("GYRODRIFT_CPP_BUILD_DIR")
    if build and (Path(build) / "cpp" / "bench_kalman").exists():
        exe = Path(build) / "cpp" / "bench_kalman"
    tmp = None
    if exe is None:
        gxx = shutil.which("g++")
        if gxx is None:
            return []
        tmp = tempfile.mkdtemp()
        exe = Path(tmp) / "bench_kalman"
        subprocess.run(
            [gxx, "-std=c++17", "-O3", "-DNDEBUG", f"-I{REPO / 'include'}",
             "-isystem", "/usr/include/eigen3", str(REPO / "cpp/bench/bench_kalman.cpp"),
             "-o", str(exe)],
            check=True,
        )
    out = subprocess.run([str(exe), str(n), str(repeats)], capture_output=True, text=True,
                         check=True).stdout
    if tmp:
        shutil.rmtree(tmp, ignore_errors=True)
    rows = []
    for line in out.splitlines()[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows.append((cells[0], float(cells[1])))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=10_000_000, help="samples for the batch binding")
    parser.add_argument("--slow-n", type=int, default=20_000,
                        help="samples for FilterPy / numpy reference / per-sample Python loop")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    n, slow_n, repeats = args.n, args.slow_n, args.repeats

    rec = gyrodrift.simulate(n=n, ar2=(0.6868, -0.0213, 0.3), bias_deg_h=9.7, seed=1)
    x = rec.rate_deg_h
    x32 = x.astype(np.float32)
    x3 = np.ascontiguousarray(np.stack([x, x[::-1], -x], axis=1)[: n // 3])
    m = gyrodrift.fit_ar2(x[:100_000], "burg")
    xs = np.ascontiguousarray(x[:slow_n])
    out_buf = np.empty_like(x)

    def per_sample_python() -> None:
        kf = gyrodrift.KalmanFilter(m)
        for y in xs:
            kf.step(y)

    # (label, samples x axes processed, callable)
    cases: list[tuple[str, int, Callable[[], object]]] = [
        ("batch binding, double, 1-D", n, lambda: gyrodrift.kalman_filter(x, m)),
        ("batch binding, double, 1-D, out= (no allocation)", n,
         lambda: gyrodrift.kalman_filter(x, m, out=out_buf)),
        ("batch binding, float, 1-D", n, lambda: gyrodrift.kalman_filter(x32, m)),
        ("batch binding, double, (n, 3)", x3.size, lambda: gyrodrift.kalman_filter(x3, m)),
        ("batch binding, steady-state, double, 1-D", n,
         lambda: gyrodrift.kalman_filter(x, m, steady_state=True)),
        ("KalmanFilter.step from Python (per-sample object)", slow_n, per_sample_python),
        ("numpy reference (gyrodrift.reference.kalman_filter)", slow_n,
         lambda: ref.kalman_filter(xs, m)),
        ("FilterPy KalmanFilter (predict + update)", slow_n, lambda: filterpy_run(xs, m)),
    ]
    results: list[tuple[str, float]] = []
    for label, count, fn in cases:
        fn()  # warm-up
        reps = repeats if count > slow_n else max(3, repeats // 2)
        results.append((label, median_seconds(fn, reps) / count * 1e9))
    cpp_rows = cpp_bench_rows(1_000_000, 7)
    t_filterpy = results[-1][1]
    t_numpy = results[-2][1]

    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    print(f"AR(2)-Kalman benchmark; machine: {machine()}; load average {load} (shared machine)")
    print(f"batch n = {n:,}; FilterPy / numpy / Python-loop n = {slow_n:,}; medians of repeats\n")
    print("| case | ns/sample/axis | M samples/s | vs FilterPy | vs numpy reference |")
    print("| --- | ---: | ---: | ---: | ---: |")
    def ratio(v: float) -> str:
        return f"{v:,.0f}x" if v >= 10 else f"{v:.2f}x"

    for label, ns in cpp_rows + results:
        print(f"| {label} | {ns:.2f} | {1e3 / ns:.3g} | {ratio(t_filterpy / ns)} "
              f"| {ratio(t_numpy / ns)} |")


if __name__ == "__main__":
    main()
