"""Estimators on records of extreme magnitude: fit(c x) equals fit(x) scaled, for c far outside
the range where sums of squares stay finite (before: ZeroDivisionError, OverflowError or
ValueError from the drift model's likelihood and from GMWM).

Tolerances: the scaled record is fitted as x * (c / 2^k), a factor in [0.5, 1), so the
optimiser starts from a different point and stops within its own tolerance of the same
optimum: the drift model's log-likelihoods agree to 1e-6 and its parameters to 1 % of their
standard errors (the statistical uncertainty); GMWM's parameters to 1e-6 relative."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gyrodrift.filters.drift_model import fit_drift_model
from gyrodrift.stability.gmwm import identify_gmwm
from scipy.signal import lfilter


@pytest.fixture(scope="module")
def drift_record() -> np.ndarray:
    rng = np.random.default_rng(1)
    n = 4000
    return (lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(0, 0.5, n))
            + rng.normal(0, 0.3, n) + 2.0)


@pytest.fixture(scope="module")
def drift_fit(drift_record: np.ndarray):
    return fit_drift_model(drift_record, 100.0)


@pytest.mark.parametrize("c", [1e-150, 1e150])
def test_drift_model_fit_is_scale_equivariant(drift_record: np.ndarray, drift_fit,
                                              c: float) -> None:
    f0 = drift_fit
    f = fit_drift_model(drift_record * c, 100.0)
    power = {"a1": 0, "a2": 0, "q": 2, "r": 2, "mean": 1}
    for k, p in power.items():
        got = getattr(f, k) / c**p
        assert abs(got - getattr(f0, k)) < 0.01 * f0.stderr[k], (k, got, getattr(f0, k))
        assert math.isclose(f.stderr[k] / c**p, f0.stderr[k], rel_tol=0.05), k
    n = drift_record.size
    assert abs((f.loglike + n * math.log(c)) - f0.loglike) < 1e-6
    assert abs((f.aic - 2 * n * math.log(c)) - f0.aic) < 1e-5
    assert (f.identified, f.tuning, f.n) == (f0.identified, f0.tuning, f0.n)
    for got, ref, k in zip(f.filter_params, f0.filter_params, power, strict=False):
        assert abs(got / c**power[k] - ref) < 0.01 * f0.stderr[k], k


def test_drift_model_in_range_record_is_not_rescaled(drift_record: np.ndarray,
                                                     drift_fit) -> None:
    """A record at 2^40 times the reference is inside the safe range: fitted as it is."""
    f = fit_drift_model(drift_record * 2.0**40, 100.0)
    assert f.q == pytest.approx(drift_fit.q * 2.0**80, rel=1e-3)


@pytest.mark.parametrize("c", [1e-160, 1e160])
def test_gmwm_is_scale_equivariant(c: float) -> None:
    rng = np.random.default_rng(2)
    y = rng.normal(size=8192) * 30 + np.cumsum(rng.normal(size=8192)) * 0.05
    r0 = identify_gmwm(y, 100.0)
    r = identify_gmwm(y * c, 100.0)
    assert r.model == r0.model == "N+K"
    for p, q in zip(r.params, r0.params, strict=True):
        s = 1.0 if p.unit == "s" else c
        for attr in ("value", "se", "ci_low", "ci_high"):
            assert math.isclose(getattr(p, attr) / s, getattr(q, attr), rel_tol=1e-6), attr
    # The wavelet variances scale by c^2: (1e160)^2 is beyond float64 (inf, not an error),
    # (1e-160)^2 times ~1e2 is subnormal (positive, a few digits).
    if c > 1.0:
        assert np.isinf(r.wv).all()
    else:
        assert (r.wv > 0).all() and (r.wv < np.finfo(float).tiny).all()


# ------------------------------------------------------------- allan and identify commands

def _cli_json(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict:
    import json

    from gyrodrift.cli import main

    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


@pytest.fixture(scope="module")
def scaled_records(tmp_path_factory: pytest.TempPathFactory) -> dict[float, str]:
    rng = np.random.default_rng(8)
    y = rng.normal(size=20000) * 30.0 + np.cumsum(rng.normal(size=20000)) * 0.3
    d = tmp_path_factory.mktemp("scaled")
    paths = {}
    for c in (1.0, 1e150, 1e-150):
        paths[c] = str(d / f"rec{c:g}.npy")
        np.save(paths[c], y * c)
    return paths


def _close(a: float | None, b: float | None, c: float) -> None:
    """a (at scale c) is c x b (at scale 1) within 1e-9 relative: the record is analysed
    divided by a power of two, exactly, so only the last digits of c x b's product and of
    the optimiser's steps on a curve off by a power of two can differ."""
    if a is None or b is None:
        assert a is None and b is None
        return
    assert math.isclose(a, c * b, rel_tol=1e-9), (a, c * b)


