"""The re-identification from lag statistics (include/gyrodrift/filters/lag_drift_identifier.hpp)
through the gyro monitor's binding (``GyroMonitorSettings(identifier="lag")``): against its numpy
reference (gyrodrift.reference.lag_identifier: the apply points, the models in use and the
guards' decisions), its convergence to the offline ML fit (gyrodrift.fit_drift_model) on the
papers' pairs, its tracking of a 2x step of q or r with the statistics restarted after each
fit, and the binding's refusals."""

from __future__ import annotations

import math
from typing import Any

import gyrodrift
import numpy as np
import pytest
from gyrodrift._native import core
from gyrodrift.filters.ar2 import Ar2Model
from gyrodrift.reference.ar2 import steady_state_gain
from gyrodrift.reference.lag_identifier import LagIdentifierReference
from scipy.signal import lfilter

PAIRS = ((0.6868, -0.0213), (0.2297, 0.1638))
MODEL = ("a1", "a2", "q", "r", "mean")
STATUS = {2: "tracking", 3: "not_identified", 4: "fallback"}


def _record(a1: float, a2: float, ratio: float, n: int, seed: int) -> np.ndarray:
    """AR(2) drift (q = 1, 2000 samples of burn-in) plus white noise (r = ratio) on 9.7: the
    records of tests/test_lag_drift_fit.py."""
    rng = np.random.default_rng(seed)
    x = lfilter([1.0], [1.0, -a1, -a2], rng.normal(size=n + 2000))[2000:]
    return 9.7 + x + rng.normal(0.0, math.sqrt(ratio), n)


def _run(y: np.ndarray, cfg: tuple[float, ...], dtype: Any = np.float64,
         **settings: Any) -> list[dict[str, float]]:
    """The C++ lag identifier over y through the monitor (one report row a sample): each
    applied fit as {sample, status, fit_status, a1, a2, q, r, mean, gain0, gain1}."""
    native = core("imu")
    s = native.GyroMonitorSettings(rate_hz=400.0, octaves=8, reidentify=True, identifier="lag",
                                   **settings)
    cls = native.GyroMonitorRun if dtype == np.float64 else native.GyroMonitorRunF32
    mon = cls(s, cfg, np.ones(8), np.zeros(8))
    yy = np.ascontiguousarray(y, dtype=dtype)
    flags = np.zeros(y.size, dtype=bool)
    out = mon.run(yy, flags, flags, 1, 0.6827)
    applied = np.asarray(out["retunes"]) + np.asarray(out["refused_retunes"])
    rows = np.flatnonzero(np.diff(np.r_[0.0, applied]) > 0)
    return [{"sample": int(out["sample"][i]), "status": STATUS[int(out["status"][i])],
             "fit_status": int(out["fit_status"][i]),
             **{k: float(out[k][i]) for k in (*MODEL, "gain0", "gain1")}} for i in rows]


def _u(a1: float, a2: float, q: float, r: float) -> np.ndarray:
    """(u1, u2, log q, log r): the coordinates of the fit and of the bounded step."""
    return np.array([math.atanh(a1 / (1.0 - a2)), math.atanh(a2), math.log(q), math.log(r)])


SETTINGS = {
    # the fit of all four parameters, steps bounded (the first one is), statistics kept
    "adapt_ar": dict(block_samples=400, retune_blocks=25, min_samples=8000, max_step=0.3,
                     fit_delay_samples=2000),
    # the same, each fit from the samples since the previous one
    "restarted": dict(block_samples=400, retune_blocks=25, min_samples=8000, max_step=0.3,
                      fit_delay_samples=2000, restart_after_fit=True),
    # a1, a2 held, the split fitted, each fit from the samples since the previous one
    "split": dict(block_samples=400, retune_blocks=25, min_samples=8000, max_step=0.3,
                  fit_delay_samples=2000, adapt_ar=False, restart_after_fit=True),
}


