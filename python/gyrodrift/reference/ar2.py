"""numpy references for AR(2) identification, the AR filter and the AR(2)-Kalman filters.

Written straight from the equations (papers 000 and 002; see include/gyrodrift/filters/ar2_*.hpp)
with plain loops where the equations recurse. They are the test oracles of the C++ core, not the
fast path. All arithmetic is float64.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import scipy.linalg

from gyrodrift.filters.ar2 import (
    MIN_SAMPLES,
    Ar2FitError,
    Ar2Model,
    is_stationary,
    normalise_method,
)

__all__ = ["ar_filter", "fit_ar2", "kalman_filter", "steady_state_gain"]


def _as_record(x: object) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"expected a 1-D record, got shape {a.shape}")
    return a


def fit_ar2(x: object, method: str = "yule-walker") -> Ar2Model:
    """AR(2) fit of a 1-D record: mean removed first and kept in the model.

    yule-walker: biased autocovariances c_k = (1/n) sum (x_i - m)(x_{i-k} - m), then
    [[c0, c1], [c1, c0]] a = [c1, c2], sigma2 = c0 - a . [c1, c2].
    burg: order-2 Burg recursion on explicit forward/backward error arrays.
    ls: forward-backward least squares (stacked design matrix, numpy lstsq),
    sigma2 = residual sum of squares / (2 (n - 2)).
    r (all methods): mean squared one-step prediction error of the fitted model on x.

    Examples
    --------
    >>> import scipy.signal
    >>> e = np.random.default_rng(0).standard_normal(20_000)
    >>> x = scipy.signal.lfilter([1.0], [1.0, -0.5], e)
    >>> round(fit_ar2(x).a1, 1)
    0.5
    """
    method = normalise_method(method)
    y = _as_record(x)
    n = y.size
    if n < MIN_SAMPLES:
        raise Ar2FitError("too_short", f"{n} samples, at least {MIN_SAMPLES} needed")
    if not np.all(np.isfinite(y)):
        raise Ar2FitError("non_finite", f"NaN/Inf at index {int(np.argmin(np.isfinite(y)))}")
    if np.all(y == y[0]):
        raise Ar2FitError("constant", "all samples are equal")
    mean = float(np.mean(y))
    d = y - mean
    if method == "yule-walker":
        c = np.array([d[k:] @ d[: n - k] for k in range(3)]) / n
        toeplitz = np.array([[c[0], c[1]], [c[1], c[0]]])
        a = np.linalg.solve(toeplitz, c[1:])
        sigma2 = float(c[0] - a @ c[1:])
    elif method == "burg":
        f = d.copy()
        b = d.copy()
        e = float(d @ d) / n
        alpha = np.zeros(0)
        for _ in range(2):
            ff, bb = f[1:], b[:-1]
            k = -2.0 * float(ff @ bb) / float(ff @ ff + bb @ bb)
            f, b = ff + k * bb, bb + k * ff
            # Levinson step on the prediction-error polynomial 1 + alpha_1 z^-1 + ...
            alpha = np.concatenate([alpha + k * alpha[::-1], [k]])
            e *= 1.0 - k * k
        a = -alpha
        sigma2 = e
    else:  # forward-backward least squares
        fwd = np.column_stack([d[1:-1], d[:-2]])
        bwd = np.column_stack([d[1:-1], d[2:]])
        design = np.vstack([fwd, bwd])
        target = np.concatenate([d[2:], d[:-2]])
        a, *_ = np.linalg.lstsq(design, target, rcond=None)
        resid = target - design @ a
        sigma2 = float(resid @ resid) / (2 * (n - 2))
    a1, a2 = float(a[0]), float(a[1])
    if not is_stationary(a1, a2):
        raise Ar2FitError(
            "non_stationary", f"a1={a1:.6g}, a2={a2:.6g} has a root on/outside the unit circle"
        )
    e1 = d[2:] - a1 * d[1:-1] - a2 * d[:-2]
    r = float(e1 @ e1) / (n - 2)
    return Ar2Model(a1=a1, a2=a2, sigma2=max(sigma2, 0.0), mean=mean, method=method, n=n, r=r)


def ar_filter(x: object, model: Ar2Model) -> np.ndarray:
    """Paper 000 sec. 2.1: out_k = y_k - r_k = m + a1 (y_{k-1} - m) + a2 (y_{k-2} - m).

    History before the first sample is the mean; a NaN/Inf sample is replaced in the history
    by its own prediction.

    Examples
    --------
    >>> ar_filter(np.array([1.0, 2.0, 3.0]), Ar2Model(0.5, 0.0, 1.0)).shape
    (3,)
    """
    y = _as_record(x)
    out = np.empty_like(y)
    d1 = d2 = 0.0
    for k, yk in enumerate(y):
        pred = model.a1 * d1 + model.a2 * d2
        out[k] = pred + model.mean
        dk = yk - model.mean
        d2, d1 = d1, (dk if math.isfinite(dk) else pred)
    return out


def _matrices(model: Ar2Model, q: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a = np.array([[model.a1, model.a2], [1.0, 0.0]])
    b = np.diag([1.0, 0.0])
    c = np.array([[1.0, 0.0]])
    q_mat = np.diag([q, q])  # papers: Q = diag(sigma^2, sigma^2); B Q B^T = diag(q, 0)
    return a, b @ q_mat @ b.T, c


def kalman_filter(
    x: object,
    model: Ar2Model,
    q: float | None = None,
    r: float | None = None,
    steady_state: bool = False,
    p0: float = 1.0,
) -> np.ndarray:
    """AR(2)-Kalman filter of a 1-D record, matrix form of papers 000/002 with the C^T erratum
    fixed and the Joseph covariance update; q defaults to model.sigma2, r to model.r
    (model.sigma2 when r is unknown).

    NaN/Inf samples are predict-only steps (as in the C++ filter).

    Examples
    --------
    >>> kalman_filter(np.zeros(5), Ar2Model(0.5, 0.0, 1.0), q=1.0, r=1.0).tolist()
    [0.0, 0.0, 0.0, 0.0, 0.0]
    """
    y = _as_record(x)
    q = model.sigma2 if q is None else float(q)
    if r is None:  # model.r when known, else sigma2 (duck-typed models welcome)
        r_model = float(getattr(model, "r", math.nan))
        r = r_model if math.isfinite(r_model) and r_model > 0 else model.sigma2
    r = float(r)
    a, bqb, c = _matrices(model, q)
    eye = np.eye(2)
    state = np.zeros((2, 1))
    p = p0 * np.eye(2)
    gain_ss = steady_state_gain(model, q, r).reshape(2, 1) if steady_state else None
    out = np.empty_like(y)
    for k, yk in enumerate(y):
        z = yk - model.mean
        state = a @ state
        if gain_ss is not None:
            if math.isfinite(z):
                state = state + gain_ss * (z - (c @ state).item())
            out[k] = state[0, 0] + model.mean
            continue
        p = a @ p @ a.T + bqb
        if math.isfinite(z):
            s = (c @ p @ c.T).item() + r
            gain = p @ c.T / s
            state = state + gain * (z - (c @ state).item())
            ikc = eye - gain @ c
            p = ikc @ p @ ikc.T + r * (gain @ gain.T)
        out[k] = state[0, 0] + model.mean
    return out


def steady_state_gain(model: Ar2Model, q: float, r: float) -> np.ndarray:
    """Gain of the stabilising DARE solution (scipy.linalg.solve_discrete_are, an independent
    solver): P = A P A^T + Q - A P C^T (C P C^T + r)^-1 C P A^T, K = P C^T / (C P C^T + r).

    Examples
    --------
    >>> k = steady_state_gain(Ar2Model(0.5, 0.0, 1.0), 1.0, 1.0)
    >>> bool(0.0 < k[0] < 1.0)
    True
    """
    a, bqb, c = _matrices(model, q)
    p = scipy.linalg.solve_discrete_are(a.T, c.T, bqb, np.array([[r]]))
    return (p @ c.T / ((c @ p @ c.T).item() + r)).ravel()


def fit_ar2_axes(x: object, method: str = "yule-walker") -> Sequence[Ar2Model]:
    """fit_ar2 per column of an (n, axes) record.

    Examples
    --------
    >>> x = np.random.default_rng(1).standard_normal((1000, 3))
    >>> len(fit_ar2_axes(x))
    3
    """
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"expected an (n, axes) record, got shape {a.shape}")
    return tuple(fit_ar2(a[:, i], method) for i in range(a.shape[1]))
