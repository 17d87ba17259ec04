"""numpy reference of the drift-model log-likelihood
(include/gyrodrift/filters/drift_likelihood.hpp).

Model: x_k = a1 x_{k-1} + a2 x_{k-2} + w_k (var q), y_k = mean + x_k + v_k (var r).
Written straight from the state-space equations with 2x2 matrices and a plain loop: the
stationary initial covariance from the Lyapunov equation P = A P A^T + Q solved by
scipy.linalg.solve_discrete_lyapunov (not the closed form the C++ core uses), then the Kalman
filter's prediction-error decomposition (Harvey 1989 eq. 3.4.7)::

    log L = -1/2 sum_k (log 2 pi + log F_k + e_k^2 / F_k).

Float64 throughout; an oracle, not the fast path.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

__all__ = ["drift_loglike"]


def drift_loglike(
    y: object, a1: float, a2: float, q: float, r: float, mean: float
) -> tuple[float, np.ndarray]:
    """Exact Gaussian log-likelihood of a 1-D record and its standardised innovations.

    Examples
    --------
    >>> import numpy as np
    >>> ll, e = drift_loglike(np.array([0.1, -0.2, 0.3]), 0.0, 0.0, 0.0, 1.0, 0.0)
    >>> bool(abs(ll - (-1.5 * np.log(2 * np.pi) - 0.5 * 0.14)) < 1e-12)
    True
    """
    z = np.asarray(y, dtype=np.float64) - float(mean)
    if z.ndim != 1 or z.size == 0:
        raise ValueError(f"expected a non-empty 1-D record, got shape {z.shape}")
    a = np.array([[a1, a2], [1.0, 0.0]])
    qm = np.array([[q, 0.0], [0.0, 0.0]])
    h = np.array([1.0, 0.0])
    p = scipy.linalg.solve_discrete_lyapunov(a, qm)
    x = np.zeros(2)
    ll = 0.0
    innov = np.empty_like(z)
    for k in range(z.size):
        f = float(h @ p @ h) + r
        e = float(z[k] - h @ x)
        ll += -0.5 * (math.log(2.0 * math.pi) + math.log(f) + e * e / f)
        innov[k] = e / math.sqrt(f)
        kg = p @ h / f
        x = x + kg * e
        p = p - np.outer(kg, h @ p)
        x = a @ x
        p = a @ p @ a.T + qm
    return ll, innov
