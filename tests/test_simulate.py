"""The noise simulator produces each IEEE Std 952 term with the intended statistics.

Allan variances here are computed in the test from first principles (block means), never by
the package. For the white/random-walk terms we use *disjoint* block pairs taken from groups
of three blocks: the difference of the two block means then depends only on noise inside the
group (white angle, white rate and rate-random-walk increments alike), so the differences are
independent Gaussians and the estimate divided by the truth is chi-square(M) / M with
relative standard deviation sqrt(2 / M). Tolerances are 5 of those standard deviations
(false-alarm probability < 1e-6 per check for any seed), and each test also asserts that the
tolerance is tight enough (< 10 %) to catch a wrong constant such as a missing sqrt(2) or 60.
"""

from __future__ import annotations

import math

import allantools
import gyrodrift
import numpy as np
import pytest
import scipy.fft
from gyrodrift.nav.earth import gravity_m_s2
from gyrodrift.simulation.records import NoiseTerms, ar2_stationary_covariance
from hypothesis import given, settings
from hypothesis import strategies as st

RATE_HZ = 400.0
DT_S = 1.0 / RATE_HZ
DT_H = DT_S / 3600.0
N_SIGMA = 5.0


def allan_disjoint(rate: np.ndarray, m: int) -> tuple[float, int]:
    """Allan variance at tau = m dt from independent block-mean differences.

    rate: (n,) or (n, axes). Uses blocks (3i, 3i+1) of each axis; returns (avar, M).
    """
    x = rate.reshape(rate.shape[0], -1)
    groups = x.shape[0] // (3 * m)
    blocks = x[: groups * 3 * m].reshape(groups, 3, m, x.shape[1]).mean(axis=2)
    d = blocks[:, 1, :] - blocks[:, 0, :]
    return float(np.mean(d**2) / 2.0), int(d.size)


def chi2_tolerance(m_dof: int) -> float:
    tol = N_SIGMA * math.sqrt(2.0 / m_dof)
    assert tol < 0.10, "test has too few degrees of freedom to detect a wrong constant"
    return tol


def overlapping_avar(x: np.ndarray, m: int) -> float:
    """Fully overlapping Allan variance of a 1-D rate record (IEEE Std 952, eq. C.19 style)."""
    c = np.concatenate([[0.0], np.cumsum(x)])
    means = (c[m:] - c[:-m]) / m
    d = means[m:] - means[:-m]
    return float(np.mean(d**2) / 2.0)


