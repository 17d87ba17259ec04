"""ENU strapdown mechanization from increments (reference for nav/strapdown.hpp).

Per sample k (interval dt, increments dtheta_k, dv_k):

- coning: phi_k = dtheta_k + (1/12) dtheta_{k-1} x dtheta_k (one-plus-previous-sample
  rotation vector, Savage 1998 eq. 7.1.1.1-11 form);
- sculling: dv_sf^b = dv_k + 1/2 dtheta_k x dv_k
  + (1/12)(dtheta_{k-1} x dv_k + dv_{k-1} x dtheta_k);
- velocity: v_k = v_{k-1} + (I - 1/2 [w_in^n dt x]) C_b^n(k-1) dv_sf^b
  + (g^n - (2 w_ie^n + w_en^n) x v_{k-1}) dt;
- position (lat, lon, h) by the trapezoid of v; attitude
  q_k = q(-w_in^n dt) (x) q_{k-1} (x) q(phi_k), renormalised.

Earth quantities are taken at the start of the sample.
"""

from __future__ import annotations

import numpy as np

from gyrodrift.nav.attitude import q2dcm, qmul, qnormalize, rv2q
from gyrodrift.nav.earth import earth_params

__all__ = [
    "Strapdown",
]


class Strapdown:
    """Strapdown attitude, velocity and position update (two-sample coning and sculling), the
    reference of nav/strapdown.hpp.

    Examples
    --------
    >>> sd = Strapdown(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), 0.5, 0.0, 0.0)
    >>> dvn = sd.step(np.zeros(3), np.array([0.0, 0.0, 9.8 * 0.01]), 0.01)  # level, at rest
    >>> dvn.round(6) + 0.0, sd.vn.round(6) + 0.0  # gravity 9.7922 m/s^2 here: 7.8e-5 m/s left
    (array([0.   , 0.   , 0.098]), array([0.0e+00, 0.0e+00, 7.8e-05]))
    """
    def __init__(self, q_nb: np.ndarray, vn_m_s: np.ndarray, lat_rad: float, lon_rad: float,
                 h_m: float) -> None:
        self.q = np.array(q_nb, dtype=float)
        self.vn = np.array(vn_m_s, dtype=float)
        self.pos = np.array([lat_rad, lon_rad, h_m], dtype=float)
        self.prev_dtheta = np.zeros(3)
        self.prev_dv = np.zeros(3)
        self.have_prev = False

    def step(self, dtheta: np.ndarray, dv: np.ndarray, dt_s: float) -> np.ndarray:
        """One sample; returns the specific-force velocity increment in n (for the KF's f^n)."""
        ep = earth_params(self.pos[0], self.pos[2], self.vn)
        pt = self.prev_dtheta if self.have_prev else np.zeros(3)
        pv = self.prev_dv if self.have_prev else np.zeros(3)
        phi = dtheta + np.cross(pt, dtheta) / 12.0
        dv_sf_b = dv + 0.5 * np.cross(dtheta, dv) + (np.cross(pt, dv) + np.cross(pv, dtheta)) / 12.0
        cnb = q2dcm(self.q)
        dvn = cnb @ dv_sf_b
        dvn = dvn - 0.5 * np.cross(ep.wnin * dt_s, dvn)
        v_new = self.vn + dvn + (ep.gn - np.cross(2.0 * ep.wnie + ep.wnen, self.vn)) * dt_s
        vm = 0.5 * (self.vn + v_new)
        self.pos = self.pos + np.array([vm[1] / ep.rm_h_m,
                                        vm[0] / (ep.rn_h_m * np.cos(self.pos[0])),
                                        vm[2]]) * dt_s
        self.vn = v_new
        self.q = qnormalize(qmul(rv2q(-ep.wnin * dt_s), qmul(self.q, rv2q(phi))))
        self.prev_dtheta = np.array(dtheta, dtype=float)
        self.prev_dv = np.array(dv, dtype=float)
        self.have_prev = True
        return dvn
