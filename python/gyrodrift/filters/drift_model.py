"""Maximum-likelihood identification of the drift model, and the Kalman filter it tunes.

Model, on a rate record y in its own units:

    x_k = a1 x_{k-1} + a2 x_{k-2} + w_k,   w_k ~ N(0, q)     (AR(2) drift, papers 000/002 eq. 1)
    y_k = mean + x_k + v_k,                 v_k ~ N(0, r)     (white rate noise: ARW, quantization)

``"ar1+white"`` is a2 = 0 (first-order Gauss-Markov drift plus white noise), ``"white"`` is
a1 = a2 = q = 0. The papers' recipe (AR(2) fitted by Burg/Yule-Walker on the noisy record) biases
a1, a2 because it ignores v; fitting the model above by maximum likelihood does not.

The exact Gaussian log-likelihood (Kalman filter, stationary start) runs in the C++ core
(include/gyrodrift/filters/drift_likelihood.hpp). One pass gives the likelihood at any mean and any
common scale of (q, r), so the optimiser (scipy L-BFGS-B) works on the profile likelihood of
only the dynamic parameters, transformed so that every trial is valid:
a2 = tanh(u2), a1 = tanh(u1) (1 - a2) (partial autocorrelations: stationary for every u), and
q / (q + r) = logistic(u3). Starts: the papers' Yule-Walker/Burg-type fit (all variance to the
drift), four moment fits that give 30, 60, 85, 95 % of the variance to the white noise, and a
grid of partial autocorrelations (+-0.9, 0) with 95 % white noise; each is optimised coarsely and
the best optimum finely. On long records the multi-start runs on the first 2^14 samples and its
distinct modes (within 3 log-likelihood units) warm-start quasi-Newton refinements on the full
record. Next to a2 = 0 (the fold, where the Fisher information is singular) the likelihood can
have a maximum on each side, and which one a run reaches is set by its start's split as much as
by its a2: when the estimate is within _FOLD_Z expected standard errors of a2 = 0, one more run
starts from its mirror (u2 -> -u2, first with u2 held, then free) and the higher maximum is
kept; the other is reported, and a tie within _FOLD_TIE_LL as the AR part not identified.

A record memory-mapped from a .npy file (1-D float64, as `numpy.load(..., mmap_mode="r")` gives
it) longer than 2^20 samples is never held in memory: every pass over the whole record (its
mean and Burg fit, the autocovariances, each likelihood evaluation through the core's
DriftLoglikeStream, the innovations' Ljung-Box sums, `block_average`) reads it from the file
in pieces of 2^20 samples, and only its first 2^16 samples (the multi-start prefix and the
split check) are copied; the fit is that of the record in memory, to rounding.

Standard errors are from the observed information: the Hessian of the log-likelihood at the
optimum, differenced in (a1, a2, q/(q+r)) and exact in the scale and the mean, carried to
(a1, a2, q, r, mean) by the chain rule.

The split of the record's variance between drift and white noise is checked (_split_check):
when neither r/q = 0.1 nor r/q = 10 is rejected by the profile likelihood, or the model does
not beat white noise by BIC, the record cannot tell them apart (nearly white drift; no
estimator can then tune the filter reliably: scripts/drift_identifiability.py) and the filter
is tuned at q = r, the minimax choice (fields identified, tuning, filter_params).

AIC = 2 k - 2 log L, BIC = k log n - 2 log L with k = 5
(ar2+white), 4 (ar1+white), 2 (white) parameters, mean included.

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> y = 3.0 + rng.normal(size=2000)
>>> fit = fit_drift_model(y, rate_hz=100.0, model="white")
>>> round(fit.mean, 1), fit.model
(3.0, 'white')
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.optimize
import scipy.stats
from threadpoolctl import threadpool_limits

from gyrodrift._native import core
from gyrodrift._scale import normalising_scale, scale_for_peak
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.filters.ar2 import Ar2FitError, Ar2Model, KalmanFilter, fit_ar2, fit_ar2_chunks
from gyrodrift.io.records import is_file_backed, iter_chunks

__all__ = [
    "DECIMATION_MIN_BLOCKS",
    "DECIMATION_MIN_FACTOR",
    "DECIMATION_TAU_FRACTION",
    "DRIFT_MODELS",
    "DriftModelComparison",
    "DriftModelFit",
    "FilterResponse",
    "LjungBox",
    "block_average",
    "choose_decimation",
    "compare_drift_models",
    "drift_fisher_information",
    "drift_params_at_rate",
    "fit_drift_model",
    "steady_state_response",
]

#: Models, most complex first.
DRIFT_MODELS = ("ar2+white", "ar1+white", "white")

#: Parameters counted by AIC/BIC (mean included).
_N_PARAMS = {"ar2+white": 5, "ar1+white": 4, "white": 2}
#: Fitted dynamic parameters (besides mean and scale) removed from the Ljung-Box degrees of
#: freedom: a1, a2 and the q/r split; a1 and the split; none.
_MODEL_DF = {"ar2+white": 3, "ar1+white": 2, "white": 0}

_LOG_2PI = math.log(2.0 * math.pi)
_U_AR_BOUND = 7.5  # |tanh(u)| <= 1 - 6e-7: stays inside the core's stationarity margin
_U_SPLIT_BOUND = 30.0
_WARM_START_N = 1 << 14
_MODE_KEEP_LL = 3.0
#: Two optima are distinct modes when they differ by more than this in some u.
_MODE_DISTINCT_U = 0.05
#: The split check (_split_check): profile likelihood at these r/q, the drop that counts as a
#: rejection (chi2_1 at 99.5 % is 7.88 = 2 x 3.94; near-white records at 2e4-6e4 samples give
#: drops up to ~3 and occasionally 6 when the fit sits in a spurious mode, correlated ones 5-470
#: at 2e4 and ~3x that at 6e4), and the longest prefix it runs on.
_SPLIT_PROBES = (0.1, 10.0)
_SPLIT_DROP_MIN = 4.0
_PROFILE_N = 1 << 16
#: The fold a2 = 0 (ar2+white): the fit runs across it from its estimate's mirror when the
#: estimate is within _FOLD_Z expected standard errors of it (the lower of two maxima seen on
#: either side was about 4.7 away, on a 10 h record of 0.6868/-0.0213; the papers'
#: 0.2297/0.1638 is 10 away at 3e4 samples and more on longer records) and not on it
#: (|u2| < _ON_FOLD, about |a2|: its mirror is itself), and calls the two maxima tied, the AR
#: part not identified by the record, when their log-likelihoods differ by at most
#: _FOLD_TIE_LL: 20 times the optimisers' stopping tolerance (1e-4 log-likelihood units,
#: _optimise), a tie to the optimiser (maxima 0.002 to 0.6 apart were seen next to the fold).
_FOLD_Z = 10.0
_ON_FOLD = 1e-3
_FOLD_TIE_LL = 2e-3



@dataclass(frozen=True)
class LjungBox:
    """Ljung-Box portmanteau test of the standardised innovations.

    Q = n (n + 2) sum_{k=1..lags} rho_k^2 / (n - k), rho_k the sample autocorrelation (mean
    removed); p-value from chi-square with df = lags - (fitted dynamic parameters). A small
    p-value (< 0.05) says the model leaves correlation in the record unexplained.

    Examples
    --------
    >>> lb = ljung_box(np.random.default_rng(0).normal(size=500), lags=10)
    >>> lb.lags, lb.df, round(lb.pvalue, 2)  # white residuals: no evidence of correlation
    (10, 10, 0.54)
    """

    statistic: float
    pvalue: float
    lags: int
    df: int

    def as_dict(self) -> dict[str, Any]:
        return {"statistic": self.statistic, "pvalue": self.pvalue, "lags": self.lags,
                "df": self.df}


@dataclass(frozen=True)
class FilterResponse:
    """Steady-state Kalman filter as a linear filter of the record.

    Attributes
    ----------
    gain
        constant Kalman gain (k0, k1).
    dc_gain
        output change per sustained input change.
    bandwidth_hz
        frequency where ``|H|`` falls 3 dB below ``|H(0)|`` (None if the filter passes
        nothing, i.e. gain 0, or never falls 3 dB below DC up to Nyquist).

    Examples
    --------
    >>> resp = steady_state_response(0.6, 0.2, 1.0, 0.25, rate_hz=100.0)
    >>> [round(g, 4) for g in resp.gain], round(resp.dc_gain, 4), resp.bandwidth_hz
    ([0.8129, 0.0948], 0.957, None)
    """

    gain: tuple[float, float]
    dc_gain: float
    bandwidth_hz: float | None

    def as_dict(self) -> dict[str, Any]:
        return {"gain": list(self.gain), "dc_gain": self.dc_gain,
                "bandwidth_hz": self.bandwidth_hz}


def _nan_to_none(v: float) -> float | None:
    return None if not math.isfinite(v) else float(v)


@dataclass(frozen=True)
class DriftModelFit:
    """A maximum-likelihood fit of the drift model (see the module docstring).

    a1, a2: AR coefficients (dimensionless; 0 where the model fixes them).
    q: drift driving-noise variance, r: white-noise variance, (units of x)^2.
    mean: constant rate, units of x. loglike, aic, bic: at the optimum.
    stderr: standard errors {a1, a2, q, r, mean} from the observed information (NaN for a
    parameter the model fixes, or when the information is singular at a boundary).
    start_loglike: log-likelihood at the start (Burg coefficients, best variance split).
    split_drop: drops of the profile log-likelihood when the split is forced to r/q = 0.1 and
    to r/q = 10 (inf for the white model). identified: False when both are below 4 (neither
    rejected at 99.5 %) or when the model does not beat the white model by BIC: the record
    cannot tell drift from white noise; False too when a standard error of a1, a2 (AR(2)),
    q or r does not exist (NaN) or a drop is zero: the estimate itself is not determined by
    the record. tuning: "ml" (the
    filter uses the fitted a1, a2, q, r) or "minimax-split" (not identified: the filter uses
    the profile fit at q = r, whose gain minimises the worst-case error over all splits; see
    the drift model validation page).
    filter_params: (a1, a2, q, r) of the filter that `kalman()` and `response()` use.
    fold_a2, fold_loglike: ar2+white next to the fold a2 = 0, where the likelihood can have a
    maximum on each side: a2 and the log-likelihood of the lower maximum, on the other side of
    the fold from a2 (NaN when the fit found none there). ar_identified: False when the two
    maxima are tied (log-likelihoods within 2e-3): the record does not tell the sign of a2,
    and the standard errors describe one maximum only.

    Examples
    --------
    >>> x = np.random.default_rng(0).normal(0.5, 1.0, 1000)  # white noise around 0.5
    >>> fit = fit_drift_model(x, 100.0, "white")
    >>> fit.model, round(fit.r, 3), round(fit.mean, 3), fit.n
    ('white', 0.954, 0.452, 1000)
    >>> sorted(fit.as_dict())[:5]
    ['a1', 'a2', 'aic', 'ar_identified', 'bic']
    """

    model: str
    a1: float
    a2: float
    q: float
    r: float
    mean: float
    loglike: float
    aic: float
    bic: float
    stderr: dict[str, float] = field(hash=False, compare=False)
    n: int
    rate_hz: float
    ljung_box: LjungBox
    start_loglike: float
    n_evaluations: int
    split_drop: tuple[float, float]
    identified: bool
    tuning: str
    filter_params: tuple[float, float, float, float]
    fold_a2: float = math.nan
    fold_loglike: float = math.nan

    @property
    def ar_identified(self) -> bool:
        """False when the maximum on the other side of the fold a2 = 0 ties with this one."""
        return not self.loglike - self.fold_loglike <= _FOLD_TIE_LL

    @property
    def n_params(self) -> int:
        return _N_PARAMS[self.model]

    def ar2_model(self) -> Ar2Model:
        """The filter's drift model as an Ar2Model (sigma2 = q; `filter_params`)."""
        a1, a2, q, _ = self.filter_params
        return Ar2Model(a1=a1, a2=a2, sigma2=q, mean=self.mean,
                        method=f"ml:{self.model}", n=self.n, r=self._filter_r)

    @property
    def _filter_r(self) -> float:
        # The filters need r > 0; a fit on the r = 0 boundary gets a negligible r.
        _, _, q, r = self.filter_params
        return max(r, 1e-12 * (q + r))

    def kalman(self, steady_state: bool = True, dtype: object = np.float64) -> KalmanFilter:
        """A ready AR(2)-Kalman filter tuned by this fit (`filter_params`: the fitted q, r, or
        the minimax split when the split is not identified; steady-state gain by default). Its
        output estimates mean + x_k, the drift without the white noise."""
        return KalmanFilter(self.ar2_model(), q=self.filter_params[2], r=self._filter_r,
                            steady_state=steady_state, dtype=dtype)

    def response(self) -> FilterResponse:
        """Gain, DC gain and -3 dB bandwidth of the steady-state filter."""
        a1, a2, q, _ = self.filter_params
        return steady_state_response(a1, a2, q, self._filter_r, self.rate_hz)

    def as_dict(self) -> dict[str, Any]:
        return {
            "model": self.model, "a1": self.a1, "a2": self.a2, "q": self.q, "r": self.r,
            "mean": self.mean, "loglike": self.loglike, "aic": self.aic, "bic": self.bic,
            "stderr": {k: _nan_to_none(v) for k, v in self.stderr.items()},
            "n": self.n, "rate_hz": self.rate_hz, "ljung_box": self.ljung_box.as_dict(),
            "start_loglike": self.start_loglike, "n_evaluations": self.n_evaluations,
            "split_drop": [_nan_to_none(v) for v in self.split_drop],
            "identified": self.identified,
            "tuning": self.tuning, "filter_params": list(self.filter_params),
            "fold_a2": _nan_to_none(self.fold_a2), "fold_loglike": _nan_to_none(self.fold_loglike),
            "ar_identified": self.ar_identified,
        }


