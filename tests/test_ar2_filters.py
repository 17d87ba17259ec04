"""AR filter and AR(2)-Kalman filters: C++ core vs numpy reference, FilterPy, scipy DARE;
fault handling, reset, 3-axis banks, and the filter's optimality on a known model."""

from __future__ import annotations

import warnings

import gyrodrift
import gyrodrift.reference as ref
import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FilterPyKF
from gyrodrift import Ar2Model, KalmanFilter
from gyrodrift.filters.ar2 import kalman_filter_result

N = 100_000  # the comparison length


def _drift(n: int, seed: int, axes: int = 1) -> np.ndarray:
    # Drift-like FOG record (paper 002 pair 0.6868/-0.0213) on an Earth-rate-like bias, plus
    # ARW, in deg/h.
    return gyrodrift.simulate(
        n=n, ar2=(0.6868, -0.0213, 0.2), bias_deg_h=9.7, n_deg_rt_h=0.0002, axes=axes, seed=seed
    ).rate_deg_h


@pytest.fixture(scope="module")
def record() -> np.ndarray:
    return _drift(N, seed=17)


@pytest.fixture(scope="module")
def model(record: np.ndarray) -> Ar2Model:
    return gyrodrift.fit_ar2(record, "burg")


def _rel_err(got: np.ndarray, want: np.ndarray) -> float:
    # Error relative to the record's scale (max |want|): per-sample relative error is
    # meaningless at zero crossings.
    return float(np.max(np.abs(got.astype(np.float64) - want)) / np.max(np.abs(want)))


# Tolerances: double 1e-12 relative (the filters are contractive, so rounding does not grow
# along the record: observed ~1e-16); float32 1e-5 relative (float eps 1.2e-7 times a few
# operations, again not growing along 1e5 samples).
@pytest.mark.parametrize("steady_state", [False, True])
def test_kalman_double_matches_reference(record, model, steady_state) -> None:
    got = gyrodrift.kalman_filter(record, model, steady_state=steady_state)
    want = ref.kalman_filter(record, model, steady_state=steady_state)
    assert got.dtype == np.float64 and got.shape == record.shape
    assert _rel_err(got, want) < 1e-12


@pytest.mark.parametrize("steady_state", [False, True])
def test_kalman_float_matches_reference(record, model, steady_state) -> None:
    got = gyrodrift.kalman_filter(record.astype(np.float32), model, steady_state=steady_state)
    want = ref.kalman_filter(record, model, steady_state=steady_state)
    assert got.dtype == np.float32
    assert _rel_err(got, want) < 1e-5


def test_kalman_overrides_q_r_p0_match_reference(record, model) -> None:
    x = record[:20_000]
    got = gyrodrift.kalman_filter(x, model, q=0.3 * model.sigma2, r=4 * model.r, p0=25.0)
    want = ref.kalman_filter(x, model, q=0.3 * model.sigma2, r=4 * model.r, p0=25.0)
    assert _rel_err(got, want) < 1e-12


def test_ar_filter_matches_reference(record, model) -> None:
    got = gyrodrift.ar_filter(record, model)
    assert _rel_err(got, ref.ar_filter(record, model)) < 1e-12
    got32 = gyrodrift.ar_filter(record.astype(np.float32), model)
    assert got32.dtype == np.float32 and _rel_err(got32, ref.ar_filter(record, model)) < 1e-5
    # Definition check independent of both implementations: y_k minus the one-step residual.
    d = record - model.mean
    resid = d[2:] - model.a1 * d[1:-1] - model.a2 * d[:-2]
    np.testing.assert_allclose(got[2:], record[2:] - resid, rtol=0, atol=1e-12 * 20)


def test_kalman_matches_filterpy(record, model) -> None:
    # FilterPy's KalmanFilter on the same state space (its update is Joseph form too). Bound
    # 1e-10 relative, as the issue asks (observed ~1e-15).
    x = record[:20_000]
    kf = FilterPyKF(dim_x=2, dim_z=1)
    kf.F = np.array([[model.a1, model.a2], [1.0, 0.0]])
    kf.H = np.array([[1.0, 0.0]])
    kf.Q = np.diag([model.sigma2, 0.0])
    kf.R = np.array([[model.r]])
    kf.P = np.eye(2)
    kf.x = np.zeros((2, 1))
    want = np.empty_like(x)
    for k, y in enumerate(x):
        kf.predict()
        kf.update(y - model.mean)
        want[k] = kf.x[0, 0] + model.mean
    got = gyrodrift.kalman_filter(x, model)
    assert _rel_err(got, want) < 1e-10


@pytest.mark.parametrize("dtype,tol", [(np.float64, 1e-12), (np.float32, 1e-5)])
def test_steady_state_gain_matches_scipy_dare(model, dtype, tol) -> None:
    cases = [(model.sigma2, model.r), (model.sigma2, 100 * model.r), (1e-3 * model.sigma2, 1.0)]
    for q, r in cases:
        kf = KalmanFilter(model, q=q, r=r, steady_state=True, dtype=dtype)
        want = ref.steady_state_gain(model, q, r)
        # Relative to the gain's size: the small component k1 is formed by cancellation.
        np.testing.assert_allclose(kf.gain, want, rtol=0, atol=tol * np.max(np.abs(want)))


