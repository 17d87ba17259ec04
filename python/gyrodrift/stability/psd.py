"""Power spectral density of a gyro rate record (Welch, scipy.signal.welch).

The one-sided PSD of a rate in deg/h is in (deg/h)^2/Hz; its integral over 0..fs/2 is the
variance of the (mean-removed) record. White rate noise of angle random walk N has the
two-sided level (60 N)^2 (deg/h)^2/Hz (IEEE Std 952 table C.2 with N in deg/sqrt(h) and
f in Hz), i.e. the one-sided level 2 (60 N)^2. `log_binned` averages the PSD over
logarithmically spaced frequency bins for a readable log-log display.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrodrift.errors import GyrodriftValueError

__all__ = ["Psd", "arw_from_white_level", "log_binned", "welch_psd"]


@dataclass(frozen=True)
class Psd:
    """

    Examples
    --------
    >>> r = welch_psd(np.zeros(64) + np.arange(64) % 2, 10.0)
    >>> r.nperseg
    8
    """
    f_hz: np.ndarray
    psd: np.ndarray  # one-sided, (input unit)^2 / Hz
    nperseg: int
    rate_hz: float


def welch_psd(x: np.ndarray, rate_hz: float, nperseg: int | None = None,
              window: str = "hann") -> Psd:
    """One-sided Welch PSD (50 % overlap, mean removed per segment) of a 1-D rate record.

    nperseg defaults to the largest power of two <= n/8 (at least 8 averaged half-overlapping
    segments, so each bin has about 16 degrees of freedom), capped at 2**16.

    Examples
    --------
    >>> r = welch_psd(np.random.default_rng(0).standard_normal(4096), 100.0)
    >>> float(r.f_hz[-1])
    50.0
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise GyrodriftValueError(f"x: expected a 1-D record, got shape {x.shape}")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise GyrodriftValueError(f"rate_hz must be positive and finite, got {rate_hz!r}")
    if x.size < 16:
        raise GyrodriftValueError(f"record too short for a PSD: {x.size} samples (need >= 16)")
    bad = int(np.count_nonzero(~np.isfinite(x)))
    if bad:
        raise GyrodriftValueError(f"x: {bad} NaN/Inf samples; drop or repair them first")
    if nperseg is None:
        nperseg = int(min(2 ** 16, 2 ** int(np.floor(np.log2(max(x.size // 8, 8))))))
    if not 8 <= nperseg <= x.size:
        raise GyrodriftValueError(f"nperseg must be in [8, {x.size}], got {nperseg}")
    import scipy.signal  # here: `import gyrodrift` stays light (scipy.signal loads scipy.stats)

    f, p = scipy.signal.welch(x, fs=rate_hz, window=window, nperseg=nperseg,
                              detrend="constant", scaling="density", return_onesided=True)
    return Psd(f, p, int(nperseg), float(rate_hz))


def log_binned(f_hz: np.ndarray, psd: np.ndarray, bins_per_decade: int = 20
               ) -> tuple[np.ndarray, np.ndarray]:
    """Mean PSD in log-spaced frequency bins (DC excluded); returns (geometric bin centre,
    mean PSD) for the non-empty bins.

    Examples
    --------
    >>> f, p = log_binned(np.linspace(0.0, 10.0, 101), np.ones(101), 5)
    >>> bool(np.all(p == 1.0))
    True
    """
    f = np.asarray(f_hz, dtype=np.float64)
    p = np.asarray(psd, dtype=np.float64)
    keep = f > 0
    f, p = f[keep], p[keep]
    if f.size == 0:
        raise GyrodriftValueError("no positive frequencies")
    lo, hi = np.log10(f[0]), np.log10(f[-1])
    n_bins = max(int(np.ceil((hi - lo) * bins_per_decade)), 1)
    edges = np.logspace(lo, hi, n_bins + 1)
    # logspace may round the end edges either way: clip so f[0] and f[-1] land inside.
    idx = np.clip(np.searchsorted(edges, f, side="right") - 1, 0, n_bins - 1)
    sums = np.bincount(idx, weights=p, minlength=n_bins)
    counts = np.bincount(idx, minlength=n_bins)
    full = counts > 0
    centres = np.sqrt(edges[:-1] * edges[1:])
    return centres[full], sums[full] / counts[full]


def arw_from_white_level(one_sided_level: float) -> float:
    """Angle random walk N (deg/sqrt(h)) from a flat one-sided rate PSD in (deg/h)^2/Hz.

    Examples
    --------
    >>> round(arw_from_white_level(2 * 60.0**2), 12)  # 2 N^2 (60)^2 for N = 1 deg/sqrt(h)
    1.0
    """
    return float(np.sqrt(one_sided_level / 2.0) / 60.0)
