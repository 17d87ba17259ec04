"""Noise identification (IEEE Std 952 Annex C NNLS, paper eq. 8 fit, slope method) on
simulated records with known terms (gyrodrift.simulation.records)."""

from __future__ import annotations

import math

import gyrodrift
import numpy as np
import pytest
from gyrodrift.stability import allan, ieee952


def test_model_and_fit_roundtrip_exact() -> None:
    # Noise-free curve from the table C.2 model: the NNLS must give the terms back to
    # solver precision (1e-6 relative: nnls tolerance on a 5-column, 25-row system).
    tau = np.logspace(-2, 5, 25)
    terms = {"q_arcsec": 0.5, "n_deg_rt_h": 0.01, "b_deg_h": 0.05, "k_deg_h_rt_h": 0.2,
             "r_deg_h2": 0.5}
    fit = ieee952.identify(tau, ieee952.allan_model_deg_h(tau, **terms))
    for name, value in terms.items():
        assert getattr(fit, name) == pytest.approx(value, rel=1e-6), name


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_identify_q_n_b(seed: int) -> None:
    # 1e6 samples at 100 Hz (10^4 s). Q and N rule tau < 10 s where the edf is > 1e4, so the
    # deviation is known to < 1 % (1/sqrt(2 edf)); 3 % is > 4 sd. B rules 10..500 s with edf
    # 30..1500 per point (3..13 % each) and flicker noise's own realisation scatter: 15 %
    # (seeds 0..9 give at most 8 %).
    q_deg, n_rt_h, b_deg_h = 2e-4, 0.01, 0.3
    rec = gyrodrift.simulate(n=1_000_000, rate_hz=100.0, q_deg=q_deg, n_deg_rt_h=n_rt_h,
                             b_deg_h=b_deg_h, seed=seed)
    r = allan.oadev(rec.rate_deg_h, 100.0, taus="decade", per_decade=8)
    fit = ieee952.identify(r.tau_s, r.adev, r.edf)
    assert fit.q_deg == pytest.approx(q_deg, rel=0.03)
    assert fit.n_deg_rt_h == pytest.approx(n_rt_h, rel=0.03)
    assert fit.b_deg_h == pytest.approx(b_deg_h, rel=0.15)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_identify_n_k_r(seed: int) -> None:
    # 4e5 s at 1 Hz. N rules tau < 100 s (edf > 3000): 3 %. K and R rule the last 1.5
    # decades where the edf falls to 1..50; the fit pools ~12 such points: K 20 %, R 10 %
    # (seeds 0..9: K within 16 %, R within 6 %; K and R partly trade against each other).
    n_rt_h, k, r_ramp = 0.01, 0.5, 2.0
    rec = gyrodrift.simulate(n=400_000, rate_hz=1.0, n_deg_rt_h=n_rt_h, k_deg_h_rt_h=k,
                             r_deg_h2=r_ramp, seed=seed)
    res = allan.oadev(rec.rate_deg_h, 1.0, taus="decade", per_decade=8)
    fit = ieee952.identify(res.tau_s, res.adev, res.edf)
    assert fit.n_deg_rt_h == pytest.approx(n_rt_h, rel=0.03)
    assert fit.k_deg_h_rt_h == pytest.approx(k, rel=0.20)
    assert fit.r_deg_h2 == pytest.approx(r_ramp, rel=0.10)


def test_paper_fit_units_and_conversions() -> None:
    # An exact eq. 8 curve: the fit returns A0, A_-1, A_-2 and the paper's conversions.
    tau = np.logspace(0, 4, 15)
    a0, a1, a2 = 0.0528, 0.072, 0.00606
    sigma = a0 + a1 / np.sqrt(tau) + a2 / tau
    f = ieee952.paper_fit(tau, sigma)
    assert (f.a0, f.a_m1, f.a_m2) == pytest.approx((a0, a1, a2), rel=1e-6)
    assert f.q_paper == pytest.approx(a2 / math.sqrt(3.0), rel=1e-6)
    assert f.q_arcsec == f.q_paper  # (deg/h)*s is arcsec: same number, honest label
    assert f.q_deg == pytest.approx(f.q_arcsec / 3600.0)
    assert f.n_deg_rt_h == pytest.approx(a1 / 60.0, rel=1e-6)
    assert f.b_deg_h == pytest.approx(a0 / 0.6648, rel=1e-6)


def test_slope_method_cross_checks_nnls(rng: np.random.Generator) -> None:
    # White rate only (N = 0.02 deg/sqrt(h) at 10 Hz, 2e5 samples): the -1/2 line read at
    # 1 h gives N; the short taus have edf > 1e4, the read-off point tolerance 5 %.
    rec = gyrodrift.simulate(n=200_000, rate_hz=10.0, n_deg_rt_h=0.02, seed=7)
    r = allan.oadev(rec.rate_deg_h, 10.0)
    s = ieee952.slope_method(r.tau_s, r.adev)
    assert s.n_deg_rt_h == pytest.approx(0.02, rel=0.05)
    assert s.k_deg_h_rt_h is None  # no +1/2 stretch in white noise
    # Noise-free Q + B + K curve with a wide flat floor: read-offs within 5 % (the neighbours'
    # tails still lift the minimum by ~3 %: the method's known bias).
    tau = np.logspace(-1, 5, 40)
    curve = ieee952.allan_model_deg_h(tau, q_arcsec=1.0, b_deg_h=0.1, k_deg_h_rt_h=0.1)
    s2 = ieee952.slope_method(tau, curve)
    assert s2.q_arcsec == pytest.approx(1.0, rel=0.01)
    assert s2.b_deg_h is not None and s2.b_deg_h == pytest.approx(0.1, rel=0.05)
    assert s2.k_deg_h_rt_h is not None and s2.k_deg_h_rt_h == pytest.approx(0.1, rel=0.05)


def test_bad_curves_rejected() -> None:
    with pytest.raises(ValueError, match="positive"):
        ieee952.identify(np.array([1.0, 2.0, 3.0, 4.0, 5.0]), np.array([1, 1, 0, 1, 1.0]))
    with pytest.raises(ValueError, match="cannot identify"):
        ieee952.identify(np.array([1.0, 2.0]), np.array([1.0, 0.5]))
    with pytest.raises(ValueError, match="finite"):
        ieee952.paper_fit(np.array([1.0, 2.0, np.nan]), np.ones(3))
