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
# On a cluster of its own
# -----------------------
# With ``workers=N`` (``gyrodrift fleet LOGS --workers N``), ``run_fleet`` starts a
# :class:`distributed.LocalCluster` of N worker processes on 127.0.0.1, one thread each, runs
# one task per log and closes the cluster at the end. A specification (``spec``) gives each
# term's limit, and a unit above it is flagged; a unit already characterized in ``out_dir``
# is skipped unless ``force=True``.
#
# The worker processes import the main script again when they start (Python's
# ``multiprocessing`` does so for every process it spawns), so a script calls ``run_fleet``
# under ``if __name__ == "__main__":``; without the guard ``run_fleet`` refuses with an error
# naming the line. (This page is run by the documentation build, which needs no guard.)
opts = FleetOptions(rate_hz=100.0, plots=False)
spec = {"gyro_N": {"max": 3e-5}}  # noise density, rad/s/sqrt(Hz): about 0.1 deg/sqrt(h)
summary = run_fleet(logs, work / "fleet", opts=opts, workers=2, spec=spec)
print(f"done {summary['n_done']}, failed {summary['n_failed']}")
for f in summary["flagged"]:
    print(f"{f['unit']}: {f['parameter']} of {f['channel']} = {f['value']:.3g} ({f['limit']})")

# %%
# On an existing scheduler
# ------------------------
# A cluster that already runs is reached by its scheduler's address (``scheduler=``, or
# ``gyrodrift fleet LOGS --scheduler tcp://host:8786``); ``run_fleet`` then starts and closes
# nothing. On a set of machines that is usually ``dask scheduler`` on one of them and
# ``dask worker tcp://host:8786`` on each machine that can read the logs. Here a
# :class:`~distributed.LocalCluster` started by this script stands in for it (its two
# workers are threads of this process, which is all a page needs): ``run_fleet`` only sees
# its address. The results are those of the run above.
with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp",
                  host="127.0.0.1", dashboard_address=None) as cluster:
    print("scheduler at", cluster.scheduler_address)
    again = run_fleet(logs, work / "fleet-existing", opts=opts,
                      scheduler=cluster.scheduler_address, spec=spec)
same = again["distribution"] == summary["distribution"]
print(f"done {again['n_done']}, failed {again['n_failed']}, same distribution: {same}")

# %%
# The summary's box plot shows the spread of each term over the fleet; the noisy unit stands
# out in the gyros' N.
fig, ax = plt.subplots(figsize=(8, 6))
ax.imshow(plt.imread(work / "fleet" / "boxplot.png"))
ax.set_axis_off()
fig.tight_layout()
