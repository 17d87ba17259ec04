"""The forced real-time wavelet prefilter (paper 004 sec. 2.2) as the FIR filter it is.

Forced denoising (every detail coefficient of a J-level decomposition set to zero) of a
sliding window of N samples, mirrored (symmetric extension, sec. 2.2 step 1), output = the
newest sample of the reconstruction. Every step is linear in the window, so once the window
is full the filter is an N-tap FIR; its taps depend only on the wavelet, N and J.

**Tap order (the one order of the package): newest first**, the scipy.signal.lfilter
convention::

    y[k] = sum_{i=0}^{N-1} b[i] x[k - i]        (b[0] multiplies the newest sample)

The C++ real-time bank and the alignment pipeline store the taps oldest first; the binding
boundary reverses them (here and in `gyrodrift.nav.run_alignment`), nowhere else.

The taps sum to 1 (unit DC gain: the approximation space contains constants), so the filter
cannot reduce angle random walk (the integral of the gyro rate is preserved); it removes
high-frequency content (dither residue, vibration, quantization noise) at the price of a
group delay (8.2 samples at DC for db4, N = 256, J = 5).

Examples
--------
>>> b = forced_fir_taps("db4", 64, 3)
>>> b.shape, round(float(b.sum()), 12)
((64,), 1.0)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gyrodrift._native import core
from gyrodrift.defaults import (
    DEFAULT_SAMPLE_RATE_HZ,
    PREFILTER_LEVEL,
    PREFILTER_WAVELET,
    PREFILTER_WINDOW,
)
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError

__all__ = [
    "TAP_ORDER",
    "apply_fir",
    "fir_group_delay",
    "forced_fir_taps",
    "group_delay_dc_samples",
]

#: The tap order of every FIR array in the package.
TAP_ORDER = "newest first: y[k] = sum_i b[i] x[k - i]"

_BANKS = {np.dtype(np.float64): "RealtimeWaveletBankF64",
          np.dtype(np.float32): "RealtimeWaveletBankF32"}


def forced_fir_taps(
    wavelet: str = PREFILTER_WAVELET, window: int = PREFILTER_WINDOW,
    level: int = PREFILTER_LEVEL, dtype: Any = np.float64
) -> np.ndarray:
    """Taps of the forced real-time wavelet prefilter, newest first, from the C++ core.

    Parameters
    ----------
    wavelet : {"db4", "db8"}
    window : int
        Window N, a power of two in 8..2048.
    level : int
        Decomposition level J (2**J <= N).
    dtype : float64 or float32
        Arithmetic of the C++ bank the taps come from.

    Returns
    -------
    numpy.ndarray
        N taps b, ``b[0]`` on the newest sample (lfilter convention).

    Examples
    --------
    >>> b = forced_fir_taps("db4", 256, 5)
    >>> round(group_delay_dc_samples(b), 3)  # samples at DC
    8.185
    """
    dt = np.dtype(dtype)
    if dt not in _BANKS:
        raise GyrodriftTypeError(f"dtype must be float64 or float32, got {dt}")
    window = int(window)
    if window < 8 or window & (window - 1):
        raise GyrodriftValueError(f"window must be a power of two in 8..2048, got {window}")
    lib = core("wavelet")
    bank = getattr(lib, _BANKS[dt])(lib.RealtimeWaveletConfig(
        wavelet=wavelet, window=window, level=int(level), mode="forced", channels=1))
    return np.ascontiguousarray(np.asarray(bank.taps())[::-1])


def group_delay_dc_samples(taps: np.ndarray) -> float:
    """Group delay at DC, sum_i i b_i / sum_i b_i, in samples (taps newest first).

    Examples
    --------
    >>> group_delay_dc_samples(np.array([0.5, 0.5]))
    0.5
    """
    b = np.asarray(taps, dtype=np.float64)
    return float(np.arange(b.size) @ b / b.sum())


def apply_fir(x: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """Run the sliding-window FIR over (n,) or (n, k) samples, taps newest first.

    The first N - 1 outputs are the raw samples (the window is still filling, paper 004
    sec. 2.2 step 1), as the real-time filter does.

    Examples
    --------
    >>> apply_fir(np.array([1.0, 3.0, 5.0]), np.array([0.5, 0.5]))
    array([1., 2., 4.])
    """
    x = np.asarray(x, dtype=float)
    b = np.asarray(taps, dtype=float)
    n = len(b)
    y = x.copy()
    if x.shape[0] < n:
        return y
    if x.ndim == 1:
        y[n - 1:] = np.convolve(x, b, mode="valid")
    else:
        for j in range(x.shape[1]):
            y[n - 1:, j] = np.convolve(x[:, j], b, mode="valid")
    return y


def fir_group_delay(
    b: np.ndarray, rate_hz: float = DEFAULT_SAMPLE_RATE_HZ, n_freqs: int = 512
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequency (Hz), magnitude ``|H|`` and group delay (s) of FIR taps b (newest first).

    Examples
    --------
    >>> f, mag, gd = fir_group_delay(np.array([0.5, 0.5]), rate_hz=100.0, n_freqs=8)
    >>> float(mag[0]), float(gd[0])
    (1.0, 0.005)
    """
    from scipy import signal

    b = np.asarray(b, dtype=float)
    f_hz, h = signal.freqz(b, 1, worN=n_freqs, fs=rate_hz)
    _, gd_samples = signal.group_delay((b, 1), w=n_freqs, fs=rate_hz)
    return f_hz, np.abs(h), gd_samples / rate_hz
