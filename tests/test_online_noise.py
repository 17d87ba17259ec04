"""Online IEEE 952 noise estimates from the streaming Allan curve
(include/gyrodrift/stability/online_noise.hpp, gyrodrift.stability.online_noise): the C++
(double and float) against the numpy reference, the target's edf and chi-square quantiles
against Greenhall's edf and scipy, the estimates on simulated records against the generating
values, and the 95 % intervals' coverage by a small Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.stats
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.reference import online_noise as ref
from gyrodrift.simulation.presets import simulate_preset
from gyrodrift.stability.edf import edf_greenhall
from gyrodrift.stability.online_noise import (
    MIN_TERMS,
    NoiseEstimates,
    chi2_quantile,
    estimate_noise,
    nonoverlapped_edf,
)
from gyrodrift.stability.streaming import StreamingAllan

RATE_HZ = 400.0


def white_rw(rng: np.random.Generator, n: int, sigma: float, step: float) -> np.ndarray:
    """White noise of standard deviation sigma plus a random walk of increment std step."""
    return sigma * rng.standard_normal(n) + np.cumsum(step * rng.standard_normal(n))


def reference_estimates(sa: StreamingAllan, ci: float) -> ref.NoiseEstimatesRef:
    return ref.estimate_noise(sa.avar, sa.counts, sa.tau_s, ci)


def assert_term_close(got, want, rel: float) -> None:
    assert got.valid == want.valid and got.upper_limit == want.upper_limit
    for a, b in ((got.value, want.value), (got.lo, want.lo), (got.hi, want.hi)):
        assert a == pytest.approx(b, rel=rel, abs=0.0)


# ---------------------------------------------------------------- edf and quantiles

@pytest.mark.parametrize("noise,alpha", [("flicker", -1), ("random_walk", -2)])
@pytest.mark.parametrize("m", [4, 64, 1024])
@pytest.mark.parametrize("n", [3, 10, 100, 1000])
def test_edf_matches_greenhall(noise: str, alpha: int, m: int, n: int) -> None:
    # Moment-matched closed forms (continuous limit for flicker) against Greenhall & Riley's
    # algorithm (non-overlapped): within 1 % at m >= 64 (measured: 0.4 % for flicker at
    # n = 1000, 1e-4 for random walk), within 3.5 % at m = 4 (the sampling matters there).
    want = edf_greenhall(alpha, 2, m, (n + 1) * m + 1, overlapping=False, modified=False)
    assert nonoverlapped_edf(noise, n, m) == pytest.approx(want, rel=0.01 if m >= 64 else 0.035)


def test_white_edf_matches_a_monte_carlo() -> None:
    # edf = 2 E[S]^2 / Var[S] of the Allan variance of independent samples: 5000 records of
    # 41 samples (n = 40 differences); the formula (exact for independent samples) lies within
    # 4 standard errors of the sample edf (its relative standard error is about 2 %).
    rng = np.random.default_rng(7)
    y = rng.standard_normal((5000, 41))
    s = np.sum(np.diff(y, axis=1) ** 2, axis=1) / (2 * 40)
    sample_edf = 2.0 * s.mean() ** 2 / s.var()
    assert nonoverlapped_edf("white", 40, 1) == pytest.approx(sample_edf, rel=0.08)
    assert nonoverlapped_edf("white", 40, 1) == pytest.approx(1600 / 59.5, rel=1e-12)


# Wilson-Hilferty against the exact quantile, measured: at the 95 % interval ends
# (p = 0.025, 0.975) within 4.1 % for nu >= 5 and 0.8 % for nu >= 10; in the upper tail
# p = 1 - 1e-6 (the alarm thresholds) above the exact quantile (conservative) by at most 4.6 %
# for nu >= 5 and 0.5 % for nu >= 43.
@pytest.mark.parametrize("nu", [5.0, 10.0, 20.0, 43.0, 200.0, 5000.0])
@pytest.mark.parametrize("p", [0.025, 0.5, 0.975, 1 - 1e-6])
def test_wilson_hilferty_accuracy(nu: float, p: float) -> None:
    exact = scipy.stats.chi2.ppf(p, nu)
    got = chi2_quantile(nu, p)
    if p > 0.99:
        assert exact <= got <= exact * (1.046 if nu < 43 else 1.005)
    else:
        assert got == pytest.approx(exact, rel=0.041 if nu < 10 else 0.008)


@pytest.mark.parametrize("p", [1e-9, 1e-6, 0.01, 0.02425, 0.3, 0.5, 0.9, 0.999999])
def test_normal_quantile_matches_scipy_and_reference(p: float) -> None:
    from gyrodrift._native import core
    native = core("allan")
    # Acklam: relative error below 1.2e-9; the reference is the same formula in Python.
    assert native.normal_quantile(p) == pytest.approx(scipy.stats.norm.ppf(p), rel=2e-9, abs=1e-9)
    assert native.normal_quantile(p) == pytest.approx(ref.normal_quantile(p), rel=1e-14, abs=1e-15)
    # float: the same formula on p rounded to float (float arithmetic in polynomials with
    # cancellation near the branch point: 1e-4 relative)
    pf = float(np.float32(p))
    assert native.normal_quantile(p, True) == pytest.approx(ref.normal_quantile(pf), rel=1e-4)


def test_edf_and_quantile_float_equal_reference() -> None:
    from gyrodrift._native import core
    native = core("allan")
    for noise_i, noise in enumerate(("white", "flicker", "random_walk")):
        for n, m in ((1, 1), (7, 2), (64, 8), (10_000, 1024)):
            want = ref.nonoverlapped_edf(noise, n, m)
            assert native.nonoverlapped_edf(noise_i, n, m) == pytest.approx(want, rel=1e-13)
            assert native.nonoverlapped_edf(noise_i, n, m, True) == pytest.approx(want, rel=1e-6)
    for nu, z in ((3.0, 1.96), (43.0, 4.75), (1000.0, -1.96)):
        assert native.chi2_quantile_wh(nu, z) == pytest.approx(ref.chi2_quantile_wh(nu, z),
                                                              rel=1e-13)


# ---------------------------------------------------------------- C++ = reference

@pytest.mark.parametrize("seed", [1, 2, 3])
def test_double_equals_reference_and_float_within_bound(seed: int) -> None:
    rng = np.random.default_rng(seed)
    y = white_rw(rng, 1 << 17, 1.0, 3e-3) + 5.0
    for ci in (0.6827, 0.95):
        sa = StreamingAllan(RATE_HZ, 16)
        sa.push(y)
        got = estimate_noise(sa, ci)
        want = reference_estimates(sa, ci)
        assert got.ok and want.ok
        # same equations on the same curve: double rounding only
        for g, w in ((got.n, want.n), (got.b, want.b), (got.k, want.k)):
            assert_term_close(g, w, 1e-12)
        assert got.b_tau_s == want.b_tau_s
        # float: its own curve (within 1e-6 of the double one, docs/validation/
        # streaming-allan.md) and float arithmetic in the read-off: the values within 1e-6,
        # the interval ends (float quantiles, the cube of Wilson-Hilferty) within 1e-4
        sf = StreamingAllan(RATE_HZ, 16, dtype=np.float32)
        sf.push(y.astype(np.float32))
        gf = estimate_noise(sf, ci)
        for g, w in ((gf.n, got.n), (gf.b, got.b), (gf.k, got.k)):
            assert g.valid == w.valid and g.upper_limit == w.upper_limit
            assert g.value == pytest.approx(w.value, rel=1e-4 if g.upper_limit else 1e-6)
            assert g.lo == pytest.approx(w.lo, rel=1e-4)
            assert g.hi == pytest.approx(w.hi, rel=1e-4)


def test_nothing_estimable_before_min_terms_and_bad_arguments() -> None:
    sa = StreamingAllan(RATE_HZ, 4)
    sa.push(np.random.default_rng(0).standard_normal(MIN_TERMS))  # 7 terms at octave 0
    assert not estimate_noise(sa).ok
    sa.push(np.zeros(1))
    est = estimate_noise(sa)
    assert est.ok and est.n.upper_limit  # one usable octave: no slope to read yet
    with pytest.raises(GyrodriftValueError):
        estimate_noise(sa, 1.0)
    with pytest.raises(GyrodriftTypeError):
        estimate_noise(np.zeros(3))  # type: ignore[arg-type]


def test_as_dict_and_ieee_units() -> None:
    sa = StreamingAllan(RATE_HZ, 10)
    sa.push(np.random.default_rng(3).standard_normal(20_000))
    est = estimate_noise(sa, 0.95)
    d = est.as_dict()
    assert d["n"]["value"] == est.n.value and d["ci"] == 0.95
    ieee = est.ieee_deg_h()
    assert ieee.n.value == pytest.approx(est.n.value / 60.0, rel=1e-15)
    assert ieee.k.hi == pytest.approx(est.k.hi * 60.0, rel=1e-15)
    assert isinstance(ieee, NoiseEstimates)


# ---------------------------------------------------------------- against the truth

def test_white_plus_random_walk_recovers_n_and_k() -> None:
    # N = sigma / sqrt(rate), K = step * sqrt(rate) (a discrete random walk of increment std
    # step per sample). 2^20 samples (44 min at 400 Hz): N within 1 % (its interval is +-0.3 %),
    # K within 25 % (read at an octave with about 30 terms: its 95 % interval is about +-40 %).
    rng = np.random.default_rng(11)
    sigma, step = 1.0, 2e-3
    y = white_rw(rng, 1 << 20, sigma, step)
    sa = StreamingAllan(RATE_HZ, 20)
    sa.push(y)
    est = estimate_noise(sa, 0.95)
    assert not est.n.upper_limit and not est.k.upper_limit
    assert est.n.value == pytest.approx(sigma / math.sqrt(RATE_HZ), rel=0.01)
    assert est.k.value == pytest.approx(step * math.sqrt(RATE_HZ), rel=0.25)
    assert est.k.lo < step * math.sqrt(RATE_HZ) < est.k.hi


@pytest.mark.parametrize("preset", ["consumer-mems", "navigation-fog"])
def test_presets_within_tolerance(preset: str) -> None:
    # Realistic records (flicker B, output filter, quantization, vibration, Gauss-Markov):
    # N within 10 % of the generating value (the output filter and the other terms bias the
    # read-off a little), B within 15 % of the truth's read-off of the expected curve
    # (b_min_deg_h: the Allan minimum / 0.664 of the generating process); K: its interval
    # or its upper limit holds the generating value.
    rec = simulate_preset(preset, 400_000, seed=5)
    t = rec.truth
    sa = StreamingAllan(rec.rate_hz, 18)
    sa.push(rec.gyro_deg_h)
    est = estimate_noise(sa, 0.95).ieee_deg_h()
    assert not est.n.upper_limit
    assert est.n.value == pytest.approx(t.n_deg_rt_h, rel=0.10)
    assert not est.b.upper_limit
    assert est.b.value == pytest.approx(t.b_min_deg_h, rel=0.15)
    assert est.k.hi >= t.k_deg_h_rt_h
    if not est.k.upper_limit:
        assert est.k.lo <= t.k_deg_h_rt_h


def test_interval_coverage_95_percent() -> None:
    # 400 records of white noise + random walk (2^14 samples each): the 95 % intervals of N
    # (read at octave 0) and K (read at the longest usable octave, 15 terms, where the random
    # walk is 30x the white part) hold the generating value in 95 % of the records. With 400
    # records the binomial standard error is 1.1 %: accept 0.91 .. 0.99. K is read only when
    # the last octave rises by 2^0.5 over the one before (measured: 80 % of these records,
    # interval coverage 95.6 %); otherwise its upper limit is given, which holds the value less
    # often (measured 84 %: the records whose last octave fluctuated low are the ones left
    # unread); K's interval or limit together hold it in 93 % (accept >= 0.90).
    rng = np.random.default_rng(2024)
    sigma, step = 1.0, 1e-2
    n_true, k_true = sigma / math.sqrt(RATE_HZ), step * math.sqrt(RATE_HZ)
    hits_n = hits_k = used_k = limit_ok = 0
    runs = 400
    for _ in range(runs):
        sa = StreamingAllan(RATE_HZ, 14)
        sa.push(white_rw(rng, 1 << 14, sigma, step))
        est = estimate_noise(sa, 0.95)
        hits_n += est.n.lo <= n_true <= est.n.hi
        if not est.k.upper_limit:
            used_k += 1
            hits_k += est.k.lo <= k_true <= est.k.hi
        else:
            limit_ok += est.k.hi >= k_true
    assert 0.91 <= hits_n / runs <= 0.99
    assert used_k >= 0.7 * runs
    assert 0.91 <= hits_k / used_k <= 0.99
    assert (hits_k + limit_ok) / runs >= 0.90