@dataclass(frozen=True)
class DriftModelComparison:
    """All three models fitted to one record, and the one chosen by `criterion`.

    Examples
    --------
    >>> x = np.random.default_rng(0).normal(0.5, 1.0, 1000)
    >>> fit = fit_drift_model(x, 100.0, "white")
    >>> cmp_ = DriftModelComparison(fits=(fit,), criterion="aic", chosen="white")
    >>> cmp_.best is fit, list(cmp_.as_dict())
    (True, ['criterion', 'chosen', 'fits'])
    """

    fits: tuple[DriftModelFit, ...]
    criterion: str
    chosen: str

    def fit(self, model: str) -> DriftModelFit:
        for f in self.fits:
            if f.model == model:
                return f
        raise KeyError(model)

    @property
    def best(self) -> DriftModelFit:
        return self.fit(self.chosen)

    def as_dict(self) -> dict[str, Any]:
        return {"criterion": self.criterion, "chosen": self.chosen,
                "fits": [f.as_dict() for f in self.fits]}


# --------------------------------------------------------------------------- likelihood


#: Samples per piece read from a file-backed record (8 MiB of float64).
_PIECE = 1 << 20


class _Pieces:
    """A file-backed record (`gyrodrift.io.records.is_file_backed`) divided by `scale`, read
    from its file in pieces of _PIECE samples for every pass (`pieces`), with the statistics
    of the whole record the fit needs (`stats`: the mean, Burg's AR(2) and the autocovariances
    at lags 0-2 around the mean, as `fit_ar2(x, "burg")` and the in-memory code give them)."""

    def __init__(self, mm: np.ndarray, scale: float) -> None:
        self.mm = mm
        self.scale = scale
        self.shape = (int(mm.shape[0]),)
        self._stats: tuple[Ar2Model, list[float]] | None = None

    def pieces(self) -> Any:
        for p in iter_chunks(self.mm, _PIECE):
            yield p if self.scale == 1.0 else p / self.scale

    def head(self, m: int) -> np.ndarray:
        """The first m samples, in memory."""
        p = next(iter_chunks(self.mm, max(1, min(m, self.shape[0]))))
        return np.array(p if self.scale == 1.0 else p / self.scale, dtype=np.float64)

    def stats(self) -> tuple[Ar2Model, list[float]]:
        """(Burg's AR(2) of the record with its mean, `fit_ar2_chunks`: the checks, errors and
        formulas of the core's fit_ar2; [c0, c1, c2] around that mean, one more pass)."""
        if self._stats is None:
            burg = fit_ar2_chunks(self.pieces, "burg")
            sums = _LagSums(2)  # its raw sums of the centred pieces: n c0, n c1, n c2
            for p in self.pieces():
                sums.add(p - burg.mean)
            n = self.shape[0]
            self._stats = (burg, [sums.sq / n, *(float(v) / n for v in sums.prod)])
        return self._stats

    def moments(self, center: float) -> tuple[float, float]:
        """(mean, sum of squares around it), the mean as center + mean(x - center)."""
        n = self.shape[0]
        mean = center + sum(float(np.sum(p - center)) for p in self.pieces()) / n
        return mean, sum(float((p - mean) @ (p - mean)) for p in self.pieces())


