"""Equivalent degrees of freedom of the deviation family (NIST SP 1065 sec. 5.3).

- `edf_greenhall`: the general algorithm of C. A. Greenhall and W. J. Riley, "Uncertainty of
  stability variances based on finite differences" (35th PTTI, 2003), which SP 1065 sec. 5.3
  points to for the modified, Hadamard and overlapping Hadamard variances (and TVAR, whose
  edf is MVAR's). Stable32 uses it for its intervals; `tests/test_deviation.py` checks it
  against Stable32's published PHASE.DAT tables and allantools.edf_greenhall.
- `edf_totdev`: SP 1065 Table 7 (Howe), edf = b (T / tau) - c for white, flicker and
  random-walk FM; for white and flicker PM SP 1065 gives no TOTVAR entry and the overlapping
  Allan approximation (Table 5, `gyrodrift.stability.allan.edf_simple`) is used, as allantools does.

Notation (Greenhall & Riley): d = order of the phase difference (2 Allan, 3 Hadamard),
F = filter factor (1 for the modified variances, m otherwise), S = stride factor (m for
overlapping estimators, 1 for non-overlapping), N = number of phase points, alpha = exponent
of the frequency noise PSD S_y(f) ~ f^alpha.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.special

from gyrodrift.errors import GyrodriftValueError

__all__ = ["edf_for", "edf_greenhall", "edf_simple", "edf_totdev"]

#: Table 1 (modified variances, F = 1): (a0, a1) by alpha = 2..-4 (rows) and d = 1..3.
_TABLE1 = {
    2: ((2 / 3, 1 / 3), (7 / 9, 1 / 2), (22 / 25, 2 / 3)),
    1: ((0.840, 0.345), (0.997, 0.616), (1.141, 0.843)),
    0: ((1.079, 0.368), (1.033, 0.607), (1.184, 0.848)),
    -1: (None, (1.048, 0.534), (1.180, 0.816)),
    -2: (None, (1.302, 0.535), (1.175, 0.777)),
    -3: (None, None, (1.194, 0.703)),
    -4: (None, None, (1.489, 0.702)),
}
#: Table 2 (unmodified variances, F = m).
_TABLE2 = {
    2: ((3 / 2, 1 / 2), (35 / 18, 1.0), (231 / 100, 3 / 2)),
    1: ((78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)),
    0: ((2 / 3, 1 / 6), (2 / 3, 1 / 3), (7 / 9, 1 / 2)),
    -1: (None, (0.852, 0.375), (0.997, 0.617)),
    -2: (None, (1.079, 0.368), (1.033, 0.607)),
    -3: (None, None, (1.053, 0.553)),
    -4: (None, None, (1.302, 0.535)),
}
#: Table 3 (unmodified, alpha = 1): (b0, b1) by d.
_TABLE3 = ((6.0, 4.0), (15.23, 12.0), (47.8, 40.0))
#: Above this J the sums are replaced by the large-r approximations (Greenhall's J_max).
_J_MAX = 100


def _sw(t: np.ndarray, alpha: int) -> np.ndarray:
    """Greenhall's generalized autocovariance of the phase, eq. (7)."""
    t = np.asarray(t, dtype=np.float64)
    if alpha % 2 == 0:  # |t|^(3 - alpha); -|t| for alpha = 2
        if alpha not in (2, 0, -2, -4):
            raise GyrodriftValueError(f"alpha must be an integer in -4..2, got {alpha}")
        at = np.abs(t)
        return -at if alpha == 2 else at ** (3 - alpha)
    if alpha not in (1, -1, -3):
        raise GyrodriftValueError(f"alpha must be an integer in -4..2, got {alpha}")
    # t^(3 - alpha) ln|t|, 0 at t = 0
    at = np.abs(t)
    safe = np.where(at > 0, at, 1.0)
    return t ** (3 - alpha) * np.log(safe)


def _sx(t: np.ndarray, f: float, alpha: int) -> np.ndarray:
    """eq. (8): the filter of F phase averages; F = inf is the limit sw(t, alpha + 2)."""
    if math.isinf(f):
        return _sw(t, alpha + 2)
    return f * f * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


def _sz(t: np.ndarray, f: float, alpha: int, d: int) -> np.ndarray:
    """eq. (9): the d-th difference, sum_k (-1)^k C(2d, d - k) sx(t + k), k = -d..d."""
    t = np.asarray(t, dtype=np.float64)
    out = np.zeros(t.shape)
    for k in range(-d, d + 1):
        out = out + (-1) ** abs(k) * math.comb(2 * d, d - abs(k)) * _sx(t + k, f, alpha)
    return out


