"""The real laser-gyro record (/work/shared/data/lasergyro.imu, PSINS format, 100 Hz) replayed
through the loop with an AR(2) model identified from the record itself and stuck-channel
detection on: the quantized counts repeat, so the health path is exercised on real data too.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import gyrodrift
import numpy as np
from conftest import SHARED_DATA, skip_unless_ci
from gyrodrift.codecs.wire import make_samples
from gyrodrift.imu.config import default_config
from gyrodrift.replay.harness import LOOP_RELATIVE, ReplayOptions, run_replay

ARCSEC_RAD = np.pi / 180 / 3600
DT_S = 0.01  # sampling interval 10 ms (data README)
G_MPS2 = 9.780327  # the record's g (data README, line 2)


def test_replay_real_laser_gyro_record(cpp_build_dir: Path) -> None:
    path = SHARED_DATA / "lasergyro.imu"
    if not path.exists():
        skip_unless_ci(f"real record not present at {path}")
    with path.open() as f:
        lines = [ln for ln in f if ln.strip() and not ln.startswith("%")]
    counts = np.loadtxt(lines[3:3003])  # 3 header lines, then 30 s of samples
    # Angle increment = count * 0.1 arcsec, velocity increment = count * 125 ug*s (README).
    gyro_rad_s = counts[:, :3] * 0.1 * ARCSEC_RAD / DT_S
    accel_m_s2 = counts[:, 3:] * 125e-6 * G_MPS2 / DT_S
    n = counts.shape[0]
    samples = make_samples(np.arange(n) * DT_S, gyro_rad_s, accel_m_s2)
    model = gyrodrift.fit_ar2(gyro_rad_s[:, 2])
    settings = default_config(gyro_model=(model.a1, model.a2, model.mean, model.sigma2,
                                          model.measurement_variance), sample_rate_hz=1 / DT_S)
    settings = replace(settings, channels=tuple(replace(c, stuck_samples=20) if c.is_gyro else c
                                                for c in settings.channels))
    res = run_replay(samples, ReplayOptions(
        transport="serial", speed=0.0, loop_binary=str(cpp_build_dir / LOOP_RELATIVE),
        processor=settings.with_timing(loop_rate_hz=1000.0)))
    rep = res.report
    assert rep["ok"], ({k: v for k, v in rep["checks"].items() if not v}, rep["comparison"])
    assert rep["accounting"]["outputs_received"] == n
    # float32 loop vs float64 reference, values up to ~1e-3 rad/s and ~10 m/s^2.
    assert max(rep["comparison"]["max_abs_error"]) <= 1e-5
    # Quantized counts do repeat 20 times in a row somewhere in 30 s; both sides flag it.
    assert rep["reference_health"]["stuck_values"] > 0
    assert res.loop_stats is not None
    assert res.loop_stats["health"]["stuck_values"] == rep["reference_health"]["stuck_values"]
