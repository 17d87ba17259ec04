"""The gyro monitor's report: its online noise estimates over time beside the offline fits of
the same record, and the health alarms it raised.

- :func:`segment_fits`: the offline IEEE Std 952 fit (``gyrodrift allan``'s default: the
  overlapping Allan deviation at octave taus, every term offered, automatic range, model
  selection, one-sigma intervals) of each given span of a record, as N, B and K in
  deg/sqrt(h), deg/h and deg/h/sqrt(h);
- :func:`trace_rows`: the monitor's trace (:class:`~gyrodrift.imu.monitor.MonitorTrace`,
  rad/s) as one dict per report, in the IEEE units (the JSON lines of ``gyrodrift monitor``);
- :func:`plot_monitor`: N, B and K over time with their intervals, the offline fits as
  horizontal bands over their spans, and the time each alarm was first raised.

Examples
--------
>>> from gyrodrift.units import TERM_UNITS
>>> round(1e-4 * TERM_UNITS["gyro"]["N"].ieee_factor, 6)  # N: rad/sqrt(s) -> deg/sqrt(h)
0.343775
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from gyrodrift.imu.monitor import MonitorTrace
from gyrodrift.io.atomic import atomic_output
from gyrodrift.units import DPH, TERM_UNITS

__all__ = ["SegmentFit", "first_alarms", "plot_monitor", "segment_fits", "trace_rows"]

#: rad/s-based term values -> IEEE display units (N deg/sqrt(h), B deg/h, K deg/h/sqrt(h)).
_N = TERM_UNITS["gyro"]["N"].ieee_factor
_B = TERM_UNITS["gyro"]["B"].ieee_factor
_K = TERM_UNITS["gyro"]["K"].ieee_factor


@dataclass(frozen=True)
class SegmentFit:
    """The offline fit of one span [t0_s, t1_s) of a record: N (deg/sqrt(h)), B (deg/h) and
    K (deg/h/sqrt(h)) with their intervals (NaN where the fit dropped the term);
    k_upper_limit: K is not identified by the span and k_hi is the largest K it allows.

    Examples
    --------
    >>> SegmentFit(0.0, 60.0, 0.01, 0.009, 0.011).as_dict()["n_deg_rt_h"]
    0.01
    """

    t0_s: float
    t1_s: float
    n_deg_rt_h: float = math.nan
    n_lo_deg_rt_h: float = math.nan
    n_hi_deg_rt_h: float = math.nan
    b_deg_h: float = math.nan
    b_lo_deg_h: float = math.nan
    b_hi_deg_h: float = math.nan
    k_deg_h_rt_h: float = math.nan
    k_lo_deg_h_rt_h: float = math.nan
    k_hi_deg_h_rt_h: float = math.nan
    k_upper_limit: bool = False
    holds: bool = True

    def as_dict(self) -> dict[str, Any]:
        """The fields as JSON-ready values."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def segment_fits(y_rad_s: ArrayLike, rate_hz: float, spans_s: Sequence[tuple[float, float]]
                 ) -> tuple[SegmentFit, ...]:
    """The offline fit of each span (t0_s, t1_s) of ``y_rad_s`` (rad/s at ``rate_hz``).

    A span too short for a fit (fewer than nine samples, or too few taus) gives a
    :class:`SegmentFit` with NaN values.

    Examples
    --------
    >>> y = np.random.default_rng(0).normal(0.0, 1e-5, 8192)  # white, rad/s, 100 Hz
    >>> (f,) = segment_fits(y, 100.0, [(0.0, 81.92)])
    >>> bool(0.9 < f.n_deg_rt_h / 0.0034377 < 1.1)  # 1e-5 rad/s at 100 Hz: 1e-6 rad/sqrt(s)
    True
    """
    from gyrodrift.stability.allan import oadev
    from gyrodrift.stability.allan_fit import fit_allan

    y = np.asarray(y_rad_s, dtype=np.float64)
    out = []
    for t0, t1 in spans_s:
        i0 = max(0, round(t0 * rate_hz))
        i1 = min(y.size, round(t1 * rate_hz))
        x = y[i0:i1] / DPH  # deg/h, as the commands fit
        seg = SegmentFit(float(t0), float(t1))
        if x.size < 9:
            out.append(seg)
            continue
        try:
            res = oadev(x, rate_hz, taus="octave", progress=False)
            fit = fit_allan(res.tau_s, res.adev, res.edf, ci=res.ci)
        except ValueError:
            out.append(seg)
            continue
        vals: dict[str, Any] = {"holds": bool(fit.check.holds)}
        for name, key in (("N", "n_{}deg_rt_h"), ("B", "b_{}deg_h"), ("K", "k_{}deg_h_rt_h")):
            if name in fit.names:
                t = fit.term(name)
                vals[key.format("")] = t.value
                vals[key.format("lo_")] = t.ci_low
                vals[key.format("hi_")] = t.ci_high
                if name == "K" and not t.identified:
                    vals["k_upper_limit"] = True
        if "K" in fit.upper_limits and "K" not in fit.names:
            vals["k_hi_deg_h_rt_h"] = fit.upper_limits["K"]
            vals["k_upper_limit"] = True
        out.append(SegmentFit(float(t0), float(t1), **vals))
    return tuple(out)


