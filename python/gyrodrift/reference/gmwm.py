"""GMWM oracles written literally from the definitions (Percival & Walden 2000).

- `haar_wv`: the Haar MODWT wavelet filter h_j of level j (L_j = 2^j taps, +1/2^j on the
  newest 2^(j-1) samples, -1/2^j on the older ones, P&W eq. 96) applied by direct
  convolution (numpy.convolve, "valid": only the M_j = N - L_j + 1 coefficients free of the
  boundary), then nu^2_j = mean of W_{j,t}^2. O(N L_j) per level: for test records.
- `haar_wv_pywt`: the same from PyWavelets' stationary wavelet transform (pywt.swt, 'haar',
  norm=True, i.e. the MODWT filters), keeping only coefficients that do not wrap around.
- `wv_covariance_fft`: the covariance of the estimated wavelet variances under a Gaussian
  model by the spectral route: c_ab(k) = inverse DFT of conj(H_a) H_b S (plus the random
  walk through the cumulative-sum filter G = cumsum(h)), Cov = 2/(M_a M_b) sum_k n_ab(k)
  c_ab(k)^2 (Isserlis). Independent of gyrodrift.stability.gmwm's closed-form lag route.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft

__all__ = ["haar_wv", "haar_wv_pywt", "wv_covariance_fft"]


def _taps(m: int) -> np.ndarray:
    return np.r_[np.full(m, 1.0 / (2 * m)), np.full(m, -1.0 / (2 * m))]


def haar_wv(x: np.ndarray, levels: int) -> np.ndarray:
    """Wavelet variance nu^2_j, j = 1..levels, by direct convolution with h_j.

    Examples
    --------
    >>> haar_wv(np.random.default_rng(0).normal(size=1024), 3).round(4)
    array([0.47  , 0.2375, 0.1208])
    """
    x = np.asarray(x, dtype=np.float64)
    out = np.empty(levels)
    for j in range(1, levels + 1):
        w = np.convolve(x, _taps(2 ** (j - 1)), mode="valid")  # W_t = sum_l h_l x_{t-l}
        out[j - 1] = np.mean(w * w)
    return out


def haar_wv_pywt(x: np.ndarray, levels: int) -> np.ndarray:
    """Wavelet variance from pywt.swt (MODWT normalisation), boundary coefficients dropped.

    pywt.swt is circular: the level-j detail is d_t = sum_i x_i g((t - i) mod N) for an
    effective filter g. The offsets k where g is non-zero come from a unit impulse; a
    coefficient is free of the wrap-around iff t - k stays in [0, N) for all of them.

    Examples
    --------
    >>> x = np.random.default_rng(0).normal(size=1024)
    >>> bool(np.allclose(haar_wv_pywt(x, 3), haar_wv(x, 3), rtol=1e-12))
    True
    """
    import pywt

    x = np.asarray(x, dtype=np.float64)
    n = x.size
    if n & (n - 1):
        raise ValueError("haar_wv_pywt needs a power-of-2 length (pywt.swt)")
    coeffs = pywt.swt(x, "haar", level=levels, norm=True, trim_approx=True)
    details = coeffs[1:][::-1]  # pywt returns [cA_J, cD_J, ..., cD_1]
    impulse = np.zeros(n)
    impulse[0] = 1.0
    g_all = pywt.swt(impulse, "haar", level=levels, norm=True, trim_approx=True)[1:][::-1]
    out = np.empty(levels)
    for j in range(1, levels + 1):
        k = np.flatnonzero(np.abs(g_all[j - 1]) > 1e-12)
        k = np.where(k > n // 2, k - n, k)  # signed offsets
        if k.size != 2 ** j:
            raise AssertionError(f"level {j}: filter of {k.size} taps, expected {2 ** j}")
        t = np.arange(n)
        ok = (t - k.max() >= 0) & (t - k.min() <= n - 1)
        out[j - 1] = float(np.mean(details[j - 1][ok] ** 2))
    return out


def wv_covariance_fft(comps: list[tuple[str, tuple[float, ...]]], levels: int, n: int
                      ) -> np.ndarray:
    """Covariance of (nu^2_1 .. nu^2_levels) of an n-sample record of the Gaussian model
    comps = [("N", (s2,)), ("Q", (q2,)), ("K", (g2,)), ("GM", (sigma2, tc_samples))].

    Examples
    --------
    >>> wv_covariance_fft([("N", (1.0,))], 2, 1024).round(6)
    array([[0.000733, 0.000183],
           [0.000183, 0.000214]])
    """
    cov = np.zeros((levels, levels))
    size = scipy.fft.next_fast_len(4 * n, real=True)
    f = np.fft.rfftfreq(size)
    z = np.exp(-2j * np.pi * f)
    spec = np.zeros(f.size)
    rw = 0.0
    for t, q in comps:
        if t == "N":
            spec += q[0]
        elif t == "Q":
            spec += q[0] * np.abs(1.0 - z) ** 2
        elif t == "GM":
            phi = math.exp(-1.0 / q[1])
            spec += q[0] * (1.0 - phi * phi) / np.abs(1.0 - phi * z) ** 2
        elif t == "K":
            rw += q[0]
    lag = np.arange(size)
    lag = np.where(lag > size // 2, lag - size, lag)
    hs = [np.fft.rfft(_taps(2 ** (j - 1)), size) for j in range(1, levels + 1)]
    gs = [np.fft.rfft(np.cumsum(_taps(2 ** (j - 1)))[:-1], size) for j in range(1, levels + 1)]
    for b in range(levels):
        for a in range(b + 1):
            cross = np.conj(hs[a]) * hs[b] * spec + rw * np.conj(gs[a]) * gs[b]
            c = np.fft.irfft(cross, size)
            la, lb = 2 ** (a + 1), 2 ** (b + 1)
            lo = np.maximum(la - 1, lb - 1 - lag)
            hi = np.minimum(n - 1, n - 1 - lag)
            cnt = np.clip(hi - lo + 1, 0, None)
            cov[a, b] = cov[b, a] = 2.0 * float(np.dot(cnt, c * c)) / (
                (n - la + 1) * (n - lb + 1))
    return cov