def _basic_sum(j_lim: float, m_big: float, s: float, f: float, alpha: int, d: int) -> float:
    """eq. (10): sz(0)^2 + (1 - J/M) sz(J/S)^2 + 2 sum_{j=1}^{J-1} (1 - j/M) sz(j/S)^2."""
    j = np.arange(1, int(j_lim), dtype=np.float64)
    sz = _sz(np.concatenate([[0.0, j_lim / s], j / s]), f, alpha, d) ** 2  # one pass
    return float(sz[0] + (1.0 - j_lim / m_big) * sz[1]
                 + np.sum(2.0 * (1.0 - j / m_big) * sz[2:]))


@functools.lru_cache(maxsize=4096)
def edf_greenhall(alpha: int, d: int, m: int, n_phase: int, *, overlapping: bool,
                  modified: bool) -> float:
    """Equivalent degrees of freedom by Greenhall & Riley's algorithm (module docstring).

    Parameters
    ----------
    alpha
        noise exponent, -4..2, with alpha + 2 d > 1.
    d
        2 for the (modified) Allan variance, 3 for the Hadamard variances.
    m
        averaging factor.
    n_phase
        phase points (rate samples + 1).
    overlapping
        True for oadev/mdev/tdev/ohdev (stride S = m).
    modified
        True for mdev/tdev.

    Examples
    --------
    >>> round(edf_greenhall(0, 2, 1, 1001, overlapping=True, modified=True), 1)
    782.0
    """
    alpha, d, m, n = int(alpha), int(d), int(m), int(n_phase)
    if d not in (1, 2, 3):
        raise GyrodriftValueError(f"d must be 1, 2 or 3, got {d}")
    if alpha + 2 * d <= 1:
        raise GyrodriftValueError(f"alpha + 2 d must exceed 1 (alpha={alpha}, d={d})")
    f = 1.0 if modified else float(m)
    s = float(m) if overlapping else 1.0
    length = m / f + m * d  # span of the estimator's filter, in phase samples
    m_big = 1.0 + math.floor(s * (n - length) / m)
    if m_big < 1:
        raise GyrodriftValueError(f"m={m} leaves no estimator term in {n} phase points")
    j_lim = min(m_big, (d + 1) * s)
    r = m_big / s
    if modified:  # case 1
        if j_lim <= _J_MAX:
            inv = _basic_sum(j_lim, m_big, s, 1.0, alpha, d) / (
                float(_sz(np.array(0.0), 1.0, alpha, d)) ** 2 * m_big)
        elif r > d + 1:
            a0, a1 = _table(_TABLE1, alpha, d)
            inv = (a0 - a1 / r) / r
        else:
            inv = _basic_sum(_J_MAX, _J_MAX, _J_MAX / r, 1.0, alpha, d) / (
                float(_sz(np.array(0.0), 1.0, alpha, d)) ** 2 * _J_MAX)
        return 1.0 / inv
    if alpha <= 0 or (alpha == 2 and math.ceil(r) <= d):  # case 2 (and exact sum, case 4a)
        if j_lim <= _J_MAX:
            f_eff = float(m) if (m * (d + 1) <= _J_MAX or alpha == 2) else math.inf
            inv = _basic_sum(j_lim, m_big, s, f_eff, alpha, d) / (
                float(_sz(np.array(0.0), f_eff, alpha, d)) ** 2 * m_big)
        elif r > d + 1:
            a0, a1 = _table(_TABLE2, alpha, d)
            inv = (a0 - a1 / r) / r
        else:
            inv = _basic_sum(_J_MAX, _J_MAX, _J_MAX / r, math.inf, alpha, d) / (
                float(_sz(np.array(0.0), math.inf, alpha, d)) ** 2 * _J_MAX)
        return 1.0 / inv
    if alpha == 1:  # case 3
        b0, b1 = _TABLE3[d - 1]
        if j_lim <= _J_MAX:
            inv = _basic_sum(j_lim, m_big, s, float(m), 1, d) / (
                float(_sz(np.array(0.0), float(m), 1, d)) ** 2 * m_big)
        elif r > d + 1:
            a0, a1 = _table(_TABLE2, alpha, d)
            inv = (a0 - a1 / r) / ((b0 + b1 * math.log(m)) ** 2 * r)
        else:
            mp = _J_MAX / r
            inv = _basic_sum(_J_MAX, _J_MAX, mp, mp, 1, d) / (
                (b0 + b1 * math.log(m)) ** 2 * _J_MAX)
        return 1.0 / inv
    # case 4, alpha = 2, unmodified, ceil(r) > d: closed form
    a0 = scipy.special.binom(4 * d, 2 * d) / scipy.special.binom(2 * d, d) ** 2
    inv = (a0 - d / 2.0 / r) / m_big
    return 1.0 / inv


def _table(table: dict[int, tuple], alpha: int, d: int) -> tuple[float, float]:
    entry = table[alpha][d - 1]
    if entry is None:
        raise GyrodriftValueError(f"no Greenhall table entry for alpha={alpha}, d={d}")
    return entry


