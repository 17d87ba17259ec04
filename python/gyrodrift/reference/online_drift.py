"""numpy reference of the online drift-model identifier
(include/gyrodrift/filters/online_drift_identifier.hpp).

Model: x_k = a1 x_{k-1} + a2 x_{k-2} + w_k (var q), y_k = mean + x_k + v_k (var r).
Recursive prediction error (Ljung & Soderstrom 1983, recursive Gauss-Newton) on the exact
Kalman innovations, written from the equations with 2x2 matrices:

- theta = (u1, u2, log q, log r), a2 = tanh(u2), a1 = tanh(u1) (1 - a2);
- per sample: d = y - running mean; four Kalman filters (theta and theta + delta e_j for
  u1, u2, log q; delta = 2^-10) in prediction form, X- = A (X- + K e), P- = A (I - K H) P- A^T + Q
  with the stationary start P = the solution of the Lyapunov equation (scipy); the
  sensitivities psi_j = (e_j - e) / delta, phi_j = (F_j - F) / delta, and for log r
  psi = -psi_logq, phi = F - phi_logq (q and r scaled together leave the gain unchanged);
  the gradient g_j = e psi_j / F + phi_j (1 - e^2 / F) / (2 F) and the information
  h_jk = psi_j psi_k / F + phi_j phi_k / (2 F^2) summed over the block;
- per block: gamma from the start-up schedule lambda_1 = lambda_start,
  lambda_k = rho lambda_{k-1} + 1 - rho (rho = 1 - 1/warmup_blocks),
  gamma_k = gamma_{k-1} / (gamma_{k-1} + lambda_k) (1/k with warmup_blocks = 0), at least
  1/memory_blocks; R += max(gamma, 1/info_blocks) (H / B - R);
  step = -gamma (R + 2^-16 diag R)^-1 G / B
  (numpy.linalg.solve), scaled as a whole to max_step, theta clipped to its bounds; the held
  parameters (u2 with ar_order 1, u1 and u2 with adapt_ar False) keep their values;
- every retune_blocks blocks the guards of the C++ header, the standard errors from
  inv(n_eff R), and the gain of the estimate from scipy.linalg.solve_discrete_are (the exact
  fixed point the C++ core iterates to).

Float64, plain Python loops: an oracle, not the fast path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["OnlineDriftReference", "ReferenceBlock"]

_DELTA = 1.0 / 1024.0
_MAX_U = 5.5
_LOG_VAR_RANGE = 23.0
_MARQUARDT = 1.0 / 65536.0
_PIVOT = 1.0 / 1048576.0
_STATUS = {"learning": 1, "tracking": 2, "not_identified": 3, "fallback": 4}


@dataclass(frozen=True)
class ReferenceBlock:
    """State after one parameter update: samples so far, estimate and in-use model
    (a1, a2, q, r, mean), gain (k0, k1), status code, standard errors (NaN if none).

    Examples
    --------
    >>> b = ReferenceBlock(400, (0.5, 0.0, 1.0, 1.0, 0.0), (0.5, 0.0, 1.0, 1.0, 0.0),
    ...                    (0.3, 0.2), 1, (math.nan,) * 5)
    >>> b.status
    1
    """

    samples: int
    estimate: tuple[float, float, float, float, float]
    in_use: tuple[float, float, float, float, float]
    gain: tuple[float, float]
    status: int
    stderr: tuple[float, float, float, float, float]


def _stationary_cov(a1: float, a2: float, q: float) -> np.ndarray:
    a = np.array([[a1, a2], [1.0, 0.0]])
    return np.asarray(scipy.linalg.solve_discrete_lyapunov(a, np.diag([q, 0.0])))


class _Kf:
    """Kalman filter in prediction form on the drift state [x_k, x_{k-1}] (scalars, for speed:
    x = [x0, x1], P = [[p00, p01], [p01, p11]])."""

    def __init__(self, a1: float, a2: float, q: float) -> None:
        p = _stationary_cov(a1, a2, q)
        self.x0 = self.x1 = 0.0
        self.p00, self.p01, self.p11 = float(p[0, 0]), float(p[0, 1]), float(p[1, 1])

    def step(self, a1: float, a2: float, q: float, r: float, d: float) -> tuple[float, float]:
        p00, p01, p11 = self.p00, self.p01, self.p11
        f = p00 + r
        e = d - self.x0
        k0, k1 = p00 / f, p01 / f
        u0, u1 = self.x0 + k0 * e, self.x1 + k1 * e
        self.x0, self.x1 = a1 * u0 + a2 * u1, u0
        # Joseph form (I - K H) P (I - K H)^T + r K K^T, H = [1, 0].
        g = 1.0 - k0
        j00, j01 = g * p00, g * p01
        j10, j11 = p01 - k1 * p00, p11 - k1 * p01
        f00 = j00 * g + r * k0 * k0
        f01 = j01 - j00 * k1 + r * k0 * k1
        f11 = j11 - j10 * k1 + r * k1 * k1
        # A Pf A^T + diag(q, 0), A = [[a1, a2], [1, 0]].
        self.p00 = a1 * (a1 * f00 + a2 * f01) + a2 * (a1 * f01 + a2 * f11) + q
        self.p01 = a1 * f00 + a2 * f01
        self.p11 = f00
        return e, f


class OnlineDriftReference:
    """Online identifier of the drift model, the oracle of the C++ core.

    Parameters
    ----------
    a1, a2, q, r, mean : float
        The configured model (start and fallback); q, r in (record units)^2.
    block_samples, retune_blocks, min_samples, memory_blocks, max_step, max_rel_stderr,
    max_innovation_ratio, ar_order
        As OnlineDriftSettings in the C++ header.

    Examples
    --------
    >>> import numpy as np
    >>> ref = OnlineDriftReference(0.5, 0.0, 1.0, 1.0, 0.0, block_samples=50,
    ...                            retune_blocks=2, min_samples=100)
    >>> blocks = ref.push(np.random.default_rng(0).normal(size=200))
    >>> len(blocks), blocks[-1].samples
    (4, 200)
    """

    def __init__(self, a1: float, a2: float, q: float, r: float, mean: float, *,
                 block_samples: int = 400, retune_blocks: int = 60, min_samples: int = 240000,
                 memory_blocks: float = 0.0, max_step: float = 0.1, max_rel_stderr: float = 0.5,
                 max_innovation_ratio: float = 3.0, ar_order: int = 2,
                 warmup_blocks: float = 50.0, lambda_start: float = 0.7,
                 adapt_ar: bool = True, info_blocks: float = 50.0,
                 min_ar_wald: float = 25.0) -> None:
        self.configured = (a1, a2, q, r, mean)
        self.block_samples = block_samples
        self.retune_blocks = retune_blocks
        self.min_samples = min_samples
        self.memory_blocks = memory_blocks
        self.max_step = max_step
        self.max_rel_stderr = max_rel_stderr
        self.max_innovation_ratio = max_innovation_ratio
        self.ar_order = ar_order
        self.warmup_blocks = warmup_blocks
        self.info_blocks = info_blocks
        self.min_ar_wald = min_ar_wald
        self.lambda_start = lambda_start
        self.free = (adapt_ar, adapt_ar and ar_order == 2, True, True)
        self.lam = 1.0
        self.gamma = 1.0
        self.cgain = self._dare_gain(a1, a2, q, r)
        self.log_var0 = math.log(q + r)
        q0 = q if q > 0 else 1e-6 * r
        self.theta = np.array([
            min(max(math.atanh(a1 / (1.0 - a2)), -_MAX_U), _MAX_U),
            min(max(math.atanh(a2), -_MAX_U), _MAX_U) if ar_order == 2 else 0.0,
            math.log(q0), math.log(r)])
        self._set_params()
        if q > 0:  # exactly the configured model until the first update
            self.params = (a1, a2, q, r)
        self.mean = mean
        self.in_use = self.configured
        self.gain = self.cgain
        self.status = _STATUS["learning"]
        self.samples = 0
        self.rejected = 0
        self.blocks = 0
        self.retunes = 0
        self.refused_retunes = 0
        self.in_block = 0
        self.g = [0.0] * 4
        self.h = [[0.0] * 4 for _ in range(4)]
        self.r_info = np.zeros((4, 4))
        self.nis = 0.0
        a1e, a2e, qe, _ = self.params
        self.filters = [_Kf(a1e, a2e, qe), _Kf(self.a1_u1, a2e, qe),
                        _Kf(self.a1_u2, self.a2_u2, qe), _Kf(a1e, a2e, self.q_lq)]

    @staticmethod
    def _dare_gain(a1: float, a2: float, q: float, r: float) -> tuple[float, float]:
        a = np.array([[a1, a2], [1.0, 0.0]])
        h = np.array([[1.0], [0.0]])
        # Predicted covariance: the filtering DARE of (A^T, H) (duality).
        p = scipy.linalg.solve_discrete_are(a.T, h, np.diag([q, 0.0]), np.array([[r]]))
        return float(p[0, 0] / (p[0, 0] + r)), float(p[1, 0] / (p[0, 0] + r))

    def _set_params(self) -> None:
        u1, u2, lq, lr = self.theta
        a2 = math.tanh(u2) if self.ar_order == 2 else 0.0
        self.params = (math.tanh(u1) * (1.0 - a2), a2, math.exp(lq), math.exp(lr))
        self.a1_u1 = math.tanh(u1 + _DELTA) * (1.0 - a2)
        self.a2_u2 = math.tanh(u2 + _DELTA)
        self.a1_u2 = math.tanh(u1) * (1.0 - self.a2_u2)
        self.q_lq = math.exp(lq + _DELTA)

    @property
    def estimate(self) -> tuple[float, float, float, float, float]:
        """(a1, a2, q, r, mean) of the running estimate."""
        return (*self.params, self.mean)

    def _mean_count(self) -> float:
        cap = self.memory_blocks * self.block_samples
        return cap if 0 < cap < self.samples else float(self.samples)

    def _mask(self, m: np.ndarray) -> np.ndarray:
        m = m.copy()
        for j in range(2):
            if not self.free[j]:
                m[j, :] = 0.0
                m[:, j] = 0.0
                m[j, j] = 1.0
        return m

    def _positive_definite(self, m: np.ndarray) -> bool:
        """Cholesky pivots above 2^-20 of their diagonal entries (as the C++ core)."""
        piv = np.diag(np.linalg.cholesky(m)) ** 2 if np.all(np.isfinite(m)) else None
        if piv is None or not np.all(np.isfinite(piv)):
            return False
        return bool(np.all(piv > _PIVOT * np.diag(self._mask(self.r_info))))

    def theta_covariance(self) -> np.ndarray | None:
        """Covariance of theta, inv(n_eff R); None if R is not positive definite."""
        if self.blocks == 0:
            return None
        m = self._mask(self.r_info)
        try:
            if not self._positive_definite(m):
                return None
        except np.linalg.LinAlgError:
            return None
        nb = float(self.blocks)
        if self.memory_blocks > 0:
            nb = min(nb, 2.0 * self.memory_blocks - 1.0)
        cov = np.linalg.inv(m) / (nb * self.block_samples)
        for j in range(2):
            if not self.free[j]:
                cov[j, :] = 0.0
                cov[:, j] = 0.0
        return np.asarray(cov)

    def stderrs(self) -> tuple[float, float, float, float, float] | None:
        """Standard errors (a1, a2, q, r, mean), or None."""
        cov = self.theta_covariance()
        if cov is None:
            return None
        a1, a2, q, r = self.params
        p1 = math.tanh(self.theta[0])
        jac = np.array([[(1 - p1 * p1) * (1 - a2), -p1 * (1 - a2 * a2)], [0.0, 1 - a2 * a2]])
        ca = jac @ cov[:2, :2] @ jac.T
        s = 1.0 - a1 - a2
        return (math.sqrt(max(ca[0, 0], 0.0)), math.sqrt(max(ca[1, 1], 0.0)),
                q * math.sqrt(cov[2, 2]), r * math.sqrt(cov[3, 3]),
                math.sqrt((q / (s * s) + r) / self._mean_count()))

    def push(self, y: object) -> list[ReferenceBlock]:
        """Push samples; returns the state after each block completed (as the binding)."""
        out = []
        for v in np.asarray(y, dtype=np.float64):
            if self._push_one(float(v)):
                se = self.stderrs()
                out.append(ReferenceBlock(self.samples, self.estimate, self.in_use, self.gain,
                                          self.status, se if se is not None else (math.nan,) * 5))
        return out

    def _push_one(self, y: float) -> bool:
        if not math.isfinite(y):
            self.rejected += 1
            return False
        self.samples += 1
        if self.samples == 1:
            self.mean = y
        d = y - self.mean
        self.mean += d / self._mean_count()
        a1, a2, q, r = self.params
        e, f = self.filters[0].step(a1, a2, q, r, d)
        if self.free[0]:
            e1, f1 = self.filters[1].step(self.a1_u1, a2, q, r, d)
        else:
            e1, f1 = e, f
        if self.free[1]:
            e2, f2 = self.filters[2].step(self.a1_u2, self.a2_u2, q, r, d)
        else:
            e2, f2 = e, f
        e3, f3 = self.filters[3].step(a1, a2, self.q_lq, r, d)
        psi = ((e1 - e) / _DELTA, (e2 - e) / _DELTA, (e3 - e) / _DELTA, -(e3 - e) / _DELTA)
        phi = ((f1 - f) / _DELTA, (f2 - f) / _DELTA, (f3 - f) / _DELTA, f - (f3 - f) / _DELTA)
        w = (1.0 - e * e / f) / (2.0 * f)
        g, h = self.g, self.h
        for j in range(4):
            g[j] += e * psi[j] / f + phi[j] * w
            for i in range(4):
                h[i][j] += psi[i] * psi[j] / f + phi[i] * phi[j] / (2.0 * f * f)
        self.nis += e * e / f
        self.in_block += 1
        if self.in_block == self.block_samples:
            self._end_block()
            return True
        return False

    def _end_block(self) -> None:
        self.in_block = 0
        self.blocks += 1
        b = float(self.block_samples)
        if self.blocks == 1:
            self.lam, gamma = self.lambda_start, 1.0
        elif self.warmup_blocks > 0:
            rho = 1.0 - 1.0 / self.warmup_blocks
            self.lam = rho * self.lam + (1.0 - rho)
            gamma = self.gamma / (self.gamma + self.lam)
        else:
            gamma = 1.0 / self.blocks
        self.gamma = gamma
        if self.memory_blocks > 0:
            gamma = max(gamma, 1.0 / self.memory_blocks)
        gamma_r = max(gamma, 1.0 / self.info_blocks) if self.info_blocks > 0 else gamma
        self.r_info += gamma_r * (np.array(self.h) / b - self.r_info)
        gb = np.array(self.g) / b
        for j in range(2):
            if not self.free[j]:
                gb[j] = 0.0
        m = self._mask(self.r_info)
        m = m + _MARQUARDT * np.diag(np.diag(m))
        ok = bool(np.all(np.isfinite(m)))
        if ok:
            try:
                piv = np.diag(np.linalg.cholesky(m)) ** 2
                ok = bool(np.all(piv > _PIVOT * np.diag(self._mask(self.r_info))))
            except np.linalg.LinAlgError:
                ok = False
        if ok:
            step = -gamma * np.linalg.solve(m, gb)
            big = float(np.max(np.abs(step)))
            if big > self.max_step:
                step = step * (self.max_step / big)
            if np.all(np.isfinite(step)):
                lo, hi = self.log_var0 - _LOG_VAR_RANGE, self.log_var0 + _LOG_VAR_RANGE
                th = np.where(self.free, self.theta + step, self.theta)
                self.theta = np.array([np.clip(th[0], -_MAX_U, _MAX_U),
                                       np.clip(th[1], -_MAX_U, _MAX_U),
                                       np.clip(th[2], lo, hi), np.clip(th[3], lo, hi)])
                self._set_params()
        self.g = [0.0] * 4
        self.h = [[0.0] * 4 for _ in range(4)]
        if self.blocks % self.retune_blocks == 0:
            self._retune()

    def _at_bound(self) -> bool:
        lo, hi = self.log_var0 - _LOG_VAR_RANGE, self.log_var0 + _LOG_VAR_RANGE
        u1, u2, lq, lr = self.theta
        return bool(abs(u1) >= _MAX_U or abs(u2) >= _MAX_U or not lo < lq < hi or not lo < lr < hi)

    def _refuse(self, why: str) -> None:
        self.refused_retunes += 1
        self.status = _STATUS[why]
        self.in_use = self.configured
        self.gain = self.cgain

    def _retune(self) -> None:
        nis = self.nis / (self.retune_blocks * self.block_samples)
        self.nis = 0.0
        if self.samples < self.min_samples:
            self.status = _STATUS["learning"]
            return
        a1, a2, q, r = self.params
        stationary = a2 < 1 and a2 - a1 < 1 and a2 + a1 < 1 and a2 > -1
        cov = self.theta_covariance()
        ratio = self.max_innovation_ratio
        if (not stationary or self._at_bound() or cov is None or not math.isfinite(nis)
                or not 1.0 / ratio <= nis <= ratio):
            self._refuse("fallback")
            return
        free = [j for j in range(2) if self.free[j]]
        if free:
            u = self.theta[free]
            cu = cov[np.ix_(free, free)]
            wald = float(u @ np.linalg.solve(cu, u)) if np.linalg.det(cu) > 0 else 0.0
        else:
            wald = math.inf
        lim = self.max_rel_stderr
        if not (math.sqrt(cov[2, 2]) <= lim and math.sqrt(cov[3, 3]) <= lim
                and wald >= self.min_ar_wald):
            self._refuse("not_identified")
            return
        self.in_use = self.estimate
        self.gain = self._dare_gain(a1, a2, q, r)
        self.retunes += 1
        self.status = _STATUS["tracking"]
