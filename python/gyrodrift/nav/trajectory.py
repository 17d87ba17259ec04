"""Kinematically consistent truth for a rocking base, and its exact IMU increments.

The base sways about a centre fixed at (lat, lon, h) plus an optional linear sway; the IMU sits
at a lever arm from the sway centre. Attitude angles are sums of sinusoids, so body rate,
velocity and specific force are analytic: omega_nb^b from the Euler-angle rates, the IMU
velocity v^n = r_c' + C_b^n (omega_nb^b x l^b), and its derivative by the complex-step rule
(exact to rounding, no finite-difference error). The gyro angle increment and accelerometer
velocity increment of sample k are the integrals of omega_ib^b and f^b over
[t_{k-1}, t_k] (what ideal integrating sensors output), evaluated by 8-point Gauss-Legendre
quadrature per sample (error < 1e-14 relative for these band-limited motions).

Simplification (stated): Earth rate, transport rate and gravity are evaluated at the sway
centre; a metre of sway changes them by < 2e-7 relative, far below every error studied here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.nav.earth import earth_params
from gyrodrift.units import DEG

__all__ = [
    "SCENARIOS",
    "Scenario",
    "Sinusoid",
    "dcm_batch",
    "imu_increments",
    "scenario",
    "truth_at",
]


@dataclass
class Sinusoid:
    """One sinusoidal motion term: amplitude (rad for angles, m for sway), period, phase.

    Examples
    --------
    >>> Sinusoid(amp=0.01, period_s=8.0).phase_rad
    0.0
    """
    amp: float  # rad (angles) or m (sway)
    period_s: float
    phase_rad: float = 0.0


@dataclass
class Scenario:
    """A rocking-base motion. Angles: [pitch, roll, yaw] means plus sinusoids per axis.

    Examples
    --------
    >>> Scenario(name="at rest").lever_arm_m.tolist()
    [0.0, 0.0, 0.0]
    """

    name: str
    att0_rad: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 30.0 * DEG]))
    angle_motion: list[list[Sinusoid]] = field(default_factory=lambda: [[], [], []])
    sway_motion_m: list[list[Sinusoid]] = field(default_factory=lambda: [[], [], []])  # E, N, U
    lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros(3))  # body frame
    lat_rad: float = 39.0 * DEG
    lon_rad: float = 116.0 * DEG
    h_m: float = 50.0
    zero_velocity_sigma_m_s: float = 0.01  # R of the zero-velocity measurement
    # Heading acquisition stage of the fine filter (AlignConfig.heading_stage_s/_q) for motions
    # whose 60 s coarse heading error reaches tens of degrees; 0 = off.
    heading_stage_s: float = 0.0
    heading_stage_q: float = 0.0
    heading_stage_max_coarse_s: float = 120.0  # longer coarse windows need no acquisition


def scenario(name: str, lat_deg: float = 39.0, yaw0_deg: float = 30.0) -> Scenario:
    """Named scenarios of the alignment study: static, ship_mild, ship_moderate, vehicle_engine.

    Examples
    --------
    >>> sc = scenario("static")
    >>> round(float(np.degrees(sc.lat_rad)), 6)
    39.0
    """
    att0 = np.array([0.0, 0.0, yaw0_deg * DEG])
    lat = lat_deg * DEG
    if name == "static":
        return Scenario(name, att0, lat_rad=lat, zero_velocity_sigma_m_s=0.001)
    if name == "ship_mild":
        # Moored ship: pitch 3 deg/12 s, roll 5 deg/15 s, yaw 2 deg/30 s.
        ang = [[Sinusoid(3 * DEG, 12.0, 0.3)], [Sinusoid(5 * DEG, 15.0, 1.1)],
               [Sinusoid(2 * DEG, 30.0, 2.0)]]
        return Scenario(name, att0, ang, lever_arm_m=np.array([1.0, 2.0, 3.0]), lat_rad=lat,
                        zero_velocity_sigma_m_s=0.2)
    if name == "ship_moderate":
        # [5, 5, 3] deg at [5, 7, 10] s plus about 1 m linear sway.
        ang = [[Sinusoid(5 * DEG, 5.0, 0.3)], [Sinusoid(5 * DEG, 7.0, 1.1)],
               [Sinusoid(3 * DEG, 10.0, 2.0)]]
        sway = [[Sinusoid(1.0, 8.0, 0.5)], [Sinusoid(1.0, 9.0, 1.5)], [Sinusoid(0.5, 6.0, 0.0)]]
        # 1 m of sway at 6-9 s periods leaves 2-57 deg of coarse heading error after 60 s
        # (first-order sway term, see test_coarse_ship_moderate_error_is_first_order_sway_term):
        # 10 min heading acquisition with (0.1 deg)^2/s of Up attitude process noise. The sway
        # term falls as T^-3: with a coarse window over 2 min the stage is not used (with 5 min
        # it made the 20-min heading spread worse: 395 vs 244 arcsec, 30 runs).
        return Scenario(name, att0, ang, sway, np.array([1.0, 2.0, 3.0]), lat_rad=lat,
                        zero_velocity_sigma_m_s=1.0, heading_stage_s=600.0,
                        heading_stage_q=(0.1 * DEG) ** 2)
    if name == "vehicle_engine":
        # Parked vehicle, engine running: sub-degree body rocking at 1-1.75 Hz and engine
        # vibration at 25-30 Hz as real angular motion (accelerometers see the lever arm and
        # sculling terms of it through the exact inversion).
        ang = [[Sinusoid(0.3 * DEG, 1 / 1.25, 0.3), Sinusoid(0.004 * DEG, 1 / 27.0, 0.7)],
               [Sinusoid(0.5 * DEG, 1 / 1.0, 1.1), Sinusoid(0.005 * DEG, 1 / 25.0, 0.1)],
               [Sinusoid(0.1 * DEG, 1 / 1.75, 2.0), Sinusoid(0.003 * DEG, 1 / 30.0, 1.3)]]
        return Scenario(name, att0, ang, lever_arm_m=np.array([0.3, 0.5, 0.4]), lat_rad=lat,
                        zero_velocity_sigma_m_s=0.02)
    raise GyrodriftValueError(f"unknown scenario {name!r}; choose from {', '.join(SCENARIOS)}")


SCENARIOS = ("static", "ship_mild", "ship_moderate", "vehicle_engine")


def _sines(motion: list[Sinusoid], t: np.ndarray, order: int) -> np.ndarray:
    out = np.zeros_like(t)
    for s in motion:
        w = 2 * np.pi / s.period_s
        arg = w * t + s.phase_rad
        if order == 0:
            out = out + s.amp * np.sin(arg)
        else:
            out = out + s.amp * w * np.cos(arg)
    return out


def _angles(sc: Scenario, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    att = np.stack([sc.att0_rad[i] + _sines(sc.angle_motion[i], t, 0) for i in range(3)])
    rate = np.stack([_sines(sc.angle_motion[i], t, 1) for i in range(3)])
    return att, rate  # (3, n) each


def dcm_batch(att: np.ndarray) -> np.ndarray:
    """C_b^n for arrays of angles (3, n) -> (n, 3, 3); works with complex input.

    Examples
    --------
    >>> dcm_batch(np.zeros((3, 2))).shape  # level attitude: identity matrices
    (2, 3, 3)
    """
    sp, cp = np.sin(att[0]), np.cos(att[0])
    sr, cr = np.sin(att[1]), np.cos(att[1])
    sy, cy = np.sin(att[2]), np.cos(att[2])
    c = np.empty((att.shape[1], 3, 3), dtype=att.dtype)
    c[:, 0, 0] = cy * cr - sy * sp * sr
    c[:, 0, 1] = -sy * cp
    c[:, 0, 2] = cy * sr + sy * sp * cr
    c[:, 1, 0] = sy * cr + cy * sp * sr
    c[:, 1, 1] = cy * cp
    c[:, 1, 2] = sy * sr - cy * sp * cr
    c[:, 2, 0] = -cp * sr
    c[:, 2, 1] = sp
    c[:, 2, 2] = cp * cr
    return c


def _wnb_b(att: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """omega_nb^b = Ry(r)^T Rx(p)^T yaw' e_z + Ry(r)^T pitch' e_x + roll' e_y, (n, 3)."""
    sp, cp = np.sin(att[0]), np.cos(att[0])
    sr, cr = np.sin(att[1]), np.cos(att[1])
    pd, rd, yd = rate
    # Rx(p)^T e_z = [0, sp, cp]; Ry(r)^T [a, b, c] = [cr a - sr c, b, sr a + cr c].
    a, b, c = pd, yd * sp, yd * cp
    return np.stack([cr * a - sr * c, b + rd, sr * a + cr * c], axis=-1)


