"""Online re-identification of the drift model (gyrodrift.filters.online, the C++
OnlineDriftIdentifier): the C++ core against its numpy reference (double) and float against
double; convergence to the offline maximum-likelihood fit on the papers' correlated pairs;
tracking a step change of r or q; the guards; the binding's per-block snapshots; and a small
fixed-seed version of scripts/online_drift_mc.py.
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType

import gyrodrift
import numpy as np
import pytest
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.filters import DriftParams, OnlineDriftIdentifier, OnlineDriftSettings
from gyrodrift.reference.online_drift import OnlineDriftReference
from scipy.signal import lfilter

MEAN = 9.7


def _record(a1: float, a2: float, q: float, r: float, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = lfilter([1.0], [1.0, -a1, -a2], rng.normal(0.0, math.sqrt(q), n + 2000))[2000:]
    return MEAN + x + rng.normal(0.0, math.sqrt(r), n)


def _changing(a1: float, a2: float, q2: float, r2: float, n: int, seed: int) -> np.ndarray:
    """q = r = 1 for the first half, (q2, r2) for the second."""
    rng = np.random.default_rng(seed)
    h = n // 2
    w = np.r_[rng.normal(0.0, 1.0, h + 2000), rng.normal(0.0, math.sqrt(q2), n - h)]
    x = lfilter([1.0], [1.0, -a1, -a2], w)[2000:]
    v = np.r_[rng.normal(0.0, 1.0, h), rng.normal(0.0, math.sqrt(r2), n - h)]
    return MEAN + x + v


SMALL = {"block_samples": 200, "retune_blocks": 20, "min_samples": 8000}


@pytest.mark.parametrize("case", [
    # (pair, start, settings): the full AR(2)+white estimator from a start 10-30 % off; the
    # tracking variant (forgetting, AR part held) and the AR(1) variant on the other pair.
    ((0.2297, 0.1638), (0.2, 0.1, 1.3, 0.8), SMALL),
    ((0.6868, -0.0213), (0.6, -0.05, 0.8, 1.3), {**SMALL, "memory_blocks": 30.0,
                                                  "adapt_ar": False}),
    ((0.6868, -0.0213), (0.6, 0.0, 0.8, 1.3), {**SMALL, "ar_order": 1, "warmup_blocks": 0.0}),
])
def test_cpp_double_equals_numpy_reference(case: tuple) -> None:
    # 24000 samples, 120 blocks, 6 retune points. The two implementations differ in rounding
    # only: Joseph-form covariance update and LAPACK solves in the reference, the r P / F form
    # and a hand-written 4x4 Cholesky in C++, and the gain from scipy's DARE solver against a
    # warm-started Riccati iteration stopped at 64 eps. Those ~1e-16 differences per step pass
    # through the recursion's Gauss-Newton solves (condition number of the information up to
    # ~1e4 here) and the gain's fixed point; 1e-9 (absolute on a1, a2, relative elsewhere) is
    # several orders above the observed ~1e-11 and far below any algorithmic difference.
    pair, start, settings = case
    y = _record(*pair, 1.0, 1.0, 24000, seed=3)
    ident = OnlineDriftIdentifier(DriftParams(*start, 0.0), OnlineDriftSettings(**settings))
    trace = ident.push(y)
    ref = OnlineDriftReference(*start, 0.0, **settings)
    blocks = ref.push(y)
    assert len(blocks) == len(trace.samples) == 120
    assert [b.status for b in blocks] == trace.status.tolist()
    assert [b.samples for b in blocks] == trace.samples.tolist()
    want = np.array([b.estimate for b in blocks])
    np.testing.assert_allclose(trace.estimate[:, :2], want[:, :2], rtol=0, atol=1e-9)
    np.testing.assert_allclose(trace.estimate[:, 2:], want[:, 2:], rtol=1e-9)
    np.testing.assert_allclose(trace.in_use, np.array([b.in_use for b in blocks]), rtol=1e-9,
                               atol=1e-9)
    np.testing.assert_allclose(trace.gain, np.array([b.gain for b in blocks]), rtol=1e-9)
    np.testing.assert_allclose(trace.stderr, np.array([b.stderr for b in blocks]), rtol=1e-9,
                               atol=1e-12)
    assert ident.retunes == ref.retunes and ident.refused_retunes == ref.refused_retunes
    assert ident.retunes > 0  # the comparison covers retuned gains


def test_float_state_follows_double() -> None:
    # Float state as on the target, the same samples: 200000 samples of the pair
    # (0.2297, 0.1638), r/q = 1. Float rounding of the innovation differences (delta = 2^-10)
    # is ~1e-4 relative per sample; the recursion averages it. Bound: 2 % on q, r and the gain,
    # 0.01 on a1, a2 (the estimates' own standard errors are ~6 % and 0.01).
    y = _record(0.2297, 0.1638, 1.0, 1.0, 200000, seed=4)
    cfg = DriftParams(0.2, 0.1, 1.3, 0.8, 0.0)
    s = OnlineDriftSettings(block_samples=200, retune_blocks=20, min_samples=20000)
    d = OnlineDriftIdentifier(cfg, s)
    f = OnlineDriftIdentifier(cfg, s, dtype=np.float32)
    td, tf = d.push(y), f.push(y.astype(np.float32))
    assert f.status == d.status == "tracking"
    assert np.array_equal(tf.status, td.status)
    ed, ef = d.estimate, f.estimate
    assert abs(ef.a1 - ed.a1) < 0.01 and abs(ef.a2 - ed.a2) < 0.01
    assert ef.q == pytest.approx(ed.q, rel=0.02) and ef.r == pytest.approx(ed.r, rel=0.02)
    assert f.gain == pytest.approx(d.gain, rel=0.02)
    assert f.state_bytes <= 408 and d.state_bytes <= 744


@pytest.mark.parametrize("pair", [(0.2297, 0.1638), (0.6868, -0.0213)])
def test_converges_to_the_offline_ml_fit(pair: tuple[float, float]) -> None:
    # 480000 samples (20 min at 400 Hz), r/q = 1, seed 1, no forgetting, configured 20 % off in
    # a1, a2 = a2/2 + 0.03, q x1.5, r x0.7. Stated bound: every parameter within one of the
    # offline fit's standard errors of the offline ML estimate, the mean within one (measured
    # here 0.39 and 0.31; over 20 records of both pairs, r/q = 1 and 3, at 480000 samples 19
    # within one standard error, the largest 1.05: `scripts/online_drift_mc.py --convergence
    # --samples 480000 --seeds 5`, docs/validation/online-identification.md, which also gives
    # the records that are not within it at 240000 and 960000 samples).
    a1, a2 = pair
    y = _record(a1, a2, 1.0, 1.0, 480000, seed=1)
    fit = gyrodrift.fit_drift_model(y, rate_hz=400.0)
    assert fit.identified
    ident = OnlineDriftIdentifier(DriftParams(0.8 * a1, 0.5 * a2 + 0.03, 1.5, 0.7, 0.0),
                                  OnlineDriftSettings(block_samples=400, retune_blocks=50,
                                                      min_samples=100000))
    ident.push(y)
    est = ident.estimate
    for name in ("a1", "a2", "q", "r"):
        z = (getattr(est, name) - getattr(fit, name)) / fit.stderr[name]
        assert abs(z) <= 1.0, (name, z)
    assert abs(est.mean - fit.mean) <= fit.stderr["mean"]
    assert ident.status == "tracking" and ident.in_use == est


@pytest.mark.parametrize("pair", [(0.2297, 0.1638), (0.6868, -0.0213)])
@pytest.mark.parametrize("change", ["r", "q"])
def test_tracks_a_step_change_of_r_or_q(pair: tuple[float, float], change: str) -> None:
    # q = r = 1, then r (or q) x2 halfway through 480000 samples. Forgetting: memory_blocks =
    # 100 (40000 samples, 100 s at 400 Hz), AR part held at the configured (first-half) model.
    # Stated: from 40000 samples after the change on, the estimate of the changed variance is
    # within 20 % of its new value; the other is pulled along for a while (up to 35 % for the
    # weakly correlated pair: the change is first shared between q and r) and stays within
    # 40 % of 1; over the last 100000 samples both are within 15 % of their values.
    q2, r2 = (1.0, 2.0) if change == "r" else (2.0, 1.0)
    y = _changing(*pair, q2, r2, 480000, seed=5)
    ident = OnlineDriftIdentifier(
        DriftParams(*pair, 1.0, 1.0, MEAN),
        OnlineDriftSettings(block_samples=400, retune_blocks=25, min_samples=100000,
                            memory_blocks=100.0, adapt_ar=False))
    trace = ident.push(y)
    after = trace.samples >= 240000 + 40000
    col = 3 if change == "r" else 2
    other = 2 if change == "r" else 3
    assert np.all(np.abs(trace.estimate[after, col] / 2.0 - 1.0) < 0.2)
    assert np.all(np.abs(trace.estimate[after, other] - 1.0) < 0.4)
    last = trace.samples >= 380000
    assert np.all(np.abs(trace.estimate[last, col] / 2.0 - 1.0) < 0.15)
    assert np.all(np.abs(trace.estimate[last, other] - 1.0) < 0.15)
    # Before the change: within 20 % of the first half's values once settled (the start-up
    # steps of the first blocks wander; from 300 s at 400 Hz on).
    before = (trace.samples >= 120000) & (trace.samples < 240000)
    assert np.all(np.abs(trace.estimate[before, 2:4] - 1.0) < 0.2)
    # The gain followed: the last retune put the second half's estimate in use.
    assert ident.status == "tracking"
    assert ident.in_use.r == pytest.approx(trace.estimate[-1, 3])


def test_too_short_is_learning_and_keeps_the_configured_model() -> None:
    y = _record(0.6868, -0.0213, 1.0, 1.0, 30000, seed=6)
    cfg = DriftParams(0.5, 0.0, 2.0, 0.5, 0.0)
    ident = OnlineDriftIdentifier(cfg, OnlineDriftSettings(block_samples=200, retune_blocks=20,
                                                           min_samples=50000))
    k = ident.gain
    trace = ident.push(y)
    assert set(trace.status_names) == {"learning"}
    assert ident.in_use == ident.configured and ident.gain == k
    assert not trace.retuned.any() and ident.retunes == 0
    assert ident.estimate != ident.configured  # the estimate itself runs


@pytest.mark.parametrize("kind", ["white", "q tiny"])
def test_unidentified_split_keeps_the_configured_model(kind: str) -> None:
    # White noise only, or a correlated drift with q = 1e-4 r (its variance is 1.6e-4 of the
    # white noise's): the drift/white split is not identified, no retune is accepted.
    n = 120000
    if kind == "white":
        y = MEAN + np.random.default_rng(7).normal(size=n)
    else:
        y = _record(0.2297, 0.1638, 1e-4, 1.0, n, seed=7)
    cfg = DriftParams(0.6868, -0.0213, 0.5, 1.0, MEAN)
    ident = OnlineDriftIdentifier(cfg, OnlineDriftSettings(block_samples=200, retune_blocks=20,
                                                           min_samples=20000))
    trace = ident.push(y)
    names = trace.status_names
    assert names[-1] == "not_identified" and "tracking" not in names
    assert ident.retunes == 0 and ident.refused_retunes >= 1
    assert ident.in_use == ident.configured
    assert np.all(trace.in_use == np.array(list(ident.configured.as_dict().values())))


def test_nan_and_inf_are_counted_and_skipped() -> None:
    y = _record(0.2297, 0.1638, 1.0, 1.0, 4000, seed=8)
    bad = y.copy()
    bad[[10, 500, 2999]] = [np.nan, np.inf, -np.inf]
    a = OnlineDriftIdentifier(DriftParams(0.2, 0.1, 1.0, 1.0, 0.0),
                              OnlineDriftSettings(block_samples=200, min_samples=0))
    b = OnlineDriftIdentifier(DriftParams(0.2, 0.1, 1.0, 1.0, 0.0),
                              OnlineDriftSettings(block_samples=200, min_samples=0))
    a.push(bad)
    b.push(np.delete(y, [10, 500, 2999]))
    assert a.rejected == 3 and a.samples == 3997
    assert a.estimate == b.estimate  # skipped exactly as if absent


def test_each_update_is_bounded_by_max_step() -> None:
    # Configured q 100x too small: unbounded steps would be large. Each block's change of
    # log q, log r and the tanh pre-images is <= max_step (rounding aside) and reaches it.
    y = _record(0.6868, -0.0213, 1.0, 1.0, 20000, seed=9)
    ident = OnlineDriftIdentifier(DriftParams(0.3, 0.0, 0.01, 5.0, 0.0),
                                  OnlineDriftSettings(block_samples=200, max_step=0.05))
    trace = ident.push(y)
    e = np.vstack([[0.3, 0.0, 0.01, 5.0, 0.0], trace.estimate])
    theta = np.column_stack([np.arctanh(e[:, 0] / (1 - e[:, 1])), np.arctanh(e[:, 1]),
                             np.log(e[:, 2]), np.log(e[:, 3])])
    steps = np.abs(np.diff(theta, axis=0)).max(axis=1)
    assert steps.max() <= 0.05 * (1 + 1e-9)
    assert steps.max() >= 0.05 * (1 - 1e-9)


def test_divergence_falls_back_to_the_configured_model() -> None:
    # A 1000-sigma rate step after 60000 samples: the model no longer describes the data (its
    # normalised innovation power leaves [1/3, 3]); the next retune falls back.
    y = _record(0.2297, 0.1638, 1.0, 1.0, 80000, seed=13)
    y[60000:] += 1000.0
    cfg = DriftParams(0.2, 0.15, 1.2, 0.8, MEAN)
    ident = OnlineDriftIdentifier(cfg, OnlineDriftSettings(block_samples=200, retune_blocks=20,
                                                           min_samples=20000))
    first = ident.push(y[:60000])
    assert first.status_names[-1] == "tracking"
    k_cfg = OnlineDriftIdentifier(cfg, OnlineDriftSettings()).gain
    trace = ident.push(y[60000:])
    assert "fallback" in trace.status_names
    assert ident.status == "fallback"
    assert ident.in_use == ident.configured and ident.gain == k_cfg
    fell = trace.status_names.index("fallback")
    assert trace.retuned[fell]


def test_trace_rows_are_the_blocks_of_each_push() -> None:
    y = _record(0.2297, 0.1638, 1.0, 1.0, 1000, seed=10)
    ident = OnlineDriftIdentifier(DriftParams(0.2, 0.1, 1.0, 1.0, 0.0),
                                  OnlineDriftSettings(block_samples=300))
    t1 = ident.push(y[:250])
    t2 = ident.push(y[250:])
    assert t1.samples.tolist() == [] and t2.samples.tolist() == [300, 600, 900]
    assert t2.estimate.shape == (3, 5) and t2.gain.shape == (3, 2) and t2.stderr.shape == (3, 5)
    assert ident.blocks == 3 and ident.samples == 1000
    assert len(t2.as_dict()["status"]) == 3
    ident.reset()
    assert ident.samples == 0 and ident.blocks == 0 and ident.estimate == ident.configured


def test_bad_arguments_are_clear_errors() -> None:
    with pytest.raises(GyrodriftValueError, match="block_samples"):
        OnlineDriftSettings(block_samples=4)
    with pytest.raises(GyrodriftValueError, match="memory_blocks"):
        OnlineDriftSettings(memory_blocks=0.5)
    with pytest.raises(GyrodriftTypeError, match="adapt_ar"):
        OnlineDriftSettings(adapt_ar=1)  # type: ignore[arg-type]
    with pytest.raises(GyrodriftValueError, match="non-stationary"):
        OnlineDriftIdentifier(DriftParams(1.5, -0.2, 1.0, 1.0, 0.0))
    with pytest.raises(GyrodriftValueError, match="r must be > 0"):
        OnlineDriftIdentifier(DriftParams(0.5, 0.0, 1.0, 0.0, 0.0))
    with pytest.raises(GyrodriftValueError, match="a2 must be 0"):
        OnlineDriftIdentifier(DriftParams(0.5, 0.1, 1.0, 1.0, 0.0), OnlineDriftSettings(ar_order=1))
    with pytest.raises(GyrodriftValueError, match="dtype"):
        OnlineDriftIdentifier(DriftParams(0.5, 0.0, 1.0, 1.0, 0.0), dtype=np.int32)
    with pytest.raises(GyrodriftTypeError):
        OnlineDriftIdentifier((0.5, 0.0, 1.0, 1.0, 0.0))  # type: ignore[arg-type]
    ident = OnlineDriftIdentifier(DriftParams(0.5, 0.0, 1.0, 1.0, 0.0))
    with pytest.raises(GyrodriftValueError, match="1-D"):
        ident.push(np.zeros((4, 2)))


def _mc_module() -> ModuleType:
    path = Path(__file__).resolve().parent.parent / "scripts" / "online_drift_mc.py"
    spec = importlib.util.spec_from_file_location("online_drift_mc", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["online_drift_mc"] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("change", ["none", "r x2"])
def test_monte_carlo_small(change: str) -> None:
    # Small fixed-seed version of scripts/online_drift_mc.py (240000 samples, pair
    # (0.6868, -0.0213), r/q = 1, seed 2), both online rows on the same record. Stated: on a
    # stationary record the online-retuned filter's MSE is within 10 % of the offline ML
    # filter's (the configured gain, ~9 % above the optimum, is in use for the first 60000
    # samples); after r doubles halfway it is below the fixed configured model's and the
    # offline ML fit's of the whole record.
    # The lag identifier (a fit every 24000 samples, applied 6000 later; stationary: the whole
    # record's statistics, first fit applied at 78000; changing: restart after each fit, AR part
    # held): stationary within 6 % of the ML filter (observed 4.7 %: the configured gain, 8.5 %
    # above the ML filter, over the first third, and fits on the side a2 > 0 of the fold at
    # a2 = 0 whose likelihood is within 0.003 units of the ML fit's and whose gain is about 12 %
    # higher; a run that never retunes stays 8.5 % above and fails); after the change below the
    # configured model (observed 1.7 % above the optimum against 6.0 %) and the ML fit.
    mc = _mc_module()
    res = mc.run_case(mc.Case(0.6868, -0.0213, 1.0, change, 240000, 2))
    assert res["optimum"] <= min(res["online"], res["lag"], res["ml"], res["configured"])
    if change == "none":
        assert res["online"] <= 1.10 * res["ml"]
        assert res["online"] < res["configured"]
        assert res["lag"] <= 1.06 * res["ml"]
        assert res["lag"] < res["configured"]
    else:
        assert res["online"] < res["configured"]
        assert res["online"] < res["ml"]
        assert res["lag"] < res["configured"]
        assert res["lag"] < res["ml"]
    assert res["tracking"] == 1.0 and res["retunes"] > 0
    assert res["lag_tracking"] == 1.0 and res["lag_retunes"] > 0 and res["lag_refused"] == 0
