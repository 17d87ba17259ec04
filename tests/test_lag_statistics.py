"""The whole-record lag statistics of the C++ core (gyrodrift.filters.LagStatistics) against
the numpy reference's (gyrodrift.reference.lag_drift.LagStatisticsReference), float against
double on a long record, and the reference's likelihood and fit on the C++ statistics."""

from __future__ import annotations

import itertools
import math

import gyrodrift
import numpy as np
import pytest
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.filters import LagStatistics
from gyrodrift.reference.lag_drift import (
    LagDriftFit,
    LagStatisticsLike,
    LagStatisticsReference,
    lag_drift_fit,
    lag_loglike,
)
from gyrodrift.simulation.records import simulate

U32 = 2.0**-24  # unit roundoff of float32


def _record(n: int, seed: int) -> np.ndarray:
    """A gyro record in deg/h at 400 Hz: bias 9.7 deg/h, angle random walk 0.005 deg/sqrt(h)
    (6 deg/h per sample) and an AR(2) drift (0.6868, -0.0213) driven by 6 deg/h: q = r."""
    rec = simulate(n=n, rate_hz=400.0, n_deg_rt_h=0.005, bias_deg_h=9.7,
                   ar2=(0.6868, -0.0213, 6.0), seed=seed)
    return np.asarray(rec.rate_deg_h, dtype=np.float64)


def _push(st: LagStatistics | LagStatisticsReference, y: np.ndarray, edges: list[int]) -> None:
    for lo, hi in itertools.pairwise([0, *edges, y.size]):
        st.push(y[lo:hi])


def test_double_statistics_equal_the_reference() -> None:
    """Pushed in different uneven chunks, the C++ double statistics equal the reference's:
    n, the centre, the first and the last 32 values of w exactly (the same subtraction
    y - c in double); the lag products and sum w within 1e-12 of their scale (P_0, and
    sum |w|): both sum 2e5 terms in double, numpy's dot products pairwise (error about
    log2(n) eps of the scale) and the C++ core in compensated pairs (about eps), so 1e-12
    leaves a margin of 100 over the worst of them. The scale is P_0 for every P_k: a lag
    product can be small against P_0, and its rounding scales with P_0."""
    y = _record(200003, 1)
    cpp, ref = LagStatistics(), LagStatisticsReference(32)
    _push(cpp, y, [1, 31, 32, 100, 50000])
    _push(ref, y, [7, 40, 2000])
    assert (cpp.n, cpp.rejected) == (y.size, 0)
    assert cpp.centre == ref.centre == y[0]
    np.testing.assert_array_equal(cpp.head, ref.head)
    np.testing.assert_array_equal(cpp.tail, ref.tail)
    p0 = ref.products[0]
    assert np.max(np.abs(cpp.products - ref.products)) <= 1e-12 * p0
    assert abs(cpp.total - ref.total) <= 1e-12 * float(np.sum(np.abs(y - y[0])))


def test_float_statistics_after_a_long_record() -> None:
    """The float state (as on the target) against the double state on the same float32
    samples, 1e6 of them (about 42 min at 400 Hz; the 10 h figure is in the docs). Bound
    (lag_statistics.hpp): each w_t and each product is rounded once in float and the pair
    sums add a rounding of order n u^2 (6e-9 relative here), so
    |dP_k| <= (3 u + n u^2) sum |w_t w_{t-k}| <= 4 u P_0 (u = 2^-24, 2.4e-7), sum w within
    2 u sum |w|, and the first and the last values of w within u |w|."""
    y = _record(1_000_000, 2).astype(np.float32)
    f32, f64 = LagStatistics(dtype=np.float32), LagStatistics()
    assert f32.push(y) == f64.push(y.astype(np.float64)) == y.size
    p0 = f64.products[0]
    assert np.max(np.abs(f32.products - f64.products)) <= 4.0 * U32 * p0
    w = y.astype(np.float64) - float(y[0])
    assert abs(f32.total - f64.total) <= 2.0 * U32 * float(np.sum(np.abs(w)))
    np.testing.assert_allclose(f32.head, f64.head, rtol=U32, atol=0.0)
    np.testing.assert_allclose(f32.tail, f64.tail, rtol=U32, atol=0.0)
    assert f32.state_bytes == 552 and f64.state_bytes == 1080


def _same_fit(a: LagDriftFit, b: LagDriftFit, st_b: LagStatisticsLike, se: dict[str, float]
              ) -> None:
    """Fit a against fit b (from the statistics st_b) of one record: every parameter and the
    mean within 1e-3 of the offline standard errors, and a's parameters as good a maximum of
    st_b's likelihood as b's own to 1e-6 log-likelihood units."""
    for k in ("a1", "a2", "q", "r", "mean"):
        assert abs(getattr(a, k) - getattr(b, k)) <= 1e-3 * se[k], k
    assert lag_loglike(st_b, a.a1, a.a2, a.q, a.r, a.mean) >= b.loglike - 1e-6


