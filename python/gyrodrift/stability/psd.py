"""Power spectral density of a gyro rate record (Welch, scipy.signal.welch).

The one-sided PSD of a rate in deg/h is in (deg/h)^2/Hz; its integral over 0..fs/2 is the
variance of the (mean-removed) record. White rate noise of angle random walk N has the
two-sided level (60 N)^2 (deg/h)^2/Hz (IEEE Std 952 table C.2 with N in deg/sqrt(h) and
f in Hz), i.e. the one-sided level 2 (60 N)^2. `log_binned` averages the PSD over
logarithmically spaced frequency bins for a readable log-log display.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.io.records import is_file_backed, iter_chunks

__all__ = ["PSD_PIECE", "Psd", "arw_from_white_level", "log_binned", "welch_psd"]


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


#: A file-backed record is read in pieces of about this many samples (whole segments).
PSD_PIECE = 1 << 20


def welch_psd(x: np.ndarray, rate_hz: float, nperseg: int | None = None,
              window: str = "hann", *, scale: float = 1.0) -> Psd:
    """One-sided Welch PSD (50 % overlap, mean removed per segment) of a 1-D rate record.

    nperseg defaults to the largest power of two <= n/8 (at least 8 averaged half-overlapping
    segments, so each bin has about 16 degrees of freedom), capped at 2**16. scale: the PSD
    is that of x / scale (a power of two keeps a record of extreme magnitude exact). A
    memory-mapped record (`gyrodrift.io.records.is_file_backed`) is read from its file in
    pieces of whole segments, each piece's mean periodogram weighted by its segments: the
    memory does not grow with the record.

    Examples
    --------
    >>> r = welch_psd(np.random.default_rng(0).standard_normal(4096), 100.0)
    >>> float(r.f_hz[-1])
    50.0
    """
    backed = is_file_backed(x)
    if not backed:
        x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise GyrodriftValueError(f"x: expected a 1-D record, got shape {x.shape}")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise GyrodriftValueError(f"rate_hz must be positive and finite, got {rate_hz!r}")
    n = int(x.shape[0])
    if n < 16:
        raise GyrodriftValueError(f"record too short for a PSD: {n} samples (need >= 16)")
    bad = sum(int(np.count_nonzero(~np.isfinite(p))) for p in iter_chunks(x, PSD_PIECE))
    if bad:
        raise GyrodriftValueError(f"x: {bad} NaN/Inf samples; drop or repair them first")
    if nperseg is None:
        nperseg = int(min(2 ** 16, 2 ** int(np.floor(np.log2(max(n // 8, 8))))))
    if not 8 <= nperseg <= n:
        raise GyrodriftValueError(f"nperseg must be in [8, {n}], got {nperseg}")
    import scipy.signal  # here: `import gyrodrift` stays light (scipy.signal loads scipy.stats)

    kw: dict[str, Any] = {"fs": rate_hz, "window": window, "nperseg": nperseg,
                          "detrend": "constant", "scaling": "density",
                          "return_onesided": True}
    if not backed:
        f, p = scipy.signal.welch(x if scale == 1.0 else x / scale, **kw)
        return Psd(f, p, int(nperseg), float(rate_hz))
    assert isinstance(x, np.memmap) and x.filename is not None  # is_file_backed
    step = nperseg - nperseg // 2  # scipy's default overlap: nperseg // 2
    n_seg = (n - nperseg) // step + 1
    per_piece = max(1, PSD_PIECE // step)
    total: np.ndarray | None = None
    f = np.empty(0)
    for a in range(0, n_seg, per_piece):
        b = min(a + per_piece, n_seg)
        lo, hi = a * step, (b - 1) * step + nperseg
        piece = np.fromfile(x.filename, dtype=x.dtype, count=hi - lo,
                            offset=x.offset + lo * x.dtype.itemsize).astype(np.float64)
        if piece.size != hi - lo:
            raise GyrodriftValueError(f"{x.filename}: file shorter than its header says")
        f, p = scipy.signal.welch(piece if scale == 1.0 else piece / scale, **kw)
        total = p * (b - a) if total is None else total + p * (b - a)
    assert total is not None
    return Psd(f, total / n_seg, int(nperseg), float(rate_hz))


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