def _head(x: np.ndarray | _Pieces, m: int) -> np.ndarray:
    return x.head(m) if isinstance(x, _Pieces) else x[:m]


def _autocov(d: np.ndarray) -> list[float]:
    """Biased autocovariances [c0, c1, c2] of a centred record."""
    n = d.size
    return [float(d[: n - k] @ d[k:]) / n for k in range(3)]


def _autocov_around(x: np.ndarray | _Pieces, center: float) -> list[float]:
    if isinstance(x, _Pieces):
        burg, c = x.stats()
        assert burg.mean == center  # the profile's center is the record's mean (_fit_1d)
        return c
    return _autocov(x - center)


class _LagSums:
    """The Ljung-Box statistic of a series that arrives in pieces: raw sums of the series, of
    its squares and of its lag-k products, with the first and last `lags` values, centred
    exactly at the end (the same rho_k as `ljung_box`, to rounding)."""

    def __init__(self, lags: int) -> None:
        self.lags = lags
        self.n = 0
        self.total = 0.0
        self.sq = 0.0
        self.prod = np.zeros(lags)
        self.first = np.empty(0)
        self.tail = np.empty(0)

    def add(self, e: np.ndarray) -> None:
        z = np.concatenate([self.tail, e])
        t = self.tail.size
        for k in range(1, self.lags + 1):
            lo = max(t, k)
            if lo < z.size:
                self.prod[k - 1] += float(z[lo - k:z.size - k] @ z[lo:])
        self.n += e.size
        self.total += float(np.sum(e))
        self.sq += float(e @ e)
        if self.first.size < self.lags:
            self.first = np.concatenate([self.first, e[: self.lags - self.first.size]])
        self.tail = z[-self.lags:]

    def result(self, model_df: int) -> LjungBox:
        n, lags = self.n, self.lags
        m = self.total / n
        c0 = self.sq - n * m * m
        k = np.arange(1, lags + 1)
        head = np.cumsum(self.first)[:lags]            # sum_{t < k} e_t
        tail = np.cumsum(self.tail[::-1])[:lags]       # sum_{t >= n - k} e_t
        cov = self.prod - m * ((self.total - tail) + (self.total - head)) + (n - k) * m * m
        rho = cov / c0
        q = float(n * (n + 2) * np.sum(rho**2 / (n - k)))
        df = max(lags - model_df, 1)
        return LjungBox(statistic=q, pvalue=float(scipy.stats.chi2.sf(q, df)), lags=lags,
                        df=df)


class _Profile:
    """Profile log-likelihood of the dynamic parameters (mean and scale concentrated out)."""

    def __init__(self, x: np.ndarray | _Pieces, model: str, center: float) -> None:
        self.x = x
        self.model = model
        self.center = center
        self.n = x.shape[0]
        self.evaluations = 0
        self.core = core("drift")

    def natural(self, u: np.ndarray) -> tuple[float, float, float]:
        """(a1, a2, w = q / (q + r)) from the unconstrained u."""
        if self.model == "ar2+white":
            a2 = math.tanh(u[0 + 1])
            a1 = math.tanh(u[0]) * (1.0 - a2)
        else:
            a1, a2 = math.tanh(u[0]), 0.0
        w = 1.0 / (1.0 + math.exp(-u[-1]))
        return a1, a2, w

    def sums(self, a1: float, a2: float, q: float, r: float, mean: float) -> tuple[float, ...]:
        self.evaluations += 1
        if isinstance(self.x, _Pieces):
            stream = self.core.DriftLoglikeStream(a1=a1, a2=a2, q=q, r=r, mean=mean)
            for piece in self.x.pieces():
                stream.update(piece)
            return tuple(stream.result())
        return tuple(self.core.drift_loglike(self.x, a1, a2, q, r, mean))

    def concentrated(self, a1: float, a2: float, w: float) -> tuple[float, float, float]:
        """(profile loglike, scale s, mean) for q = s w, r = s (1 - w)."""
        _, slog, see, seg, sgg = self.sums(a1, a2, w, 1.0 - w, self.center)
        d = seg / sgg
        s = max(see - seg * d, 1e-300) / self.n
        ll = -0.5 * (self.n * (_LOG_2PI + math.log(s) + 1.0) + slog)
        return ll, s, self.center + d

    def negll(self, u: np.ndarray) -> float:
        try:
            ll = self.concentrated(*self.natural(u))[0]
        except ValueError:
            return math.inf
        return -ll / self.n


def _u_of(model: str, a1: float, a2: float, w: float) -> np.ndarray:
    w = min(max(w, 1e-12), 1.0 - 1e-12)
    split = math.log(w / (1.0 - w))
    b = _U_AR_BOUND
    if model == "ar2+white":
        p2 = max(min(a2, 0.999), -0.999)
        p1 = max(min(a1 / (1.0 - p2), 0.999), -0.999)
        return np.array([min(max(math.atanh(p1), -b), b), min(max(math.atanh(p2), -b), b), split])
    p1 = max(min(a1, 0.999), -0.999)
    return np.array([min(max(math.atanh(p1), -b), b), split])


def _optimise(prof: _Profile, u0: np.ndarray, tight: bool = True) -> np.ndarray:
    bounds = [(-_U_AR_BOUND, _U_AR_BOUND)] * (u0.size - 1) + [(-_U_SPLIT_BOUND, _U_SPLIT_BOUND)]
    # Tight: stop when log L changes by < ~1e-4 per iteration (the objective is -log L / n, about
    # 1-2 per sample), i.e. parameters to ~1 % of their standard errors.
    opts = ({"ftol": 5e-5 / prof.n, "gtol": 1e-9, "maxiter": 500} if tight
            else {"ftol": 1e-9, "gtol": 1e-6, "maxiter": 30})
    # Central differences where evaluations are cheap; forward ones on long records (the
    # warm start is already close there).
    jac = "3-point" if tight and prof.n <= 1 << 16 else "2-point"
    res = scipy.optimize.minimize(prof.negll, u0, method="L-BFGS-B", jac=jac, bounds=bounds,
                                  options=opts)
    return np.asarray(res.x)


def _moment_starts(c: list[float], model: str, burg: Ar2Model) -> list[np.ndarray]:
    """Start points from the sample autocovariances c = [c0, c1, c2] of the demeaned record: a
    share f of c0 is attributed to the white noise (r = f c0, f = 0, 0.3, 0.6, 0.85) and the AR
    part solved from the Yule-Walker equations with c0 (1 - f); for f = 0 the papers' Burg fit
    (all variance to the drift) is used instead."""
    starts = []
    for f in (0.0, 0.3, 0.6, 0.85, 0.95):
        g0 = c[0] * (1.0 - f)
        if model == "ar2+white":
            det = g0 * g0 - c[1] * c[1]
            if det <= 0:
                continue
            a1 = (c[1] * g0 - c[1] * c[2]) / det
            a2 = (c[2] * g0 - c[1] * c[1]) / det
            a2 = max(min(a2, 0.99), -0.99)
            a1 = max(min(a1, 0.99 * (1.0 - a2)), -0.99 * (1.0 - a2))
            q = g0 - a1 * c[1] - a2 * c[2]
        else:
            a1 = max(min(c[1] / g0, 0.99), -0.99)
            a2 = 0.0
            q = g0 * (1.0 - a1 * a1)
        if f == 0.0 and model == "ar2+white":
            a1, a2, q = burg.a1, burg.a2, burg.sigma2
        q = max(q, 1e-6 * c[0])
        r = max(f * c[0], 1e-6 * c[0])
        starts.append(_u_of(model, a1, a2, q / (q + r)))
    # A near-white record's likelihood can have separate modes far from the moment fits (e.g.
    # a weak, sharp resonance near Nyquist): a coarse grid of partial autocorrelations with
    # most of the variance white.
    grid = (-0.9, 0.0, 0.9)
    split = math.log(0.05 / 0.95)
    if model == "ar2+white":
        starts += [np.array([math.atanh(p1), math.atanh(p2), split]) for p1 in grid for p2 in grid]
    else:
        starts += [np.array([math.atanh(p1), split]) for p1 in grid]
    return starts


def _best_of(prof: _Profile, starts: list[np.ndarray]) -> np.ndarray:
    """A coarse optimisation from every start, then a tight one from the best coarse optimum
    (never returns a point worse than the best start)."""
    coarse = [_optimise(prof, u0, tight=False) for u0 in starts]
    best = min([*coarse, *starts], key=prof.negll)
    u = _optimise(prof, best, tight=True)
    return u if prof.negll(u) <= prof.negll(best) else best


