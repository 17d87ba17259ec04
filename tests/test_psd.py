"""Welch PSD in (deg/h)^2/Hz: white level of angle random walk, Parseval, log binning."""

from __future__ import annotations

import gyrodrift
import numpy as np
import pytest
import scipy.signal
from gyrodrift.stability import psd


def test_white_level_gives_arw() -> None:
    # N = 0.05 deg/sqrt(h) at 200 Hz: one-sided level 2 (60 N)^2 = 18 (deg/h)^2/Hz. 2e5
    # samples, nperseg 4096 -> ~97 half-overlapping segments, per-bin sd ~ 1/sqrt(48) = 14 %;
    # the median over the 2049 bins is biased by ln2/(chi2 median) ~ -4 % at 2*48 edf... use
    # the mean: sd 14 %/sqrt(2049) ~ 0.3 %, so 3 % is > 9 sd.
    rec = gyrodrift.simulate(n=200_000, rate_hz=200.0, n_deg_rt_h=0.05, seed=11)
    p = psd.welch_psd(rec.rate_deg_h, 200.0, nperseg=4096)
    level = float(np.mean(p.psd[1:]))
    assert level == pytest.approx(2.0 * (60.0 * 0.05) ** 2, rel=0.03)
    assert psd.arw_from_white_level(level) == pytest.approx(0.05, rel=0.02)


def test_parseval_and_equals_scipy(rng: np.random.Generator) -> None:
    x = rng.normal(3.0, 2.0, 65_536)
    p = psd.welch_psd(x, 10.0)
    _f, ref = scipy.signal.welch(x, fs=10.0, nperseg=p.nperseg)
    np.testing.assert_allclose(p.psd, ref, rtol=1e-12)
    # integral of the one-sided PSD = variance (hann window, 50 % overlap: within 2 %)
    assert np.trapezoid(p.psd, p.f_hz) == pytest.approx(np.var(x), rel=0.02)


def test_log_binned_means() -> None:
    f = np.arange(0, 1001, dtype=float)  # 0..1000 Hz, DC dropped
    s = f.copy()
    fb, sb = psd.log_binned(f, s, bins_per_decade=10)
    assert np.all(np.diff(fb) > 0)
    # each bin's mean lies inside its bin, and the first bin (1 Hz..1.26 Hz) holds only f=1
    assert sb[0] == 1.0
    assert fb.size <= 30 and sb[-1] > 800  # last bin: 794..1000 Hz


def test_bad_input() -> None:
    with pytest.raises(ValueError, match="too short"):
        psd.welch_psd(np.ones(5), 1.0)
    with pytest.raises(ValueError, match="NaN"):
        psd.welch_psd(np.r_[np.ones(100), np.nan], 1.0)
