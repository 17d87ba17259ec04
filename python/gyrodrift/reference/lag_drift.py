"""numpy reference: the drift model fitted from whole-record lag statistics kept while
streaming.

Model (as `gyrodrift.fit_drift_model`): x_k = a1 x_{k-1} + a2 x_{k-2} + w_k (var q),
y_k = mean + x_k + v_k (var r); spectrum S(w) = q / ``|A(e^iw)|^2`` + r.

Streaming state of a record y_0..y_{n-1} (`LagStatisticsReference`), with w_t = y_t - c and
c the first sample: n, sum_t w_t, the lag products P_k = sum_{t>=k} w_t w_{t-k} for
k = 0..L, the first L and the last L values of w. Memory and work per sample do not depend
on n (L + 1 multiply-adds per sample). The likelihood and the fit take any object with the
same attributes (`LagStatisticsLike`: lags, n, centre, total, products, head, tail), e.g. the
C++ statistics `gyrodrift.filters.lag_statistics.LagStatistics`.

From these, for any (a1, a2, q, r, mean), with z_t = y_t - mean:

- the lag sums S_k = sum_{t>=k} z_t z_{t-k} exactly (`LagStatisticsReference.lag_sums`):
  P_k - d (2 sum w - sum_{t<k} w_t - sum_{t>=n-k} w_t) + (n - k) d^2, d = mean - c;
- ``"exact"``: the exact Gaussian log-likelihood (the Kalman filter's, stationary start) up
  to terms of order rho^L, rho the pole modulus of the steady-state innovation filter
  (`innovation_pole`): the Kalman filter over the first L samples gives their innovations
  e_t and variances F_t; from t = L on the filter is in steady state to rho^(2L) and its
  innovations are e_t = sum_{j<=L} pi_j z_{t-j} (pi the steady-state innovation filter's
  impulse response) to rho^L, whose sum of squares over t = L..n-1 is
  sum_{j,l} pi_j pi_l S_``|j-l|`` minus the squares of the zero-padded convolution pi * z at
  t = 0..L-1 (from the first L samples) and t = n..n+L-1 (from the last L samples); then
  log L = -(n log 2 pi + sum_{t<L} log F_t + (n - L) log sigma^2 + Q) / 2 with
  Q = sum_{t<L} e_t^2 / F_t + (that sum of squares) / sigma^2;
- ``"whittle"``: Whittle's approximation, log L = -(n log 2 pi + n log sigma^2 +
  sum_``|k|<=L`` S_``|k|`` d_k) / 2, d_k = sum_j pi_j pi_{j+k} / sigma^2 the Fourier
  coefficients of 1 / S(w) truncated at L (sigma^2 = exp of the mean of log S, the
  steady-state innovation variance).
- ``"whittle_no_head"``: Whittle's with the first L values of w replaced by the record's
  mean of w, sum w / n, in the mean's correction (the only place Whittle's form reads
  them): what a target that keeps no first samples can evaluate; the statistics' ``head``
  is not read.

Both are quadratic in the mean and scale as 1/s with a common factor s of (q, r), so the fit
(`lag_drift_fit`) maximises the profile log-likelihood over (u1, u2, u3) only
(a2 = tanh u2, a1 = tanh u1 (1 - a2), q / (q + r) = logistic u3, as `fit_drift_model`), with
scipy's BFGS from the two best points on each side of a2 = 0 of a grid of partial
autocorrelations ((-0.5, 0.3, 0.7, 0.95) x (+-0.05, +-0.3)) and splits (0.2, 0.5, 0.8).
Next to a2 = 0 the likelihood can have a maximum on each side of the fold, and which one a
start reaches is set by its split as much as by its a2: when every run ends on one side, the
maximum over (u1, u3) with u2 held at the mirror of the best one's starts one more run on the
other side. The steady state is the Riccati recursion continued from the filter over the
first L samples until the innovation variance stops changing (on two steps running).

Choice of L: the neglected terms are of order rho^L per sample; L >= ln(1e-10) / ln(rho)
(`lags_needed`) makes them negligible against one log-likelihood unit at any record length
the loop sees (n rho^L < 2e-3 at 10 h at 400 Hz). rho grows with r/q and with the drift's
pole: 0.27 and 0.43 for the pair (0.6868, -0.0213) at r/q = 1 and 3 (L 18 and 28), 0.34 and
0.44 for (0.2297, 0.1638).

Float64, plain loops where the equations have them: an oracle, not the fast path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import scipy.optimize

from gyrodrift.errors import GyrodriftValueError

__all__ = ["LagDriftFit", "LagStatisticsLike", "LagStatisticsReference", "innovation_pole",
           "lag_drift_fit", "lag_loglike", "lag_profile", "lags_needed"]

_LOG_2PI = math.log(2.0 * math.pi)
_RICCATI_TOL = 1e-15
#: rho^L below which the neglected terms of the likelihood count as negligible (`lags_needed`).
TRUNCATION_TOL = 1e-10
_KINDS = ("exact", "whittle", "whittle_no_head")


class LagStatisticsLike(Protocol):
    """The statistics the likelihood and the fit read (module docstring): L (``lags``), n,
    the centre c, sum w (``total``), P_0..P_L (``products``), the first and the last
    min(n, L) values of w (``head``, ``tail``, oldest first).

    Examples
    --------
    >>> st: LagStatisticsLike = LagStatisticsReference(4)
    >>> st.push([2.0, 3.0]); st.products.tolist()
    [1.0, 0.0, 0.0, 0.0, 0.0]
    """

    @property
    def lags(self) -> int:
        """L."""
        ...

    @property
    def n(self) -> int:
        """Samples."""
        ...

    @property
    def centre(self) -> float:
        """c, the first sample."""
        ...

    @property
    def total(self) -> float:
        """sum_t w_t."""
        ...

    @property
    def products(self) -> np.ndarray:
        """P_0 .. P_L."""
        ...

    @property
    def head(self) -> np.ndarray:
        """The first min(n, L) values of w."""
        ...

    @property
    def tail(self) -> np.ndarray:
        """The last min(n, L) values of w, oldest first."""
        ...


class LagStatisticsReference:
    """Streaming lag statistics of a record (module docstring); `push` takes chunks of any
    size and gives the same state as pushing one sample at a time.

    Parameters
    ----------
    lags : int
        L, the largest lag kept (>= 1).

    Examples
    --------
    >>> st = LagStatisticsReference(2)
    >>> st.push([1.0, 2.0, 4.0]); st.push([3.0])
    >>> st.n, st.centre, st.products.tolist()   # w = 0, 1, 3, 2
    (4, 1.0, [14.0, 9.0, 2.0])
    >>> st.lag_sums(2.5).tolist()               # z = -1.5, -0.5, 1.5, 0.5
    [5.0, 0.75, -2.5]
    """

    def __init__(self, lags: int) -> None:
        if not (isinstance(lags, int) and lags >= 1):
            raise GyrodriftValueError(f"lags must be an integer >= 1, got {lags!r}")
        self.lags = lags
        self.n = 0
        self.centre = 0.0
        self.total = 0.0
        self.products = np.zeros(lags + 1)
        self.head = np.zeros(0)
        self.tail = np.zeros(0)

    @classmethod
    def from_statistics(cls, st: LagStatisticsLike) -> LagStatisticsReference:
        """A copy of statistics kept elsewhere (e.g. by the C++ core), in float64, to push
        on or to take `lag_sums` from.

        Examples
        --------
        >>> a = LagStatisticsReference(2); a.push([1.0, 2.0, 4.0])
        >>> b = LagStatisticsReference.from_statistics(a); b.push([3.0])
        >>> b.n, b.products.tolist(), a.n
        (4, [14.0, 9.0, 2.0], 3)
        """
        lags = int(st.lags)
        out = cls(lags)
        out.n = int(st.n)
        kept = min(out.n, lags)
        out.centre = float(st.centre)
        out.total = float(st.total)
        out.products = np.array(st.products, dtype=np.float64).reshape(-1)
        out.head = np.array(st.head, dtype=np.float64).reshape(-1)
        out.tail = np.array(st.tail, dtype=np.float64).reshape(-1)
        if (out.products.size != lags + 1 or out.head.size != kept or out.tail.size != kept
                or out.n < 0):
            raise GyrodriftValueError(
                f"inconsistent statistics: {out.n} samples, {lags} lags, "
                f"{out.products.size} products, {out.head.size} first and "
                f"{out.tail.size} last values")
        return out

    def push(self, y: object) -> None:
        """Add samples (1-D, finite)."""
        a = np.asarray(y, dtype=np.float64).reshape(-1)
        if not np.all(np.isfinite(a)):
            raise GyrodriftValueError("the samples contain NaN or Inf")
        if a.size == 0:
            return
        if self.n == 0:
            self.centre = float(a[0])
        w = a - self.centre
        ext = np.concatenate([self.tail, w])
        t0 = self.tail.size  # the new samples are ext[t0:]
        for k in range(self.lags + 1):
            lo = max(t0, k)
            if lo < ext.size:
                self.products[k] += float(ext[lo:] @ ext[lo - k:ext.size - k])
        self.total += float(w.sum())
        if self.head.size < self.lags:
            self.head = np.concatenate([self.head, w[: self.lags - self.head.size]])
        self.tail = ext[-self.lags:].copy()
        self.n += int(w.size)

    def lag_sums(self, mean: float) -> np.ndarray:
        """S_k = sum_{t>=k} (y_t - mean)(y_{t-k} - mean), k = 0..L (needs n >= L)."""
        if self.n < self.lags:
            raise GyrodriftValueError(f"{self.n} samples, at least {self.lags} needed")
        return self._sums_form(mean - self.centre)

    def _sums_form(self, d: float) -> np.ndarray:
        k = np.arange(self.lags + 1)
        head_cum = np.r_[0.0, np.cumsum(self.head)]
        tail_cum = np.r_[0.0, np.cumsum(self.tail[::-1])]
        lin = 2.0 * self.total - head_cum[k] - tail_cum[k]
        return self.products - d * lin + (self.n - k) * d * d


def innovation_pole(a1: float, a2: float, q: float, r: float) -> float:
    """Pole modulus rho of the steady-state innovation filter of the model: its impulse
    response, and the distance of the Kalman filter from its steady state, decay as rho^t.

    Examples
    --------
    >>> round(innovation_pole(0.6868, -0.0213, 1.0, 3.0), 2)
    0.43
    """
    terms = _steady(a1, a2, q, r, 1)
    a = np.array([[a1, a2], [1.0, 0.0]])
    closed = a @ (np.eye(2) - np.outer(terms[2], [1.0, 0.0]))
    return float(max(abs(np.linalg.eigvals(closed))))


def lags_needed(a1: float, a2: float, q: float, r: float, tol: float = TRUNCATION_TOL) -> int:
    """The smallest L with rho^L <= tol (`innovation_pole`; module docstring).

    Examples
    --------
    >>> lags_needed(0.6868, -0.0213, 1.0, 3.0), lags_needed(0.2297, 0.1638, 1.0, 1.0)
    (28, 22)
    """
    rho = innovation_pole(a1, a2, q, r)
    return max(1, math.ceil(math.log(tol) / math.log(rho))) if rho > 0 else 1


def _stationary_cov(a1: float, a2: float, q: float) -> np.ndarray:
    g0 = q * (1.0 - a2) / ((1.0 + a2) * ((1.0 - a2) ** 2 - a1 * a1))
    g1 = a1 * g0 / (1.0 - a2)
    return np.array([[g0, g1], [g1, g0]])


def _steady(a1: float, a2: float, q: float, r: float, lags: int
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Kalman filter (prediction form, stationary start) over `lags` steps: innovation
    variances F_t, gains K_t; then the Riccati recursion on until F stops changing: the
    steady gain and innovation variance sigma^2 (F unchanged to 1e-15 on two steps
    running). P = [[p00, p01], [p01, p11]]:
    U = P - K P[0, :] with K = P[:, 0] / F, F = p00 + r; P' = A U A^T + diag(q, 0)."""
    c = _stationary_cov(a1, a2, q)
    p00, p01, p11 = float(c[0, 0]), float(c[0, 1]), float(c[1, 1])
    fs = np.empty(lags)
    gains = np.empty((lags, 2))
    t, f_prev, calm = 0, math.inf, 0
    while True:
        f = p00 + r
        k0, k1 = p00 / f, p01 / f
        # Steady when F has stopped changing on two steps running: with a1 = 0 the even and
        # odd samples are two chains, F moves every other step only.
        calm = calm + 1 if abs(f - f_prev) <= _RICCATI_TOL * f else 0
        if t < lags:
            fs[t] = f
            gains[t] = (k0, k1)
        elif calm >= 2 or t >= 64 * lags + 256:
            break
        f_prev = f
        u00, u01, u11 = p00 - k0 * p00, p01 - k0 * p01, p11 - k1 * p01
        p00 = a1 * a1 * u00 + 2.0 * a1 * a2 * u01 + a2 * a2 * u11 + q
        p01 = a1 * u00 + a2 * u01
        p11 = u00
        t += 1
    return fs, gains, np.array([k0, k1]), f


