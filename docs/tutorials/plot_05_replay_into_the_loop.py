"""
Replay a log into the loop with faults
======================================

Replay an IMU log into the fixed-rate loop program (``gyrodrift-loop``, the firmware-style
processor) over the interfaces a navigation computer uses, inject faults on the link, and read
the report: every filtered sample the loop sends back is checked against the reference
processor run offline on exactly the samples the loop received. Here the loop runs on this
machine behind a pseudo-terminal (serial) or an SLCAN adapter emulation; ``--device`` and
``--transport socketcan`` attach to real hardware the same way.
"""

# %%
# A log to replay
# ---------------
# A simulated static IMU, written as the harness's binary log (``.bin``; candump, ASC and BLF
# CAN logs are read the same way by :func:`gyrodrift.read_imu_log`).
import tempfile
from pathlib import Path

import gyrodrift
import matplotlib.pyplot as plt
import numpy as np
from gyrodrift.replay.faults import FaultSpec
from gyrodrift.replay.harness import ReplayOptions
from gyrodrift.report.replay import format_table, write_png

imu = gyrodrift.simulate_imu(n=2000, rate_hz=400.0,
                             gyro=gyrodrift.NoiseTerms(n_deg_rt_h=0.01, b_deg_h=0.01), seed=5)
t_s = np.arange(imu.gyro_rad_s.shape[0]) / imu.rate_hz
work = Path(tempfile.mkdtemp())
log = work / "imu.bin"
gyrodrift.write_imu_log(log, t_s, imu.gyro_rad_s, imu.accel_m_s2)
samples = gyrodrift.read_imu_log(log)
print(f"{len(samples)} samples in {log.name}")

# %%
# Replay over serial, with faults
# -------------------------------
# :class:`~gyrodrift.replay.harness.ReplayOptions` chooses the link, the pacing (``speed=0``:
# as fast as the link takes it) and the faults, as probabilities per sample: dropped,
# corrupted on the wire (the CRC catches it), duplicated, reordered. The processor is the
# default configuration (see :doc:`/guides/configuration-file`).
faults = FaultSpec(drop=0.01, corrupt=0.01, duplicate=0.01, reorder=0.01, seed=1)
res = gyrodrift.run_replay(samples, ReplayOptions(speed=0.0, faults=faults))
print(format_table(res))

# %%
# The report accounts for every sample: sent, rejected on the link (CRC), rejected by the
# processor (duplicate, out of order), and the outputs compared. ``ok`` is true only if every
# check passed.
acc = res.report["accounting"]
print("ok:", res.ok, "| sent:", acc["sent"], "| outputs:", acc["outputs_received"])

# %%
# Latency over time, its histogram, and the loop's output period:
png = write_png(res, work / "report.png")
fig, ax = plt.subplots(figsize=(8, 6))
ax.imshow(plt.imread(png))
ax.set_axis_off()
fig.tight_layout()

# %%
# The same over CAN
# -----------------
# The SLCAN transport sends the samples as CAN frames through the text protocol of USB-CAN
# adapters; a corrupted frame becomes a line error.
res_can = gyrodrift.run_replay(samples, ReplayOptions(transport="slcan", speed=0.0,
                                                      faults=FaultSpec(corrupt=0.01, seed=2)))
print("slcan ok:", res_can.ok, "| link errors:", res_can.report["accounting"]["rejected_on_link"])