def first_alarms(trace: MonitorTrace) -> dict[str, float]:
    """The report time (s) at which each alarm was first raised (alarms never raised are
    left out).

    Examples
    --------
    >>> tr = _example_trace()
    >>> first_alarms(tr)
    {'arw_high': 20.0}
    """
    out: dict[str, float] = {}
    health = np.asarray(trace.health, dtype=np.int64)
    for i, name in enumerate(trace.alarm_names):
        raised = np.flatnonzero((health >> i) & 1)
        if raised.size:
            out[name] = float(trace.t_s[raised[0]])
    return out


def trace_rows(trace: MonitorTrace) -> list[dict[str, Any]]:
    """One dict per report of ``trace``, in the IEEE units: ``t_s``; ``n_deg_rt_h``,
    ``b_deg_h``, ``k_deg_h_rt_h`` with ``_lo``/``_hi`` bounds (None where not estimable) and
    ``k_upper_limit``; the model in use (``a1``, ``a2``, ``q_deg_h_sq``, ``r_deg_h_sq``,
    ``mean_deg_h``; the reference's while the re-identification is off) and its
    steady-state ``gain`` [g0, g1]; the re-identification
    ``status`` (and, where the trace has them, ``b_tau_s``, the averaging time B is read at,
    and the counts ``retunes`` and ``refused_retunes``); its method ``identifier``
    (``recursive`` or ``lag``) and, with the lag identifier, ``fit_status``, the status of
    the last fit applied (None otherwise); ``health``, the names of the raised (latched)
    alarms, empty when healthy; and ``trips``, for each raised alarm the statistic that
    tripped it.

    Examples
    --------
    >>> rows = trace_rows(_example_trace())
    >>> rows[0]["health"], rows[2]["health"], round(rows[0]["n_deg_rt_h"], 6)
    ([], ['arw_high'], 0.343775)
    """
    rows = []
    sq = DPH * DPH
    configured = _configured_model(trace)
    for i in range(int(np.size(trace.t_s))):
        flags = trace.flags(i)
        row: dict[str, Any] = {"t_s": float(trace.t_s[i])}
        for name, factor, unit in (("n", _N, "deg_rt_h"), ("b", _B, "deg_h"),
                                   ("k", _K, "deg_h_rt_h")):
            for part, arr in (("", getattr(trace, name)), ("lo_", getattr(trace, f"{name}_lo")),
                              ("hi_", getattr(trace, f"{name}_hi"))):
                v = float(arr[i]) * factor
                row[f"{name}_{part}{unit}"] = v if math.isfinite(v) else None
        row["k_upper_limit"] = bool(trace.k_upper_limit[i])
        b_tau = getattr(trace, "b_tau_s", None)
        if b_tau is not None and np.size(b_tau) == np.size(trace.t_s):
            v = float(b_tau[i])
            row["b_tau_s"] = v if math.isfinite(v) and v > 0.0 else None
        model = (float(trace.a1[i]), float(trace.a2[i]), float(trace.q[i]), float(trace.r[i]),
                 float(trace.mean[i]), float(trace.gain0[i]), float(trace.gain1[i]))
        if configured is not None and not all(math.isfinite(v) for v in model[:5]):
            model = configured  # no re-identification: the filter runs the reference model
        row.update({"a1": model[0], "a2": model[1], "q_deg_h_sq": model[2] / sq,
                    "r_deg_h_sq": model[3] / sq, "mean_deg_h": model[4] / DPH,
                    "gain": [model[5], model[6]],
                    "status": str(trace.status[i]),
                    **{name: int(getattr(trace, name)[i]) for name in ("retunes",
                                                                       "refused_retunes")
                       if np.size(getattr(trace, name, ())) == np.size(trace.t_s)},
                    "identifier": trace.identifier,
                    "fit_status": (str(trace.fit_status[i])
                                   if len(trace.fit_status) == np.size(trace.t_s) else None),
                    "health": flags,
                    "trips": {f: dict(trace.trips[f]) for f in flags if f in trace.trips}})
        rows.append(row)
    return rows


