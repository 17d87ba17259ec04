"""bior3.7 wavelet-packet denoising (paper 000 sec. 2.4): Coifman-Wickerhauser best basis
against an exhaustive search, on signals whose best basis is known, and the denoiser."""

from __future__ import annotations

import numpy as np
import pytest
import pywt
from gyrodrift import best_basis, wavelet_packet_denoise
from gyrodrift.filters.wavelet_packet import wavelet_packet_denoise_result
from gyrodrift.reference.wavelet import best_basis_bruteforce

LEAVES3 = ["aaa", "aad", "ada", "add", "daa", "dad", "dda", "ddd"]


def packet_atom(path: str, wavelet: str = "bior3.7", level: int = 3, n: int = 128) -> np.ndarray:
    """Synthesis of one unit coefficient in node `path` (all other leaves zero)."""
    wp = pywt.WaveletPacket(None, wavelet, mode="periodization", maxlevel=level)
    for leaf in LEAVES3:
        wp[leaf] = np.zeros(n >> level)
    atom = np.zeros(n >> level)
    atom[5] = 1.0
    wp[path] = atom
    return wp.reconstruct(update=False)


@pytest.mark.parametrize(
    ("path", "expected"),
    [
        # A packet atom has Shannon cost 0 in its own node (one coefficient equal to 1) and
        # positive cost in every other node that sees it (spread coefficients, all |c| < 1
        # for bior3.7's filters); the rest of the tree is zero (cost 0), where ties go to the
        # coarser node. So the best basis is the coarsest tiling that contains the atom's node.
        ("ada", ["aa", "ada", "add", "d"]),
        ("ddd", ["a", "da", "dda", "ddd"]),
        ("dad", ["a", "daa", "dad", "dd"]),
        ("aad", ["aaa", "aad", "ad", "d"]),
    ],
)
def test_best_basis_of_a_packet_atom_is_known(path: str, expected: list[str]) -> None:
    x = packet_atom(path)
    assert best_basis(x, "bior3.7", 3) == expected
    assert best_basis_bruteforce(x, "bior3.7", 3) == expected


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("level", [3, 4])
def test_coifman_wickerhauser_equals_exhaustive_search(seed: int, level: int) -> None:
    rng = np.random.default_rng(seed)
    n = 256
    t = np.arange(n)
    # Mixtures of tones and noise with a non-trivial best basis.
    x = np.sin(2 * np.pi * (0.05 + 0.1 * seed) * t) + 0.3 * rng.standard_normal(n) * (t > n / 2)
    assert best_basis(x, "bior3.7", level) == best_basis_bruteforce(x, "bior3.7", level)


def test_best_basis_tiles_the_frequency_axis() -> None:
    x = np.random.default_rng(1).standard_normal(300)  # not a multiple of 2**4: padded
    basis = best_basis(x, "bior3.7", 4)
    width = sum(2.0 ** -len(p) for p in basis)
    assert width == pytest.approx(1.0)
    for p in basis:
        assert not any(q != p and q.startswith(p) for q in basis)


def test_packet_denoise_reduces_noise_and_keeps_length() -> None:
    rng = np.random.default_rng(2)
    n = 2000
    t = np.arange(n) / 100.0
    truth = np.sin(2 * np.pi * 0.3 * t) + 0.2 * np.sin(2 * np.pi * 1.1 * t)
    noisy = truth + 0.4 * rng.standard_normal(n)
    res = wavelet_packet_denoise_result(noisy, "bior3.7", 4)
    y, basis = res.y, res.basis
    np.testing.assert_array_equal(y, wavelet_packet_denoise(noisy, "bior3.7", 4))
    assert y.shape == (n,)
    assert basis == best_basis(noisy, "bior3.7", 4)
    rms_in = np.sqrt(np.mean((noisy - truth) ** 2))
    rms_out = np.sqrt(np.mean((y - truth) ** 2))
    assert rms_out < 0.5 * rms_in


def test_packet_denoise_without_noise_reconstructs_the_signal() -> None:
    # Piecewise-constant signal: the noise estimate from node "d" is 0, so t = 0 and the
    # chosen basis must reconstruct the input (biorthogonal perfect reconstruction).
    x = np.repeat(np.arange(16.0), 16)
    np.testing.assert_allclose(wavelet_packet_denoise(x, "bior3.7", 3), x, rtol=0, atol=1e-10)


@pytest.mark.parametrize(
    ("x", "kwargs", "exc", "message"),
    [
        (np.r_[np.zeros(63), np.nan], {}, ValueError, "NaN or Inf"),
        (np.zeros(7), {"level": 3}, ValueError, "too short"),
        (np.zeros(64), {"wavelet": "nope"}, ValueError, "unsupported wavelet"),
        (np.zeros(64), {"mode": "forced"}, ValueError, "mode must be"),
        (np.zeros((64, 3)), {}, ValueError, "1-D"),
        (np.zeros(64, dtype=complex), {}, TypeError, "real numeric"),
    ],
)
def test_bad_input(x: np.ndarray, kwargs: dict, exc: type, message: str) -> None:
    args = {"wavelet": "bior3.7", "level": 3, "mode": "soft"} | kwargs
    with pytest.raises(exc, match=message):
        wavelet_packet_denoise(x, args["wavelet"], args["level"], args["mode"])
