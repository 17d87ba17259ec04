"""The offline wavelet denoisers of a long record without holding it: `wavelet_denoise` and
`wavelet_packet_denoise` of a 1-D record read in pieces (a file-backed memory map is read with
file reads, `gyrodrift.io.records.iter_chunks`), the denoised record yielded piece by piece.

Both denoisers are whole-record transforms: periodized (the record's end wraps around to its
start), with a threshold from the median of every level-1 detail coefficient and, for the
packets, a best basis from the Shannon cost of every node of the tree. Each is computed here
from windows of the padded record:

- a coefficient of the periodized transform depends only on the samples within its filter's
  support around it (circularly), so the transform of a window that reaches `margin` samples
  beyond a piece on both sides (circularly: the record's start follows its end) has the
  whole record's coefficients inside the piece, and the inverse transform of the
  thresholded window has the whole record's output there; `margin` is 64 2^J samples, more
  than the support of the forward and inverse transforms together (filters of 16 taps:
  about 2 x 15 x 2^J);
- the median of the level-1 details is found exactly without holding them: the float64
  bits of a non-negative number order as the number does, so passes over the pieces count
  the values per 16 leading bits of the range that holds the wanted rank, until that range
  holds few enough values to sort;
- the packets' node costs are sums over the pieces' coefficients (in another order than the
  whole record's sum: equal to rounding; the best basis already settles ties within 1e-12 of
  the cost for the parent).

`wavelet_denoise` in float32 (the lifting core of the MCU build, ``dtype=numpy.float32``)
is computed the same way: each window is rounded to float32 as the whole record is, its
coefficients are the whole float32 transform's (each is the same float32 lifting arithmetic
on the same float32 samples, whatever the window), the median is taken of the float32
level-1 details (the mean of the middle two in float32, as ``numpy.median`` of float32
values), and the threshold is applied to the float32 coefficients with the same float32
operations.

Memory: a window of about `piece` + 2 `margin` samples and its transforms, and the counts
(65536 per pass); the record is read once per pass (4-8 passes).
"""

from __future__ import annotations

import gc
import math
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.io.records import is_file_backed, iter_chunks

__all__ = ["wavelet_denoise_pieces", "wavelet_packet_denoise_pieces"]

#: Samples per output piece (a multiple of 2^J is used).
DEFAULT_PIECE = 1 << 20
#: Samples per piece of the packet denoiser at most (its tree holds J + 1 copies of a window).
PACKET_PIECE = 1 << 18


class _Padded:
    """The record padded to a multiple of 2^level by half-sample symmetric reflection at the
    end (`gyrodrift.filters.wavelet.pad_symmetric`), read over circular index ranges."""

    def __init__(self, x: np.ndarray, level: int) -> None:
        self.x = x
        self.n = int(x.shape[0])
        self.m = self.n + (-self.n) % (1 << level)

    def _read(self, lo: int, hi: int) -> np.ndarray:
        """x[lo:hi] as float64 (file reads for a file-backed record)."""
        if is_file_backed(self.x):
            assert isinstance(self.x, np.memmap) and self.x.filename is not None
            with open(self.x.filename, "rb") as fh:
                fh.seek(self.x.offset + lo * self.x.dtype.itemsize)
                a = np.fromfile(fh, dtype=self.x.dtype, count=hi - lo)
            if a.size != hi - lo:
                raise GyrodriftValueError(f"{self.x.filename}: file shorter than its header says")
            return a.astype(np.float64, copy=False)
        return np.asarray(self.x[lo:hi], dtype=np.float64)

    def _linear(self, lo: int, hi: int) -> np.ndarray:
        """xp[lo:hi] for 0 <= lo <= hi <= m."""
        parts = []
        if lo < self.n:
            parts.append(self._read(lo, min(hi, self.n)))
        if hi > self.n:  # xp[n + k] = x[n - 1 - k]
            a, b = max(lo, self.n) - self.n, hi - self.n
            parts.append(self._read(self.n - b, self.n - a)[::-1])
        return np.concatenate(parts) if len(parts) != 1 else np.ascontiguousarray(parts[0])

    def window(self, lo: int, hi: int) -> np.ndarray:
        """xp[lo:hi] circularly (lo may be negative, hi may exceed m; hi - lo <= m)."""
        parts = []
        pos = lo
        while pos < hi:
            k = pos % self.m
            take = min(hi - pos, self.m - k)
            parts.append(self._linear(k, k + take))
            pos += take
        return np.concatenate(parts)


