"""Fine-alignment Kalman filter with zero-velocity measurements (reference for
nav/fine_align_kf.hpp).

States (psi-angle ENU error model, Savage / Yan Gongmin PSINS "Ft" form), 15 states::

  x = [phi (3, rad), dv^n (3, m/s), dp (3, ENU metres), eps^b (3, gyro drift rad/s),
       nabla^b (3, accelerometer bias m/s^2)];

12 states drop dp. With w_in = w_ie + w_en, R_M/R_N + h, f^n the specific force::

  phi'  = -[w_in x] phi + M_av dv + M_ap dp - C_b^n eps
  dv'   = [f^n x] phi - [(2 w_ie + w_en) x] dv + M_vp dp + C_b^n nabla
  dp'   = dv;  eps' = 0;  nabla' = 0   (+ white process noise)
  M_av: d w_en / d v = [[0, -1/RM, 0], [1/RN, 0, 0], [tanL/RN, 0, 0]];
  M_ap: d w_ie / d pN = [0, -W sinL, W cosL]/RM (north-position column);
  M_vp: d g_U / d h = +3.086e-6 /s^2 (Up/Up element), the free-air gradient of the gravity model.

Discretisation over the update interval T: Phi = I + F T + (F T)^2 / 2,
Q_k = (Phi Q Phi^T + Q) T / 2 (trapezoid), Q = diag(q).
Update (z = v^n, H = [0 I 0 ...]): S = H P H^T + R (Cholesky solve, no explicit inverse),
K = P H^T S^-1 (the papers' (C P + R)^-1 is the known erratum), Joseph form
P = (I - K H) P (I - K H)^T + K R K^T, then symmetrised and its diagonal floored.
The state is zero before each update (full feedback after it), so x = K z.
"""

from __future__ import annotations

import numpy as np

from gyrodrift.nav.attitude import skew
from gyrodrift.nav.earth import EARTH_RATE_RAD_S, GRAVITY_DH_PER_S2, EarthParams

__all__ = [
    "FineAlignKF",
]


class FineAlignKF:
    """The fine-alignment Kalman filter (12 or 15 states: attitude, velocity, [position], gyro and
    accelerometer biases) with zero-velocity updates.

    Examples
    --------
    >>> kf = FineAlignKF(12, np.ones(12), np.zeros(12), np.full(3, 0.01), np.zeros(12))
    >>> x = kf.update(np.array([0.1, 0.0, 0.0]))  # v^n measured 0.1 m/s east at rest
    >>> x[3:6].round(4), kf.P.shape
    (array([0.099, 0.   , 0.   ]), (12, 12))
    """
    def __init__(self, n_states: int, p0_diag: np.ndarray, q_diag: np.ndarray,
                 r_diag: np.ndarray, p_floor_diag: np.ndarray) -> None:
        if n_states not in (12, 15):
            raise ValueError("n_states must be 12 or 15")
        self.n = n_states
        self.i_eb = 9 if n_states == 15 else 6
        self.i_db = self.i_eb + 3
        self.P = np.diag(np.asarray(p0_diag, dtype=float))
        self.q = np.asarray(q_diag, dtype=float)
        self.R = np.diag(np.asarray(r_diag, dtype=float))
        self.floor = np.asarray(p_floor_diag, dtype=float)
        self.x = np.zeros(n_states)

    def transition(self, cnb: np.ndarray, fn: np.ndarray, vn: np.ndarray, ep: EarthParams,
                   lat_rad: float) -> np.ndarray:
        n = self.n
        f = np.zeros((n, n))
        f[0:3, 0:3] = -skew(ep.wnin)
        f[0:3, 3:6] = np.array([[0.0, -1.0 / ep.rm_h_m, 0.0], [1.0 / ep.rn_h_m, 0.0, 0.0],
                                [ep.tan_lat / ep.rn_h_m, 0.0, 0.0]])
        f[0:3, self.i_eb:self.i_eb + 3] = -cnb
        f[3:6, 0:3] = skew(fn)
        f[3:6, 3:6] = -skew(2.0 * ep.wnie + ep.wnen)
        f[3:6, self.i_db:self.i_db + 3] = cnb
        if n == 15:
            f[1, 7] = -EARTH_RATE_RAD_S * np.sin(lat_rad) / ep.rm_h_m
            f[2, 7] = EARTH_RATE_RAD_S * np.cos(lat_rad) / ep.rm_h_m
            f[5, 8] = GRAVITY_DH_PER_S2
            f[6:9, 3:6] = np.eye(3)
        del vn  # the -[w x] v terms of the error model vanish at the near-zero velocity
        return f

    def predict(self, f: np.ndarray, t_s: float) -> None:
        ft = f * t_s
        phi = np.eye(self.n) + ft + 0.5 * ft @ ft
        q = np.diag(self.q)
        qk = 0.5 * (phi @ q @ phi.T + q) * t_s
        self.P = phi @ self.P @ phi.T + qk
        self._hygiene()

    def update(self, z: np.ndarray) -> np.ndarray:
        """Zero-velocity update with z = v^n (m/s); returns the state estimate (to feed back)."""
        p = self.P
        s = p[3:6, 3:6] + self.R
        # K^T = S^-1 H P via Cholesky: S = L L^T.
        chol = np.linalg.cholesky(s)
        kt = np.linalg.solve(chol.T, np.linalg.solve(chol, p[3:6, :]))
        k = kt.T
        a = np.eye(self.n)
        a[:, 3:6] -= k
        self.P = a @ p @ a.T + k @ self.R @ k.T
        self._hygiene()
        self.x = k @ z
        return self.x

    def _hygiene(self) -> None:
        self.P = 0.5 * (self.P + self.P.T)
        d = np.diag(self.P)
        low = d < self.floor
        if np.any(low):
            idx = np.nonzero(low)[0]
            self.P[idx, idx] = self.floor[idx]