def test_likelihood_and_fit_on_the_cpp_statistics() -> None:
    """The reference's likelihood and fit take the C++ statistics as they are. The
    log-likelihood at three parameter sets equals the one from the reference statistics to
    1e-11 relative (the statistics agree to about 1e-15 of their scale; the likelihood's
    quadratic form adds 33 of them with weights of order 1 and is of the order of n, so the
    difference this makes is below 1e-13 relative). The fit from the C++ statistics runs the
    same optimiser from the same starts on a likelihood that differs in the last digits, and
    its BFGS stops (gtol 1e-10 on the per-sample gradient) at slightly different points of
    the likelihood's ridge: every parameter within 1e-3 standard errors of the reference
    fit's (the offline fit's standard errors; observed about 1e-4), and on the reference
    statistics its log-likelihood within 1e-6 of the reference fit's maximum (observed
    4e-9)."""
    y = _record(60000, 3)
    cpp, ref = LagStatistics(), LagStatisticsReference(32)
    cpp.push(y)
    ref.push(y)
    for params in ((0.6868, -0.0213, 36.0, 36.0, 9.7), (0.5, 0.1, 50.0, 20.0, 9.0),
                   (0.9, -0.2, 10.0, 60.0, 10.5)):
        assert lag_loglike(cpp, *params) == pytest.approx(lag_loglike(ref, *params), rel=1e-11)
    _same_fit(lag_drift_fit(cpp), lag_drift_fit(ref), ref,
              gyrodrift.fit_drift_model(y, rate_hz=400.0).stderr)


def test_fit_on_float_statistics() -> None:
    """The fit from the float state's statistics against the fit from the double state's, on
    the same float32 samples. The statistics differ by up to 3e-8 of their scale here (the
    float rounding of w = y - c, the centre 8 deg/h off the mean), which shifts the
    log-likelihood as a whole by about 1e-3 units but moves its maximum by far less than the
    optimiser's stopping rule does: the same tolerances as the double statistics against
    the reference (observed: about 1e-4 standard errors; the float fit's parameters score
    higher on the double statistics than the double fit's own, by 8e-9)."""
    y = _record(60000, 4).astype(np.float32)
    f32, f64 = LagStatistics(dtype=np.float32), LagStatistics()
    f32.push(y)
    f64.push(y.astype(np.float64))
    _same_fit(lag_drift_fit(f32), lag_drift_fit(f64), f64,
              gyrodrift.fit_drift_model(y.astype(np.float64), rate_hz=400.0).stderr)


def test_copy_into_the_reference() -> None:
    """A reference copy of the C++ statistics gives the lag sums about any mean and pushes on
    as the reference would have (the same tolerance as above)."""
    y = _record(3000, 5)
    cpp, ref = LagStatistics(), LagStatisticsReference(32)
    cpp.push(y[:2000])
    ref.push(y)
    copy = LagStatisticsReference.from_statistics(cpp)
    copy.push(y[2000:])
    assert copy.n == ref.n and copy.centre == ref.centre
    np.testing.assert_array_equal(copy.tail, ref.tail)
    for m in (9.7, 0.0):
        want = ref.lag_sums(m)
        assert np.max(np.abs(copy.lag_sums(m) - want)) <= 1e-12 * want[0]
    short = LagStatistics()
    short.push([1.0, 2.0])
    assert LagStatisticsReference.from_statistics(short).head.tolist() == [0.0, 1.0]


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_non_finite_samples_are_refused(dtype: type) -> None:
    """NaN and Inf are skipped and counted; the statistics are those of the other samples."""
    y = _record(500, 6).astype(dtype)
    bad = y.copy()
    bad[[0, 100, 499]] = [math.nan, math.inf, -math.inf]
    st, clean = LagStatistics(dtype=dtype), LagStatistics(dtype=dtype)
    assert st.push(bad) == 497
    assert clean.push(np.delete(y, [0, 100, 499])) == 497
    assert (st.n, st.rejected, clean.rejected) == (497, 3, 0)
    assert st.centre == clean.centre and st.total == clean.total
    np.testing.assert_array_equal(st.products, clean.products)
    np.testing.assert_array_equal(st.head, clean.head)
    np.testing.assert_array_equal(st.tail, clean.tail)
    st.reset()
    assert (st.n, st.rejected, st.products[0]) == (0, 0, 0.0)


def test_bad_arguments_are_clear_errors() -> None:
    with pytest.raises(GyrodriftValueError, match="dtype must be"):
        LagStatistics(dtype=np.int32)
    with pytest.raises(GyrodriftValueError, match="1-D"):
        LagStatistics().push(np.zeros((3, 2)))
    st = LagStatistics()
    st.push(np.arange(10.0))
    with pytest.raises(GyrodriftValueError, match="at least 66 needed"):
        lag_drift_fit(st)
