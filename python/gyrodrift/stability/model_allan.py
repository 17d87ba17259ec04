"""Expected Allan variance of noise models at octave-spaced averaging times tau = 2^k / rate:
the reference curves the health alarms (:mod:`gyrodrift.stability.health`) compare a
streaming Allan variance against.

- :func:`ar2_white_avar`: the drift model "AR(2) drift + white noise" (a1, a2, q, r: the
  model :func:`gyrodrift.filters.drift_model.fit_drift_model` fits), exactly: every squared
  difference of consecutive cluster means of a stationary rate has the same expectation, so
  the non-overlapped (and the overlapped) Allan variance has the expectation
  (D(m) - C(m)) / m^2 + r / m, D and C the variance of a cluster sum and the covariance of
  neighbouring ones (C++: include/gyrodrift/stability/model_allan.hpp, by doubling per
  octave; computed in double).
- :func:`ar2_white_edf_per_term`: the degrees of freedom per squared difference of a block of
  n consecutive ones under the same model (the correlation of the differences from the
  phase's structure function; a smooth drift has strongly correlated differences), which
  the health alarms use for their chi-square bound.
- :func:`ieee952_avar`: the IEEE Std 952 terms 3 Q^2 / tau^2 + N^2 / tau + (0.664 B)^2 +
  K^2 tau / 3.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftValueError

__all__ = ["ar2_white_avar", "ar2_white_edf_per_term", "ieee952_avar"]


def ar2_white_avar(a1: float, a2: float, q: float, r: float, n_octaves: int) -> np.ndarray:
    """Expected Allan variance of AR(2) drift + white noise at m = 2^k samples.

    Parameters
    ----------
    a1, a2 : float
        AR(2) coefficients of the drift (stationary).
    q : float
        Driving-noise variance of the drift, (record units)^2, >= 0.
    r : float
        White measurement-noise variance, (record units)^2, >= 0 (q + r > 0).
    n_octaves : int
        Octaves k = 0 .. n_octaves - 1 (1 .. 60).

    Returns
    -------
    numpy.ndarray
        sigma^2(2^k / rate) in (record units)^2 (independent of the rate: tau = 2^k / rate).

    Raises
    ------
    GyrodriftValueError
        A non-stationary AR(2), a negative or non-finite variance, q + r == 0, n_octaves out
        of range.

    Examples
    --------
    >>> ar2_white_avar(0.0, 0.0, 0.0, 4.0, 3).tolist()  # white: r / m
    [4.0, 2.0, 1.0]
    >>> av = ar2_white_avar(0.9, 0.0, 1.0, 0.0, 2)  # AR(1): (1 - rho) g0 at m = 1
    >>> bool(abs(av[0] - (1 - 0.9) / (1 - 0.81)) < 1e-12)
    True
    """
    if int(n_octaves) != n_octaves or not 1 <= int(n_octaves) <= 60:
        raise GyrodriftValueError(f"n_octaves must be an integer in 1..60, got {n_octaves!r}")
    try:
        return np.asarray(core("allan").ar2_white_avar(float(a1), float(a2), float(q), float(r),
                                                       int(n_octaves)))
    except ValueError as exc:
        raise GyrodriftValueError(f"{exc} (a1={a1!r}, a2={a2!r}, q={q!r}, r={r!r})") from None


def ar2_white_edf_per_term(a1: float, a2: float, q: float, r: float, n_octaves: int,
                           n: int = 64) -> np.ndarray:
    """Equivalent degrees of freedom per term of n consecutive squared differences at
    m = 2^k under AR(2) drift + white noise (moment matching, Gaussian).

    Parameters
    ----------
    a1, a2, q, r : float
        The model (see :func:`ar2_white_avar`).
    n_octaves : int
        Octaves k = 0 .. n_octaves - 1 (1 .. 60).
    n : int, optional
        Squared differences per block (the alarms' ``block_terms``; 1 .. 10^6).

    Returns
    -------
    numpy.ndarray
        edf / n per octave, in (0, 1].

    Examples
    --------
    >>> e = ar2_white_edf_per_term(0.0, 0.0, 0.0, 1.0, 2, n=100)  # white: n / (1.5 n - 0.5)
    >>> bool(abs(e[0] - 100 / 149.5) < 1e-12)
    True
    """
    if int(n_octaves) != n_octaves or not 1 <= int(n_octaves) <= 60:
        raise GyrodriftValueError(f"n_octaves must be an integer in 1..60, got {n_octaves!r}")
    if int(n) != n or not 1 <= int(n) <= 1_000_000:
        raise GyrodriftValueError(f"n must be an integer in 1..1000000, got {n!r}")
    try:
        return np.asarray(core("allan").ar2_white_edf_per_term(
            float(a1), float(a2), float(q), float(r), int(n_octaves), int(n)))
    except ValueError as exc:
        raise GyrodriftValueError(f"{exc} (a1={a1!r}, a2={a2!r}, q={q!r}, r={r!r})") from None


def ieee952_avar(tau_s: ArrayLike, *, q_angle: float = 0.0, n: float = 0.0, b: float = 0.0,
                 k: float = 0.0) -> np.ndarray:
    """IEEE Std 952 Allan variance of quantization, angle and rate random walk and bias
    instability at tau_s.

    Parameters
    ----------
    tau_s : array_like
        Averaging times (s, > 0).
    q_angle, n, b, k : float
        Quantization (record units * s), angle random walk (record units * sqrt(s)), bias
        instability (record units), rate random walk (record units / sqrt(s)); >= 0.

    Examples
    --------
    >>> ieee952_avar([1.0, 4.0], n=2.0).tolist()  # N^2 / tau
    [4.0, 1.0]
    >>> ieee952_avar([3.0], k=1.0).tolist()  # K^2 tau / 3
    [1.0]
    """
    t = np.asarray(tau_s, dtype=float)
    if t.size == 0 or not np.all(np.isfinite(t)) or np.any(t <= 0.0):
        raise GyrodriftValueError("tau_s must be positive and finite")
    for name, v in (("q_angle", q_angle), ("n", n), ("b", b), ("k", k)):
        if not (np.isfinite(v) and v >= 0.0):
            raise GyrodriftValueError(f"{name} must be finite and >= 0, got {v!r}")
    fn = core("allan").ieee952_avar
    return np.array([fn(float(q_angle), float(n), float(b), float(k), float(x))
                     for x in t.ravel()]).reshape(t.shape)
