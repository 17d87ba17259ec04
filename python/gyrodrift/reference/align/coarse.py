"""Coarse alignment on a rocking base by the inertial-frame gravity method
(reference for nav/coarse_align.hpp).

C_b^n(t) = C_i0^n(t) C_ib0^i0 C_b^ib0(t): C_b^ib0 is integrated from the gyro increments
(coning-corrected, starting at I), C_i0^n(t) is the Earth rotation of the ENU frame about the
polar axis u = [0, cos L, sin L] (angle Omega t), and the constant C_ib0^i0 is found from the
gravity-induced specific force integrated in both inertial frames at t1 = T/2 and t2 = T::

  V^i0(t) = int_0^t C_n^i0(tau) [0, 0, g] dtau  (closed form below),
  V^ib0(t) = sum_k C_b^ib0(k-1) (dv_k + 1/2 dtheta_k x dv_k + sculling).

The position-integral variant uses S(t) = int_0^t V dtau instead, which turns the bounded
lever-arm sway velocity into a bounded displacement against a signal growing as t^3; the
unknown sway velocity at t = 0 would still leave a term v(0) t, so the least-squares
projection onto t (beta = sum t_k S_k / sum t_k^2 over [0, t_j]) is removed from the
sequences in both frames. The operator is linear and C_ib0^i0 constant, so the two frames
stay consistent, and no gravity term is linear in t.
C_ib0^i0 = M(V^i0_2, V^i0_1) M(V^ib0_2, V^ib0_1)^T with the TRIAD frame
``M(a, b) = [a/|a|, a x b/|a x b|, a x (a x b)/|..|]``, exactly orthonormal by construction.
"""

from __future__ import annotations

import numpy as np

from gyrodrift.nav.attitude import q2dcm, qmul, qnormalize, rv2q
from gyrodrift.nav.earth import EARTH_RATE_RAD_S, gravity_m_s2

__all__ = [
    "InertialCoarseAlign",
    "earth_rotation_i0_n",
    "gravity_integral_i0",
    "triad",
]


def _series_1mcos(x: float) -> float:
    """1 - cos x, cancellation-free for the small angles of alignment (|x| < 0.5)."""
    if abs(x) >= 0.5:
        return 1.0 - np.cos(x)
    x2 = x * x
    return x2 / 2 * (1 - x2 / 12 * (1 - x2 / 30 * (1 - x2 / 56 * (1 - x2 / 90))))


def _series_xmsin(x: float) -> float:
    """x - sin x, cancellation-free for |x| < 0.5."""
    if abs(x) >= 0.5:
        return x - np.sin(x)
    x2 = x * x
    return x * x2 / 6 * (1 - x2 / 20 * (1 - x2 / 42 * (1 - x2 / 72 * (1 - x2 / 110))))


def _series_x2h_m_1mcos(x: float) -> float:
    """x^2/2 - (1 - cos x), cancellation-free for |x| < 0.5."""
    if abs(x) >= 0.5:
        return x * x / 2 - (1.0 - np.cos(x))
    x2 = x * x
    return x2 * x2 / 24 * (1 - x2 / 30 * (1 - x2 / 56 * (1 - x2 / 90 * (1 - x2 / 132))))


def gravity_integral_i0(t_s: float, lat_rad: float, g_m_s2: float, position: bool) -> np.ndarray:
    """V^i0(t) (velocity variant) or S^i0(t) (position variant) of -g^n = [0, 0, g].

    C_n(t)^i0 e_U = [cL sin(Wt), sL cL (1 - cos Wt), cos Wt + sL^2 (1 - cos Wt)]; its
    integrals in closed form (W = Omega).

    Examples
    --------
    >>> gravity_integral_i0(0.0, 0.5, 9.8, position=False)
    array([0., 0., 0.])
    >>> gravity_integral_i0(10.0, 0.5, 9.8, position=False).round(6)  # ~ g t up, Earth turning
    array([3.1357000e-02, 4.0000000e-06, 9.7999993e+01])
    """
    w = EARTH_RATE_RAD_S
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    x = w * t_s
    if not position:
        a = _series_1mcos(x) / w  # int sin
        b = _series_xmsin(x) / w  # int (1 - cos)
        c = t_s - b  # int cos
        return g_m_s2 * np.array([cl * a, sl * cl * b, c + sl * sl * b])
    a = _series_xmsin(x) / (w * w)  # int int sin
    b = _series_x2h_m_1mcos(x) / (w * w)  # int int (1 - cos)
    c = 0.5 * t_s * t_s - b  # int int cos
    return g_m_s2 * np.array([cl * a, sl * cl * b, c + sl * sl * b])