def test_full_filter_converges_to_steady_state(record, model) -> None:
    # After the transient of P0 = I, the full filter's gain equals the DARE gain, so the two
    # filters' outputs agree (to 1e-9 of the scale after 2000 samples: contraction of the
    # Riccati recursion is fast for q ~ r).
    full = gyrodrift.kalman_filter(record[:10_000], model)
    steady = gyrodrift.kalman_filter(record[:10_000], model, steady_state=True)
    assert _rel_err(full[2000:], steady[2000:]) < 1e-9
    assert _rel_err(full[:10], steady[:10]) > 1e-6  # and they do differ at the start


def test_three_axes_equal_per_axis_filters() -> None:
    rec = _drift(30_000, seed=5, axes=3)
    models = gyrodrift.fit_ar2(rec, "yule-walker")
    for dtype in (np.float64, np.float32):
        x = rec.astype(dtype)
        for ss in (False, True):
            out = gyrodrift.kalman_filter(x, models, steady_state=ss)
            assert out.shape == x.shape and out.dtype == dtype
            for i in range(3):
                col = np.ascontiguousarray(x[:, i])
                one = gyrodrift.kalman_filter(col, models[i], steady_state=ss)
                np.testing.assert_array_equal(out[:, i], one)  # same arithmetic: bit-identical
        out = gyrodrift.ar_filter(x, models)
        for i in range(3):
            np.testing.assert_array_equal(
                out[:, i], gyrodrift.ar_filter(np.ascontiguousarray(x[:, i]), models[i])
            )
    # One model for all axes.
    same = gyrodrift.kalman_filter(rec, models[0])
    np.testing.assert_array_equal(
        same[:, 2], gyrodrift.kalman_filter(np.ascontiguousarray(rec[:, 2]), models[0])
    )


@pytest.mark.parametrize("steady_state", [False, True])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_non_finite_samples_are_predict_only_and_counted(
    record, model, steady_state, dtype
) -> None:
    x = record[:5000].astype(dtype)
    x[[10, 11, 12, 400, 4999]] = [np.nan, np.inf, -np.inf, np.nan, np.nan]
    res = kalman_filter_result(x, model, steady_state=steady_state)
    out, faults = res.y, res.faults
    assert faults.tolist() == [5]
    assert np.all(np.isfinite(out))
    want = ref.kalman_filter(x.astype(np.float64), model, steady_state=steady_state)
    assert _rel_err(out, want) < (1e-12 if dtype == np.float64 else 1e-5)
    with pytest.warns(RuntimeWarning, match="5 non-finite"):
        gyrodrift.kalman_filter(x, model, steady_state=steady_state)
    # The per-sample object: state stays finite, counter increments, later samples filter.
    kf = KalmanFilter(model, steady_state=steady_state, dtype=dtype)
    assert np.isfinite(kf.step(np.nan)) and kf.fault_count == 1
    assert np.isfinite(kf.step(float(record[0]))) and kf.fault_count == 1


def test_ar_filter_non_finite() -> None:
    m = Ar2Model(a1=0.5, a2=-0.2, sigma2=1.0, mean=2.0)
    x = np.array([3.0, np.nan, 1.0, 2.5, np.inf, 4.0, 1.0])
    with pytest.warns(RuntimeWarning, match="2 non-finite"):
        out = gyrodrift.ar_filter(x, m)
    np.testing.assert_allclose(out, ref.ar_filter(x, m), rtol=1e-15)
    assert np.all(np.isfinite(out))


@pytest.mark.parametrize("dtype,big", [(np.float64, 1.7e308), (np.float32, 3.3e38)])
def test_overflowing_input_never_poisons_state(dtype, big) -> None:
    # Finite but huge samples of alternating sign: the innovation overflows to Inf on the
    # second one; that update is rejected (predict only, counted), the state stays finite.
    m = Ar2Model(a1=0.9, a2=-0.05, sigma2=1.0, mean=0.0)
    for ss in (False, True):
        kf = KalmanFilter(m, steady_state=ss, dtype=dtype)
        for y in (big, -big, big, -big):
            assert np.isfinite(kf.step(y))
        assert kf.fault_count >= 1
        outs = kf.process(np.zeros(3000, dtype=dtype))
        assert np.all(np.isfinite(outs))
        assert abs(outs[-1]) < 1e-3 * big  # decays back towards the mean


