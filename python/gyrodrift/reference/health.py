"""Reference for the health alarms (include/gyrodrift/imu/health_alarms.hpp) and the model
Allan variance (include/gyrodrift/stability/model_allan.hpp), written from the equations in
numpy: the alarms from the definition of the non-overlapped Allan variance (cluster means of
the whole record, their squared differences), not from a streaming state.

Model Allan variance of AR(2) drift + white noise: the drift's autocovariance g(j) from the
Yule-Walker recursion g(j) = a1 g(j-1) + a2 g(j-2) with g0 = q (1 - a2) / ((1 + a2)
((1 - a2)^2 - a1^2)), g1 = a1 g0 / (1 - a2); D(m) = m g0 + 2 sum_{j<m} (m - j) g(j);
sigma^2(m) = (4 D(m) - D(2m)) / (2 m^2) + r / m.

Alarms: octave k (m = 2^k) has its t-th squared difference after (t + 1) m accepted samples.
While t < block_terms the Allan variance of the first t terms, at t a multiple of
block_terms that of the last block_terms terms (their sum, as the target adds each term to
the block as it arrives), is divided by the reference and compared
with max(f^2, chi2_{1-p}(nu) / nu) (Wilson-Hilferty). nu = e_k t for t terms, e_k the edf per
term of block_terms terms of power-law noise with the reference's local slope mu_k (over two
octaves, one at the ends): the phase's generalized autocovariance G(t) = t^2 (abs(t)^mu - 1) / mu,
the correlation of second differences h apart from the fourth differences of G, edf = n^2 /
(n + 2 sum (n - h) rho(h)^2).
The classes: the leading run of octaves whose reference falls by at least half over two
octaves is arw_high; later octaves rising by at least 2 over two octaves rate_random_walk_high;
the others bias_instability_high.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrodrift.reference.online_noise import chi2_quantile_wh, normal_quantile

__all__ = ["ALARM_BITS", "HealthRunRef", "ar2_white_avar", "ar2_white_edf_per_term",
           "health_alarms", "ieee952_avar", "octave_alarms", "power_law_edf_per_term"]

#: (name, bit) of every alarm in index order.
ALARM_BITS = (("arw_high", 1), ("bias_instability_high", 2), ("rate_random_walk_high", 4),
              ("stuck", 8), ("saturated", 16))


def ar2_white_avar(a1: float, a2: float, q: float, r: float, n_octaves: int) -> np.ndarray:
    """Expected Allan variance at m = 2^k, k < n_octaves, by direct sums of the autocovariance.

    Examples
    --------
    >>> ar2_white_avar(0.0, 0.0, 0.0, 2.0, 2).tolist()
    [2.0, 1.0]
    """
    m_max = 1 << n_octaves  # D(2m) for the largest m = 2^(n_octaves - 1)
    g = np.zeros(m_max)
    if q > 0.0:
        g[0] = q * (1.0 - a2) / ((1.0 + a2) * ((1.0 - a2) ** 2 - a1 * a1))
        if m_max > 1:
            g[1] = a1 * g[0] / (1.0 - a2)
        for j in range(2, m_max):
            g[j] = a1 * g[j - 1] + a2 * g[j - 2]

    def big_d(m: int) -> float:
        j = np.arange(1, m)
        return float(m * g[0] + 2.0 * np.sum((m - j) * g[1:m]))

    out = np.empty(n_octaves)
    for k in range(n_octaves):
        m = 1 << k
        drift = (4.0 * big_d(m) - big_d(2 * m)) / (2.0 * m * m)
        out[k] = max(drift, 0.0) + r / m
    return out


def _autocovariance(a1: float, a2: float, q: float, length: int) -> np.ndarray:
    g = np.zeros(max(length, 2))
    if q > 0.0:
        g[0] = q * (1.0 - a2) / ((1.0 + a2) * ((1.0 - a2) ** 2 - a1 * a1))
        g[1] = a1 * g[0] / (1.0 - a2)
        for j in range(2, length):
            g[j] = a1 * g[j - 1] + a2 * g[j - 2]
    return g


def ar2_white_edf_per_term(a1: float, a2: float, q: float, r: float, n_octaves: int,
                           n: int) -> np.ndarray:
    """edf / n of n consecutive squared differences at m = 2^k: the covariance of the
    cluster-mean differences h apart summed from the autocovariance, Cov(S_i, S_j) of cluster
    sums = sum over the m x m pairs of samples (r on the diagonal).

    Examples
    --------
    >>> e = ar2_white_edf_per_term(0.0, 0.0, 0.0, 1.0, 1, 10)  # white: n / (1.5 n - 0.5)
    >>> bool(abs(e[0] - 10 / 14.5) < 1e-12)
    True
    """
    out = np.empty(n_octaves)
    for k in range(n_octaves):
        m = 1 << k
        g = _autocovariance(a1, a2, q, (n + 2) * m + 1)
        g[0] += r
        # covariance of two cluster sums j clusters apart: sum_{u,v<m} g(|j m + v - u|)
        lag = np.arange(-(m - 1), m)
        weight = m - np.abs(lag)

        cs = [float(np.sum(weight * g[np.abs(j * m + lag)])) for j in range(n + 2)]
        # d_h = S_{h+1} - S_h: Cov(d_0, d_h) = 2 c(h) - c(h - 1) - c(h + 1)
        c = [2 * cs[h] - cs[abs(h - 1)] - cs[h + 1] for h in range(n)]
        total = sum((n - h) * (c[h] / c[0]) ** 2 for h in range(1, n))
        out[k] = n / (n + 2.0 * total)
    return out


def ieee952_avar(tau_s: np.ndarray, q_angle: float = 0.0, n: float = 0.0, b: float = 0.0,
                 k: float = 0.0) -> np.ndarray:
    """IEEE Std 952 Allan variance 3 Q^2/tau^2 + N^2/tau + (0.664 B)^2 + K^2 tau / 3.

    Examples
    --------
    >>> ieee952_avar([1.0, 4.0], n=2.0).tolist()
    [4.0, 1.0]
    """
    t = np.asarray(tau_s, dtype=float)
    return 3.0 * q_angle ** 2 / t ** 2 + n ** 2 / t + (0.66428 * b) ** 2 + k ** 2 * t / 3.0


def power_law_edf_per_term(mu: float, n: int) -> float:
    """edf / n of n squared differences of power-law noise with Allan variance ~ tau^mu.

    Examples
    --------
    >>> round(power_law_edf_per_term(-1.0, 10), 4)  # white: 10 / (1.5 * 10 - 0.5)
    0.6897
    """
    mu = min(max(mu, -1.0), 1.9) if np.isfinite(mu) else -1.0

    def g(t: float) -> float:
        t = abs(t)
        if t == 0.0:
            return 0.0
        lt = np.log(t)
        x = mu * lt
        return float(t * t * lt * (1.0 if x == 0.0 else np.expm1(x) / x))

    def c(h: float) -> float:
        return g(h - 2) - 4 * g(h - 1) + 6 * g(h) - 4 * g(h + 1) + g(h + 2)

    c0 = c(0.0)
    total = sum((n - h) * (c(h) / c0) ** 2 for h in range(1, n))
    return n / (n + 2.0 * total)


def octave_alarms(ref: np.ndarray) -> list[int]:
    """The alarm bit of each octave of a reference curve.

    Examples
    --------
    >>> octave_alarms(np.array([4.0, 2.0, 1.0, 1.0, 1.0, 2.0, 4.0]))
    [1, 1, 1, 2, 4, 4, 4]
    """
    n = len(ref)
    out: list[int] = []
    leading = True
    for k in range(n):
        if n >= 3 and 0 < k < n - 1:
            r = ref[k + 1] / ref[k - 1]
        elif n >= 2:
            r = (ref[1] / ref[0] if k == 0 else ref[k] / ref[k - 1]) ** 2
        else:
            r = 1.0
        if leading and (n == 1 or r <= 0.5):
            out.append(1)
            continue
        leading = False
        out.append(4 if r >= 2.0 else 2)
    return out


@dataclass(frozen=True)
class HealthRunRef:
    """Latched bits after each sample, raise counts, exceedances, trips per alarm index.

    Examples
    --------
    >>> run = health_alarms(np.zeros(4), 100.0, np.array([1.0]), stuck=np.ones(4, bool),
    ...                     stuck_samples=2)
    >>> run.bits.tolist(), run.raised[3], run.trips[3][3]
    ([0, 8, 8, 8], 1, 2)
    """

    bits: np.ndarray
    raised: list[int]
    exceedances: list[int]
    trips: list[tuple[float, float, float, int]]


def health_alarms(y: np.ndarray, rate_hz: float, ref: np.ndarray, *,
                  edf_per_term: np.ndarray | None = None, arw_factor: float = 2.0,
                  bias_instability_factor: float = 2.0, rate_random_walk_factor: float = 2.0,
                  false_alarm_probability: float = 1e-6, block_terms: int = 64,
                  stuck: np.ndarray | None = None, saturated: np.ndarray | None = None,
                  stuck_samples: int = 0, saturated_samples: int = 0) -> HealthRunRef:
    """The alarms of one channel over a record, update() after every sample.

    Examples
    --------
    >>> health_alarms(np.ones(8), 100.0, np.array([1.0, 0.5])).raised
    [0, 0, 0, 0, 0]
    """
    y = np.asarray(y, dtype=float)
    n_all = len(y)
    accepted = np.flatnonzero(np.isfinite(y))
    ya = y[accepted]
    classes = octave_alarms(ref)
    factors = {1: arw_factor, 2: bias_instability_factor, 4: rate_random_walk_factor}
    index = {1: 0, 2: 1, 4: 2}
    nref = len(ref)
    e = []
    for k in range(nref):
        if edf_per_term is not None and 0.0 < edf_per_term[k] <= 1.0:
            e.append(float(edf_per_term[k]))
            continue
        lo, hi = ref[max(k - 1, 0)], ref[min(k + 1, nref - 1)]
        span = 2.0 if 0 < k < nref - 1 else 1.0
        mu = float(np.log2(hi / lo) / span) if nref >= 2 else -1.0
        e.append(power_law_edf_per_term(mu, block_terms))
    z = -normal_quantile(false_alarm_probability)
    # events: (update index (1-based), octave, alarm index, statistic, threshold, tau)
    events: list[tuple[int, int, int, float, float, float]] = []
    for k, bit in enumerate(classes):
        m = 1 << k
        clusters = len(ya) // m
        if clusters < 2:
            continue
        means = ya[:clusters * m].reshape(clusters, m).mean(axis=1)
        d2 = np.diff(means) ** 2
        csum = np.concatenate([[0.0], np.cumsum(d2)])
        f2 = factors[bit] ** 2
        for t in range(1, clusters):
            if t < block_terms:
                var, tested = csum[t] / (2.0 * t), t
            elif t % block_terms == 0:
                block = float(np.sum(d2[t - block_terms:t]))  # the block's own terms
                var, tested = block / (2.0 * block_terms), block_terms
            else:
                continue
            nu = max(e[k] * tested, 1.0)
            thr = max(f2, chi2_quantile_wh(nu, z) / nu)
            ratio = var / ref[k]
            if ratio > thr:
                sample = int(accepted[(t + 1) * m - 1]) + 1
                events.append((sample, k, index[bit], float(np.sqrt(ratio)), float(np.sqrt(thr)),
                               m / rate_hz))
    for flags, limit, i in ((stuck, stuck_samples, 3), (saturated, saturated_samples, 4)):
        if flags is None or limit == 0:
            continue
        run = 0
        for s, f in enumerate(np.asarray(flags, dtype=bool)):
            run = run + 1 if f else 0
            if run >= limit:
                events.append((s + 1, -1, i, float(run), float(limit), 0.0))
    events.sort(key=lambda e: (e[0], e[1]))
    raised = [0] * 5
    exceed = [0] * 5
    trips: list[tuple[float, float, float, int]] = [(0.0, 0.0, 0.0, 0)] * 5
    bits = np.zeros(n_all, dtype=np.uint16)
    for sample, _k, i, stat, thr, tau in events:
        exceed[i] += 1
        if raised[i] == 0:
            raised[i] = 1
            trips[i] = (stat, thr, tau, sample)
            bits[sample - 1:] |= np.uint16(ALARM_BITS[i][1])
    return HealthRunRef(bits, raised, exceed, trips)
