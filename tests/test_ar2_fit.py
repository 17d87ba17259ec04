"""AR(2) identification: C++ core vs numpy reference vs statsmodels, papers' coefficient pairs,
rejection of bad records."""

from __future__ import annotations

import math

import gyrodrift
import gyrodrift.reference as ref
import numpy as np
import pytest
from conftest import SHARED_DATA, skip_unless_ci
from gyrodrift import Ar2FitError, Ar2Model, _core
from statsmodels.regression.linear_model import burg, yule_walker

# Papers' published AR(2) pairs: 000 eq. 6 (RLG) and 002 table 1 (three FOGs).
PAPER_PAIRS = [(-0.0340, 0.0252), (0.6868, -0.0213), (0.2297, 0.1638), (-0.0069, 0.0113)]
METHODS = ["yule-walker", "burg", "ls"]


def _record(a1: float, a2: float, n: int, seed: int) -> np.ndarray:
    # Drift-like record: AR(2) on top of a constant bias and a little white noise (deg/h).
    rec = gyrodrift.simulate(n=n, ar2=(a1, a2, 0.05), bias_deg_h=-3.7, seed=seed)
    return rec.rate_deg_h


# Coefficients are O(1) (|a| < 2 in the stationarity triangle), so an absolute 1e-12 bound is
# ~1e4 eps: room for different summation orders over 2e4 samples, far below any real error.
# sigma2, r, mean: relative 1e-12 for the same reason.
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("pair", PAPER_PAIRS)
def test_cpp_fit_matches_numpy_reference(pair: tuple[float, float], method: str) -> None:
    x = _record(*pair, n=20_000, seed=11)
    got = gyrodrift.fit_ar2(x, method)
    want = ref.fit_ar2(x, method)
    assert got.method == want.method and got.n == want.n == x.size
    assert abs(got.a1 - want.a1) < 1e-12
    assert abs(got.a2 - want.a2) < 1e-12
    for name in ("sigma2", "r", "mean"):
        assert getattr(got, name) == pytest.approx(getattr(want, name), rel=1e-12, abs=1e-300)


@pytest.mark.filterwarnings("ignore::FutureWarning")
@pytest.mark.parametrize("pair", PAPER_PAIRS)
def test_yule_walker_equals_statsmodels_mle(pair: tuple[float, float]) -> None:
    # Our Yule-Walker uses the biased (1/n) autocovariance = statsmodels method="mle"; its
    # default "adjusted" (1/(n-k)) differs by O(1/n), which this test also shows.
    x = _record(*pair, n=20_000, seed=3)
    m = gyrodrift.fit_ar2(x, "yule-walker")
    rho, sigma = yule_walker(x, order=2, method="mle", demean=True)
    assert abs(m.a1 - rho[0]) < 1e-12 and abs(m.a2 - rho[1]) < 1e-12
    assert m.sigma2 == pytest.approx(sigma**2, rel=1e-12)
    rho_adj, _ = yule_walker(x, order=2, demean=True)
    assert max(abs(m.a1 - rho_adj[0]), abs(m.a2 - rho_adj[1])) > 1e-9


@pytest.mark.parametrize("pair", PAPER_PAIRS)
def test_burg_equals_statsmodels(pair: tuple[float, float]) -> None:
    # Same reflection coefficients, hence the same (a1, a2) to rounding. sigma2 differs in
    # normalisation: ours (= MATLAB arburg) is E0 (1 - k1^2)(1 - k2^2) with E0 = sum x^2 / n;
    # statsmodels divides the stage-2 forward+backward error energy by 2 (n - 2). Both are
    # consistent; they differ by O(order / n) (edge terms), bounded here by 10 / n.
    n = 20_000
    x = _record(*pair, n=n, seed=5)
    m = gyrodrift.fit_ar2(x, "burg")
    rho, sigma2 = burg(x, order=2, demean=True)
    assert abs(m.a1 - rho[0]) < 1e-12 and abs(m.a2 - rho[1]) < 1e-12
    assert m.sigma2 == pytest.approx(sigma2, rel=10.0 / n)


