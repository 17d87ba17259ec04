"""The reference firmware image's size, stack and cost with and without the gyro monitor, for
docs/validation/monitor-firmware.md and docs/validation/firmware.md: each configuration built
(`build_firmware(..., check_budget=False)`, so that images over a budget are measured too),
then a measuring replay at 1x on QEMU (`-icount shift=0`: instructions per step, the stack's
high-water mark). With the lag identifier also its fits: a 22 s record at 50 Hz with a fit
every 6 s per gyro, run as `tests/test_firmware_qemu.py` runs it (the fits' own instructions
in thread mode, late fits), and a measurement build whose fits run with interrupts masked on
freshly painted stack (the fit's own stack below thread mode's frame).

Usage (prints Markdown table rows; minutes: one build and replay per row):
  PYTHONPATH=python:BUILD/py GYRODRIFT_CPP_BUILD_DIR=BUILD \
      python scripts/firmware_monitor_measure.py [--only lag]
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from gyrodrift.codecs.wire import Samples, make_samples
from gyrodrift.imu.config import (
    Ar2KalmanStage,
    ProcessorConfig,
    default_config,
    drift_filter_config,
)
from gyrodrift.replay.faults import FaultSpec
from gyrodrift.replay.firmware import FirmwareImage, build_firmware
from gyrodrift.replay.harness import ReplayOptions, run_replay
from gyrodrift.simulation.records import NoiseTerms, simulate_imu


def gyros_config(gyros: int, rate_hz: float) -> ProcessorConfig:
    """One gyro: the AR(2)-Kalman stage on gz alone, every other channel passed through; two:
    the default configuration with the stage alone on gx and gy (gz keeps its wavelet stage);
    three: the stage alone on gx, gy, gz."""
    if gyros == 1:
        cfg = drift_filter_config("gz", a1=1.0, a2=-0.25, mean=0.0, q=1e-10, r=1e-8,
                                  sample_rate_hz=rate_hz)
        return cfg.with_channel("gz", replace(cfg.channel("gz"), saturation=8.0,
                                              stuck_samples=50))
    cfg = default_config(sample_rate_hz=rate_hz)
    for name in ("gx", "gy", "gz")[:gyros]:
        ch = cfg.channel(name)
        cfg = cfg.with_channel(name, replace(ch, stages=tuple(
            s for s in ch.stages if isinstance(s, Ar2KalmanStage))))
    return cfg


def monitor(cfg: ProcessorConfig, kind: str, **fields: Any) -> ProcessorConfig:
    """kind: none (the monitor off), watch (no re-identification), recursive, lag."""
    if kind == "none":
        return cfg.with_monitor(enabled=False)
    return cfg.with_monitor(enabled=True, octaves=16, reidentify=kind != "watch",
                            identifier="lag" if kind == "lag" else "recursive", **fields)


def simulated(duration_s: float, rate_hz: float, seed: int) -> Samples:
    rec = simulate_imu(duration_s, rate_hz=rate_hz, seed=seed,
                       gyro=NoiseTerms(n_deg_rt_h=0.01, b_deg_h=0.01, ar2=(1.0, -0.25, 0.5)),
                       vrw_m_s_rt_h=0.02)
    n = rec.gyro_rad_s.shape[0]
    return make_samples(np.arange(n) / rate_hz, rec.gyro_rad_s, rec.accel_m_s2)


def ar2_record(n: int, rate_hz: float, seed: int) -> Samples:
    """AR(2) drift (a1 = 1, a2 = -0.25, q = 1e-10) plus white noise (r = 1e-10) on each gyro."""
    rng = np.random.default_rng(seed)
    gyro = np.empty((n, 3))
    for c in range(3):
        w = rng.normal(0.0, 1e-5, n)
        x = np.zeros(n)
        for k in range(n):
            x[k] = w[k] + (x[k - 1] if k >= 1 else 0.0) - 0.25 * (x[k - 2] if k >= 2 else 0.0)
        gyro[:, c] = x + rng.normal(0.0, 1e-5, n)
    accel = simulated(n / rate_hz, rate_hz, seed).channels[:n, 3:]
    return make_samples(np.arange(n) / rate_hz, gyro, accel)


def run(image: FirmwareImage, cfg: ProcessorConfig, samples: Samples) -> dict[str, Any]:
    res = run_replay(samples, ReplayOptions(speed=1.0, target="qemu", firmware_image=image,
                                            processor=cfg, faults=FaultSpec(seed=1),
                                            compare_host_loop=False, loop_realtime=False,
                                            harness_realtime=False))
    loop = res.loop_stats or {}
    return {"firmware": loop.get("firmware", {}), "cost": loop.get("step_cost") or {},
            "health": loop.get("health", {})}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=["lag"], help="the lag identifier's rows only")
    args = ap.parse_args()
    out = Path(tempfile.mkdtemp(prefix="gyrodrift-fw-measure-"))
    kinds = ("none", "lag") if args.only else ("none", "watch", "recursive", "lag")
    for gyros in (1, 2, 3):
        plain_ram = 0
        for kind in kinds:
            if kind == "lag" and gyros == 2:
                continue
            cfg = monitor(gyros_config(gyros, 400.0), kind)
            image = build_firmware(cfg, out / f"g{gyros}-{kind}", check_budget=False)
            r = run(image, cfg, simulated(2.0, 400.0, seed=0))
            c, fw = r["cost"], r["firmware"]
            plain_ram = image.ram_bytes if kind == "none" else plain_ram
            delta = "-" if kind == "none" else f"+{image.ram_bytes - plain_ram} B"
            print(f"| {gyros} gyros, {kind} | {image.flash_bytes} B | {image.ram_bytes} B "
                  f"({image.data} + {image.bss} + {image.stack_reserved}) | {delta} | "
                  f"{fw.get('stack_bytes')} B | {c.get('instructions_median'):.0f} / "
                  f"{c.get('instructions_max'):.0f} |", flush=True)
    # the lag identifier's fits: the schedule of tests/test_firmware_qemu.py's lag_config
    fields = {"retune_s": 6.0, "fit_delay_s": 2.0, "min_learn_s": 2.0,
              "identified_max_rel_stderr": 10.0, "max_step": 1.0}
    for gyros in (1, 3):
        cfg = monitor(gyros_config(gyros, 50.0), "lag", **fields)
        samples = ar2_record(1100, 50.0, seed=5)
        image = build_firmware(cfg, out / f"fits{gyros}", check_budget=False)
        r = run(image, cfg, samples)
        probe = build_firmware(cfg, out / f"probe{gyros}", check_budget=False,
                               defines=("GYRODRIFT_FW_MEASURE_FIT_STACK",))
        p = run(probe, cfg, samples)
        sim = run(image, cfg, simulated(22.0, 50.0, seed=5))  # fits the guards refuse
        c, fw, pf, cs = r["cost"], r["firmware"], p["firmware"], sim["cost"]
        above = pf.get("stack_bytes", 0) - pf.get("fit_stack_bytes", 0)
        print(f"lag, {gyros} gyros, 50 Hz: fits run {c.get('fits_run')}, late "
              f"{fw.get('monitor_late_fits')}, retunes {r['health'].get('monitor_retunes')}, "
              f"refused {r['health'].get('monitor_refused_retunes')}; instructions per fit "
              f"{c.get('fit_instructions_min'):.3g} .. {c.get('fit_instructions_max'):.3g}; "
              f"stack high-water {fw.get('stack_bytes')} B of {image.stack_reserved} B; the "
              f"fit's own stack {pf.get('fit_stack_bytes')} B, thread mode's frames above "
              f"it {above} B; the simulated IMU record: fits run {cs.get('fits_run')}, late "
              f"{sim['firmware'].get('monitor_late_fits')}, retunes "
              f"{sim['health'].get('monitor_retunes')}, refused "
              f"{sim['health'].get('monitor_refused_retunes')}, instructions per fit "
              f"{cs.get('fit_instructions_min'):.3g} .. {cs.get('fit_instructions_max'):.3g}, "
              f"stack high-water {sim['firmware'].get('stack_bytes')} B",
              flush=True)


if __name__ == "__main__":
    main()
