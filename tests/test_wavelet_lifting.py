"""Lifting DWT (C++ core) against PyWavelets periodization; factorization derivation; float32.

Tolerances: double results are compared within 1e-12 absolute on unit-variance data (the
issue's requirement; observed ~2e-15, i.e. a few ulps times the 9 lifting steps x 8 levels).
Float32 is judged relative to a direct 16-tap float32 convolution on the same data (issue:
no worse than 4x it).
"""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest
import pywt
from conftest import REPO_ROOT
from gyrodrift import _core
from gyrodrift.filters.wavelet import wavedec, waverec
from hypothesis import given, settings
from hypothesis import strategies as st

TOL_DOUBLE = 1e-12


def pywt_concat(x: np.ndarray, wavelet: str, level: int) -> np.ndarray:
    return np.concatenate(pywt.wavedec(x, wavelet, mode="periodization", level=level))


@pytest.mark.filterwarnings("ignore:Level value")
@pytest.mark.parametrize("wavelet", ["db4", "db8"])
@pytest.mark.parametrize(("n", "level"), [(2, 1), (16, 4), (64, 1), (96, 5), (512, 5), (1024, 8)])
def test_wavedec_equals_pywt_periodization(wavelet: str, n: int, level: int, rng) -> None:
    x = rng.standard_normal(n)
    c = wavedec(x, wavelet, level)
    np.testing.assert_allclose(c, pywt_concat(x, wavelet, level), rtol=0, atol=TOL_DOUBLE)
    # waverec reproduces pywt.waverec of the pywt coefficients, and reconstructs x.
    ref = pywt.waverec(
        pywt.wavedec(x, wavelet, mode="periodization", level=level), wavelet, mode="periodization"
    )
    np.testing.assert_allclose(waverec(c, wavelet, level), ref, rtol=0, atol=TOL_DOUBLE)
    np.testing.assert_allclose(waverec(c, wavelet, level), x, rtol=0, atol=TOL_DOUBLE)


def test_wavedec_on_simulated_gyro_record() -> None:
    import gyrodrift as g

    rec = g.simulate(n=4096, rate_hz=400.0, n_deg_rt_h=0.01, b_deg_h=0.02, bias_deg_h=3.0, seed=5)
    x = (rec.rate_deg_h - rec.rate_deg_h.mean()) / rec.rate_deg_h.std()  # unit variance
    np.testing.assert_allclose(
        wavedec(x, "db8", 5), pywt_concat(x, "db8", 5), rtol=0, atol=TOL_DOUBLE
    )


@pytest.mark.filterwarnings("ignore:Level value")
@settings(max_examples=60, deadline=None)
@given(
    wavelet=st.sampled_from(["db4", "db8"]),
    level=st.integers(1, 8),
    blocks=st.integers(1, 12),
    seed=st.integers(0, 2**32 - 1),
)
def test_property_random_lengths_and_levels(
    wavelet: str, level: int, blocks: int, seed: int
) -> None:
    n = blocks * 2**level
    x = np.random.default_rng(seed).standard_normal(n)
    c = wavedec(x, wavelet, level)
    np.testing.assert_allclose(c, pywt_concat(x, wavelet, level), rtol=0, atol=TOL_DOUBLE)
    np.testing.assert_allclose(waverec(c, wavelet, level), x, rtol=0, atol=TOL_DOUBLE)