@pytest.mark.parametrize("variant", sorted(SETTINGS))
def test_cpp_equals_the_reference(variant: str) -> None:
    """The C++ identifier (double state) and the reference on a 48000-sample record of the
    pair (0.2297, 0.1638), r/q 1, with a white-noise stretch (refusals where the statistics
    restart after each fit): the same apply points and decisions; the models in use within
    0.01 standard errors of the reference's fit in (u1, u2, log q, log r) (its covariance
    from the guards' Hessian; the two fits are different maximisers stopped at 1e-8
    log-likelihood units of predicted gain, observed 1e-4 SE) and the mean within 0.01 of
    its standard error; the
    gain that of the C++ model (the reference's DARE, 1e-9 relative: the Riccati recursion
    stops at 64 eps of its fixed point)."""
    settings = SETTINGS[variant]
    y = _record(0.2297, 0.1638, 1.0, 48000, 3)
    white = np.random.default_rng(4).normal(9.7, math.sqrt(2.0), 48000)
    y[22000:34000] = white[22000:34000]
    cfg = (0.18, 0.1, 1.5, 0.7, 9.0)
    got = _run(y, cfg, **settings)
    ref = LagIdentifierReference([cfg], **settings)
    ref.run(y[:, None])
    want = ref.events(0)
    assert [g["sample"] for g in got] == [e.sample for e in want] == [12000, 22000, 32000, 42000]
    assert [g["status"] for g in got] == [e.status for e in want]
    assert "tracking" in [e.status for e in want]
    if variant != "adapt_ar":  # the white stretch, the statistics restarted: refusals
        assert "not_identified" in [e.status for e in want]
    for g, e in zip(got, want, strict=True):
        assert e.fit is not None
        if e.status == "tracking":
            assert e.cov_u is not None
            se = np.sqrt(np.diag(e.cov_u))
            lam = e.fit.q / (e.fit.q + e.fit.r)
            # SE of (u1, u2, log q, log r): log q and log r from u3 as the guards take them
            se4 = np.r_[se[:2], (1.0 - lam) * se[-1], lam * se[-1]] if variant != "split" \
                else np.r_[np.inf, np.inf, (1.0 - lam) * se[-1], lam * se[-1]]
            d = np.abs(_u(g["a1"], g["a2"], g["q"], g["r"]) - _u(*e.model[:4]))
            assert np.all(d <= 0.01 * se4), (d / se4, g["sample"])
            se_mean = math.sqrt((e.fit.q / (1.0 - e.fit.a1 - e.fit.a2) ** 2 + e.fit.r) / 10000)
            assert abs(g["mean"] - e.model[4]) <= 0.01 * se_mean
            gain = steady_state_gain(Ar2Model(g["a1"], g["a2"], g["q"], 0.0), g["q"], g["r"])
            assert g["gain0"] == pytest.approx(gain[0], rel=1e-9)
            assert g["gain1"] == pytest.approx(gain[1], rel=1e-9)
            if variant == "split":
                assert (g["a1"], g["a2"]) == (cfg[0], cfg[1])
        else:  # refused: the configured model back
            assert tuple(g[k] for k in MODEL) == cfg
    # the first step is bounded: max_step 0.3 from the configured model, in both
    first = _u(*e.model[:4]) if (e := want[0]).status == "tracking" else None
    assert first is not None
    assert np.max(np.abs(first - _u(*cfg[:4]))) == pytest.approx(0.3, rel=1e-9)
    # float state as on the target: the same apply points and decisions
    got32 = _run(y, cfg, dtype=np.float32, **settings)
    assert [(g["sample"], g["status"]) for g in got32] == [(g["sample"], g["status"]) for g in got]


@pytest.mark.parametrize(("a1", "a2"), PAIRS)
@pytest.mark.parametrize("ratio", [1.0, 3.0])
def test_converges_to_the_offline_fit(a1: float, a2: float, ratio: float) -> None:
    """On the papers' pairs at r/q 1 and 3 (seed 1), the model in use after the fit of the
    first 100000 samples (cadence 100000, applied 1000 samples later, steps not bounded:
    max_step 100) is within 0.1 offline standard errors of fit_drift_model on those samples,
    every parameter and the mean (docs/validation/online-identification.md: the C++ fit of
    float statistics without the first values at L = 8 is within 0.061 SE on 40 such records),
    in float state as on the target."""
    n = 100000
    y = _record(a1, a2, ratio, n + 1000, 1)
    cfg = (0.5, 0.0, 1.0, 1.0, 9.0)
    got = _run(y, cfg, dtype=np.float32, block_samples=1000, retune_blocks=100, min_samples=n,
               max_step=100.0, fit_delay_samples=1000, max_rel_stderr=1.0, min_ar_wald=0.0)
    assert [g["sample"] for g in got] == [n + 1000]
    offline = gyrodrift.fit_drift_model(y[:n].astype(np.float32).astype(np.float64), rate_hz=400.0)
    g = got[0]
    assert g["status"] == "tracking"
    for k in MODEL:
        assert abs(g[k] - getattr(offline, k)) <= 0.1 * offline.stderr[k], k