def _next_to_fold(a1: float, a2: float, q: float, r: float, n: int) -> bool:
    """Is a2 within _FOLD_Z expected standard errors of the fold a2 = 0?

    From the expected information (`drift_fisher_information`) at the estimate: it is
    singular on the fold itself, so next to it a2's expected standard error is large; a
    singular matrix anywhere (e.g. q = 0) counts as next to the fold too (the run across it is
    then only a cost)."""
    try:
        cov = np.linalg.inv(drift_fisher_information(a1, a2, q, r, n))
    except np.linalg.LinAlgError:
        return True
    var = float(cov[1, 1])
    return not (math.isfinite(var) and var > 0.0) or abs(a2) < _FOLD_Z * math.sqrt(var)


def _across_fold(prof: _Profile, u: np.ndarray, pre: _Profile | None) -> np.ndarray:
    """A run from the mirror of u across the fold a2 = 0 (ar2+white; u = (u1, u2, u3)).

    The profile likelihood maximised over (u1, u3) with u2 held at -u2, then over all three
    from there: next to a2 = 0 the likelihood can have a maximum on each side, and which one a
    run from the multi-start's points reaches is set by the start's split as much as by its
    a2. The full run is L-BFGS-B (_optimise) on a short record and quasi-Newton steps
    (_newton_refine, curvature from the prefix profile pre) on a long one. Returns the point
    it ends at, which may be back on u's side."""
    u2 = -float(u[1])

    def held(v: np.ndarray) -> float:
        return prof.negll(np.array([v[0], u2, v[1]]))

    res = scipy.optimize.minimize(held, u[[0, 2]], method="L-BFGS-B", jac="2-point",
                                  bounds=[(-_U_AR_BOUND, _U_AR_BOUND),
                                          (-_U_SPLIT_BOUND, _U_SPLIT_BOUND)],
                                  options={"ftol": 1e-3 / prof.n, "maxiter": 100})
    side = np.array([res.x[0], u2, res.x[1]])
    if pre is None:
        return _optimise(prof, side, tight=True)
    _, _, hess_pre = _fd_gradient_hessian(pre.negll, side, 1e-4, hessian=True)
    assert hess_pre is not None
    cand, f_c, status = _newton_refine(prof, side, hess_pre)
    if status == "failed":
        other = _optimise(prof, cand, tight=True)
        cand = other if prof.negll(other) <= f_c else cand
    return cand


def _prefix_modes(prof: _Profile, starts: list[np.ndarray], max_modes: int = 3
                  ) -> list[np.ndarray]:
    """Distinct local optima of the prefix likelihood worth refining on the full record.

    A coarse optimisation from every start; the optima within _MODE_KEEP_LL log-likelihood
    units of the best that differ by more than _MODE_DISTINCT_U in u (at most max_modes, best
    first).
    They need no tight optimisation here: the Newton steps on the full record do that."""
    coarse = sorted([_optimise(prof, u0, tight=False) for u0 in starts] + starts,
                    key=prof.negll)
    best_f = prof.negll(coarse[0])
    modes: list[np.ndarray] = []
    for u in coarse:
        if (prof.negll(u) - best_f) * prof.n > _MODE_KEEP_LL or len(modes) == max_modes:
            break
        if all(np.max(np.abs(u - m)) > _MODE_DISTINCT_U for m in modes):
            modes.append(u)
    return modes


def _forward_gradient(fun: Any, u: np.ndarray, f0: float, h: float = 1e-6) -> np.ndarray:
    """Forward-difference gradient (k passes). For -log L / n (about 1 per sample, computed to
    ~1e-14 relative) h = 1e-6 leaves a truncation error h f'' / 2 ~ 5e-7 and a rounding error
    ~1e-8: Newton steps are then exact to ~1e-6 in u, a small fraction of a standard error."""
    e = np.eye(u.size) * h
    return np.array([(fun(u + e[i]) - f0) / h for i in range(u.size)])


def _fd_gradient_hessian(fun: Any, u: np.ndarray, h: float, hessian: bool
                         ) -> tuple[float, np.ndarray, np.ndarray | None]:
    """f(u), its central-difference gradient and (optionally) Hessian.

    Gradient: 1 + 2k evaluations; Hessian from the same points plus one pair per off-diagonal
    element, H_ij = (f(+i+j) + f(-i-j) - f(+i) - f(-i) - f(+j) - f(-j) + 2 f0) / (2 h^2)
    (second order accurate like the four-point formula, at half its cost)."""
    k = u.size
    f0 = fun(u)
    e = np.eye(k) * h
    fp = np.array([fun(u + e[i]) for i in range(k)])
    fm = np.array([fun(u - e[i]) for i in range(k)])
    g = (fp - fm) / (2.0 * h)
    if not hessian:
        return f0, g, None
    hess = np.diag((fp - 2.0 * f0 + fm) / h**2)
    for i in range(k):
        for j in range(i + 1, k):
            fpp = fun(u + e[i] + e[j])
            fmm = fun(u - e[i] - e[j])
            hess[i, j] = hess[j, i] = (fpp + fmm - fp[i] - fm[i] - fp[j] - fm[j] + 2.0 * f0) / (
                2.0 * h * h)
    return f0, g, hess


def _newton_refine(prof: _Profile, u0: np.ndarray, hess0: np.ndarray, f_best: float = math.inf,
                   max_iter: int = 12) -> tuple[np.ndarray, float, str]:
    """Quasi-Newton refinement of the profile likelihood on the full record from a warm start.

    hess0: Hessian of -log L / n in u from the prefix fit (per sample, so it applies to the
    full record up to sampling noise); forward-difference gradients (1 + k passes), a full
    step with backtracking, BFGS updates of the Hessian. Returns (u, -log L(u) / n, status):
    "converged" when
    the predicted gain g' H^-1 g / 2 falls below 1e-5 log-likelihood units (the L-BFGS-B
    criterion it replaces stopped at changes of ~1e-4, see _optimise); "behind" when even twice
    the predicted gain cannot bring -log L / n below f_best (another mode is better: no need
    to finish this one); "failed" otherwise (u is then the best point reached)."""
    bounds = np.array([_U_AR_BOUND] * (u0.size - 1) + [_U_SPLIT_BOUND])
    h = 1e-4
    u = np.clip(u0, -bounds + 2 * h, bounds - 2 * h)
    hess = hess0.copy()
    try:
        f = prof.negll(u)
        g = _forward_gradient(prof.negll, u, f)
        for _ in range(max_iter):
            if not (np.all(np.isfinite(g)) and math.isfinite(f)):
                return u, f, "failed"
            w, v = np.linalg.eigh(hess)
            w = np.maximum(w, 1e-8 * max(float(w.max()), 1e-12))
            step = -(v @ ((v.T @ g) / w))
            gain = -0.5 * float(g @ step) * prof.n
            if gain < 1e-5:
                return u, f, "converged"
            if (f - f_best) * prof.n > 2.0 * gain + 0.5:
                return u, f, "behind"
            t = 1.0
            for _ in range(30):
                un = np.clip(u + t * step, -bounds + 2 * h, bounds - 2 * h)
                fn = prof.negll(un)
                if fn <= f:
                    break
                t *= 0.5
            else:
                return u, f, ("converged" if gain < 1e-3 else "failed")
            gn = _forward_gradient(prof.negll, un, fn)
            s_, y_ = un - u, gn - g
            sy = float(s_ @ y_)
            if sy > 1e-12 * float(s_ @ s_):
                hs = hess @ s_
                hess = hess - np.outer(hs, hs) / float(s_ @ hs) + np.outer(y_, y_) / sy
            u, f, g = un, fn, gn
    except (ValueError, np.linalg.LinAlgError):
        return u, prof.negll(u), "failed"
    return u, f, "failed"


