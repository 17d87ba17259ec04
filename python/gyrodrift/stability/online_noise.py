"""Online IEEE Std 952 noise estimates (angle random walk N, bias instability B, rate random
walk K) with intervals, read from a :class:`~gyrodrift.stability.streaming.StreamingAllan`
curve while it grows, by the C++ code the target runs
(include/gyrodrift/stability/online_noise.hpp).

Read-offs (IEEE Std 952-1997 Annex C) from the octaves with at least :data:`MIN_TERMS`
squared differences:

- **N** where white rate noise dominates: of the octaves whose variance falls to the next
  one with slope -1 +- 0.3, the shortest within -1 +- 0.1, else the one closest to -1
  (quantization below and bias instability above add least there): N = sqrt(sigma^2(tau)
  tau); without such an octave an upper limit.
- **B** from the Allan minimum: B = sigma_min / 0.664 at ``b_tau_s`` (not a fitted flat
  term); an upper limit while the curve still falls at its longest usable octave.
- **K** at the longest usable octave once the curve rises into it by at least half the
  random-walk slope: K = sqrt(3 (sigma^2 - N^2 / tau) / tau); until then an upper limit.

Intervals: chi-square with the non-overlapped edf of the noise type read (white for N,
flicker for B, random walk for K; :func:`nonoverlapped_edf`), quantiles by Wilson-Hilferty.
Units are the record's: for a record in deg/h, N in deg/h*sqrt(s), B in deg/h, K in
deg/h/sqrt(s); :meth:`NoiseEstimates.ieee_deg_h` converts to deg/sqrt(h), deg/h and
deg/h/sqrt(h).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.stability.allan import ONE_SIGMA_CI
from gyrodrift.stability.streaming import StreamingAllan

__all__ = ["MIN_TERMS", "NOISE_EDF_TYPES", "NoiseEstimates", "NoiseTerm", "chi2_quantile",
           "estimate_noise", "noise_from_tuple", "nonoverlapped_edf"]

#: Octaves with fewer squared differences are not read.
MIN_TERMS = 8
#: Noise types of :func:`nonoverlapped_edf` (white: N, flicker: B, random_walk: K).
NOISE_EDF_TYPES: tuple[str, ...] = ("white", "flicker", "random_walk")


@dataclass(frozen=True)
class NoiseTerm:
    """One noise-term estimate.

    Attributes:
        value: the estimate (the upper limit when ``upper_limit``).
        lo, hi: the interval at the requested probability (lo = 0 for an upper limit).
        valid: False when the curve so far tells nothing about the term.
        upper_limit: True when only ``hi`` is meaningful (the term is not seen yet).

    Examples
    --------
    >>> NoiseTerm(2.0, 1.0, 3.0, True, False).as_dict()["hi"]
    3.0
    """

    value: float
    lo: float
    hi: float
    valid: bool
    upper_limit: bool

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {"value": self.value, "lo": self.lo, "hi": self.hi, "valid": self.valid,
                "upper_limit": self.upper_limit}

    def scaled(self, factor: float) -> NoiseTerm:
        """The same estimate in other units (every number times factor).

        Examples
        --------
        >>> NoiseTerm(2.0, 1.0, 3.0, True, False).scaled(0.5).value
        1.0
        """
        return NoiseTerm(self.value * factor, self.lo * factor, self.hi * factor, self.valid,
                         self.upper_limit)


@dataclass(frozen=True)
class NoiseEstimates:
    """N, B, K read from a streaming Allan curve, with intervals.

    Attributes:
        ok: False when no octave has :data:`MIN_TERMS` terms yet (then nothing is valid).
        n, b, k: the estimates in the record's units (see the module docstring).
        b_tau_s: averaging time of the Allan minimum (s).
        ci: the probability of the intervals.

    Examples
    --------
    >>> import numpy as np
    >>> sa = StreamingAllan(100.0, 8)
    >>> _ = sa.push(np.random.default_rng(0).standard_normal(20_000))
    >>> est = estimate_noise(sa, 0.95)
    >>> est.ok, est.n.valid, est.n.upper_limit, est.k.upper_limit
    (True, True, False, True)
    >>> bool(est.n.lo < 0.1 < est.n.hi)  # N = sigma / sqrt(rate) = 0.1
    True
    """

    ok: bool
    n: NoiseTerm
    b: NoiseTerm
    k: NoiseTerm
    b_tau_s: float
    ci: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {"ok": self.ok, "n": self.n.as_dict(), "b": self.b.as_dict(),
                "k": self.k.as_dict(), "b_tau_s": self.b_tau_s, "ci": self.ci}

    def ieee_deg_h(self) -> NoiseEstimates:
        """For a record in deg/h: N in deg/sqrt(h), B in deg/h, K in deg/h/sqrt(h).

        Examples
        --------
        >>> t = NoiseTerm(60.0, 60.0, 60.0, True, False)
        >>> e = NoiseEstimates(True, t, t, t, 1.0, 0.95).ieee_deg_h()
        >>> e.n.value, e.b.value, e.k.value
        (1.0, 60.0, 3600.0)
        """
        return NoiseEstimates(self.ok, self.n.scaled(1.0 / 60.0), self.b,
                              self.k.scaled(60.0), self.b_tau_s, self.ci)


def _term(t: tuple[float, float, float, bool, bool]) -> NoiseTerm:
    return NoiseTerm(float(t[0]), float(t[1]), float(t[2]), bool(t[3]), bool(t[4]))


def noise_from_tuple(raw: tuple[Any, ...], ci: float) -> NoiseEstimates:
    """Build the result from the binding's tuple (ok, n, b, k, b_tau_s).

    Examples
    --------
    >>> t = (1.0, 0.5, 2.0, True, False)
    >>> noise_from_tuple((True, t, t, t, 4.0), 0.95).b_tau_s
    4.0
    """
    return NoiseEstimates(bool(raw[0]), _term(raw[1]), _term(raw[2]), _term(raw[3]),
                          float(raw[4]), ci)


def _check_ci(ci: float) -> float:
    c = float(ci)
    if not (0.0 < c < 1.0):
        raise GyrodriftValueError(f"ci must lie in (0, 1), got {ci!r}")
    return c


def estimate_noise(allan: StreamingAllan, ci: float = ONE_SIGMA_CI) -> NoiseEstimates:
    """IEEE 952 N, B, K from a streaming Allan curve so far, intervals at probability ci.

    Runs the target's C++ code on the curve's own precision (float64 or float32).

    Parameters
    ----------
    allan : StreamingAllan
        The curve (its samples in the record's units).
    ci : float, optional
        Probability of the intervals (default one sigma, 0.6827).

    Raises
    ------
    GyrodriftTypeError
        allan is not a StreamingAllan.
    GyrodriftValueError
        ci outside (0, 1).

    Examples
    --------
    >>> import numpy as np
    >>> sa = StreamingAllan(10.0, 4)
    >>> estimate_noise(sa).ok  # no sample yet
    False
    """
    if not isinstance(allan, StreamingAllan):
        raise GyrodriftTypeError(f"allan must be a StreamingAllan, got {type(allan).__name__}")
    c = _check_ci(ci)
    return noise_from_tuple(allan._impl.estimate_noise(c), c)


def nonoverlapped_edf(noise: str, n: int, m: int) -> float:
    """Equivalent degrees of freedom of the non-overlapped Allan variance the target uses.

    Moment matching for n squared differences at averaging factor m: white noise exact,
    flicker and random walk within 0.5 % of Greenhall's algorithm at m >= 4
    (include/gyrodrift/stability/allan_chi2.hpp).

    Parameters
    ----------
    noise : {'white', 'flicker', 'random_walk'}
        The noise type.
    n : int
        Squared differences (>= 0).
    m : int
        Averaging factor (>= 1).

    Examples
    --------
    >>> round(nonoverlapped_edf("white", 100, 1), 3)  # 100^2 / (1.5 * 100 - 0.5)
    66.89
    """
    if noise not in NOISE_EDF_TYPES:
        raise GyrodriftValueError(f"noise must be one of {NOISE_EDF_TYPES}, got {noise!r}")
    if int(n) < 0 or int(m) < 1:
        raise GyrodriftValueError(f"need n >= 0 and m >= 1, got n={n!r}, m={m!r}")
    return float(core("allan").nonoverlapped_edf(NOISE_EDF_TYPES.index(noise), int(n), int(m)))


def chi2_quantile(nu: float, p: float) -> float:
    """Chi-square quantile at probability p with nu degrees of freedom, as the target computes
    it (Wilson-Hilferty with Acklam's normal quantile; within 1 % of the exact one for
    nu >= 3 and 1e-6 <= p <= 1 - 1e-6).

    Examples
    --------
    >>> round(chi2_quantile(10.0, 0.975), 1)  # exact: 20.48
    20.5
    """
    if not (float(nu) > 0.0 and math.isfinite(float(nu))):
        raise GyrodriftValueError(f"nu must be positive and finite, got {nu!r}")
    if not (0.0 < float(p) < 1.0):
        raise GyrodriftValueError(f"p must lie in (0, 1), got {p!r}")
    native = core("allan")
    return float(native.chi2_quantile_wh(float(nu), native.normal_quantile(float(p))))
