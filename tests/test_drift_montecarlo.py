"""Monte Carlo (fixed seeds, lean): the maximum-likelihood-tuned steady-state AR(2)-Kalman
filter against the true-model filter (the DARE optimum), with the papers' tuning reported.

Issue-10 criterion: ML MSE within 10 % of the optimum over the papers' four pairs and r/q in
{0.3, 1, 3}. What holds and is asserted here: for the two pairs with real correlation
(0.6868/-0.0213 and 0.2297/0.1638) the ML filter is within 10 % of the optimum at every r/q.
For the two near-white pairs (-0.0340/0.0252, -0.0069/0.0113: |a| < 0.04) the drift is
practically white noise itself, so only q + r is identifiable from the record: no method that
sees only the record can be within 10 % there (scripts/drift_identifiability.py: Cramer-Rao
and two-point bounds). The fit detects it and tunes at q = r (minimax);
tests/test_drift_identifiability.py asserts that, and that the filter is then no worse than
the raw record (within the analytic 8.3 % at r/q = 0.3). Here the test asserts what is
identifiable: the record's total variance (drift + noise) within 5 %.
The larger run is scripts/drift_montecarlo.py (table in the README).
"""

from __future__ import annotations

import math

import gyrodrift
import numpy as np
import pytest
from scipy.signal import lfilter

N = 20000
SKIP = 500


def _record(a1: float, a2: float, ratio: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = lfilter([1.0], [1.0, -a1, -a2], rng.normal(0.0, 1.0, N + 2000))[2000:]
    truth = 9.7 + x
    return truth + rng.normal(0.0, math.sqrt(ratio), N), truth


def _mse(est: np.ndarray, truth: np.ndarray) -> float:
    return float(np.mean((est[SKIP:] - truth[SKIP:]) ** 2))


@pytest.mark.parametrize("pair", [(0.6868, -0.0213), (0.2297, 0.1638)])
@pytest.mark.parametrize("ratio", [0.3, 1.0, 3.0])
def test_ml_filter_within_10_percent_of_optimum(pair: tuple[float, float], ratio: float) -> None:
    a1, a2 = pair
    y, truth = _record(a1, a2, ratio, seed=100)
    true_model = gyrodrift.Ar2Model(a1=a1, a2=a2, sigma2=1.0, mean=9.7)
    optimum = _mse(gyrodrift.kalman_filter(y, true_model, q=1.0, r=ratio, steady_state=True), truth)
    ml = _mse(gyrodrift.fit_drift_model(y, rate_hz=100.0).kalman().process(y), truth)
    papers = _mse(gyrodrift.kalman_filter(y, gyrodrift.fit_ar2(y), steady_state=True), truth)
    print(f"pair {pair} r/q {ratio}: raw {_mse(y, truth):.4f} papers {papers:.4f} "
          f"ML {ml:.4f} optimum {optimum:.4f}")
    assert optimum <= ml <= 1.10 * optimum
    assert optimum <= papers  # nothing beats the optimum (a check of the yardstick itself)


@pytest.mark.parametrize("pair", [(-0.0340, 0.0252), (-0.0069, 0.0113)])
def test_near_white_pairs_only_the_total_variance_is_identified(pair: tuple[float, float]) -> None:
    # Not the 10 % criterion (it does not hold here, see the module docstring): the fit gets
    # the identifiable part, q + r, right; the MSE ratio is printed for the record.
    a1, a2 = pair
    y, truth = _record(a1, a2, 1.0, seed=101)
    fit = gyrodrift.fit_drift_model(y, rate_hz=100.0)
    true_model = gyrodrift.Ar2Model(a1=a1, a2=a2, sigma2=1.0, mean=9.7)
    optimum = _mse(gyrodrift.kalman_filter(y, true_model, q=1.0, r=1.0, steady_state=True), truth)
    ml = _mse(fit.kalman().process(y), truth)
    print(f"near-white pair {pair}: ML/optimum {ml / optimum:.3f}, q {fit.q:.3f}, r {fit.r:.3f}")
    # Total variance of the stationary drift + noise: g0 + r with g0 = q (1 - a2) / (...).
    g0 = (1 - a2) / ((1 + a2) * ((1 - a2) ** 2 - a1 ** 2))
    x_var = fit.q * (1 - fit.a2) / ((1 + fit.a2) * ((1 - fit.a2) ** 2 - fit.a1 ** 2))
    assert x_var + fit.r == pytest.approx(g0 + 1.0, rel=0.05)