def test_ls_equals_normal_equations_of_stacked_regression() -> None:
    # Independent check of FB-LS: scipy's lstsq (LAPACK gelsd) on the stacked forward and
    # backward regression, separately from the reference's numpy lstsq.
    import scipy.linalg

    x = _record(0.2297, 0.1638, n=5000, seed=9)
    d = x - x.mean()
    design = np.vstack([np.column_stack([d[1:-1], d[:-2]]), np.column_stack([d[1:-1], d[2:]])])
    target = np.concatenate([d[2:], d[:-2]])
    coef, res, *_ = scipy.linalg.lstsq(design, target)
    m = gyrodrift.fit_ar2(x, "ls")
    assert abs(m.a1 - coef[0]) < 1e-12 and abs(m.a2 - coef[1]) < 1e-12
    assert m.sigma2 == pytest.approx(res / (2 * (x.size - 2)), rel=1e-10)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("pair", PAPER_PAIRS)
def test_papers_pairs_recovered(pair: tuple[float, float], method: str) -> None:
    # Pure AR(2) record (no extra white noise). Asymptotic std of the estimates is
    # sqrt((1 - a2^2) / n) for both coefficients (Box-Jenkins, AR(2) information matrix);
    # n = 2e5 gives <= 2.24e-3, and 5 std (1.12e-2) is the bound (fixed seed, so the
    # test is deterministic; a real bias of the estimator would exceed it).
    n = 200_000
    a1, a2 = pair
    x = gyrodrift.simulate(n=n, ar2=(a1, a2, 0.3), bias_deg_h=1.5, seed=21).rate_deg_h
    m = gyrodrift.fit_ar2(x, method)
    tol = 5 * math.sqrt((1 - a2**2) / n)
    assert abs(m.a1 - a1) < tol and abs(m.a2 - a2) < tol
    # Residual variance: relative std sqrt(2 / n) = 3.2e-3; 5 std bound.
    assert m.sigma2 == pytest.approx(0.3**2, rel=5 * math.sqrt(2 / n))
    assert m.r == pytest.approx(0.3**2, rel=5 * math.sqrt(2 / n))
    assert m.mean == pytest.approx(1.5, abs=0.05)


def test_streaming_yule_walker_matches_two_pass() -> None:
    # Streaming sums of the data shifted by its first sample, centred at the end: algebraically
    # equal to the two-pass fit; rounding differs through the shifted sums (|shift| ~ 20 std),
    # so 1e-10 absolute on coefficients, 1e-10 relative on sigma2 and mean.
    x = _record(0.6868, -0.0213, n=50_000, seed=2) + 40.0
    a1, a2, sigma2, mean = _core.ar2_yule_walker_stream(x)
    m = gyrodrift.fit_ar2(x, "yule-walker")
    assert abs(a1 - m.a1) < 1e-10 and abs(a2 - m.a2) < 1e-10
    assert sigma2 == pytest.approx(m.sigma2, rel=1e-10)
    assert mean == pytest.approx(m.mean, rel=1e-10)


@pytest.mark.parametrize("method", METHODS)
def test_reject_too_short(method: str) -> None:
    for fn in (gyrodrift.fit_ar2, ref.fit_ar2):
        with pytest.raises(Ar2FitError, match="too-short") as info:
            fn(np.arange(7.0), method)
        assert info.value.cause == "too_short"
    gyrodrift.fit_ar2(np.array([1.0, 3, 2, 5, 4, 7, 6, 8]), method)  # 8 samples are enough


