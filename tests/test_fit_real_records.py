"""`gyrodrift fit` is honest about what a record identifies: a fit whose standard errors do
not exist (NaN: the likelihood is flat or singular at the estimate) or whose profile drop is
zero is reported as "not identified" and its filter tuned as for any split that is not.

The record: white noise (std 1) with a near-unit-root drift 100x smaller (AR(1) 0.999 driven
by std 0.01), 5000 samples. The AR coefficients of so faint a drift are not determined by the
record (their standard errors are NaN), yet the probes' drops were large, and the fit was
reported "identified" with NaN errors: the failure seen on a real 100 Hz gyro axis."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gyrodrift.filters.drift_model import fit_drift_model
from scipy.signal import lfilter


def _record() -> np.ndarray:
    rng = np.random.default_rng(5)
    return rng.normal(0.0, 1.0, 5000) + lfilter([1.0], [1.0, -0.999], rng.normal(0.0, 0.01,
                                                                               5000))


def test_nan_standard_errors_are_not_identified() -> None:
    fit = fit_drift_model(_record(), 100.0)
    assert not isinstance(fit, tuple)
    free = [fit.stderr[k] for k in ("a1", "a2", "q", "r")]
    if all(math.isfinite(v) for v in free) and min(fit.split_drop) > 0.0:
        raise AssertionError(f"the premise changed: errors {free}, drops {fit.split_drop}")
    assert fit.identified is False
    assert fit.tuning == "minimax-split"
    _, _, q, r = fit.filter_params
    assert q == pytest.approx(r, rel=1e-12)  # the minimax tuning: q = r (rounding only)


def test_an_identified_fit_keeps_its_errors() -> None:
    # AR(2) drift (a1 0.6868, a2 -0.0213) well above white noise (std 0.3), 20000 samples:
    # identified, with finite errors, tuned by maximum likelihood
    rng = np.random.default_rng(1)
    x = lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(0, 0.5, 20000)) + rng.normal(
        0, 0.3, 20000)
    fit = fit_drift_model(x, 100.0)
    assert not isinstance(fit, tuple)
    assert fit.identified and fit.tuning == "ml"
    assert all(math.isfinite(fit.stderr[k]) for k in ("a1", "a2", "q", "r"))