def test_reset_restores_initial_behaviour(record, model) -> None:
    for ss in (False, True):
        for dtype in (np.float64, np.float32):
            kf = KalmanFilter(model, steady_state=ss, dtype=dtype)
            first = kf.process(record[:3000])
            kf.step(np.nan)
            assert kf.fault_count == 1
            kf.reset()
            assert kf.fault_count == 0
            again = kf.process(record[:3000])
            np.testing.assert_array_equal(first, again)
            # And equals the batch function (a new filter).
            batch = gyrodrift.kalman_filter(record[:3000].astype(dtype), model, steady_state=ss)
            np.testing.assert_array_equal(first, batch)


def test_step_equals_process(record, model) -> None:
    kf = KalmanFilter(model)
    block = kf.process(record[:500])
    kf.reset()
    steps = np.array([kf.step(y) for y in record[:500]])
    np.testing.assert_array_equal(block, steps)


def test_kalman_error_variance_matches_riccati_prediction(rng) -> None:
    # Optimality check independent of any implementation detail: a true AR(2) state observed
    # with white noise of variance r. The steady-state filtered error variance is
    # P_f = P - K C P from the DARE (scipy). Its empirical estimate over n = 2e5 samples of
    # a correlated error has relative std ~ sqrt(2 tau / n) < 1 %; bound 5 %.
    a1, a2, q, r, n = 0.6868, -0.0213, 1.0, 2.0, 200_000
    truth = gyrodrift.simulate(n=n, ar2=(a1, a2, np.sqrt(q)), seed=99).rate_deg_h
    y = truth + rng.normal(0.0, np.sqrt(r), n)
    m = Ar2Model(a1=a1, a2=a2, sigma2=q, mean=0.0)
    est = gyrodrift.kalman_filter(y, m, q=q, r=r)
    err = est[1000:] - truth[1000:]
    k = ref.steady_state_gain(m, q, r)
    import scipy.linalg

    a = np.array([[a1, a2], [1.0, 0.0]])
    c = np.array([[1.0, 0.0]])
    p = scipy.linalg.solve_discrete_are(a.T, c.T, np.diag([q, 0.0]), np.array([[r]]))
    p_filtered = (np.eye(2) - np.outer(k, c)) @ p
    assert np.var(err) == pytest.approx(p_filtered[0, 0], rel=0.05)
    assert np.var(err) < 0.7 * r  # and it beats the raw measurement by a wide margin


def test_invalid_models_and_variances(model) -> None:
    x = np.ones(100)
    bad = Ar2Model(a1=1.2, a2=-0.1, sigma2=1.0, mean=0.0)  # a1 + a2 > 1
    for fn in (gyrodrift.kalman_filter, gyrodrift.ar_filter):
        with pytest.raises(ValueError, match="non-stationary"):
            fn(x, bad)
    with pytest.raises(ValueError, match="non-stationary"):
        KalmanFilter(bad)
    with pytest.raises(ValueError, match="q must be"):
        gyrodrift.kalman_filter(x, model, q=-1.0)
    with pytest.raises(ValueError, match="r must be"):
        gyrodrift.kalman_filter(x, model, r=0.0)
    with pytest.raises(ValueError, match="r must be"):
        KalmanFilter(model, r=float("nan"))
    with pytest.raises(ValueError, match="must be finite"):
        Ar2Model(a1=float("nan"), a2=0.0, sigma2=1.0)
    with pytest.raises(TypeError, match="Ar2Model"):
        KalmanFilter((0.1, 0.2, 1.0, 0.0))  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="sequence of 3"):
        gyrodrift.kalman_filter(np.ones((10, 3)), [model, model])
    # Riccati iteration bound reached (near-unit roots, tiny gain): a clear error, no filter.
    slow = Ar2Model(a1=1.9, a2=-0.99999, sigma2=1e-12, mean=0.0)
    with pytest.raises(ValueError, match="not converged"):
        KalmanFilter(slow, r=1.0, steady_state=True)


def test_model_without_r_uses_sigma2() -> None:
    m = Ar2Model(a1=0.3, a2=0.1, sigma2=2.0, mean=1.0)
    x = _drift(2000, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = gyrodrift.kalman_filter(x, m)
    np.testing.assert_array_equal(got, gyrodrift.kalman_filter(x, m, q=2.0, r=2.0))


@pytest.mark.parametrize("pair,r", [((0.6868, -0.0213), 1.0), ((-0.034, 0.0252), 7.5),
                                    ((0.2297, 0.1638), 0.2)])
def test_dc_gain_matches_step_response(pair, r) -> None:
    # A sustained offset d from the mean comes out as G d (both variants, after the transient):
    # the filter attenuates true rate changes; G is the documented limit of the method.
    m = Ar2Model(a1=pair[0], a2=pair[1], sigma2=1.0, mean=2.0)
    g = KalmanFilter(m, r=r).dc_gain
    assert 0.0 < g < 1.0
    x = np.full(5000, 2.0 + 3.0)
    for ss in (False, True):
        y = gyrodrift.kalman_filter(x, m, r=r, steady_state=ss)
        assert y[-1] - 2.0 == pytest.approx(3.0 * g, rel=1e-9)