def _pieces_plan(level: int, piece: int) -> tuple[int, int]:
    """(samples per piece, a multiple of 2^level; margin of the windows)."""
    step = max(1 << level, (int(piece) >> level) << level)
    margin = 64 << level
    return step, margin


def _checked(x: Any, level: int, max_level: int, wavelet_ok: Callable[[], None]) -> np.ndarray:
    arr = x if isinstance(x, np.ndarray) else np.asarray(x)
    if arr.ndim != 1:
        raise GyrodriftValueError(f"x: expected a 1-D array, got shape {arr.shape}")
    if arr.dtype.kind not in "fiu":
        raise GyrodriftValueError(f"x: expected a real numeric array, got dtype {arr.dtype}")
    wavelet_ok()
    if not 1 <= int(level) <= max_level:
        raise GyrodriftValueError(f"level must be in 1..{max_level}, got {level}")
    if arr.shape[0] < 2 ** int(level):
        raise GyrodriftValueError(
            f"x: {arr.shape[0]} samples are too short for level {level} (need >= {2**level})")
    return arr


def _scan(x: np.ndarray, piece: int, dtype: Any = np.float64) -> float:
    """The largest |x| in `dtype`; a NaN or Inf, or a value `dtype` cannot hold (float32:
    beyond about 3.4e38), is refused with its index (as `wavelet_denoise`)."""
    from gyrodrift.filters.wavelet import as_core_dtype

    peak, start = 0.0, 0
    for p in iter_chunks(x, piece):
        a = as_core_dtype(p, dtype, start=start)
        ok = np.isfinite(a)
        if not np.all(ok):
            raise GyrodriftValueError(
                f"x: non-finite value (NaN or Inf) at index {start + int(np.argmin(ok))}")
        peak = max(peak, float(np.max(np.abs(a), initial=0.0)))
        start += a.size
    return peak


def _order_statistic(values: Callable[[], Iterator[np.ndarray]], rank: int) -> float:
    """The value of the given rank (0 = smallest) among non-negative float64 values given by
    passes over `values()`, exactly, holding at most 65536 counts and the values of one
    narrow bit range."""
    shift, prefix = 64, 0  # the candidates: bits >> shift == prefix
    while True:
        if shift == 0:
            return float(np.array([prefix], dtype=np.int64).view(np.float64)[0])
        counts = np.zeros(1 << 16, dtype=np.int64)
        for v in values():
            b = np.ascontiguousarray(v, dtype=np.float64).view(np.int64)
            if shift < 64:
                b = b[(b >> shift) == prefix]
            counts += np.bincount((b >> (shift - 16)) & 0xFFFF, minlength=1 << 16)
        cum = np.cumsum(counts)
        k = int(np.searchsorted(cum, rank, side="right"))
        rank -= int(cum[k - 1]) if k else 0
        shift -= 16
        prefix = (prefix << 16) | k if shift < 48 else k
        if counts[k] <= 1 << 16:
            found = [b[(b >> shift) == prefix] for v in values()
                     for b in [np.ascontiguousarray(v, dtype=np.float64).view(np.int64)]]
            keep = np.sort(np.concatenate(found))
            return float(keep[rank:rank + 1].view(np.float64)[0])


