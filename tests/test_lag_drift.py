"""The drift model from whole-record lag statistics (gyrodrift.reference.lag_drift): the
streaming statistics against the direct sums, the likelihood from them against the core's
exact Kalman likelihood and against Whittle's formula on a frequency grid, and the fit
against the offline ML fit (gyrodrift.fit_drift_model)."""

from __future__ import annotations

import itertools
import math

import gyrodrift
import numpy as np
import pytest
from gyrodrift._native import core
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.reference.lag_drift import (
    LagStatisticsReference,
    lag_drift_fit,
    lag_loglike,
    lags_needed,
)
from scipy.signal import lfilter

PAIRS = ((0.6868, -0.0213), (0.2297, 0.1638))


def _record(a1: float, a2: float, ratio: float, n: int, seed: int) -> np.ndarray:
    """AR(2) drift (q = 1, 2000 samples of burn-in) plus white noise (r = ratio) on 9.7."""
    rng = np.random.default_rng(seed)
    x = lfilter([1.0], [1.0, -a1, -a2], rng.normal(size=n + 2000))[2000:]
    return 9.7 + x + rng.normal(0.0, math.sqrt(ratio), n)


def _stats(y: np.ndarray, lags: int) -> LagStatisticsReference:
    st = LagStatisticsReference(lags)
    edges = [0, 1, 8, 341, 2000, y.size]  # uneven chunks, one shorter than L
    for lo, hi in itertools.pairwise(edges):
        st.push(y[lo:hi])
    return st


def test_streaming_statistics_equal_the_direct_sums() -> None:
    """Pushed in uneven chunks, the lag products equal the whole-array sums, and the lag sums
    about any mean equal sum_{t>=k} (y_t - m)(y_{t-k} - m) computed directly (double:
    1e-12 relative; both are sums of 5000 products)."""
    y = _record(0.6868, -0.0213, 1.0, 5000, 3)
    st = _stats(y, 12)
    w = y - y[0]
    direct = np.array([w[k:] @ w[: w.size - k] for k in range(13)])
    assert st.n == 5000 and st.centre == y[0]
    np.testing.assert_allclose(st.products, direct, rtol=1e-12)
    for m in (9.7, float(np.mean(y)), 0.0):
        z = y - m
        want = np.array([z[k:] @ z[: z.size - k] for k in range(13)])
        np.testing.assert_allclose(st.lag_sums(m), want, rtol=1e-12, atol=1e-9 * want[0])


@pytest.mark.parametrize(("a1", "a2"), PAIRS)
def test_likelihood_equals_the_exact_kalman_likelihood(a1: float, a2: float) -> None:
    """At L = 32 the likelihood from the statistics equals the core's exact one (Kalman
    filter, stationary start, on the samples) at the truth and away from it: the neglected
    terms are of order rho^32 <= 4e-12 per sample here (rho <= 0.44 at r/q = 3; observed
    differences about 1e-15 relative), so 1e-11 relative. At L = 4 the truncation shows
    (rho^4 about 0.04): the comparison can fail."""
    y = _record(a1, a2, 3.0, 20000, 1)
    exact = core("drift").drift_loglike
    st32, st4 = _stats(y, 32), _stats(y, 4)
    for params in ((a1, a2, 1.0, 3.0, 9.7), (0.5, 0.1, 2.0, 1.0, 9.5), (0.9, -0.2, 0.5, 4.0,
                                                                           10.0)):
        want = exact(y, *params)[0]
        assert lag_loglike(st32, *params) == pytest.approx(want, rel=1e-11)
        assert abs(lag_loglike(st4, *params) - want) > 1e-3
    assert lags_needed(a1, a2, 1.0, 3.0) <= 32