def _observed_stderr(prof: _Profile, model: str, a1: float, a2: float, w: float, s: float,
                     mean: float) -> dict[str, float]:
    """Standard errors from the inverse of minus the Hessian of log L in (a1, a2, q, r, mean).

    The likelihood is computed in phi = (theta, s, mean), theta the model's free subset of
    (a1, a2, w), q = s w, r = s (1 - w): one core pass at theta gives the sums from which log L
    and its derivatives in the scale s and the mean are exact (see filters/drift_likelihood.hpp),
    log L = -1/2 (n log 2 pi + S_logF + n log s + (S_ee - 2 d S_eg + d^2 S_gg) / s).
    Only theta is differenced (central differences, 1 + 2k + k(k-1)/2 passes: 13 for ar2+white
    instead of 33 when all four variances are differenced); the cross terms in s and the mean
    are central differences of their exact first derivatives. The Hessian is then carried to
    (a1, a2, q, r, mean) by the chain rule, including the gradient term of w(q, r)."""
    names = {"ar2+white": ["a1", "a2", "w"], "ar1+white": ["a1", "w"], "white": []}[model]
    vals = {"a1": a1, "a2": a2, "w": w}
    theta = np.array([vals[k] for k in names])
    k = theta.size
    d = mean - prof.center
    n = prof.n

    def parts(t: np.ndarray) -> np.ndarray:
        """(log L, d log L / d s, d log L / d mean) at (t, s, mean)."""
        p = dict(zip(names, t, strict=True))
        ww = p.get("w", 0.0)
        _, slog, see, seg, sgg = prof.sums(p.get("a1", 0.0), p.get("a2", 0.0), ww, 1.0 - ww,
                                           prof.center)
        sq = see - 2.0 * d * seg + d * d * sgg
        ll = -0.5 * (n * (_LOG_2PI + math.log(s)) + slog + sq / s)
        return np.array([ll, -0.5 * (n / s - sq / s**2), (seg - d * sgg) / s, sq, sgg])

    hphi = np.zeros((k + 2, k + 2))  # order: theta..., s, mean
    grad_w = 0.0
    try:
        # On the boundary (w = 0 or 1) no central difference fits inside [0, 1]: NaN standard
        # errors (caught below; internal, never reaches the caller).
        h = np.array([max(min(1e-4, 0.5 * v, 0.5 * (1.0 - v)), 0.0) if nm == "w" else 1e-4
                      for nm, v in zip(names, theta, strict=True)])
        if np.any(h <= 0):
            raise np.linalg.LinAlgError("on the boundary of the split")
        p0 = parts(theta)
        ei = np.eye(k) * h
        pp = [parts(theta + ei[i]) for i in range(k)]
        pm = [parts(theta - ei[i]) for i in range(k)]
        for i in range(k):
            hphi[i, i] = (pp[i][0] - 2.0 * p0[0] + pm[i][0]) / h[i] ** 2
            hphi[i, k] = hphi[k, i] = (pp[i][1] - pm[i][1]) / (2.0 * h[i])
            hphi[i, k + 1] = hphi[k + 1, i] = (pp[i][2] - pm[i][2]) / (2.0 * h[i])
            if names[i] == "w":
                grad_w = (pp[i][0] - pm[i][0]) / (2.0 * h[i])
            for j in range(i + 1, k):
                fpp = parts(theta + ei[i] + ei[j])[0]
                fmm = parts(theta - ei[i] - ei[j])[0]
                hphi[i, j] = hphi[j, i] = (fpp + fmm - pp[i][0] - pm[i][0] - pp[j][0]
                                           - pm[j][0] + 2.0 * p0[0]) / (2.0 * h[i] * h[j])
        sq, sgg = p0[3], p0[4]
        hphi[k, k] = -0.5 * (-n / s**2 + 2.0 * sq / s**3)
        hphi[k + 1, k + 1] = -sgg / s
        hphi[k, k + 1] = hphi[k + 1, k] = -p0[2] / s
        # Natural parameters psi = (theta without w, q, r, mean) (white: r, mean).
        q, r = s * w, s * (1.0 - w)
        nat = [nm for nm in names if nm != "w"] + (["q", "r"] if "w" in names else ["r"])
        jac = np.zeros((k + 2, len(nat) + 1))  # d phi / d psi
        for i, nm in enumerate(names):
            if nm != "w":
                jac[i, nat.index(nm)] = 1.0
        if "w" in names:
            iw, iq, ir = names.index("w"), nat.index("q"), nat.index("r")
            jac[iw, iq], jac[iw, ir] = r / s**2, -q / s**2
            jac[k, iq] = jac[k, ir] = 1.0
        else:
            jac[k, nat.index("r")] = 1.0
        jac[k + 1, len(nat)] = 1.0
        hess = jac.T @ hphi @ jac
        if "w" in names:  # + dL/dw * d^2 w / d psi^2 (w = q / (q + r))
            hess[iq, iq] += grad_w * (-2.0 * r / s**3)
            hess[ir, ir] += grad_w * (2.0 * q / s**3)
            hess[iq, ir] += grad_w * (q - r) / s**3
            hess[ir, iq] = hess[iq, ir]
        cov = np.linalg.inv(-hess)
        var = np.diag(cov)
        se = np.where(var > 0, np.sqrt(np.abs(var)), np.nan)
    except (ValueError, np.linalg.LinAlgError):
        nat = [nm for nm in names if nm != "w"] + (["q", "r"] if "w" in names else ["r"])
        se = np.full(len(nat) + 1, np.nan)
    out = {nm: math.nan for nm in ("a1", "a2", "q", "r", "mean")}
    for nm, v in zip([*nat, "mean"], se, strict=True):
        out[nm] = float(v)
    return out


def drift_fisher_information(a1: float, a2: float, q: float, r: float, n: int,
                             free: tuple[str, ...] = ("a1", "a2", "q", "r"),
                             n_freq: int = 1 << 15) -> np.ndarray:
    """Expected (Fisher) information of n samples about the drift model's parameters.

    Whittle's asymptotic form for a stationary Gaussian record with spectrum
    ``S(f) = q / |1 - a1 e^{-i w} - a2 e^{-2 i w}|^2 + r`` (w = 2 pi f / rate):
    I_jk = (n / 2) (1 / pi) int_0^pi d_j log S(w) d_k log S(w) dw, evaluated on n_freq
    midpoints (the mean is asymptotically orthogonal to these parameters and left out). The
    test holds it to the numerical Hessian of the exact expected log-likelihood.

    Parameters
    ----------
    a1, a2, q, r : float
        Model parameters (q, r in (record units)^2).
    n : int
        Record length, samples.
    free : tuple of str
        The parameters in the matrix, in this order (a subset of a1, a2, q, r).
    n_freq : int
        Frequency grid size.

    Returns
    -------
    numpy.ndarray, shape (len(free), len(free))

    Examples
    --------
    >>> info = drift_fisher_information(0.0, 0.0, 0.0, 2.0, 1000, free=("r",))
    >>> float(info[0, 0])   # n / (2 r^2) for white noise
    125.0
    """
    w = (np.arange(n_freq) + 0.5) * (math.pi / n_freq)
    z1 = np.exp(-1j * w)
    a_poly = 1.0 - a1 * z1 - a2 * z1 * z1
    a2abs = np.abs(a_poly) ** 2
    spec = q / a2abs + r
    rows = {
        "a1": 2.0 * q * np.real(np.conj(a_poly) * z1) / a2abs**2,
        "a2": 2.0 * q * np.real(np.conj(a_poly) * z1 * z1) / a2abs**2,
        "q": 1.0 / a2abs,
        "r": np.ones_like(w),
    }
    d = np.array([rows[k] for k in free]) / spec
    return np.asarray(0.5 * n * (d @ d.T) / n_freq)


def _profile_split(prof: _Profile, model: str, ratio: float,
                   starts: list[tuple[float, float]]) -> tuple[float, np.ndarray]:
    """Profile of the likelihood at a fixed split r/q = ratio: max over (a1, a2) (mean and scale
    concentrated out) from each start; returns (-log L / n, u) of the best."""
    w = 1.0 / (1.0 + ratio)
    u_split = math.log(w / (1.0 - w))
    k = 2 if model == "ar2+white" else 1

    def negll(v: np.ndarray) -> float:
        return prof.negll(np.r_[v, u_split])

    bounds = [(-_U_AR_BOUND, _U_AR_BOUND)] * k
    best_f, best_u = math.inf, np.zeros(k + 1)
    for a1, a2 in starts:
        v0 = _u_of(model, a1, a2, w)[:k]
        res = scipy.optimize.minimize(negll, v0, method="L-BFGS-B", jac="2-point", bounds=bounds,
                                      options={"ftol": 1e-3 / prof.n, "maxiter": 100})
        for v in (np.asarray(res.x), v0):
            f = negll(v)
            if f < best_f:
                best_f, best_u = f, np.r_[v, u_split]
    return best_f, best_u


