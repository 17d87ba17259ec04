"""The misspecification-robust intervals of the default Allan fit
(gyrodrift.stability.allan_fit): the Allan-filter correlation over log-frequency, the
moment estimate of the model discrepancy, the sampling covariance from the record, and
the model-set widening. Coverage on the presets: tests/test_noise_presets.py."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import scipy.integrate
from gyrodrift.simulation import simulate_preset
from gyrodrift.stability import allan_fit, gmwm
from gyrodrift.stability.allan import oadev
from gyrodrift.stability.allan_fit import fit_allan
from gyrodrift.stability.gmwm import allan_kernel_corr


def _corr_quad(delta: float) -> float:
    # independent route: x = pi f tau, du = dx / x, the kernel sin^4(x) / x^2 of the
    # Allan variance's transfer function per log-frequency; quad on [0, 200] (the tail
    # beyond is below 1e-6 of the integral), split at multiples of pi (the zeros)
    def g(x: float) -> float:
        return math.sin(x) ** 4 / x**2

    edges = [1e-9] + [math.pi * k for k in range(1, 64)]

    def integral(f) -> float:
        return sum(scipy.integrate.quad(f, a, b, limit=200)[0]
                   for a, b in itertools.pairwise(edges))

    num = integral(lambda x: g(x) * g(x * math.exp(delta)) / x)
    den = integral(lambda x: g(x) ** 2 / x)
    return num / den


def test_allan_kernel_corr_against_quadrature() -> None:
    # the grid (14001 points over 14 e-folds) and its interpolation: within 2e-3 absolute
    tau = np.array([1.0, 2.0, 4.0, 8.0, 3.0])
    c = allan_kernel_corr(tau)
    for j, t in enumerate(tau[1:], start=1):
        assert c[0, j] == pytest.approx(_corr_quad(math.log(t)), abs=2e-3)
    assert np.allclose(np.diag(c), 1.0) and np.allclose(c, c.T)


def test_discrepancy_moment_estimate_is_unbiased() -> None:
    # Linear model in log sigma^2 (the fit's linearisation): residuals r = M e of errors
    # e ~ N(0, V_s + d^2 C) with a known d; the moment estimate d_hat^2 averages to d^2
    # (500 draws: the sd of the mean is about 4 % of d^2 here; bound 12 %).
    rng = np.random.default_rng(4)
    tau = 2.0 ** np.arange(-4, 12)
    jac = np.column_stack([1.0 / tau, np.ones_like(tau), tau]) / (1.0 / tau + 1.0 + tau)[:, None]
    edf = np.maximum(1e5 / tau, 3.0)
    v_s = np.diag(2.0 / edf)
    corr = allan_kernel_corr(tau)
    wt = 1.0 / (2.0 / edf + allan_fit.MODEL_DISCREPANCY**2)
    d_true = 0.05
    chol = np.linalg.cholesky(v_s + d_true**2 * corr)
    bread = np.linalg.inv(jac.T @ (jac * wt[:, None]))
    maker = np.eye(tau.size) - jac @ bread @ (jac.T * wt[None, :])
    d2 = []
    for _ in range(500):
        e = chol @ rng.standard_normal(tau.size)
        _, d = allan_fit._robust_cov(jac, wt, maker @ e, v_s, corr)
        d2.append(d * d)
    assert float(np.mean(d2)) == pytest.approx(d_true**2, rel=0.12)


def test_sampling_cov_from_the_record_is_the_white_noise_covariance() -> None:
    # white noise: the sieve's covariance of the log Allan variances against the exact
    # Gaussian covariance of the generating model (gmwm.wv_covariance, itself held to an
    # FFT reference and a Monte Carlo in tests/test_gmwm.py): variances within 25 % at taus
    # with >= 100 edf (the sieve is matched to a noisy curve).
    n = 1 << 15
    x = np.random.default_rng(9).standard_normal(n)
    r = oadev(x, 100.0, progress=False)
    used = r.adev > 0
    v_s, source = allan_fit._sampling_cov(r.tau_s, r.adev**2, r.edf, used, n, 100.0)
    assert source == "sieve"
    level = np.round(np.log2(r.tau_s[used] * 100.0)).astype(int) + 1
    exact = 4.0 * gmwm.wv_covariance("N", np.array([1.0]), level, n) / np.outer(
        1.0 / r.m[used], 1.0 / r.m[used])  # sigma^2(m) = 1 / m for unit white noise
    ok = r.edf[used] >= 100
    assert np.count_nonzero(ok) >= 6
    np.testing.assert_allclose(np.diag(v_s)[ok], np.diag(exact)[ok], rtol=0.25)
    # without the record's length the fit falls back to 2 / edf with the filter overlap
    _, source = allan_fit._sampling_cov(r.tau_s, r.adev**2, r.edf, used, None, None)
    assert source == "edf"


def test_model_set_widens_b_when_k_is_dropped() -> None:
    # tactical-mems at its default length, seed 1001: the selection keeps N+B (K dropped)
    # although N+B+K is within 4 of its IC; B's interval then covers N+B+K's B interval
    # (that one recomputed here as a fit of N+B+K alone on the same taus; its t quantile is
    # that of one dof fewer, rescaled) and the notes say so.
    import scipy.stats

    rec = simulate_preset("tactical-mems", 1_000_000, seed=1001)
    r = oadev(rec.gyro_deg_h, rec.rate_hz, progress=False, ci=0.95)
    fit = fit_allan(r.tau_s, r.adev, r.edf, ci=0.95, n_samples=r.n_samples, rate_hz=r.rate_hz)
    assert fit.covariance_source == "sieve"
    assert fit.names == ("N", "B") and ("N", "B", "K") in fit.model_set, (fit.names,
                                                                           fit.model_set)
    other = fit_allan(r.tau_s, r.adev, r.edf, ci=0.95, n_samples=r.n_samples,
                      rate_hz=r.rate_hz, terms="N,B,K", select=False,
                      fit_range=(fit.tau_min_s, fit.tau_max_s))
    assert other.dof == fit.dof - 1
    ob = other.term("B")
    f = scipy.stats.t.ppf(0.975, fit.dof) / scipy.stats.t.ppf(0.975, other.dof)
    b = fit.term("B")
    assert b.ci_high >= ob.value * (ob.ci_high / ob.value) ** f * (1 - 1e-6)
    assert b.ci_low <= ob.value * (ob.ci_low / ob.value) ** f * (1 + 1e-6)
    assert any("within 4 of the selected one's IC: N+B+K" in n for n in fit.notes())
