"""AR(2) drift model identification, AR filter and AR(2)-Kalman filters (C++ core).

Model (paper 000 eq. 1, paper 002 eq. 1), on the demeaned rate x = y - mean:

    x_k = a1 x_{k-1} + a2 x_{k-2} + r_k,   r_k ~ (0, sigma2)

AR(2)-Kalman (papers 000 sec. 2.2 / 002 sec. 3): X_k = [x_k, x_{k-1}]^T, A = [[a1, a2], [1, 0]],
B = diag(1, 0), C = [1, 0], process variance q, measurement variance r, P0 = p0 I, X0 = 0,
gain K = P C^T (C P C^T + r)^-1 (the papers print (C P + R)^-1: erratum), Joseph update.

Defaults, as the papers choose them: q = model.sigma2 (the AR(2) driving-noise variance) and
r = model.r, "the variance of the AR(2) estimation error", taken as the mean squared one-step
prediction error of the fitted model on the fitting record. Both are in (units of y)^2.
With q = r the steady-state gain on white-like drift is about 0.5 (half the STD); raise r (or
lower q) for more smoothing at the cost of lag and of attenuating true rate changes (dc_gain).

All heavy lifting is in gyrodrift._core (include/gyrodrift/filters/ar2_*.hpp); the numpy oracles
are in gyrodrift.reference.ar2.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError

__all__ = [
    "AR2_METHODS",
    "DEFAULT_AR2_METHOD",
    "MIN_SAMPLES",
    "Ar2FitError",
    "Ar2Model",
    "FilterResult",
    "KalmanFilter",
    "ar_filter",
    "ar_filter_pieces",
    "fit_ar2",
    "fit_ar2_chunks",
    "is_stationary",
    "kalman_filter",
    "kalman_filter_result",
]

#: The AR(2) estimators (``fit_ar2(method=...)``, the command line's ``--ar-method``).
AR2_METHODS: tuple[str, ...] = ("yule-walker", "burg", "ls")
#: The one default AR(2) estimator of the library and of every command.
DEFAULT_AR2_METHOD = "yule-walker"

#: Fewest samples a fit accepts (include/gyrodrift/filters/ar2_model.hpp kAr2MinSamples).
MIN_SAMPLES = 8

_METHODS = {
    "yule-walker": "yule-walker",
    "yule_walker": "yule-walker",
    "yw": "yule-walker",
    "burg": "burg",
    "ls": "ls",
    "least-squares": "ls",
    "least_squares": "ls",
    "fb": "ls",
}

_STATIONARITY_MARGIN = 64 * float(np.finfo(np.float64).eps)

class Ar2FitError(GyrodriftValueError):
    """An AR(2) fit was rejected.

    ``cause`` is the C++ ``Ar2Status`` name returned by the binding: too_short, constant,
    non_finite or non_stationary.

    Examples
    --------
    >>> import numpy as np
    >>> try:
    ...     fit_ar2(np.ones(100))
    ... except Ar2FitError as exc:
    ...     print(exc.cause)
    constant
    """

    def __init__(self, cause: str, detail: str) -> None:
        self.cause = cause
        super().__init__(f"AR(2) fit rejected ({cause.replace('_', '-')}): {detail}")


def normalise_method(method: str) -> str:
    key = str(method).lower()
    if key not in _METHODS:
        raise GyrodriftValueError(
            f"unknown AR(2) method {method!r}; use 'yule-walker', 'burg' or 'ls'")
    return _METHODS[key]


def is_stationary(a1: float, a2: float) -> bool:
    """Both roots of z^2 - a1 z - a2 strictly inside the unit circle (stationarity triangle),
    with the C++ core's margin of 64 eps for "on the circle".

    Examples
    --------
    >>> is_stationary(0.5, 0.1), is_stationary(1.5, 0.0)
    (True, False)
    """
    one = 1.0 - _STATIONARITY_MARGIN
    return (
        math.isfinite(a1)
        and math.isfinite(a2)
        and -one < a2 < one
        and a1 + a2 < one
        and a2 - a1 < one
    )


@dataclass(frozen=True)
class Ar2Model:
    """An identified AR(2) drift model.

    Attributes
    ----------
    a1, a2
        AR coefficients (dimensionless).
    sigma2
        driving-noise variance of the method (Yule-Walker c0 - a.c, Burg final
        prediction-error power, FB-LS residual SS / (2 (n - 2))), (units of y)^2.
    mean
        removed mean (constant drift), units of y.
    method
        "yule-walker", "burg" or "ls".
    n
        number of samples fitted (0 if the model was given by hand).
    r
        variance of the AR(2) estimation (one-step prediction) error on the fitting record,
        (units of y)^2; the Kalman filter's default measurement variance. NaN if unknown
        (then kalman_filter uses sigma2).

    Examples
    --------
    >>> m = Ar2Model(a1=0.5, a2=0.1, sigma2=1.0)
    >>> m.stationary, m.measurement_variance
    (True, 1.0)
    """

    a1: float
    a2: float
    sigma2: float
    mean: float = 0.0
    method: str = "given"
    n: int = 0
    r: float = math.nan

    def __post_init__(self) -> None:
        for name in ("a1", "a2", "sigma2", "mean"):
            if not math.isfinite(float(getattr(self, name))):
                raise GyrodriftValueError(
                    f"Ar2Model.{name} must be finite, got {getattr(self, name)!r}")
        if self.sigma2 < 0:
            raise GyrodriftValueError(f"Ar2Model.sigma2 must be >= 0, got {self.sigma2!r}")

    @property
    def stationary(self) -> bool:
        return is_stationary(self.a1, self.a2)

    @property
    def root_modulus(self) -> float:
        """Largest modulus of the roots of z^2 - a1 z - a2 (< 1 for a stationary model). Yule-Walker
        and Burg always return a stationary model; a trending (ramp, random-walk) record shows
        up as a modulus close to 1, where the drift model and the filter's dc_gain degrade."""
        return float(np.max(np.abs(np.roots([1.0, -self.a1, -self.a2]))))

    @property
    def measurement_variance(self) -> float:
        """Default r of the Kalman filter: self.r, or sigma2 when r is unknown."""
        return self.r if math.isfinite(self.r) and self.r > 0 else self.sigma2



