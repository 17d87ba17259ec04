"""
Characterize a whole IMU and export Kalibr's imu.yaml
=====================================================

Characterize the six channels of an IMU (three gyros, three accelerometers) at once and write
the noise model Kalibr and most visual-inertial estimators read (``imu.yaml``). The record is
a simulated static IMU: a tactical-grade gyro triad (angle random walk 0.05 deg/sqrt(h), bias
instability 0.5 deg/h) and accelerometers with 0.02 m/s/sqrt(h) velocity random walk.
"""

# %%
# Load the record
# ---------------
# :func:`gyrodrift.simulate_imu` gives a static, level IMU: the gyros see the Earth rate plus
# their noise (rad/s), the accelerometers gravity plus theirs (m/s^2). A file on disk (.npy,
# CSV, PSINS .imu, IMU logs, ROS bags) is read the same way by
# :func:`~gyrodrift.io.imu_data.load_imu`; here the channels go in directly.
import io

import gyrodrift
import matplotlib.pyplot as plt
import numpy as np
from gyrodrift.io.imu_data import CHANNELS, ImuData
from gyrodrift.workflows.characterize import characterize, kalibr_yaml, plot_sensor

rate_hz = 100.0
imu = gyrodrift.simulate_imu(n=2**16, rate_hz=rate_hz,
                             gyro=gyrodrift.NoiseTerms(n_deg_rt_h=0.05, b_deg_h=0.5),
                             vrw_m_s_rt_h=0.02, seed=11)
data = np.hstack([imu.gyro_rad_s, imu.accel_m_s2])
channels = {name: data[:, k].copy() for k, name in enumerate(CHANNELS)}
rec = ImuData(channels, rate_hz, "simulated static IMU", "simulated", data.shape[0])
print(rec.names, f"{rec.n} samples at {rec.rate_hz:g} Hz")

# %%
# Characterize every channel
# --------------------------
# :func:`~gyrodrift.workflows.characterize.characterize` runs the Allan deviation and the
# IEEE 952 fit (or GMWM with ``method="gmwm"``) on each channel, with intervals at the given
# probability.
res = characterize(rec, ci=0.95)
for ch in res.channels:
    n_term = ch.terms["N"]
    print(f"{ch.channel}: noise density {n_term.value:.4g} {n_term.unit} "
          f"[{n_term.ci_low:.4g}, {n_term.ci_high:.4g}]")

# %%
# The Kalibr file
# ---------------
# :func:`~gyrodrift.workflows.characterize.kalibr_yaml` writes the continuous-time noise
# densities and random walks Kalibr expects, of the worst axis per parameter (or one axis),
# with the intervals and the discrete-time conversion as comments.
print(kalibr_yaml(res))

# %%
# The plots
# ---------
# Each sensor's Allan deviations with the fit, per axis (the same figure the HTML report of
# ``gyrodrift characterize --html`` holds):
for sensor in ("gyro", "accel"):
    png = plot_sensor(res, sensor)
    fig, ax = plt.subplots(figsize=(8, 5))
    ax.imshow(plt.imread(io.BytesIO(png)))
    ax.set_axis_off()
    fig.tight_layout()
