"""The drift-model fit from whole-record lag statistics in the C++ core
(include/gyrodrift/filters/lag_drift_fit.hpp, gyrodrift.filters.lag_drift_fit): its
likelihood against the numpy reference's (gyrodrift.reference.lag_drift.lag_loglike), its fit
against the reference's fit and against the offline ML fit (gyrodrift.fit_drift_model), on a
record with a maximum on each side of the fold a2 = 0 among others, and its refusals."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import gyrodrift
import numpy as np
import pytest
from gyrodrift._native import core
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.filters import (
    LagDriftFitError,
    LagStatistics,
    lag_drift_fit,
    lag_drift_loglike,
)
from gyrodrift.reference.lag_drift import LagStatisticsReference, lag_loglike
from gyrodrift.reference.lag_drift import lag_drift_fit as reference_fit
from scipy.signal import lfilter

PAIRS = ((0.6868, -0.0213), (0.2297, 0.1638))
PARAMS = ("a1", "a2", "q", "r", "mean")


def _record(a1: float, a2: float, ratio: float, n: int, seed: int) -> np.ndarray:
    """AR(2) drift (q = 1, 2000 samples of burn-in) plus white noise (r = ratio) on 9.7: the
    records of tests/test_lag_drift.py and scripts/drift_fold_check.py."""
    rng = np.random.default_rng(seed)
    x = lfilter([1.0], [1.0, -a1, -a2], rng.normal(size=n + 2000))[2000:]
    return 9.7 + x + rng.normal(0.0, math.sqrt(ratio), n)


# Models away from the records' own: a2 = 0 (the fold), and poles of A of modulus 0.95 with
# q/r = 0.05, whose innovation filter's pole modulus is 0.85 (Whittle's kinds take the steady
# state in closed form, the reference iterates the Riccati recursion to it).
OFF_MODELS = ((0.5, 0.0, 1.0, 1.0, 9.7), (1.2, -0.9, 0.05, 1.0, 9.7))


@pytest.mark.parametrize(("a1", "a2"), PAIRS)
@pytest.mark.parametrize("ratio", [1.0, 3.0])
def test_likelihood_equals_the_reference(a1: float, a2: float, ratio: float) -> None:
    """The C++ log-likelihood from the statistics equals the reference's on the same
    statistics (the C++ double state, and the float state read the same way by both), exact
    and Whittle's kind, at the truth and away from it, to 1e-12 relative. Both evaluate the
    same formula in double from the same 33 + 64 statistics; they differ in the order of
    their sums (numpy's dot products against running sums) and in library log/exp, each
    about eps of terms of the size of the log-likelihood (n log 2 pi, the log determinant and
    the quadratic form, all of order n, none cancelling the others by more than a factor of
    about 10): some 1e-14 relative (observed 4e-16), so 1e-12 leaves a margin of about 100.
    Whittle's kinds take the steady state in closed form, the reference iterates the Riccati
    recursion until the innovation variance changes by at most 1e-15: at the poles of modulus
    0.95 (OFF_MODELS) that stop leaves 2e-13 of sigma^2 and 4e-14 of the log-likelihood
    (observed; 4e-15 with the reference's recursion run on to its step limit)."""
    y = _record(a1, a2, ratio, 20000, 1)
    for dtype in (np.float64, np.float32):
        st = LagStatistics(dtype=dtype)
        st.push(y)
        for params in ((a1, a2, 1.0, ratio, 9.7), (0.5, 0.1, 2.0, 1.0, 9.5),
                       (0.9, -0.2, 0.5, 4.0, 10.0), *OFF_MODELS):
            for kind in ("exact", "whittle"):
                want = lag_loglike(st, *params, kind=kind)
                got = lag_drift_loglike(st, *params, kind=kind)
                assert got == pytest.approx(want, rel=1e-12), (dtype, params, kind)


def test_exact_likelihood_with_a1_zero_reaches_the_steady_state() -> None:
    """The C++ exact kind at a1 = 0 (even and odd samples two chains: the innovation
    variance moves every other step) equals the reference, whose steady state is checked
    against the DARE (tests/test_lag_drift.py), to 1e-12 relative. Before, both stopped the
    Riccati recursion at the first step it did not move: 0.5 % of sigma^2 short at
    (0, 0.99, q/r 0.01)."""
    st = LagStatistics()
    st.push(_record(0.2297, 0.1638, 1.0, 20000, 1))
    for params in ((0.0, 0.99, 0.01, 1.0, 9.7), (0.0, -0.9, 1.0, 1.0, 9.7)):
        want = lag_loglike(st, *params, kind="exact")
        assert lag_drift_loglike(st, *params, kind="exact") == pytest.approx(want, rel=1e-12)


def test_a_run_stopped_by_its_iteration_limit_is_not_converged() -> None:
    """The fit reports not_converged (with its estimate and iteration count) when its best
    run stops at the iteration limit: at 2 iterations a run the record's fit (about 15 a run
    unlimited) stops short; unlimited it is ok. A bad limit is refused."""
    st = LagStatistics()
    st.push(_record(0.6868, -0.0213, 1.0, 20000, 1))
    full = lag_drift_fit(st)
    assert full.status == "ok" and full.iterations > 4 * 2
    short = lag_drift_fit(st, max_iterations=2)
    assert short.status == "not_converged", short
    assert short.iterations <= 6 * 2 and math.isfinite(short.loglike)
    assert short.loglike < full.loglike
    for bad in (0, -1, 2.5, True):
        with pytest.raises(GyrodriftValueError, match="max_iterations"):
            lag_drift_fit(st, max_iterations=bad)  # type: ignore[arg-type]


# (pair, r/q, samples, seed): the fold record is 60000 samples, r/q 0.3, seed 9 (the offline
# fit's regression record, docs/validation/drift-model.md): its likelihood has a maximum at
# a2 = -0.069 and one at a2 = +0.0445, 0.102 log-likelihood units lower, where every run of a
# multi-start without the run across the fold ends.
FOLD = (PAIRS[0], 0.3, 60000, 9)
RECORDS = [(PAIRS[0], 1.0, 60000, 1), (PAIRS[1], 3.0, 60000, 3), FOLD]


@pytest.mark.parametrize(("pair", "ratio", "n", "seed"), RECORDS,
                         ids=["papers-1", "papers-2-r3", "fold"])
def test_fit_equals_the_reference_and_reaches_the_offline_fit(
        pair: tuple[float, float], ratio: float, n: int, seed: int) -> None:
    """On the C++ double statistics, the C++ fit against the reference's fit: every
    parameter and the mean within 0.01 offline standard errors (two maximisers with their
    own stopping rules stop at different points of the same maximum: observed up to 5e-4
    standard errors), and its log-likelihood on the reference's own likelihood within 1e-6
    units of the reference's maximum (observed 1e-7). Against the offline ML fit of the
    samples: within 1 offline standard error (observed 3e-3), with an exact log-likelihood
    on the samples at most 0.01 below the offline maximum. On the fold record the offline
    fit reports the other maximum on the other side of a2 = 0, and the C++ fit lands on the
    higher one."""
    y = _record(*pair, ratio, n, seed)
    st = LagStatistics()
    st.push(y)
    fit = lag_drift_fit(st)
    assert fit.status == "ok" and fit.truncation < 1e-10
    ref = reference_fit(st)
    offline = gyrodrift.fit_drift_model(y, rate_hz=400.0)
    for k in PARAMS:
        assert abs(getattr(fit, k) - getattr(ref, k)) <= 0.01 * offline.stderr[k], k
        assert abs(getattr(fit, k) - getattr(offline, k)) <= offline.stderr[k], k
    on_ref = lag_loglike(st, fit.a1, fit.a2, fit.q, fit.r, fit.mean)
    assert abs(on_ref - ref.loglike) <= 1e-6
    assert fit.loglike == pytest.approx(on_ref, rel=1e-12)
    exact = core("drift").drift_loglike
    assert exact(y, fit.a1, fit.a2, fit.q, fit.r, fit.mean)[0] >= offline.loglike - 0.01
    if (pair, ratio, n, seed) == FOLD:
        assert math.copysign(1.0, offline.fold_a2) != math.copysign(1.0, offline.a2)
        assert offline.loglike - offline.fold_loglike > 0.05
        assert fit.a2 < 0.0 < offline.fold_a2 and fit.runs == 6


def test_whittle_fit_equals_the_reference() -> None:
    """Whittle's kind: the C++ fit against the reference's on the same statistics, within
    0.01 offline standard errors and 1e-6 log-likelihood units of its maximum (the same
    reasoning as the exact kind's)."""
    y = _record(*PAIRS[1], 1.0, 60000, 6)
    st = LagStatistics()
    st.push(y)
    fit, ref = lag_drift_fit(st, kind="whittle"), reference_fit(st, kind="whittle")
    se = gyrodrift.fit_drift_model(y, rate_hz=400.0).stderr
    assert fit.status == "ok"
    for k in PARAMS:
        assert abs(getattr(fit, k) - getattr(ref, k)) <= 0.01 * se[k], k
    on_ref = lag_loglike(st, fit.a1, fit.a2, fit.q, fit.r, fit.mean, kind="whittle")
    assert abs(on_ref - ref.loglike) <= 1e-6


def test_truncation_is_reported() -> None:
    """AR(1) drift at 0.9 with r/q = 10: rho is about 0.71 and rho^32 about 2e-5, so L = 32
    is too short for the model; the estimate comes back with the status truncation, as
    the reference's rho^L says."""
    y = _record(0.9, 0.0, 10.0, 20000, 7)
    st = LagStatistics()
    st.push(y)
    fit, ref = lag_drift_fit(st), reference_fit(st)
    assert fit.status == "truncation" and ref.truncation > 1e-10
    assert fit.truncation == pytest.approx(ref.truncation, rel=0.1)


def test_fit_on_float_statistics() -> None:
    """The fit on the float state (as on the target) against the fit on the double state of
    the same float32 samples: the statistics differ by about 1e-8 of their scale, which
    moves the maximum far less than the maximiser's stopping rule (tests/test_lag_statistics.py
    shows the same for the reference's fit): within 0.01 offline standard errors."""
    y = _record(*PAIRS[1], 1.0, 60000, 4).astype(np.float32)
    f32, f64 = LagStatistics(dtype=np.float32), LagStatistics()
    f32.push(y)
    f64.push(y.astype(np.float64))
    a, b = lag_drift_fit(f32), lag_drift_fit(f64)
    se = gyrodrift.fit_drift_model(y.astype(np.float64), rate_hz=400.0).stderr
    assert a.status == b.status == "ok"
    for k in PARAMS:
        assert abs(getattr(a, k) - getattr(b, k)) <= 0.01 * se[k], k


def test_refusals_do_not_throw_and_leave_the_statistics_usable() -> None:
    """The C++ core answers a refusal with a status (the binding returns it, nothing is
    raised there); the wrapper turns it into one clear error with its cause; the statistics
    are untouched and fit once they hold enough samples. 2 L + 2 = 66 samples are needed."""
    y = _record(*PAIRS[0], 1.0, 5000, 5)
    lib = core("drift")
    bound = lib.LagStatistics()  # the bound C++ statistics, as the wrapper holds them
    bound.push(y[:65])
    raw = lib.lag_drift_fit(bound, lib.LagLikelihoodKind.exact)
    assert raw[0] == lib.LagDriftFitStatus.too_few_samples and raw[9] == 0
    assert lib.lag_drift_loglike(bound, 0.5, 0.0, 1.0, 1.0, 9.7)[0] == raw[0]
    bound.push(y[65:])
    assert lib.lag_drift_fit(bound)[0] == lib.LagDriftFitStatus.ok
    st = LagStatistics()
    st.push(y[:65])
    with pytest.raises(LagDriftFitError, match="65 samples, at least 66 needed") as exc:
        lag_drift_fit(st)
    assert exc.value.cause == "too_few_samples"
    with pytest.raises(LagDriftFitError, match="too few samples"):
        lag_drift_loglike(st, 0.5, 0.0, 1.0, 1.0, 9.7)
    assert st.n == 65
    st.push(y[65:])
    assert lag_drift_fit(st).status in ("ok", "truncation")
    with pytest.raises(LagDriftFitError) as exc:
        lag_drift_loglike(st, 1.2, 0.0, 1.0, 1.0, 9.7)
    assert exc.value.cause == "bad_model"
    with pytest.raises(LagDriftFitError) as exc:
        lag_drift_loglike(st, 0.5, 0.0, math.nan, 1.0, 9.7)
    assert exc.value.cause == "non_finite"
    # Float statistics whose sums overflowed (every sample and every w^2 finite).
    big = LagStatistics(dtype=np.float32)
    assert big.push(np.r_[0.0, np.tile([1.5e19, -1.5e19], 50)]) == 101
    assert not math.isfinite(big.products[0])
    big_bound = lib.LagStatisticsF32()
    big_bound.push(np.r_[0.0, np.tile([1.5e19, -1.5e19], 50)].astype(np.float32))
    assert lib.lag_drift_fit(big_bound)[0] == lib.LagDriftFitStatus.non_finite
    with pytest.raises(LagDriftFitError) as exc:
        lag_drift_fit(big)
    assert exc.value.cause == "non_finite"
    with pytest.raises(GyrodriftValueError, match="kind must be"):
        lag_drift_fit(st, kind="nope")
    with pytest.raises(GyrodriftTypeError, match="LagStatistics"):
        lag_drift_fit(LagStatisticsReference(32))  # type: ignore[arg-type]


def _no_head_view(bound: Any) -> Any:
    """The bound statistics without the first values as the reference reads statistics
    (its whittle_no_head kind reads no ``head``; an empty one stands in)."""
    return SimpleNamespace(lags=int(bound.lags), n=int(bound.n), centre=float(bound.centre),
                           total=float(bound.total), products=np.asarray(bound.products),
                           tail=np.asarray(bound.tail), head=np.empty(0))


def test_whittle_no_head_is_the_reference_with_the_mean_as_first_values() -> None:
    """The reference's whittle_no_head kind is its Whittle's kind on statistics whose first L
    values are the record's mean of w (scripts/online_whittle_proto.py --no-head), to
    1e-12 relative (the same sums, the head's running sum against a constant's); and it is
    not Whittle's with the first values (the mean's correction differs)."""
    y = _record(*PAIRS[0], 3.0, 20000, 2)
    st = LagStatisticsReference(12)
    st.push(y)
    as_mean = LagStatisticsReference.from_statistics(st)
    as_mean.head = np.full(12, st.total / st.n)
    for params in ((PAIRS[0][0], PAIRS[0][1], 1.0, 3.0, 9.7), (0.5, 0.1, 2.0, 1.0, 9.5)):
        want = lag_loglike(as_mean, *params, kind="whittle")
        assert lag_loglike(st, *params, kind="whittle_no_head") == pytest.approx(want, rel=1e-12)
        assert lag_loglike(st, *params, kind="whittle") != want


@pytest.mark.parametrize(("a1", "a2"), PAIRS)
def test_no_head_likelihood_equals_the_reference(a1: float, a2: float) -> None:
    """The C++ whittle_no_head log-likelihood equals the reference's on the same statistics,
    to 1e-12 relative (the reasoning of test_likelihood_equals_the_reference): on the bound
    statistics without the first values (L = 12 and 8, double and float state) and on the
    full ones (L = 32) through the wrapper."""
    y = _record(a1, a2, 3.0, 20000, 3)
    lib = core("drift")
    kind = lib.LagLikelihoodKind.whittle_no_head
    params = ((a1, a2, 1.0, 3.0, 9.7), (0.9, -0.2, 0.5, 4.0, 10.0), *OFF_MODELS)
    for cls, dtype in ((lib.LagStatisticsNoHead12, np.float64),
                       (lib.LagStatisticsNoHead12F32, np.float32),
                       (lib.LagStatisticsNoHead8, np.float64),
                       (lib.LagStatisticsNoHead8F32, np.float32)):
        bound = cls()
        bound.push(y.astype(dtype))
        assert not hasattr(bound, "head")
        view = _no_head_view(bound)
        for p in params:
            status, got = lib.lag_drift_loglike(bound, *p)  # whittle_no_head: their default
            assert status == lib.LagDriftFitStatus.ok
            assert got == pytest.approx(lag_loglike(view, *p, kind="whittle_no_head"), rel=1e-12)
            assert lib.lag_drift_loglike(bound, *p, kind)[1] == got
            assert (lib.lag_drift_loglike(bound, *p, lib.LagLikelihoodKind.exact)[0]
                    == lib.LagDriftFitStatus.needs_head)
    st = LagStatistics()
    st.push(y)
    for p in params:
        want = lag_loglike(st, *p, kind="whittle_no_head")
        assert lag_drift_loglike(st, *p, kind="whittle_no_head") == pytest.approx(want, rel=1e-12)


def test_no_head_fit_equals_the_reference() -> None:
    """The C++ fit from the float statistics without the first values (L = 12, as a target
    would keep them) against the reference's whittle_no_head fit on the same statistics:
    within 0.01 offline standard errors and 1e-6 log-likelihood units of its maximum (the
    reasoning of test_fit_equals_the_reference_and_reaches_the_offline_fit); status ok, with
    rho^L within the kind's 3e-3. And within 1 standard error of the offline ML fit."""
    y = _record(*PAIRS[1], 3.0, 60000, 5)
    lib = core("drift")
    bound = lib.LagStatisticsNoHead12F32()
    bound.push(y.astype(np.float32))
    assert bound.state_bytes == 184
    out = lib.lag_drift_fit(bound)
    assert out[0] == lib.LagDriftFitStatus.ok
    fit = dict(zip(PARAMS, (float(v) for v in out[1:6]), strict=True))
    loglike, truncation = float(out[6]), float(out[7])
    assert 1e-10 < truncation <= lib.LAG_DRIFT_WHITTLE_NO_HEAD_TRUNCATION_TOL
    view = _no_head_view(bound)
    ref = reference_fit(view, kind="whittle_no_head")
    offline = gyrodrift.fit_drift_model(y.astype(np.float32).astype(np.float64), rate_hz=400.0)
    for k in PARAMS:
        assert abs(fit[k] - getattr(ref, k)) <= 0.01 * offline.stderr[k], k
        assert abs(fit[k] - getattr(offline, k)) <= offline.stderr[k], k
    on_ref = lag_loglike(view, *(fit[k] for k in PARAMS), kind="whittle_no_head")
    assert abs(on_ref - ref.loglike) <= 1e-6
    assert loglike == pytest.approx(on_ref, rel=1e-12)
    assert ref.truncation == pytest.approx(truncation, rel=0.1)
