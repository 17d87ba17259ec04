"""Offline wavelet denoiser (paper 000 sec. 2.3) on the C++ lifting core vs the pywt reference.

Tolerance 1e-12 absolute (double, unit-variance data; the lifting transform matches pywt to
~1e-15 and thresholding is exact apart from coefficients within 1e-15 of t, which random data
does not produce). Float32: 5e-5 (float32 ulps x 8 levels x sqrt(n) accumulation).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SHARED_DATA
from gyrodrift import wavelet_denoise, wavelet_packet_denoise
from gyrodrift.reference import wavelet as ref
from hypothesis import given, settings
from hypothesis import strategies as st

TOL = 1e-12


def real_records() -> list[tuple[str, np.ndarray]]:
    """The real laser-gyro record (first 5000 samples of each gyro axis, counts, 100 Hz) when
    /work/shared/data is present; the package itself never needs it."""
    path = SHARED_DATA / "lasergyro.imu"
    if not path.exists():
        return []
    rows = []
    with path.open() as fh:
        data_lines = (ln for ln in fh if ln.strip() and not ln.startswith("%"))
        for i, line in enumerate(data_lines):
            if i >= 3:
                rows.append([float(v) for v in line.split()[:3]])
            if len(rows) == 5000:
                break
    gyro = np.array(rows)
    return [(f"lasergyro-{'xyz'[k]}", gyro[:, k]) for k in range(3)]


REAL = real_records()


@pytest.mark.parametrize(("name", "counts"), REAL, ids=[r[0] for r in REAL])
@pytest.mark.parametrize("mode", ["soft", "hard", "forced"])
def test_real_laser_gyro_record(name: str, counts: np.ndarray, mode: str) -> None:
    x = (counts - counts.mean()) / counts.std()  # unit variance, as the tolerance assumes
    got = wavelet_denoise(x, "db8", 5, mode)
    np.testing.assert_allclose(got, ref.wavelet_denoise(x, "db8", 5, mode), rtol=0, atol=TOL)
    # Quantized pulse counts: the denoised record keeps the mean (the drift) and is smoother
    # sample to sample (the record includes vehicle motion, so no fixed reduction factor).
    assert abs(got.mean() - x.mean()) < 1e-3
    assert np.std(np.diff(got)) < np.std(np.diff(x))
    if mode == "soft":
        y = wavelet_packet_denoise(x, "bior3.7", 4)
        assert y.shape == x.shape and np.std(np.diff(y)) < np.std(np.diff(x))


@pytest.mark.parametrize("mode", ["soft", "hard", "forced"])
@pytest.mark.parametrize("per_level_sigma", [False, True])
@pytest.mark.parametrize("wavelet", ["db4", "db8"])
@pytest.mark.parametrize("n", [1024, 1000, 777])  # multiple of 2**5, and not
def test_denoise_equals_pywt_reference(
    mode: str, per_level_sigma: bool, wavelet: str, n: int, rng
) -> None:
    x = np.sin(np.arange(n) * 0.01) + rng.standard_normal(n)
    got = wavelet_denoise(x, wavelet, 5, mode, per_level_sigma=per_level_sigma)
    want = ref.wavelet_denoise(x, wavelet, 5, mode, per_level_sigma)
    assert got.shape == (n,)
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


def test_reference_uses_pywt_periodization_directly_for_dyadic_lengths(rng) -> None:
    """For n a multiple of 2**J no padding happens: the reference is plain pywt."""
    import pywt

    x = rng.standard_normal(512)
    c = pywt.wavedec(x, "db8", mode="periodization", level=4)
    c = [c[0]] + [np.zeros_like(d) for d in c[1:]]
    want = pywt.waverec(c, "db8", mode="periodization")
    np.testing.assert_allclose(wavelet_denoise(x, "db8", 4, "forced"), want, rtol=0, atol=TOL)


def test_non_dyadic_length_padding_is_symmetric_reflection() -> None:
    x = np.arange(5.0)
    np.testing.assert_array_equal(ref.pad_symmetric(x, 8), [0, 1, 2, 3, 4, 4, 3, 2])
    np.testing.assert_array_equal(ref.pad_symmetric(x[:2], 8), [0, 1, 1, 0, 0, 1, 1, 0])


def test_denoising_reduces_error_on_a_drifting_gyro_signal(rng) -> None:
    n = 4096
    t = np.arange(n) / 400.0
    truth = 0.5 * np.sin(2 * np.pi * 0.2 * t) + 0.1 * t
    noisy = truth + 0.3 * rng.standard_normal(n)
    for mode in ("soft", "hard", "forced"):
        y = wavelet_denoise(noisy, "db8", 5, mode)
        rms_in = np.sqrt(np.mean((noisy - truth) ** 2))
        rms_out = np.sqrt(np.mean((y - truth) ** 2))
        assert rms_out < 0.5 * rms_in, (mode, rms_in, rms_out)


def test_three_axes_and_float32(rng) -> None:
    x = rng.standard_normal((600, 3))
    y = wavelet_denoise(x, "db4", 4, "soft")
    for k in range(3):
        np.testing.assert_allclose(
            y[:, k], ref.wavelet_denoise(x[:, k], "db4", 4, "soft"), rtol=0, atol=TOL
        )
    y32 = wavelet_denoise(x.astype(np.float32), "db4", 4, "soft", dtype=np.float32)
    assert y32.dtype == np.float32
    np.testing.assert_allclose(y32, y, rtol=0, atol=5e-5)


@pytest.mark.filterwarnings("ignore:Level value")
@settings(max_examples=40, deadline=None)
@given(
    wavelet=st.sampled_from(["db4", "db8"]),
    level=st.integers(1, 6),
    extra=st.integers(0, 300),
    mode=st.sampled_from(["soft", "hard", "forced"]),
    per_level=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_property_random_lengths_and_levels(
    wavelet: str, level: int, extra: int, mode: str, per_level: bool, seed: int
) -> None:
    n = 2**level + extra
    x = np.random.default_rng(seed).standard_normal(n)
    got = wavelet_denoise(x, wavelet, level, mode, per_level_sigma=per_level)
    want = ref.wavelet_denoise(x, wavelet, level, mode, per_level)
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


@pytest.mark.parametrize(
    ("x", "kwargs", "exc", "message"),
    [
        (np.r_[np.zeros(100), np.nan], {}, ValueError, "non-finite .* index 100"),
        (np.r_[np.zeros(100), np.inf], {}, ValueError, "non-finite"),
        (np.zeros(31), {"level": 5}, ValueError, "too short for level 5"),
        (np.zeros(64), {"level": 9}, ValueError, "level must be in 1..8"),
        (np.zeros(64), {"mode": "garrote"}, ValueError, "mode must be"),
        (np.zeros(64), {"wavelet": "sym4"}, ValueError, "unsupported wavelet"),
        (np.zeros((64, 2)), {}, ValueError, r"1-D or \(n, 3\)"),
        (np.array(["a"] * 64), {}, TypeError, "real numeric"),
        (np.zeros(64), {"dtype": np.float16}, TypeError, "float64 or float32"),
    ],
)
def test_bad_input(x: np.ndarray, kwargs: dict, exc: type, message: str) -> None:
    args = {"wavelet": "db8", "level": 3, "mode": "soft"} | kwargs
    dtype = args.pop("dtype", np.float64)
    with pytest.raises(exc, match=message):
        wavelet_denoise(x, args["wavelet"], args["level"], args["mode"], dtype=dtype)