# --------------------------------------------------------------------------- helpers


def _float_array(x: object, name: str, dtype: object = None) -> np.ndarray:
    """A C-contiguous float32/float64 array (no copy when it already is one)."""
    if dtype is not None:
        dt = np.dtype(dtype)  # type: ignore[call-overload]
        if dt not in (np.float32, np.float64):
            raise GyrodriftTypeError(f"dtype must be float32 or float64, got {dt}")
    a = np.asarray(x)
    if a.dtype.kind not in "fiu" or a.dtype == np.float16:
        raise GyrodriftTypeError(
            f"{name} must be a real numeric array (float32/float64 or integers), "
            f"got dtype {a.dtype}"
        )
    if a.ndim == 0:  # np.ascontiguousarray would silently make it 1-D
        raise GyrodriftValueError(f"{name} must be an array of samples, got a scalar (shape ())")
    if a.dtype.kind == "f" and a.dtype.itemsize > 8:
        raise GyrodriftTypeError(
            f"{name}: dtype {a.dtype} is not supported; use float32 or float64")
    if dtype is None:
        dt = a.dtype if a.dtype in (np.float32, np.float64) else np.dtype(np.float64)
    if dt == np.float32 and a.dtype == np.float64:
        from gyrodrift.filters.wavelet import as_core_dtype

        return as_core_dtype(a, dt, what=name)  # a value beyond float32: refused, not Inf
    return np.ascontiguousarray(a, dtype=dt)


_FLOAT32_MAX = float(np.finfo(np.float32).max)
_FLOAT32_TINY = float(np.finfo(np.float32).tiny)


def _check_core_model(settings: Any, dtype: np.dtype, what: str) -> None:
    """Refuse, for the float32 core, a model whose mean or variances float32 cannot hold
    (they would reach the filter as Inf or 0): e.g. a model fitted in float64 to a record in
    units that make its variance 1e66."""
    if dtype != np.float32:
        return
    for name in ("mean", "sigma2", "q", "r"):
        v = float(getattr(settings, name))
        if abs(v) > _FLOAT32_MAX or (name != "mean" and 0.0 < v < _FLOAT32_TINY):
            raise GyrodriftValueError(
                f"{what}: the model's {name} = {v:.3g} is beyond what the float32 core holds "
                f"(from {_FLOAT32_TINY:.2g} to {_FLOAT32_MAX:.2g}); use float64, or scale the "
                "record")


