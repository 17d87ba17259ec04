"""PNG plots of Allan deviations and PSDs (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from gyrodrift.io.atomic import atomic_output
from gyrodrift.stability.allan import AllanResult
from gyrodrift.stability.allan_fit import ALLAN_TERMS, AllanFit
from gyrodrift.stability.gmwm import GmwmResult
from gyrodrift.stability.ieee952 import NoiseFit, allan_model_deg_h
from gyrodrift.stability.psd import Psd, log_binned

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["plot_allan", "plot_allan_fit", "plot_gmwm", "plot_psd"]


def plot_allan(results: Sequence[tuple[str, AllanResult]], path: str | Path, *,
               fit: NoiseFit | None = None, title: str = "Overlapping Allan deviation",
               unit: str = "deg/h", symbol: str = "sigma") -> Path:
    """Log-log Allan deviation (or another deviation of the family: pass its `title` and
    `symbol`, the y axis reads "symbol(tau)") with confidence-interval error bars, one curve
    per result; with `fit`, the identified model and its separate terms as lines.

    Examples
    --------
    >>> import os, tempfile
    >>> from gyrodrift.stability.allan import oadev
    >>> r = oadev(np.random.default_rng(0).standard_normal(1000), 10.0, progress=False)
    >>> p = plot_allan([("white", r)], os.path.join(tempfile.mkdtemp(), "a.png"))
    >>> p.read_bytes()[1:4]
    b'PNG'
    """
    fig, ax = plt.subplots(figsize=(7.5, 5.5), dpi=110)
    for label, r in results:
        err = np.vstack([r.adev - r.ci_low, r.ci_high - r.adev])
        ax.errorbar(r.tau_s, r.adev, yerr=err, fmt="o-", ms=3, lw=1, capsize=2, label=label)
    if fit is not None:
        tau_lo = min(r.tau_s[0] for _, r in results)
        tau_hi = max(r.tau_s[-1] for _, r in results)
        tau = np.logspace(np.log10(tau_lo), np.log10(tau_hi), 200)
        ax.plot(tau, allan_model_deg_h(tau, fit.q_arcsec, fit.n_deg_rt_h, fit.b_deg_h,
                                     fit.k_deg_h_rt_h, fit.r_deg_h2), "k-", lw=1.5,
                label="IEEE 952 fit")
        parts = {
            f"Q = {fit.q_arcsec:.3g} arcsec": {"q_arcsec": fit.q_arcsec},
            f"N = {fit.n_deg_rt_h:.3g} deg/sqrt(h)": {"n_deg_rt_h": fit.n_deg_rt_h},
            f"B = {fit.b_deg_h:.3g} deg/h": {"b_deg_h": fit.b_deg_h},
            f"K = {fit.k_deg_h_rt_h:.3g} deg/h/sqrt(h)": {"k_deg_h_rt_h": fit.k_deg_h_rt_h},
            f"R = {fit.r_deg_h2:.3g} deg/h/h": {"r_deg_h2": fit.r_deg_h2},
        }
        for label, kw in parts.items():
            if next(iter(kw.values())) > 0:
                ax.plot(tau, allan_model_deg_h(tau, **kw), "--", lw=0.8, label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("tau (s)")
    ax.set_ylabel(f"{symbol}(tau) ({unit})")
    return _save(fig, ax, path, title, legend_fontsize=7)


def plot_psd(psds: Sequence[tuple[str, Psd]], path: str | Path, *, bins_per_decade: int = 20,
             title: str = "Welch PSD", unit: str = "deg/h") -> Path:
    """Log-log one-sided PSDs, log-binned for display.

    Examples
    --------
    >>> import os, tempfile
    >>> from gyrodrift.stability.psd import welch_psd
    >>> r = welch_psd(np.random.default_rng(0).standard_normal(4096), 100.0)
    >>> plot_psd([("white", r)], os.path.join(tempfile.mkdtemp(), "p.png")).suffix
    '.png'
    """
    fig, ax = plt.subplots(figsize=(7.5, 5.0), dpi=110)
    for label, p in psds:
        f, s = log_binned(p.f_hz, p.psd, bins_per_decade)
        ax.loglog(f, s, lw=1, label=label)
    ax.set_xlabel("f (Hz)")
    ax.set_ylabel(f"PSD (({unit})^2/Hz)")
    return _save(fig, ax, path, title, legend_fontsize=8)


def _save(fig: Figure, ax: Axes, path: str | Path, title: str, *, legend_fontsize: float) -> Path:
    """Common finish of every plot: title, log grid, legend, tight layout, save, close."""
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=legend_fontsize)
    out = Path(path)
    fig.tight_layout()
    try:
        with atomic_output(out) as tmp:  # the output rule of gyrodrift.io.atomic
            fig.savefig(tmp)
    finally:
        plt.close(fig)
    return out


def plot_allan_fit(result: AllanResult, fit: AllanFit, path: str | Path, *, label: str = "",
                   title: str = "Overlapping Allan deviation and IEEE 952 fit",
                   unit: str = "deg/h") -> Path:
    """Allan deviation with its interval bars, the fitted total and each kept term, drawn
    only inside the fit range used.

    Examples
    --------
    >>> import tempfile
    >>> from gyrodrift.stability.allan import oadev
    >>> from gyrodrift.stability.allan_fit import fit_allan
    >>> r = oadev(np.random.default_rng(0).normal(0.0, 1.0, 8192), 100.0)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     png = plot_allan_fit(r, fit_allan(r.tau_s, r.adev, r.edf), Path(d) / "allan.png")
    ...     print(png.name, png.read_bytes()[:4])
    allan.png b'\\x89PNG'
    """
    fig, ax = plt.subplots(figsize=(7.5, 5.5), dpi=110)
    r = result
    err = np.vstack([r.adev - r.ci_low, r.ci_high - r.adev])
    ax.errorbar(r.tau_s, r.adev, yerr=err, fmt="o", ms=3, lw=1, capsize=2,
                label=f"{label} ({100 * r.ci:.1f} % intervals)".strip())
    tau = np.geomspace(fit.tau_min_s, fit.tau_max_s, 200)
    comps = {t.name: np.sqrt(t.coeff * tau ** ALLAN_TERMS[t.name]) for t in fit.terms}
    total = np.sqrt(sum((v**2 for v in comps.values()), np.zeros_like(tau)))
    ax.plot(tau, total, "k-", lw=1.5, label="fitted total")
    for t in fit.terms:
        ax.plot(tau, comps[t.name], "--", lw=0.9,
                label=f"{t.name} = {t.value:.3g} [{t.ci_low:.3g}, {t.ci_high:.3g}] {t.unit}")
    ax.axvspan(fit.tau_min_s, fit.tau_max_s, color="0.9", alpha=0.4, lw=0)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("tau (s)")
    ax.set_ylabel(f"sigma(tau) ({unit})")
    return _save(fig, ax, path, title, legend_fontsize=7)


def plot_gmwm(res: GmwmResult, path: str | Path, *, label: str = "",
              title: str = "Haar wavelet variance and GMWM fit", unit: str = "deg/h") -> Path:
    """Empirical Haar wavelet variance with its interval band, the fitted total and each
    component.

    Examples
    --------
    >>> import tempfile
    >>> from gyrodrift.stability.gmwm import identify_gmwm
    >>> res = identify_gmwm(np.random.default_rng(0).normal(0.0, 1.0, 4096), 100.0, model="N")
    >>> with tempfile.TemporaryDirectory() as d:
    ...     png = plot_gmwm(res, Path(d) / "gmwm.png")
    ...     print(png.name, png.read_bytes()[:4])
    gmwm.png b'\\x89PNG'
    """
    fig, ax = plt.subplots(figsize=(7.5, 5.5), dpi=110)
    ax.fill_between(res.tau_s, res.wv_ci_low, res.wv_ci_high, color="C0", alpha=0.25,
                    label=f"{100 * res.ci:.0f} % interval")
    ax.plot(res.tau_s, res.wv, "o", ms=3, color="C0", label=f"{label} empirical WV".strip())
    ax.plot(res.tau_s, res.wv_fit, "k-", lw=1.5, label=f"fitted total ({res.model})")
    for name, comp in res.wv_components.items():
        ax.plot(res.tau_s, comp, "--", lw=0.9, label=name)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("scale tau_j = 2^j dt (s)")
    ax.set_ylabel(f"wavelet variance (({unit})^2)")
    return _save(fig, ax, path, title, legend_fontsize=7)
