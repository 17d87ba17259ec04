"""What the gyro monitor compares against (:class:`~gyrodrift.imu.monitor.MonitorReference`):
from a processor configuration's drift model, or learned from the first part of a record.

- :func:`drift_model_avar`: the Allan variance of the AR(2) drift + white noise model
  (``y_k = d_k + v_k``, ``d_k = a1 d_{k-1} + a2 d_{k-2} + w_k``, ``var w = q``,
  ``var v = r``) at the octave averaging factors m = 2^k, exactly (no simulation).
- :func:`reference_from_config`: the configured model of one gyro channel (its
  ``ar2_kalman`` stage, rad/s) and its Allan variance.
- :func:`learn_reference`: the model identified from the first ``learn_s`` seconds of a
  record: the drift model as ``gyrodrift fit`` identifies it (maximum likelihood, on block
  averages where the drift is slow) and the expected Allan variance from the IEEE Std 952 fit
  of that span as ``gyrodrift allan`` makes it, evaluated at every octave (the drift model's
  Allan variance where the fit fails).

Units: rad/s throughout (q, r and the Allan variances in (rad/s)^2).

Examples
--------
>>> avar = drift_model_avar(0.0, 0.0, 0.0, 1e-6, 3)  # white noise only: r / m
>>> [float(f"{v:.3g}") for v in avar]
[1e-06, 5e-07, 2.5e-07]
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import solve_discrete_lyapunov

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.imu.config import Ar2KalmanStage, ProcessorConfig
from gyrodrift.imu.monitor import MonitorReference
from gyrodrift.units import DPH

__all__ = [
    "DEFAULT_LEARN_S",
    "REFERENCE_OCTAVES",
    "drift_model_avar",
    "learn_reference",
    "reference_from_config",
    "reference_from_drift",
]

#: The span a reference is learned from when no configuration gives one, s.
DEFAULT_LEARN_S = 600.0
#: Octaves of the reference Allan variance (tau0 .. tau0 * 2^31: beyond any record's reach).
REFERENCE_OCTAVES = 32


def drift_model_avar(a1: float, a2: float, q: float, r: float,
                     n_octaves: int = REFERENCE_OCTAVES) -> np.ndarray:
    """Allan variance of AR(2) drift + white noise at m = 2^k samples, k = 0 .. n_octaves - 1.

    With the block sums S of m consecutive samples, the Allan variance is
    ``(4 D(m) - D(2m)) / (2 m^2)``, ``D(m) = var S``. The white part gives ``r / m``. For the
    drift, in state form ``x_t = (d_t, d_{t-1})``, ``x_{t+1} = F x_t + (w, 0)`` with stationary
    covariance P (discrete Lyapunov equation), the sum V_m of m states and the covariance
    C_m = G_m F G_m P of two adjacent block sums (G_m = I + F + ... + F^(m-1)) double as
    ``V_2m = 2 V_m + C_m + C_m^T``, ``G_2m = G_m + F^m G_m``; the drift's Allan variance is
    ``(2 V_m - C_m - C_m^T)[0, 0] / (2 m^2)``. Units: those of q and r (per sample).

    Raises
    ------
    GyrodriftValueError
        a non-stationary AR(2) model, a negative variance, or n_octaves < 1.

    Examples
    --------
    >>> v = drift_model_avar(0.9, 0.0, 1.0, 0.0, 2)  # AR(1), phi 0.9: var d = 1 / 0.19
    >>> bool(abs(v[0] - (1 - 0.9) / 0.19) < 1e-12)  # var d - cov(d_0, d_1) at m = 1
    True
    """
    if n_octaves < 1:
        raise GyrodriftValueError(f"n_octaves must be >= 1, got {n_octaves!r}")
    if not (q >= 0.0 and r >= 0.0 and math.isfinite(q) and math.isfinite(r)):
        raise GyrodriftValueError(f"q and r must be finite and >= 0, got q={q!r}, r={r!r}")
    if not (abs(a2) < 1.0 and abs(a1) < 1.0 - a2):
        raise GyrodriftValueError(f"AR(2) model a1={a1!r}, a2={a2!r} is not stationary")
    f = np.array([[a1, a2], [1.0, 0.0]])
    p = solve_discrete_lyapunov(f, np.array([[q, 0.0], [0.0, 0.0]]))
    g = np.eye(2)
    fm = f.copy()
    v = p.copy()
    out = np.empty(n_octaves)
    m = 1.0
    for k in range(n_octaves):
        c = g @ f @ g @ p
        out[k] = (2.0 * v[0, 0] - c[0, 0] - c[0, 0]) / (2.0 * m * m) + r / m
        v = 2.0 * v + c + c.T
        g = g + fm @ g
        fm = fm @ fm
        m *= 2.0
    return np.maximum(out, 0.0)


def reference_from_drift(drift: tuple[float, float, float, float, float],
                         n_octaves: int = REFERENCE_OCTAVES, *, source: str = "config",
                         learn_s: float = 0.0) -> MonitorReference:
    """A reference from a drift model (a1, a2, q, r, mean) in rad/s: its Allan variance.

    Examples
    --------
    >>> ref = reference_from_drift((0.0, 0.0, 0.0, 1e-8, 0.0), 4)
    >>> ref.source, ref.avar.size
    ('config', 4)
    """
    a1, a2, q, r, _ = (float(v) for v in drift)
    return MonitorReference(drift=tuple(float(v) for v in drift),  # type: ignore[arg-type]
                            avar=drift_model_avar(a1, a2, q, r, n_octaves), source=source,
                            learn_s=float(learn_s))


def reference_from_config(cfg: ProcessorConfig, channel: str,
                          n_octaves: int = REFERENCE_OCTAVES) -> MonitorReference:
    """The configured drift model of gyro ``channel`` (gx, gy or gz): its ``ar2_kalman``
    stage (a1, a2, q, r, mean in rad/s).

    Raises
    ------
    GyrodriftValueError
        not a gyro channel, or the channel has no ``ar2_kalman`` stage.

    Examples
    --------
    >>> from gyrodrift.imu.config import drift_filter_config
    >>> cfg = drift_filter_config("gz", a1=0.5, a2=0.2, mean=0.0, q=1e-12, r=1e-10,
    ...                           sample_rate_hz=100.0)
    >>> ref = reference_from_config(cfg, "gz", 3)
    >>> ref.drift[:2], ref.source
    ((0.5, 0.2), 'config')
    """
    if channel not in ("gx", "gy", "gz"):
        raise GyrodriftValueError(f"channel must be gx, gy or gz, got {channel!r}")
    stages = [s for s in cfg.channel(channel).stages if isinstance(s, Ar2KalmanStage)]
    if not stages:
        raise GyrodriftValueError(
            f"the configuration's channel {channel} has no ar2_kalman stage, so no drift model "
            "to compare against (write one with gyrodrift fit -o, or learn it from the record)")
    s = stages[0]
    return reference_from_drift((s.a1, s.a2, s.q, s.r, s.mean), n_octaves)


def _fit_drift(x_deg_h: np.ndarray, rate_hz: float) -> tuple[float, float, float, float, float]:
    """The drift model of a span as ``gyrodrift fit`` identifies it (deg/h): maximum
    likelihood on block averages where the drift is slow, mapped back to the sample rate."""
    from gyrodrift.filters.ar2 import Ar2FitError
    from gyrodrift.filters.drift_model import (
        block_average,
        choose_decimation,
        compare_drift_models,
        drift_params_at_rate,
    )
    from gyrodrift.stability.allan import oadev

    factor = 1
    if x_deg_h.size >= 64:
        a = oadev(x_deg_h, rate_hz, taus="octave", progress=False)
        factor = choose_decimation(a.tau_s, a.adev, rate_hz, int(x_deg_h.size))
    try:
        best = compare_drift_models(block_average(x_deg_h, factor) if factor > 1 else x_deg_h,
                                    rate_hz / factor).best
        params = best.filter_params
        if factor > 1:
            try:
                params = drift_params_at_rate(*params, factor)
            except GyrodriftValueError:
                best = compare_drift_models(x_deg_h, rate_hz).best
                params = best.filter_params
    except (Ar2FitError, ValueError) as exc:
        raise GyrodriftValueError(f"the drift model of the learning span: {exc}") from exc
    a1, a2, q, r = (float(v) for v in params)
    return a1, a2, q, max(r, 1e-12 * (q + r)), float(best.mean)


def learn_reference(y_rad_s: ArrayLike, rate_hz: float, learn_s: float = DEFAULT_LEARN_S,
                    n_octaves: int = REFERENCE_OCTAVES) -> MonitorReference:
    """The reference identified from the first ``learn_s`` seconds of ``y_rad_s`` (rad/s).

    The drift model is the maximum-likelihood fit of that span (as ``gyrodrift fit``); the
    expected Allan variance at each octave is the IEEE Std 952 fit of the span's overlapping
    Allan deviation (as ``gyrodrift allan``, default terms, automatic range), evaluated at
    tau0 * 2^k; where that fit fails, the drift model's own Allan variance.

    Raises
    ------
    GyrodriftValueError
        the record is shorter than ``learn_s``, or the span cannot be fitted.

    Examples
    --------
    >>> y = np.random.default_rng(0).normal(0.0, 1e-5, 20000)  # white noise, rad/s, 100 Hz
    >>> ref = learn_reference(y, 100.0, 150.0, 4)
    >>> ref.source, ref.learn_s, ref.avar.size
    ('learned', 150.0, 4)
    >>> bool(0.8 < ref.avar[0] / 1e-10 < 1.2)  # white: the Allan variance at tau0 is var y
    True
    """
    from gyrodrift.stability.allan import oadev
    from gyrodrift.stability.allan_fit import ALLAN_TERMS, fit_allan

    y = np.asarray(y_rad_s, dtype=np.float64)
    n = round(learn_s * rate_hz)
    if not (learn_s > 0.0 and math.isfinite(learn_s)):
        raise GyrodriftValueError(
            f"learn_s must be a positive number of seconds, got {learn_s!r}")
    if n > y.size:
        raise GyrodriftValueError(f"the record ({y.size / rate_hz:.6g} s) is shorter than the "
                                  f"learning span ({learn_s:g} s)")
    x = y[:n] / DPH  # the fits work in deg/h, like the commands
    a1, a2, q, r, mean = _fit_drift(x, rate_hz)
    drift = (a1, a2, q * DPH * DPH, r * DPH * DPH, mean * DPH)
    ref = reference_from_drift(drift, n_octaves, source="learned", learn_s=learn_s)
    try:
        res = oadev(x, rate_hz, taus="octave", progress=False)
        fit = fit_allan(res.tau_s, res.adev, res.edf, ci=res.ci)
    except ValueError:
        return ref
    tau = np.exp2(np.arange(n_octaves)) / rate_hz
    avar_deg_h = np.zeros(n_octaves)
    for t in fit.terms:
        avar_deg_h += t.coeff * tau ** ALLAN_TERMS[t.name]
    if not np.all(np.isfinite(avar_deg_h) & (avar_deg_h > 0)):
        return ref
    return dataclasses.replace(ref, avar=avar_deg_h * DPH * DPH)
