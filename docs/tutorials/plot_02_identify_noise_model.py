"""
Identify a noise model with intervals
=====================================

Identify the noise terms of a gyro record twice: with the IEEE Std 952 fit of the Allan
variance (term selection, confidence intervals) and with the generalized method of wavelet
moments (GMWM: model selection, Gauss-Markov terms), and read the plots. The record is
simulated, so the true terms are known: angle random walk N = 0.01 deg/sqrt(h), rate random
walk K = 1 deg/h/sqrt(h) and a Gauss-Markov drift of 0.5 deg/h with a 20 s correlation time.
"""

# %%
# The record and its Allan deviation
# ----------------------------------
# :func:`gyrodrift.oadev` returns the overlapping Allan deviation at octave-spaced averaging
# times with the equivalent degrees of freedom (``edf``) of each point, from which the
# confidence intervals follow.
import tempfile
from pathlib import Path

import gyrodrift
import matplotlib.pyplot as plt
from gyrodrift.report.plots import plot_allan_fit, plot_gmwm
from gyrodrift.stability.allan_fit import fit_allan

rate_hz = 20.0
rec = gyrodrift.simulate(n=2**15, rate_hz=rate_hz, n_deg_rt_h=0.01, k_deg_h_rt_h=1.0,
                         gm=((0.5, 20.0),), seed=7)
x = rec.rate_deg_h
allan = gyrodrift.oadev(x, rate_hz, progress=False)
print(f"{x.size} samples ({x.size / rate_hz / 3600:.2f} h), {allan.tau_s.size} taus "
      f"from {allan.tau_s[0]:g} to {allan.tau_s[-1]:g} s")

# %%
# The IEEE 952 fit
# ----------------
# :func:`~gyrodrift.stability.allan_fit.fit_allan` fits the five terms by weighted
# non-negative least squares, drops the terms that do not improve the information criterion,
# and gives each kept term a 95 % interval. A Gauss-Markov drift is not one of the five terms:
# the fit describes its hump with the terms it has.
fit = fit_allan(allan.tau_s, allan.adev, allan.edf, ci=0.95)
for t in fit.terms:
    print(f"{t.name}: {t.value:.4g} [{t.ci_low:.4g}, {t.ci_high:.4g}] {t.unit}")
print("dropped:", ", ".join(fit.dropped) or "none")

# %%
# The plot shows the Allan deviation with its intervals, each kept term's line and their sum.
# Where the fitted sum leaves the intervals, the model lacks a term: here the Gauss-Markov
# hump, which the five IEEE 952 terms can only approximate.
out = Path(tempfile.mkdtemp())


def show(png: Path) -> None:
    """Show a PNG the package wrote."""
    fig, ax = plt.subplots(figsize=(7, 5))
    ax.imshow(plt.imread(png))
    ax.set_axis_off()
    fig.tight_layout()


show(plot_allan_fit(allan, fit, out / "allan_fit.png", label="simulated gyro"))

# %%
# GMWM
# ----
# :func:`gyrodrift.identify_gmwm` matches the Haar wavelet variance of the record to the
# model's, chooses among the sub-models of ``max_model`` by the wavelet information criterion
# (WIC) and gives asymptotic intervals. It can hold Gauss-Markov terms (``GM``), so it finds
# the drift the Allan fit could not name.
g = gyrodrift.identify_gmwm(x, rate_hz, max_model="N+K+GM", ci=0.95)
print("selected model:", g.model)
for p in g.params:
    print(f"{p.name}: {p.value:.4g} [{p.ci_low:.4g}, {p.ci_high:.4g}] {p.unit}")

# %%
# GMWM names the drift the Allan fit could only approximate: N and the Gauss-Markov term
# (its standard deviation and correlation time), each within its interval of the simulated
# value. It leaves K out: over half an hour, K's part of the wavelet variance is too small to
# tell from the others, and the criterion prefers the smaller model (a longer record shows it).
# The wavelet variance with its intervals, the fitted model and each term's part:
show(plot_gmwm(g, out / "gmwm.png", label="simulated gyro"))