@pytest.mark.parametrize("method", METHODS)
def test_reject_constant(method: str) -> None:
    for fn in (gyrodrift.fit_ar2, ref.fit_ar2):
        with pytest.raises(Ar2FitError, match="constant") as info:
            fn(np.full(100, 0.1), method)
        assert info.value.cause == "constant"


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("method", METHODS)
def test_reject_non_finite(method: str, bad: float) -> None:
    x = _record(0.2, 0.1, n=200, seed=1)
    x[57] = bad
    for fn in (gyrodrift.fit_ar2, ref.fit_ar2):
        with pytest.raises(Ar2FitError, match="non-finite") as info:
            fn(x, method)
        assert info.value.cause == "non_finite"
    with pytest.raises(ValueError, match="non-finite"):
        _core.ar2_yule_walker_stream(x)


def test_reject_non_stationary() -> None:
    # A pure sinusoid obeys x_k = 2 cos(w) x_{k-1} - x_{k-2} forward and backward exactly, so
    # forward-backward LS returns a2 = -1 (to rounding): both roots on the unit circle. Whole
    # periods (25 x 20 samples) so that the removed mean is 2.0 to rounding.
    x = np.cos(2 * np.pi / 20 * np.arange(500)) + 2.0
    for fn in (gyrodrift.fit_ar2, ref.fit_ar2):
        with pytest.raises(Ar2FitError, match="non-stationary") as info:
            fn(x, "ls")
        assert info.value.cause == "non_stationary"


def test_fit_three_axes_and_bad_arguments() -> None:
    rec = gyrodrift.simulate(n=4000, ar2=(0.5, -0.2, 1.0), axes=3, seed=4)
    models = gyrodrift.fit_ar2(rec.rate_deg_h, "burg")
    assert len(models) == 3
    for i, m in enumerate(models):
        assert m == gyrodrift.fit_ar2(np.ascontiguousarray(rec.rate_deg_h[:, i]), "burg")
    with pytest.raises(ValueError, match="unknown AR"):
        gyrodrift.fit_ar2(rec.rate_deg_h[:, 0], "arma")
    with pytest.raises(ValueError, match="shape"):
        gyrodrift.fit_ar2(np.zeros((10, 2)))
    with pytest.raises(TypeError, match="dtype"):
        gyrodrift.fit_ar2(np.array(["a"] * 20))
    with pytest.raises(TypeError):
        _core.ar2_fit(np.arange(20, dtype=np.int64), _core.Ar2Method.burg)  # strict: no convert
    with pytest.raises(TypeError):
        _core.ar2_fit(np.arange(40.0)[::2], _core.Ar2Method.burg)  # strided: no silent copy
    with pytest.raises(TypeError, match="float32 or float64"):
        gyrodrift.fit_ar2(rec.rate_deg_h[:, 0], "burg", dtype=np.int32)


def test_fit_cause_is_the_binding_status_not_the_message() -> None:
    """The binding returns the C++ Ar2Status as a value; Ar2FitError.cause is its name and the
    error is a GyrodriftValueError (issue 9: no message parsing)."""
    from gyrodrift.errors import GyrodriftError, GyrodriftValueError

    for x, status in ((np.ones(100), _core.Ar2Status.constant),
                      (np.zeros(3), _core.Ar2Status.too_short),
                      (np.array([1.0, np.nan] * 20), _core.Ar2Status.non_finite)):
        got = _core.ar2_fit(np.ascontiguousarray(x), _core.Ar2Method.burg)
        assert got[0] == status and got[1:] == (0.0, 0.0, 0.0, 0.0, 0.0)
        with pytest.raises(Ar2FitError) as info:
            gyrodrift.fit_ar2(x, "burg")
        assert info.value.cause == status.name
        assert isinstance(info.value, GyrodriftValueError)
        assert isinstance(info.value, GyrodriftError) and isinstance(info.value, ValueError)
    ok = _core.ar2_fit(np.random.default_rng(1).standard_normal(200), _core.Ar2Method.burg)
    assert ok[0] == _core.Ar2Status.ok


