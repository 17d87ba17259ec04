"""PyWavelets reference implementations of the wavelet denoisers, the test oracles.

Written straight from the equations, deliberately plain:

* offline denoiser (paper 000, sec. 2.3): J-level periodized DWT, t = sigma sqrt(2 ln n),
  sigma = median(``|d1|``) / 0.6745, soft ``eta(W) = sgn(W)(|W| - t)+`` or hard, or forced (all
  details zero), inverse DWT;
* real-time sliding window (paper 004, sec. 2.2): per sample, the full recompute of the
  symmetric-extended window ``ext = [w, w[::-1]]``, output ``waverec(...)[N - 1]``;
* wavelet packets (paper 000, sec. 2.4): the best basis by brute force over every admissible
  basis (the oracle for the Coifman-Wickerhauser search in gyrodrift.filters.wavelet_packet).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pywt

from gyrodrift.defaults import (
    PREFILTER_LEVEL,
    PREFILTER_THRESHOLD,
    PREFILTER_WAVELET,
    PREFILTER_WINDOW,
)

__all__ = [
    "MAD_TO_SIGMA",
    "admissible_bases",
    "best_basis_bruteforce",
    "forced_fir_taps",
    "pad_symmetric",
    "realtime_wavelet",
    "realtime_window",
    "shannon_cost",
    "threshold_value",
    "wavelet_denoise",
]

MAD_TO_SIGMA = 0.6745  # median(|N(0,1)|); paper 000 sec. 2.3, Donoho & Johnstone 1994


def pad_symmetric(x: np.ndarray, multiple: int) -> np.ndarray:
    """Pad the end to a multiple of `multiple` by half-sample symmetric reflection
    (x[n-1], x[n-2], ...; numpy.pad mode="symmetric").

    Examples
    --------
    >>> pad_symmetric(np.arange(3), 4)
    array([0, 1, 2, 2])
    """
    x = np.asarray(x)
    return np.pad(x, (0, (-len(x)) % multiple), mode="symmetric")


def threshold_value(d1: np.ndarray, n: int) -> float:
    """t = sigma sqrt(2 ln n) with sigma = median(``|d1|``) / 0.6745 (paper 000 sec. 2.3).

    Examples
    --------
    >>> round(threshold_value(np.array([0.6745, -0.6745]), 100), 6)  # sigma 1: sqrt(2 ln 100)
    3.034854
    """
    sigma = float(np.median(np.abs(d1))) / MAD_TO_SIGMA
    return sigma * math.sqrt(2.0 * math.log(n))


def wavelet_denoise(
    x: np.ndarray,
    wavelet: str = "db8",
    level: int = 5,
    mode: str = "soft",
    per_level_sigma: bool = False,
) -> np.ndarray:
    """Offline denoiser with pywt (periodization). A length that is not a multiple of 2**level
    is padded by symmetric reflection at the end and the result truncated back; n in the
    threshold is the original length.

    Examples
    --------
    >>> wavelet_denoise(np.random.default_rng(0).normal(size=64), "db4", 2).shape
    (64,)
    """
    x = np.asarray(x, dtype=float)
    n = len(x)
    xp = pad_symmetric(x, 2**level)
    coeffs = pywt.wavedec(xp, wavelet, mode="periodization", level=level)
    t1 = threshold_value(coeffs[-1], n)
    out = [coeffs[0]]
    for d in coeffs[1:]:
        if mode == "forced":
            out.append(np.zeros_like(d))
            continue
        t = threshold_value(d, n) if per_level_sigma else t1
        out.append(pywt.threshold(d, t, mode=mode))
    return pywt.waverec(out, wavelet, mode="periodization")[:n]


def realtime_window(w: np.ndarray, wavelet: str, level: int, mode: str) -> float:
    """The real-time wavelet prefilter's output for one window w (oldest first), by its
    definition: decompose the window followed by its mirror image (periodized DWT), threshold
    the details (forced: zero them), reconstruct, and keep the newest sample of the window.

    Examples
    --------
    >>> round(realtime_window(np.ones(32), "db4", 2, "forced"), 12)  # constants pass
    1.0
    """
    n = len(w)
    ext = np.concatenate([w, w[::-1]])
    c = pywt.wavedec(ext, wavelet, mode="periodization", level=level)
    if mode == "forced":
        c = [c[0]] + [np.zeros_like(d) for d in c[1:]]
    else:
        t = threshold_value(c[-1], n)
        c = [c[0]] + [pywt.threshold(d, t, mode=mode) for d in c[1:]]
    return float(pywt.waverec(c, wavelet, mode="periodization")[n - 1])


def realtime_wavelet(
    x: np.ndarray, wavelet: str = PREFILTER_WAVELET, window: int = PREFILTER_WINDOW,
    level: int = PREFILTER_LEVEL, mode: str = PREFILTER_THRESHOLD
) -> np.ndarray:
    """Per-sample recompute over a 1-D stream. Start-up: the first window-1 accepted samples
    pass through unchanged. NaN/Inf samples are skipped (not in the window) and the previous
    output (0 before any) is repeated.

    Examples
    --------
    >>> y = realtime_wavelet(np.ones(40), "db4", 32, 2, "forced")
    >>> y.shape, round(float(y[-1]), 12)
    ((40,), 1.0)
    """
    x = np.asarray(x, dtype=float)
    out = np.empty_like(x)
    accepted: list[float] = []
    last = 0.0
    for i, v in enumerate(x):
        if not math.isfinite(v):
            out[i] = last
            continue
        accepted.append(float(v))
        if len(accepted) < window:
            last = float(v)
        else:
            last = realtime_window(np.array(accepted[-window:]), wavelet, level, mode)
        out[i] = last
    return out


def forced_fir_taps(wavelet: str, window: int, level: int) -> np.ndarray:
    """Forced-mode taps, newest first (the package's one order, gyrodrift.filters.fir), by
    linearity:
    b[i] is the output for a window holding 1 at age i (i samples before the newest).

    Examples
    --------
    >>> b = forced_fir_taps("db4", 32, 2)
    >>> b.shape, round(float(b.sum()), 12)  # newest first, unit DC gain
    ((32,), 1.0)
    """
    eye = np.eye(window)
    return np.array([realtime_window(eye[window - 1 - i], wavelet, level, "forced")
                     for i in range(window)])


# ---------------------------------------------------------------------------------------------
# Wavelet packets: brute-force best basis (oracle for Coifman-Wickerhauser)


def shannon_cost(c: np.ndarray) -> float:
    """Non-normalised Shannon entropy -sum c^2 log c^2 (0 log 0 = 0), additive over nodes.

    Examples
    --------
    >>> round(shannon_cost(np.array([0.5, 0.5])), 4)
    0.6931
    """
    e = np.asarray(c, dtype=float) ** 2
    e = e[e > 0]
    return float(-np.sum(e * np.log(e)))


def admissible_bases(path: str, max_level: int) -> Iterator[list[str]]:
    """Every admissible basis (set of disjoint nodes tiling the subtree of `path`).

    Examples
    --------
    >>> list(admissible_bases("a", 2))
    [['a'], ['aa', 'ad']]
    """
    yield [path]
    if len(path) < max_level:
        for left in admissible_bases(path + "a", max_level):
            for right in admissible_bases(path + "d", max_level):
                yield left + right


def best_basis_bruteforce(x: np.ndarray, wavelet: str, level: int) -> list[str]:
    """The admissible basis with the least total Shannon cost, by exhaustive search (the
    root itself is not a candidate: a packet denoiser splits at least once). Ties are broken
    towards the shallower node (the parent), as in Coifman-Wickerhauser.

    Examples
    --------
    >>> b = best_basis_bruteforce(np.random.default_rng(0).standard_normal(64), "db4", 2)
    >>> all(set(p) <= {"a", "d"} for p in b)
    True
    """
    wp = pywt.WaveletPacket(x, wavelet, mode="periodization", maxlevel=level)
    cost = {}
    for lev in range(1, level + 1):
        for node in wp.get_level(lev, order="natural"):
            cost[node.path] = shannon_cost(node.data)
    best: list[str] | None = None
    best_key: tuple[float, int] | None = None
    for left in admissible_bases("a", level):
        for right in admissible_bases("d", level):
            basis = left + right
            total = sum(cost[p] for p in basis)
            key = (round(total, 9), sum(len(p) for p in basis))
            if best_key is None or key < best_key:
                best, best_key = basis, key
    assert best is not None
    return sorted(best)
