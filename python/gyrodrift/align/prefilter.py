"""The real-time wavelet prefilter of paper 004 (sec. 2.2) as the FIR filter it is.

Forced denoising (all detail coefficients of a db4, level-5 decomposition set to zero) of a
sliding window of N samples, mirrored (symmetric periodic extension, sec. 2.2 step 1), output =
the newest sample of the reconstruction. Every step is linear in the window, so the filter is
an N-tap FIR whose taps are the reference applied to unit vectors. DC gain is 1 (db4
reproduces constants), so it cannot reduce angle random walk (the integral of the gyro rate
is preserved); it removes high-frequency content (dither residue, vibration, quantization
noise) at the price of a group delay of about 8 samples at DC.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pywt


def _forced_newest(window: np.ndarray, wavelet: str, level: int) -> float:
    ext = np.concatenate([window, window[::-1]])
    coeffs = pywt.wavedec(ext, wavelet, mode="periodization", level=level)
    coeffs = [coeffs[0]] + [np.zeros_like(c) for c in coeffs[1:]]
    return float(pywt.waverec(coeffs, wavelet, mode="periodization")[len(window) - 1])


@lru_cache(maxsize=8)
def _taps_cached(n: int, wavelet: str, level: int) -> tuple[float, ...]:
    eye = np.eye(n)
    return tuple(_forced_newest(eye[j], wavelet, level) for j in range(n))


def realtime_wavelet_taps(n: int = 256, wavelet: str = "db4", level: int = 5,
                          source: str = "core") -> np.ndarray:
    """Taps h (oldest first): y_k = sum_j h_j x_{k-N+1+j}.

    source="core": the wavelet area's C++ RealtimeWavelet (lifting-derived taps, the filter a
    navigation computer runs; needs the wavelet binding); source="pywt": derived here from
    the PyWavelets definition applied to unit windows (the independent cross-check)."""
    if n < 2 ** level or n % (2 ** level):
        raise ValueError(f"window {n} must be a positive multiple of 2**level = {2 ** level}")
    if source == "core":
        from gyrodrift.wavelet import forced_fir_taps

        return np.ascontiguousarray(forced_fir_taps(wavelet, n, level)[::-1], dtype=np.float64)
    if source == "pywt":
        return np.array(_taps_cached(n, wavelet, level))
    raise ValueError(f"source must be 'core' or 'pywt', got {source!r}")


def group_delay_dc_samples(taps: np.ndarray) -> float:
    """Group delay at DC, sum_j h_j (N-1-j) / sum_j h_j, in samples."""
    n = len(taps)
    age = (n - 1) - np.arange(n)
    return float(taps @ age / taps.sum())


def apply_realtime(x: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """Run the sliding-window filter over (n,) or (n, k) samples: the first N-1 outputs are
    the raw samples (the window is still filling, paper 004 sec. 2.2 step 1)."""
    x = np.asarray(x, dtype=float)
    n = len(taps)
    y = x.copy()
    if x.shape[0] < n:
        return y
    if x.ndim == 1:
        y[n - 1:] = np.convolve(x, taps[::-1], mode="valid")
    else:
        for j in range(x.shape[1]):
            y[n - 1:, j] = np.convolve(x[:, j], taps[::-1], mode="valid")
    return y