def _yule_walker_at(c: list[float], model: str, w: float) -> tuple[float, float]:
    """(a1, a2) from the sample autocovariances c = [c0, c1, c2] when a share 1 - w of the
    variance is white."""
    g0 = c[0] * w
    if model == "ar1+white":
        return max(min(c[1] / g0, 0.99), -0.99), 0.0
    det = g0 * g0 - c[1] * c[1]
    if det <= 0:
        return 0.0, 0.0
    a1 = (c[1] * g0 - c[1] * c[2]) / det
    a2 = max(min((c[2] * g0 - c[1] * c[1]) / det, 0.99), -0.99)
    return max(min(a1, 0.99 * (1.0 - a2)), -0.99 * (1.0 - a2)), a2


def _split_check(prof: _Profile, model: str, u_ml: np.ndarray
                 ) -> tuple[tuple[float, float], tuple[float, float, float, float] | None]:
    """Is the drift/white split identified? Profile log-likelihood drops at r/q = 0.1 and 10.

    Returns ((drop at r/q = 0.1, drop at r/q = 10), minimax tuning or None). Both drops below
    _SPLIT_DROP_MIN = 4 mean the record does not reject "white noise 10x the drift" nor "drift
    10x the white noise" (at 99.5 %); a fit that does not beat the white model by BIC has found
    no drift to split. Either way the split is not identified, and the tuning returned is the
    profile fit at q = r, (a1, a2, q, r). Why q = r: for such (nearly white) drift a gain g
    gives the error (1 - g)^2 q + g^2 r; over all splits of the identified total q + r its
    worst case is smallest, a quarter of the total, at g = 1/2, the steady-state gain of q = r
    (minimax; the drift model validation page and scripts/drift_identifiability.py give the
    numbers). Records longer
    than _PROFILE_N are profiled on their first _PROFILE_N samples with the drops scaled by
    n / _PROFILE_N (the expected drop grows in proportion to n)."""
    if model == "white":
        return (math.inf, math.inf), None
    n = prof.n
    sub = (prof if n <= _PROFILE_N and not isinstance(prof.x, _Pieces)
           else _Profile(_head(prof.x, _PROFILE_N), model, prof.center))
    f_ml = sub.negll(u_ml)
    a1, a2, _ = prof.natural(u_ml)
    assert not isinstance(sub.x, _Pieces)
    c_sub = _autocov(sub.x - prof.center)
    drops = []
    for ratio in _SPLIT_PROBES:
        f, _ = _profile_split(sub, model, ratio, [(a1, a2), _yule_walker_at(c_sub, model,
                                                                             1.0 / (1.0 + ratio))])
        drops.append(max(f - f_ml, 0.0) * n)
    prof.evaluations += sub.evaluations if sub is not prof else 0
    # Evidence of any drift structure at all: the model must beat "white noise + mean" by BIC.
    # If it does not, the drift cannot be told from white noise whatever the probes say (the
    # fit then sits in a spurious mode, e.g. a weak sharp resonance, that can make the probes'
    # drops exceed the threshold: seen on -0.0069/0.0113 at 6e4 samples).
    if isinstance(prof.x, _Pieces):
        ss = prof.x.moments(prof.center)[1]
    else:
        dx = prof.x - float(np.mean(prof.x))
        ss = float(dx @ dx)
    ll_white = -0.5 * n * (_LOG_2PI + math.log(ss / n) + 1.0)
    ll_ml = -prof.negll(u_ml) * n
    beats_white = ll_ml - ll_white > 0.5 * (_N_PARAMS[model] - _N_PARAMS["white"]) * math.log(n)
    if beats_white and max(drops) > _SPLIT_DROP_MIN:
        return (drops[0], drops[1]), None
    return (drops[0], drops[1]), _minimax_tuning(prof, model, a1, a2)


def _minimax_tuning(prof: _Profile, model: str, a1: float, a2: float
                    ) -> tuple[float, float, float, float]:
    """The tuning of a split that is not identified: the profile fit at q = r on the whole
    record, (a1, a2, q, r) (see _split_check)."""
    _, u = _profile_split(prof, model, 1.0, [(a1, a2), _yule_walker_at(
        _autocov_around(prof.x, prof.center), model, 0.5)])
    b1, b2, w = prof.natural(u)
    _, scale, _ = prof.concentrated(b1, b2, w)
    return (b1, b2, scale * w, scale * (1.0 - w))


#: The parameters of each model whose standard errors must exist for its drift/white split
#: to count as identified.
_FREE_PARAMS = {"ar2+white": ("a1", "a2", "q", "r"), "ar1+white": ("a1", "q", "r"),
                "white": ()}


def ljung_box(e: np.ndarray, lags: int, model_df: int = 0) -> LjungBox:
    """Ljung-Box Q of a series (mean removed) with `lags` autocorrelations and chi-square
    degrees of freedom lags - model_df (at least 1)."""
    z = np.asarray(e, dtype=np.float64)
    z = z - z.mean()
    n = z.size
    c0 = float(z @ z)
    rho = np.array([float(z[:-k] @ z[k:]) / c0 for k in range(1, lags + 1)])
    q = float(n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1))))
    df = max(lags - model_df, 1)
    return LjungBox(statistic=q, pvalue=float(scipy.stats.chi2.sf(q, df)), lags=lags, df=df)


def _prepare(x: object) -> np.ndarray:
    a = np.asarray(x)
    if a.dtype.kind not in "fiu" or a.dtype == np.float16:
        raise GyrodriftTypeError(f"x must be a real numeric array, got dtype {a.dtype}")
    a = a.astype(np.float64, copy=False)
    if a.ndim != 1:
        raise GyrodriftValueError(f"x must have shape (n,) or (n, 3), got {a.shape}")
    return a


