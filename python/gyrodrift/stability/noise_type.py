"""Power-law noise type per averaging time: the lag-1 autocorrelation method where it is
valid, the local slope of the deviation as the fallback (NIST SP 1065 sec. 5.6).

The noise type alpha (S_y(f) ~ f^alpha: 2 white PM, 1 flicker PM, 0 white FM, -1 flicker FM,
-2 random-walk FM) sets the equivalent degrees of freedom of every deviation, so it sets the
width of the confidence intervals and the weights of any fit to the curve.

- Lag-1 ACF (Riley & Greenhall 2004): average non-overlapping groups of m rate samples,
  remove a linear trend, r1 = lag-1 autocorrelation, delta = r1 / (1 + r1); difference the
  series until delta < 0.25 (at most twice); alpha = -round(2 delta) - 2 d. It reads the data
  themselves, so a steep or hump-shaped deviation curve (vehicle motion, quantization) does not
  mislead it. Validity rule used here: at least MIN_ACF_POINTS = 30 averages (the minimum
  Riley & Greenhall give; the sd of r1 is ~1/sqrt(points), 0.18 at 30).
- Slope fallback (taus with fewer than 30 averages): the local log-log slope mu of the
  variance, alpha = -mu - 1 (SP 1065 Table 2; mu <= -2 -> white PM for the Allan and
  Hadamard variances, the modified variances separate flicker PM: mu = -2 -> alpha = 1,
  mu = -3 -> alpha = 2), capped by the last ACF value (noise types do not move back towards
  white PM as tau grows).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

__all__ = ["MAX_ACF_POINTS", "MIN_ACF_POINTS", "alpha_per_tau", "lag1_alpha",
"noise_alpha_from_slope",
           "slope_alpha"]

#: Fewest averages for which the lag-1 ACF method is used.
MIN_ACF_POINTS = 30
#: Most averages read per tau (sd of r1 ~ 1/sqrt(points) = 0.008, far inside the 0.25 steps
#: of the decision): bounds the cost and the memory (a few arrays of 128 KiB).
MAX_ACF_POINTS = 1 << 14


def lag1_alpha(z: np.ndarray, *, dmax: int = 2) -> int:
    """alpha of a series of averages z by the lag-1 ACF method (module docstring).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> lag1_alpha(rng.normal(size=1000)), lag1_alpha(np.cumsum(rng.normal(size=1000)))
    (0, -2)
    """
    z = np.array(z, dtype=np.float64)  # a copy, detrended in place
    # Least-squares line (frequency drift) removed in closed form: O(n) temporaries.
    n = z.size
    t = np.arange(n, dtype=np.float64)
    t -= (n - 1) / 2.0
    z -= z.mean()
    # (plain multiply-and-sum, not np.dot: BLAS threads cost milliseconds per call on a
    # loaded machine for these short vectors)
    z -= (float(np.sum(t * z)) / float(np.sum(t * t))) * t
    del t
    d = 0
    while True:
        zc = z - z.mean()
        denom = float(np.sum(zc * zc))
        r1 = float(np.sum(zc[:-1] * zc[1:])) / denom if denom > 0 else 0.0
        delta = r1 / (1.0 + r1)
        if delta < 0.25 or d >= dmax:
            return int(-round(2.0 * delta) - 2 * d)
        z = np.diff(z)
        d += 1


def slope_alpha(tau_s: np.ndarray, dev: np.ndarray, *, modified: bool = False) -> np.ndarray:
    """alpha per tau from the local slope of dev^2 (module docstring), made non-increasing
    in tau. `modified`: the deviation is mdev (for tdev pass tdev / tau).

    Examples
    --------
    >>> tau = np.array([1.0, 2.0, 4.0, 8.0])
    >>> slope_alpha(tau, tau ** -0.5), slope_alpha(tau, tau ** 0.5)  # white FM, random walk FM
    (array([0, 0, 0, 0]), array([-2, -2, -2, -2]))
    """

    if not modified:
        return noise_alpha_from_slope(tau_s, dev)
    tau_s = np.asarray(tau_s, dtype=np.float64)
    dev = np.asarray(dev, dtype=np.float64)
    pos = dev > 0
    if np.count_nonzero(pos) < 2 or not np.all(pos):
        return noise_alpha_from_slope(tau_s, dev)
    mu = np.gradient(np.log(dev * dev), np.log(tau_s))
    alpha = np.clip(np.rint(-mu - 1.0), -2, 2)
    return np.minimum.accumulate(alpha).astype(np.int64)


def alpha_per_tau(averages: Callable[[int, int], np.ndarray], m: np.ndarray, n_rate: int,
                  slope: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(alpha, method) per averaging factor: ACF where n_rate // m >= MIN_ACF_POINTS,
    else the slope value capped by the last ACF value. averages(m, n_avg) returns the first
    n_avg non-overlapping averages of m rate samples. method is "acf" or "slope".

    Examples
    --------
    >>> y = np.random.default_rng(0).normal(size=4096)
    >>> alpha, method = alpha_per_tau(averages_in_memory(y), np.array([1, 64, 512]), y.size,
    ...                               slope=np.array([0, 0, 1]))
    >>> alpha, method  # too few averages at m = 512 for the ACF: the slope, capped
    (array([0, 0, 0]), array(['acf', 'acf', 'slope'], dtype='<U5'))
    """
    alpha = np.empty(m.size, dtype=np.int64)
    method = np.empty(m.size, dtype=object)
    last: int | None = None
    averages = coarsening(averages, n_rate)
    for j, mj in enumerate(int(v) for v in m):
        n_avg = min(n_rate // mj, MAX_ACF_POINTS)
        if n_avg >= MIN_ACF_POINTS:
            a = lag1_alpha(averages(mj, n_avg))
            last = a
            method[j] = "acf"
        else:
            a = int(slope[j]) if last is None else min(int(slope[j]), last)
            method[j] = "slope"
        alpha[j] = min(max(a, -2), 2)
    return alpha, method.astype(str)


def coarsening(averages: Callable[[int, int], np.ndarray], n_rate: int
               ) -> Callable[[int, int], np.ndarray]:
    """averages(m, n_avg) that reads the record once for all the factors whose averages
    cover it: once a factor k's averages span the whole record (n_avg = n_rate // k; every
    factor from n_rate // MAX_ACF_POINTS up), a multiple m of k takes the means of m // k
    consecutive averages of k (<= 2^14 values) instead of another pass over the n_rate
    samples. Octave factors on 1e7 samples then read 0.21 GB per channel instead of 0.85 GB
    (5.1 GB per 6-channel fleet log before, on the memory bus that two workers share). The result
    equals the direct averages to rounding (a mean of means of equal-size blocks; tested to
    1e-13); what is kept, <= 2 x 2^14 values, is dropped with the returned function.

    Examples
    --------
    >>> y = np.arange(16.0)
    >>> avg = coarsening(averages_in_memory(y), y.size)
    >>> avg(2, 8)  # the whole record: kept
    array([ 0.5,  2.5,  4.5,  6.5,  8.5, 10.5, 12.5, 14.5])
    >>> avg(4, 4)  # from the 8 averages of 2, not from y
    array([ 1.5,  5.5,  9.5, 13.5])
    """
    full: dict[int, np.ndarray] = {}  # factor -> its averages over the whole record

    def reusing(m: int, n_avg: int) -> np.ndarray:
        base = max((k for k, z in full.items() if m % k == 0 and n_avg * (m // k) <= z.size),
                    default=None)
        if base is None:
            z = averages(m, n_avg)
        else:
            r = m // base
            z = full[base][: n_avg * r].reshape(n_avg, r).mean(axis=1)
        if n_avg == n_rate // m:
            full[m] = z
        return z
    return reusing


def averages_in_memory(y: np.ndarray) -> Callable[[int, int], np.ndarray]:
    """averages(m, n_avg) over an in-memory rate array."""
    def averages(m: int, n_avg: int) -> np.ndarray:
        return np.asarray(y[: n_avg * m], dtype=np.float64).reshape(n_avg, m).mean(axis=1)
    return averages


def averages_from_pieces(pieces: Callable[[int, int], Iterator[np.ndarray]]
                         ) -> Callable[[int, int], np.ndarray]:
    """averages(m, n_avg) from pieces(start, stop) (float64 chunks of the rate record, read
    in order): bounded memory (one chunk plus n_avg averages, whatever m is)."""
    def averages(m: int, n_avg: int) -> np.ndarray:
        out = np.empty(n_avg)
        filled = 0
        partial = 0.0  # sum of the unfinished block
        have = 0  # its samples
        for piece in pieces(0, n_avg * m):
            pos = 0
            if have:  # finish the open block
                take = min(m - have, piece.size)
                partial += float(piece[:take].sum())
                have += take
                pos = take
                if have == m:
                    out[filled] = partial / m
                    filled += 1
                    partial, have = 0.0, 0
            k = (piece.size - pos) // m
            if k:
                out[filled:filled + k] = piece[pos:pos + k * m].reshape(k, m).mean(axis=1)
                filled += k
                pos += k * m
            if pos < piece.size:
                partial = float(piece[pos:].sum())
                have = piece.size - pos
        return out[:filled]
    return averages


def noise_alpha_from_slope(tau_s: np.ndarray, adev: np.ndarray) -> np.ndarray:
    """Dominant power-law noise per tau from the local log-log slope mu of sigma^2(tau)
    (SP 1065 Table 2: mu = -alpha - 1 for -2 <= alpha <= 0; mu = -2 for alpha = 1 and 2).

    mu ~ -2 maps to alpha = 2 (white phase: the angle quantization of optical gyros); mu >= 1
    (random-walk FM and steeper, e.g. rate ramp) to alpha = -2. A single tau gives alpha = 0.
    The result is made non-increasing in tau (cumulative minimum): in the IEEE Std 952 model
    the dominant term moves from tau^-2 towards tau^+2 as tau grows, so a steep drop at the
    last few taus (few differences, large scatter) must not be read as white phase noise,
    whose edf would be ~N and would make those scattered points dominate a weighted fit.

    Examples
    --------
    >>> tau = np.logspace(0, 3, 10)
    >>> noise_alpha_from_slope(tau, 1 / np.sqrt(tau)).tolist()  # slope -1/2: white FM
    [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
    """
    tau_s = np.asarray(tau_s, dtype=np.float64)
    adev = np.asarray(adev, dtype=np.float64)
    positive = adev > 0
    if np.count_nonzero(positive) < 2:
        return np.zeros(tau_s.shape, dtype=np.int64)
    if not np.all(positive):
        # A zero deviation (exactly periodic or quantized stretches) has no slope: read the
        # slope on the positive points and give each zero point its nearest neighbour's.
        idx = np.flatnonzero(positive)
        inner = noise_alpha_from_slope(tau_s[idx], adev[idx])
        nearest = idx[np.abs(np.arange(tau_s.size)[:, None] - idx[None, :]).argmin(axis=1)]
        lookup = np.empty(tau_s.size, dtype=np.int64)
        lookup[idx] = inner
        return np.minimum.accumulate(lookup[nearest])
    mu = np.gradient(np.log(adev * adev), np.log(tau_s))
    alpha = np.rint(-mu - 1.0)
    alpha = np.where(mu < -1.5, 2.0, alpha)
    alpha = np.minimum.accumulate(np.clip(alpha, -2, 2))
    return alpha.astype(np.int64)