def _check_shape(a: np.ndarray, name: str) -> None:
    if a.ndim == 1 or (a.ndim == 2 and a.shape[1] == 3):
        if a.shape[0] == 0:
            raise GyrodriftValueError(f"{name} is empty")
        return
    raise GyrodriftValueError(f"{name} must have shape (n,) or (n, 3), got {a.shape}")


def _models_for(model: Ar2Model | Sequence[Ar2Model], axes: int) -> list[Ar2Model]:
    if isinstance(model, Ar2Model):
        return [model]
    models = list(model)
    if len(models) != axes or not all(isinstance(m, Ar2Model) for m in models):
        raise GyrodriftTypeError(
            f"model must be an Ar2Model or a sequence of {axes} Ar2Model (one per axis)"
        )
    return models


def _variance(value: float | None, default: float, name: str, positive: bool) -> float:
    v = default if value is None else float(value)
    if not math.isfinite(v) or v < 0 or (positive and v == 0):
        bound = "> 0" if positive else ">= 0"
        raise GyrodriftValueError(f"{name} must be finite and {bound}, got {v!r}")
    return v


def _params(m: Ar2Model, q: float | None, r: float | None) -> tuple[float, ...]:
    if not m.stationary:
        raise GyrodriftValueError(f"non-stationary AR(2) model a1={m.a1}, a2={m.a2}")
    qv = _variance(q, m.sigma2, "q", positive=False)
    rv = _variance(r, m.measurement_variance, "r", positive=True)
    return (m.a1, m.a2, m.sigma2, m.mean, qv, rv)


def _settings(m: Ar2Model, q: float | None, r: float | None) -> Any:
    """The bound C++ configuration of one channel (gyrodrift._core.Ar2KalmanSettings)."""
    a1, a2, sigma2, mean, qv, rv = _params(m, q, r)
    return core("ar2").Ar2KalmanSettings(a1=a1, a2=a2, sigma2=sigma2, mean=mean, q=qv, r=rv)


def _report_faults(faults: np.ndarray, what: str) -> None:
    total = int(np.sum(faults))
    if total:
        warnings.warn(
            f"{what}: {total} non-finite or out-of-range sample(s) (per axis {faults.tolist()}) "
            "were replaced "
            "by the filter's prediction",
            RuntimeWarning,
            stacklevel=3,
        )


# --------------------------------------------------------------------------- public API


def fit_ar2(
    x: object, method: str = DEFAULT_AR2_METHOD, dtype: object = np.float64
) -> Ar2Model | tuple[Ar2Model, ...]:
    """Identify an AR(2) model (C++ core) from a record of shape (n,) or (n, 3).

    dtype: computation dtype, float64 (default, whatever the input dtype) or float32 (the
    on-target firmware arithmetic; ~1e-4 relative accuracy on 1e4-1e5 samples).

    method: "yule-walker" (biased autocovariances, = statsmodels yule_walker(method="mle")),
    "burg", or "ls" (forward-backward least squares, MATLAB `ar` default). The mean is removed
    first and kept. For (n, 3) input, returns one model per axis.

    Raises
    ------
    Ar2FitError
        (a ValueError) too short (< 8 samples), constant, NaN/Inf, or a
        non-stationary result; the message names the cause.
    TypeError
        non-numeric input.

    Examples
    --------
    >>> import scipy.signal
    >>> e = np.random.default_rng(0).standard_normal(20_000)
    >>> x = scipy.signal.lfilter([1.0], [1.0, -0.6, 0.1], e)  # AR(2): 0.6, -0.1
    >>> m = fit_ar2(x, "burg")
    >>> round(m.a1, 1), round(m.a2, 1)
    (0.6, -0.1)
    """
    name = normalise_method(method)
    a = _float_array(x, "x", dtype)
    if a.ndim == 2 and a.shape[1] == 3:
        return tuple(fit_ar2(a[:, i], name, dtype) for i in range(3))  # type: ignore[misc]
    if a.ndim != 1:
        raise GyrodriftValueError(f"x must have shape (n,) or (n, 3), got {a.shape}")
    lib = core("ar2")
    cpp_method = {
        "yule-walker": lib.Ar2Method.yule_walker,
        "burg": lib.Ar2Method.burg,
        "ls": lib.Ar2Method.least_squares,
    }[name]
    status, a1, a2, sigma2, mean, r = lib.ar2_fit(a, cpp_method)
    if status != lib.Ar2Status.ok:
        cause = status.name
        detail = {
            "too_short": f"{a.size} samples, at least {MIN_SAMPLES} needed",
            "constant": "all samples are equal",
            "non_finite": "the record contains NaN or Inf (or values whose sum overflows)",
            "non_stationary": "the fitted model has a root on or outside the unit circle "
            "(or its normal equations are singular)",
        }.get(cause, f"status {cause}")
        raise Ar2FitError(cause, detail)
    return Ar2Model(a1=a1, a2=a2, sigma2=sigma2, mean=mean, method=name, n=int(a.size), r=r)


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    # einsum, not the BLAS dot: BLAS starts threads, many times slower on a loaded machine
    return float(np.einsum("i,i->", a, b))