def test_whittle_form_equals_the_frequency_grid() -> None:
    """Whittle's form from the statistics equals -(n log 2 pi + n log sigma^2 +
    sum_k S_k d_k) / 2 with d_k and log sigma^2 = mean log S taken on a 4096-point grid of
    S(w) = q / |A|^2 + r (grid aliasing of d_k below 1e-300 here), at 1e-12 relative."""
    a1, a2, q, r, mean = 0.6868, -0.0213, 1.0, 3.0, 9.7
    y = _record(a1, a2, r, 20000, 2)
    st = _stats(y, 32)
    w = 2.0 * np.pi * np.arange(4096) / 4096
    s = q / np.abs(1.0 - a1 * np.exp(-1j * w) - a2 * np.exp(-2j * w)) ** 2 + r
    d = np.real(np.fft.ifft(1.0 / s))[:33]
    sums = st.lag_sums(mean)
    quad = sums[0] * d[0] + 2.0 * sums[1:] @ d[1:]
    want = -0.5 * (y.size * math.log(2.0 * math.pi) + y.size * np.mean(np.log(s)) + quad)
    assert lag_loglike(st, a1, a2, q, r, mean, kind="whittle") == pytest.approx(want, rel=1e-12)


@pytest.mark.parametrize(("a1", "a2", "n", "seed"),
                         [(*PAIRS[0], 60000, 1), (*PAIRS[1], 60000, 1), (*PAIRS[0], 240000, 5)])
def test_fit_reaches_the_offline_ml_fit(a1: float, a2: float, n: int, seed: int) -> None:
    """From the statistics alone the fit lands on the offline ML fit of the same record:
    every parameter and the mean within 0.05 of the offline standard error (the two
    optimisers' stopping rules; the requirement is 1), and its exact log-likelihood within
    0.01 of the offline maximum. The third record has a maximum on each side of a2 = 0
    (a2 +0.059 and -0.070, the second 0.3 log-likelihood units lower, 8 standard errors
    away) and every start of the grid ranked best runs to the lower one: the run across the
    fold finds the other."""
    y = _record(a1, a2, 1.0, n, seed)
    est = lag_drift_fit(_stats(y, 32))
    fit = gyrodrift.fit_drift_model(y, rate_hz=400.0)
    for k in ("a1", "a2", "q", "r", "mean"):
        assert abs(getattr(est, k) - getattr(fit, k)) <= 0.05 * fit.stderr[k], k
    exact = core("drift").drift_loglike
    assert exact(y, est.a1, est.a2, est.q, est.r, est.mean)[0] >= fit.loglike - 0.01
    assert est.truncation < 1e-10


def test_bad_input_is_a_clear_error() -> None:
    with pytest.raises(GyrodriftValueError, match="lags must be"):
        LagStatisticsReference(0)
    st = LagStatisticsReference(8)
    with pytest.raises(GyrodriftValueError, match="NaN or Inf"):
        st.push([1.0, math.nan])
    assert st.n == 0
    st.push(np.arange(10.0))
    with pytest.raises(GyrodriftValueError, match="at least 18 needed"):
        lag_drift_fit(st)
    st.push(np.arange(10.0))
    with pytest.raises(GyrodriftValueError, match="kind must be"):
        lag_loglike(st, 0.5, 0.0, 1.0, 1.0, 0.0, kind="nope")


@pytest.mark.parametrize(("a2", "q", "lags"), [(-0.9, 1.0, 8), (0.99, 0.01, 32),
                                               (-0.99, 0.01, 32)])
def test_steady_state_with_a1_zero_is_the_riccati_fixed_point(a2: float, q: float,
                                                             lags: int) -> None:
    """With a1 = 0 the even and the odd samples are two chains and the innovation variance F
    moves every other step only. The recursion used to stop at the first step F did not move,
    short of the steady state by up to 0.5 % of sigma^2 (a2 = 0.99, q/r = 0.01, L = 32); it
    must equal the DARE's (scipy) to 1e-12 relative (the recursion stops at a change of
    1e-15 relative, a contraction of at least about 0.9 a step leaves ~1e-14)."""
    import scipy.linalg
    from gyrodrift.reference.lag_drift import _steady

    r = 1.0
    a = np.array([[0.0, a2], [1.0, 0.0]])
    p = scipy.linalg.solve_discrete_are(a.T, np.array([[1.0], [0.0]]), np.diag([q, 0.0]),
                                        np.array([[r]]))
    assert _steady(0.0, a2, q, r, lags)[3] == pytest.approx(p[0, 0] + r, rel=1e-12)
