"""Whole-record lag statistics of a rate record, kept sample by sample on the C++ core the
target runs (include/gyrodrift/filters/lag_statistics.hpp), from which the exact likelihood
of the drift model (that of :func:`gyrodrift.filters.drift_model.fit_drift_model`) follows.

State of the accepted samples y_0 .. y_{n-1}, with w_t = y_t - c and c = y_0 (the centre):
n, sum_t w_t (``total``), the lag products P_k = sum_{t>=k} w_t w_{t-k} for k = 0..L
(``products``, L = 32), the first min(n, L) values of w (``head``) and the last min(n, L)
(``tail``, oldest first). Fixed memory and L + 1 products per sample, whatever n; every sum
is carried as a compensated pair (about twice the precision of the state's scalar) and read
out in float64. Non-finite samples are refused and counted (``rejected``).

The attribute names are those of the numpy reference's statistics
(``gyrodrift.reference.lag_drift``), whose likelihood and fit take either. Measurements:
docs/validation/online-identification.md, "Whole-record statistics".

``dtype=np.float32`` runs the float state the microcontroller uses.

`lag_drift_fit` fits the drift model from them in the C++ core (double, on either state;
include/gyrodrift/filters/lag_drift_fit.hpp): the exact likelihood from the statistics
maximised over (a1, a2, q / (q + r)) with the mean and the scale in closed form, from a grid
of starts on both sides of a2 = 0 and across that fold, as the numpy reference's
``lag_drift_fit``; `lag_drift_loglike` is the likelihood itself. ``kind="whittle_no_head"``
is the form a target can keep without the first samples (the C++ core's
``LagStatisticsNoHead``; docs/validation/online-identification.md).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError

__all__ = ["LAG_LIKELIHOOD_KINDS", "LagDriftFitError", "LagDriftFitResult", "LagStatistics",
           "lag_drift_fit", "lag_drift_loglike"]

#: The likelihoods the fit can maximise: the exact one (up to terms of order rho^L),
#: Whittle's approximation truncated at L, and Whittle's with the first L samples replaced by
#: the record's mean (what statistics without the first samples give; its fit is refused as
#: truncation above rho^L = 3e-3 instead of 1e-10).
LAG_LIKELIHOOD_KINDS = ("exact", "whittle", "whittle_no_head")


class LagStatistics:
    """Streaming whole-record lag statistics (L = 32 lags) of a rate record.

    Parameters
    ----------
    dtype : numpy dtype, optional
        ``np.float64`` (default) or ``np.float32`` (the float state of the target).

    Raises
    ------
    GyrodriftValueError
        Another dtype.

    Examples
    --------
    >>> st = LagStatistics()
    >>> st.push([1.0, 2.0, 4.0]), st.push([3.0, float("nan")])  # w = 0, 1, 3, 2
    (3, 1)
    >>> st.n, st.rejected, st.centre, st.total
    (4, 1, 1.0, 6.0)
    >>> st.products[:3].tolist(), st.head.tolist(), st.tail.tolist()
    ([14.0, 9.0, 2.0], [0.0, 1.0, 3.0, 2.0], [0.0, 1.0, 3.0, 2.0])
    >>> st.lags, LagStatistics(dtype=np.float32).state_bytes
    (32, 552)
    """

    #: L, the largest lag kept.
    lags: int = 32

    def __init__(self, *, dtype: DTypeLike = np.float64) -> None:
        self._dtype = np.dtype(dtype)
        lib = core("drift")
        if self._dtype == np.float64:
            cls = lib.LagStatistics
        elif self._dtype == np.float32:
            cls = lib.LagStatisticsF32
        else:
            raise GyrodriftValueError(f"dtype must be float64 or float32, got {self._dtype}")
        self._impl: Any = cls()
        if int(self._impl.lags) != self.lags:
            raise AssertionError(f"the C++ statistics keep {self._impl.lags} lags, not {self.lags}")

    def push(self, y: ArrayLike) -> int:
        """Add rate samples in time order (GIL released); returns the number accepted.

        Non-finite samples are skipped and counted in :attr:`rejected`. Pushing a record in
        chunks of any size gives the same state as pushing it at once.

        Raises
        ------
        GyrodriftValueError
            y is not one-dimensional.
        """
        arr = np.ascontiguousarray(y, dtype=self._dtype)
        if arr.ndim != 1:
            raise GyrodriftValueError(f"y: expected a 1-D array, got shape {arr.shape}")
        return int(self._impl.push(arr))

    def reset(self) -> None:
        """Forget every sample and the rejected count."""
        self._impl.reset()

    @property
    def dtype(self) -> np.dtype[Any]:
        """The precision of the state (float64 or float32)."""
        return self._dtype

    @property
    def n(self) -> int:
        """Samples accepted so far."""
        return int(self._impl.n)

    @property
    def rejected(self) -> int:
        """Non-finite samples skipped so far."""
        return int(self._impl.rejected)

    @property
    def centre(self) -> float:
        """c, the first accepted sample (0 before it)."""
        return float(self._impl.centre)

    @property
    def total(self) -> float:
        """sum_t w_t."""
        return float(self._impl.total)

    @property
    def products(self) -> np.ndarray:
        """The lag products P_0 .. P_L (float64, L + 1 values)."""
        return np.asarray(self._impl.products)

    @property
    def head(self) -> np.ndarray:
        """The first min(n, L) values of w (float64)."""
        return np.asarray(self._impl.head)

    @property
    def tail(self) -> np.ndarray:
        """The last min(n, L) values of w, oldest first (float64)."""
        return np.asarray(self._impl.tail)

    @property
    def state_bytes(self) -> int:
        """Size of the C++ statistics' state in this precision (bytes)."""
        return int(self._impl.state_bytes)