def direct_float32_dwt(x: np.ndarray, wavelet: str, level: int) -> np.ndarray:
    """Direct 2N-tap periodized convolution accumulated in float32 (the baseline)."""
    w = pywt.Wavelet(wavelet)
    h = np.array(w.rec_lo, dtype=np.float32)  # pywt: cA[k] = sum_m rec_lo[m+N-1] x[2k+m]
    g = np.array(w.rec_hi, dtype=np.float32)
    m0 = -(len(h) // 2 - 1)
    a = x.astype(np.float32)
    details = []
    for _ in range(level):
        ca = np.zeros(len(a) // 2, np.float32)
        cd = np.zeros(len(a) // 2, np.float32)
        for i in range(len(h)):
            xs = np.roll(a, -(m0 + i))[0::2]
            ca = ca + h[i] * xs
            cd = cd + g[i] * xs
        details.insert(0, cd)
        a = ca
    return np.concatenate([a, *details])


@pytest.mark.parametrize("wavelet", ["db4", "db8"])
@pytest.mark.parametrize("level", [1, 5])
def test_float32_error_not_worse_than_4x_direct_convolution(wavelet: str, level: int, rng) -> None:
    x = rng.standard_normal(1 << 14)
    exact = pywt_concat(x, wavelet, level)
    err_lift = np.max(
        np.abs(wavedec(x.astype(np.float32), wavelet, level, dtype=np.float32) - exact)
    )
    err_direct = np.max(np.abs(direct_float32_dwt(x, wavelet, level) - exact))
    assert err_lift <= 4.0 * err_direct, (err_lift, err_direct)
    # And the float32 transform is a float32-accurate transform at all (~1e-6 on unit data).
    assert err_lift < 2e-5


def test_float32_perfect_reconstruction(rng) -> None:
    x = rng.standard_normal(4096).astype(np.float32)
    c = wavedec(x, "db8", 5, dtype=np.float32)
    assert c.dtype == np.float32
    np.testing.assert_allclose(waverec(c, "db8", 5, dtype=np.float32), x, rtol=0, atol=2e-5)


def header_constants(name: str) -> tuple[list[float], float, float]:
    header = REPO_ROOT / "include" / "gyrodrift" / "filters" / f"lifting_coefficients_{name}.hpp"
    text = header.read_text()
    steps = text[text.index("kStep[kSteps]") :]
    coefs = [float(v) for v in re.findall(r"Scalar\(([-0-9.e]+)\)", steps)]
    k_a = float(re.search(r"kA = Scalar\(([-0-9.e]+)\)", text).group(1))
    k_d = float(re.search(r"kD = Scalar\(([-0-9.e]+)\)", text).group(1))
    return coefs, k_a, k_d


def test_db8_factorization_is_well_conditioned() -> None:
    coefs, k_a, k_d = header_constants("db8")
    assert len(coefs) == 9 * 2  # 9 steps, up to 2 taps each (zero-padded)
    assert max(abs(c) for c in coefs) < 1.0
    assert k_a == pytest.approx(1.214, abs=1e-3)
    assert k_a * k_d == pytest.approx(1.0, abs=1e-15)  # det of the polyphase matrix is 1


def test_db4_factorization_is_well_conditioned() -> None:
    coefs, _, _ = header_constants("db4")
    assert max(abs(c) for c in coefs) < 1.0


def test_headers_match_the_high_precision_derivation() -> None:
    """Re-runs scripts/derive_lifting.py (mpmath, 60 digits) and compares with the headers."""
    proc = subprocess.run(
        [sys.executable, str(REPO_ROOT / "scripts" / "derive_lifting.py"), "--check"],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "max|c|=0.864292 K=1.213794916" in proc.stdout


@pytest.mark.parametrize(
    ("kwargs", "exc", "message"),
    [
        ({"x": np.zeros(100), "level": 3}, ValueError, "multiple of 2\\*\\*level"),
        ({"x": np.zeros(64), "level": 0}, ValueError, "level must be in 1..8"),
        ({"x": np.zeros(512), "level": 9}, ValueError, "level must be in 1..8"),
        ({"x": np.array([1.0, np.nan, 0, 0]), "level": 1}, ValueError, "non-finite"),
        ({"x": np.zeros((8, 2)), "level": 1}, ValueError, "1-D"),
        ({"x": np.zeros(0), "level": 1}, ValueError, "multiple"),
    ],
)
def test_transform_bad_arguments(kwargs: dict, exc: type, message: str) -> None:
    with pytest.raises(exc, match=message):
        wavedec(kwargs["x"], "db8", kwargs["level"])


def test_unsupported_wavelet_and_dtype() -> None:
    with pytest.raises(ValueError, match="unsupported wavelet 'sym8'"):
        wavedec(np.zeros(64), "sym8", 2)
    with pytest.raises(TypeError, match="float64 or float32"):
        wavedec(np.zeros(64), "db8", 2, dtype=np.int32)
    with pytest.raises(TypeError):  # the core itself refuses a silent conversion
        _core.wavedec_periodization(np.zeros(64, dtype=np.int64), "db8", 2)