def _velocity(sc: Scenario, t: np.ndarray) -> np.ndarray:
    """IMU velocity in n, (n, 3); analytic in t (complex t allowed)."""
    att, rate = _angles(sc, t)
    cnb = dcm_batch(att)
    w = _wnb_b(att, rate)
    v = np.einsum("nij,nj->ni", cnb, np.cross(w, sc.lever_arm_m))
    return v + np.stack([_sines(sc.sway_motion_m[i], t, 1) for i in range(3)], axis=-1)


def truth_at(sc: Scenario, t: np.ndarray) -> dict[str, np.ndarray]:
    """Attitude (pitch, roll, yaw), C_b^n, IMU velocity and position offset (ENU m) at t.

    Examples
    --------
    >>> truth_at(scenario("static"), np.array([0.0, 1.0]))["cnb"].shape
    (2, 3, 3)
    """
    t = np.asarray(t, dtype=float)
    att, _ = _angles(sc, t)
    cnb = dcm_batch(att)
    pos = np.einsum("nij,j->ni", cnb, sc.lever_arm_m) + np.stack(
        [_sines(sc.sway_motion_m[i], t, 0) for i in range(3)], axis=-1)
    return {"att": att.T, "cnb": cnb, "vn": _velocity(sc, t), "pos_enu_m": pos}


