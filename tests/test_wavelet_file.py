"""The offline wavelet denoisers of a record read in pieces (gyrodrift.filters.wavelet_file)
give the whole-record denoisers' output: `wavelet_denoise` bit for bit (the same lifting
arithmetic on the same samples inside each window, the same threshold: exact comparison),
`wavelet_packet_denoise` to 1e-12 of the record's scale (PyWavelets' inverse transform sums
in another order near a window's edge: ~1e-15 seen; a wrong window, threshold or basis is off
by the noise level, ~1). The median of the level-1 details is exact: numpy.median of the
values, also for an even count and ties."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gyrodrift.filters import wavelet_file
from gyrodrift.filters.wavelet import wavelet_denoise
from gyrodrift.filters.wavelet_packet import wavelet_packet_denoise


def _record(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.standard_normal(n) * 3.0 + np.cumsum(rng.standard_normal(n)) * 0.01 + 5.0


@pytest.mark.parametrize("values", [
    np.abs(np.random.default_rng(1).standard_normal(100_001)),
    np.abs(np.random.default_rng(2).standard_normal(70_000)) * 1e-300,
    np.repeat([0.0, 1.5, 2.0, 2.0, 7.0], 30_000),  # ties across the wanted ranks
])
def test_median_from_passes_is_numpys(values: np.ndarray) -> None:
    passes = []

    def pieces():
        passes.append(1)
        return (values[i:i + 4099] for i in range(0, values.size, 4099))

    assert wavelet_file._median(pieces, values.size) == float(np.median(values))
    assert 2 <= len(passes) <= 10


@pytest.mark.parametrize("n", [20_000, 20_011])
@pytest.mark.parametrize("mode", ["soft", "hard", "forced"])
def test_wavelet_denoise_in_pieces_is_the_whole_record_denoiser(
        tmp_path: Path, n: int, mode: str) -> None:
    x = _record(n, 3)
    np.save(tmp_path / "x.npy", x)
    mm = np.load(tmp_path / "x.npy", mmap_mode="r")  # read with file reads
    for wavelet, level, piece in (("db8", 5, 1024), ("db4", 3, 4128)):
        ref = wavelet_denoise(x, wavelet, level, mode)
        pieces = list(wavelet_file.wavelet_denoise_pieces(mm, wavelet, level, mode,
                                                          piece=piece))
        assert len(pieces) > 3
        np.testing.assert_array_equal(np.concatenate(pieces), ref)



@pytest.mark.parametrize("mode", ["soft", "hard"])
def test_float32_wavelet_denoise_in_pieces_is_the_whole_record_float32_denoiser(
        tmp_path: Path, mode: str) -> None:
    """The float32 lifting core (the MCU build's, `gyrodrift filter --core float`) over
    windows of a memory-mapped record gives the whole-record float32 output.

    Tolerance: 1e-5 of the record's scale (max |x|). Each window is rounded to float32 as
    the whole record is and every coefficient inside it is the same float32 lifting
    arithmetic on the same samples, so the output is equal bit for bit on this build; the
    tolerance leaves room for a compiler that contracts the lifting loops into fused
    multiply-adds differently at a window's edge than inside it (float32's unit roundoff
    6e-8 times the ~100 roundings of a db8 level-5 round trip: ~6e-6 of the scale at
    worst). A wrong margin, threshold or piece boundary is off by the noise level (~1, a
    fifth of the scale). The pieces must also be float32 computations: closer to the
    whole float32 output than the float64 denoiser is (~5e-6 here, float32 rounding)."""
    x = _record(20_011, 6)
    np.save(tmp_path / "x.npy", x)
    mm = np.load(tmp_path / "x.npy", mmap_mode="r")  # read with file reads
    scale = float(np.max(np.abs(x)))
    for wavelet, level, piece in (("db8", 5, 1024), ("db4", 3, 4128)):
        ref = wavelet_denoise(x, wavelet, level, mode, dtype=np.float32)
        pieces = list(wavelet_file.wavelet_denoise_pieces(mm, wavelet, level, mode,
                                                          piece=piece, dtype=np.float32))
        assert len(pieces) > 3 and all(p.dtype == np.float32 for p in pieces)
        y = np.concatenate(pieces)
        np.testing.assert_allclose(y, ref, rtol=0, atol=1e-5 * scale)
        err32 = float(np.max(np.abs(y - ref)))
        gap64 = float(np.max(np.abs(wavelet_denoise(x, wavelet, level, mode) - ref)))
        assert err32 < 0.5 * gap64, (err32, gap64)


def test_float32_pieces_refuse_what_float32_cannot_hold() -> None:
    """A value beyond float32's range is infinite in the float32 core: refused with its
    index, as the whole-record float32 denoiser refuses it."""
    x = _record(20_000, 5)
    x[12_345] = 1e39
    with pytest.raises(ValueError, match="at index 12345") as whole:
        wavelet_denoise(x, dtype=np.float32)
    with pytest.raises(ValueError, match="at index 12345") as pieces:
        next(wavelet_file.wavelet_denoise_pieces(x, piece=1024, dtype=np.float32))
    assert str(pieces.value) == str(whole.value)
    assert next(wavelet_file.wavelet_denoise_pieces(x, piece=1024)).dtype == np.float64


@pytest.mark.parametrize("mode", ["soft", "hard"])
def test_wavelet_packet_denoise_in_pieces_is_the_whole_record_denoiser(
        tmp_path: Path, mode: str) -> None:
    x = _record(50_003, 4)
    np.save(tmp_path / "x.npy", x)
    mm = np.load(tmp_path / "x.npy", mmap_mode="r")
    ref = wavelet_packet_denoise(x, "bior3.7", 4, mode)
    pieces = list(wavelet_file.wavelet_packet_denoise_pieces(mm, "bior3.7", 4, mode,
                                                             piece=4096))
    assert len(pieces) > 10
    np.testing.assert_allclose(np.concatenate(pieces), ref, rtol=0,
                               atol=1e-12 * float(np.max(np.abs(x))))


def test_pieces_refuse_nan_with_its_index() -> None:
    x = _record(20_000, 5)
    x[12_345] = np.nan
    with pytest.raises(ValueError, match="at index 12345"):
        next(wavelet_file.wavelet_denoise_pieces(x, piece=1024))
    with pytest.raises(ValueError, match="at index 12345"):
        next(wavelet_file.wavelet_packet_denoise_pieces(x, piece=1024))
