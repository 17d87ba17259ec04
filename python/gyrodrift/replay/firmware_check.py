"""The firmware image held to the whole MCU budget: flash and RAM from the build, and the
instructions per loop step measured by a short replay on QEMU (scripts/build-firmware).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.codecs.wire import make_samples
from gyrodrift.imu.config import ProcessorConfig
from gyrodrift.io.atomic import atomic_write_text
from gyrodrift.replay.firmware import (
    ASSUMED_CPI,
    CORE_CLOCK_HZ,
    CPU_LOAD_GOAL,
    MONITOR_RAM_BUDGET_BYTES,
    QEMU_MACHINE,
    FirmwareError,
    FirmwareImage,
    budget_violations,
    build_firmware,
    instruction_budget,
)
from gyrodrift.replay.harness import ReplayOptions, run_replay
from gyrodrift.simulation.records import NoiseTerms, simulate_imu

__all__ = ["check_firmware", "measure_step_cost"]


def measure_step_cost(image: FirmwareImage, config: ProcessorConfig, *,
                      duration_s: float = 2.0, seed: int = 0) -> dict[str, Any]:
    """Instructions per step of `image` on QEMU over `duration_s` of simulated IMU data at
    the configuration's sample rate, replayed at 1x (the receive interrupts that land inside
    a step count with it, as on the MCU); raises FirmwareError if the replay itself fails.

    Examples
    --------
    Needs QEMU and a built image (tests/test_firmware_qemu.py runs this):

    >>> from gyrodrift.imu.config import default_config
    >>> from gyrodrift.replay.firmware import cached_firmware
    >>> cfg = default_config()
    >>> cost = measure_step_cost(cached_firmware(cfg), cfg)  # doctest: +SKIP
    >>> cost["instructions_max"] < 14000  # doctest: +SKIP
    True
    """
    rate = config.timing.sample_rate_hz
    rec = simulate_imu(duration_s, rate_hz=rate, seed=seed,
                       gyro=NoiseTerms(n_deg_rt_h=0.01, b_deg_h=0.01, ar2=(1.0, -0.25, 0.5)),
                       vrw_m_s_rt_h=0.02)
    n = rec.gyro_rad_s.shape[0]
    samples = make_samples(np.arange(n) / rate, rec.gyro_rad_s, rec.accel_m_s2)
    res = run_replay(samples, ReplayOptions(speed=1.0, target="qemu", firmware_image=image,
                                            processor=config, compare_host_loop=False,
                                            loop_realtime=False, harness_realtime=False))
    cost = (res.loop_stats or {}).get("step_cost")
    if not res.ok or not cost:
        failed = [k for k, v in res.report["checks"].items() if not v]
        raise FirmwareError(f"the image failed its measuring replay on {QEMU_MACHINE}: "
                            f"failed checks {failed}")
    return dict(cost)


def check_firmware(config: ProcessorConfig, out_dir: str | os.PathLike[str], *,
                   defines: tuple[str, ...] = ()) -> dict[str, Any]:
    """Build the image for `config` in `out_dir` and hold it to the whole budget: flash, RAM,
    and instructions per step (worst case of a measuring replay on QEMU) within
    `instruction_budget` at the configuration's loop rate. Returns the image's sizes and its
    step cost; raises FirmwareError with the reason otherwise (scripts/build-firmware).

    Examples
    --------
    A configuration with no firmware form is refused before anything is built or run:

    >>> import tempfile
    >>> from dataclasses import replace
    >>> from gyrodrift.imu.config import default_config
    >>> from gyrodrift.replay.firmware import FirmwareError
    >>> cfg = default_config()
    >>> gx = cfg.channel("gx")
    >>> soft = cfg.with_channel("gx", replace(gx, stages=(
    ...     replace(gx.stages[0], threshold="soft"), gx.stages[1])))
    >>> try:
    ...     check_firmware(soft, tempfile.mkdtemp())
    ... except FirmwareError as exc:
    ...     print(str(exc).split(":")[0])
    configuration refused for the firmware
    """
    image = build_firmware(config, out_dir, defines=defines, check_budget=False)
    monitor: dict[str, Any] | None = None
    why: list[str] = []
    if config.monitor.enabled:
        # the gyro monitor's share: the same configuration's image without it
        plain = build_firmware(config.with_monitor(enabled=False),
                               Path(out_dir) / "without_monitor", defines=defines,
                               check_budget=False)
        monitor = {"ram_bytes_without": plain.ram_bytes,
                   "flash_bytes_without": plain.flash_bytes,
                   "ram_delta_bytes": image.ram_bytes - plain.ram_bytes,
                   "stack_delta_bytes": image.stack_reserved - plain.stack_reserved,
                   "flash_delta_bytes": image.flash_bytes - plain.flash_bytes,
                   "ram_budget_bytes": MONITOR_RAM_BUDGET_BYTES}
        delta = monitor["ram_delta_bytes"]
        if delta > MONITOR_RAM_BUDGET_BYTES:
            stack = monitor["stack_delta_bytes"]
            of_which = (f"; {stack} B of the {delta} B is the stack reserved for the lag "
                        "identifier's fit" if stack else "")
            why.append(f"the gyro monitor takes {delta} B more RAM than the image without it "
                       f"({plain.ram_bytes} B{of_which}) > {MONITOR_RAM_BUDGET_BYTES} B by "
                       f"{delta - MONITOR_RAM_BUDGET_BYTES} B (fewer [monitor] octaves, fewer "
                       "monitored gyros, or the recursive identifier)")
    why += budget_violations(image)
    if why:  # refused before the measuring replay
        raise FirmwareError("the configuration does not fit the MCU budget: " + "; ".join(why))
    cost = measure_step_cost(image, config)
    budget = instruction_budget(config.timing.loop_hz)
    summary: dict[str, Any] = {"image": image.as_dict(), "step_cost": cost}
    if monitor is not None:
        summary["monitor"] = monitor
    atomic_write_text(Path(out_dir) / "budget.json", json.dumps(summary, indent=1) + "\n")
    if cost["instructions_max"] > budget:
        raise FirmwareError(
            f"the configuration does not fit the MCU budget: {cost['instructions_max']:.0f} "
            f"instructions per step (worst case) > {budget:.0f} (= {100 * CPU_LOAD_GOAL:g} % of "
            f"{CORE_CLOCK_HZ / 1e6:g} MHz at {config.timing.loop_hz:g} Hz, CPI {ASSUMED_CPI:g})")
    return summary
