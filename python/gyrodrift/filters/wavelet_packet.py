"""Wavelet-packet denoising with a Shannon best basis (paper 000, sec. 2.4), on PyWavelets.

1. Full packet tree to level J (pywt.WaveletPacket, mode="periodization", default bior3.7).
2. Best basis by the Coifman-Wickerhauser bottom-up search with the additive Shannon cost
   E(c) = -sum c_i^2 ln c_i^2 (0 ln 0 = 0): a parent replaces its children's best basis when
   E(parent) <= E(best(children)) (ties go to the parent, the coarser description). The root
   is never chosen: the denoiser splits at least once.
3. Thresholding of the chosen nodes: t = sigma sqrt(2 ln n), sigma = median(``|d|``)/0.6745 from
   the level-1 high-pass node "d" (the finest noise estimate, as in paper 000 sec. 2.3);
   every chosen node except the pure low-pass one ("aa...a") is thresholded (soft by default).
4. Reconstruction from the chosen nodes only; truncated to the input length.

Lengths that are not a multiple of 2**level are padded by half-sample symmetric reflection at
the end (as in gyrodrift.filters.wavelet.wavelet_denoise) and truncated back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pywt

from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.filters.wavelet import MAD_TO_SIGMA, pad_symmetric

__all__ = [
    "PacketDenoiseResult",
    "best_basis",
    "best_basis_from_costs",
    "shannon_cost",
    "wavelet_packet_denoise",
    "wavelet_packet_denoise_result",
]


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
        raise GyrodriftTypeError(f"x: expected a real numeric array, got dtype {arr.dtype}")
    arr = np.asarray(arr, dtype=float)
    if arr.ndim != 1:
        raise GyrodriftValueError(f"x: expected a 1-D array, got shape {arr.shape}")
    if wavelet not in pywt.wavelist(kind="discrete"):
        raise GyrodriftValueError(
            f"unsupported wavelet {wavelet!r} (not a PyWavelets discrete wavelet)")
    if not 1 <= int(level) <= 10:
        raise GyrodriftValueError(f"level must be in 1..10, got {level}")
    if len(arr) < 2**level:
        raise GyrodriftValueError(f"x: {len(arr)} samples are too short for level {level}")
    if not np.all(np.isfinite(arr)):
        raise GyrodriftValueError("x: contains NaN or Inf")
    return arr


def _best_from_tree(wp: pywt.WaveletPacket, level: int) -> list[str]:
    costs = {node.path: shannon_cost(node.data)
             for lev in range(1, level + 1) for node in wp.get_level(lev, order="natural")}
    return best_basis_from_costs(costs, level)


def best_basis_from_costs(costs: dict[str, float], level: int) -> list[str]:
    """The Shannon best basis (module docstring, step 2) from the cost of every node of the
    tree below the root (paths of 1 to `level` letters 'a'/'d').

    Examples
    --------
    >>> costs = {"a": 5.0, "d": 3.0, "aa": 1.0, "ad": 1.0, "da": 2.0, "dd": 2.0}
    >>> best_basis_from_costs(costs, 2)  # "a" splits (1 + 1 < 5), "d" does not (3 < 4)
    ['aa', 'ad', 'd']
    """
    best: dict[str, tuple[float, list[str]]] = {}
    for path in (p for p in costs if len(p) == level):  # leaves
        best[path] = (costs[path], [path])
    for lev in range(level - 1, 0, -1):  # bottom-up merge
        for path in (p for p in costs if len(p) == lev):
            ca, ba = best[path + "a"]
            cd, bd = best[path + "d"]
            own = costs[path]
            children = ca + cd
            # Ties (to rounding) go to the parent: the coarser basis.
            if own <= children + 1e-12 * max(1.0, abs(children)):
                best[path] = (own, [path])
            else:
                best[path] = (children, ba + bd)
    return sorted(best["a"][1] + best["d"][1])


def best_basis(x: Any, wavelet: str = "bior3.7", level: int = 4) -> list[str]:
    """Node paths ('a'/'d' strings) of the Shannon best basis (Coifman-Wickerhauser).

    Examples
    --------
    >>> b = best_basis(np.random.default_rng(0).standard_normal(256), "bior3.7", 3)
    >>> all(set(p) <= {"a", "d"} for p in b)
    True
    """
    arr = _check(x, wavelet, level)
    xp = pad_symmetric(arr, 2**level)
    return _best_from_tree(_tree(xp, wavelet, level), level)


@dataclass(frozen=True)
class PacketDenoiseResult:
    """Wavelet-packet denoising: the denoised record and the best basis it used.

    Examples
    --------
    >>> x = np.random.default_rng(0).standard_normal(256)
    >>> r = wavelet_packet_denoise_result(x, "bior3.7", 3)
    >>> r.y.shape, all(set(p) <= {"a", "d"} for p in r.basis)
    ((256,), True)
    """

    y: np.ndarray
    basis: list[str]
    threshold: float

    def as_dict(self) -> dict[str, object]:
        """JSON-ready values."""
        return {"y": self.y.tolist(), "basis": list(self.basis), "threshold": self.threshold}


def wavelet_packet_denoise_result(
    x: Any,
    wavelet: str = "bior3.7",
    level: int = 4,
    mode: str = "soft",
) -> PacketDenoiseResult:
    """Packet denoising (see the module doc) with the basis and threshold it used.

    Examples
    --------
    >>> x = np.sin(np.arange(512) / 20) + 0.1 * np.random.default_rng(1).standard_normal(512)
    >>> r = wavelet_packet_denoise_result(x, level=3)
    >>> bool(np.std(r.y - np.sin(np.arange(512) / 20)) < 0.1)
    True
    """
    if mode not in ("soft", "hard"):
        raise GyrodriftValueError(f"mode must be 'soft' or 'hard', got {mode!r}")
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
    return PacketDenoiseResult(np.asarray(y[:n]), basis, t)


def wavelet_packet_denoise(
    x: Any,
    wavelet: str = "bior3.7",
    level: int = 4,
    mode: str = "soft",
) -> np.ndarray:
    """Packet denoising (see the module doc): the denoised array.

    `wavelet_packet_denoise_result` also returns the best basis and the threshold.

    Examples
    --------
    >>> y = wavelet_packet_denoise(np.random.default_rng(0).standard_normal(256), level=3)
    >>> y.shape
    (256,)
    """
    return wavelet_packet_denoise_result(x, wavelet, level, mode).y
