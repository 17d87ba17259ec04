"""The deviation family straight from NIST SP 1065 (phase form), in plain numpy.

Phase x_0..x_{N-1} at interval tau0, tau = m tau0:

- eq. 14, modified Allan: 1 / (2 m^2 tau^2 (N-3m+1)) sum_j [sum_{i=j}^{j+m-1}
  (x_{i+2m} - 2 x_{i+m} + x_i)]^2
- eq. 15, time deviation: tau / sqrt(3) Mod sigma
- eq. 18, Hadamard: 1 / (6 tau^2 n) sum over i = 0, m, 2m, ... of
  (x_{i+3m} - 3 x_{i+2m} + 3 x_{i+m} - x_i)^2
- eq. 20, overlapping Hadamard: the same over every i, n = N - 3m
- eq. 25, total: ``1 / (2 tau^2 (N-2)) sum_{i=1}^{N-2} (x*_{i-m} - 2 x*_i + x*_{i+m})^2`` on
  the record extended by reflection about both ends, ``x*_{-j} = 2 x_0 - x_j`` and
  ``x*_{N-1+j} = 2 x_{N-1} - x_{N-1-j}``.

Each difference is formed explicitly (the inner sums of eq. 14 as window sums, no running
updates), so this is independent of the C++ kernels' recursions; O(N m) at worst, for tests.
`rate_to_phase` integrates rate samples (mean removed first: every statistic here is blind to
a constant rate, and removing it keeps the cumulative sum small).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

__all__ = ["hdev_phase", "mdev_phase", "ohdev_phase", "rate_to_phase", "tdev_phase",
           "totdev_phase"]


def rate_to_phase(y: np.ndarray, tau0_s: float) -> np.ndarray:
    """x_k = tau0 sum_{i<k} (y_i - mean(y)), k = 0..N (N + 1 phase points).

    Examples
    --------
    >>> rate_to_phase(np.array([1.0, 2.0, 3.0]), 0.5)
    array([ 0. , -0.5, -0.5,  0. ])
    """
    y = np.asarray(y, dtype=np.float64)
    return tau0_s * np.concatenate([[0.0], np.cumsum(y - y.mean())])


def _check(x: np.ndarray, m: int, need: int) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1 or m < 1 or x.size < need:
        raise ValueError(f"m={m} does not fit {x.size} phase points")
    return x


def mdev_phase(x: np.ndarray, m: int, tau0_s: float) -> tuple[float, int]:
    """(Mod sigma, number of terms), SP 1065 eq. 14.

    Examples
    --------
    >>> dev, terms = mdev_phase(np.array([0.0, 1.0] * 4), 1, 1.0)  # (deviation, number of terms)
    >>> round(dev, 6), terms
    (1.414214, 6)
    """
    x = _check(x, m, 3 * m + 1)
    d2 = x[2 * m:] - 2.0 * x[m:-m] + x[: -2 * m]  # i = 0 .. N-2m-1
    inner = sliding_window_view(d2, m).sum(axis=1)  # j = 0 .. N-3m
    tau = m * tau0_s
    return float(np.sqrt(np.sum(inner * inner) / (2.0 * m * m * tau * tau * inner.size))), \
        int(inner.size)


def tdev_phase(x: np.ndarray, m: int, tau0_s: float) -> tuple[float, int]:
    """(time deviation, terms), SP 1065 eq. 15: tau / sqrt(3) Mod sigma.

    Examples
    --------
    >>> dev, terms = tdev_phase(np.array([0.0, 1.0] * 4), 1, 1.0)  # tau / sqrt(3) mdev
    >>> round(dev, 6), terms
    (0.816497, 6)
    """
    md, n = mdev_phase(x, m, tau0_s)
    return m * tau0_s * md / math.sqrt(3.0), n


def _third(x: np.ndarray, m: int) -> np.ndarray:
    return x[3 * m:] - 3.0 * x[2 * m: x.size - m] + 3.0 * x[m: x.size - 2 * m] - x[: x.size - 3 * m]


def ohdev_phase(x: np.ndarray, m: int, tau0_s: float) -> tuple[float, int]:
    """(overlapping Hadamard deviation, terms), SP 1065 eq. 20.

    Examples
    --------
    >>> dev, terms = ohdev_phase(np.array([0.0, 1.0] * 4), 1, 1.0)
    >>> round(dev, 6), terms
    (1.632993, 5)
    """
    x = _check(x, m, 3 * m + 1)
    d3 = _third(x, m)
    tau = m * tau0_s
    return float(np.sqrt(np.sum(d3 * d3) / (6.0 * tau * tau * d3.size))), int(d3.size)


def hdev_phase(x: np.ndarray, m: int, tau0_s: float) -> tuple[float, int]:
    """(Hadamard deviation, terms), SP 1065 eq. 18 (i = 0, m, 2m, ...).

    Examples
    --------
    >>> dev, terms = hdev_phase(np.array([0.0, 1.0] * 4), 1, 1.0)
    >>> round(dev, 6), terms
    (1.632993, 5)
    """
    x = _check(x, m, 3 * m + 1)
    d3 = _third(x, m)[::m]
    tau = m * tau0_s
    return float(np.sqrt(np.sum(d3 * d3) / (6.0 * tau * tau * d3.size))), int(d3.size)


def totdev_phase(x: np.ndarray, m: int, tau0_s: float) -> tuple[float, int]:
    """(total deviation, terms), SP 1065 eq. 25, 1 <= m <= N - 1.

    Examples
    --------
    >>> dev, terms = totdev_phase(np.array([0.0, 1.0] * 4), 1, 1.0)
    >>> round(dev, 6), terms
    (1.414214, 6)
    """
    x = _check(x, m, 3)
    n = x.size
    if m > n - 1:
        raise ValueError(f"m={m} does not fit {n} phase points")
    j = np.arange(1, n - 1)
    left = 2.0 * x[0] - x[j][::-1]  # x*_{-(N-2)} .. x*_{-1}
    right = 2.0 * x[-1] - x[n - 1 - j]  # x*_{N} .. x*_{2N-3}
    ext = np.concatenate([left, x, right])
    off = n - 2  # ext[off + k] = x*_k
    i = np.arange(1, n - 1)
    d2 = ext[off + i - m] - 2.0 * ext[off + i] + ext[off + i + m]
    tau = m * tau0_s
    return float(np.sqrt(np.sum(d2 * d2) / (2.0 * tau * tau * (n - 2)))), int(n - 2)