def _finish(prof: _Profile, model: str, a1: float, a2: float, w: float, s: float, mean: float,
            rate_hz: float, start_ll: float,
            split: tuple[tuple[float, float], tuple[float, float, float, float] | None],
            fold: tuple[float, float] = (math.nan, math.nan)) -> DriftModelFit:
    n = prof.n
    q, r = s * w, s * (1.0 - w)
    lags = max(1, min(10, n // 5))
    if isinstance(prof.x, _Pieces):
        stream = prof.core.DriftLoglikeStream(a1=a1, a2=a2, q=q, r=r, mean=mean)
        lag_sums = _LagSums(lags)
        for piece in prof.x.pieces():
            innov = np.empty(piece.size)
            stream.update(piece, innov)
            lag_sums.add(innov)
        ll = stream.result()[0]
        lb = lag_sums.result(_MODEL_DF[model])
    else:
        innov = np.empty(n)
        ll = prof.core.drift_loglike(prof.x, a1, a2, q, r, mean, innov)[0]
        lb = ljung_box(innov, lags, _MODEL_DF[model])
    stderr = _observed_stderr(prof, model, a1, a2, w, s, mean)
    k = _N_PARAMS[model]
    split_drop, minimax = split
    # The probes' drops say the split is identified, but a standard error that does not exist
    # (NaN: the likelihood is flat or singular at the estimate) or a zero drop says the
    # estimate is not: then the split is not identified either, and the filter is tuned as
    # for any split that is not (minimax, q = r).
    if minimax is None and model != "white" and (
            any(not math.isfinite(stderr[k]) for k in _FREE_PARAMS[model])
            or min(split_drop) <= 0.0):
        minimax = _minimax_tuning(prof, model, a1, a2)
    identified = minimax is None
    filter_params = (a1, a2, q, r) if minimax is None else minimax
    return DriftModelFit(
        model=model, a1=a1, a2=a2, q=q, r=r, mean=mean, loglike=ll,
        aic=2.0 * k - 2.0 * ll, bic=k * math.log(n) - 2.0 * ll, stderr=stderr, n=n,
        rate_hz=rate_hz, ljung_box=lb,
        start_loglike=start_ll, n_evaluations=prof.evaluations, split_drop=split_drop,
        identified=identified, tuning="ml" if identified else "minimax-split",
        filter_params=tuple(float(v) for v in filter_params),  # type: ignore[arg-type]
        fold_a2=float(fold[0]), fold_loglike=float(fold[1]))


def _fit_1d(a: np.ndarray | _Pieces, rate_hz: float, model: str) -> DriftModelFit:
    # Both reject too short / constant / non-finite records (Ar2FitError).
    burg = a.stats()[0] if isinstance(a, _Pieces) else fit_ar2(a, "burg")
    assert isinstance(burg, Ar2Model)
    center = burg.mean
    if model == "white":
        prof = _Profile(a, model, center)
        if isinstance(a, _Pieces):
            mean, ss = a.moments(center)
            r = ss / a.shape[0]
        else:
            d = a - center
            mean = center + float(d.mean())
            r = float(np.mean((a - mean) ** 2))
        if not r > 0:
            raise Ar2FitError("constant", "all samples are equal")
        return _finish(prof, model, 0.0, 0.0, 0.0, r, mean, rate_hz, math.nan,
                       ((math.inf, math.inf), None))
    starts = _moment_starts(_autocov_around(a, center), model, burg)
    prof = _Profile(a, model, center)
    if a.shape[0] > 2 * _WARM_START_N:
        # Multi-start on a prefix of the long record, then Newton steps on the whole record
        # from its modes, with the prefix's Hessian (per sample) as the first curvature: 2-3
        # steps of 1 + k passes instead of ~75 passes of L-BFGS-B with finite differences.
        # Every distinct prefix mode within _MODE_KEEP_LL of the best is refined: on a prefix
        # of 2^14 samples two modes (e.g. r -> 0 and an interior split) can be tied within
        # 0.1, and the full record then prefers the other one by over 1 log-likelihood unit.
        pre = _Profile(_head(a, _WARM_START_N), model, center)
        modes = sorted(_prefix_modes(pre, starts), key=prof.negll)
        start_ll = -prof.negll(modes[0]) * prof.n
        u, f_u, status = modes[0], math.inf, "failed"
        for u_pre in modes:  # best first on the full record
            _, _, hess_pre = _fd_gradient_hessian(pre.negll, u_pre, 1e-4, hessian=True)
            assert hess_pre is not None
            cand, f_c, st = _newton_refine(prof, u_pre, hess_pre, f_best=f_u)
            if st != "behind" and f_c < f_u:
                u, f_u, status = cand, f_c, st
        if status == "failed":  # the general optimiser from the best point reached
            cand = _optimise(prof, u, tight=True)
            u = cand if prof.negll(cand) <= f_u else u
        fold_pre: _Profile | None = pre
    else:
        start_ll = -min(prof.negll(u) for u in starts) * prof.n
        u = _best_of(prof, starts)
        fold_pre = None
    fold = (math.nan, math.nan)
    # (an estimate on the fold itself, |a2| < _ON_FOLD, is its own mirror: no run)
    if model == "ar2+white" and abs(u[1]) >= _ON_FOLD:
        # Across the fold a2 = 0 (module docstring): when the estimate is next to it, one more
        # run from its mirror; the higher maximum is the fit, the other one is reported
        # (DriftModelFit.fold_a2, fold_loglike).
        a1, a2, w = prof.natural(u)
        _, s, _ = prof.concentrated(a1, a2, w)
        if _next_to_fold(a1, a2, s * w, s * (1.0 - w), prof.n):
            other = _across_fold(prof, u, fold_pre)
            f_u, f_o = prof.negll(u), prof.negll(other)
            if f_o < f_u:
                u, other, f_u, f_o = other, u, f_o, f_u
            # a distinct maximum on the other side, not the same one on the fold itself
            if (np.sign(other[1]) * np.sign(u[1]) < 0.0
                    and np.max(np.abs(other - u)) > _MODE_DISTINCT_U):
                fold = (prof.natural(other)[1], -f_o * prof.n)
    if fold_pre is not None:
        prof.evaluations += fold_pre.evaluations
    a1, a2, w = prof.natural(u)
    _, s, mean = prof.concentrated(a1, a2, w)
    split = _split_check(prof, model, u)
    return _finish(prof, model, a1, a2, w, s, mean, rate_hz, start_ll, split, fold)


def fit_drift_model(
    x: object, rate_hz: float, model: str = "ar2+white", method: str = "ml"
) -> DriftModelFit | tuple[DriftModelFit, ...]:
    """Fit the drift model to a rate record by exact maximum likelihood.

    Parameters
    ----------
    x : array_like, shape (n,) or (n, 3)
        Rate record in any units (q, r come out in those units squared). (n, 3): one fit per
        axis, returned as a tuple.
    rate_hz : float
        Sample rate, Hz (kept in the result for the filter's bandwidth).
    model : {"ar2+white", "ar1+white", "white"}
    method : {"ml"}
        Maximum likelihood (the only method).

    Returns
    -------
    DriftModelFit (or a tuple of three for (n, 3) input)

    Raises
    ------
    Ar2FitError
        Too short (< 8 samples), constant, or non-finite record (as `fit_ar2`).
    GyrodriftValueError
        Unknown model/method, bad rate_hz or shape.
    GyrodriftTypeError
        Non-numeric input.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> rng = np.random.default_rng(1)
    >>> drift = lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(0, 0.5, 20000))
    >>> y = drift + rng.normal(0, 0.3, 20000)
    >>> fit = fit_drift_model(y, rate_hz=100.0)
    >>> abs(fit.a1 - 0.6868) < 4 * fit.stderr["a1"]
    True
    >>> out = fit.kalman().process(y)   # the drift estimate
    """
    if model not in DRIFT_MODELS:
        raise GyrodriftValueError(
            f"unknown drift model {model!r}; use one of {', '.join(DRIFT_MODELS)}")
    if method != "ml":
        raise GyrodriftValueError(f"unknown method {method!r}; use 'ml'")
    rate = float(rate_hz)
    if not (math.isfinite(rate) and rate > 0):
        raise GyrodriftValueError(f"rate_hz must be finite and > 0, got {rate_hz!r}")
    # One BLAS thread: scipy's L-BFGS-B calls BLAS on 3-vectors, and OpenBLAS's thread
    # hand-off then costs more than the whole likelihood (measured 1.3 -> 0.5 s CPU on a 1e6
    # fit on 2 cores; on a loaded machine a trivial 3-parameter minimize took 45 ms instead of 2).
    if is_file_backed(x) and np.asarray(x).dtype == np.float64 and len(x) > _PIECE:  # type: ignore[arg-type]
        # read from its file in pieces (module docstring): memory independent of its length
        with threadpool_limits(limits=1, user_api="blas"):
            return _fit_normalised(x, rate, model)  # type: ignore[arg-type]
    a = np.asarray(x)
    with threadpool_limits(limits=1, user_api="blas"):
        if a.ndim == 2 and a.shape[1] == 3:
            return tuple(_fit_normalised(_prepare(a[:, i]), rate, model) for i in range(3))
        return _fit_normalised(_prepare(a), rate, model)


def _fit_normalised(a: np.ndarray, rate_hz: float, model: str) -> DriftModelFit:
    """`_fit_1d` of a record scaled into the safe range (`normalising_scale`), its fit scaled
    back: q, r, their standard errors and the filter's q, r by c^2; mean by c;
    log-likelihoods by -n ln c (the density of c x); AIC and BIC accordingly. a1, a2, the
    Ljung-Box test and the split drops do not depend on the scale. A record of extreme
    magnitude (1e150, 1e-150) failed with OverflowError/ZeroDivisionError before. A file-backed
    record is scaled piece by piece as it is read (_Pieces)."""
    if is_file_backed(a):
        peak = 0.0
        for p in iter_chunks(a, _PIECE):
            peak = max(peak, float(np.max(p)), -float(np.min(p)))
        c = scale_for_peak(peak)
        fit = _fit_1d(_Pieces(a, c), rate_hz, model)
        if c == 1.0:
            return fit
    else:
        c = normalising_scale(a)
        if c == 1.0:
            return _fit_1d(a, rate_hz, model)
        fit = _fit_1d(a / c, rate_hz, model)
    c2 = c * c
    dll = fit.n * math.log(c)
    scale = {"a1": 1.0, "a2": 1.0, "q": c2, "r": c2, "mean": c}
    a1, a2, q, r = fit.filter_params
    return replace(
        fit, q=fit.q * c2, r=fit.r * c2, mean=fit.mean * c, loglike=fit.loglike - dll,
        aic=fit.aic + 2.0 * dll, bic=fit.bic + 2.0 * dll, start_loglike=fit.start_loglike - dll,
        fold_loglike=fit.fold_loglike - dll,
        stderr={k: v * scale.get(k, 1.0) for k, v in fit.stderr.items()},
        filter_params=(a1, a2, q * c2, r * c2))


def compare_drift_models(x: object, rate_hz: float, criterion: str = "aic"
                         ) -> DriftModelComparison:
    """Fit all three models to a 1-D record and choose the one with the lowest AIC or BIC.

    Examples
    --------
    >>> from scipy.signal import lfilter
    >>> rng = np.random.default_rng(1)  # AR(1) drift (a1 0.85) under white noise
    >>> x = lfilter([1.0], [1.0, -0.85], rng.normal(0, 1, 1000)) + rng.normal(0, 0.7, 1000)
    >>> cmp_ = compare_drift_models(x, 100.0)
    >>> [f.model for f in cmp_.fits], cmp_.chosen
    (['ar2+white', 'ar1+white', 'white'], 'ar1+white')
    """
    if criterion not in ("aic", "bic"):
        raise GyrodriftValueError(f"criterion must be 'aic' or 'bic', got {criterion!r}")
    fits = tuple(fit_drift_model(x, rate_hz, m) for m in DRIFT_MODELS)
    if not all(isinstance(f, DriftModelFit) for f in fits):
        raise GyrodriftValueError("compare_drift_models takes a 1-D record")
    chosen = min(fits, key=lambda f: getattr(f, criterion)).model  # type: ignore[union-attr]
    return DriftModelComparison(fits=fits, criterion=criterion, chosen=chosen)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- filter response


def steady_state_response(a1: float, a2: float, q: float, r: float, rate_hz: float
                          ) -> FilterResponse:
    """Frequency response of the steady-state AR(2)-Kalman filter as a filter of the record:
    X_k = (I - K C) A X_{k-1} + K y_k, output C X_k, so
    H(z) = C (I - (I - K C) A z^-1)^-1 K; DC gain H(1); -3 dB point where
    ``|H| = |H(1)| / sqrt 2``.
    The gain K comes from the C++ DARE solver (Ar2SteadyStateKalman).

    Examples
    --------
    >>> resp = steady_state_response(0.6, 0.2, q=1.0, r=0.25, rate_hz=100.0)
    >>> round(resp.dc_gain, 4), resp.as_dict()["bandwidth_hz"]
    (0.957, None)
    """
    ar2 = core("ar2")
    k0, k1 = ar2.Ar2SteadyStateKalman(
        ar2.Ar2KalmanSettings(a1=a1, a2=a2, sigma2=q, mean=0.0, q=q, r=r)).gain
    kv = np.array([k0, k1])
    a = np.array([[a1, a2], [1.0, 0.0]])
    abar = (np.eye(2) - np.outer(kv, [1.0, 0.0])) @ a

    def mag(f_hz: float) -> float:
        z = np.exp(1j * 2.0 * math.pi * f_hz / rate_hz)
        return float(abs(np.linalg.solve(np.eye(2) - abar / z, kv)[0]))

    dc = float(np.linalg.solve(np.eye(2) - abar, kv)[0])
    bw: float | None = None
    if abs(dc) > 0:
        target = abs(dc) / math.sqrt(2.0)
        grid = np.linspace(0.0, rate_hz / 2.0, 2049)
        m = np.array([mag(f) for f in grid])
        below = np.nonzero(m < target)[0]
        if below.size:
            i = int(below[0])
            bw = float(scipy.optimize.brentq(lambda f: mag(f) - target, grid[i - 1], grid[i]))
    return FilterResponse(gain=(float(k0), float(k1)), dc_gain=dc, bandwidth_hz=bw)


# ---------------------------------------------------------------------- fits at a lower rate

#: choose_decimation: the block length is at most this fraction of the Allan-minimum tau
#: (the drift then spans many blocks), and leaves at least DECIMATION_MIN_BLOCKS blocks.
DECIMATION_TAU_FRACTION = 1.0 / 20.0
DECIMATION_MIN_BLOCKS = 2000
#: Below this factor the record is fitted at its own rate.
DECIMATION_MIN_FACTOR = 4


def choose_decimation(tau_s: np.ndarray, adev: np.ndarray, rate_hz: float, n: int) -> int:
    """The block length (samples) to average a record over before fitting its drift model:
    the largest power of two whose duration is at most DECIMATION_TAU_FRACTION of the tau of
    the Allan minimum (where averaging the white noise stops paying and the drift takes over)
    and that leaves at least DECIMATION_MIN_BLOCKS blocks; 1 (no decimation) below
    DECIMATION_MIN_FACTOR.

    Examples
    --------
    >>> tau = np.logspace(-2, 3, 30); adev = np.sqrt(1e-2 / tau + 1e-5 * tau)  # minimum at 32 s
    >>> choose_decimation(tau, adev, 100.0, 10**6)
    128
    >>> choose_decimation(tau, adev, 100.0, 10**5)   # 2000 blocks at most
    32
    """
    tau = np.asarray(tau_s, dtype=np.float64)
    dev = np.asarray(adev, dtype=np.float64)
    ok = np.isfinite(dev) & (dev > 0)
    if not np.any(ok) or not (math.isfinite(rate_hz) and rate_hz > 0):
        return 1
    tau_min = float(tau[ok][np.argmin(dev[ok])])
    limit = min(tau_min * DECIMATION_TAU_FRACTION * rate_hz, n / DECIMATION_MIN_BLOCKS)
    if limit < DECIMATION_MIN_FACTOR:
        return 1
    return int(2 ** math.floor(math.log2(limit)))


def block_average(x: np.ndarray, factor: int) -> np.ndarray:
    """Means of consecutive blocks of `factor` samples (a trailing partial block dropped).

    Examples
    --------
    >>> block_average(np.arange(7.0), 3).tolist()
    [1.0, 4.0]
    """
    if factor < 1:
        raise GyrodriftValueError(f"factor must be >= 1, got {factor!r}")
    if is_file_backed(x):  # read from its file, whole blocks at a time (module docstring)
        m = x.shape[0] // factor
        step = factor * max(1, _PIECE // factor)
        out = [p[: p.size // factor * factor].reshape(-1, factor).astype(np.float64).mean(axis=1)
               for p in iter_chunks(x, step)]
        return np.concatenate(out)[:m] if out else np.empty(0)
    a = np.asarray(x, dtype=np.float64)
    m = a.size // factor
    return a[:m * factor].reshape(m, factor).mean(axis=1)


def drift_params_at_rate(a1: float, a2: float, q: float, r: float, factor: int
                         ) -> tuple[float, float, float, float]:
    """Map an AR(2) + white model fitted on block averages of `factor` samples back to the
    original sample period: (a1, a2, q, r) there.

    Derivation (valid when the drift's correlation time is long against a block, the case
    decimation is for): the AR(2) recursion x_k = a1 x_{k-1} + a2 x_{k-2} + w_k has poles
    z_1, z_2, the roots of z^2 - a1 z - a2, and decays as z_i^k; one block step of `factor`
    samples multiplies by z_i^factor, so the original period's poles are the principal
    roots z_i^(1/factor) (a complex pair rho e^(+-i theta) -> rho^(1/factor)
    e^(+-i theta / factor)), and a1 = z_1 + z_2, a2 = -z_1 z_2. Averaging over a block hardly
    changes a slow drift, so its stationary variance
    gamma_0 = q (1 - a2) / ((1 + a2) ((1 - a2)^2 - a1^2)) is kept, which gives q at the
    original poles. The average of `factor` white samples of variance r has variance
    r / factor, so r = factor r_block.

    Raises
    ------
    GyrodriftValueError
        a negative real pole (an oscillation at the block rate's Nyquist frequency has no
        slow original), a non-stationary model, or factor < 1.

    Examples
    --------
    >>> a1, a2, q, r = drift_params_at_rate(0.9**4 + 0.5**4, -(0.9 * 0.5)**4, 1.0, 0.1, 4)
    >>> round(a1, 12), round(a2, 12), round(r, 12)   # poles 0.9, 0.5 at the original rate
    (1.4, -0.45, 0.4)
    """
    if factor < 1:
        raise GyrodriftValueError(f"factor must be >= 1, got {factor!r}")
    if factor == 1:
        return a1, a2, q, r
    roots = np.roots([1.0, -a1, -a2])
    if np.any(np.abs(roots) >= 1.0):
        raise GyrodriftValueError(f"AR(2) ({a1:g}, {a2:g}) is not stationary")
    real = np.abs(roots.imag) <= 1e-12 * np.maximum(np.abs(roots), 1e-300)
    if np.any(real & (roots.real < 0)):
        raise GyrodriftValueError(
            f"AR(2) ({a1:g}, {a2:g}) has a negative real pole: no slower model at the "
            f"original rate (fit it there)")
    orig = np.where(real, np.abs(roots.real) ** (1.0 / factor) + 0j,
                    np.abs(roots) ** (1.0 / factor) * np.exp(1j * np.angle(roots) / factor))
    b1 = float(np.real(orig[0] + orig[1]))
    b2 = float(-np.real(orig[0] * orig[1])) + 0.0  # no -0.0

    def gamma0_per_q(c1: float, c2: float) -> float:
        return (1.0 - c2) / ((1.0 + c2) * ((1.0 - c2) ** 2 - c1 * c1))

    q_orig = q * gamma0_per_q(a1, a2) / gamma0_per_q(b1, b2)
    return b1, b2, q_orig, r * factor