class LagDriftFitError(GyrodriftValueError):
    """The statistics cannot be fitted, or the model is outside its domain.

    ``cause`` is the C++ status name: too_few_samples (fewer than 2 L + 2 = 66 samples),
    non_finite (statistics or parameters not finite) or bad_model (q < 0, r <= 0, or a
    non-stationary AR part; `lag_drift_loglike` only).

    Examples
    --------
    >>> st = LagStatistics(); _ = st.push(np.arange(10.0))
    >>> try:
    ...     lag_drift_fit(st)
    ... except LagDriftFitError as exc:
    ...     print(exc.cause)
    too_few_samples
    """

    def __init__(self, cause: str, detail: str) -> None:
        self.cause = cause
        super().__init__(f"lag-statistics fit refused ({cause.replace('_', ' ')}): {detail}")


@dataclass(frozen=True)
class LagDriftFitResult:
    """The drift model fitted from the lag statistics.

    ``status``: ok; truncation (rho^L of the fit above 1e-10, or 3e-3 for the kind
    whittle_no_head; rho the pole modulus of the model's steady-state innovation filter:
    L = 32 is too short for this model and the likelihood's neglected terms are not
    negligible); not_converged (the best run stopped at
    its iteration bound). a1, a2, q, r (record units squared) and mean (record units) are the
    estimate, ``loglike`` its log-likelihood of the kind fitted, ``truncation`` its rho^L;
    ``iterations``, ``evaluations`` and ``runs`` the maximiser's work.

    Examples
    --------
    >>> r = LagDriftFitResult("ok", 0.5, 0.0, 1.0, 1.0, 0.0, -10.0, 1e-20, 50, 400, 4)
    >>> r.as_dict()["status"], r.q / r.r
    ('ok', 1.0)
    """

    status: str
    a1: float
    a2: float
    q: float
    r: float
    mean: float
    loglike: float
    truncation: float
    iterations: int
    evaluations: int
    runs: int

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready values.

        Examples
        --------
        >>> fit = LagDriftFitResult("ok", 0.5, 0.0, 1.0, 1.0, 0.0, -1.0, 0.0, 1, 1, 4)
        >>> sorted(fit.as_dict())[:3]
        ['a1', 'a2', 'evaluations']
        """
        return asdict(self)


def _kind(kind: str) -> Any:
    if kind not in LAG_LIKELIHOOD_KINDS:
        raise GyrodriftValueError(
            f"kind must be one of {', '.join(LAG_LIKELIHOOD_KINDS)}, got {kind!r}")
    return getattr(core("drift").LagLikelihoodKind, kind)


def _impl(stats: LagStatistics) -> Any:
    if not isinstance(stats, LagStatistics):
        raise GyrodriftTypeError(
            f"stats must be a gyrodrift.filters.LagStatistics, got {type(stats).__name__}")
    return stats._impl


def _refused(status: Any, stats: LagStatistics) -> LagDriftFitError:
    name = str(status.name)
    detail = {"too_few_samples": f"{stats.n} samples, at least {2 * stats.lags + 2} needed "
                                 f"for {stats.lags} lags",
              "non_finite": "the statistics or the parameters are not finite",
              "bad_model": "q < 0, r <= 0 or a non-stationary AR part"}.get(name, name)
    return LagDriftFitError(name, detail)


def lag_drift_fit(stats: LagStatistics, *, kind: str = "exact",
                  max_iterations: int | None = None) -> LagDriftFitResult:
    """Fit the drift model (AR(2) drift + white noise) from the lag statistics in the C++
    core, in double on either state (GIL released).

    Parameters
    ----------
    stats : LagStatistics
        The statistics of the record (float64 or float32 state); not changed.
    kind : {"exact", "whittle", "whittle_no_head"}
        The likelihood maximised (module docstring, `LAG_LIKELIHOOD_KINDS`).
    max_iterations : int, optional
        BFGS iterations a run at most (None: the core's default, 200); the status is
        not_converged when the best run stops there.

    Returns
    -------
    LagDriftFitResult
        The estimate, with the status ok, truncation or not_converged.

    Raises
    ------
    LagDriftFitError
        Fewer than 2 L + 2 samples, or statistics that are not finite (``cause``).
    GyrodriftValueError
        `max_iterations` not an integer in 1..100000.

    Examples
    --------
    >>> from scipy.signal import lfilter
    >>> rng = np.random.default_rng(1)
    >>> y = lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(size=20000)) \\
    ...     + rng.normal(size=20000)
    >>> st = LagStatistics(dtype=np.float32); _ = st.push(y)
    >>> fit = lag_drift_fit(st)
    >>> fit.status, bool(abs(fit.a1 - 0.6868) < 0.2 and abs(fit.q / fit.r - 1.0) < 0.5)
    ('ok', True)
    """
    lib = core("drift")
    if max_iterations is None:
        out = lib.lag_drift_fit(_impl(stats), _kind(kind))
    else:
        if isinstance(max_iterations, bool) or not isinstance(max_iterations, int) \
                or not 1 <= max_iterations <= 100000:
            raise GyrodriftValueError(
                f"max_iterations must be an integer in 1..100000, got {max_iterations!r}")
        out = lib.lag_drift_fit(_impl(stats), _kind(kind), max_iterations)
    status = out[0]
    if status.name in ("too_few_samples", "non_finite"):
        raise _refused(status, stats)
    a1, a2, q, r, mean, loglike, truncation = (float(v) for v in out[1:8])
    iterations, evaluations, runs = (int(v) for v in out[8:11])
    return LagDriftFitResult(str(status.name), a1, a2, q, r, mean, loglike, truncation,
                             iterations, evaluations, runs)


def lag_drift_loglike(stats: LagStatistics, a1: float, a2: float, q: float, r: float,
                      mean: float, *, kind: str = "exact") -> float:
    """Log-likelihood of the drift model from the lag statistics (C++ core, double).

    Parameters
    ----------
    stats : LagStatistics
        The statistics of the record.
    a1, a2 : float
        AR coefficients of the drift (stationary).
    q, r : float
        Driving-noise and white-noise variances (record units squared; q >= 0, r > 0).
    mean : float
        The record's constant offset (record units).
    kind : {"exact", "whittle", "whittle_no_head"}
        The likelihood (module docstring, `LAG_LIKELIHOOD_KINDS`).

    Raises
    ------
    LagDriftFitError
        Too few samples, non-finite statistics or parameters, or a model outside its domain.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> y = rng.normal(size=1000); st = LagStatistics(); _ = st.push(y)
    >>> white = -0.5 * (1000 * np.log(2 * np.pi) + float(np.sum(y * y)))
    >>> bool(abs(lag_drift_loglike(st, 0.0, 0.0, 1e-12, 1.0, 0.0) - white) < 1e-6)
    True
    """
    status, ll = core("drift").lag_drift_loglike(_impl(stats), float(a1), float(a2), float(q),
                                                 float(r), float(mean), _kind(kind))
    if status.name != "ok":
        raise _refused(status, stats)
    return float(ll)