def earth_rotation_i0_n(t_s: float, lat_rad: float) -> np.ndarray:
    """C_n(t)^i0: rotation by Omega t about u = [0, cos L, sin L] (Rodrigues).

    Examples
    --------
    >>> bool(np.allclose(earth_rotation_i0_n(0.0, 0.5), np.eye(3)))
    True
    """
    u = np.array([0.0, np.cos(lat_rad), np.sin(lat_rad)])
    x = EARTH_RATE_RAD_S * t_s
    ux = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + np.sin(x) * ux + _series_1mcos(x) * (ux @ ux)


def triad(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """

    Examples
    --------
    >>> c = triad(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    >>> c.shape
    (3, 3)
    """
    c = np.cross(a, b)
    d = np.cross(a, c)
    return np.column_stack([a / np.linalg.norm(a), c / np.linalg.norm(c), d / np.linalg.norm(d)])


class InertialCoarseAlign:
    """Accumulates increments for a fixed number of samples, then solves C_b^n at the end.

    Examples
    --------
    >>> from gyrodrift.nav import imu_increments, scenario
    >>> from gyrodrift.nav.attitude import dcm2euler
    >>> sc = scenario("static")
    >>> dth, dv = imu_increments(sc, 3000, 0.01)  # 30 s at rest, no sensor errors
    >>> ca = InertialCoarseAlign(3000, 0.01, sc.lat_rad, sc.h_m)
    >>> done = [ca.add(dth[k], dv[k]) for k in range(3000)][-1]
    >>> done, np.rad2deg(dcm2euler(ca.solve())).round(3) + 0.0
    (True, array([ 0.,  0., 30.]))
    """

    def __init__(self, n_samples: int, dt_s: float, lat_rad: float, h_m: float,
                 position_integral: bool = True) -> None:
        if n_samples < 4:
            raise ValueError("coarse alignment needs at least 4 samples")
        self.n = n_samples
        self.dt = dt_s
        self.lat = lat_rad
        self.g = gravity_m_s2(lat_rad, h_m)
        self.position = position_integral
        self.q = np.array([1.0, 0.0, 0.0, 0.0])  # C_b^ib0
        self.vib0 = np.zeros(3)
        self.sib0 = np.zeros(3)
        self.prev_dtheta = np.zeros(3)
        self.prev_dv = np.zeros(3)
        self.k = 0
        self.v1 = np.zeros(3)  # ib0 vector at t1
        self.v1_i0 = np.zeros(3)  # i0 vector at t1
        self.stt = 0.0  # sum t_k^2
        self.sty_b = np.zeros(3)  # sum t_k S^ib0(t_k)
        self.sty_i = np.zeros(3)  # sum t_k S^i0(t_k)

    def add(self, dtheta: np.ndarray, dv: np.ndarray) -> bool:
        """Feed one sample; returns True once the window is complete."""
        if self.k >= self.n:
            return True
        pt, pv = self.prev_dtheta, self.prev_dv
        dv_sf = dv + 0.5 * np.cross(dtheta, dv) + (np.cross(pt, dv) + np.cross(pv, dtheta)) / 12.0
        dvi = q2dcm(self.q) @ dv_sf
        v_old = self.vib0.copy()
        self.vib0 = self.vib0 + dvi
        self.sib0 = self.sib0 + 0.5 * (v_old + self.vib0) * self.dt
        phi = dtheta + np.cross(pt, dtheta) / 12.0
        self.q = qnormalize(qmul(self.q, rv2q(phi)))
        self.prev_dtheta = np.array(dtheta, dtype=float)
        self.prev_dv = np.array(dv, dtype=float)
        self.k += 1
        t = self.k * self.dt
        if self.position:
            self.stt += t * t
            self.sty_b = self.sty_b + t * self.sib0
            self.sty_i = self.sty_i + t * gravity_integral_i0(t, self.lat, self.g, True)
        if self.k == self.n // 2:
            self.v1, self.v1_i0 = self._vectors()
        return self.k >= self.n

    def _vectors(self) -> tuple[np.ndarray, np.ndarray]:
        t = self.k * self.dt
        if not self.position:
            return self.vib0.copy(), gravity_integral_i0(t, self.lat, self.g, False)
        s_i0 = gravity_integral_i0(t, self.lat, self.g, True)
        return (self.sib0 - (t / self.stt) * self.sty_b, s_i0 - (t / self.stt) * self.sty_i)

    def solve(self) -> np.ndarray:
        """C_b^n at the end of the window."""
        if self.k < self.n:
            raise ValueError("coarse alignment window not complete")
        t2 = self.n * self.dt
        a_b, a_i0 = self._vectors()
        c_ib0_i0 = triad(a_i0, self.v1_i0) @ triad(a_b, self.v1).T
        return earth_rotation_i0_n(t2, self.lat).T @ c_ib0_i0 @ q2dcm(self.q)