def _median(values: Callable[[], Iterator[np.ndarray]], count: int,
            dtype: Any = np.float64) -> float:
    """numpy.median of the non-negative values of `dtype` (the mean of the middle two in
    `dtype` for an even count), from passes over them."""
    lo = _order_statistic(values, (count - 1) // 2)
    if count % 2:
        return lo
    return float(np.mean(np.array([lo, _order_statistic(values, count // 2)], dtype=dtype)))


def _sigma_t(pad: _Padded, step: int, margin: int,
             level1: Callable[[np.ndarray], np.ndarray], dtype: Any = np.float64) -> float:
    """The universal threshold sigma sqrt(2 ln n), sigma = median(|d1|) / MAD_TO_SIGMA of the
    level-1 details (of `dtype`) of the whole padded record."""
    from gyrodrift.filters.wavelet import MAD_TO_SIGMA

    def details() -> Iterator[np.ndarray]:
        for a in range(0, pad.m, step):
            b = min(pad.m, a + step)
            d = level1(pad.window(a - margin, b + margin))  # the window's level-1 details
            yield np.abs(d[margin // 2:(margin + b - a) // 2])

    sigma = _median(details, pad.m // 2, dtype) / MAD_TO_SIGMA
    return sigma * math.sqrt(2 * math.log(pad.n))


def wavelet_denoise_pieces(x: Any, wavelet: str = "db8", level: int = 5, mode: str = "soft", *,
                           piece: int = DEFAULT_PIECE, dtype: Any = np.float64
                           ) -> Iterator[np.ndarray]:
    """`gyrodrift.filters.wavelet.wavelet_denoise` (one sigma from the level-1 details) of a
    1-D record read in pieces, yielded in consecutive pieces of about `piece` samples
    (module docstring): the whole record's output, never the whole record in memory.

    Parameters
    ----------
    x
        1-D record: a file-backed memory map is read with file reads.
    wavelet, level, mode
        as `wavelet_denoise`.
    piece
        samples per output piece (rounded down to a multiple of 2^level).
    dtype
        scalar type of the lifting core: float64, or float32 (the MCU build's).

    Yields
    ------
    numpy.ndarray
        the denoised record's next samples (of `dtype`).

    Raises
    ------
    GyrodriftValueError
        as `wavelet_denoise` (raised when the generator is first advanced).

    Examples
    --------
    >>> from gyrodrift.filters.wavelet import wavelet_denoise
    >>> x = np.random.default_rng(0).standard_normal(5000)
    >>> y = np.concatenate(list(wavelet_denoise_pieces(x, "db8", 3, piece=1024)))
    >>> bool(np.allclose(y, wavelet_denoise(x, "db8", 3), rtol=0, atol=1e-12))
    True
    >>> y32 = np.concatenate(list(wavelet_denoise_pieces(x, "db8", 3, piece=1024,
    ...                                                  dtype=np.float32)))
    >>> y32.dtype, bool(np.allclose(y32, wavelet_denoise(x, "db8", 3, dtype=np.float32),
    ...                             rtol=0, atol=1e-5))
    (dtype('float32'), True)
    """
    from gyrodrift.filters.wavelet import SUPPORTED_WAVELETS, wavedec, waverec

    def wavelet_ok() -> None:
        if wavelet not in SUPPORTED_WAVELETS:
            raise GyrodriftValueError(f"unsupported wavelet {wavelet!r}: the lifting core "
                                      f"implements {SUPPORTED_WAVELETS}")

    arr = _checked(x, level, 8, wavelet_ok)
    modes = ("soft", "hard", "forced")
    if mode not in modes:
        raise GyrodriftValueError(f"mode must be one of {modes}, got {mode!r}")
    dt = np.dtype(dtype)
    if dt not in (np.dtype(np.float64), np.dtype(np.float32)):
        raise GyrodriftTypeError(f"dtype must be float64 or float32, got {dt}")
    level = int(level)
    pad = _Padded(arr, level)
    step, margin = _pieces_plan(level, piece)
    peak = _scan(arr, step, dt)
    if pad.m <= step + 2 * margin:  # short: one window is the whole record
        from gyrodrift.filters.wavelet import wavelet_denoise

        yield wavelet_denoise(np.asarray(arr, dtype=np.float64), wavelet, level, mode,
                              dtype=dt)
        return
    t = 0.0
    if mode != "forced":
        t = _sigma_t(pad, step, margin,
                     lambda w: wavedec(w, wavelet, 1, dtype=dt)[w.size // 2:], dt)
    for a in range(0, pad.m, step):
        b = min(pad.m, a + step)
        w = pad.window(a - margin, b + margin).astype(dt, copy=False)
        c = wavedec(w, wavelet, level, dtype=dt)
        if not np.all(np.isfinite(c)):
            raise GyrodriftValueError(
                f"x: values up to {peak:.3g} overflow the {dt.name} wavelet transform (its "
                f"largest value is {float(np.finfo(dt).max):.3g}); scale the record")
        n_approx = w.size >> level
        if mode == "forced":
            c[n_approx:] = 0
        else:  # as the whole-record denoiser thresholds (float32 stays float32)
            d = c[n_approx:]
            mag = np.maximum(np.abs(d) - t, 0.0)
            c[n_approx:] = (np.where(np.abs(d) < t, 0.0, d) if mode == "hard"
                            else np.sign(d) * mag).astype(d.dtype, copy=False)
        y = waverec(c, wavelet, level, dtype=dt)[margin:margin + b - a]
        if not np.all(np.isfinite(y)):
            raise GyrodriftValueError(
                f"x: values up to {peak:.3g} overflow the {dt.name} inverse wavelet "
                "transform; scale the record")
        yield y[:max(0, min(b, pad.n) - a)]


def wavelet_packet_denoise_pieces(x: Any, wavelet: str = "bior3.7", level: int = 4,
                                  mode: str = "soft", *, piece: int = DEFAULT_PIECE
                                  ) -> Iterator[np.ndarray]:
    """`gyrodrift.filters.wavelet_packet.wavelet_packet_denoise` of a 1-D record read in
    pieces, yielded in consecutive pieces of about `piece` samples (module docstring): the
    node costs, the threshold and the reconstruction of the whole record, never the whole
    record in memory.

    Parameters
    ----------
    x
        1-D record: a file-backed memory map is read with file reads.
    wavelet, level, mode
        as `wavelet_packet_denoise`.
    piece
        samples per output piece (at most PACKET_PIECE, rounded down to a multiple of
        2^level).

    Yields
    ------
    numpy.ndarray
        the denoised record's next samples (float64).

    Raises
    ------
    GyrodriftValueError
        as `wavelet_packet_denoise` (raised when the generator is first advanced).

    Examples
    --------
    >>> from gyrodrift.filters.wavelet_packet import wavelet_packet_denoise
    >>> x = np.random.default_rng(0).standard_normal(5000)
    >>> y = np.concatenate(list(wavelet_packet_denoise_pieces(x, level=3, piece=1024)))
    >>> bool(np.allclose(y, wavelet_packet_denoise(x, level=3), rtol=0, atol=1e-12))
    True
    """
    import pywt

    from gyrodrift.filters.wavelet_packet import best_basis_from_costs, shannon_cost

    def wavelet_ok() -> None:
        if wavelet not in pywt.wavelist(kind="discrete"):
            raise GyrodriftValueError(
                f"unsupported wavelet {wavelet!r} (not a PyWavelets discrete wavelet)")

    if mode not in ("soft", "hard"):
        raise GyrodriftValueError(f"mode must be 'soft' or 'hard', got {mode!r}")
    arr = _checked(x, level, 10, wavelet_ok)
    level = int(level)
    pad = _Padded(arr, level)
    step, margin = _pieces_plan(level, min(piece, PACKET_PIECE))
    _scan(arr, step)
    if pad.m <= step + 2 * margin:
        from gyrodrift.filters.wavelet_packet import wavelet_packet_denoise

        yield wavelet_packet_denoise(np.asarray(arr, dtype=np.float64), wavelet, level, mode)
        return

    def tree(w: np.ndarray) -> Any:
        return pywt.WaveletPacket(w, wavelet, mode="periodization", maxlevel=level)

    def windows() -> Iterator[tuple[Any, int, int]]:
        for a in range(0, pad.m, step):
            b = min(pad.m, a + step)
            # a packet tree's nodes refer to each other: freed by the cycle collector only,
            # which counts objects, not bytes (dozens of MB per tree would pile up)
            gc.collect()
            yield tree(pad.window(a - margin, b + margin)), a, b

    costs: dict[str, float] = {}
    for wp, a, b in windows():
        for lev in range(1, level + 1):
            lo, hi = margin >> lev, (margin + b - a) >> lev
            for node in wp.get_level(lev, order="natural"):
                costs[node.path] = costs.get(node.path, 0.0) + shannon_cost(node.data[lo:hi])
    basis = best_basis_from_costs(costs, level)

    t = _sigma_t(pad, step, margin, lambda w: pywt.dwt(w, wavelet, mode="periodization")[1])
    for wp, a, b in windows():
        out = pywt.WaveletPacket(None, wavelet, mode="periodization", maxlevel=level)
        for path in basis:
            data = wp[path].data
            out[path] = data if set(path) == {"a"} else pywt.threshold(data, t, mode=mode)
        y = np.asarray(out.reconstruct(update=False))[margin:margin + b - a]
        yield y[:max(0, min(b, pad.n) - a)]
