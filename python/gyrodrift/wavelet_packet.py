"""Wavelet-packet denoising with a Shannon best basis (paper 000, sec. 2.4), on PyWavelets.

1. Full packet tree to level J (pywt.WaveletPacket, mode="periodization", default bior3.7).
2. Best basis by the Coifman-Wickerhauser bottom-up search with the additive Shannon cost
   E(c) = -sum c_i^2 ln c_i^2 (0 ln 0 = 0): a parent replaces its children's best basis when
   E(parent) <= E(best(children)) (ties go to the parent, the coarser description). The root
   is never chosen: the denoiser splits at least once.
3. Thresholding of the chosen nodes: t = sigma sqrt(2 ln n), sigma = median(|d|)/0.6745 from
   the level-1 high-pass node "d" (the finest noise estimate, as in paper 000 sec. 2.3);
   every chosen node except the pure low-pass one ("aa...a") is thresholded (soft by default).
4. Reconstruction from the chosen nodes only; truncated to the input length.

Lengths that are not a multiple of 2**level are padded by half-sample symmetric reflection at
the end (as in gyrodrift.wavelet.wavelet_denoise) and truncated back.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pywt

from gyrodrift.wavelet import MAD_TO_SIGMA, pad_symmetric

__all__ = ["best_basis", "wavelet_packet_denoise"]


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


def _tree(x: np.ndarray, wavelet: str, level: int) -> pywt.WaveletPacket:
    return pywt.WaveletPacket(x, wavelet, mode="periodization", maxlevel=level)


def _check(x: Any, wavelet: str, level: int) -> np.ndarray:
    arr = np.asarray(x)
    if arr.dtype.kind not in "fiu":
        raise TypeError(f"x: expected a real numeric array, got dtype {arr.dtype}")
    arr = np.asarray(arr, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"x: expected a 1-D array, got shape {arr.shape}")
    if wavelet not in pywt.wavelist(kind="discrete"):
        raise ValueError(f"unsupported wavelet {wavelet!r} (not a PyWavelets discrete wavelet)")
    if not 1 <= int(level) <= 10:
        raise ValueError(f"level must be in 1..10, got {level}")
    if len(arr) < 2**level:
        raise ValueError(f"x: {len(arr)} samples are too short for level {level}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("x: contains NaN or Inf")
    return arr


def _best_from_tree(wp: pywt.WaveletPacket, level: int) -> list[str]:
    best: dict[str, tuple[float, list[str]]] = {}
    for node in wp.get_level(level, order="natural"):  # leaves
        best[node.path] = (shannon_cost(node.data), [node.path])
    for lev in range(level - 1, 0, -1):  # bottom-up merge
        for node in wp.get_level(lev, order="natural"):
            ca, ba = best[node.path + "a"]
            cd, bd = best[node.path + "d"]
            own = shannon_cost(node.data)
            children = ca + cd
            # Ties (to rounding) go to the parent: the coarser basis.
            if own <= children + 1e-12 * max(1.0, abs(children)):
                best[node.path] = (own, [node.path])
            else:
                best[node.path] = (children, ba + bd)
    return sorted(best["a"][1] + best["d"][1])


def best_basis(x: Any, wavelet: str = "bior3.7", level: int = 4) -> list[str]:
    """Node paths ('a'/'d' strings) of the Shannon best basis (Coifman-Wickerhauser)."""
    arr = _check(x, wavelet, level)
    xp = pad_symmetric(arr, 2**level)
    return _best_from_tree(_tree(xp, wavelet, level), level)


def wavelet_packet_denoise(
    x: Any,
    wavelet: str = "bior3.7",
    level: int = 4,
    mode: str = "soft",
    *,
    return_basis: bool = False,
) -> Any:
    """Packet denoising (see the module doc). Returns the denoised array, or
    (array, basis paths) with return_basis=True."""
    if mode not in ("soft", "hard"):
        raise ValueError(f"mode must be 'soft' or 'hard', got {mode!r}")
    arr = _check(x, wavelet, level)
    n = len(arr)
    xp = pad_symmetric(arr, 2**level)
    wp = _tree(xp, wavelet, level)
    basis = _best_from_tree(wp, level)
    sigma = float(np.median(np.abs(wp["d"].data))) / MAD_TO_SIGMA
    t = sigma * math.sqrt(2.0 * math.log(n))
    out = pywt.WaveletPacket(None, wavelet, mode="periodization", maxlevel=level)
    for path in basis:
        data = wp[path].data
        out[path] = data if set(path) == {"a"} else pywt.threshold(data, t, mode=mode)
    y = out.reconstruct(update=False)
    return (y[:n], basis) if return_basis else y[:n]