_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


def imu_increments(sc: Scenario, n: int, dt_s: float,
                   t0_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Ideal gyro angle increments (rad) and accelerometer velocity increments (m/s), (n, 3)
    each, for samples ending at t0 + k dt, k = 1..n.

    Examples
    --------
    >>> dth, dv = imu_increments(scenario("static"), 400, 1 / 400)
    >>> dth.shape, round(float(dv[:, 2].sum()), 2)  # one second of gravity reaction, m/s
    ((400, 3), 9.8)
    """
    ep = earth_params(sc.lat_rad, sc.h_m, np.zeros(3))
    dtheta = np.zeros((n, 3))
    dv = np.zeros((n, 3))
    starts = t0_s + dt_s * np.arange(n)
    h = 1e-20 * max(1.0, t0_s + n * dt_s)  # complex step
    for xg, wg in zip(_GL_X, _GL_W, strict=True):
        t = starts + 0.5 * dt_s * (xg + 1.0)
        att, rate = _angles(sc, t)
        cnb = dcm_batch(att)
        vn = _velocity(sc, t)
        an = np.imag(_velocity(sc, t + 1j * h)) / h
        # Transport rate from the IMU velocity at the sway centre's latitude.
        wnen = np.stack([-vn[:, 1] / ep.rm_h_m, vn[:, 0] / ep.rn_h_m,
                         vn[:, 0] * ep.tan_lat / ep.rn_h_m], axis=-1)
        wnin = ep.wnie + wnen
        wib_b = _wnb_b(att, rate) + np.einsum("nji,nj->ni", cnb, wnin)
        fn = an + np.cross(2 * ep.wnie + wnen, vn) - ep.gn
        fb = np.einsum("nji,nj->ni", cnb, fn)
        dtheta += 0.5 * dt_s * wg * wib_b
        dv += 0.5 * dt_s * wg * fb
    return dtheta, dv