def _lagged(chunks: Iterable[np.ndarray], mean: float) -> Iterator[tuple[np.ndarray, ...]]:
    """(x_i, x_{i-1}, x_{i-2}) of the demeaned record over consecutive pieces: the indices
    i >= 0, i >= 1 and i >= 2 of each piece, the previous piece's last two samples carried."""
    tail = np.empty(0)
    for p in chunks:
        d = np.concatenate([tail, np.asarray(p, dtype=np.float64) - mean])
        t = tail.size
        yield d[t:], d[max(t, 1) - 1:-1], d[max(t, 1):], d[max(t, 2) - 2:-2], d[max(t, 2):], \
            d[max(t, 2) - 1:-1]
        tail = d[-2:]


def fit_ar2_chunks(chunks: Callable[[], Iterable[np.ndarray]],
                   method: str = DEFAULT_AR2_METHOD) -> Ar2Model:
    """`fit_ar2` of a 1-D record given in consecutive pieces, never held whole (float64).

    The formulas, checks and errors of the core's fit (ar2_model.hpp: the mean, then the
    lag sums of Yule-Walker, Burg's two reflection coefficients or the forward-backward
    normal equations, then the one-step prediction-error variance ``r``), each sum taken over
    the pieces with the previous piece's last two samples carried. The sums are numpy's, in
    another order than the core's sequential loop: the parameters agree with `fit_ar2` of
    the whole record to rounding (about 1e-13 relative on 1e6 samples).

    Parameters
    ----------
    chunks
        called once per pass (three or four), returns the record's pieces in order (e.g.
        ``lambda: gyrodrift.io.records.iter_chunks(mm, 1 << 20)``).
    method
        as `fit_ar2`.

    Returns
    -------
    Ar2Model

    Raises
    ------
    Ar2FitError
        as `fit_ar2`.

    Examples
    --------
    >>> x = np.random.default_rng(0).standard_normal(1000)
    >>> m = fit_ar2_chunks(lambda: (x[i:i + 300] for i in range(0, x.size, 300)))
    >>> ref = fit_ar2(x)
    >>> bool(np.isclose(m.a1, ref.a1, rtol=1e-12, atol=0) and np.isclose(m.r, ref.r, rtol=1e-12))
    True
    """
    name = normalise_method(method)
    n, total, first, equal, finite = 0, 0.0, None, True, True
    for p in chunks():
        a = np.asarray(p, dtype=np.float64)
        if a.size == 0:
            continue
        finite = finite and bool(np.all(np.isfinite(a)))
        first = float(a[0]) if first is None else first
        equal = equal and bool(np.all(a == first))
        total += float(np.sum(a))
        n += int(a.size)
    if n < MIN_SAMPLES:
        raise Ar2FitError("too_short", f"{n} samples, at least {MIN_SAMPLES} needed")
    if not finite:
        raise Ar2FitError("non_finite", "the record contains NaN or Inf (or values whose sum "
                          "overflows)")
    if equal:
        raise Ar2FitError("constant", "all samples are equal")
    mean = total / n
    if not math.isfinite(mean):
        raise Ar2FitError("non_finite", "the record contains NaN or Inf (or values whose sum "
                          "overflows)")
    non_stationary = ("non_stationary", "the fitted model has a root on or outside the unit "
                      "circle (or its normal equations are singular)")
    s0 = s1 = s2 = den1 = 0.0
    g00 = g01 = g11 = h0 = h1 = yy = 0.0
    for x0, x1p, x0p, x2, x0q, x1q in _lagged(chunks(), mean):
        # x0: i >= 0; (x1p, x0p): x_{i-1}, x_i for i >= 1; (x2, x1q, x0q): i >= 2
        s0 += _dot(x0, x0)
        s1 += _dot(x0p, x1p)
        s2 += _dot(x0q, x2)
        den1 += _dot(x0p, x0p) + _dot(x1p, x1p)
        if name == "ls":
            g00 += 2.0 * _dot(x1q, x1q)
            g01 += _dot(x1q, x2 + x0q)
            g11 += _dot(x2, x2) + _dot(x0q, x0q)
            h0 += _dot(x1q, x0q + x2)
            h1 += 2.0 * _dot(x0q, x2)
            yy += _dot(x0q, x0q) + _dot(x2, x2)
    if name == "yule-walker":
        c0, c1, c2 = s0 / n, s1 / n, s2 / n
        if not (c0 > 0 and math.isfinite(c0) and math.isfinite(c1) and math.isfinite(c2)):
            raise Ar2FitError("constant", "all samples are equal")
        rho1, rho2 = c1 / c0, c2 / c0
        det = 1.0 - rho1 * rho1
        if not det > 0:
            raise Ar2FitError(*non_stationary)
        a1 = rho1 * (1.0 - rho2) / det
        a2 = (rho2 - rho1 * rho1) / det
        sigma2 = c0 * (1.0 - a1 * rho1 - a2 * rho2)
    elif name == "burg":
        if not den1 > 0:
            raise Ar2FitError("constant", "all samples are equal")
        k1 = -2.0 * s1 / den1
        num2 = den2 = 0.0
        for _x0, _x1p, _x0p, x2, x0q, x1q in _lagged(chunks(), mean):
            f = x0q + k1 * x1q
            b = x2 + k1 * x1q
            num2 += _dot(f, b)
            den2 += _dot(f, f) + _dot(b, b)
        if not den2 > 0:
            raise Ar2FitError(*non_stationary)
        k2 = -2.0 * num2 / den2
        a1, a2 = -(k1 * (1.0 + k2)), -k2
        sigma2 = s0 / n * (1.0 - k1 * k1) * (1.0 - k2 * k2)
    else:
        det = g00 * g11 - g01 * g01
        if not det > float(np.finfo(np.float64).eps) * g00 * g11:
            raise Ar2FitError(*non_stationary)
        a1 = (h0 * g11 - g01 * h1) / det
        a2 = (g00 * h1 - g01 * h0) / det
        sigma2 = (yy - a1 * h0 - a2 * h1) / (2 * (n - 2))
    if not (math.isfinite(sigma2) and is_stationary(a1, a2)):
        raise Ar2FitError(*non_stationary)
    ss = 0.0
    for _x0, _x1p, _x0p, x2, x0q, x1q in _lagged(chunks(), mean):
        e = x0q - a1 * x1q - a2 * x2
        ss += _dot(e, e)
    return Ar2Model(a1=a1, a2=a2, sigma2=max(sigma2, 0.0), mean=mean, method=name, n=n,
                    r=ss / (n - 2))