#: SP 1065 Table 7: TOTVAR edf = b (T / tau) - c, keyed by alpha (white, flicker, RW FM).
_TOTVAR_BC = {0: (1.50, 0.0), -1: (1.17, 0.22), -2: (0.93, 0.36)}


def edf_totdev(n_phase: int, m: int, alpha: int) -> float:
    """TOTVAR edf, SP 1065 Table 7 with T / tau = n_phase / m (as Stable32 and allantools);
    for alpha = 1, 2 the overlapping-Allan approximation (SP 1065 Table 5).

    Examples
    --------
    >>> edf_totdev(1001, 10, 0)  # white FM: 1.5 (N - 1) / m (Howe's table)
    150.15
    """
    alpha = int(alpha)
    if alpha in _TOTVAR_BC:
        b, c = _TOTVAR_BC[alpha]
        return b * n_phase / m - c

    return float(edf_simple(n_phase, m, alpha))


def edf_for(name: str, n_phase: int, m: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """edf per tau of deviation `name` (oadev, mdev, tdev, hdev, ohdev, totdev).

    Examples
    --------
    >>> edf_for("oadev", 1001, np.array([1, 10]), np.array([0, 0])).round(1)
    array([665.8, 146.2])
    """

    m = np.asarray(m, dtype=np.int64)
    alpha = np.broadcast_to(np.asarray(alpha, dtype=np.int64), m.shape)
    if name == "oadev":
        return np.asarray(edf_simple(n_phase, m, alpha), dtype=np.float64)
    out = np.empty(m.shape, dtype=np.float64)
    for j, (mj, aj) in enumerate(zip(m.tolist(), alpha.tolist(), strict=True)):
        if name in ("mdev", "tdev"):
            out[j] = edf_greenhall(aj, 2, mj, n_phase, overlapping=True, modified=True)
        elif name == "hdev":
            out[j] = edf_greenhall(aj, 3, mj, n_phase, overlapping=False, modified=False)
        elif name == "ohdev":
            out[j] = edf_greenhall(aj, 3, mj, n_phase, overlapping=True, modified=False)
        elif name == "totdev":
            out[j] = edf_totdev(n_phase, mj, aj)
        else:
            raise GyrodriftValueError(f"unknown deviation {name!r}")
    return out


def edf_simple(n_phase: int | np.ndarray, m: int | np.ndarray, alpha: int | np.ndarray
               ) -> np.ndarray:
    """Equivalent degrees of freedom of the overlapping Allan variance, NIST SP 1065 Table 5
    (Stein 1985), for n_phase phase points (= rate samples + 1), factor m, noise exponent
    alpha in {2, 1, 0, -1, -2} (white PM, flicker PM, white FM, flicker FM, random-walk FM).

    Examples
    --------
    >>> bool(edf_simple(1001, 1, 0) > 500)  # white FM, m = 1: of the order of n
    True
    """
    n_arr, m_arr, a_arr = np.broadcast_arrays(
        np.asarray(n_phase, dtype=np.float64), np.asarray(m, dtype=np.float64),
        np.asarray(alpha, dtype=np.int64),
    )
    out = np.empty(n_arr.shape, dtype=np.float64)
    for idx in np.ndindex(n_arr.shape):
        n, mm, a = float(n_arr[idx]), float(m_arr[idx]), int(a_arr[idx])
        if a == 2:
            edf = (n + 1.0) * (n - 2.0 * mm) / (2.0 * (n - mm))
        elif a == 1:
            edf = math.exp(math.sqrt(math.log((n - 1.0) / (2.0 * mm))
                                     * math.log((2.0 * mm + 1.0) * (n - 1.0) / 4.0)))
        elif a == 0:
            edf = ((3.0 * (n - 1.0) / (2.0 * mm) - 2.0 * (n - 2.0) / n)
                   * (4.0 * mm * mm / (4.0 * mm * mm + 5.0)))
        elif a == -1:
            if mm == 1.0:
                # SP 1065 Table 5: 2 (N-2)^2 / (2.3 N - 4.9), ~0.87 N. allantools drops the
                # square (edf ~0.87 whatever N); Greenhall's exact value is 0.895 N.
                edf = 2.0 * (n - 2.0) ** 2 / (2.3 * n - 4.9)
            else:
                edf = 5.0 * n * n / (4.0 * mm * (n + 3.0 * mm))
        elif a == -2:
            edf = (n - 2.0) / (mm * (n - 3.0) ** 2) * (
                (n - 1.0) ** 2 - 3.0 * mm * (n - 1.0) + 4.0 * mm * mm)
        else:
            raise GyrodriftValueError(f"alpha must be one of 2, 1, 0, -1, -2, got {a}")
        out[idx] = edf
    return out