def test_allan_helpers_match_allantools() -> None:
    # The test's own Allan code, checked against the established peer on the same record.
    rec = gyrodrift.simulate(n=20_000, q_deg=0.001, n_deg_rt_h=0.01, b_deg_h=0.05, seed=2)
    for m in (1, 7, 100, 1000):
        taus, adev, *_ = allantools.oadev(
            rec.rate_deg_h, rate=RATE_HZ, data_type="freq", taus=[m * DT_S]
        )
        assert taus[0] == pytest.approx(m * DT_S)
        # Same estimator, different summation order: agreement to rounding (double).
        assert overlapping_avar(rec.rate_deg_h, m) == pytest.approx(adev[0] ** 2, rel=1e-9)
        adev_nonoverlap = allantools.adev(
            rec.rate_deg_h[: (rec.n // m) * m], rate=RATE_HZ, data_type="freq", taus=[m * DT_S]
        )[1][0]
        blocks = rec.rate_deg_h[: (rec.n // m) * m].reshape(-1, m).mean(axis=1)
        assert np.mean(np.diff(blocks) ** 2) / 2 == pytest.approx(adev_nonoverlap**2, rel=1e-9)


# --- white angle (quantization) --------------------------------------------------------------


def test_quantization_allan_is_3q2_over_tau2() -> None:
    q_deg = 0.002
    rec = gyrodrift.simulate(n=400_000, q_deg=q_deg, axes=4, seed=11)
    for m in (1, 4, 20, 100):
        tau_h = m * DT_H
        truth = 3.0 * q_deg**2 / tau_h**2  # (deg/h)^2
        avar, dof = allan_disjoint(rec.rate_deg_h, m)
        assert avar / truth == pytest.approx(1.0, abs=chi2_tolerance(dof)), m


def test_quantization_is_differenced_white_angle() -> None:
    # Integrated angle = e_k - e_{-1}: its variance stays 2 Q^2 at every lag (no growth).
    q_deg = 0.01
    rec = gyrodrift.simulate(n=2000, q_deg=q_deg, axes=5000, seed=3)
    angle = np.cumsum(rec.dtheta_deg, axis=0)
    for k in (0, 99, 1999):
        var = np.var(angle[k])
        tol = N_SIGMA * math.sqrt(2.0 / 5000)  # chi-square(5000) spread
        assert var / (2.0 * q_deg**2) == pytest.approx(1.0, abs=tol)


def test_pulse_counting_output_and_bounded_angle_error() -> None:
    pulse_deg = 0.1 / 3600.0  # 0.1 arcsec per count, as the shared laser-gyro record
    rec = gyrodrift.simulate(
        n=100_000,
        n_deg_rt_h=0.1,
        bias_deg_h=15.0,
        pulse_deg=pulse_deg,
        axes=2,
        seed=17,
        keep_components=True,
    )
    counts = rec.dtheta_deg / pulse_deg
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)  # whole pulses only
    error = rec.components["pulse_quantization"]
    true_angle = np.cumsum((rec.rate_deg_h - error) * DT_H, axis=0)
    counted_angle = np.cumsum(rec.rate_deg_h * DT_H, axis=0)
    angle_err = counted_angle - true_angle
    # Counting never loses angle: the error stays within one pulse (plus summation rounding).
    assert np.max(np.abs(angle_err)) < pulse_deg * (1.0 + 1e-6)
    # ARW spans ~3 pulses per sample, so the error is uniform and white: variance S^2/12
    # (sample variance of a uniform: relative SD sqrt(0.8 / n)) and no lag-1 correlation.
    for axis in range(2):
        e = angle_err[:, axis]
        assert np.var(e) / (pulse_deg**2 / 12.0) == pytest.approx(
            1.0, abs=N_SIGMA * math.sqrt(0.8 / rec.n)
        )
        r1 = np.corrcoef(e[1:], e[:-1])[0, 1]
        assert abs(r1) < N_SIGMA / math.sqrt(rec.n)


def test_pulse_counting_allan_quantization_term() -> None:
    # Q = S / sqrt(12) (IEEE Std 952 C.1): the Allan variance of the pulse-counting error
    # component is 3 Q^2 / tau^2, tested like the white-angle term.
    pulse_deg = 1e-4
    rec = gyrodrift.simulate(
        n=400_000, n_deg_rt_h=0.5, pulse_deg=pulse_deg, axes=4, seed=18, keep_components=True
    )
    q_deg = pulse_deg / math.sqrt(12.0)
    err = rec.components["pulse_quantization"]
    for m in (1, 10, 100):
        truth = 3.0 * q_deg**2 / (m * DT_H) ** 2
        avar, dof = allan_disjoint(err, m)
        # Uniform (not Gaussian) angle error: the squared second difference has a slightly
        # lighter tail, so the Gaussian chi-square spread is conservative.
        assert avar / truth == pytest.approx(1.0, abs=chi2_tolerance(dof)), m


# --- angle random walk -----------------------------------------------------------------------


def test_arw_white_rate_std() -> None:
    n_deg_rt_h = 0.0012
    rec = gyrodrift.simulate(n=400_000, n_deg_rt_h=n_deg_rt_h, seed=5)
    sigma_deg_h = 60.0 * n_deg_rt_h / math.sqrt(DT_S)
    tol = N_SIGMA * math.sqrt(2.0 / rec.n)  # sample variance of n white Gaussians
    assert np.var(rec.rate_deg_h) / sigma_deg_h**2 == pytest.approx(1.0, abs=tol)


def test_arw_allan_is_n2_over_tau() -> None:
    n_deg_rt_h = 0.05
    rec = gyrodrift.simulate(n=400_000, n_deg_rt_h=n_deg_rt_h, axes=4, seed=6)
    for m in (1, 10, 50, 100):
        truth = n_deg_rt_h**2 / (m * DT_H)
        avar, dof = allan_disjoint(rec.rate_deg_h, m)
        assert avar / truth == pytest.approx(1.0, abs=chi2_tolerance(dof)), m


def test_arw_angle_variance_grows_linearly() -> None:
    # Variance of the integrated angle over independent realisations: N^2 t.
    n_deg_rt_h = 0.1
    rec = gyrodrift.simulate(n=800, n_deg_rt_h=n_deg_rt_h, axes=8000, seed=7)
    angle_deg = np.cumsum(rec.dtheta_deg, axis=0)
    tol = N_SIGMA * math.sqrt(2.0 / 8000)
    for k in (1, 50, 800):
        truth = n_deg_rt_h**2 * k * DT_H
        assert np.var(angle_deg[k - 1]) / truth == pytest.approx(1.0, abs=tol), k


# --- rate random walk ------------------------------------------------------------------------


def test_rrw_allan_exact_discrete_and_k2_tau_over_3() -> None:
    k_coef = 2.0  # deg/h/sqrt(h)
    rec = gyrodrift.simulate(n=400_000, k_deg_h_rt_h=k_coef, axes=4, seed=8)
    step_var = k_coef**2 * DT_H  # (deg/h)^2 per sample
    for m in (1, 2, 10, 100):
        # Exact for a discrete random walk (derivation: block-difference weights 1..m..1 / m).
        truth = step_var * (2 * m * m + 1) / (6.0 * m)
        avar, dof = allan_disjoint(rec.rate_deg_h, m)
        assert avar / truth == pytest.approx(1.0, abs=chi2_tolerance(dof)), m
    # The IEEE 952 asymptote K^2 tau / 3 is reached for large m (relative gap 1/(2 m^2)).
    m = 1000
    assert step_var * (2 * m * m + 1) / (6.0 * m) == pytest.approx(
        k_coef**2 * m * DT_H / 3.0, rel=1e-6
    )


def test_rrw_rate_variance_grows_linearly() -> None:
    k_coef = 1.0
    rec = gyrodrift.simulate(n=1000, k_deg_h_rt_h=k_coef, axes=8000, seed=9)
    tol = N_SIGMA * math.sqrt(2.0 / 8000)
    for k in (1, 100, 1000):
        truth = k_coef**2 * k * DT_H
        assert np.var(rec.rate_deg_h[k - 1]) / truth == pytest.approx(1.0, abs=tol), k


# --- ramp and constant bias (deterministic: exact to rounding) -------------------------------


def test_ramp_and_bias_exact() -> None:
    rec = gyrodrift.simulate(n=1000, r_deg_h2=36.0, bias_deg_h=-2.5, seed=0)
    t_h = np.arange(1000) * DT_H
    np.testing.assert_allclose(rec.rate_deg_h, -2.5 + 36.0 * t_h, rtol=1e-12, atol=1e-12)
    avar, _ = allan_disjoint(rec.rate_deg_h, 50)
    tau_h = 50 * DT_H
    assert avar == pytest.approx(36.0**2 * tau_h**2 / 2.0, rel=1e-9)  # R^2 tau^2 / 2


# --- bias instability (flicker) --------------------------------------------------------------


def flicker_expected_avar(n: int, b_deg_h: float, m: int) -> float:
    """Exact expected Allan variance of the generated flicker process.

    Documented construction: white noise of length L = next_fast_len(2 n) shaped by
    sqrt(S(f) / dt), S(f) = B^2 / (2 pi f) two-sided, DC removed. For a circular process with
    bin powers g_k^2 the block-difference variance is (1/L) sum_k g_k^2 |W(w_k)|^2 with
    |W(w)|^2 = 4 sin^4(m w / 2) / (m^2 sin^2(w / 2)).
    """
    length = scipy.fft.next_fast_len(2 * n, real=True)
    k = np.arange(1, length)
    f_hz = np.minimum(k, length - k) / (length * DT_S)
    g2 = b_deg_h**2 / (2.0 * np.pi * f_hz) / DT_S
    w = 2.0 * np.pi * k / length
    w2 = 4.0 * np.sin(m * w / 2.0) ** 4 / (m**2 * np.sin(w / 2.0) ** 2)
    return float(np.sum(g2 * w2) / length / 2.0)


def test_flicker_expected_floor_range() -> None:
    # The claim in the simulate docstring: within 3 % of (2 ln2 / pi) B^2 for
    # 4 dt <= tau <= T/4, within 1 % for 8 dt <= tau <= T/10.
    n = 2**15
    floor = 2.0 * math.log(2.0) / math.pi
    for m in (4, 16, 256, n // 10, n // 4):
        assert flicker_expected_avar(n, 1.0, m) / floor == pytest.approx(1.0, abs=0.03), m
    for m in (8, 64, 1024, n // 10):
        assert flicker_expected_avar(n, 1.0, m) / floor == pytest.approx(1.0, abs=0.01), m
    assert math.sqrt(floor) == pytest.approx(0.664, abs=5e-4)  # IEEE 952's 0.664 B


def test_flicker_allan_floor_measured() -> None:
    b_deg_h = 0.0794
    n, axes = 2**15, 48
    rec = gyrodrift.simulate(n=n, b_deg_h=b_deg_h, axes=axes, seed=12)
    floor = 2.0 * math.log(2.0) / math.pi * b_deg_h**2
    for m in (4, 32, 256, 1024):
        per_axis = np.array([overlapping_avar(rec.rate_deg_h[:, a], m) for a in range(axes)])
        mean = per_axis.mean()
        # Independent axes: the spread of their estimates gives the standard error directly.
        se = per_axis.std(ddof=1) / math.sqrt(axes)
        assert se / floor < 0.05, "not enough averaging to test the floor"
        expected = flicker_expected_avar(n, b_deg_h, m)
        assert abs(mean - expected) < N_SIGMA * se, (m, mean / floor, expected / floor)
        assert mean / floor == pytest.approx(1.0, abs=0.03 + N_SIGMA * se / floor)


def test_flicker_spectrum_slope() -> None:
    # Periodogram averaged over axes, fitted in log-log over a mid band: slope -1 (1/f).
    b_deg_h = 1.0
    rec = gyrodrift.simulate(n=2**14, b_deg_h=b_deg_h, axes=64, seed=13)
    spec = np.mean(np.abs(np.fft.rfft(rec.rate_deg_h, axis=0)) ** 2, axis=1)
    f = np.fft.rfftfreq(rec.n, DT_S)
    band = (f > 1.0) & (f < 100.0)
    slope = np.polyfit(np.log(f[band]), np.log(spec[band]), 1)[0]
    assert slope == pytest.approx(-1.0, abs=0.05)  # 64-axis average: slope SE ~ 0.005


# --- AR(2) component -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "a1, a2",
    [(-0.0340, 0.0252), (0.6868, -0.0213), (0.2297, 0.1638), (-0.0069, 0.0113), (1.6, -0.8)],
)
def test_ar2_coefficients_recovered_by_least_squares(a1: float, a2: float) -> None:
    sigma = 0.05
    n = 200_000
    rec = gyrodrift.simulate(n=n, ar2=(a1, a2, sigma), seed=21)
    y = rec.rate_deg_h
    design = np.column_stack([y[1:-1], y[:-2]])
    coef, *_ = np.linalg.lstsq(design, y[2:], rcond=None)
    resid = y[2:] - design @ coef
    # Asymptotic SE of the AR(2) LS estimates is sqrt((1 - a2^2) / n) for both coefficients.
    se = math.sqrt((1.0 - a2**2) / n)
    assert coef[0] == pytest.approx(a1, abs=N_SIGMA * se)
    assert coef[1] == pytest.approx(a2, abs=N_SIGMA * se)
    assert np.var(resid) / sigma**2 == pytest.approx(1.0, abs=N_SIGMA * math.sqrt(2.0 / n))


def test_ar2_stationary_from_first_sample() -> None:
    # A slowly decaying AR(2): with a zero start the first samples would have variance sigma^2,
    # not gamma0 = 5.2 sigma^2... so the exact stationary start is visible at k = 0.
    a1, a2, sigma = 1.6, -0.8, 1.0
    gamma0, gamma1 = ar2_stationary_covariance(a1, a2, sigma**2)
    # Independent check of gamma0 from the MA(infinity) weights psi_j: gamma0 = sigma^2 sum psi^2.
    psi = [1.0, a1]
    for _ in range(2000):
        psi.append(a1 * psi[-1] + a2 * psi[-2])
    assert gamma0 == pytest.approx(sigma**2 * float(np.sum(np.square(psi))), rel=1e-9)
    rec = gyrodrift.simulate(n=3, ar2=(a1, a2, sigma), axes=20_000, seed=22)
    tol = N_SIGMA * math.sqrt(2.0 / 20_000)
    for k in range(3):
        assert np.var(rec.rate_deg_h[k]) / gamma0 == pytest.approx(1.0, abs=tol), k
    lag1 = np.mean(rec.rate_deg_h[0] * rec.rate_deg_h[1]) / gamma0
    assert lag1 == pytest.approx(gamma1 / gamma0, abs=N_SIGMA / math.sqrt(20_000) * 1.5)


# --- reproducibility, independence, components, units ----------------------------------------


def test_seed_reproducible_and_distinct() -> None:
    kwargs = dict(
        n=5000,
        q_deg=0.001,
        n_deg_rt_h=0.01,
        b_deg_h=0.05,
        k_deg_h_rt_h=0.1,
        ar2=(0.5, 0.1, 0.02),
        axes=3,
    )
    a = gyrodrift.simulate(seed=42, **kwargs)
    b = gyrodrift.simulate(seed=42, **kwargs)
    c = gyrodrift.simulate(seed=43, **kwargs)
    np.testing.assert_array_equal(a.rate_deg_h, b.rate_deg_h)
    assert not np.allclose(a.rate_deg_h, c.rate_deg_h)


def test_terms_use_independent_streams() -> None:
    # Adding a term does not change the realisation of the others.
    full = gyrodrift.simulate(n=4000, n_deg_rt_h=0.01, b_deg_h=0.1, seed=5, keep_components=True)
    arw_only = gyrodrift.simulate(n=4000, n_deg_rt_h=0.01, seed=5)
    np.testing.assert_array_equal(full.components["arw"], arw_only.rate_deg_h)
    np.testing.assert_allclose(
        full.components["arw"] + full.components["bias_instability"], full.rate_deg_h, rtol=1e-15
    )


def test_components_sum_to_record() -> None:
    rec = gyrodrift.simulate(
        n=3000,
        q_deg=0.001,
        n_deg_rt_h=0.01,
        b_deg_h=0.05,
        k_deg_h_rt_h=0.1,
        r_deg_h2=3.0,
        bias_deg_h=1.0,
        ar2=(0.3, 0.2, 0.01),
        axes=2,
        seed=1,
        keep_components=True,
    )
    assert set(rec.components) == {
        "quantization",
        "arw",
        "bias_instability",
        "rrw",
        "ramp",
        "bias",
        "ar2",
    }
    total = sum(rec.components.values())
    np.testing.assert_allclose(total, rec.rate_deg_h, rtol=1e-12, atol=1e-9)


def test_multi_axis_independent() -> None:
    n = 100_000
    rec = gyrodrift.simulate(
        n=n, n_deg_rt_h=0.01, q_deg=0.001, ar2=(0.7, 0.1, 0.01), axes=3, seed=31
    )
    assert rec.rate_deg_h.shape == (n, 3) and rec.rate_deg_h.flags.c_contiguous
    corr = np.corrcoef(rec.rate_deg_h.T)
    off = corr[np.triu_indices(3, k=1)]
    # Sample correlation of independent series: SE ~ 1/sqrt(n_eff); the AR(2) component makes
    # n_eff smaller than n, so allow 3x headroom on 5 SE.
    assert np.all(np.abs(off) < 3 * N_SIGMA / math.sqrt(n))


def test_shapes_units_and_duration() -> None:
    rec = gyrodrift.simulate(2.5, rate_hz=200.0, n_deg_rt_h=0.1, seed=0)
    assert rec.n == 500 and rec.rate_deg_h.shape == (500,) and rec.rate_deg_h.dtype == np.float64
    assert rec.dt_s == pytest.approx(0.005)
    np.testing.assert_allclose(rec.t_s[:3], [0.0, 0.005, 0.01])
    np.testing.assert_allclose(rec.rate_deg_s * 3600.0, rec.rate_deg_h, rtol=1e-15)
    np.testing.assert_allclose(rec.rate_rad_s, rec.rate_deg_h * math.pi / 180.0 / 3600.0,
                               rtol=1e-15)
    np.testing.assert_allclose(rec.dtheta_rad, rec.rate_rad_s * 0.005, rtol=1e-15)
    assert isinstance(rec.terms, NoiseTerms) and rec.terms.n_deg_rt_h == 0.1


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(n=100, q_deg=-1.0), "q_deg"),
        (dict(n=100, n_deg_rt_h=float("nan")), "n_deg_rt_h"),
        (dict(n=100, b_deg_h=-0.1), "b_deg_h"),
        (dict(n=100, k_deg_h_rt_h=float("inf")), "k_deg_h_rt_h"),
        (dict(n=100, bias_deg_h=float("nan")), "bias_deg_h"),
        (dict(n=100, rate_hz=0.0), "rate_hz"),
        (dict(n=100, rate_hz=-400.0), "rate_hz"),
        (dict(n=1), "too few samples"),
        (dict(n=0), "too few samples"),
        (dict(duration_s=0.001), "too few samples"),
        (dict(), "exactly one"),
        (dict(duration_s=1.0, n=400), "exactly one"),
        (dict(duration_s=-1.0), "duration_s"),
        (dict(n=100, axes=0), "axes"),
        (dict(n=100, seed=-1), "seed"),
        (dict(n=100, ar2=(1.2, -0.1, 1.0)), "not stationary"),
        (dict(n=100, ar2=(0.5, 0.6, 1.0)), "not stationary"),
        (dict(n=100, ar2=(0.1, 0.1, -1.0)), "sigma"),
        (dict(n=100, ar2=(0.1, 0.1)), "ar2"),
        (dict(n=2.5), "integer"),
        (dict(n=100, pulse_deg=-1e-5), "pulse_deg"),
    ],
)
def test_bad_arguments_raise_value_error(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gyrodrift.simulate(**kwargs)


# --- static IMU ------------------------------------------------------------------------------


def test_imu_truth_earth_rate_and_gravity() -> None:
    lat = 34.246048
    imu = gyrodrift.simulate_imu(n=100, latitude_deg=lat, height_m=380.0, seed=0)
    w_ie = 7.2921151467e-5  # WGS-84 (NIMA TR8350.2), rad/s
    lat_r = math.radians(lat)
    expected_gyro = [0.0, w_ie * math.cos(lat_r), w_ie * math.sin(lat_r)]
    np.testing.assert_allclose(imu.gyro_rad_s, np.tile(expected_gyro, (100, 1)), atol=1e-20)
    assert imu.accel_m_s2[:, :2].max() == 0.0
    np.testing.assert_allclose(imu.accel_m_s2[:, 2], imu.gravity_m_s2)
    assert imu.dtheta_rad.shape == (100, 3) and imu.dv_m_s.shape == (100, 3)


def test_gravity_m_s2_against_published_somigliana() -> None:
    # gyrodrift.nav.earth (the one Earth model, shared with nav/earth.hpp) uses the PSINS series
    # g_eq (1 + b1 sin^2 L + b2 sin^4 L). Against WGS-84 normal gravity (NIMA TR8350.2,
    # Somigliana's a/b form with the published equator and pole values) it is within
    # 8e-5 m/s^2 (8e-6 g; largest at the pole), far below any accelerometer bias simulated
    # here. Radians in.
    a_m, b_m = 6378137.0, 6356752.3142
    g_e, g_p = 9.7803253359, 9.8321849378
    for lat in (0.0, 12.0, 34.246048, 45.0, 71.0, 90.0):
        c2, s2 = math.cos(math.radians(lat)) ** 2, math.sin(math.radians(lat)) ** 2
        somigliana = (a_m * g_e * c2 + b_m * g_p * s2) / math.sqrt(a_m**2 * c2 + b_m**2 * s2)
        assert gravity_m_s2(math.radians(lat)) == pytest.approx(somigliana, abs=8e-5), lat
    assert gravity_m_s2(0.0) == pytest.approx(9.7803253359, abs=2e-6)
    lat45 = math.radians(45.0)
    assert gravity_m_s2(lat45) - gravity_m_s2(lat45, 1000.0) == pytest.approx(3.086e-3, rel=1e-12)
    # the simulator uses the same model
    imu = gyrodrift.simulate_imu(n=10, latitude_deg=45.0, height_m=100.0)
    assert imu.gravity_m_s2 == gravity_m_s2(lat45, 100.0)


def test_imu_heading_rotates_horizontal_earth_rate() -> None:
    lat = 39.0
    w_h = 7.2921151467e-5 * math.cos(math.radians(lat))  # WGS-84 Earth rate
    east = gyrodrift.simulate_imu(n=10, latitude_deg=lat, heading_deg=90.0).gyro_rad_s[0]
    # Facing east, body x (right) points south: it sees minus the north component.
    np.testing.assert_allclose(east[:2], [-w_h, 0.0], atol=1e-18)
    yawed = gyrodrift.simulate_imu(n=10, latitude_deg=lat, heading_deg=30.0).gyro_rad_s[0]
    assert math.hypot(yawed[0], yawed[1]) == pytest.approx(w_h, rel=1e-14)


def test_imu_errors() -> None:
    n = 200_000
    terms = NoiseTerms(n_deg_rt_h=0.005, bias_deg_h=0.02)
    imu = gyrodrift.simulate_imu(
        n=n, gyro=terms, accel_bias_m_s2=[1e-3, -2e-3, 5e-4], vrw_m_s_rt_h=0.03, seed=4
    )
    gyro_err_deg_h = np.rad2deg(imu.gyro_rad_s - imu.gyro_true_rad_s) * 3600.0
    np.testing.assert_allclose(gyro_err_deg_h, imu.gyro_err_deg_h, rtol=1e-6, atol=1e-9)
    sigma_deg_h = 60.0 * 0.005 / math.sqrt(DT_S)
    tol = N_SIGMA * math.sqrt(2.0 / n)
    assert np.var(gyro_err_deg_h, axis=0) / sigma_deg_h**2 == pytest.approx(np.ones(3), abs=tol)
    np.testing.assert_allclose(gyro_err_deg_h.mean(axis=0), 0.02,
                               atol=N_SIGMA * sigma_deg_h / n**0.5)
    accel_err = imu.accel_m_s2 - imu.accel_true_m_s2
    sigma_a = 0.03 / 60.0 / math.sqrt(DT_S)  # m/s^2
    assert np.var(accel_err, axis=0) / sigma_a**2 == pytest.approx(np.ones(3), abs=tol)
    np.testing.assert_allclose(
        accel_err.mean(axis=0), [1e-3, -2e-3, 5e-4], atol=N_SIGMA * sigma_a / n**0.5
    )
    # Axes independent of each other and of the accelerometers.
    corr = np.corrcoef(np.hstack([gyro_err_deg_h, accel_err]).T)
    assert np.all(np.abs(corr[np.triu_indices(6, k=1)]) < N_SIGMA / math.sqrt(n))


def test_imu_per_axis_terms_and_validation() -> None:
    terms = [NoiseTerms(bias_deg_h=1.0), NoiseTerms(bias_deg_h=2.0), NoiseTerms(bias_deg_h=3.0)]
    imu = gyrodrift.simulate_imu(n=50, gyro=terms)
    np.testing.assert_allclose(imu.gyro_err_deg_h[0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="latitude"):
        gyrodrift.simulate_imu(n=50, latitude_deg=91.0)
    with pytest.raises(ValueError, match="3 NoiseTerms"):
        gyrodrift.simulate_imu(n=50, gyro=terms[:2])
    with pytest.raises(ValueError, match="vrw"):
        gyrodrift.simulate_imu(n=50, vrw_m_s_rt_h=-1.0)
    with pytest.raises(ValueError, match="accel_bias"):
        gyrodrift.simulate_imu(n=50, accel_bias_m_s2=[0.0, float("nan"), 0.0])
    a = gyrodrift.simulate_imu(n=50, gyro=NoiseTerms(n_deg_rt_h=0.1), vrw_m_s_rt_h=0.1, seed=9)
    b = gyrodrift.simulate_imu(n=50, gyro=NoiseTerms(n_deg_rt_h=0.1), vrw_m_s_rt_h=0.1, seed=9)
    np.testing.assert_array_equal(a.gyro_rad_s, b.gyro_rad_s)
    np.testing.assert_array_equal(a.accel_m_s2, b.accel_m_s2)


# --- properties over random arguments --------------------------------------------------------

_nonneg = st.floats(min_value=0.0, max_value=10.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(min_value=2, max_value=300),
    axes=st.integers(min_value=1, max_value=4),
    rate_hz=st.floats(min_value=0.5, max_value=2000.0),
    q=_nonneg,
    arw=_nonneg,
    b=_nonneg,
    k=_nonneg,
    r=st.floats(min_value=-10.0, max_value=10.0),
    bias=st.floats(min_value=-100.0, max_value=100.0),
    a1=st.floats(min_value=-1.9, max_value=1.9),
    a2=st.floats(min_value=-0.95, max_value=0.95),
    pulse=st.sampled_from([0.0, 1e-5, 1e-3]),
    seed=st.integers(min_value=0, max_value=2**32),
)
def test_any_valid_arguments_give_finite_reproducible_records(
    n: int,
    axes: int,
    rate_hz: float,
    q: float,
    arw: float,
    b: float,
    k: float,
    r: float,
    bias: float,
    a1: float,
    a2: float,
    pulse: float,
    seed: int,
) -> None:
    ar2 = (a1, a2, 0.1) if (a2 + a1 < 0.99 and a2 - a1 < 0.99) else None
    kwargs = dict(
        n=n,
        rate_hz=rate_hz,
        q_deg=q,
        n_deg_rt_h=arw,
        b_deg_h=b,
        k_deg_h_rt_h=k,
        r_deg_h2=r,
        bias_deg_h=bias,
        ar2=ar2,
        pulse_deg=pulse,
        axes=axes,
        seed=seed,
    )
    rec = gyrodrift.simulate(**kwargs)
    assert rec.rate_deg_h.shape == ((n,) if axes == 1 else (n, axes))
    assert np.all(np.isfinite(rec.rate_deg_h))
    np.testing.assert_array_equal(rec.rate_deg_h, gyrodrift.simulate(**kwargs).rate_deg_h)