def _form(st: LagStatisticsLike, a1: float, a2: float, q: float, r: float, kind: str
          ) -> tuple[float, np.ndarray]:
    """(log det, M): the quadratic form is Q(d) = v M v^T with v = (1, -d), d = mean - c."""
    lags, n = st.lags, st.n
    fs, gains, kss, s2 = _steady(a1, a2, q, r, lags)
    pi = np.empty(lags + 1)  # impulse response of the steady-state innovation filter
    x0 = x1 = 0.0
    for t in range(lags + 1):
        e = (1.0 if t == 0 else 0.0) - x0
        pi[t] = e
        u0, u1 = x0 + kss[0] * e, x1 + kss[1] * e
        x0, x1 = a1 * u0 + a2 * u1, u0
    g = np.array([pi[: lags + 1 - m] @ pi[m:] for m in range(lags + 1)])
    g[1:] *= 2.0
    k = np.arange(lags + 1)
    head = np.full(lags, st.total / n) if kind == "whittle_no_head" else st.head
    head_cum = np.r_[0.0, np.cumsum(head)]
    tail_cum = np.r_[0.0, np.cumsum(st.tail[::-1])]
    lin = 2.0 * st.total - head_cum[k] - tail_cum[k]
    m = np.array([[st.products @ g, 0.5 * (lin @ g)],
                  [0.5 * (lin @ g), (n - k) @ g]]) / s2
    if kind != "exact":
        return n * math.log(s2), m
    ones = np.ones(lags)
    eh = np.empty((2, lags))  # innovations are linear in z = w - d: those of w and of 1
    for row, z in enumerate((st.head, ones)):
        x0 = x1 = 0.0
        for t in range(lags):
            e = float(z[t]) - x0
            eh[row, t] = e
            u0, u1 = x0 + gains[t, 0] * e, x1 + gains[t, 1] * e
            x0, x1 = a1 * u0 + a2 * u1, u0
    eh /= np.sqrt(fs)
    ch = np.stack([np.convolve(pi, st.head)[:lags], np.convolve(pi, ones)[:lags]])
    ct = np.stack([np.convolve(pi, st.tail)[lags:], np.convolve(pi, ones)[lags:]])
    m += eh @ eh.T - (ch @ ch.T + ct @ ct.T) / s2
    return float(np.log(fs).sum()) + (n - lags) * math.log(s2), m


