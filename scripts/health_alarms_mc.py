#!/usr/bin/env python3
"""Monte Carlo of the gyro health alarms (gyrodrift.stability.health, the C++ the target runs,
float state): the false-alarm rate per hour on stationary simulated records with the exact
reference curve, and the detection delays of a 2x angle random walk and a 2x bias
instability increase.

    PYTHONPATH=python:build/dev-NAME/py python scripts/health_alarms_mc.py [--full]

Cases (seeds fixed: the same command gives the same table):
- ar2-fast: AR(2) drift + white (a1, a2 = 0.6868, -0.0213, q = 0.25, r = 0.09) at 400 Hz;
- ar2-slow: AR(2) drift + white (double root 0.995, q = 1e-5, r = 1) at 400 Hz;
- consumer-mems, navigation-fog: the presets without their warm-up, reference = the exact
  expected Allan variance of the generating process (PresetTruth.avar_m);
and for the delays: ar2-slow with r x4 (2x ARW) or q x4 (2x the drift, the bias-instability
octaves) at the middle of each 1 h record; consumer-mems with its flicker B doubled (an
independent flicker of sqrt(3) B added) at the middle of each 4 h record.
The AR(2) cases use the model's edf per term (ar2_white_edf_per_term), the presets the one
from the reference's local slope. Default settings (factors 2, false_alarm_probability 1e-6,
block_terms 64) except the
bias-instability factor 1.5 in the 2x B cases (with 2 the increase sits on the threshold).
The default run is small (a few minutes); --full is the run in
docs/validation/health-alarms.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import platform
import subprocess
import time

import numpy as np
import scipy.signal
import scipy.stats
from gyrodrift.simulation.presets import PRESETS, kasdin_flicker, simulate_preset
from gyrodrift.stability.health import HealthAlarms, HealthAlarmSettings
from gyrodrift.stability.model_allan import ar2_white_avar, ar2_white_edf_per_term

AR2_FAST = (0.6868, -0.0213, 0.25, 0.09)
AR2_SLOW = (1.99, -0.990025, 1e-5, 1.0)
RATE_HZ = 400.0
OCTAVES = 18


def ar2_white(rng: np.random.Generator, model: tuple[float, float, float, float], n: int,
              q_scale: np.ndarray | float = 1.0, r_scale: np.ndarray | float = 1.0) -> np.ndarray:
    a1, a2, q, r = model
    burn = 20_000
    w = rng.standard_normal(n + burn) * math.sqrt(q)
    w[burn:] *= np.sqrt(np.broadcast_to(q_scale, (n,)))
    x = scipy.signal.lfilter([1.0], [1.0, -a1, -a2], w)[burn:]
    v = rng.standard_normal(n) * math.sqrt(r) * np.sqrt(np.broadcast_to(r_scale, (n,)))
    return (x + v).astype(np.float32)


def false_alarms(case: str, records: int, hours: float) -> tuple[float, int, list[str]]:
    """Total hours, records with an alarm, names of the alarms raised."""
    raised: list[str] = []
    total_h = 0.0
    with_alarm = 0
    for seed in range(records):
        rng = np.random.default_rng(1000 + seed)
        if case.startswith("ar2"):
            model = AR2_FAST if case == "ar2-fast" else AR2_SLOW
            n = int(hours * 3600 * RATE_HZ)
            y, rate = ar2_white(rng, model, n), RATE_HZ
            ref = ar2_white_avar(*model, OCTAVES)
            edf = ar2_white_edf_per_term(*model, OCTAVES)
        else:
            preset = dataclasses.replace(PRESETS[case], warmup=None)
            n = int(hours * 3600 * preset.rate_hz)
            rec = simulate_preset(preset, n, seed=1000 + seed)
            y, rate = rec.gyro_deg_h.astype(np.float32), rec.rate_hz
            octaves = min(OCTAVES, int(math.log2(n // 2)))
            ref = rec.truth.avar_m(2 ** np.arange(octaves))
            edf = None
        ha = HealthAlarms(rate, ref, edf_per_term=edf, dtype=np.float32)
        bits = ha.run(y, every=len(y))
        total_h += len(y) / rate / 3600.0
        if bits[-1]:
            with_alarm += 1
            raised.extend(ha.latched)
    return total_h, with_alarm, raised


def delays(case: str, records: int) -> tuple[list[float], int]:
    """Detection delays (s) of the expected alarm, and the records where it was missed."""
    out: list[float] = []
    missed = 0
    for seed in range(records):
        rng = np.random.default_rng(5000 + seed)
        if case in ("2x-arw", "2x-drift"):
            n = int(3600 * RATE_HZ)
            t0 = n // 2
            scale = np.ones(n)
            scale[t0:] = 4.0
            y = ar2_white(rng, AR2_SLOW, n, q_scale=scale if case == "2x-drift" else 1.0,
                          r_scale=scale if case == "2x-arw" else 1.0)
            ref = ar2_white_avar(*AR2_SLOW, OCTAVES)
            edf = ar2_white_edf_per_term(*AR2_SLOW, OCTAVES)
            rate = RATE_HZ
            settings = HealthAlarmSettings(
                bias_instability_factor=1.5 if case == "2x-drift" else 2.0)
            name = "arw_high" if case == "2x-arw" else "bias_instability_high"
        else:
            preset = dataclasses.replace(PRESETS["consumer-mems"], warmup=None)
            n = int(4 * 3600 * preset.rate_hz)
            t0 = n // 2
            rec = simulate_preset(preset, n, seed=5000 + seed)
            extra = kasdin_flicker(rng, math.sqrt(3.0) * preset.b_deg_h, n - t0)
            y = rec.gyro_deg_h.copy()
            y[t0:] += extra
            y = y.astype(np.float32)
            rate = preset.rate_hz
            ref = rec.truth.avar_m(2 ** np.arange(OCTAVES))
            edf = None
            settings = HealthAlarmSettings(bias_instability_factor=1.5)
            name = "bias_instability_high"
        ha = HealthAlarms(rate, ref, settings, edf_per_term=edf, dtype=np.float32)
        ha.run(y, every=len(y))
        trip = ha.trips.get(name)
        if trip is None or trip.sample <= t0:
            missed += 1
        else:
            out.append((trip.sample - t0) / rate)
    return out, missed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="the run of the validation page")
    args = ap.parse_args()
    fa_records, fa_hours, d_records = (20, 5.0, 50) if args.full else (4, 1.0, 10)
    started = time.time()
    print(f"date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    cpu = subprocess.run(["sh", "-c", "lscpu | grep 'Model name'"], capture_output=True,
                         text=True, check=False).stdout.strip()
    print(f"machine: {cpu or platform.processor()}")
    load = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout
    print(f"load: {load.strip()}")
    print()
    print("| stationary case | hours | records with an alarm | rate per hour (95 % upper) "
          "| alarms |")
    print("| --- | --- | --- | --- | --- |")
    for case in ("ar2-fast", "ar2-slow", "consumer-mems", "navigation-fog"):
        hours = fa_hours * (10.0 if case == "navigation-fog" else 1.0)  # 10 Hz: longer records
        total_h, with_alarm, names = false_alarms(case, fa_records, hours)
        # 95 % upper limit of a Poisson rate with k events: chi2_{0.95}(2k + 2) / 2 / T
        upper = scipy.stats.chi2.ppf(0.95, 2 * with_alarm + 2) / 2.0 / total_h
        print(f"| {case} | {total_h:.0f} | {with_alarm} | {with_alarm / total_h:.3g} "
              f"({upper:.2g}) | {', '.join(sorted(set(names))) or '-'} |")
    print()
    print("| change at mid-record | records | missed | delay median (s) | 90 % (s) | max (s) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for case in ("2x-arw", "2x-drift", "2x-flicker-b"):
        d, missed = delays(case, d_records)
        if d:
            q = np.percentile(d, [50, 90])
            print(f"| {case} | {d_records} | {missed} | {q[0]:.3g} | {q[1]:.3g} | {max(d):.3g} |")
        else:
            print(f"| {case} | {d_records} | {missed} | - | - | - |")
    print()
    print(f"wall time: {time.time() - started:.0f} s")


if __name__ == "__main__":
    main()
