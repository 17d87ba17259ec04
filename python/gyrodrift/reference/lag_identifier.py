"""numpy reference: the drift model re-identified from lag statistics on a schedule (the
C++ ``LagDriftIdentifier``, include/gyrodrift/filters/lag_drift_identifier.hpp), written from
its equations with the reference's statistics and fit (`gyrodrift.reference.lag_drift`).

Per channel: lag statistics of its samples (`LagStatisticsReference`, L lags; the likelihood
kind ``"whittle_no_head"`` reads no first values). Schedule, per channel c of n, with the
cadence C = block_samples * retune_blocks (push and skip both count a sample):

- a fit is requested when the channel's count reaches C + c C // n, then every C; while another
  channel's fit waits for its apply point the request is tried again at the next sample;
- at the request, if the statistics hold at least max(min_samples, 2 L + 2) samples, the fit
  runs and the statistics pause (samples counted, not pushed) until the apply point, the
  request's count + fit_delay_samples; there the outcome applies and the statistics resume
  (emptied first with restart_after_fit);
- the fit: `lag_drift_fit` (adapt_ar), or with a1, a2 held at the configured model the
  profile maximised over u3 = logit(q / (q + r)) alone (scipy's BFGS from the best of the
  splits 0.02, 0.1, ..., 0.9, 0.98); status ``"truncation"`` when rho^L exceeds 3e-3, else
  ``"ok"``;
- the guards: the Hessian of f(u) = -(profile log-likelihood) / n at the fit's u by central
  differences (step 1e-3; `lag_profile`), Cov(u) = inv(n H) (Cholesky: not positive definite
  means not identified); relative standard errors of q and r as (1 - lam) SE(u3) and
  lam SE(u3), at most max_rel_stderr; with adapt_ar the Wald statistic of (u1, u2) at least
  min_ar_wald;
- accepted: the model in use moves toward the fit in (u1, u2, log q, log r), the step scaled
  as a whole to at most max_step (the mean is the fit's; within max_step the fit itself), and
  its gain is the stabilising DARE solution's (`steady_state_gain`); refused: the configured
  model and its gain.

Float64; the statistics are pushed a run of samples at a time between events.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.filters.ar2 import Ar2Model
from gyrodrift.reference.ar2 import steady_state_gain
from gyrodrift.reference.lag_drift import (
    LagDriftFit,
    LagStatisticsReference,
    innovation_pole,
    lag_drift_fit,
    lag_profile,
)

__all__ = ["LagIdentifierEvent", "LagIdentifierReference"]

_KIND = "whittle_no_head"
_TRUNCATION_TOL = 3e-3  # the kind's truncation tolerance (lag_drift_fit.hpp)
_HESSIAN_STEP = 1e-3
_SPLITS = (0.02, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.98)

Model = tuple[float, float, float, float, float]  # a1, a2, q, r, mean


def _atanh(p: float) -> float:
    return 0.5 * math.log((1.0 + p) / (1.0 - p))


@dataclass(frozen=True)
class LagIdentifierEvent:
    """One applied fit: the channel, its sample count at the apply point, the fit's status
    (``"ok"``, ``"truncation"``), the outcome (``"tracking"``: accepted; ``"not_identified"``,
    ``"fallback"``: refused), the fit, the covariance of its free u coordinates and the model
    and gain in use from then on.

    Examples
    --------
    >>> e = LagIdentifierEvent(0, 3500, "ok", "tracking", None, None,
    ...                        (0.5, 0.0, 1.0, 1.0, 0.0), (0.5, 0.4))
    >>> e.accepted
    True
    """

    channel: int
    sample: int
    fit_status: str
    status: str
    fit: LagDriftFit | None
    cov_u: np.ndarray | None
    model: Model
    gain: tuple[float, float]

    @property
    def accepted(self) -> bool:
        """Whether the fit was taken (status tracking)."""
        return self.status == "tracking"


@dataclass
class _Channel:
    configured: Model
    gain0: tuple[float, float]
    stats: LagStatisticsReference
    in_use: Model
    gain: tuple[float, float]
    next_request: int
    samples: int = 0
    paused: int = 0
    apply_at: int = 0  # 0: collecting
    pending: LagIdentifierEvent | None = None
    events: list[LagIdentifierEvent] = field(default_factory=list)


class LagIdentifierReference:
    """The scheduled lag-statistics re-identification of n channels (module docstring).

    Parameters
    ----------
    models : sequence of (a1, a2, q, r, mean)
        Each channel's configured model (its start and fallback; r > 0).
    block_samples, retune_blocks : int
        The cadence is their product (samples of a channel between fits).
    min_samples : int
        No fit from fewer statistics samples.
    max_step : float
        Largest step of the model in use per retune in (u1, u2, log q, log r).
    max_rel_stderr, min_ar_wald : float
        The identification guards.
    adapt_ar : bool
        False: a1, a2 held at the configured model, the split fitted.
    fit_delay_samples : int
        Samples from a fit's request to its apply point.
    restart_after_fit : bool
        Empty the statistics after each fit.
    lags : int
        L of the statistics.

    Examples
    --------
    >>> from scipy.signal import lfilter
    >>> rng = np.random.default_rng(0)
    >>> y = lfilter([1.0], [1.0, -0.9, 0.2], rng.normal(size=4000)) + rng.normal(size=4000)
    >>> ref = LagIdentifierReference([(0.5, 0.0, 1.0, 1.0, 0.0)], block_samples=100,
    ...                              retune_blocks=30, min_samples=2000, max_step=10.0,
    ...                              fit_delay_samples=500)
    >>> ref.run(y[:, None])
    >>> [(e.sample, e.status) for e in ref.events(0)]
    [(3500, 'tracking')]
    """

    def __init__(self, models: Sequence[Sequence[float]], *, block_samples: int = 400,
                 retune_blocks: int = 60, min_samples: int = 240000, max_step: float = 0.1,
                 max_rel_stderr: float = 0.5, min_ar_wald: float = 25.0, adapt_ar: bool = True,
                 fit_delay_samples: int = 12000, restart_after_fit: bool = False,
                 lags: int = 8) -> None:
        self.cadence = int(block_samples) * int(retune_blocks)
        n = len(models)
        if n < 1 or n * int(fit_delay_samples) > self.cadence:
            raise GyrodriftValueError(
                "expected 1 or more channels and n * fit_delay_samples <= cadence")
        self.min_samples = max(int(min_samples), 2 * lags + 2)
        self.max_step = float(max_step)
        self.max_rel_stderr = float(max_rel_stderr)
        self.min_ar_wald = float(min_ar_wald)
        self.adapt_ar = bool(adapt_ar)
        self.fit_delay = int(fit_delay_samples)
        self.restart = bool(restart_after_fit)
        self.lags = int(lags)
        self._owner: int | None = None
        self._ch: list[_Channel] = []
        for c, m in enumerate(models):
            cfg = tuple(float(v) for v in m)
            if len(cfg) != 5 or not cfg[3] > 0.0:
                raise GyrodriftValueError(f"models[{c}]: expected (a1, a2, q, r, mean) with r > 0")
            g = self._gain(cfg)
            self._ch.append(_Channel(configured=cfg, gain0=g, stats=LagStatisticsReference(lags),
                                     in_use=cfg, gain=g,
                                     next_request=self.cadence + c * self.cadence // n))

    # ------------------------------------------------------------------ state
    def in_use(self, c: int) -> Model:
        """The model in use of channel c.

        Examples
        --------
        >>> LagIdentifierReference([(0.5, 0.0, 1.0, 1.0, 0.0)]).in_use(0)
        (0.5, 0.0, 1.0, 1.0, 0.0)
        """
        return self._ch[c].in_use

    def events(self, c: int) -> list[LagIdentifierEvent]:
        """The applied fits of channel c, in order.

        Examples
        --------
        >>> LagIdentifierReference([(0.5, 0.0, 1.0, 1.0, 0.0)]).events(0)
        []
        """
        return list(self._ch[c].events)

    # ------------------------------------------------------------------ samples
    def run(self, y: np.ndarray, used: np.ndarray | None = None) -> None:
        """Push samples: ``y[i, c]`` is channel c's sample at step i (the channels in order
        within a step); ``used[i, c]`` False (or a non-finite value) counts the sample for the
        schedule but not for the statistics (a skip).

        Examples
        --------
        >>> ref = LagIdentifierReference([(0.5, 0.0, 1.0, 1.0, 0.0)])
        >>> ref.run(np.zeros((10, 1)))
        >>> ref.events(0)
        []
        """
        y = np.asarray(y, dtype=np.float64)
        if y.ndim != 2 or y.shape[1] != len(self._ch):
            raise GyrodriftValueError(
                f"y: expected shape (samples, {len(self._ch)}), got {y.shape}")
        ok = np.isfinite(y) if used is None else np.asarray(used, dtype=bool) & np.isfinite(y)
        i, total = 0, y.shape[0]
        while i < total:
            # the next step at which some channel has an event (its count after the step)
            nxt = min(self._event_count(ch) for ch in self._ch) - self._ch[0].samples - 1
            j = min(total, i + max(nxt, 0))
            for c, ch in enumerate(self._ch):  # a run of steps without events
                if ch.apply_at == 0:
                    ch.stats.push(y[i:j, c][ok[i:j, c]])
                else:
                    ch.paused += j - i
                ch.samples += j - i
            i = j
            if i < total:
                for c in range(len(self._ch)):
                    self._step(c, float(y[i, c]), bool(ok[i, c]))
                i += 1

    def _event_count(self, ch: _Channel) -> int:
        if ch.apply_at != 0:
            return ch.apply_at
        # a request the shared fit blocks is tried again at every sample
        return ch.next_request if ch.next_request > ch.samples else ch.samples + 1

    def _step(self, c: int, y: float, ok: bool) -> None:
        ch = self._ch[c]
        ch.samples += 1
        if ch.apply_at == 0:
            if ok:
                ch.stats.push(np.array([y]))
            if ch.samples >= ch.next_request:
                self._request(c)
        else:
            ch.paused += 1
            if ch.samples >= ch.apply_at:
                self._apply(c)

    def _request(self, c: int) -> None:
        ch = self._ch[c]
        if self._owner is not None:
            return
        while ch.next_request <= ch.samples:
            ch.next_request += self.cadence
        if ch.stats.n < self.min_samples:
            return
        self._owner = c
        ch.apply_at = ch.samples + self.fit_delay
        ch.pending = self._fit(ch)
        if ch.samples >= ch.apply_at:
            self._apply(c)

    def _apply(self, c: int) -> None:
        ch = self._ch[c]
        assert ch.pending is not None
        e = LagIdentifierEvent(c, ch.samples, ch.pending.fit_status, ch.pending.status,
                               ch.pending.fit, ch.pending.cov_u, ch.pending.model,
                               ch.pending.gain)
        ch.events.append(e)
        ch.in_use, ch.gain = e.model, e.gain
        ch.pending = None
        ch.apply_at = 0
        if self.restart:
            ch.stats = LagStatisticsReference(self.lags)
        self._owner = None

    # ------------------------------------------------------------------ the fit
    @staticmethod
    def _gain(m: Model) -> tuple[float, float]:
        k = steady_state_gain(Ar2Model(m[0], m[1], m[2], 0.0), m[2], m[3])
        return float(k[0]), float(k[1])

    def _negll(self, st: LagStatisticsReference, u: np.ndarray) -> float:
        a2 = math.tanh(u[1])
        a1 = math.tanh(u[0]) * (1.0 - a2)
        lam = 1.0 / (1.0 + math.exp(-u[2]))
        if not 0.0 < lam < 1.0:
            return math.inf
        return -lag_profile(st, a1, a2, lam, kind=_KIND)[0] / st.n

    def _fit_split(self, st: LagStatisticsReference, a1: float, a2: float) -> LagDriftFit:
        u12 = [_atanh(a1 / (1.0 - a2)), _atanh(a2)]

        def f(v: np.ndarray) -> float:
            return self._negll(st, np.array([u12[0], u12[1], float(v[0])]))

        start = min((math.log(s / (1.0 - s)) for s in _SPLITS), key=lambda u3: f(np.array([u3])))
        res = scipy.optimize.minimize(f, np.array([start]), method="BFGS", options={"gtol": 1e-10})
        lam = 1.0 / (1.0 + math.exp(-float(res.x[0])))
        ll, mean, q, r = lag_profile(st, a1, a2, lam, kind=_KIND)
        return LagDriftFit(a1=a1, a2=a2, q=q, r=r, mean=mean, loglike=ll, evaluations=0,
                           truncation=innovation_pole(a1, a2, q, r) ** st.lags)

    def _covariance(self, st: LagStatisticsReference, u: np.ndarray) -> np.ndarray | None:
        free = [0, 1, 2] if self.adapt_ar else [2]
        h, d = _HESSIAN_STEP, len(free)
        hess = np.empty((d, d))
        f0 = self._negll(st, u)

        def at(**shift: float) -> float:
            v = u.copy()
            for k, s in shift.items():
                v[int(k[1:])] += s
            return self._negll(st, v)

        for i, a in enumerate(free):
            hess[i, i] = (at(**{f"u{a}": h}) - 2.0 * f0 + at(**{f"u{a}": -h})) / h**2
            for j, b in enumerate(free[:i]):
                s = sum(sa * sb * at(**{f"u{a}": sa * h, f"u{b}": sb * h})
                        for sa in (-1.0, 1.0) for sb in (-1.0, 1.0))
                hess[i, j] = hess[j, i] = s / (4.0 * h * h)
        hess *= st.n
        try:
            lower = np.linalg.cholesky(hess)
        except np.linalg.LinAlgError:
            return None
        inv_lower = np.linalg.inv(lower)
        cov = inv_lower.T @ inv_lower
        return cov if np.all(np.isfinite(cov)) else None

    def _fit(self, ch: _Channel) -> LagIdentifierEvent:
        st = ch.stats
        cfg = ch.configured
        fit = (lag_drift_fit(st, kind=_KIND) if self.adapt_ar
               else self._fit_split(st, cfg[0], cfg[1]))
        status = "ok" if fit.truncation <= _TRUNCATION_TOL else "truncation"

        def refused(why: str, cov: np.ndarray | None = None) -> LagIdentifierEvent:
            return LagIdentifierEvent(0, 0, status, why, fit, cov, cfg, ch.gain0)

        if status != "ok" or not (fit.q > 0.0 and fit.r > 0.0):
            return refused("fallback")
        lam = fit.q / (fit.q + fit.r)
        u = np.array([_atanh(fit.a1 / (1.0 - fit.a2)), _atanh(fit.a2), math.log(lam / (1.0 - lam))])
        cov = self._covariance(st, u)
        if cov is None:
            return refused("not_identified")
        se_u3 = math.sqrt(cov[-1, -1])
        if not ((1.0 - lam) * se_u3 <= self.max_rel_stderr and lam * se_u3 <= self.max_rel_stderr):
            return refused("not_identified", cov)
        if self.adapt_ar:
            wald = float(u[:2] @ np.linalg.solve(cov[:2, :2], u[:2]))
            if not wald >= self.min_ar_wald:
                return refused("not_identified", cov)
        use = ch.in_use
        uq = max(use[2], 1e-6 * use[3])
        src = np.array([_atanh(use[0] / (1.0 - use[1])), _atanh(use[1]), math.log(uq),
                        math.log(use[3])])
        dst = np.array([u[0] if self.adapt_ar else src[0], u[1] if self.adapt_ar else src[1],
                        math.log(fit.q), math.log(fit.r)])
        big = float(np.max(np.abs(dst - src)))
        model: Model = (fit.a1, fit.a2, fit.q, fit.r, fit.mean)
        if big > self.max_step:
            v = src + self.max_step / big * (dst - src)
            a2 = math.tanh(v[1])
            model = (math.tanh(v[0]) * (1.0 - a2), a2, math.exp(v[2]), math.exp(v[3]), fit.mean)
        if not self.adapt_ar:
            model = (cfg[0], cfg[1], model[2], model[3], model[4])
        return LagIdentifierEvent(0, 0, status, "tracking", fit, cov, model, self._gain(model))