def _check(st: LagStatisticsLike, kind: str) -> None:
    if kind not in _KINDS:
        raise GyrodriftValueError(f"kind must be one of {', '.join(_KINDS)}, got {kind!r}")
    if st.n < 2 * st.lags + 2:
        raise GyrodriftValueError(
            f"{st.n} samples, at least {2 * st.lags + 2} needed for {st.lags} lags")


def lag_loglike(st: LagStatisticsLike, a1: float, a2: float, q: float, r: float,
                mean: float, kind: str = "exact") -> float:
    """Log-likelihood of the model from the lag statistics (module docstring).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> st = LagStatisticsReference(8); st.push(rng.normal(size=1000))
    >>> white = -0.5 * (1000 * math.log(2 * math.pi) + np.sum(st.lag_sums(0.0)[0]))
    >>> bool(abs(lag_loglike(st, 0.0, 0.0, 1e-12, 1.0, 0.0) - white) < 1e-6)
    True
    """
    _check(st, kind)
    logdet, m = _form(st, a1, a2, q, r, kind)
    v = np.array([1.0, -(mean - st.centre)])
    return -0.5 * (st.n * _LOG_2PI + logdet + float(v @ m @ v))


def lag_profile(st: LagStatisticsLike, a1: float, a2: float, lam: float,
                kind: str = "exact") -> tuple[float, float, float, float]:
    """The profile log-likelihood at (a1, a2, lam = q / (q + r)): the log-likelihood from the
    lag statistics maximised over the mean and the common scale s of q and r (both in closed
    form: quadratic in the mean, q = lam s, r = (1 - lam) s).

    Returns
    -------
    tuple of float
        (log-likelihood, mean, q, r) at that maximum.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> st = LagStatisticsReference(8); st.push(rng.normal(2.0, 1.0, size=4000))
    >>> ll, mean, q, r = lag_profile(st, 0.5, 0.0, 0.5, kind="whittle_no_head")
    >>> at = lag_loglike(st, 0.5, 0.0, q, r, mean, kind="whittle_no_head")
    >>> bool(abs(mean - 2.0) < 0.1 and math.isclose(ll, at, rel_tol=1e-12))
    True
    """
    _check(st, kind)
    n = st.n
    logdet, m = _form(st, a1, a2, lam, 1.0 - lam, kind)
    d = m[0, 1] / m[1, 1]
    scale = (m[0, 0] - m[0, 1] * d) / n
    ll = -0.5 * (n * _LOG_2PI + logdet + n * math.log(scale) + n)
    return float(ll), float(st.centre + d), float(lam * scale), float((1.0 - lam) * scale)


