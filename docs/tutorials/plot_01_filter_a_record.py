"""
Filter a gyro record
====================

Filter a gyro record with the AR(2)-Kalman filter and see what the filter did to the drift and
to the noise. The record is simulated, so the drift the filter should keep is known: a
fiber-optic gyro at rest with a constant drift of 9.7 deg/h, an AR(2) drift and bias
instability, under angle random walk.
"""

# %%
# Simulate a record
# -----------------
# :func:`gyrodrift.simulate` returns a :class:`gyrodrift.GyroRecord` in deg/h. With
# ``keep_components=True`` it also keeps each noise term, so we can tell the drift (what the
# gyro's error really is) from the white noise on top of it.
import gyrodrift
import matplotlib.pyplot as plt
import numpy as np

rec = gyrodrift.simulate(
    300.0, rate_hz=100.0, n_deg_rt_h=0.0005, b_deg_h=0.02, bias_deg_h=9.7,
    ar2=(0.6868, -0.0213, 0.5), seed=2006, keep_components=True,
)
x = rec.rate_deg_h
white = rec.components["arw"]
drift = x - white
print(f"{x.size} samples at {rec.rate_hz:g} Hz, mean {x.mean():.3f} deg/h, STD {x.std():.3f} deg/h")

# %%
# Tune the filter from the data
# -----------------------------
# Two ways to tune the AR(2)-Kalman filter: the papers' recipe (an AR(2) fit on the record,
# ``q`` the fit's driving-noise variance and ``r`` its one-step prediction error), and maximum
# likelihood on the model "AR(2) drift + white noise"
# (:func:`~gyrodrift.filters.drift_model.fit_drift_model`), which separates the two parts of
# the record.
model = gyrodrift.fit_ar2(x, "yule-walker")
papers = gyrodrift.kalman_filter(x, model, steady_state=True)

ml = gyrodrift.fit_drift_model(x, rec.rate_hz, "ar2+white")
tuned = ml.kalman().process(x)
print(f"AR(2) fit: a1 = {model.a1:.3f}, a2 = {model.a2:.3f}, "
      f"sigma2 = {model.sigma2:.3f} (deg/h)^2")
print(f"maximum likelihood: a1 = {ml.a1:.3f}, a2 = {ml.a2:.3f}, q = {ml.q:.3f}, r = {ml.r:.3f}"
      f" (deg/h)^2, identified: {ml.identified}")

# %%
# What the filter did
# -------------------
# The yardstick only a simulation has: the mean squared error against the simulated drift
# (after the first second, the filter's start-up). A good drift filter lowers it; the raw
# record's error is the white noise itself.
skip = round(rec.rate_hz)
for name, y in [("raw", x), ("papers' tuning", papers), ("maximum likelihood", tuned)]:
    mse = np.mean((y[skip:] - drift[skip:]) ** 2)
    print(f"{name:>20}: STD {y[skip:].std():.4f} deg/h, MSE against the drift {mse:.4f} (deg/h)^2")

# %%
# The filtered record follows the drift and drops most of the white noise:
t = np.arange(x.size) / rec.rate_hz
fig, ax = plt.subplots(figsize=(7, 3.2))
sl = slice(6000, 7000)
ax.plot(t[sl], x[sl], lw=0.6, color="0.6", label="raw")
ax.plot(t[sl], drift[sl], lw=1.2, label="simulated drift")
ax.plot(t[sl], tuned[sl], lw=1.0, label="AR(2)-Kalman (ML tuning)")
ax.set_xlabel("time (s)")
ax.set_ylabel("rate (deg/h)")
ax.legend(loc="upper right", fontsize=8)
fig.tight_layout()

# %%
# The noise, by averaging time
# ----------------------------
# The overlapping Allan deviation (:func:`gyrodrift.oadev`) shows the same per averaging time:
# the filter lowers the short-tau (white-noise) branch and leaves the long-tau drift alone.
fig, ax = plt.subplots(figsize=(7, 3.6))
for name, y in [("raw", x), ("AR(2)-Kalman (ML tuning)", tuned)]:
    a = gyrodrift.oadev(y[skip:], rec.rate_hz, progress=False)
    ax.loglog(a.tau_s, a.adev, marker=".", label=name)
ax.set_xlabel("averaging time tau (s)")
ax.set_ylabel("Allan deviation (deg/h)")
ax.grid(True, which="both", alpha=0.3)
ax.legend()
fig.tight_layout()
