"""`gyrodrift fit` is honest about what a record identifies: a fit whose standard errors do
not exist (NaN: the likelihood is flat or singular at the estimate) or whose profile drop is
zero is reported as "not identified" and its filter tuned as for any split that is not.

The record: white noise (std 1) with a near-unit-root drift 100x smaller (AR(1) 0.999 driven
by std 0.01), 5000 samples. The AR coefficients of so faint a drift are not determined by the
record (their standard errors are NaN), yet the probes' drops were large, and the fit was
reported "identified" with NaN errors: the failure seen on a real 100 Hz gyro axis."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.cli import main
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.filters.drift_model import block_average, drift_params_at_rate, fit_drift_model
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


# --------------------------------------------------------------- fits at a decimated rate

def test_pole_mapping_is_exact_for_the_block_step() -> None:
    # original poles rho e^(+-i theta); one block of F samples multiplies them by the power F;
    # the mapping takes the block model's poles back to the original ones (rounding only)
    rho, theta, factor = 0.99, 0.05, 8
    z = rho * np.exp(1j * theta)
    zf = z**factor
    a1_block, a2_block = 2.0 * zf.real, -abs(zf) ** 2
    a1, a2, _, r = drift_params_at_rate(a1_block, a2_block, 1.0, 0.5, factor)
    assert a1 == pytest.approx(2.0 * z.real, rel=1e-12)
    assert a2 == pytest.approx(-(rho**2), rel=1e-12)
    assert r == 0.5 * factor
    with pytest.raises(GyrodriftValueError, match="negative real pole"):
        drift_params_at_rate(-0.5, 0.0, 1.0, 1.0, 4)


def test_decimated_fit_agrees_with_a_direct_fit() -> None:
    """AR(2) drift with poles 0.99 and 0.9 (correlation times 100 and 10 samples) driven by
    std 0.05, under white noise of std 0.5, 40000 samples at 100 Hz: identified at its own
    rate (finite standard errors), so the direct fit is the reference. Fitted on block
    averages of 2 and 4 samples and mapped back: a1, a2 within 3 of the direct fit's standard
    errors; q and r within 10 % (2 samples) and 25 % (4 samples: the fast pole spans only 2.5
    blocks, so averaging removes part of the drift the white noise is told from; measured
    -16 % and -15 %)."""
    rng = np.random.default_rng(11)
    n, p1, p2 = 40000, 0.99, 0.9
    x = lfilter([1.0], [1.0, -(p1 + p2), p1 * p2], rng.normal(0, 0.05, n)) + rng.normal(0, 0.5,
                                                                                       n)
    direct = fit_drift_model(x, 100.0)
    assert not isinstance(direct, tuple) and direct.identified
    for factor, rel in ((2, 0.10), (4, 0.25)):
        f = fit_drift_model(block_average(x, factor), 100.0 / factor)
        assert not isinstance(f, tuple)
        a1, a2, q, r = drift_params_at_rate(f.a1, f.a2, f.q, f.r, factor)
        assert abs(a1 - direct.a1) < 3 * direct.stderr["a1"], factor
        assert abs(a2 - direct.a2) < 3 * direct.stderr["a2"], factor
        assert q == pytest.approx(direct.q, rel=rel), factor
        assert r == pytest.approx(direct.r, rel=rel), factor


def test_fit_cli_decimates_a_slow_drift_and_says_so(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """White noise (std 1 deg/h) with a first-order drift of correlation time 100 s (std
    about 0.7 deg/h), 2e5 samples at 100 Hz: the Allan minimum lies near 10 s, far from the
    0.01 s sample, so the fit runs on block averages and the filter comes back at 100 Hz."""
    rng = np.random.default_rng(3)
    n, phi = 200_000, math.exp(-0.01 / 100.0)
    drift = lfilter([1.0], [1.0, -phi], rng.normal(0.0, 0.7 * math.sqrt(1 - phi**2), n))
    path = tmp_path / "slow.npy"
    np.save(path, drift + rng.normal(0.0, 1.0, n))
    assert main(["fit", str(path), "--rate-hz", "100", "--gyro-units", "deg/h", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    dec = doc["decimation"]
    assert dec["factor"] >= 4 and dec["fit_rate_hz"] == 100.0 / dec["factor"]
    assert dec["filter_params_at_rate_hz"] == 100.0
    a1, a2, _, _ = doc["filter_params"]
    # the filter at 100 Hz: a slow pole (correlation time of tens of seconds or more)
    assert 0.99 < a1 + a2 < 1.0
    assert main(["fit", str(path), "--rate-hz", "100", "--gyro-units", "deg/h"]) == 0
    out = capsys.readouterr().out
    assert f"block averages of {dec['factor']} samples" in out
    assert "converted back to 100 Hz" in out
    # the configuration written from the fit says at which rate it was fitted
    toml = tmp_path / "fit.toml"
    assert main(["fit", str(path), "--rate-hz", "100", "--gyro-units", "deg/h", "-o",
                 str(toml)]) == 0
    text = toml.read_text()
    assert f"fit_rate_hz = {100.0 / dec['factor']!r}" in text
    assert 'identified = "yes"' in text
