"""Alignment benchmark: per-sample cost of the C++ pipeline (through the binding)
vs the numpy reference in the same process, the 15-state KF cycle vs FilterPy, and the Monte
Carlo wall time (goal: 30 runs x 30 min x 2 configurations < 2 min on this 2-core machine).

    python benchmarks/bench_align.py [--runs 30] [--duration-s 1800] [--scenario ship_mild]

Medians of repeats; wall-clock time on a shared machine (the load average is printed).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from _bench_util import machine, median_seconds
from filterpy.kalman import KalmanFilter as FilterPyKF
from gyrodrift.filters.fir import forced_fir_taps
from gyrodrift.nav import (
    AlignConfig,
    imu_increments,
    run_alignment,
    scenario,
    strapdown_run,
    truth_at,
)
from gyrodrift.nav.attitude import dcm2q
from gyrodrift.papers.alignment_study import StudyConfig, run_study
from gyrodrift.papers.imu_errors import ImuErrors, add_imu_errors
from gyrodrift.reference.align import FineAlignKF, run_alignment_reference


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--duration-s", type=float, default=1800.0)
    ap.add_argument("--scenario", default="ship_mild")
    args = ap.parse_args()
    print(f"machine: {machine()}; load average at start {os.getloadavg()[0]:.1f}")

    sc = scenario(args.scenario)
    dt = 1.0 / 400.0
    n = 400 * 120
    dth, dv = imu_increments(sc, n, dt)
    dth, dv = add_imu_errors(dth, dv, dt, ImuErrors(), seed=1)
    taps = forced_fir_taps("db4", 256, 5)
    base = {"dt_s": dt, "lat_rad": sc.lat_rad, "lon_rad": sc.lon_rad, "h_m": sc.h_m,
            "zv_sigma_m_s": sc.zero_velocity_sigma_m_s}
    cfg_raw = AlignConfig(**base)
    cfg_pre = AlignConfig(**base, taps=taps, accel_delay_samples=8)
    n_ref = 400 * 70  # the reference is slow: 60 s coarse + 10 s fine
    t_cpp_raw = median_seconds(lambda: run_alignment(dth, dv, cfg_raw)) / n
    t_cpp_pre = median_seconds(lambda: run_alignment(dth, dv, cfg_pre)) / n
    t_ref_raw = median_seconds(lambda: run_alignment_reference(dth[:n_ref], dv[:n_ref], cfg_raw),
                               repeats=1) / n_ref
    tr0 = truth_at(sc, np.array([0.0]))
    t_sd = median_seconds(lambda: strapdown_run(dth, dv, dt, dcm2q(tr0["cnb"][0]), tr0["vn"][0],
                                                np.array([sc.lat_rad, sc.lon_rad, sc.h_m]))) / n

    # KF cycle: ours (C++ pipeline minus C++ strapdown, per 40-sample cycle) vs the numpy
    # reference KF and FilterPy (predict + update with the same 15x15 F, Q, 3x15 H, R).
    kf_ref = FineAlignKF(15, cfg_raw.p0_diag(), cfg_raw.q_diag(), np.full(3, 0.04),
                         cfg_raw.floor_diag())
    rng = np.random.default_rng(0)
    f = rng.standard_normal((15, 15)) * 1e-3
    z = np.array([0.01, -0.02, 0.005])

    def ref_cycles() -> None:
        for _ in range(200):
            kf_ref.predict(f, 0.1)
            kf_ref.update(z)

    fp = FilterPyKF(dim_x=15, dim_z=3)
    fp.F = np.eye(15) + f * 0.1
    fp.Q = np.diag(cfg_raw.q_diag()) * 0.1
    fp.H = np.zeros((3, 15))
    fp.H[:, 3:6] = np.eye(3)
    fp.R = np.eye(3) * 0.04
    fp.P = np.diag(cfg_raw.p0_diag())

    def fp_cycles() -> None:
        for _ in range(200):
            fp.predict()
            fp.update(z)

    t_kf_ref = median_seconds(ref_cycles) / 200
    t_kf_fp = median_seconds(fp_cycles) / 200
    t_kf_cpp = (t_cpp_raw - t_sd) * 40

    print("\n| what | ns/sample | samples/s | ratio vs C++ pipeline |")
    print("| --- | --- | --- | --- |")
    for name, t in (("C++ pipeline (mechanization + 15-state KF @10 Hz), binding", t_cpp_raw),
                    ("C++ pipeline + 256-tap wavelet prefilter, binding", t_cpp_pre),
                    ("C++ strapdown alone, binding", t_sd),
                    ("numpy reference pipeline (same algorithm)", t_ref_raw)):
        print(f"| {name} | {t * 1e9:.0f} | {1 / t:.3g} | {t / t_cpp_raw:.2f} |")
    print("\n| KF cycle (predict + zero-velocity update, 15 states) | us/cycle | ratio vs C++ |")
    print("| --- | --- | --- |")
    for name, t in (("C++ (pipeline - strapdown, x40 samples)", t_kf_cpp),
                    ("numpy reference (Joseph, Cholesky)", t_kf_ref),
                    ("FilterPy KalmanFilter (peer)", t_kf_fp)):
        print(f"| {name} | {t * 1e6:.1f} | {t / t_kf_cpp:.1f} |")

    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    res, _ = run_study(StudyConfig(scenario=args.scenario, runs=args.runs,
                                   duration_s=args.duration_s))
    wall = time.perf_counter() - t0
    align_s = sum(r.wall_s for r in res.values())
    samples = sum(r.samples for r in res.values())
    print(f"\n| Monte Carlo ({args.scenario}) | runs x min x configs | wall s | C++ alignment s "
          "| ns/sample (alignment) | load avg (start/end) |")
    print("| --- | --- | --- | --- | --- | --- |")
    print(f"| truth + errors + 2 alignments + analysis | {args.runs} x {args.duration_s:g} s x 2 "
          f"| {wall:.1f} | {align_s:.1f} | {align_s / samples * 1e9:.0f} "
          f"| {load0:.1f} / {os.getloadavg()[0]:.1f} |")


if __name__ == "__main__":
    main()
