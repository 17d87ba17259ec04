"""Issue 6: strapdown, coarse alignment and fine-alignment KF; numpy references vs theory and
vs the C++ headers (through gyrodrift._core).

Tolerances: the C++ port performs the same floating-point operations in the same order as
the numpy reference except for summation order inside small dot products/matrix products,
so differences are rounding-level (observed 2e-13 rad over 18 000 steps); the issue's 1e-9
bound (double) is used. Physical bounds are stated where they are asserted.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from gyrodrift.filters.fir import forced_fir_taps
from gyrodrift.nav import (
    SCENARIOS,
    AlignConfig,
    coarse_align,
    euler2dcm,
    imu_increments,
    misalignment,
    run_alignment,
    scenario,
    strapdown_run,
    truth_at,
)
from gyrodrift.nav.attitude import dcm2q, q2dcm
from gyrodrift.nav.earth import EARTH_RATE_RAD_S, gravity_m_s2
from gyrodrift.nav.trajectory import Sinusoid
from gyrodrift.papers.imu_errors import ImuErrors, add_imu_errors
from gyrodrift.reference.align import InertialCoarseAlign, Strapdown, run_alignment_reference
from gyrodrift.reference.align.coarse import gravity_integral_i0
from gyrodrift.units import ARCSEC, DPH, DPSH, UG


def _phi_history(att: np.ndarray, cnb_true: np.ndarray) -> np.ndarray:
    return np.array([misalignment(euler2dcm(a), c) for a, c in zip(att, cnb_true, strict=True)])


# ---------------------------------------------------------------- truth / mechanization


def test_truth_increments_match_numerical_derivative_of_attitude() -> None:
    """The exact inversion is independent of the mechanization: the body rate recovered from
    the DCM history by central differences must equal dtheta/dt (to the O(h^2) difference
    error, ~1e-9 rad/s at h = 1 ms for these motions)."""
    sc = scenario("ship_moderate")
    dt = 0.01
    dth, _ = imu_increments(sc, 200, dt)
    k = 150
    t_mid = (k + 0.5) * dt
    h = 1e-3
    c = truth_at(sc, np.array([t_mid - h, t_mid + h]))["cnb"]
    c0 = truth_at(sc, np.array([t_mid]))["cnb"][0]
    dc = (c[1] - c[0]) / (2 * h)
    w_nb = c0.T @ dc  # [omega_nb^b x]
    w_nb = np.array([w_nb[2, 1], w_nb[0, 2], w_nb[1, 0]])
    lat = sc.lat_rad
    wnie = EARTH_RATE_RAD_S * np.array([0.0, np.cos(lat), np.sin(lat)])
    w_ib_mid = w_nb + c0.T @ wnie  # transport rate < 1e-7 rad/s is below this check
    # dtheta/dt is the interval mean; the mid-point rate differs by O(dt^2 w'') ~ 1e-6 rad/s.
    assert np.allclose(dth[k] / dt, w_ib_mid, atol=2e-6)


@pytest.mark.parametrize("name", SCENARIOS)
def test_mechanization_follows_truth_with_ideal_sensors(name: str) -> None:
    """From the true initial state (C++ strapdown, equal to the reference by
    test_strapdown_cpp_equals_reference). Static: 10 min at 100 Hz, bounds 1e-4 arcsec /
    1e-6 m/s (algorithm exact for constant rates; observed 1.2e-6 arcsec, 5e-10 m/s).
    Rocking: 2 min at 400 Hz (the truth generation dominates the test time), bounds
    0.01 arcsec / 1e-3 m/s (the one-plus-previous-sample coning/sculling residue; observed
    over 10 min 1.2e-3 arcsec and 1.3e-4 m/s on ship_moderate)."""
    sc = scenario(name)
    dt = 1.0 / 100.0 if name == "static" else 1.0 / 400.0
    n = 60000 if name == "static" else 48000
    dth, dv = imu_increments(sc, n, dt)
    tr0 = truth_at(sc, np.array([0.0]))
    q, v, _, bad = strapdown_run(dth, dv, dt, dcm2q(tr0["cnb"][0]), tr0["vn"][0],
                                 np.array([sc.lat_rad, sc.lon_rad, sc.h_m]))
    assert bad == 0
    idx = np.arange(n // 20 - 1, n, n // 20)
    tr = truth_at(sc, (idx + 1) * dt)
    phi = np.array([misalignment(q2dcm(q[i]), tr["cnb"][j]) for j, i in enumerate(idx)])
    att_bound, vel_bound = (1e-4 * ARCSEC, 1e-6) if name == "static" else (0.01 * ARCSEC, 1e-3)
    assert np.abs(phi).max() < att_bound
    assert np.abs(v[idx] - tr["vn"]).max() < vel_bound


def test_strapdown_cpp_equals_reference() -> None:
    sc = scenario("vehicle_engine")
    dt = 1.0 / 400.0
    n = 2000
    dth, dv = imu_increments(sc, n, dt)
    tr0 = truth_at(sc, np.array([0.0]))
    q0 = dcm2q(tr0["cnb"][0])
    pos0 = np.array([sc.lat_rad, sc.lon_rad, sc.h_m])
    q, v, pos, _ = strapdown_run(dth, dv, dt, q0, tr0["vn"][0], pos0)
    ref = Strapdown(q0, tr0["vn"][0], *pos0)
    for k in range(n):
        ref.step(dth[k], dv[k], dt)
    assert np.abs(q[-1] - ref.q).max() < 1e-12
    assert np.abs(v[-1] - ref.vn).max() < 1e-9
    assert np.abs(pos[:2] - ref.pos[:2]).max() < 1e-12 and abs(pos[2] - ref.pos[2]) < 1e-9


def test_strapdown_binding_rejects_bad_arrays_and_counts_nan() -> None:
    dth = np.zeros((10, 3))
    dv = np.zeros((10, 3))
    q0, v0, p0 = np.array([1.0, 0, 0, 0]), np.zeros(3), np.array([0.6, 2.0, 0.0])
    with pytest.raises(TypeError):
        strapdown_run(dth.astype(np.float32), dv, 0.01, q0, v0, p0)
    with pytest.raises(ValueError, match="shape"):
        strapdown_run(np.zeros((10, 2)), dv, 0.01, q0, v0, p0)
    with pytest.raises(ValueError, match="dt_s"):
        strapdown_run(dth, dv, 0.0, q0, v0, p0)
    dth[3, 1] = np.nan
    q, _, _, bad = strapdown_run(dth, dv, 0.01, q0, v0, p0)
    assert bad == 1 and np.isfinite(q).all()


# ---------------------------------------------------------------- coarse alignment


def test_gravity_integral_closed_form_matches_quadrature() -> None:
    """Closed forms (with the cancellation-free series) vs direct numerical integration of
    C_n(t)^i0 [0, 0, g] (Rodrigues), 1e-9 relative (trapezoid with 2e5 steps)."""
    from gyrodrift.reference.align.coarse import earth_rotation_i0_n

    lat, g, t_end = np.deg2rad(39.0), 9.8, 120.0
    ts = np.linspace(0.0, t_end, 200001)
    f = np.array([earth_rotation_i0_n(t, lat) @ np.array([0.0, 0.0, g]) for t in ts[::100]])
    # Coarse sampling for the rotation, then interpolate (the rotation is smooth).
    fi = np.stack([np.interp(ts, ts[::100], f[:, i]) for i in range(3)], axis=1)
    v = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (fi[1:] + fi[:-1]) * np.diff(ts)[:, None],
                                                    axis=0)])
    s = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(ts)[:, None],
                                                    axis=0)])
    cv = gravity_integral_i0(t_end, lat, g, False)
    cs = gravity_integral_i0(t_end, lat, g, True)
    # The East component is the small Earth-rate part; compare each component relatively.
    assert np.allclose(cv, v[-1], rtol=1e-6, atol=0)
    assert np.allclose(cs, s[-1], rtol=1e-6, atol=0)


def _triad_bound(sc, n: int, dt: float, position: bool, t0_s: float = 0.0) -> np.ndarray:
    """First-order bound of the TRIAD solution under a disturbance d of the two vectors:
    total <= |d2|/|a| + (|d2||b| + |a||d1|)/|a x b|, level <= |d2|/|a| + total sin(a, up_T)
    (the rotation about a, mostly heading, tilts the level by the angle between a and the
    local vertical at T, ~ W T cos L / 2 rad); a, b are the
    gravity vectors at T and T/2 and |d_j| bounds the sway term: velocity variant
    max|v(t) - v(0)|; position variant 2.5 max|r(t) - r(0)| (the displacement plus its
    least-squares projection onto t, which is at most 1.5 D on [0, T]). The window starts at
    t0_s of the scenario's time (the rocking phase)."""
    t = np.arange(1, n + 1) * dt
    tr = truth_at(sc, t0_s + np.concatenate([[0.0], t]))
    g = gravity_m_s2(sc.lat_rad, sc.h_m)
    out = []
    for t_j in (t[-1], t[n // 2 - 1]):
        m = t <= t_j + 1e-12
        if position:
            d = 2.5 * np.linalg.norm(tr["pos_enu_m"][1:][m] - tr["pos_enu_m"][0], axis=1).max()
        else:
            d = np.linalg.norm(tr["vn"][1:][m] - tr["vn"][0], axis=1).max()
        out.append(d)
    d2, d1 = out
    a = gravity_integral_i0(t[-1], sc.lat_rad, g, position)
    b = gravity_integral_i0(t[n // 2 - 1], sc.lat_rad, g, position)
    if position:  # the projection removal applied to the gravity vectors too
        def detr(t_j: float) -> np.ndarray:
            tt = t[t <= t_j + 1e-12]
            s = np.array([gravity_integral_i0(x, sc.lat_rad, g, True) for x in tt])
            return s[-1] - t_j * (tt @ s) / (tt @ tt)
        a, b = detr(t[-1]), detr(t[n // 2 - 1])
    from gyrodrift.reference.align.coarse import earth_rotation_i0_n

    na = np.linalg.norm(a)
    total = d2 / na + (d2 * np.linalg.norm(b) + na * d1) / np.linalg.norm(np.cross(a, b))
    up_t = earth_rotation_i0_n(t[-1], sc.lat_rad) @ np.array([0.0, 0.0, 1.0])
    sin_a_up = np.linalg.norm(np.cross(a / na, up_t))
    return np.array([d2 / na + total * sin_a_up, total])


@pytest.mark.parametrize("name", SCENARIOS)
@pytest.mark.parametrize("position", [False, True])
def test_coarse_alignment_within_theoretical_bound(name: str, position: bool) -> None:
    """Ideal sensors, 60 s at 50 Hz (t sampled coarsely to keep the bound cheap): the error
    comes from the sway alone and must lie inside the first-order TRIAD bound (+1 arcsec for
    the discrete-time integration). C++ and the numpy reference agree within 1e-9 rad."""
    sc = scenario(name)
    dt = 0.02
    n = 3000
    dth, dv = imu_increments(sc, n, dt)
    cnb = coarse_align(dth, dv, dt, sc.lat_rad, sc.h_m, position)
    ref = InertialCoarseAlign(n, dt, sc.lat_rad, sc.h_m, position)
    for k in range(n):
        ref.add(dth[k], dv[k])
    assert np.abs(cnb - ref.solve()).max() < 1e-9
    phi = misalignment(cnb, truth_at(sc, np.array([n * dt]))["cnb"][0])
    level_bound, total_bound = _triad_bound(sc, n, dt, position) + 1.0 * ARCSEC
    assert np.abs(phi[:2]).max() <= level_bound
    assert np.linalg.norm(phi) <= total_bound


def _scaled_sway(sc, k: float):
    """The scenario with its lever arm and linear sway scaled by k (same rotation)."""
    return dataclasses.replace(
        sc, lever_arm_m=sc.lever_arm_m * k,
        sway_motion_m=[[Sinusoid(s.amp * k, s.period_s, s.phase_rad) for s in ax]
                       for ax in sc.sway_motion_m])


@pytest.mark.parametrize("t0_s", [0.0, 10.0, 25.0, 40.0])
@pytest.mark.parametrize("position", [False, True])
def test_coarse_ship_moderate_error_is_first_order_sway_term(t0_s: float, position: bool) -> None:
    """Why ship_moderate's 60 s coarse heading is off by tens of degrees. At full sway (about
    1 m of linear sway plus the 3.7 m lever arm) the first-order TRIAD bound exceeds pi, so the
    bound test above cannot discriminate there. Scale the sway down to 1 cm and 2 cm (same
    rotation, several rocking phases t0) instead:
    - with the sway removed, the residual is the discrete-time error alone (< 3 arcsec at 50 Hz);
    - the sway-driven part (error minus that residual) doubles when the sway doubles (within 5%),
      i.e. the error is the first-order sway term the bound describes, and no implementation
      defect adds to it;
    - at 1 cm it lies inside the bound, which is now meaningful (a few degrees).
    Scaled by 100 to the full sway, the first-order term of the position variant is 0.05-0.95
    rad over these phases, i.e. outside the small-angle regime (measured full-sway heading errors
    reach about 80 deg): 1 m of sway at 6-9 s periods is too much for a 60 s window. The term
    falls as T^-3 for this variant and as T^-2 for the velocity variant."""
    sc0 = scenario("ship_moderate")
    dt = 0.02
    n = 3000
    phi = {}
    for k in (0.0, 0.01, 0.02):
        sc = _scaled_sway(sc0, k)
        dth, dv = imu_increments(sc, n, dt, t0_s)
        c_true = truth_at(sc, np.array([t0_s + n * dt]))["cnb"][0]
        phi[k] = misalignment(coarse_align(dth, dv, dt, sc.lat_rad, sc.h_m, position), c_true)
    assert np.linalg.norm(phi[0.0]) < 3.0 * ARCSEC
    d1, d2 = phi[0.01] - phi[0.0], phi[0.02] - phi[0.0]
    assert np.linalg.norm(d2 - 2.0 * d1) <= 0.05 * np.linalg.norm(2.0 * d1)
    level_bound, total_bound = _triad_bound(_scaled_sway(sc0, 0.01), n, dt, position, t0_s)
    assert total_bound < 10.0 * np.pi / 180.0  # the bound is informative at this sway
    assert np.linalg.norm(phi[0.01]) <= total_bound + np.linalg.norm(phi[0.0])
    assert np.abs(phi[0.01][:2]).max() <= level_bound + np.abs(phi[0.0][:2]).max()


def test_coarse_position_variant_beats_velocity_variant_under_sway() -> None:
    sc = scenario("ship_moderate")
    dt = 0.02
    dth, dv = imu_increments(sc, 3000, dt)
    c_true = truth_at(sc, np.array([60.0]))["cnb"][0]
    e_vel = abs(misalignment(coarse_align(dth, dv, dt, sc.lat_rad, sc.h_m, False), c_true)[2])
    e_pos = abs(misalignment(coarse_align(dth, dv, dt, sc.lat_rad, sc.h_m, True), c_true)[2])
    assert e_pos < 0.2 * e_vel


def test_coarse_static_with_biases_matches_bias_formula() -> None:
    """Static base with biases: level = nabla/g and the heading error follows the same bias
    formula as the analytic method, -eps_E/(W cos L) + (nab_E/g) tan L, to first order; the
    60 s inertial integration leaves a difference under 5 % of the heading term here."""
    sc = scenario("static")
    dt = 0.02
    dth, dv = imu_increments(sc, 3000, dt)
    c = truth_at(sc, np.array([60.0]))["cnb"][0]
    eps_n = np.array([0.05, 0.0, 0.0]) * DPH
    nab_n = np.array([100.0, -80.0, 0.0]) * UG
    cnb = coarse_align(dth + (c.T @ eps_n) * dt, dv + (c.T @ nab_n) * dt, dt, sc.lat_rad, sc.h_m)
    phi = misalignment(cnb, c)
    g = gravity_m_s2(sc.lat_rad, sc.h_m)
    theory = np.array([-nab_n[1] / g, nab_n[0] / g,
                       -eps_n[0] / (EARTH_RATE_RAD_S * np.cos(sc.lat_rad))
                       + nab_n[0] / g * np.tan(sc.lat_rad)])
    assert np.allclose(phi, theory, rtol=0.05, atol=0.5 * ARCSEC)


def test_coarse_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="at least 4"):
        coarse_align(np.zeros((3, 3)), np.zeros((3, 3)), 0.01, 0.6, 0.0)
    dth = np.zeros((100, 3))
    dv = np.tile([0.0, 0.0, 0.098], (100, 1))
    dth[50, 0] = np.inf
    with pytest.raises(ValueError, match=r"non-finite|degenerate"):
        coarse_align(dth, dv, 0.01, 0.6, 0.0)


# ---------------------------------------------------------------- fine alignment


def _static_biased(eps_n: np.ndarray, nab_n: np.ndarray, dt: float, minutes: float):
    sc = scenario("static")
    n = round(minutes * 60 / dt)
    dth, dv = imu_increments(sc, n, dt)
    c = truth_at(sc, np.array([0.0]))["cnb"][0]
    return sc, c, dth + (c.T @ eps_n) * dt, dv + (c.T @ nab_n) * dt


@pytest.mark.parametrize("n_states", [12, 15])
def test_fine_alignment_converges_to_steady_state_formulas(n_states: int) -> None:
    """Noise-free static data with known biases, 1 min coarse + 19 min fine (10 Hz samples
    and updates, numpy reference; constant rates make the sample rate immaterial). Nav-frame
    gyro drift purely East (the North/Up drift is
    observable and only partly estimated in 20 min, which would bias the check); the
    residual misalignment must equal phi_E = -nab_N/g, phi_N = nab_E/g and the heading error
    phi_U = -eps_E/(W cos L) + (nab_E/g) tan L (176 arcsec for 0.01 deg/h at 39 deg plus the
    accelerometer term) within 5 % (issue 6)."""
    eps_n = np.array([0.01, 0.0, 0.0]) * DPH
    nab_n = np.array([100.0, -80.0, 50.0]) * UG
    dt = 0.1
    sc, c, dth, dv = _static_biased(eps_n, nab_n, dt, 20.0)
    cfg = AlignConfig(dt_s=dt, kf_every=1, n_states=n_states, lat_rad=sc.lat_rad,
                      lon_rad=sc.lon_rad, h_m=sc.h_m, zv_sigma_m_s=0.001)
    out = run_alignment_reference(dth, dv, cfg)
    phi = misalignment(euler2dcm(out.att[-1]), c)
    g = gravity_m_s2(sc.lat_rad, sc.h_m)
    theory = np.array([-nab_n[1] / g, nab_n[0] / g,
                       -eps_n[0] / (EARTH_RATE_RAD_S * np.cos(sc.lat_rad))
                       + nab_n[0] / g * np.tan(sc.lat_rad)])
    # Magnitude quoted in the issue: about 176 arcsec for 0.01 deg/h at 39 deg.
    assert abs(eps_n[0] / (EARTH_RATE_RAD_S * np.cos(sc.lat_rad)) / ARCSEC - 176.0) < 1.0
    assert np.all(np.abs(phi - theory) <= 0.05 * np.abs(theory))
    cpp = run_alignment(dth, dv, cfg)
    assert np.abs(cpp.att - out.att).max() < 1e-9


@pytest.mark.parametrize("name", SCENARIOS)
@pytest.mark.parametrize("prefilter", [False, True])
def test_pipeline_cpp_equals_reference_on_noisy_rocking_data(name: str, prefilter: bool) -> None:
    """Whole alignment (prefilter + 8-sample accelerometer delay, coarse, 15-state KF) on 100 s
    of noisy 100 Hz data: every recorded quantity equal within 1e-9 (double)."""
    sc = scenario(name)
    dt = 0.01
    n = 10000
    dth, dv = imu_increments(sc, n, dt)
    dth, dv = add_imu_errors(dth, dv, dt, ImuErrors(gyro_lsb_arcsec=0.1), seed=7)
    cfg = AlignConfig(dt_s=dt, kf_every=10, coarse_s=60.0, lat_rad=sc.lat_rad,
                      lon_rad=sc.lon_rad, h_m=sc.h_m, zv_sigma_m_s=sc.zero_velocity_sigma_m_s,
                      taps=forced_fir_taps("db4", 256, 5) if prefilter else None,
                      accel_delay_samples=8 if prefilter else 0)
    ref = run_alignment_reference(dth, dv, cfg)
    cpp = run_alignment(dth, dv, cfg)
    assert not cpp.failed and cpp.bad_samples == 0
    assert np.array_equal(ref.t_s, cpp.t_s)
    assert np.abs(ref.coarse_cnb - cpp.coarse_cnb).max() < 1e-9
    assert np.abs(ref.att - cpp.att).max() < 1e-9
    assert np.abs(ref.eb - cpp.eb).max() < 1e-9 * DPH
    assert np.abs(ref.db - cpp.db).max() < 1e-9
    assert np.abs(ref.p_phi - cpp.p_phi).max() < 1e-9


def test_pipeline_cpp_equals_reference_with_heading_stage() -> None:
    """The heading acquisition stage (extra Up process noise, then KF restart and drift/bias
    reset) in C++ equals the numpy reference within 1e-9 (double); 20 s stage inside a 100 s
    record so both the switch and the restart are exercised."""
    sc = scenario("ship_moderate")
    dt = 0.01
    n = 10000
    dth, dv = imu_increments(sc, n, dt, 30.0)
    dth, dv = add_imu_errors(dth, dv, dt, ImuErrors(), seed=11)
    cfg = AlignConfig(dt_s=dt, kf_every=10, coarse_s=30.0, lat_rad=sc.lat_rad,
                      lon_rad=sc.lon_rad, h_m=sc.h_m, zv_sigma_m_s=sc.zero_velocity_sigma_m_s,
                      heading_stage_s=20.0, heading_stage_q=(0.1 * np.pi / 180) ** 2)
    assert cfg.heading_stage_cycles() == 200
    ref = run_alignment_reference(dth, dv, cfg)
    cpp = run_alignment(dth, dv, cfg)
    assert not cpp.failed
    assert np.abs(ref.att - cpp.att).max() < 1e-9
    assert np.abs(ref.eb - cpp.eb).max() < 1e-9 * DPH
    assert np.abs(ref.db - cpp.db).max() < 1e-9
    assert np.abs(ref.p_phi - cpp.p_phi).max() < 1e-9
    # The restart is visible: the heading sigma returns to its P0 (10 deg) after the stage,
    # from about 4 deg at its end (the acquisition noise keeps it open).
    k = cfg.heading_stage_cycles()
    assert ref.p_phi[k, 2] > 2.0 * ref.p_phi[k - 1, 2]
    off = dataclasses.replace(cfg, heading_stage_s=0.0)
    assert np.abs(run_alignment(dth, dv, off).att[-1] - cpp.att[-1]).max() > 1e-6


@pytest.mark.parametrize("t0_s", [5.0, 30.0, 10.0])
def test_heading_stage_converges_from_large_coarse_heading_error(t0_s: float) -> None:
    """ship_moderate, ideal sensors plus known constant biases, 30 min at 400 Hz. The rocking
    phase t0 sets the 60 s coarse heading error (the sway term): -19 deg (t0 5 s), +24 deg
    (30 s), +81 deg (10 s). With the scenario's acquisition stage (10 min,
    (0.1 deg)^2/s) the end heading lies within 2 sigma of the steady-state formula
    -eps_E/(W cos L) + (nab_E/g) tan L, sigma being the filter's own end heading std (about
    355 arcsec: the 1 m/s sway velocity is the zero-velocity noise, so that is the bound this
    measurement allows). Without the stage the 56.6 deg case stays about 6600 arcsec off
    (the drift state absorbs W cos L sin psi while the small-angle model is wrong)."""
    sc = scenario("ship_moderate")
    dt = 1.0 / 400.0
    n = 30 * 60 * 400
    dth, dv = imu_increments(sc, n, dt, t0_s)
    eps_b = np.full(3, 0.01) * DPH
    nab_b = np.full(3, 100.0) * UG
    dth = dth + eps_b * dt
    dv = dv + nab_b * dt
    cfg = AlignConfig(lat_rad=sc.lat_rad, lon_rad=sc.lon_rad, h_m=sc.h_m,
                      zv_sigma_m_s=sc.zero_velocity_sigma_m_s,
                      heading_stage_s=sc.heading_stage_s, heading_stage_q=sc.heading_stage_q)
    out = run_alignment(dth, dv, cfg)
    assert not out.failed
    cnb = truth_at(sc, out.t_s + t0_s)["cnb"]
    # Heading error after the first KF cycle (Up component of the misalignment = sin psi).
    psi0 = np.arcsin(misalignment(euler2dcm(out.att[0]), cnb[0])[2])
    assert 15.0 * np.pi / 180 < abs(psi0) < 85.0 * np.pi / 180  # large coarse error indeed
    c = cnb.mean(axis=0)
    u, _, vt = np.linalg.svd(c)
    c = u @ vt
    eps_n, nab_n = c @ eps_b, c @ nab_b
    g = gravity_m_s2(sc.lat_rad, sc.h_m)
    psi_ss = (-eps_n[0] / (EARTH_RATE_RAD_S * np.cos(sc.lat_rad))
              + nab_n[0] / g * np.tan(sc.lat_rad))
    sigma_end = out.p_phi[-1, 2]
    psi_end = misalignment(euler2dcm(out.att[-1]), cnb[-1])[2]
    assert abs(psi_end - psi_ss) <= 2.0 * sigma_end
    if t0_s == 10.0:
        base = run_alignment(dth, dv, dataclasses.replace(cfg, heading_stage_s=0.0))
        psi_base = misalignment(euler2dcm(base.att[-1]), cnb[-1])[2]
        assert abs(psi_base - psi_ss) > 5.0 * 2.0 * sigma_end


def test_pipeline_counts_nan_samples_and_validates_arguments() -> None:
    sc = scenario("static")
    dt = 0.05
    dth, dv = imu_increments(sc, 2400, dt)
    cfg = AlignConfig(dt_s=dt, kf_every=2, lat_rad=sc.lat_rad, zv_sigma_m_s=0.001)
    bad = dth.copy()
    bad[1500, 2] = np.nan
    bad[1700, 0] = np.inf
    out = run_alignment(bad, dv, cfg)
    assert out.bad_samples == 2 and not out.failed
    assert np.isfinite(out.att).all()
    with pytest.raises(TypeError):
        run_alignment(dth.astype(np.float32), dv, cfg)
    with pytest.raises(ValueError, match="coarse"):
        run_alignment(dth[:100], dv[:100], cfg)
    with pytest.raises(ValueError, match="n_states"):
        run_alignment(dth, dv, AlignConfig(dt_s=dt, n_states=9))
    with pytest.raises(ValueError, match="taps"):
        run_alignment(dth, dv, AlignConfig(dt_s=dt, taps=np.ones(300) / 300))
    with pytest.raises(ValueError, match="invalid alignment settings"):
        run_alignment(dth, dv, AlignConfig(dt_s=dt, zv_sigma_m_s=0.0))


def test_fine_alignment_heading_noise_near_arw_limit() -> None:
    """Static base, white gyro noise N = 0.005 deg/sqrt(h) (larger than the default so the
    test is short): the KF's own heading sigma after T of fine alignment must approach
    the ARW limit N/(W cos L sqrt(T)) from above (within a factor 1.5: the KF also spends
    information on level and bias states)."""
    sc = scenario("static")
    dt = 0.05
    n = round(16 * 60 / dt)
    dth, dv = imu_increments(sc, n, dt)
    arw = 0.005 * DPSH
    cfg = AlignConfig(dt_s=dt, kf_every=2, lat_rad=sc.lat_rad, lon_rad=sc.lon_rad,
                      h_m=sc.h_m, arw_rad_s_rt_hz=arw, zv_sigma_m_s=0.001, p0_eb_rad_s=1e-6 * DPH)
    out = run_alignment(dth, dv, cfg)
    t_fine = out.t_s[-1] - cfg.coarse_s
    limit = arw / (EARTH_RATE_RAD_S * np.cos(sc.lat_rad) * np.sqrt(t_fine))
    assert limit <= out.p_phi[-1, 2] <= 1.5 * limit


@pytest.mark.parametrize("where", ["all", "after_coarse", "most"])
def test_alignment_without_a_solution_reports_failure_with_reason(where: str) -> None:
    """issue 13: an all-NaN record returned empty histories with failed=False."""
    sc = scenario("static")
    dt = 0.05
    dth, dv = imu_increments(sc, 2400, dt)
    cfg = AlignConfig(dt_s=dt, kf_every=2, lat_rad=sc.lat_rad, zv_sigma_m_s=0.001)
    bad = dth.copy()
    if where == "all":
        bad[:] = np.nan
    elif where == "after_coarse":
        bad[cfg.coarse_samples() + 1 :] = np.nan
    else:
        bad[10:] = np.nan
    out = run_alignment(bad, dv, cfg)
    assert out.failed
    assert out.t_s.size == 0
    assert {"all": "all 2400 samples are NaN", "after_coarse": "no Kalman update",
            "most": "too few"}[where] in out.reason
    good = run_alignment(dth, dv, cfg)
    assert not good.failed and good.reason == ""