def _stepped(which: str, n: int, seed: int) -> np.ndarray:
    """The pair (0.2297, 0.1638), q = r = 1, with q (the drift's driving noise) or r (the
    white noise) doubled from the middle of the record on."""
    rng = np.random.default_rng(seed)
    half = n // 2
    scale_q = np.where(np.arange(n + 2000) >= half + 2000, math.sqrt(2.0), 1.0) if which == "q" \
        else np.ones(n + 2000)
    x = lfilter([1.0], [1.0, -0.2297, -0.1638], scale_q * rng.normal(size=n + 2000))[2000:]
    scale_r = np.where(np.arange(n) >= half, math.sqrt(2.0), 1.0) if which == "r" else np.ones(n)
    return 9.7 + x + scale_r * rng.normal(size=n)


@pytest.mark.parametrize("which", ["q", "r"])
def test_tracks_a_step(which: str) -> None:
    """q or r doubled at sample 120000 of 240000; cadence 60000, fits applied 1000 samples
    after their request, the statistics restarted after each fit, steps of at most 1 in log q,
    log r. Within two cadences of the step (the fit requested at 180000, applied at 181000:
    its samples 121001 to 180000 all after the step) the model in use is within two of its
    offline standard errors (fit_drift_model on those samples) of the new q and r, and equal to
    that offline fit within 0.1 of them; before the step (the fit applied at 121000) it is
    within two standard errors of the old values."""
    n = 240000
    y = _stepped(which, n, 5)
    cfg = (0.2297, 0.1638, 1.0, 1.0, 9.7)
    got = _run(y, cfg, block_samples=1000, retune_blocks=60, min_samples=20000, max_step=1.0,
               fit_delay_samples=1000, restart_after_fit=True)
    assert [g["sample"] for g in got] == [61000, 121000, 181000]
    assert all(g["status"] == "tracking" for g in got)
    before = gyrodrift.fit_drift_model(y[61000:120000], rate_hz=400.0)
    after = gyrodrift.fit_drift_model(y[121000:180000], rate_hz=400.0)
    new = {"q": 2.0 if which == "q" else 1.0, "r": 2.0 if which == "r" else 1.0}
    for k in ("q", "r"):
        assert abs(got[1][k] - 1.0) <= 2.0 * before.stderr[k], k
        assert abs(got[2][k] - new[k]) <= 2.0 * after.stderr[k], k
        assert abs(got[2][k] - getattr(after, k)) <= 0.1 * after.stderr[k], k
    assert got[2][which] > 1.5


def test_binding_refusals() -> None:
    """A misspelt identifier and settings the identifier refuses (n fit_delay_samples above
    the cadence) are errors with their field's name, not silent defaults."""
    native = core("imu")
    with pytest.raises(ValueError, match="identifier"):
        native.GyroMonitorSettings(rate_hz=400.0, octaves=8, identifier="kalman")
    with pytest.raises(ValueError, match="fit_delay_samples"):
        native.GyroMonitorSettings(rate_hz=400.0, octaves=8, fit_delay_samples=-1)
    s = native.GyroMonitorSettings(rate_hz=400.0, octaves=8, reidentify=True, identifier="lag",
                                   block_samples=100, retune_blocks=10, fit_delay_samples=1001)
    with pytest.raises(ValueError, match="re-identification refuses"):
        native.GyroMonitorRun(s, (0.5, 0.0, 1.0, 1.0, 0.0), np.ones(8), np.zeros(8))
    s.fit_delay_samples = 1000
    mon = native.GyroMonitorRun(s, (0.5, 0.0, 1.0, 1.0, 0.0), np.ones(8), np.zeros(8))
    assert mon.samples == 0
