"""Overlapping and non-overlapped Allan deviation straight from their definitions (IEEE Std
952-1997 Annex C).

For rate samples y_k at interval tau0 and averaging factor m, the overlapping cluster
averages are ybar_i(m) = (y_i + ... + y_{i+m-1}) / m for every start i, and

    sigma^2(m tau0) = 1 / (2 (N - 2m + 1)) * sum_i (ybar_{i+m}(m) - ybar_i(m))^2.

The averages are taken window by window (no cumulative sums), so this is independent of the
C++ kernel's running-difference route; it costs O(N m) per tau and is meant for test records.

The non-overlapped variance (``adev_rate``) uses the M = floor(N / m) consecutive clusters only,
sigma^2 = sum_j (ybar_{j+1} - ybar_j)^2 / (2 (M - 1)); ``adev_octaves`` gives it at
m = 1, 2, 4, ... by averaging pairs of cluster means octave after octave, the route of the
streaming C++ estimator (include/gyrodrift/stability/streaming_allan.hpp), in numpy.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

__all__ = [
    "adev_octaves",
    "adev_rate",
    "oadev_phase",
    "oadev_rate",
]


def oadev_rate(y: np.ndarray, m: int) -> tuple[float, int]:
    """Overlapping Allan deviation of rate samples at averaging factor m (same units as y).

    Returns (sigma, number of squared differences).

    Examples
    --------
    >>> dev, terms = oadev_rate(np.array([1.0, -1.0, 1.0, -1.0]), 1)
    >>> round(dev, 6), terms  # sqrt(mean((2)^2) / 2)
    (1.414214, 3)
    """
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 1:
        raise ValueError(f"y: expected a 1-D array, got shape {y.shape}")
    n_terms = y.size - 2 * m + 1
    if m < 1 or n_terms < 1:
        raise ValueError(f"m={m} does not fit {y.size} samples")
    ybar = sliding_window_view(y, m).mean(axis=1)  # ybar_i for i = 0 .. N - m
    diff = ybar[m:] - ybar[:-m]  # n_terms differences
    return float(np.sqrt(0.5 * np.mean(diff * diff))), int(diff.size)


def oadev_phase(x: np.ndarray, m: int, tau0_s: float) -> tuple[float, int]:
    """Overlapping Allan deviation from phase (cumulative angle) samples x_k, NIST SP 1065
    eq. 11: sigma^2 = sum (x_{i+2m} - 2 x_{i+m} + x_i)^2 / (2 (m tau0)^2 (Np - 2m)).

    Examples
    --------
    >>> dev, terms = oadev_phase(np.arange(10.0), 1, 1.0)  # a constant rate has zero deviation
    >>> dev, terms
    (0.0, 8)
    """
    x = np.asarray(x, dtype=np.float64)
    n_terms = x.size - 2 * m
    if m < 1 or n_terms < 1:
        raise ValueError(f"m={m} does not fit {x.size} phase samples")
    d2 = x[2 * m :] - 2.0 * x[m:-m] + x[: -2 * m]
    tau = m * tau0_s
    return float(np.sqrt(np.sum(d2 * d2) / (2.0 * tau * tau * n_terms))), int(n_terms)


def adev_rate(y: np.ndarray, m: int) -> tuple[float, int]:
    """Non-overlapped Allan deviation of rate samples at averaging factor m (same units as y).

    The record is cut into M = floor(N / m) consecutive clusters (a partial last cluster is
    left out); returns (sigma, M - 1), the deviation and its number of squared differences.

    Examples
    --------
    >>> dev, terms = adev_rate(np.array([1.0, 1.0, -1.0, -1.0, 1.0, 1.0, 5.0]), 2)
    >>> round(dev, 6), terms  # cluster means 1, -1, 1: differences -2, 2
    (1.414214, 2)
    """
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 1:
        raise ValueError(f"y: expected a 1-D array, got shape {y.shape}")
    clusters = y.size // m if m >= 1 else 0
    if clusters < 2:
        raise ValueError(f"m={m} does not fit {y.size} samples (needs two clusters)")
    means = y[: clusters * m].reshape(clusters, m).mean(axis=1)
    diff = np.diff(means)
    return float(np.sqrt(0.5 * np.mean(diff * diff))), int(diff.size)


def adev_octaves(y: np.ndarray, n_octaves: int) -> tuple[np.ndarray, np.ndarray]:
    """Non-overlapped Allan variance at m = 2^k, k = 0 .. n_octaves - 1, by cascaded pairwise
    averaging of cluster means.

    Returns (avar, terms): the variance per octave in (units of y)^2 (NaN where fewer than two
    clusters fit) and the number of squared differences, floor(N / 2^k) - 1 (0 if none).

    Examples
    --------
    >>> avar, terms = adev_octaves(np.array([1.0, -1.0, 1.0, -1.0, 1.0]), 2)
    >>> avar.tolist(), terms.tolist()  # octave 1: cluster means 0, 0
    ([2.0, 0.0], [4, 1])
    """
    means = np.asarray(y, dtype=np.float64)
    if means.ndim != 1:
        raise ValueError(f"y: expected a 1-D array, got shape {means.shape}")
    avar = np.full(n_octaves, np.nan)
    terms = np.zeros(n_octaves, dtype=np.int64)
    for k in range(n_octaves):
        if means.size >= 2:
            diff = np.diff(means)
            avar[k] = 0.5 * np.mean(diff * diff)
            terms[k] = diff.size
        pairs = means.size // 2
        means = 0.5 * (means[0 : 2 * pairs : 2] + means[1 : 2 * pairs : 2])
    return avar, terms
