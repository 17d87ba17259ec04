"""Reference for the online IEEE 952 noise estimates read from an octave Allan curve
(include/gyrodrift/stability/online_noise.hpp), its edf and its chi-square quantiles
(include/gyrodrift/stability/allan_chi2.hpp), written from the equations in numpy.

- edf of the non-overlapped Allan variance from n squared differences (moment matching):
  n^2 / (n (1 + 2 S) - 2 S1), S = sum rho(h)^2, S1 = sum h rho(h)^2 over the correlations of
  neighbouring differences: white rho(1) = -1/2; flicker S = 0.0677068, S1 = 0.0939406;
  random walk rho(1) = (m^2 - 1) / (2 (2 m^2 + 1)).
- standard normal quantile: Acklam's rational approximation; chi-square quantile:
  Wilson & Hilferty (1931).
- N: among the octaves whose next octave's variance is 2^-1.3 .. 2^-0.7 times their own,
  the shortest where it is within 2^-1.1 .. 2^-0.9, else the one where it is closest to
  1/2 in log (the shortest on a tie),
  N = sqrt(sigma^2 tau), else an upper limit min sqrt(hi tau); B: the minimum over the usable
  octaves / 0.664, an upper limit while the minimum is the longest usable octave; K: at the
  longest usable octave when it lies beyond the minimum and rises by 2^0.5 over the one
  before, sqrt(3 (sigma^2 - N^2 / tau) / tau), else an upper limit sqrt(3 hi / tau) there.
  Usable: a prefix of octaves with at least 8 terms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["MIN_TERMS", "NoiseEstimatesRef", "TermRef", "chi2_quantile_wh", "estimate_noise",
           "nonoverlapped_edf", "normal_quantile"]

MIN_TERMS = 8
FLICKER_FLOOR = 0.66428
_S_S1 = {"white": (0.25, 0.25), "flicker": (0.0677068, 0.0939406)}


def nonoverlapped_edf(noise: str, n: int, m: int) -> float:
    """edf of the non-overlapped Allan variance ('white', 'flicker', 'random_walk').

    Examples
    --------
    >>> nonoverlapped_edf("white", 1, 1), nonoverlapped_edf("random_walk", 4, 1)
    (1.0, 4.0)
    """
    if n == 0:
        return 0.0
    if noise == "random_walk":
        mm = float(max(m, 1))
        rho = (mm * mm - 1.0) / (2.0 * (2.0 * mm * mm + 1.0))
        s = s1 = rho * rho
    else:
        s, s1 = _S_S1[noise]
    edf = n * n / (n * (1.0 + 2.0 * s) - 2.0 * s1)
    return min(edf, float(n))


_A = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
      1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00)
_B = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
      6.680131188771972e+01, -1.328068155288572e+01)
_C = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
      -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00)
_D = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
      3.754408661907416e+00)


def normal_quantile(p: float) -> float:
    """Acklam's approximation of the standard normal quantile.

    Examples
    --------
    >>> normal_quantile(0.5), round(normal_quantile(0.975), 6)
    (0.0, 1.959964)
    """
    if not 0.0 < p < 1.0:
        return math.nan
    plow = 0.02425
    if p < plow or p > 1.0 - plow:
        q = math.sqrt(-2.0 * math.log(min(p, 1.0 - p)))
        num = ((((_C[0] * q + _C[1]) * q + _C[2]) * q + _C[3]) * q + _C[4]) * q + _C[5]
        den = (((_D[0] * q + _D[1]) * q + _D[2]) * q + _D[3]) * q + 1.0
        return num / den if p < plow else -num / den
    q = p - 0.5
    r = q * q
    num = (((((_A[0] * r + _A[1]) * r + _A[2]) * r + _A[3]) * r + _A[4]) * r + _A[5]) * q
    den = ((((_B[0] * r + _B[1]) * r + _B[2]) * r + _B[3]) * r + _B[4]) * r + 1.0
    return num / den


def chi2_quantile_wh(nu: float, z: float) -> float:
    """Wilson-Hilferty chi-square quantile at the normal quantile z (0 where it goes negative).

    Examples
    --------
    >>> round(chi2_quantile_wh(100.0, 0.0), 1)  # the median, exact 99.33
    99.3
    """
    h = 2.0 / (9.0 * nu)
    t = 1.0 - h + z * math.sqrt(h)
    return nu * t ** 3 if t > 0.0 else 0.0


@dataclass(frozen=True)
class TermRef:
    """One estimate: value, interval, valid, upper_limit.

    Examples
    --------
    >>> TermRef(1.0, 0.5, 2.0, True, False).hi
    2.0
    """

    value: float = 0.0
    lo: float = 0.0
    hi: float = 0.0
    valid: bool = False
    upper_limit: bool = False


@dataclass(frozen=True)
class NoiseEstimatesRef:
    """N, B, K and the tau of the Allan minimum; ok False when nothing is estimable.

    Examples
    --------
    >>> NoiseEstimatesRef(False, TermRef(), TermRef(), TermRef(), 0.0).ok
    False
    """

    ok: bool
    n: TermRef
    b: TermRef
    k: TermRef
    b_tau_s: float


def _interval(avar: float, nu: float, z: float) -> tuple[float, float]:
    q_hi = chi2_quantile_wh(nu, z)
    q_lo = chi2_quantile_wh(nu, -z)
    lo = avar * nu / q_hi if q_hi > 0.0 else 0.0
    hi = avar * nu / q_lo if q_lo > 0.0 else math.inf
    return lo, hi


def estimate_noise(avar: np.ndarray, terms: np.ndarray, tau_s: np.ndarray,
                   coverage: float) -> NoiseEstimatesRef:
    """The estimates from an octave curve (avar, term counts, tau of octaves 0, 1, ...).

    Examples
    --------
    >>> import numpy as np
    >>> est = estimate_noise(np.array([1.0, 0.5, 0.25]), np.array([99, 49, 24]),
    ...                      np.array([1.0, 2.0, 4.0]), 0.95)
    >>> est.n.value, est.n.upper_limit, est.b.upper_limit
    (1.0, False, True)
    """
    none = NoiseEstimatesRef(False, TermRef(), TermRef(), TermRef(), 0.0)
    if not 0.0 < coverage < 1.0:
        return none
    usable = 0
    for k in range(len(avar)):
        if terms[k] < MIN_TERMS or not math.isfinite(avar[k]):
            break
        usable = k + 1
    if usable == 0:
        return none
    av = [float(v) for v in avar[:usable]]
    cnt = [int(t) for t in terms[:usable]]
    tau = [float(t) for t in tau_s[:usable]]
    fac = [1 << k for k in range(usable)]
    z = -normal_quantile(0.5 * (1.0 - coverage))

    kn = None
    best_dev = 0.0
    for k in range(usable - 1):
        if not (av[k] > 0.0 and 2.0 ** -1.3 * av[k] <= av[k + 1] <= 2.0 ** -0.7 * av[k]):
            continue
        r = 2.0 * av[k + 1] / av[k]
        dev = max(r, 1.0 / r)
        if dev <= 2.0 ** 0.1:
            kn = k
            break
        if kn is None or dev < best_dev:
            kn, best_dev = k, dev
    if kn is not None:
        lo, hi = _interval(av[kn], nonoverlapped_edf("white", cnt[kn], fac[kn]), z)
        n = TermRef(math.sqrt(av[kn] * tau[kn]), math.sqrt(lo * tau[kn]),
                    math.sqrt(hi * tau[kn]), True, False)
    else:
        best = min(math.sqrt(_interval(av[k], nonoverlapped_edf("white", cnt[k], fac[k]), z)[1]
                             * tau[k]) for k in range(usable))
        n = TermRef(best, 0.0, best, True, True)

    kmin = int(np.argmin(av))
    lo, hi = _interval(av[kmin], nonoverlapped_edf("flicker", cnt[kmin], fac[kmin]), z)
    b_hi = math.sqrt(hi) / FLICKER_FLOOR
    if kmin + 1 < usable:
        b = TermRef(math.sqrt(av[kmin]) / FLICKER_FLOOR, math.sqrt(lo) / FLICKER_FLOOR, b_hi,
                    True, False)
    else:
        b = TermRef(b_hi, 0.0, b_hi, True, True)

    kl = usable - 1
    if kl > kmin and av[kl] >= 2.0 ** 0.5 * av[kl - 1]:
        white = n.value ** 2 / tau[kl] if not n.upper_limit else 0.0
        lo, hi = _interval(av[kl], nonoverlapped_edf("random_walk", cnt[kl], fac[kl]), z)

        def k_of(v: float) -> float:
            return math.sqrt(3.0 * (v - white) / tau[kl]) if v > white else 0.0

        kk = TermRef(k_of(av[kl]), k_of(lo), k_of(hi), True, False)
    else:
        hi = _interval(av[kl], nonoverlapped_edf("random_walk", cnt[kl], fac[kl]), z)[1]
        best = math.sqrt(3.0 * hi / tau[kl])
        kk = TermRef(best, 0.0, best, True, True)
    return NoiseEstimatesRef(True, n, b, kk, tau[kmin])
