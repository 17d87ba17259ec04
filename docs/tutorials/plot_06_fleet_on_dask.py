"""
Characterize a fleet of logs on Dask
====================================

Characterize many IMUs at once: each log is one task on a Dask cluster, the results are
written per unit and summarized across the fleet (a box plot per noise term, flagging units
outside a specification). The cluster is either one ``run_fleet`` starts on this machine
(a ``LocalCluster``) or one that already runs (``scheduler="tcp://host:8786"``).
"""

# %%
# A fleet of logs
# ---------------
# Four simulated static IMUs, one of them with a gyro four times noisier than the others,
# saved as (n, 6) .npy records (gyros in rad/s, accelerometers in m/s^2).
import tempfile
from pathlib import Path

import gyrodrift
import matplotlib.pyplot as plt
import numpy as np
from distributed import LocalCluster
from gyrodrift.workflows.fleet import FleetOptions, run_fleet

work = Path(tempfile.mkdtemp())
logs = []
for unit, arw in enumerate([0.05, 0.05, 0.2, 0.05]):
    imu = gyrodrift.simulate_imu(n=2**14, rate_hz=100.0,
                                 gyro=gyrodrift.NoiseTerms(n_deg_rt_h=arw), vrw_m_s_rt_h=0.02,
                                 seed=100 + unit)
    path = work / f"unit{unit}.npy"
    np.save(path, np.hstack([imu.gyro_rad_s, imu.accel_m_s2]))
    logs.append(path)

# %%
# On a local cluster
# ------------------
# A :class:`distributed.LocalCluster` on this machine (here with its workers as threads of this
# process; ``run_fleet(..., workers=N)`` and ``gyrodrift fleet LOGS --workers N`` start one of
# N worker processes themselves and close it at the end). A specification (``spec``) gives
# each term's limit, and a unit above it is flagged; a unit already characterized in
# ``out_dir`` is skipped unless ``force=True``.
opts = FleetOptions(rate_hz=100.0, plots=False)
spec = {"gyro_N": {"max": 3e-5}}  # noise density, rad/s/sqrt(Hz): about 0.1 deg/sqrt(h)
with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                  dashboard_address=":0") as cluster:
    # An existing scheduler is reached by its address: run_fleet starts and closes nothing
    # (``gyrodrift fleet LOGS --scheduler tcp://host:8786`` for a cluster started with
    # ``dask scheduler`` and ``dask worker`` on the machines that hold the logs).
    summary = run_fleet(logs, work / "fleet", opts=opts, scheduler=cluster.scheduler_address,
                        spec=spec)
print(f"done {summary['n_done']}, failed {summary['n_failed']}")
for f in summary["flagged"]:
    print(f"{f['unit']}: {f['parameter']} of {f['channel']} = {f['value']:.3g} ({f['limit']})")

# %%
# The summary's box plot shows the spread of each term over the fleet; the noisy unit stands
# out in the gyros' N.
fig, ax = plt.subplots(figsize=(8, 6))
ax.imshow(plt.imread(work / "fleet" / "boxplot.png"))
ax.set_axis_off()
fig.tight_layout()