def _configured_model(trace: MonitorTrace
                      ) -> tuple[float, float, float, float, float, float, float] | None:
    """The reference's drift model (a1, a2, q, r, mean) and its steady-state Kalman gain:
    the model the filter runs while the re-identification is off (None without a
    reference)."""
    if trace.reference is None:
        return None
    from gyrodrift._native import core

    a1, a2, q, r, mean = (float(v) for v in trace.reference.drift)
    ar2 = core("ar2")
    try:
        g0, g1 = ar2.Ar2SteadyStateKalman(ar2.Ar2KalmanSettings(
            a1=a1, a2=a2, sigma2=q, mean=mean, q=q, r=r)).gain
    except ValueError:  # no steady state (e.g. q = r = 0)
        g0 = g1 = math.nan
    return a1, a2, q, r, mean, float(g0), float(g1)


def plot_monitor(trace: MonitorTrace, path: str | Path, *,
                 fits: Sequence[SegmentFit] = (), fits_label: str = "offline fit",
                 whole: SegmentFit | None = None, learn_s: float = 0.0,
                 title: str = "gyro monitor") -> Path:
    """N, B and K over time (online estimates with their intervals, upper limits of K as
    open triangles), each offline fit in ``fits`` as a horizontal line with its interval band
    over its span (``whole``: the fit of the whole record, dashed), the learning span
    [0, ``learn_s``] shaded when the reference was learned, and a marker line at the time
    each alarm was first raised.

    Examples
    --------
    >>> import os, tempfile
    >>> p = plot_monitor(_example_trace(), os.path.join(tempfile.mkdtemp(), "m.png"),
    ...                  fits=[SegmentFit(0.0, 30.0, 0.3, 0.25, 0.35)])
    >>> p.read_bytes()[1:4]
    b'PNG'
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = trace_rows(trace)
    t = np.array([r["t_s"] for r in rows], dtype=np.float64)

    def col(key: str) -> np.ndarray:
        return np.array([math.nan if r[key] is None else r[key] for r in rows], dtype=np.float64)

    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    panels = (("n", "deg_rt_h", "N (deg/sqrt(h))"), ("b", "deg_h", "B (deg/h)"),
              ("k", "deg_h_rt_h", "K (deg/h/sqrt(h))"))
    alarms = first_alarms(trace)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (name, unit, label) in zip(axes, panels, strict=True):
        v, lo, hi = col(f"{name}_{unit}"), col(f"{name}_lo_{unit}"), col(f"{name}_hi_{unit}")
        hi_all = hi.copy()  # the upper limits of K are drawn too
        if name == "k":
            upper = np.array([r["k_upper_limit"] for r in rows], dtype=bool)
            v = np.where(upper, math.nan, v)
            if np.any(upper):
                ax.plot(t[upper], hi[upper], "v", mfc="none", color=colors[0], ms=4,
                        label="online upper limit")
            lo = np.where(upper, math.nan, lo)
            hi = np.where(upper, math.nan, hi)
        ax.fill_between(t, lo, hi, color=colors[0], alpha=0.25, lw=0)
        ax.plot(t, v, "-", color=colors[0], lw=1.2, label="online estimate")
        for j, f in enumerate(fits):
            fv = getattr(f, f"{name}_{unit}")
            flo = getattr(f, f"{name}_lo_{unit}")
            fhi = getattr(f, f"{name}_hi_{unit}")
            lab = fits_label if j == 0 else None
            if name == "k" and f.k_upper_limit and math.isfinite(fhi):
                ax.plot([f.t0_s, f.t1_s], [fhi, fhi], ":", color="k", lw=1.2,
                        label=None if j else f"{fits_label} (K upper limit)")
                continue
            if math.isfinite(fv):
                ax.plot([f.t0_s, f.t1_s], [fv, fv], "-", color="k", lw=1.5, label=lab)
                if math.isfinite(flo) and math.isfinite(fhi):
                    ax.fill_between([f.t0_s, f.t1_s], flo, fhi, color="k", alpha=0.12, lw=0)
        if whole is not None:
            wv = getattr(whole, f"{name}_{unit}")
            if name == "k" and whole.k_upper_limit:
                wv = whole.k_hi_deg_h_rt_h
            if math.isfinite(wv):
                ax.plot([whole.t0_s, whole.t1_s], [wv, wv], "--", color="0.45", lw=1.2,
                        label="offline fit, whole record" + (
                            " (K upper limit)" if name == "k" and whole.k_upper_limit else ""))
        if learn_s > 0.0:
            ax.axvspan(0.0, learn_s, color="0.5", alpha=0.08, lw=0,
                       label="learning span" if ax is axes[0] else None)
        for k, (flag, when) in enumerate(sorted(alarms.items(), key=lambda kv: kv[1])):
            ax.axvline(when, color=colors[(k + 3) % len(colors)], ls="--", lw=1,
                       label=f"alarm {flag}" if ax is axes[0] else None)
        ax.set_ylabel(label)
        shown = [v, lo, hi_all] + [np.array([getattr(f, f"{name}_{p}{unit}") for f in fits])
                               for p in ("", "lo_", "hi_")]
        positive = np.concatenate([x[np.isfinite(x) & (x > 0)] for x in shown])
        if positive.size >= 2 and positive.max() / positive.min() > 20:
            ax.set_yscale("log")  # limits set: a band reaching 0 must not decide them
            ax.set_ylim(positive.min() / 1.5, positive.max() * 1.5)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[-1].set_xlabel("time (s)")
    healthy = "no alarm" if not alarms else "alarms: " + ", ".join(
        f"{k} at {v:g} s" for k, v in alarms.items())
    fig.suptitle(f"{title} ({healthy})", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    try:
        with atomic_output(path) as tmp:
            fig.savefig(tmp, dpi=100)
    finally:
        plt.close(fig)
    return path


def _example_trace() -> MonitorTrace:
    """A three-report trace for the examples: N 1e-4 rad/sqrt(s), arw_high from 20 s."""
    n = 3
    one = np.ones(n)
    nan = np.full(n, math.nan)
    return MonitorTrace(
        t_s=np.array([10.0, 20.0, 30.0]), n=1e-4 * one, n_lo=0.9e-4 * one, n_hi=1.1e-4 * one,
        b=1e-6 * one, b_lo=0.5e-6 * one, b_hi=2e-6 * one, k=nan, k_lo=nan, k_hi=1e-7 * one,
        k_upper_limit=np.ones(n, dtype=bool), a1=0.5 * one, a2=0.1 * one, q=1e-14 * one,
        r=4e-10 * one, mean=0.0 * one, gain0=0.1 * one, gain1=0.05 * one,
        status=("configured",) * n, health=np.array([0, 1, 1], dtype=np.uint16),
        alarm_names=("arw_high", "bias_instability_high", "rate_random_walk_high", "stuck",
                     "saturated"),
        trips={"arw_high": {"statistic": 1.6, "threshold": 1.3, "tau_s": 0.01, "t_s": 20.0}})