def test_fit_real_laser_gyro_record() -> None:
    path = SHARED_DATA / "lasergyro.imu"
    if not path.exists():
        skip_unless_ci(f"real record not present at {path}")
    with path.open() as f:
        data_lines = [line for line in f if line.strip() and not line.startswith("%")]
    rows = np.loadtxt(data_lines[3:30_003])  # 3 header lines (data README), then 300 s
    gz_arcsec = rows[:, 2] * 0.1  # counts * 0.1 arcsec per count (data README)
    rate_deg_h = gz_arcsec / 0.01  # arcsec per 10 ms sample -> arcsec/s == deg/h
    for method in METHODS:
        got = gyrodrift.fit_ar2(rate_deg_h, method)
        want = ref.fit_ar2(rate_deg_h, method)
        # This record is strongly correlated (a1 + a2 ~ 0.93): rounding is amplified by the
        # condition number (1 + rho1) / (1 - rho1) (~18) of the Toeplitz system, so the
        # 1e-12 bound of the synthetic cases is scaled by it.
        rho1 = want.a1 / (1 - want.a2)
        tol = 1e-12 * (1 + abs(rho1)) / (1 - abs(rho1))
        assert abs(got.a1 - want.a1) < tol and abs(got.a2 - want.a2) < tol
        assert got.sigma2 == pytest.approx(want.sigma2, rel=tol)
        assert got.r == pytest.approx(want.r, rel=tol)
        assert got.stationary


def test_root_modulus_flags_trending_records() -> None:
    # Closed form check: complex roots have modulus sqrt(-a2); real roots the larger |root|.
    assert Ar2Model(a1=0.2, a2=-0.5, sigma2=1.0).root_modulus == pytest.approx(math.sqrt(0.5))
    assert Ar2Model(a1=0.5, a2=0.14, sigma2=1.0).root_modulus == pytest.approx(0.7)
    # A rate-random-walk record (non-stationary) is fitted (YW/Burg cannot return a
    # non-stationary model) but its root modulus sits next to 1; white noise is far from it.
    walk = gyrodrift.simulate(n=50_000, k_deg_h_rt_h=5.0, seed=8).rate_deg_h
    white = gyrodrift.simulate(n=50_000, n_deg_rt_h=0.01, seed=8).rate_deg_h
    assert gyrodrift.fit_ar2(walk, "burg").root_modulus > 0.99
    # White noise: a1, a2 ~ N(0, 1/n) (std 4.5e-3); complex roots have modulus sqrt(-a2), so
    # 5 std of a2 (0.022) bounds it by 0.15.
    assert gyrodrift.fit_ar2(white, "burg").root_modulus < 0.15


def test_python_constants_match_cpp() -> None:
    from gyrodrift.filters.ar2 import MIN_SAMPLES

    assert _core.AR2_MIN_SAMPLES == MIN_SAMPLES


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("pair", PAPER_PAIRS)
def test_float32_fit_as_on_target(pair: tuple[float, float], method: str) -> None:
    # The float32 C++ fit (firmware arithmetic) against the float64 reference on the same
    # float32 samples. Float sums of 2e4 terms: typical relative error sqrt(n) eps ~ 1e-5
    # (observed <= 5e-6); bound 1e-4 absolute on coefficients, 1e-4 relative otherwise.
    x32 = _record(*pair, n=20_000, seed=11).astype(np.float32)
    got = gyrodrift.fit_ar2(x32, method, dtype=np.float32)
    want = ref.fit_ar2(x32.astype(np.float64), method)
    assert abs(got.a1 - want.a1) < 1e-4 and abs(got.a2 - want.a2) < 1e-4
    for name in ("sigma2", "r", "mean"):
        assert getattr(got, name) == pytest.approx(getattr(want, name), rel=1e-4)
    # Default: float32 input is fitted in float64 (then it matches the reference to 1e-12).
    default = gyrodrift.fit_ar2(x32, method)
    assert abs(default.a1 - want.a1) < 1e-12 and abs(default.a2 - want.a2) < 1e-12