@dataclass(frozen=True)
class LagDriftFit:
    """The lag-statistics fit: a1, a2, q, r, mean, its log-likelihood (of the kind fitted),
    the likelihood evaluations used, and rho^L (`innovation_pole` of the fit to the power L:
    the size of the neglected terms; above 1e-10 L is too short for this model).

    Examples
    --------
    >>> LagDriftFit(0.5, 0.0, 1.0, 1.0, 0.0, -10.0, 1, 1e-12).truncation < 1e-10
    True
    """

    a1: float
    a2: float
    q: float
    r: float
    mean: float
    loglike: float
    evaluations: int
    truncation: float


def lag_drift_fit(st: LagStatisticsLike, kind: str = "exact") -> LagDriftFit:
    """Maximise the profile log-likelihood from the lag statistics (module docstring).

    Examples
    --------
    >>> from scipy.signal import lfilter
    >>> rng = np.random.default_rng(1)
    >>> y = lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(size=20000)) \\
    ...     + rng.normal(size=20000)
    >>> st = LagStatisticsReference(24); st.push(y)
    >>> fit = lag_drift_fit(st)
    >>> bool(abs(fit.a1 - 0.6868) < 0.2 and abs(fit.q / fit.r - 1.0) < 0.5)
    True
    """
    _check(st, kind)
    n = st.n
    evaluations = 0

    def natural(u: np.ndarray) -> tuple[float, float, float]:
        a2 = math.tanh(u[1])
        return math.tanh(u[0]) * (1.0 - a2), a2, 1.0 / (1.0 + math.exp(-u[2]))

    def profile(a1: float, a2: float, lam: float) -> tuple[float, float, float]:
        nonlocal evaluations
        evaluations += 1
        logdet, m = _form(st, a1, a2, lam, 1.0 - lam, kind)
        d = m[0, 1] / m[1, 1]
        scale = (m[0, 0] - m[0, 1] * d) / n
        return -0.5 * (n * _LOG_2PI + logdet + n * math.log(scale) + n), d, scale

    def negll(u: np.ndarray) -> float:
        try:
            with np.errstate(all="raise"):
                a1, a2, lam = natural(u)
                if not 0.0 < lam < 1.0:
                    return math.inf
                return -profile(a1, a2, lam)[0] / n
        except (FloatingPointError, OverflowError, ValueError, np.linalg.LinAlgError):
            return math.inf

    starts = [np.array([math.atanh(p1), math.atanh(p2), math.log(lam / (1.0 - lam))])
              for p1 in (-0.5, 0.3, 0.7, 0.95) for p2 in (-0.3, -0.05, 0.05, 0.3)
              for lam in (0.2, 0.5, 0.8)]
    ranked = sorted(starts, key=negll)
    # the two best starts on each side of a2 = 0
    chosen = [u for u in ranked if u[1] < 0][:2] + [u for u in ranked if u[1] > 0][:2]
    modes = [scipy.optimize.minimize(negll, u, method="BFGS", options={"gtol": 1e-10})
             for u in chosen]
    best = min(modes, key=lambda res: float(res.fun))
    if all(np.sign(m.x[1]) == np.sign(best.x[1]) for m in modes):
        # Across the fold: every start ended on one side of a2 = 0 (which side is set by
        # the split as much as by the start's a2). Maximise over (u1, u3) with a2 held at
        # the mirror of the best mode's, then over all three from there.
        u2 = -float(best.x[1])
        side = scipy.optimize.minimize(lambda v: negll(np.array([v[0], u2, v[1]])),
                                       best.x[[0, 2]], method="BFGS", options={"gtol": 1e-10})
        other = scipy.optimize.minimize(negll, np.array([side.x[0], u2, side.x[1]]),
                                        method="BFGS", options={"gtol": 1e-10})
        best = min((best, other), key=lambda res: float(res.fun))
    a1, a2, lam = natural(best.x)
    ll, d, scale = profile(a1, a2, lam)
    q, r = float(lam * scale), float((1.0 - lam) * scale)
    return LagDriftFit(a1=a1, a2=a2, q=q, r=r, mean=float(st.centre + d), loglike=float(ll),
                       evaluations=evaluations,
                       truncation=innovation_pole(a1, a2, q, r) ** st.lags)