def ar_filter(
    x: object,
    model: Ar2Model | Sequence[Ar2Model],
    dtype: object = None,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """AR filter, paper 000 sec. 2.1: y_k minus its one-step residual, i.e. the one-step AR(2)
    prediction plus the mean. x: (n,) or (n, 3), float32/float64 kept (integers -> float64).
    out: optional C-contiguous array of x's shape and the computation dtype (may be x).

    Examples
    --------
    >>> m = Ar2Model(a1=0.5, a2=0.0, sigma2=1.0)
    >>> ar_filter(np.array([1.0, 2.0, 3.0, 4.0]), m).shape
    (4,)
    """
    a = _float_array(x, "x", dtype)
    _check_shape(a, "x")
    axes = 1 if a.ndim == 1 else 3
    params = [_settings(m, None, None) for m in _models_for(model, axes)]
    for p in params:
        _check_core_model(p, a.dtype, "ar_filter")
    out, faults = core("ar2").ar_filter_batch(a, params, out)
    _report_faults(faults, "ar_filter")
    return out


def ar_filter_pieces(pieces: Iterable[np.ndarray], model: Ar2Model, dtype: object = np.float64
                     ) -> Iterator[np.ndarray]:
    """`ar_filter` of a 1-D record given in consecutive pieces, yielded piece by piece.

    The filter's state is its last two inputs: each piece is filtered behind the previous
    piece's last two samples, whose outputs are dropped, so that the pieces' outputs are the
    one-call `ar_filter`'s bit for bit (for finite inputs: a NaN, replaced by the prediction
    inside the filter, is carried as the sample).

    Examples
    --------
    >>> m = Ar2Model(a1=0.5, a2=0.1, sigma2=1.0)
    >>> x = np.random.default_rng(0).standard_normal(100)
    >>> y = np.concatenate(list(ar_filter_pieces((x[i:i + 7] for i in range(0, 100, 7)), m)))
    >>> bool(np.array_equal(y, ar_filter(x, m)))
    True
    """
    from gyrodrift.filters.wavelet import as_core_dtype

    dt = np.dtype(dtype)  # type: ignore[call-overload]
    carry = np.empty(0, dtype=dt)
    start = 0
    for p in pieces:
        piece = as_core_dtype(p, dt, start=start)  # a value beyond float32: refused
        start += piece.size
        a = np.concatenate([carry, piece])
        yield np.asarray(ar_filter(a, model))[carry.size:]
        carry = a[-2:]


@dataclass(frozen=True)
class FilterResult:
    """A filtered record and the non-finite samples the filter skipped, per axis.

    Examples
    --------
    >>> m = Ar2Model(0.5, 0.1, 1.0)
    >>> r = kalman_filter_result(np.array([1.0, np.nan, 2.0, 0.5] * 4), m)
    >>> r.faults.tolist()
    [4]
    """

    y: np.ndarray
    faults: np.ndarray

    def as_dict(self) -> dict[str, object]:
        """JSON-ready values."""
        return {"y": self.y.tolist(), "faults": self.faults.tolist()}


def kalman_filter_result(
    x: object,
    model: Ar2Model | Sequence[Ar2Model],
    q: float | None = None,
    r: float | None = None,
    steady_state: bool = False,
    dtype: object = None,
    p0: float = 1.0,
    out: np.ndarray | None = None,
) -> FilterResult:
    """AR(2)-Kalman filter (C++ core) of a record of shape (n,) or (n, 3), with the count of
    skipped non-finite samples per axis (`kalman_filter` warns instead).

    Parameters
    ----------
    x : array (n,) or (n, 3)
    model : Ar2Model, or one per axis
    q, r : float, optional
        Process / measurement variances, (units of x)^2; default model.sigma2 and model.r.
    steady_state : bool
        Constant gain from the discrete algebraic Riccati equation (solved once).
    dtype : float32 or float64, optional
        Computation dtype; default: x's float dtype, float64 for integers. A float32/float64
        C-contiguous input of that dtype is read without a copy.
    p0 : float
        Initial covariance P0 = p0 I.
    out : array, optional
        C-contiguous array of x's shape and the computation dtype to write into (no
        allocation; may be x itself for in-place filtering); TypeError/ValueError otherwise.

    Returns
    -------
    FilterResult
        ``y`` (the filtered record) and ``faults`` (NaN/Inf samples, which are predict-only
        steps, per axis).

    Examples
    --------
    >>> m = Ar2Model(0.5, 0.1, 1.0, r=1.0)
    >>> kalman_filter_result(np.zeros(10), m).y.shape
    (10,)
    """
    a = _float_array(x, "x", dtype)
    _check_shape(a, "x")
    axes = 1 if a.ndim == 1 else 3
    params = [_settings(m, q, r) for m in _models_for(model, axes)]
    for p in params:
        _check_core_model(p, a.dtype, "kalman_filter")
    p0 = _variance(p0, 1.0, "p0", positive=False)
    y, faults = core("ar2").ar2_kalman_batch(a, params, p0, bool(steady_state), out)
    return FilterResult(y, np.asarray(faults))


def kalman_filter(x: object, model: Ar2Model | Sequence[Ar2Model], q: float | None = None,
                  r: float | None = None, steady_state: bool = False, dtype: object = None,
                  p0: float = 1.0, out: np.ndarray | None = None) -> np.ndarray:
    """AR(2)-Kalman filter (C++ core) of a record of shape (n,) or (n, 3).

    Parameters as `kalman_filter_result`; NaN/Inf samples are predict-only steps, reported
    with a RuntimeWarning (`kalman_filter_result` returns their count instead).

    Examples
    --------
    >>> import gyrodrift
    >>> rec = gyrodrift.simulate(n=2000, rate_hz=100.0, n_deg_rt_h=0.01,
    ...                          ar2=(0.6868, -0.0213, 0.5), seed=1)
    >>> model = gyrodrift.fit_ar2(rec.rate_deg_h)
    >>> y = kalman_filter(rec.rate_deg_h, model)
    >>> bool(np.std(y) < np.std(rec.rate_deg_h))
    True
    """
    res = kalman_filter_result(x, model, q, r, steady_state, dtype, p0, out)
    _report_faults(res.faults, "kalman_filter")
    return res.y


class KalmanFilter:
    """Stateful per-sample AR(2)-Kalman filter (C++ Ar2Kalman / Ar2SteadyStateKalman).

    Examples
    --------
    >>> model = Ar2Model(a1=0.5, a2=0.1, sigma2=1.0, r=1.0)
    >>> kf = KalmanFilter(model)            # q = model.sigma2, r = model.r
    >>> y_hat = kf.step(0.3)                # one sample
    >>> block = kf.process(np.zeros(10))    # continues from the current state
    >>> block.shape
    (10,)
    """

    def __init__(
        self,
        model: Ar2Model,
        q: float | None = None,
        r: float | None = None,
        steady_state: bool = False,
        dtype: object = np.float64,
        p0: float = 1.0,
    ) -> None:
        if not isinstance(model, Ar2Model):
            raise GyrodriftTypeError(f"model must be an Ar2Model, got {type(model).__name__}")
        dt = np.dtype(dtype)  # type: ignore[call-overload]
        if dt not in (np.float32, np.float64):
            raise GyrodriftTypeError(f"dtype must be float32 or float64, got {dt}")
        self.model = model
        self.dtype = dt
        self.steady_state = bool(steady_state)
        settings = _settings(model, q, r)
        _check_core_model(settings, dt, "KalmanFilter")
        self.q, self.r = float(settings.q), float(settings.r)
        lib = core("ar2")
        f32 = dt == np.float32
        if self.steady_state:
            cls = lib.Ar2SteadyStateKalmanF32 if f32 else lib.Ar2SteadyStateKalman
            self._f = cls(settings)
        else:
            cls = lib.Ar2KalmanF32 if f32 else lib.Ar2Kalman
            self._f = cls(settings, _variance(p0, 1.0, "p0", positive=False))

    def step(self, y: float) -> float:
        """Filter one sample; NaN/Inf -> predict-only (fault_count increments)."""
        return float(self._f.step(float(y)))

    def process(self, x: object) -> np.ndarray:
        """Filter a 1-D block, continuing from the current state."""
        a = _float_array(x, "x", self.dtype)
        if a.ndim != 1:
            raise GyrodriftValueError(f"x must be 1-D, got shape {a.shape}")
        return self._f.process(a)

    def reset(self) -> None:
        """Back to X0 = 0, P0 = p0 I, zero faults."""
        self._f.reset()

    @property
    def fault_count(self) -> int:
        return int(self._f.fault_count)

    @property
    def state(self) -> tuple[float, float]:
        """Demeaned state estimate (x_k, x_{k-1}) (full filter only; zeros before any step)."""
        if self.steady_state:
            raise AttributeError("state is exposed by the full filter only")
        return tuple(self._f.state)

    @property
    def covariance(self) -> np.ndarray:
        """Current 2x2 state covariance P (full filter only)."""
        if self.steady_state:
            raise AttributeError("covariance is exposed by the full filter only")
        return np.asarray(self._f.covariance)

    @property
    def dc_gain(self) -> float:
        """Steady-state response to a sustained rate offset d from model.mean: the output
        settles at mean + G d with G = u / ((1 - a1 - a2)(1 - k0) + u), u = k0 + a2 k1, from
        the fixed point of X = A X + K (d - C A X) with the DARE gain K = (k0, k1). G < 1:
        true rate changes are attenuated, so the filter suits drift (static) records only."""
        m = self.model
        k0, k1 = core("ar2").Ar2SteadyStateKalman(_settings(m, self.q, self.r)).gain
        u = k0 + m.a2 * k1
        return float(u / ((1.0 - m.a1 - m.a2) * (1.0 - k0) + u))

    @property
    def gain(self) -> tuple[float, float] | None:
        """Constant gain of the steady-state variant (None for the full filter)."""
        return tuple(self._f.gain) if self.steady_state else None