@pytest.mark.parametrize("c", [1e150, 1e-150])
def test_allan_command_on_extreme_scales_gives_the_scaled_answer(
        scaled_records: dict[float, str], capsys: pytest.CaptureFixture[str], c: float) -> None:
    """Before: `allan` on the 1e150 record refused ("the Allan sums are not finite") or
    ended in a traceback from the IEEE 952 fit; the 1e-150 record failed in the fit too."""
    argv = ["--rate-hz", "100", "--gyro-units", "deg/h", "--json"]
    ref = _cli_json(["allan", scaled_records[1.0], *argv], capsys)
    got = _cli_json(["allan", scaled_records[c], *argv], capsys)
    for a, b in zip(got["taus"], ref["taus"], strict=True):
        for k in ("adev", "ci_low", "ci_high", "fit_adev"):
            _close(a[k], b[k], c)
    assert [t["name"] for t in got["fit"]["terms"]] == [t["name"] for t in ref["fit"]["terms"]]
    for a, b in zip(got["fit"]["terms"], ref["fit"]["terms"], strict=True):
        for k in ("value", "ci_low", "ci_high"):
            _close(a[k], b[k], c)
    for k in ("n_deg_rt_h", "k_deg_h_rt_h", "b_deg_h"):
        _close(got["ieee952"][k], ref["ieee952"][k], c)
    assert got["self_check"]["holds"] == ref["self_check"]["holds"]


@pytest.mark.parametrize("c", [1e150, 1e-150])
def test_identify_command_on_extreme_scales_gives_the_scaled_answer(
        scaled_records: dict[float, str], capsys: pytest.CaptureFixture[str], c: float) -> None:
    argv = ["--rate-hz", "100", "--gyro-units", "deg/h", "--json"]
    ref = _cli_json(["identify", scaled_records[1.0], *argv], capsys)
    got = _cli_json(["identify", scaled_records[c], *argv], capsys)
    assert [t["name"] for t in got["fit"]["terms"]] == [t["name"] for t in ref["fit"]["terms"]]
    for a, b in zip(got["fit"]["terms"], ref["fit"]["terms"], strict=True):
        for k in ("value", "ci_low", "ci_high"):
            _close(a[k], b[k], c)


def test_a_deviation_beyond_double_is_a_clear_error() -> None:
    """Where the answer itself is beyond double (samples alternating +-1.7e308: the Allan
    deviation at tau0 is 1.7e308 sqrt(2)), one line says so instead of an inf deviation."""
    from gyrodrift.stability.allan import oadev
    from gyrodrift.stability.deviations import deviation

    y = np.where(np.arange(4096) % 2 == 0, 1.7e308, -1.7e308)
    with pytest.raises(ValueError, match="beyond the floating-point range"):
        oadev(y, 100.0, progress=False)
    with pytest.raises(ValueError, match="beyond the floating-point range"):
        deviation(y, 100.0, "mdev")
