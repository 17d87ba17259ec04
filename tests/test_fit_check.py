"""The fit self-check: a point passes inside its interval or within the ratio tolerance; the
model holds only when every used point passes; unused points never fail the model."""

from __future__ import annotations

import numpy as np
from gyrodrift.stability.fit_check import DEFAULT_TOLERANCE, check_fit


def _curve(n: int = 6) -> tuple[np.ndarray, np.ndarray]:
    tau = np.logspace(-1, 2, n)
    return tau, 0.5 / np.sqrt(tau)


def test_fit_inside_interval_holds() -> None:
    tau, m = _curve()
    chk = check_fit(tau, m, m * 0.9, m * 1.1, m * 1.05, np.ones(tau.size, bool))
    assert chk.holds and chk.n_failed == 0 and chk.warnings == ()
    assert chk.inside.all()


def test_point_outside_interval_but_within_tolerance_passes() -> None:
    tau, m = _curve()
    fitted = m * (1.0 + 0.8 * DEFAULT_TOLERANCE)  # outside a +-5 % interval, inside tolerance
    chk = check_fit(tau, m, m * 0.95, m * 1.05, fitted, np.ones(tau.size, bool))
    assert chk.holds and not chk.inside.any()


def test_flat_misfit_in_used_points_fails_and_names_the_worst() -> None:
    tau, m = _curve()
    fitted = m.copy()
    fitted[3] *= 3.4  # the flat-B failure: the curve lifted well above the measurement
    chk = check_fit(tau, m, m * 0.9, m * 1.1, fitted, np.ones(tau.size, bool))
    assert not chk.holds and chk.n_failed == 1
    assert abs(chk.worst_ratio - 3.4) < 1e-12
    assert "1 of 6" in chk.warnings[0] and "3.4x" in chk.warnings[0]
    d = chk.as_dict()
    assert d["holds"] is False and d["passed"][3] is False and len(d["ratio"]) == 6


def test_misfit_outside_the_fit_range_does_not_fail_the_model() -> None:
    tau, m = _curve()
    fitted = m.copy()
    fitted[-1] *= 10.0
    used = np.ones(tau.size, bool)
    used[-1] = False
    chk = check_fit(tau, m, m * 0.9, m * 1.1, fitted, used)
    assert chk.holds and not chk.passed[-1]


def test_non_finite_fit_and_no_used_point_fail() -> None:
    tau, m = _curve()
    fitted = m.copy()
    fitted[0] = np.nan
    assert not check_fit(tau, m, m * 0.9, m * 1.1, fitted, np.ones(tau.size, bool)).holds
    chk = check_fit(tau, m, m * 0.9, m * 1.1, m, np.zeros(tau.size, bool))
    assert not chk.holds and "no tau" in chk.warnings[0]
