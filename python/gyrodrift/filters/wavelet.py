"""Lifting wavelet denoisers on the C++ core.

* :func:`wavedec` / :func:`waverec`: periodized db4/db8 DWT by lifting (C++), identical to
  ``numpy.concatenate(pywt.wavedec(x, w, mode="periodization", level=J))`` (no index shift).
* :func:`wavelet_denoise`: offline denoiser of paper 000 sec. 2.3: t = sigma sqrt(2 ln n),
  sigma = median(``|d1|``)/0.6745 (or per level), soft / hard thresholding or forced (all
  details zero). A length that is not a multiple of 2**level is padded at the end by
  half-sample symmetric reflection (x[n-1], x[n-2], ...) to the next multiple, denoised,
  and truncated back to n; n in the threshold is the original length.
* :class:`RealtimeWavelet`: the sliding-window prefilter of paper 004 sec. 2.2 (see
  include/gyrodrift/filters/realtime_wavelet.hpp for the exact definition), per axis.

References (pywt-based oracles) are in :mod:`gyrodrift.reference.wavelet`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gyrodrift._native import core
from gyrodrift.defaults import (
    DEFAULT_SAMPLE_RATE_HZ,
    PREFILTER_LEVEL,
    PREFILTER_THRESHOLD,
    PREFILTER_WAVELET,
    PREFILTER_WINDOW,
)
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.filters.fir import forced_fir_taps

__all__ = [
    "MAD_TO_SIGMA",
    "SUPPORTED_WAVELETS",
    "RealtimeWavelet",
    "as_core_dtype",
    "max_level",
    "pad_symmetric",
    "wavedec",
    "wavelet_denoise",
    "waverec",
]

#: median(|N(0,1)|): sigma = median(|d1|) / MAD_TO_SIGMA (paper 000 sec. 2.3, Donoho and
#: Johnstone 1994).
MAD_TO_SIGMA = 0.6745


def pad_symmetric(x: np.ndarray, multiple: int) -> np.ndarray:
    """Pad the end to a multiple of ``multiple`` by half-sample symmetric reflection
    (x[n-1], x[n-2], ...; numpy.pad mode="symmetric").

    Examples
    --------
    >>> pad_symmetric(np.arange(4), 8)
    array([0, 1, 2, 3, 3, 2, 1, 0])
    """
    x = np.asarray(x)
    return np.pad(x, (0, (-len(x)) % multiple), mode="symmetric")


SUPPORTED_WAVELETS = ("db4", "db8")
_MODES = ("soft", "hard", "forced")
_DTYPES = {np.dtype(np.float64): "F64", np.dtype(np.float32): "F32"}



def _check_wavelet(wavelet: str) -> None:
    if wavelet not in SUPPORTED_WAVELETS:
        raise GyrodriftValueError(
            f"unsupported wavelet {wavelet!r}: the lifting core implements {SUPPORTED_WAVELETS}"
        )


def _check_dtype(dtype: Any) -> np.dtype:
    dt = np.dtype(dtype)
    if dt not in _DTYPES:
        raise GyrodriftTypeError(f"dtype must be float64 or float32, got {dt}")
    return dt


def _as_float_array(x: Any, dtype: np.dtype, what: str = "x") -> np.ndarray:
    arr = np.asarray(x)
    if arr.dtype.kind not in "fiub":
        raise GyrodriftTypeError(f"{what}: expected a real numeric array, got dtype {arr.dtype}")
    if arr.ndim == 0:  # ascontiguousarray would make it 1-D
        return np.asarray(arr, dtype=dtype)
    return np.ascontiguousarray(arr, dtype=dtype)


def as_core_dtype(x: Any, dtype: Any = np.float64, *, what: str = "x",
                  start: int = 0) -> np.ndarray:
    """`x` as a contiguous array of the C++ core's scalar type, refusing a finite value
    that the type cannot hold (beyond float32's largest value, about 3.4e38) before it
    becomes an infinity, and without numpy's overflow warning.

    NaN and Inf in `x` pass through: the caller refuses or counts them.

    Parameters
    ----------
    x
        real numeric array (any shape).
    dtype
        float64 or float32.
    what
        the array's name in error messages.
    start
        index of ``x[0]`` in the whole record (for a piece of it), added to the index an
        error names.

    Returns
    -------
    numpy.ndarray
        `x` in `dtype`.

    Raises
    ------
    GyrodriftValueError
        a finite value of `x` overflows `dtype`, naming the first one and its index.
    GyrodriftTypeError
        `x` is not real numeric, or `dtype` is not float64 or float32.

    Examples
    --------
    >>> as_core_dtype([1.0, 2.5], np.float32).dtype
    dtype('float32')
    >>> try:
    ...     as_core_dtype([1.0, 1e39], np.float32)
    ... except GyrodriftValueError as exc:
    ...     print(exc)
    x: value 1e+39 at index 1 is beyond the float32 range (largest 3.4e+38); scale the record
    """
    dt = _check_dtype(dtype)
    arr = np.asarray(x)
    with np.errstate(over="ignore"):  # a value beyond the range becomes Inf: refused below
        out = _as_float_array(arr, dt, what)
    if arr.dtype.kind == "f" and arr.dtype.itemsize > dt.itemsize:
        lost = np.isinf(out) & np.isfinite(arr)
        if np.any(lost):
            flat = int(np.argmax(lost))
            pos = np.unravel_index(flat, arr.shape) if arr.ndim else ()
            where = (str(start + flat) if arr.ndim <= 1
                     else str((start + int(pos[0]), *(int(i) for i in pos[1:]))))
            raise GyrodriftValueError(
                f"{what}: value {float(arr.flat[flat]):.3g} at index {where} is beyond the "
                f"{dt.name} range (largest {float(np.finfo(dt).max):.3g}); scale the record")
    return out


def max_level(window: int, wavelet: str = "db8") -> int:
    """Largest level the real-time filter accepts: pywt.dwt_max_level(2*window, filter_len).

    Examples
    --------
    >>> max_level(256, "db4")
    6
    """
    _check_wavelet(wavelet)
    return int(core("wavelet").realtime_wavelet_max_level(int(window), wavelet))


def wavedec(x: Any, wavelet: str = "db8", level: int = 5, dtype: Any = np.float64) -> np.ndarray:
    """Lifting DWT, Mallat layout [cA_J, cD_J, ..., cD_1]; len(x) must be a multiple of 2**level.

    Examples
    --------
    >>> c = wavedec(np.arange(64.0), "db4", 2)
    >>> c.shape
    (64,)
    """
    _check_wavelet(wavelet)
    arr = as_core_dtype(x, dtype)
    return core("wavelet").wavedec_periodization(arr, wavelet, int(level))


def waverec(c: Any, wavelet: str = "db8", level: int = 5, dtype: Any = np.float64) -> np.ndarray:
    """Inverse of :func:`wavedec`.

    Examples
    --------
    >>> x = np.random.default_rng(0).standard_normal(64)
    >>> bool(np.allclose(waverec(wavedec(x, "db8", 3), "db8", 3), x))
    True
    """
    _check_wavelet(wavelet)
    arr = as_core_dtype(c, dtype, what="c")
    return core("wavelet").wavedec_periodization(arr, wavelet, int(level), inverse=True)


def _threshold(d: np.ndarray, t: float, mode: str) -> np.ndarray:
    if mode == "hard":  # pywt.threshold hard: zero where |d| < t
        return np.where(np.abs(d) < t, 0.0, d).astype(d.dtype)
    mag = np.maximum(np.abs(d) - t, 0.0)  # soft: eta(W) = sgn(W)(|W| - t)+ (paper 000 sec. 2.3)
    return (np.sign(d) * mag).astype(d.dtype)


def wavelet_denoise(
    x: Any,
    wavelet: str = "db8",
    level: int = 5,
    mode: str = "soft",
    *,
    per_level_sigma: bool = False,
    dtype: Any = np.float64,
) -> np.ndarray:
    """Offline wavelet denoising of a 1-D record or of each column of an (n, 3) array.

    Examples
    --------
    >>> x = np.sin(np.arange(1024) / 50.0)
    >>> y = wavelet_denoise(x + 0.1 * np.random.default_rng(0).standard_normal(1024), "db8", 4)
    >>> bool(np.std(y - x) < 0.05)
    True
    """
    _check_wavelet(wavelet)
    if mode not in _MODES:
        raise GyrodriftValueError(f"mode must be one of {_MODES}, got {mode!r}")
    dt = _check_dtype(dtype)
    arr = as_core_dtype(x, dt)
    if arr.ndim == 2 and arr.shape[1] == 3:
        return np.stack(
            [
                wavelet_denoise(
                    arr[:, k], wavelet, level, mode, per_level_sigma=per_level_sigma, dtype=dt
                )
                for k in range(3)
            ],
            axis=1,
        )
    if arr.ndim != 1:
        raise GyrodriftValueError(f"x: expected a 1-D or (n, 3) array, got shape {arr.shape}")
    level = int(level)
    if not 1 <= level <= 8:
        raise GyrodriftValueError(f"level must be in 1..8, got {level}")
    n = arr.shape[0]
    if n < 2**level:
        raise GyrodriftValueError(
            f"x: {n} samples are too short for level {level} (need >= {2**level})")
    if not np.all(np.isfinite(arr)):
        raise GyrodriftValueError(
            f"x: non-finite value (NaN or Inf) at index {int(np.argmin(np.isfinite(arr)))}"
        )
    xp = np.ascontiguousarray(pad_symmetric(arr, 2**level), dtype=dt)
    c = wavedec(xp, wavelet, level, dtype=dt)
    if not np.all(np.isfinite(c)):
        # Finite but huge input (near the dtype's maximum) overflows the lifting sums: say
        # so, instead of the inverse transform's complaint about non-finite coefficients.
        raise GyrodriftValueError(
            f"x: values up to {float(np.max(np.abs(arr))):.3g} overflow the {dt.name} wavelet "
            f"transform (its largest value is {float(np.finfo(dt).max):.3g}); scale the record"
        )
    m = len(xp)
    n_approx = m >> level
    if mode == "forced":
        c[n_approx:] = 0
    else:
        t1 = float(np.median(np.abs(c[m // 2 :]))) / MAD_TO_SIGMA * math.sqrt(2 * math.log(n))
        for j in range(1, level + 1):  # level-j details occupy c[m >> j : m >> (j - 1)]
            band = slice(m >> j, m >> (j - 1))
            t = t1
            if per_level_sigma:
                t = float(np.median(np.abs(c[band]))) / MAD_TO_SIGMA * math.sqrt(2 * math.log(n))
            c[band] = _threshold(c[band], t, mode)
    y = waverec(c, wavelet, level, dtype=dt)[:n]
    if not np.all(np.isfinite(y)):
        raise GyrodriftValueError(
            f"x: values up to {float(np.max(np.abs(arr))):.3g} overflow the {dt.name} inverse "
            "wavelet transform; scale the record"
        )
    return y


class RealtimeWavelet:
    """Sliding-window wavelet prefilter (paper 004 sec. 2.2) on the C++ core, per axis.

    ``step(sample)`` takes a scalar (1 channel) or a 3-vector (3 channels); ``filter(x)``
    takes (n,) or (n, 3) and continues the same stream. The channel count is fixed by the
    first call. Start-up: the first ``window - 1`` samples pass through unfiltered
    (``ready`` is False). NaN/Inf samples are counted (``fault_counts``), left out of the
    window, and the previous output of that channel is repeated; so are, in float32, values
    beyond its range and samples whose window sums it cannot hold.

    Examples
    --------
    >>> f = RealtimeWavelet("db4", window=64, level=3)
    >>> y = f.filter(np.full(100, 2.0))
    >>> f.ready, round(float(y[-1]), 9)  # unit DC gain
    (True, 2.0)
    """

    def __init__(
        self,
        wavelet: str = PREFILTER_WAVELET,
        window: int = PREFILTER_WINDOW,
        level: int = PREFILTER_LEVEL,
        mode: str = PREFILTER_THRESHOLD,
        *,
        dtype: Any = np.float64,
    ) -> None:
        _check_wavelet(wavelet)
        if mode not in _MODES:
            raise GyrodriftValueError(f"mode must be one of {_MODES}, got {mode!r}")
        window = int(window)
        if window < 8 or window & (window - 1):
            raise GyrodriftValueError(f"window must be a power of two in 8..2048, got {window}")
        self.dtype = _check_dtype(dtype)
        self.wavelet, self.window, self.level, self.mode = wavelet, window, int(level), mode
        self._bank_cls = getattr(core("wavelet"), "RealtimeWaveletBank" + _DTYPES[self.dtype])
        self._bank_cls(self._config(1))  # validates level now
        self._bank: Any = None

    def _config(self, channels: int) -> Any:
        """The bound configuration of the C++ bank (gyrodrift._core.RealtimeWaveletConfig)."""
        return core("wavelet").RealtimeWaveletConfig(wavelet=self.wavelet, window=self.window,
                                             level=self.level, mode=self.mode,
                                             channels=channels)

    def _get_bank(self, channels: int) -> Any:
        if self._bank is None:
            self._bank = self._bank_cls(self._config(channels))
        elif self._bank.channels != channels:
            raise GyrodriftValueError(
                f"this filter runs {self._bank.channels} channel(s); got {channels} (call reset())"
            )
        return self._bank

    def filter(self, x: Any, *, recompute: bool = False) -> np.ndarray:
        """Filter (n,) or (n, 3) samples; recompute=True uses the full-window recompute path
        (the C++ reference algorithm, slow) instead of the streaming one."""
        with np.errstate(over="ignore"):  # beyond float32: Inf, counted as a fault
            arr = _as_float_array(x, self.dtype)
        if arr.ndim == 1:
            channels = 1
        elif arr.ndim == 2 and arr.shape[1] == 3:
            channels = 3
        else:
            raise GyrodriftValueError(f"x: expected a 1-D or (n, 3) array, got shape {arr.shape}")
        return self._get_bank(channels).filter(arr, recompute)

    def step(self, sample: Any) -> Any:
        with np.errstate(over="ignore"):  # beyond float32: Inf, counted as a fault
            arr = _as_float_array(sample, self.dtype, "sample")
        if arr.ndim == 0:
            return self.dtype.type(self.filter(arr.reshape(1))[0])
        if arr.shape == (3,):
            return self.filter(arr.reshape(1, 3))[0]
        raise GyrodriftValueError(f"sample: expected a scalar or a 3-vector, got shape {arr.shape}")

    def reset(self) -> None:
        """Back to the start-up state; the channel count may change after a reset."""
        self._bank = None

    @property
    def ready(self) -> bool:
        return bool(self._bank is not None and self._bank.ready)

    @property
    def fault_counts(self) -> np.ndarray:
        """NaN/Inf samples skipped, per channel."""
        if self._bank is None:
            return np.zeros(1, dtype=np.uint32)
        return self._bank.fault_counts()

    def fir_taps(self) -> np.ndarray:
        """Forced-mode equivalent FIR taps, newest first (`gyrodrift.filters.fir`)."""
        if self.mode != "forced":
            raise GyrodriftValueError("fir_taps(): only the forced mode is a linear (FIR) filter")
        return forced_fir_taps(self.wavelet, self.window, self.level, self.dtype)

    def group_delay_s(self, rate_hz: float = DEFAULT_SAMPLE_RATE_HZ, freq_hz: float = 0.0
                      ) -> float:
        """Group delay of the forced filter at freq_hz (default DC), seconds."""
        from scipy import signal

        _, gd = signal.group_delay((self.fir_taps().astype(float), 1), w=[freq_hz], fs=rate_hz)
        return float(gd[0]) / rate_hz
