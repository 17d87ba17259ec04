"""Generalized Method of Wavelet Moments (GMWM; Guerrier, Skaloud, Stebler, Victoria-Feser,
JASA 108 (2013) 776-789) for composite gyro noise models, with parameter intervals and model
selection by the wavelet variance information criterion.

Record and scales
-----------------
x_t, t = 0..N-1: rate samples (deg/h) at interval dt = 1 / rate_hz. Haar MODWT wavelet filter
of level j (Percival & Walden 2000, "Wavelet Methods for Time Series Analysis", eq. 96):
L_j = 2^j taps, h_{j,l} = +1/2^j for l < 2^(j-1) and -1/2^j for 2^(j-1) <= l < 2^j, i.e.
W_{j,t} = (mean of x over the newer half - mean over the older half) / 2 with halves of
m_j = 2^(j-1) samples. The scale is tau_j = 2^j dt (the filter width; GMWM's convention).
The unbiased wavelet variance uses the M_j = N - L_j + 1 coefficients free of the boundary::

    nu^2_j = (1 / M_j) sum_{t = L_j - 1}^{N - 1} W_{j,t}^2.

W_{j,t} is half the difference of adjacent m_j-sample averages, so nu^2_j = sigma^2_A(m_j dt)
/ 2: half the overlapping Allan variance at averaging time tau_j / 2 (Percival & Guttorp 1994),
used as a cross-check in the tests. Computed with one cumulative sum: S_i = C_{i+m} - C_i,
W = (S_{i+m} - S_i) / (2m), O(N) per scale.

Theoretical Haar wavelet variance (tau = 2^j in samples; Guerrier et al. 2013 sec. 2 and
table 1, Zhang 2008; each one checked in the tests against the exact quadratic form
h_j' Gamma h_j of the process's covariance Gamma)::

    - white noise N, per-sample variance s2:          nu^2 = s2 / tau
    - quantization Q, white angle error e_t of variance q2 differenced into rate,
      x_t = e_t - e_{t-1} (per-sample units):          nu^2 = 6 q2 / tau^2
    - random walk K, x_t = x_{t-1} + u_t, var(u) = g2: nu^2 = (tau^2 + 2) g2 / (12 tau)
    - drift (ramp) R, x_t = w t:                       nu^2 = w^2 tau^2 / 16
    - first-order Gauss-Markov = AR(1) x_t = phi x_{t-1} + u_t, var(u) = v, phi = exp(-dt / T_c),
      stationary variance sigma^2 = v / (1 - phi^2):
          nu^2 = 2 v [tau/2 - 3 phi - (tau/2) phi^2 + 4 phi^(tau/2 + 1) - phi^(tau + 1)]
                 / [tau^2 (1 - phi)^2 (1 - phi^2)]
      (from sigma^2_A(m) = Var(ybar_m) - Cov(ybar_m, ybar'_m) with gamma(k) = sigma^2 phi^|k|,
      summed in closed form; nu^2 = sigma^2_A(tau/2) / 2).

IEEE Std 952 / 1554 units (dt in s, x in deg/h): N = sqrt(s2 dt) / 60 deg/sqrt(h) (white rate
of two-sided PSD N^2), Q = sqrt(q2) dt arcsec ((deg/h) s), K = 60 sqrt(g2 / dt)
deg/h/sqrt(h), R = 3600 w / dt deg/h^2, GM sigma deg/h and T_c s. The continuous-time
densities a filter needs: N [rad/s/sqrt(Hz)] = N [deg/sqrt(h)] (pi/180) / 60 and
K [rad/s^2/sqrt(Hz)] = K [deg/h/sqrt(h)] (pi/180) / 3600 / 60.

Estimator
---------
theta_hat = argmin (nu_hat - nu(theta))' Omega^-1 (nu_hat - nu(theta)) over the log of each
variance and of T_c (each bounded: T_c as below, a variance within 1e-12..1e6 of what
that term alone needs to reach the measured WV, so that exp() of a trial step cannot
overflow). Iterated GMM, three steps (Hansen 1982; Hansen, Heaton & Yaron 1996): step 1 with
the diagonal weights 1 / var(nu_hat_j) of the chi-squared approximation with
eta_j = max(M_j / 2^j, 1) degrees of freedom (Percival & Walden 2000 eq. 313c, model-free);
steps 2 and 3 with the efficient weight Omega(theta_prev)^-1, where Omega is the covariance
of the estimated wavelet variances under the fitted Gaussian model, computed exactly for the
record length (not a bootstrap)::

    Cov(nu_hat_i, nu_hat_j) = 2 / (M_i M_j) sum_k n_ij(k) c_ij(k)^2,

c_ij(k) = Cov(W_{i,s}, W_{j,s+k}) from the model's spectrum and the filters by FFT, n_ij(k)
the number of coefficient pairs at lag k (Isserlis' theorem for Gaussian W; the drift term is
deterministic and adds no variance). Parameter covariance (GMM, efficient weight):
(D' Omega^-1 D)^-1 with D = d nu / d theta at theta_hat, recomputed with Omega(theta_hat);
asymptotic intervals are symmetric on the log scale (theta_hat exp(+-z se_log)), or,
with bootstrap=B > 0, percentile intervals of B parametric-bootstrap refits (records
simulated from theta_hat, same weight matrix).

Model selection (model="auto"): every sub-model of max_model (but the drift alone) is
fitted with ONE common weight, the inverse of `wv_covariance_nonparametric`: the Gaussian
covariance of the estimated WV under a sieve (white, quantization, random walk and one
Gauss-Markov term per octave, matched to the measured WV by NNLS), i.e. an octave-band
spectral estimate that depends on the data only, not on the candidate. All candidates then
minimise the same quadratic form, so their J statistics and the wavelet variance
information criterion (Guerrier, Stebler, Skaloud, Victoria-Feser, IEEE TIM 65 (2016)
973-983)::

    WIC = J + 2 tr(P) = J + 2 p,  P = D (D' W D)^+ D' W,  W = Omega_np^-1,

are comparable (tr(P) = p: W is the inverse of the covariance the penalty needs). Scoring
each candidate with its own model-based weight Omega(theta_hat), as done before, made
the objectives incomparable: a model that misstates the variance of the long scales (a
random walk alone with an absurd K) states an enormous Omega there and scored the smallest
J while its fitted WV was 1e7 times the measured one. Each candidate's fit is then
checked scale by scale (`gyrodrift.stability.fit_check.check_fit`: inside the measured
chi-squared interval or within the ratio tolerance), and only candidates whose check holds
are eligible; when none holds, the candidates are refitted with a model-error allowance
of MODEL_ERROR_REL per scale added to the common covariance, and the notes say that no
candidate describes the data. A Gauss-Markov term whose correlation time stops at a bound
is turned into the white noise (lower bound) or random walk (upper bound) it stands for
and the candidate is scored as that model (`_convert_pinned`). A named model (model=
"N+K", ...) keeps the iterated efficient weight below, and the same conversion.

Misfit and intervals: where J exceeds its MISFIT_P quantile of chi-squared (scales - p
dof) or the check fails, the result is flagged approximate. The parameter covariance is
misspecification-robust in every case (`_robust_param_cov`): the GMM sandwich
(D' W D)^-1 D' W S W D (D' W D)^-1 (Hall & Inoue 2003 for GMM under misspecification, here
without their higher-order term), W the fit's weight, S the covariance of the measured
wavelet variances from the data (the sieve of `wv_covariance_nonparametric`; for a named
model its variances raised to the model's where those are larger) plus a model
discrepancy d^2 diag(nu_hat) C diag(nu_hat): what no candidate follows (an output filter,
a hump, flicker noise between the Gauss-Markov terms) as a random relative error of the
wavelet variance, correlated between scales by the overlap C of the Haar filters over
log-frequency (`allan_kernel_corr`), with d^2 estimated from the residuals by moments (the
same construction as the Allan fit's, `gyrodrift.stability.allan_fit`). When the model holds,
d is near 0 and the sandwich is the efficient GMM covariance. (The earlier rule multiplied
the model-based covariance by J / dof; on a misfit record with J / dof = 7e4 that gave an
interval of a factor 55 each way.) A correlation time at a bound that is kept gets a
one-sided interval.

Selected (`select_nested`): start at the eligible candidate of smallest WIC; while a sub-model with
one term fewer has a WIC within WIC_MARGIN = 2 of the current model's, move to the best such
sub-model. WIC(sub) - WIC(model) = J_sub - J_model - 2 dp, so a term of dp parameters is kept
only if it lowers J by more than 2 dp + 2: a nested GMM distance test at about 5 % (chi-squared
with dp dof: P(chi2_1 > 4) = 0.046, P(chi2_2 > 6) = 0.050), not a preference for small
models in general. Models that are not nested in one another (white + random walk + GM
against white + two GM, where a slow GM and a random walk are nearly the same curve over
the longest scales) are compared by WIC alone. (The earlier rule took the model with the
fewest parameters among all within 2 of the minimum, nested or not; on the Monte Carlo's
tuning seeds it chose N+K+GM over a lower-WIC N+GM+GM; scripts/gmwm_monte_carlo.py and
the GMWM validation page.)

The random walk a user reads (`GmwmResult.implied`): no candidate has a flicker floor (bias
instability, a flat wavelet variance), so on flicker records the selected model's random
walk holds the floor's longest scales (K too high, with an interval that misses the truth)
or a Gauss-Markov term at its upper bound or a ramp hides it. K is therefore reported only
where the record resolves it: a linear fit of white noise, K and a flat floor to the
longest LONG_SCALE_LEVELS scales (`_long_scale_k`) says whether the floor is there; K is
that fit's if it is, else the selected model's own K term, and is reported only if it
carries at least K_RESOLVED_SHARE of the fitted wavelet variance at the longest scale and
its interval is within a factor K_RESOLVED_RATIO (`_resolve_k`); otherwise its upper limit
is.

Examples
--------
>>> import gyrodrift
>>> rec = gyrodrift.simulate(n=2**15, rate_hz=100.0, n_deg_rt_h=0.05, k_deg_h_rt_h=5.0,
...                          seed=1)
>>> res = gyrodrift.identify_gmwm(rec.rate_deg_h, 100.0, model="N+K")
>>> res.model
'N+K'
>>> 0.04 < res.value("N") < 0.06
True
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
from collections.abc import Callable, Generator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.fft
import scipy.linalg
import scipy.optimize
import scipy.stats

from gyrodrift._scale import normalising_scale, scale_for_peak
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.io.records import is_file_backed, iter_chunks
from gyrodrift.stability.fit_check import DEFAULT_TOLERANCE, FitCheck, check_fit
from gyrodrift.units import TERM_UNITS

__all__ = [
    "FILE_BACKED_MIN",
    "TERMS",
    "GmwmParam",
    "GmwmResult",
    "WaveletVariance",
    "allan_kernel_corr",
    "haar_wv",
    "identify_gmwm",
    "parse_model",
    "theoretical_wv",
    "wv_covariance",
    "wv_covariance_nonparametric",
]

#: Term letters in canonical order; GM may repeat up to MAX_GM times.
TERMS = ("Q", "N", "K", "R", "GM")
MAX_GM = 3
DEFAULT_MAX_MODEL = "Q+N+K+R+GM+GM"
#: Above this correlation time (samples) the GM wavelet variance is computed by the
#: cancellation-free route (see _component_wv); up to it the closed form is accurate to ~1e-7
#: (1024 = the upper T_c bound of a 2^14-sample record: the Monte Carlo's numbers are unchanged).
GM_CLOSED_FORM_MAX_TC = 1024.0
#: A term is dropped from the selected model while that raises its WIC by at most this
#: (select_nested: a nested test at about 5 %).
WIC_MARGIN = 2.0
#: Iterated GMM (_weighted_lsq): at most this many efficient-weight steps after the first,
#: model-free one; they go on while J at the own weight falls by more than J_REL_TOL.
MAX_EFFICIENT_STEPS = 6
J_REL_TOL = 0.01
#: _weighted_lsq restarts the iteration of a model with GM terms whose J did not settle and
#: exceeds this quantile of chi-squared (scales - parameters dof) while its step-1 objective
#: does not, from RESTART_TC_POINTS correlation times per GM term spread geometrically over
#: the T_c bounds (all combinations for several GMs).
RESTART_P = 0.999
RESTART_TC_POINTS = 3
#: A fit whose J statistic exceeds this quantile of chi-squared (scales - parameters dof), or
#: whose fitted wavelet variance leaves the measured one (FitCheck), is reported as
#: approximate and its intervals are widened (identify_gmwm).
MISFIT_P = 0.95
#: A Gauss-Markov correlation time within this distance (on the log scale) of a bound of
#: `_tc_bounds` is at the bound (converted by `_resolve_pinned`).
TC_BOUND_LOG_TOL = 1e-3
#: Model-error allowance (relative, per scale) added to the common weight's covariance when
#: no candidate's fit holds (identify_gmwm): half the check's ratio tolerance.
MODEL_ERROR_REL = DEFAULT_TOLERANCE / 2.0
#: The intervals of N and K of a selected model cover those of the eligible candidates
#: within this WIC distance (`_widen_by_model_set`): twice the nested-selection margin, the
#: distance within which information-criterion weights still give a model real support.
MODEL_SET_DELTA = 2.0 * WIC_MARGIN
#: Whether the longest scales show a flicker floor, and K if they do, is read from a fit of
#: white noise + K + a flat floor (+ the ramp where the selected model has one) to the
#: longest LONG_SCALE_LEVELS scales (`_long_scale_k`): six octaves, a factor 64 in scale.
LONG_SCALE_LEVELS = 6
#: K is reported as resolved only where its random walk carries at least this share of the
#: fitted wavelet variance at the longest scale (the record shows it) ...
K_RESOLVED_SHARE = 0.5
#: ... and its 95 % interval is within this factor (high / low). With an honest interval
#: that is a standard error of at most ln(2) / (2 * 1.96) = 0.177 on log K, so the estimate
#: lies within -30 % .. +30 % of the truth with probability >= 0.91 (log 1.3 = 0.262 =
#: 1.48 se, log 0.7 = -0.357 = -2.02 se); wider, the record does not show K within 30 %
#: and only the upper limit is reported.
K_RESOLVED_RATIO = 2.0


# --------------------------------------------------------------------------------------
# model strings


def parse_model(model: str) -> tuple[str, ...]:
    """'N+K+GM' -> canonical tuple ('N', 'K', 'GM'); ValueError on unknown or repeated terms.

    Examples
    --------
    >>> parse_model("N+K"), parse_model("q+n+gm")
    (('N', 'K'), ('Q', 'N', 'GM'))
    """
    if not isinstance(model, str) or not model.strip():
        raise GyrodriftValueError(f"model must be a string like 'N+K+GM', got {model!r}")
    parts = [p.strip().upper() for p in model.split("+")]
    for p in parts:
        if p not in TERMS:
            raise GyrodriftValueError(
                f"unknown term {p!r} in model {model!r}; terms: {', '.join(TERMS)}")
    for p in TERMS[:-1]:
        if parts.count(p) > 1:
            raise GyrodriftValueError(f"term {p} appears more than once in {model!r}")
    if parts.count("GM") > MAX_GM:
        raise GyrodriftValueError(
            f"at most {MAX_GM} GM terms, got {parts.count('GM')} in {model!r}")
    return tuple(t for t in TERMS[:-1] if t in parts) + ("GM",) * parts.count("GM")


def _model_str(terms: tuple[str, ...]) -> str:
    return "+".join(terms)


def _n_params(terms: tuple[str, ...]) -> int:
    return sum(2 if t == "GM" else 1 for t in terms)


def _sub_models(terms: tuple[str, ...]) -> list[tuple[str, ...]]:
    singles = [t for t in terms if t != "GM"]
    n_gm = terms.count("GM")
    out = []
    for r in range(len(singles) + 1):
        for combo in itertools.combinations(singles, r):
            for g in range(n_gm + 1):
                cand = tuple(combo) + ("GM",) * g
                if cand:
                    out.append(cand)
    return out


# --------------------------------------------------------------------------------------
# wavelet variance


@dataclass(frozen=True, eq=False)
class WaveletVariance:
    """Empirical Haar wavelet variance of a record.

    Attributes
    ----------
    tau_s
        scales 2^j dt, s (Haar filter width; the Allan averaging time is tau_s / 2).
    level
        j = 1..J.
    nu2
        wavelet variance, (record unit)^2.
    n_coeffs
        M_j, boundary-free coefficients behind each value.
    eta
        chi-squared degrees of freedom max(M_j / 2^j, 1) (Percival & Walden eq. 313c).

    Examples
    --------
    >>> wv = haar_wv(np.random.default_rng(0).normal(0, 1.0, 4096), 100.0)
    >>> wv.level[:3], wv.tau_s[:3], wv.n_coeffs[:3]
    (array([1, 2, 3]), array([0.02, 0.04, 0.08]), array([4095, 4093, 4089]))
    """

    tau_s: np.ndarray
    level: np.ndarray
    nu2: np.ndarray
    n_coeffs: np.ndarray
    eta: np.ndarray
    rate_hz: float
    n_samples: int

    def interval(self, ci: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """Chi-squared interval of nu^2 with eta degrees of freedom, probability ci."""
        p = (1.0 - ci) / 2.0
        lo = self.nu2 * self.eta / scipy.stats.chi2.ppf(1.0 - p, self.eta)
        hi = self.nu2 * self.eta / scipy.stats.chi2.ppf(p, self.eta)
        return lo, hi


def _check_record(x: Any, rate_hz: float, min_n: int = 16) -> np.ndarray:
    if not (isinstance(rate_hz, (int, float, np.floating, np.integer))
            and not isinstance(rate_hz, bool) and math.isfinite(rate_hz) and rate_hz > 0):
        raise GyrodriftValueError(f"rate_hz must be a positive finite number, got {rate_hz!r}")
    arr = np.asarray(x)
    if arr.ndim != 1:
        raise GyrodriftValueError(f"x: expected a 1-D record, got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
        raise GyrodriftTypeError(f"x: expected real numbers, got dtype {arr.dtype}")
    if arr.size < min_n:
        raise GyrodriftValueError(f"x: {arr.size} samples are too few for GMWM (need >= {min_n})")
    arr = np.asarray(arr, dtype=np.float64)
    bad = int(np.count_nonzero(~np.isfinite(arr)))
    if bad:
        raise GyrodriftValueError(f"x: {bad} NaN/Inf samples; drop or repair them first")
    return arr


def _default_levels(n: int) -> int:
    # Top level with M_J = N - 2^J + 1 >= N / 2 (at least half the record behind it).
    return max(int(n).bit_length() - 2, 1)  # floor(log2 N) - 1


def haar_wv(x: np.ndarray, rate_hz: float, *, max_level: int | None = None
            ) -> WaveletVariance:
    """Haar MODWT wavelet variance (module docstring), O(N) per level by one cumulative sum.

    max_level: highest level J (default floor(log2 N) - 1, so that M_J >= N / 2).

    Examples
    --------
    >>> wv = haar_wv(np.random.default_rng(0).normal(0, 1.0, 4096), 100.0, max_level=3)
    >>> wv.nu2.round(3)  # white noise: sigma^2 / 2^j
    array([0.5  , 0.246, 0.126])
    """
    arr = _check_record(x, rate_hz, min_n=4)
    n = arr.size
    j_max = _default_levels(n) if max_level is None else int(max_level)
    if j_max < 1 or 2 ** j_max > n:
        raise GyrodriftValueError(f"max_level={max_level} does not fit {n} samples (2^J <= N)")
    # The mean cancels from W exactly; removing it keeps the cumulative sum small.
    c = np.empty(n + 1)
    c[0] = 0.0
    np.cumsum(arr - arr.mean(), out=c[1:])
    levels = np.arange(1, j_max + 1)
    nu2 = np.empty(j_max)
    m_coef = np.empty(j_max, dtype=np.int64)
    buf_s = np.empty(n)  # reused: no page faults for new temporaries at every level
    buf_w = np.empty(n)
    for idx, j in enumerate(levels):
        m = 1 << (int(j) - 1)
        s = np.subtract(c[m:], c[:-m], out=buf_s[:n + 1 - m])  # sums of m samples from i
        w = np.subtract(s[m:], s[:-m], out=buf_w[:n + 1 - 2 * m])  # newer - older half
        # einsum, not np.dot: BLAS dot spawns threads and is 50x slower on a loaded machine
        nu2[idx] = float(np.einsum("i,i->", w, w)) / (w.size * 4.0 * m * m)
        m_coef[idx] = w.size
    tau_s = (2.0 ** levels) / float(rate_hz)
    eta = np.maximum(m_coef / 2.0 ** levels, 1.0)
    return WaveletVariance(tau_s, levels, nu2, m_coef, eta, float(rate_hz), n)


#: A file-backed record longer than this (samples) is never held in memory (_haar_wv_file).
FILE_BACKED_MIN = 1 << 20
#: Samples per chunk read from a file-backed record (the streamed Allan variance holds about
#: three chunks).
_WV_PIECE = 1 << 20


def _haar_wv_file(mm: np.ndarray, rate_hz: float, max_level: int | None
                  ) -> WaveletVariance | None:
    """`haar_wv` of a file-backed record without holding it: the Haar MODWT wavelet variance
    at level j is half the overlapping Allan variance at m = 2^(j-1) (w_i is half the
    difference of two adjacent means of m samples, over the same n - 2m + 1 positions), which
    `gyrodrift.stability.allan.oadev` streams from the file in chunks. None when the record is
    of extreme magnitude (`normalising_scale` is not 1; the caller scales it in memory) or a
    level does not fit the Allan variance's range."""
    from gyrodrift.stability.allan import oadev

    n = int(mm.shape[0])
    peak, bad = 0.0, 0
    for p in iter_chunks(mm, _WV_PIECE):
        bad += int(np.count_nonzero(~np.isfinite(p)))
        peak = max(peak, float(np.nanmax(np.abs(p), initial=0.0)))
    if bad:
        raise GyrodriftValueError(f"x: {bad} NaN/Inf samples; drop or repair them first")
    if scale_for_peak(peak) != 1.0:
        return None
    j_max = _default_levels(n) if max_level is None else int(max_level)
    if j_max < 1 or 2 ** j_max > n:
        raise GyrodriftValueError(f"max_level={max_level} does not fit {n} samples (2^J <= N)")
    levels = np.arange(1, j_max + 1)
    m = 2 ** (levels - 1)
    if int(m[-1]) > (n - 1) // 2:
        return None
    res = oadev(mm, float(rate_hz), taus=m / float(rate_hz), alpha=0, progress=False,
                chunk_samples=_WV_PIECE)
    if not np.array_equal(res.m, m):
        return None
    nu2 = res.adev ** 2 / 2.0
    m_coef = np.asarray(res.terms, dtype=np.int64)
    tau_s = (2.0 ** levels) / float(rate_hz)
    eta = np.maximum(m_coef / 2.0 ** levels, 1.0)
    return WaveletVariance(tau_s, levels, nu2, m_coef, eta, float(rate_hz), n)


def _subset(wv: WaveletVariance, tau_range: tuple[float, float]) -> WaveletVariance:
    lo, hi = (float(v) for v in tau_range)
    keep = (wv.tau_s >= lo * (1 - 1e-12)) & (wv.tau_s <= hi * (1 + 1e-12))
    if np.count_nonzero(keep) < 2:
        raise GyrodriftValueError(
            f"tau_range {lo:g}..{hi:g} s keeps {int(np.count_nonzero(keep))} of the scales "
            f"{wv.tau_s[0]:g}..{wv.tau_s[-1]:g} s; need at least 2")
    return WaveletVariance(wv.tau_s[keep], wv.level[keep], wv.nu2[keep], wv.n_coeffs[keep],
                           wv.eta[keep], wv.rate_hz, wv.n_samples)


# --------------------------------------------------------------------------------------
# theoretical wavelet variance


def _ar1_wv(tau: np.ndarray, phi: float, innov: float) -> np.ndarray:
    """Haar WV of AR(1) with innovation variance innov (module docstring)."""
    h = tau / 2.0
    num = h - 3.0 * phi - h * phi * phi + 4.0 * phi ** (h + 1.0) - phi ** (tau + 1.0)
    return 2.0 * innov * num / (tau * tau * (1.0 - phi) ** 2 * (1.0 - phi * phi))


def _component_wv(term: str, p: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """WV of one term for natural per-sample parameters p (see theoretical_wv)."""
    if term == "Q":
        return 6.0 * p[0] / tau**2
    if term == "N":
        return p[0] / tau
    if term == "K":
        return (tau * tau + 2.0) * p[0] / (12.0 * tau)
    if term == "R":
        return p[0] * tau * tau / 16.0
    if term == "B":  # flicker floor (the long-scale K fit only): flat
        return np.full(tau.shape, float(p[0]))
    if term == "GM":
        sigma2, tc = p[0], p[1]
        phi = math.exp(-1.0 / tc)
        if phi < 1e-12:  # shorter than a sample: white noise of variance sigma2
            return sigma2 / tau
        if tc > GM_CLOSED_FORM_MAX_TC:
            # phi -> 1: the closed form cancels (relative error ~1e-16 T_c^3: 1e-4 at
            # T_c = 1e4 samples, negative values from 2^18; it was clamped at 1e7, where
            # it returned 2e5 times the true value at tau = 2). Var W from the generalised
            # covariance K of `_gen_cov`, written without cancellation:
            # nu^2 = (6 K(0) - 8 K(m) + 2 K(2m)) / (4 m^2), m = tau / 2, K(0) = 0.
            m = tau / 2.0
            comp = [("GM", np.array([sigma2, tc]))]
            return (2.0 * _gen_cov(comp, 2.0 * m) - 8.0 * _gen_cov(comp, m)) / (4.0 * m * m)
        return _ar1_wv(tau, phi, sigma2 * (1.0 - phi * phi))
    raise GyrodriftValueError(f"unknown term {term!r}")


def theoretical_wv(model: str | tuple[str, ...], params: np.ndarray, tau: np.ndarray
                   ) -> np.ndarray:
    """Haar WV of a composite model at scales tau (in samples, 2^j), per-sample parameters.

    params, in model order: Q -> q2 (variance of the angle error, (x dt)^2 / dt^2 = x^2);
    N -> s2 (variance of the white rate); K -> g2 (random-walk increment variance);
    R -> w^2 (squared ramp per sample); GM -> (sigma^2, T_c in samples).

    Examples
    --------
    >>> theoretical_wv("N", np.array([0.01]), np.array([0.01, 0.02]))
    array([1. , 0.5])
    """
    terms = parse_model(model) if isinstance(model, str) else model
    tau = np.asarray(tau, dtype=np.float64)
    p = np.asarray(params, dtype=np.float64)
    total = np.zeros_like(tau)
    k = 0
    for t in terms:
        width = 2 if t == "GM" else 1
        total = total + _component_wv(t, p[k:k + width], tau)
        k += width
    return total


# --------------------------------------------------------------------------------------
# covariance of the wavelet variance under a Gaussian model


def _series_g3(x: np.ndarray) -> np.ndarray:
    """exp(-x) - 1 + x - x^2/2 without cancellation (Taylor below 0.1, relative error
    < 1e-10 there)."""
    out = np.expm1(-x) + x - 0.5 * x * x
    small = x < 0.1
    xs = x[small]
    out[small] = -xs ** 3 * (1.0 / 6.0 - xs * (1.0 / 24.0 - xs * (1.0 / 120.0 - xs * (
        1.0 / 720.0 - xs * (1.0 / 5040.0 - xs / 40320.0)))))
    return out


def _sinh_minus(eps: float) -> float:
    """sinh(eps) - eps without cancellation."""
    if eps < 0.1:
        e2 = eps * eps
        return eps * e2 * (1.0 / 6.0 + e2 * (1.0 / 120.0 + e2 * (1.0 / 5040.0 + e2 / 362880.0)))
    return math.sinh(eps) - eps


def _gen_cov(comps: list[tuple[str, np.ndarray]], h: np.ndarray) -> np.ndarray:
    """Generalised covariance K(h) of the phase C_t = sum_{s<t} x_s of the model: for
    weights alpha, beta that kill polynomials of degree <= 1 (second differences),
    Cov(sum alpha_p C_{u_p}, sum beta_q C_{v_q}) = sum_p sum_q alpha_p beta_q K(v_q - u_p).

    Stationary x: K = -D/2 with D(h) = Var(x_t + ... + x_{t+h-1}). White noise (s2):
    D = s2 |h|. Quantization (x_t = e_t - e_{t-1}, var e = q2): D = 2 q2 for h != 0.
    AR(1) (stationary variance sigma2, phi = exp(-eps), eps = 1/T_c):
    D = sigma2 [h (1 + phi)/(1 - phi) - 2 phi (1 - phi^h)/(1 - phi)^2]
      = sigma2 {h^2 / sinhc(eps/2)^2 + 2 phi [g3(x) + h (sinh eps - eps)] / (1 - phi)^2},
    x = h eps, g3(x) = e^-x - 1 + x - x^2/2; the h^2 part is a polynomial the second
    differences annihilate, so K = -sigma2 phi [g3(x) + |h| (sinh eps - eps)] / (1 - phi)^2
    is used: no cancellation of h^2-sized terms even for T_c far above the record length.
    Random walk (increment
    variance g2; C is an integrated random walk, an intrinsic random function of order 1):
    K = g2 (|h|^3 - |h|) / 12, which gives Var W = (tau^2 + 2) g2 / (12 tau) (checked).
    """
    a = np.abs(h).astype(np.float64)
    k_out = np.zeros_like(a)
    for t, q in comps:
        if t == "N":
            k_out -= 0.5 * float(q[0]) * a
        elif t == "Q":
            k_out -= float(q[0]) * (a != 0)
        elif t == "K":
            k_out += float(q[0]) * (a * a * a - a) / 12.0
        elif t == "GM":
            sigma2, tc = float(q[0]), float(q[1])
            if tc < 0.05:  # phi < 2e-9: white noise of variance sigma2
                k_out -= 0.5 * sigma2 * a
                continue
            eps = 1.0 / tc
            phi = math.exp(-eps)
            r = -math.expm1(-eps)
            k_out -= sigma2 * phi * (_series_g3(a * eps) + a * _sinh_minus(eps)) / (r * r)
    return k_out


#: At most this many lags per pair of scales in the covariance sum (see wv_covariance).
MAX_LAGS = 1 << 12


def wv_covariance(model: str | tuple[str, ...], params: np.ndarray, levels: np.ndarray,
                  n_samples: int) -> np.ndarray:
    """Covariance matrix of the estimated wavelet variances (levels j, record of n_samples)
    under the Gaussian model (module docstring), for the record length (not asymptotic).

    W_{j,s} = (C_{s+1} - 2 C_{s+1-m} + C_{s+1-2m}) / (2m), m = 2^(j-1), is a second
    difference of the phase C (cumulative sum), so with the generalised covariance K of
    `_gen_cov`, c_ab(k) = Cov(W_{a,s}, W_{b,s+k}) = sum_{p,q} w_p w_q K(k + o_q - o_p)
    / (4 m_a m_b) with w = (1, -2, 1), o = (-2m, -m, 0): nine closed-form terms per lag, no
    FFT, cost independent of the record length. Then::

        Cov(nu_a, nu_b) = 2 / (M_a M_b) sum_k n_ab(k) c_ab(k)^2,

    n_ab(k) = number of s with s in [L_a - 1, N - 1] and s + k in [L_b - 1, N - 1]. The lags
    run over the support of c (``|k| <= 2 m_a`` + 2 m_b, plus the Gauss-Markov tails) with a
    step delta (a power of 2, <= m_a / 8 and <= T_c / 4, so the kinks of c, at multiples of
    m_a, lie on the grid an even number of steps apart; Simpson's rule, exact sum for
    delta = 1); if that would exceed MAX_LAGS lags (scales more than ~8 octaves apart, whose
    covariance is small), delta grows to fit. Tested against the
    FFT route of `gyrodrift.reference.gmwm` and a Monte Carlo covariance.

    Examples
    --------
    >>> wv_covariance("N", np.array([1.0]), np.array([1, 2]), n_samples=1024).round(6)
    array([[0.000733, 0.000183],
           [0.000183, 0.000214]])
    """
    terms = parse_model(model) if isinstance(model, str) else model
    p = np.asarray(params, dtype=np.float64)
    levels = np.asarray(levels, dtype=np.int64)
    n = int(n_samples)
    comps: list[tuple[str, np.ndarray]] = []
    k = 0
    tc_max = 0.0
    tc_min = math.inf
    for t in terms:
        width = 2 if t == "GM" else 1
        comps.append((t, p[k:k + width]))
        if t == "GM":
            tc_max = max(tc_max, float(p[k + 1]))
            tc_min = min(tc_min, float(p[k + 1]))
        k += width
    smooth = [cp for cp in comps if cp[0] != "Q"]
    spiky = [cp for cp in comps if cp[0] == "Q"]
    big_l = (2 ** levels).astype(np.int64)
    m_coef = n - big_l + 1
    w3 = np.array([1.0, -2.0, 1.0])
    cov = np.zeros((levels.size, levels.size))
    for b in range(levels.size):
        mb = int(big_l[b]) // 2
        ob = np.array([-2 * mb, -mb, 0])
        for a in range(b + 1):
            ma = int(big_l[a]) // 2
            oa = np.array([-2 * ma, -ma, 0])
            # Gauss-Markov tails beyond the filters: 16 T_c, at most 32 (m_a + m_b) (further
            # out c decays as phi^k times (m/T_c)^2 and adds < 1e-3 of the sum).
            ext = int(min(16.0 * tc_max, 32.0 * (ma + mb))) if tc_max > 0 else 0
            span = min(2 * ma + 2 * mb + ext, n)
            step = max(1, ma // 8)
            if tc_min < math.inf:
                # resolve the Gauss-Markov cusp (width T_c) where it matters; once
                # T_c < m_a / 16 it carries a few per cent of the sum and m_a / 64 suffices
                step = min(step, max(1, int(tc_min // 4), ma // 64))
            step = 1 << (step.bit_length() - 1)  # power of 2 (divides m_a)
            while 2 * span // step > MAX_LAGS:
                step *= 2
            unit = max(ma, step)
            kmax = (span // unit + 1) * unit  # a multiple of m_a: kinks at even grid indices
            lag = np.arange(-kmax, kmax + 1, step, dtype=np.int64)
            offs = (ob[None, :] - oa[:, None]).ravel()  # o_q - o_p
            wts = np.outer(w3, w3).ravel()
            grid = lag[:, None] + offs[None, :]
            if step <= ma:
                # lags and offsets are multiples of step (powers of 2, offsets multiples of
                # m_a): K is even, so evaluate it once on the lattice 0, step, .. max |h| and
                # gather the 9 values per lag (the same numbers, ~5x fewer evaluations)
                idx = np.abs(grid) // step
                k_smooth = _gen_cov(smooth, step * np.arange(int(idx.max()) + 1))[idx]
            else:
                k_smooth = _gen_cov(smooth, grid)
            c = np.einsum("ij,j->i", k_smooth, wts) / (4.0 * ma * mb)
            # quantization: K has a jump at 0, so c has isolated spikes at lags -(o_q - o_p)
            # (multiples of m_a, on the grid); they are summed exactly, not by the rule.
            cq = (np.einsum("ij,j->i", _gen_cov(spiky, grid), wts) / (4.0 * ma * mb)
                  if spiky else None)
            la, lb = int(big_l[a]), int(big_l[b])
            lo = np.maximum(la - 1, lb - 1 - lag)
            hi = np.minimum(n - 1, n - 1 - lag)
            cnt = np.clip(hi - lo + 1, 0, None).astype(np.float64)
            terms_sum = cnt * c * c
            if step == 1:
                total = float(np.sum(terms_sum))
            else:
                # Simpson's rule: between kinks (multiples of m_a, an even number of steps
                # apart) n c^2 is a polynomial of low degree (white noise: cubic, exact).
                wsimp = np.full(lag.size, 2.0)
                wsimp[1::2] = 4.0
                wsimp[0] = wsimp[-1] = 1.0
                total = step / 3.0 * float(np.einsum("i,i->", wsimp, terms_sum))
            if cq is not None:
                total += float(np.sum(cnt * cq * (2.0 * c + cq)))
            val = 2.0 * total / (float(m_coef[a]) * float(m_coef[b]))
            cov[a, b] = cov[b, a] = val
    return cov


def wv_covariance_nonparametric(wv: WaveletVariance) -> np.ndarray:
    """Covariance of the estimated wavelet variances taken from the measured wavelet
    variance alone, the same for every candidate model: the common weight of model
    selection (identify_gmwm).

    The measured WV is matched by a sieve: quantization, white noise, random walk and a
    comb of Gauss-Markov terms with correlation times 2^k samples, k = -1 .. J - 1 (one per
    octave, so the comb can follow any spectrum that is smooth over an octave: a sum of
    octave-spaced Lorentzians approximates flicker noise's 1/f, and humps from vibration or
    a filter), its variances by non-negative least squares with the model-free weights
    sqrt(eta_j / 2) / nu_hat_j (the chi-squared approximation of each scale, P&W eq. 313c).
    Its covariance follows from the Gaussian formula of `wv_covariance`, exact for the
    record length. It is a spectral estimate in the octave bands of the Haar filters (the
    WV at level j is about twice the spectrum's integral over the octave 1/2^(j+1) ..
    1/2^j, Percival & Walden 2000 sec. 8.1), not a candidate model: it does not change
    with the model being scored and does not depend on any model being right, which is what
    makes the candidates' J statistics comparable. (A weight built from each candidate's own
    fit is not: a model that misstates the long-scale variance, e.g. a random walk alone
    with an absurd K, states an enormous variance there and scores a small J against
    its own weight while its fitted WV is 1e7 times the measured one.)

    Examples
    --------
    >>> x = np.random.default_rng(0).normal(0, 1.0, 1 << 14)
    >>> wv = haar_wv(x, 100.0)
    >>> om = wv_covariance_nonparametric(wv)
    >>> exact = wv_covariance("N", np.array([1.0]), wv.level, wv.n_samples)
    >>> ratio = np.diag(om) / np.diag(exact)  # white noise: the exact covariance
    >>> bool(np.all(np.abs(ratio[:7] - 1.0) < 0.15))  # levels 1-7 (>= 127 dof each)
    True
    """
    tau = 2.0 ** wv.level.astype(np.float64)
    tcs = [2.0 ** k for k in range(-1, int(wv.level[-1]))]
    names = ("Q", "N", "K") + ("GM",) * len(tcs)
    cols = [_component_wv(t, np.array([1.0]), tau) for t in ("Q", "N", "K")]
    cols += [_component_wv("GM", np.array([1.0, tc]), tau) for tc in tcs]
    a = np.column_stack(cols)
    w = np.sqrt(wv.eta / 2.0) / wv.nu2
    aw = a * w[:, None]
    scale = np.linalg.norm(aw, axis=0)
    scale[scale == 0] = 1.0
    coef, _ = scipy.optimize.nnls(aw / scale, w * wv.nu2)
    coef = coef / scale
    terms: list[str] = []
    params: list[float] = []
    for k, t in enumerate(names):
        if coef[k] <= 0.0:
            continue
        terms.append(t)
        params.append(float(coef[k]))
        if t == "GM":
            params.append(tcs[k - 3])
    if not terms:  # cannot happen for a positive WV; keep the diagonal fallback honest
        return np.diag(2.0 * wv.nu2 ** 2 / wv.eta)
    return wv_covariance(tuple(terms), np.array(params), wv.level, wv.n_samples)


# --------------------------------------------------------------------------------------
# fitting


def _chol(v: np.ndarray) -> np.ndarray:
    # Relative jitter for a numerically indefinite covariance (very correlated long scales).
    d = np.sqrt(np.clip(np.diag(v), 1e-300, None))
    corr = v / np.outer(d, d)
    for eps in (0.0, 1e-12, 1e-9, 1e-6, 1e-3):
        try:
            lc = np.linalg.cholesky(corr + eps * np.eye(len(d)))
            return lc * d[:, None]
        except np.linalg.LinAlgError:
            continue
    return np.diag(d)


def _tri_inv(lc: np.ndarray) -> np.ndarray:
    """Inverse of a lower-triangular matrix by LAPACK's unthreaded dtrtri: the BLAS trsm
    behind scipy.linalg.solve_triangular woke its threads at every call and cost ~20 ms
    per 13 x 13 solve on a loaded 2-core machine (0.002 ms here)."""
    inv, info = scipy.linalg.lapack.dtrtri(lc, lower=1)
    if info != 0:
        return scipy.linalg.solve_triangular(lc, np.eye(lc.shape[0]), lower=True)
    return np.tril(inv)


@dataclass
class _Fit:
    terms: tuple[str, ...]
    theta: np.ndarray  # log of per-sample natural parameters
    objective: float


def _design(terms: tuple[str, ...], tau: np.ndarray, tcs: tuple[float, ...]) -> np.ndarray:
    cols = []
    gm = iter(tcs)
    for t in terms:
        if t == "GM":
            cols.append(_component_wv("GM", np.array([1.0, next(gm)]), tau))
        else:
            cols.append(_component_wv(t, np.array([1.0]), tau))
    return np.column_stack(cols)


def _tc_bounds(tau: np.ndarray) -> tuple[float, float]:
    """Bounds of a GM correlation time in samples, [max(0.5, tau_1 / 8), tau_J / 8]
    (_fit_model says why)."""
    return max(0.5, float(tau[0]) / 8.0), float(tau[-1]) / 8.0


def _nnls_start(terms: tuple[str, ...], nu2: np.ndarray, tau: np.ndarray, winv: np.ndarray,
                tcs: tuple[float, ...]) -> tuple[float, np.ndarray]:
    """Linear start at fixed GM correlation times tcs (samples): NNLS of the variances in
    the space whitened by winv; (residual norm, log parameters)."""
    b = np.einsum("ij,j->i", winv, nu2)
    a = np.einsum("ij,jk->ik", winv, _design(terms, tau, tcs))
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    coef, rnorm = scipy.optimize.nnls(a / scale, b)
    coef = coef / scale
    floor = float(np.min(nu2)) * 1e-6
    theta = []
    gm = iter(tcs)
    for k, t in enumerate(terms):
        # a term NNLS switched off starts small but identifiable
        var = max(coef[k], floor / max(np.max(_design((t,), tau, (1.0,))), 1e-300))
        theta.append(math.log(var))
        if t == "GM":
            theta.append(math.log(next(gm)))
    return float(rnorm), np.array(theta)


def _fit_model(terms: tuple[str, ...], nu2: np.ndarray, tau: np.ndarray, chol: np.ndarray,
               start: np.ndarray | None = None) -> _Fit:
    """Minimise |chol^-1 (nu2 - nu(theta))|^2 over log parameters, several starts."""
    def resid(theta: np.ndarray) -> np.ndarray:
        model = theoretical_wv(terms, np.exp(theta), tau)
        return np.einsum("ij,j->i", winv, nu2 - model)

    def jac(theta: np.ndarray) -> np.ndarray:
        return -np.einsum("ij,jk->ik", winv, _jacobian(terms, theta, tau))

    n_gm = terms.count("GM")
    starts: list[np.ndarray] = []
    if start is not None:
        starts.append(start)
    # Linear starts: for fixed GM correlation times the WV is linear in the variances; NNLS
    # in the whitened space over a grid of T_c gives the variance starts.
    tc_grid = np.geomspace(max(1.0, float(tau[0]) / 4.0), float(tau[-1]) / 8.0, 10)
    combos = list(itertools.combinations(tc_grid, n_gm)) if n_gm else [()]
    # Small matrix products by einsum: BLAS calls wake threads, ~2 ms each on a busy machine.
    winv = _tri_inv(chol)
    scored = [_nnls_start(terms, nu2, tau, winv, tcs) for tcs in combos]
    scored.sort(key=lambda s: s[0])
    starts.extend(theta for _, theta in scored[:2 if start is None else 1])
    # A GM term with T_c below half a sample is white noise; one whose wavelet-variance
    # peak (tau ~ 3.8 T_c, the Allan peak at 1.89 T_c) lies near or beyond the longest
    # scale is indistinguishable from a random walk. T_c is kept inside
    # [max(0.5, tau_1 / 8), tau_J / 8]
    # samples (peak at most at tau_J / 2) so that the terms stay distinct and model
    # selection is meaningful.
    # Each variance is kept within 1e6 (above) and 1e-12 (below) of the largest / smallest
    # value that term alone could take to reach the measured WV at some scale: the model WV
    # then stays finite (exp of an unbounded log variance overflowed in trust-region trial
    # steps: test_fit_has_no_overflow_warnings), and a term at the lower bound is absent.
    lower = np.empty(_n_params(terms))
    upper = np.empty(_n_params(terms))
    k = 0
    for t in terms:
        if t == "GM":
            tc_lo, tc_hi = _tc_bounds(tau)
            unit = np.concatenate([_design((t,), tau, (tc,))[:, 0] for tc in (tc_lo, tc_hi)])
            lower[k + 1] = math.log(tc_lo)
            upper[k + 1] = math.log(tc_hi)
        else:
            unit = _design((t,), tau, ())[:, 0]
        # (the GM closed form cancels to 0 at the shortest scales for T_c ~ 1e5 samples:
        # those scales say nothing about the bound)
        ok = np.isfinite(unit) & (unit > 0)
        ratios = np.tile(nu2, unit.size // nu2.size)[ok] / unit[ok]
        lower[k] = math.log(float(np.min(ratios))) - math.log(1e12)
        upper[k] = math.log(float(np.max(ratios))) + math.log(1e6)
        k += 2 if t == "GM" else 1
    best: _Fit | None = None
    for s0 in starts:
        s0 = np.clip(s0, lower + 1e-9, upper - 1e-9)
        try:
            sol = scipy.optimize.least_squares(resid, s0, jac=jac, method="trf", x_scale=1.0,
                                               bounds=(lower, upper), max_nfev=100 * len(s0))
        except (ValueError, FloatingPointError):
            continue
        obj = float(np.einsum("i,i->", sol.fun, sol.fun))
        if best is None or obj < best.objective:
            best = _Fit(terms, sol.x, obj)
    if best is None:
        raise GyrodriftValueError(f"GMWM fit of {_model_str(terms)} failed")
    return _sort_gm(best)


def _sort_gm(fit: _Fit) -> _Fit:
    """Order GM terms by correlation time (identifiability: no label switching)."""
    terms = fit.terms
    idx = []
    k = 0
    for t in terms:
        if t == "GM":
            idx.append(k)
        k += 2 if t == "GM" else 1
    if len(idx) < 2:
        return fit
    theta = fit.theta.copy()
    pairs = sorted((theta[i + 1], theta[i]) for i in idx)
    for i, (ltc, ls2) in zip(idx, pairs, strict=True):
        theta[i], theta[i + 1] = ls2, ltc
    return _Fit(terms, theta, fit.objective)


def _jacobian(terms: tuple[str, ...], theta: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """d nu / d theta (log parameters); analytic for variances, central differences for
    log T_c."""
    p = np.exp(theta)
    cols = []
    k = 0
    for t in terms:
        if t == "GM":
            cols.append(_component_wv("GM", p[k:k + 2], tau))  # d/d log sigma2 = value
            h = 1e-5
            up = _component_wv("GM", np.array([p[k], math.exp(theta[k + 1] + h)]), tau)
            dn = _component_wv("GM", np.array([p[k], math.exp(theta[k + 1] - h)]), tau)
            cols.append((up - dn) / (2 * h))
            k += 2
        else:
            cols.append(_component_wv(t, p[k:k + 1], tau))
            k += 1
    return np.column_stack(cols)


def _weighted_lsq(terms: tuple[str, ...], wv: WaveletVariance, tau: np.ndarray,
                  ) -> tuple[_Fit, np.ndarray]:
    """Iterated GMWM: step 1 with model-free weights, then efficient-weight steps until the
    J statistic stops falling (at least two, at most MAX_EFFICIENT_STEPS). Returns the
    iterate with the smallest J at the model's own efficient weight at that iterate,
    J(theta) = r' Omega(theta)^-1 r (r = nu_hat - nu(theta)), with that J as its objective,
    and Omega(theta) (also the covariance behind the parameter intervals).

    Step 1 uses model-free diagonal weights; its estimate can be far enough off that
    Omega(theta_1) misstates the long scales' variance (J of the true model 20-40 on 13
    scales in the Monte Carlo); one more update of the weight usually brings the estimate to
    the iterated-GMM fixed point (Hansen, Heaton & Yaron 1996) within a few per cent. J is
    taken with Omega(theta_k), not with the weight the step used: a weight from another
    parameter point (e.g. a Gauss-Markov term that stood in for a random walk in step 2 and
    moved in step 3) would state a variance the fitted model does not have, and make J
    small for the wrong reason.

    The iteration need not converge in three steps, nor at all. Where the data fit two
    configurations about equally (white + two Gauss-Markov, 164 s: the slow GM at its T_c
    bound, or at 2-3 s, or both GMs sharing the fast one), the weight of one makes the other
    the best fit and the weight of that one the first again: a 2-cycle, theta_2 ~ theta_4,
    theta_3 ~ theta_5, with J 8-12 at one point and 20-36 at the other (4 of 40 tuning
    records of the Monte Carlo's case 3; the fixed three steps returned the bad point on all
    four). Misfitting candidates creep (white + random walk + GM on case-3 records: J 30-46 at
    step 3, 14-18 at step 7), as does the real record's z axis (Q+GM: J 60.8, 58.3, 56.1,
    55.5, 55.3). J(theta) is the continuously-updated GMM criterion (Hansen, Heaton & Yaron
    1996), which the iterated estimator approximates at its fixed point: the steps go on while it
    falls by more than J_REL_TOL, and the iterate with the smallest criterion is kept. A
    converged iteration stops after step 3, as before (no extra cost), with the estimate of
    step 2 or 3, whichever has the smaller J (they differ by < 1 % in J); each extra step
    costs one covariance and one fit.

    The first weight can also set the whole iteration on a wrong path (the restart
    comment below): a model with GM terms whose iteration did not settle at an implausible
    J, although its step-1 fit is plausible, is restarted from spread-out GM correlation
    times, each start with its own Omega as first weight."""
    nu2 = wv.nu2
    # step 1: model-free diagonal weights, chi-squared with eta dof: var = 2 nu^4 / eta
    chol1 = np.diag(np.sqrt(2.0 / wv.eta) * nu2)
    fit = _fit_model(terms, nu2, tau, chol1)
    best, omega, settled = _iterate(terms, wv, tau, fit.theta)
    n_gm = terms.count("GM")
    dof = max(nu2.size - _n_params(terms), 1)
    plausible = float(scipy.stats.chi2.ppf(RESTART_P, dof))
    if n_gm == 0 or settled or best.objective <= plausible or fit.objective > plausible:
        return best, omega
    # The first weight can set the iteration on a wrong path: on two records of the Monte
    # Carlo's case 2 (random walk + GM of 0.3 s) the step-1 estimate (diagonal weights) had K
    # at 0.1 of the truth, its Omega understated the long scales' variance, and the
    # iteration went on between that point and a GM of 8-10 s standing in for the random
    # walk, J 150-340 on 8 dof, J rising at step 3 (a 2-cycle on one record, a detour on the
    # other), while the iteration started at the true values reaches J ~8. At every weight
    # of that path the fit from the true values found the same minimum as the default
    # start: the weight, not the starts of the fit at a fixed weight, went wrong. So where
    # the iteration did not settle (J still moving by more than J_REL_TOL when it stopped)
    # and J is implausible for a correct model (above the RESTART_P quantile of
    # chi-squared) while the model-free step-1 fit is not (its objective, with the
    # chi-squared variances of each scale, below the same quantile: the model can follow the
    # measured WV, a model that cannot gains nothing from a restart and is not worth its
    # cost), it is restarted from the linear (NNLS) starts at GM correlation times
    # spread over the T_c bounds, each taking its own Omega as first weight: one step each
    # (two covariances), then the iteration goes on from the step with the smallest J,
    # and the smallest J of all is kept.
    winv1 = _tri_inv(chol1)
    tc_lo, tc_hi = _tc_bounds(tau)
    grid = [float(t) for t in np.geomspace(tc_lo, tc_hi, RESTART_TC_POINTS)]
    screened = [
        _iterate(terms, wv, tau, _nnls_start(terms, nu2, tau, winv1, tuple(tcs))[1],
                 max_steps=1)
        for tcs in itertools.combinations(grid, n_gm)]
    first = min(screened, key=lambda c: c[0].objective)
    if first[0].objective < best.objective:
        best, omega = first[0], first[1]
        cont = _iterate(terms, wv, tau, first[0].theta, omega0=first[1])
        if cont[0].objective < best.objective:
            best, omega = cont[0], cont[1]
    return best, omega


def _iterate(terms: tuple[str, ...], wv: WaveletVariance, tau: np.ndarray, theta0: np.ndarray,
             omega0: np.ndarray | None = None, max_steps: int = MAX_EFFICIENT_STEPS
             ) -> tuple[_Fit, np.ndarray, bool]:
    """Efficient-weight steps from theta0 (the first weight is Omega(theta0), or omega0)
    until J at the own weight stops falling (_weighted_lsq), at most max_steps: the iterate
    with the smallest J, its Omega, and whether J settled (changed by at most J_REL_TOL at
    the last step; False where it rose, or the steps ran out)."""
    nu2 = wv.nu2
    theta = theta0
    omega = wv_covariance(terms, np.exp(theta), wv.level, wv.n_samples) if omega0 is None \
        else omega0
    best: tuple[_Fit, np.ndarray] | None = None
    last = math.inf
    settled = False
    for step in range(max_steps):  # steps 2, 3, ...: J at each one's own weight
        fit = _fit_model(terms, nu2, tau, _chol(omega), start=theta)
        theta = fit.theta
        omega = wv_covariance(terms, np.exp(theta), wv.level, wv.n_samples)
        r = np.einsum("ij,j->i", _tri_inv(_chol(omega)),
                      nu2 - theoretical_wv(terms, np.exp(theta), tau))
        scored = _Fit(terms, theta, float(np.einsum("i,i->", r, r)))
        if best is None or scored.objective <= best[0].objective:
            best = (scored, omega)
        if step >= 1 and scored.objective >= (1.0 - J_REL_TOL) * last:
            # converged (J flat) or cycling / rising: no further step helps this path
            settled = scored.objective <= (1.0 + J_REL_TOL) * last
            break
        last = scored.objective
    assert best is not None
    return best[0], best[1], settled


# --------------------------------------------------------------------------------------
# results


@dataclass(frozen=True)
class GmwmParam:
    """One estimated parameter in IEEE Std 952 units, with its interval.

    density / density_unit: the continuous-time density a filter uses (N in
    rad/s/sqrt(Hz), K in rad/s^2/sqrt(Hz)); None for other terms.

    Examples
    --------
    >>> p = GmwmParam(name="N", value=0.01, unit="deg/sqrt(h)", se=0.001, ci_low=0.008,
    ...               ci_high=0.012)
    >>> p.name, p.value, p.density is None
    ('N', 0.01, True)
    """

    name: str
    value: float
    unit: str
    se: float
    ci_low: float
    ci_high: float
    density: float | None = None
    density_unit: str | None = None
    density_ci_low: float | None = None
    density_ci_high: float | None = None

    def as_dict(self) -> dict[str, object]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True, eq=False)
class GmwmResult:
    """GMWM fit of a composite noise model (see the module docstring).

    Attributes
    ----------
    model
        the fitted (or selected) model, canonical order, e.g. "Q+N+GM+K".
    params
        one GmwmParam per parameter (Q, N, K, R, GM1_sigma, GM1_tau, ...).
    tau_s
        scales 2^j dt, s.
    wv
        empirical Haar wavelet variance, (deg/h)^2.
    wv_ci_low, wv_ci_high
        its chi-squared interval (probability ci, eta dof).
    wv_fit
        the fitted total.
    wv_components
        each term's WV ("GM1", ...).
    objective
        the GMM J statistic at the estimate (efficient weight).
    wic
        WIC of the selected model with its own efficient weight (model="auto"), else None.
    candidates
        (model, WIC) of every sub-model tried, best first (model="auto").
    ci, ci_method
        interval probability and "asymptotic" or "bootstrap".
    param_cov
        covariance of the log parameters (internal, model order).
    check
        the fitted WV against the measured one at every scale (FitCheck; statistic
        J / dof).
    approximate
        the model does not describe the data (J above its MISFIT_P quantile of
        chi-squared, or the check fails); the intervals are widened by J / dof.
    weight
        "common" (the model-free weight of wv_covariance_nonparametric, model="auto")
        or "efficient" (the fitted model's own, iterated; a named model).
    notes
        what the fit changed or found (converted Gauss-Markov terms, misfit, K not
        resolved), one line each.
    k_long
        the random walk of the long-scale fit with a flicker floor (`_long_scale_k`): K,
        its interval (probability ci), and the share of the fitted wavelet variance it
        carries at the longest scale; None where the record has too few scales.
    k_resolved
        the K reported as resolved by the record (`_resolve_k`): value and interval;
        None where only its upper limit is reported.

    Examples
    --------
    >>> import numpy as np
    >>> res = identify_gmwm(np.random.default_rng(2).standard_normal(2048), 10.0, model="N")
    >>> res.model, [p.name for p in res.params], sorted(res.as_dict())[:3]
    ('N', ['N'], ['approximate', 'candidates', 'check'])
    """

    model: str
    params: tuple[GmwmParam, ...]
    rate_hz: float
    n_samples: int
    tau_s: np.ndarray
    wv: np.ndarray
    wv_ci_low: np.ndarray
    wv_ci_high: np.ndarray
    wv_fit: np.ndarray
    wv_components: dict[str, np.ndarray]
    objective: float
    wic: float | None
    candidates: tuple[tuple[str, float], ...]
    ci: float
    ci_method: str
    param_cov: np.ndarray = field(repr=False)
    check: FitCheck | None = field(default=None, repr=False)
    approximate: bool = False
    weight: str = "efficient"
    notes: tuple[str, ...] = ()
    k_long: tuple[float, float, float, float] | None = None
    k_resolved: tuple[float, float, float] | None = None

    def param(self, name: str) -> GmwmParam:
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(f"{name} is not a parameter of model {self.model}")

    def value(self, name: str) -> float:
        return self.param(name).value

    def implied(self) -> dict[str, float]:
        """The white-noise density N (deg/sqrt(h)) and the random walk K (deg/h/sqrt(h))
        the fit implies, with intervals (probability ci).

        N adds to the model's N term every Gauss-Markov term whose correlation time lies
        below the smallest scale (white noise there, with its spectral density at zero
        frequency, sigma^2 (1 + phi) / (1 - phi) per sample).

        K is reported only where the record resolves it (K_resolved = 1.0; `_resolve_k`):
        where a fit of white noise, K and a flat flicker floor to the longest scales
        (`_long_scale_k`) shows the floor, the K of that fit; where it shows none, the
        selected model's own K term; in both cases only if that random walk carries at least
        K_RESOLVED_SHARE of the fitted wavelet variance at the longest scale and its interval
        is within a factor K_RESOLVED_RATIO. Otherwise K, K_ci_low and K_ci_high are 0.0
        (not resolved) and K_upper_limit is the value to report: the largest K the measured
        wavelet variance allows at any fitted scale (the random walk's wavelet variance
        alone, (tau^2 + 2) g2 / (12 tau), reaching the upper end of the measured interval).

        K_model (K_model_ci_low, K_model_ci_high) is the random walk of the selected model
        itself: its K term plus every Gauss-Markov term whose correlation time stopped at
        its upper bound, a random walk of increment variance sigma^2 (1 - phi^2) over the
        scales below it (0.0 where it has neither: the random walk is then in the flicker
        floor, a slow Gauss-Markov term or a ramp). Intervals of sums follow from
        param_cov by the delta method on the log scale (d log(1 + phi)/(1 - phi) / d log
        T_c = 2 phi / (T_c (1 - phi^2)), d log(1 - phi^2) / d log T_c = -2 phi^2 / (T_c
        (1 - phi^2)), T_c in samples); a term's own interval where it is alone.

        Examples
        --------
        >>> x = np.random.default_rng(1).standard_normal(4096) * 30.0
        >>> res = identify_gmwm(x, 100.0, model="N")
        >>> imp = res.implied()
        >>> imp["N"] == res.value("N"), imp["K"], imp["K_resolved"]
        (True, 0.0, 0.0)
        >>> imp["N_ci_low"] == res.param("N").ci_low
        True
        """
        dt = 1.0 / self.rate_hz
        terms = parse_model(self.model)
        lo_s = float(self.tau_s[0])
        tc_hi_s = _tc_bounds(self.tau_s / dt)[1] * dt
        z = float(scipy.stats.norm.ppf(0.5 + self.ci / 2.0))
        # per quantity: [(variance, gradient of its log w.r.t. theta)]
        parts: dict[str, list[tuple[float, np.ndarray]]] = {"N": [], "K": []}
        npar = _n_params(terms)
        k = 0
        g = 0
        for t in terms:
            grad = np.zeros(npar)
            grad[k] = 1.0
            if t == "N":
                parts["N"].append(((60.0 * self.value("N")) ** 2 / dt, grad))
            elif t == "K":
                parts["K"].append(((self.value("K") / 60.0) ** 2 * dt, grad))
            elif t == "GM":
                g += 1
                sigma2 = self.value(f"GM{g}_sigma") ** 2
                tc_s = self.value(f"GM{g}_tau")
                tc = tc_s / dt
                phi = math.exp(-1.0 / tc)
                if tc_s < lo_s:
                    grad[k + 1] = 2.0 * phi / (tc * (1.0 - phi * phi))
                    parts["N"].append((sigma2 * (1.0 + phi) / (1.0 - phi), grad))
                elif math.log(tc_s) >= math.log(tc_hi_s) - TC_BOUND_LOG_TOL:
                    grad[k + 1] = -2.0 * phi * phi / (tc * (1.0 - phi * phi))
                    parts["K"].append((sigma2 * (1.0 - phi * phi), grad))
            k += 2 if t == "GM" else 1
        out: dict[str, float] = {}
        for name, items in parts.items():
            key = "N" if name == "N" else "K_model"
            total = sum(v for v, _ in items)
            conv = (lambda v: math.sqrt(v * dt) / 60.0) if name == "N" else (
                lambda v: 60.0 * math.sqrt(v / dt))
            value = conv(total) if total > 0 else 0.0
            out[key] = value
            if not items:
                out[f"{key}_ci_low"] = out[f"{key}_ci_high"] = 0.0
            elif len(items) == 1 and name in terms and value == self.value(name):
                out[f"{key}_ci_low"] = self.param(name).ci_low
                out[f"{key}_ci_high"] = self.param(name).ci_high
            else:
                grad = np.sum([v / total * gr for v, gr in items], axis=0)
                var = float(grad @ self.param_cov @ grad)
                half = z * 0.5 * math.sqrt(max(var, 0.0))
                out[f"{key}_ci_low"] = value * math.exp(-half) if half < 700 else 0.0
                out[f"{key}_ci_high"] = value * math.exp(half) if half < 700 else math.inf
        kr = self.k_resolved if self.k_resolved is not None else (0.0, 0.0, 0.0)
        out["K"], out["K_ci_low"], out["K_ci_high"] = kr
        out["K_resolved"] = 0.0 if self.k_resolved is None else 1.0
        out["K_upper_limit"] = _k_upper_limit(self.tau_s, self.wv_ci_high, dt)
        return out

    def as_dict(self) -> dict[str, object]:
        return {
            "model": self.model,
            "params": [p.as_dict() for p in self.params],
            "rate_hz": self.rate_hz,
            "n_samples": self.n_samples,
            "tau_s": self.tau_s.tolist(),
            "wv": self.wv.tolist(),
            "wv_ci_low": self.wv_ci_low.tolist(),
            "wv_ci_high": self.wv_ci_high.tolist(),
            "wv_fit": self.wv_fit.tolist(),
            "wv_components": {k: v.tolist() for k, v in self.wv_components.items()},
            "objective": self.objective,
            "wic": self.wic,
            "candidates": [[m, w] for m, w in self.candidates],
            "ci": self.ci,
            "ci_method": self.ci_method,
            "param_cov": self.param_cov.tolist(),
            "check": None if self.check is None else self.check.as_dict(),
            "approximate": self.approximate,
            "weight": self.weight,
            "notes": list(self.notes),
            "implied": self.implied(),
        }


def _k_upper_limit(tau_s: np.ndarray, wv_ci_high: np.ndarray, dt: float) -> float:
    """The largest K (deg/h/sqrt(h)) the measured wavelet variance allows: the random walk's
    WV alone, (tau^2 + 2) g2 / (12 tau) (tau in samples), reaching the upper end of the
    measured interval at some fitted scale. An upper limit whatever the model."""
    tau_n = tau_s / dt
    g2 = 12.0 * tau_n * wv_ci_high / (tau_n * tau_n + 2.0)
    return float(60.0 * math.sqrt(float(np.min(g2)) / dt))


def _narrow(lo: float, hi: float) -> bool:
    """An interval of K within the factor K_RESOLVED_RATIO (lower end above 0)."""
    return bool(lo > 0.0 and math.isfinite(hi) and hi <= K_RESOLVED_RATIO * lo)


def _long_scale_k(wv: WaveletVariance, omega: np.ndarray, terms: tuple[str, ...], dt: float,
                  ci: float) -> tuple[tuple[float, float, float, float], bool] | None:
    """K from the longest scales, with a flicker floor the candidate models lack.

    Bias instability is flicker noise, whose Haar wavelet variance is flat (B^2 ln 2 / pi,
    half the Allan variance 2 ln 2 B^2 / pi): no Gauss-Markov term follows it beyond its
    correlation time, so over the longest scales of a candidate model the floor is taken
    either by the random walk (K too high, with an interval that does not hold the truth:
    K+GM on the tactical MEMS preset, 1.4-1.5x) or by a Gauss-Markov term at its upper
    bound or a ramp (no K). Here white noise (which also holds the tails of faster terms,
    1 / tau beyond their correlation times), K, a flat floor (and the ramp, where the
    selected model has one) are fitted to the longest LONG_SCALE_LEVELS scales: a linear
    model in the variances, fitted by non-negative least squares with the weight omega^-1
    (the selection's common weight there). The covariance of the variances is the
    generalised-least-squares sandwich (A' W A)^-1 A' W (S + d^2 V) W A (A' W A)^-1 with
    S = omega and the model discrepancy d^2 V of `_robust_param_cov`, taken without the
    non-negativity constraint, so that a term the fit set to 0 still widens the interval of
    the terms it trades with (a log-scale delta method at a term's bound does not: its
    derivative vanishes and K's interval came out narrow and wrong). K's interval is
    g2 +- z sd on the increment variance (lower end at least 0).

    Returns ((K, its interval low and high, K's share of the fitted WV at the longest
    scale), whether the floor is shown: its variance's lower limit, estimate - z sd, above
    0); None with fewer than LONG_SCALE_LEVELS scales or when the fit fails."""
    n_lev = wv.nu2.size
    if n_lev < LONG_SCALE_LEVELS:
        return None
    sl = slice(n_lev - LONG_SCALE_LEVELS, n_lev)
    nu2 = wv.nu2[sl]
    tau = 2.0 ** wv.level[sl].astype(np.float64)
    om = omega[sl, sl]
    long_terms = ("N", "K", "R", "B") if "R" in terms else ("N", "K", "B")
    a = _design(long_terms, tau, ())
    li = _tri_inv(_chol(om))
    aw = np.einsum("ij,jk->ik", li, a)
    bw = np.einsum("ij,j->i", li, nu2)
    scale = np.linalg.norm(aw, axis=0)
    scale[scale == 0] = 1.0
    try:
        v, _ = scipy.optimize.nnls(aw / scale, bw)
        bread = np.linalg.pinv(aw.T @ aw)
    except (ValueError, RuntimeError, np.linalg.LinAlgError):
        return None
    v = v / scale
    gw = bread @ aw.T @ li  # (A' W A)^-1 A' W
    resid = nu2 - a @ v
    maker = np.eye(tau.size) - a @ gw
    w_diag = 1.0 / np.diag(om)
    vc = np.outer(nu2, nu2) * allan_kernel_corr(tau)
    den = float(np.einsum("i,ij,ji->", w_diag, maker, vc @ maker.T))
    excess = float(np.sum(w_diag * resid**2)) - float(
        np.einsum("i,ij,ji->", w_diag, maker, om @ maker.T))
    d2 = max(0.0, excess / den) if den > 0 else 0.0
    cov = gw @ (om + d2 * vc) @ gw.T
    z = float(scipy.stats.norm.ppf(0.5 + ci / 2.0))
    g2 = float(v[1])
    sd = math.sqrt(max(float(cov[1, 1]), 0.0))
    b_sd = math.sqrt(max(float(cov[-1, -1]), 0.0))

    def k_of(g: float) -> float:
        return 60.0 * math.sqrt(max(g, 0.0) / dt)

    total = float(a[-1] @ v)
    share = float(a[-1, 1] * g2 / total) if total > 0 else 0.0
    return (k_of(g2), k_of(g2 - z * sd), k_of(g2 + z * sd), share), \
        bool(float(v[-1]) - z * b_sd > 0.0)


def _resolve_k(res: GmwmResult, long: tuple[tuple[float, float, float, float], bool] | None
               ) -> tuple[float, float, float] | None:
    """The K to report (value, interval) where the record resolves it, else None.

    Where the long-scale fit shows a flicker floor (`_long_scale_k`), K is its random walk,
    resolved if that carries at least K_RESOLVED_SHARE of the fitted WV at the longest scale
    and its interval is within K_RESOLVED_RATIO. Where it shows none, the candidate models
    lack nothing on the long scales and K is the selected model's own K term, resolved on
    the same two conditions (its share of the model's fitted WV at the longest scale). A
    random walk held by a Gauss-Markov term at its upper bound is never resolved: its
    correlation time is only a lower limit, so its increment variance is not determined
    (its delta-method interval is too narrow)."""
    if long is None:
        return None
    (value, lo, hi, share), floor = long
    if floor:
        ok = value > 0.0 and share >= K_RESOLVED_SHARE and _narrow(lo, hi)
        return (value, lo, hi) if ok else None
    terms = parse_model(res.model)
    if "K" not in terms:
        return None
    imp = res.implied()
    k = res.param("K")
    if imp["K_model"] != k.value:  # a GM at its upper bound adds to it
        return None
    dt = 1.0 / res.rate_hz
    tau = float(res.tau_s[-1]) / dt
    g2 = (k.value / 60.0) ** 2 * dt
    k_share = (tau * tau + 2.0) * g2 / (12.0 * tau) / float(res.wv_fit[-1])
    ok = k_share >= K_RESOLVED_SHARE and _narrow(k.ci_low, k.ci_high)
    return (k.value, k.ci_low, k.ci_high) if ok else None


def _to_ieee(terms: tuple[str, ...], theta: np.ndarray, dt: float
             ) -> list[tuple[str, float, str, float]]:
    """(name, value, unit, d log value / d theta_k factor) per parameter; every IEEE value is
    sqrt(variance) times a constant, or T_c times dt, so log value = c + f theta_k."""
    out = []
    p = np.exp(theta)
    k = 0
    g = 0
    for t in terms:
        if t == "Q":
            out.append(("Q", math.sqrt(p[k]) * dt, "arcsec", 0.5))
        elif t == "N":
            out.append(("N", math.sqrt(p[k] * dt) / 60.0, "deg/sqrt(h)", 0.5))
        elif t == "K":
            out.append(("K", 60.0 * math.sqrt(p[k] / dt), "deg/h/sqrt(h)", 0.5))
        elif t == "R":
            out.append(("R", 3600.0 * math.sqrt(p[k]) / dt, "deg/h^2", 0.5))
        else:
            g += 1
            out.append((f"GM{g}_sigma", math.sqrt(p[k]), "deg/h", 0.5))
            out.append((f"GM{g}_tau", p[k + 1] * dt, "s", 1.0))
            k += 1
        k += 1
    return out


#: Terms reported as densities too (Kalibr-style SI): factor from the display unit, SI unit.
_DENSITY = {n: (TERM_UNITS["gyro"][n].from_ieee, TERM_UNITS["gyro"][n].si) for n in ("N", "K")}


def _make_params(terms: tuple[str, ...], theta: np.ndarray, cov: np.ndarray, dt: float,
                 ci: float, boot: np.ndarray | None, inflate: float = 1.0
                 ) -> tuple[GmwmParam, ...]:
    """IEEE-unit parameters with intervals; cov is already inflated, bootstrap percentile
    intervals are widened about the estimate by sqrt(inflate) on the log scale."""
    z = float(scipy.stats.norm.ppf(0.5 + ci / 2.0))
    widen = math.sqrt(inflate)
    vals = _to_ieee(terms, theta, dt)
    out = []
    for k, (name, value, unit, fac) in enumerate(vals):
        se_log = fac * math.sqrt(max(float(cov[k, k]), 0.0))
        if boot is not None:
            bvals = np.array([_to_ieee(terms, b, dt)[k][1] for b in boot])
            lo, hi = (float(v) for v in np.quantile(bvals, [(1 - ci) / 2, (1 + ci) / 2]))
            if widen > 1.0 and lo > 0.0:
                lo, hi = value * (lo / value) ** widen, value * (hi / value) ** widen
            se = float(np.std(bvals, ddof=1)) * widen
        else:
            # a term at its variance bound has a vanishing derivative: an unbounded interval
            half = z * se_log
            lo, hi = ((value * math.exp(-half), value * math.exp(half)) if half < 700.0
                      else (0.0, math.inf))
            se = value * se_log
        dens = _DENSITY.get(name)
        out.append(GmwmParam(
            name, value, unit, se, lo, hi,
            None if dens is None else value * dens[0], None if dens is None else dens[1],
            None if dens is None else lo * dens[0], None if dens is None else hi * dens[0]))
    return tuple(out)


def _param_cov(terms: tuple[str, ...], theta: np.ndarray, tau: np.ndarray,
               omega: np.ndarray) -> np.ndarray:
    d = _jacobian(terms, theta, tau)
    lc = _chol(omega)
    a = np.einsum("ij,jk->ik", _tri_inv(lc), d)
    return np.linalg.pinv(a.T @ a)


@functools.lru_cache(maxsize=1)
def _allan_kernel() -> tuple[np.ndarray, np.ndarray]:
    """Power of the Allan filter per unit log-frequency for a flicker spectrum (module
    docstring): g(u) = sin^4(x) / x^2, x = pi f tau = pi e^u, on a grid of u."""
    u = np.linspace(-10.0, 4.0, 14001)
    x = np.pi * np.exp(u)
    return u, np.sin(x) ** 4 / x**2


def allan_kernel_corr(tau_s: np.ndarray) -> np.ndarray:
    """Correlation matrix C_ij = int g(u) g(u + ln(tau_j / tau_i)) du / int g^2 du of the
    Allan filters at averaging times tau_i, tau_j over log-frequency (module docstring):
    the overlap of the frequency bands two taus see. About 0.6 for adjacent octaves.

    Examples
    --------
    >>> c = allan_kernel_corr(np.array([1.0, 2.0, 4.0, 1024.0]))
    >>> bool(0.5 < c[0, 1] < 0.8), bool(c[0, 2] < c[0, 1]), bool(c[0, 3] < 1e-3)
    (True, True, True)
    """
    u, g = _allan_kernel()
    lt = np.log(np.asarray(tau_s, dtype=np.float64))
    d = np.abs(lt[:, None] - lt[None, :])
    norm = float(np.einsum("i,i->", g, g))
    out = np.empty_like(d)
    for delta in np.unique(np.round(d, 9)):
        shifted = np.interp(u + delta, u, g, left=0.0, right=0.0)
        out[np.abs(d - delta) < 1e-8] = float(np.einsum("i,i->", g, shifted)) / norm
    return out


def _raise_diag(cov: np.ndarray, var: np.ndarray) -> np.ndarray:
    """cov with its variances raised to var where var is larger, correlations kept."""
    d = np.sqrt(np.diag(cov))
    up = np.sqrt(np.maximum(np.diag(cov), var)) / np.where(d > 0, d, 1.0)
    return cov * np.outer(up, up)


def _robust_param_cov(terms: tuple[str, ...], theta: np.ndarray, tau: np.ndarray,
                      omega_w: np.ndarray, omega_data: np.ndarray, nu2: np.ndarray
                      ) -> tuple[np.ndarray, float]:
    """Misspecification-robust covariance of the log parameters (module docstring): the GMM
    sandwich (D' W D)^-1 D' W S W D (D' W D)^-1 with W = omega_w^-1 the fit's weight and S
    the covariance of the measured wavelet variances taken from the data
    (omega_data, the sieve) plus a model discrepancy d^2 diag(nu) C diag(nu) (C: the
    overlap of the Haar filters over log-frequency, `allan_kernel_corr`), d^2 by moments
    from the residuals; returns the covariance and d."""
    d = _jacobian(terms, theta, tau)
    li = _tri_inv(_chol(omega_w))
    dw = li @ d
    bread = np.linalg.pinv(dw.T @ dw)
    gw = bread @ dw.T @ li  # (D' W D)^-1 D' W
    resid = nu2 - theoretical_wv(terms, np.exp(theta), tau)
    maker = np.eye(tau.size) - d @ gw
    a = 1.0 / np.diag(omega_data)
    vc = np.outer(nu2, nu2) * allan_kernel_corr(tau)
    den = float(np.einsum("i,ij,ji->", a, maker, vc @ maker.T))
    excess = float(np.sum(a * resid**2)) - float(
        np.einsum("i,ij,ji->", a, maker, omega_data @ maker.T))
    d2 = max(0.0, excess / den) if den > 0 else 0.0
    return gw @ (omega_data + d2 * vc) @ gw.T, math.sqrt(d2)


def _wic(fit: _Fit) -> float:
    """WIC with the candidate's own efficient weight (module docstring): J + 2 tr(P),
    tr(P) = number of parameters (P is the projection onto the model's tangent space; its
    trace is the nominal count even where a term is at the edge of identifiability)."""
    return fit.objective + 2.0 * _n_params(fit.terms)


def _drop_one(terms: tuple[str, ...]) -> list[tuple[str, ...]]:
    """The sub-models of terms without one of its terms (one GM of several), non-empty."""
    out = []
    for t in dict.fromkeys(terms):
        sub = list(terms)
        sub.remove(t)
        if sub:
            out.append(tuple(sub))
    return out


def select_nested(wics: dict[tuple[str, ...], float], margin: float | None = None
                  ) -> tuple[str, ...]:
    """Model selection by WIC with parsimony along nested chains (module docstring).

    Start at the candidate of smallest WIC; while one of its one-term-smaller sub-models
    (scored in wics) has a WIC within margin (default WIC_MARGIN) of the current model's,
    move to the one of those with the smallest WIC. With the margin 2 a term of dp
    parameters stays only if it lowers the J statistic by more than 2 dp + 2 (4 for one
    parameter, 6 for a Gauss-Markov term's two): the nested GMM distance test at about 5 %
    (P(chi2_1 > 4) = 0.046, P(chi2_2 > 6) = 0.050). Candidates that are not nested in the
    current model are compared by WIC alone.

    Examples
    --------
    >>> select_nested({("N", "K"): 10.0, ("N",): 11.5, ("K",): 30.0, ("Q", "K"): 10.5})
    ('N',)
    """
    m = float(WIC_MARGIN if margin is None else margin)
    cur = min(wics, key=lambda c: (wics[c], _n_params(c)))
    while True:
        near = [s for s in _drop_one(cur) if s in wics and wics[s] <= wics[cur] + m]
        if not near:
            return cur
        cur = min(near, key=lambda c: (wics[c], _n_params(c)))


class _ModelStream:
    """A parametric-bootstrap record of the model (per-sample parameters) in consecutive
    pieces, each term's generator state carried from one piece to the next (the random walk's
    running sum, the Gauss-Markov AR(1) filter state, the quantization noise's last draw), so
    that the record never needs to be held whole.

    The random numbers are those `_simulate_model` draws from `rng` for the whole record at
    once, term after term (Q: n + 1 normals, N and K: n, GM: n, then one for its start; R:
    none), and the pieces are bit-identical to that record however it is cut: cut into
    several pieces, the start of each term's draws is found by one pass over the earlier
    terms' draws (their states recorded, the numbers discarded), after which `rng` stands
    where the whole-record simulation leaves it.
    """

    def __init__(self, terms: tuple[str, ...], p: np.ndarray, n: int,
                 rng: np.random.Generator, piece: int) -> None:
        self.terms, self.p, self.n, self.piece = terms, p, int(n), max(int(piece), 1)
        self.pos = 0
        self._carry: list[Any] = [None] * len(terms)
        self._zi: list[float | None] = [None] * len(terms)
        self._gens: list[np.random.Generator | None] = []
        if self.piece >= self.n:  # one piece: the draws come from rng in order
            self._gens = [None if t == "R" else rng for t in terms]
            return
        for t in terms:
            if t == "R":
                self._gens.append(None)
                continue
            bit = type(rng.bit_generator)()
            bit.state = rng.bit_generator.state
            self._gens.append(np.random.Generator(bit))
            left = self.n + (1 if t == "Q" else 0)
            while left:
                rng.standard_normal(min(left, self.piece))
                left -= min(left, self.piece)
            if t == "GM":
                self._zi[len(self._gens) - 1] = float(rng.standard_normal())

    def next_piece(self) -> np.ndarray:
        """The next samples (at most `piece`; an empty array at the end)."""
        import scipy.signal

        a = self.pos
        b = min(self.n, a + self.piece)
        m = b - a
        x = np.zeros(m)
        if m == 0:
            return x
        k = 0
        for i, t in enumerate(self.terms):
            g = self._gens[i]
            carry = self._carry[i]
            if t == "Q":
                assert g is not None
                e = math.sqrt(self.p[k]) * g.standard_normal(m + (1 if carry is None else 0))
                if carry is not None:
                    e = np.concatenate(([carry], e))
                x += np.diff(e)
                self._carry[i] = float(e[-1])
            elif t == "N":
                assert g is not None
                x += math.sqrt(self.p[k]) * g.standard_normal(m)
            elif t == "K":
                assert g is not None
                steps = math.sqrt(self.p[k]) * g.standard_normal(m)
                walk = np.cumsum(steps if carry is None else np.concatenate(([carry], steps)))
                x += walk if carry is None else walk[1:]
                self._carry[i] = float(walk[-1])
            elif t == "R":
                x += math.sqrt(self.p[k]) * np.arange(a, b)
            else:
                assert g is not None
                sigma2, tc = self.p[k], self.p[k + 1]
                phi = math.exp(-1.0 / tc)
                u = math.sqrt(sigma2 * (1 - phi * phi)) * g.standard_normal(m)
                if carry is None:
                    zi = self._zi[i]
                    z = zi if zi is not None else float(g.standard_normal())
                    carry = np.array([phi * math.sqrt(sigma2) * z])
                y, self._carry[i] = scipy.signal.lfilter([1.0], [1.0, -phi], u, zi=carry)
                x += y
                k += 1
            k += 1
        self.pos = b
        return x


def _simulate_model(terms: tuple[str, ...], p: np.ndarray, n: int, rng: np.random.Generator
                    ) -> np.ndarray:
    """A record of the model (per-sample parameters) for the parametric bootstrap (one piece
    of `_ModelStream`)."""
    return _ModelStream(terms, p, n, rng, n).next_piece()


def _spool_replicate(path: Path, stream: _ModelStream) -> None:
    """Write the stream's whole record to `path` as a float64 .npy file, piece by piece with
    file writes (never through a mapping, whose written pages would stay resident)."""
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_1_0(
            fh, {"descr": np.lib.format.dtype_to_descr(np.dtype(np.float64)),
                 "fortran_order": False, "shape": (stream.n,)})
        while stream.pos < stream.n:
            stream.next_piece().tofile(fh)


def _bootstrap_wv_file(terms: tuple[str, ...], p: np.ndarray, n: int, rng: np.random.Generator,
                       rate_hz: float, max_level: int
                       ) -> Generator[WaveletVariance, None, None]:
    """Wavelet variances of successive bootstrap records of a file-backed record's length,
    without holding one: each record is simulated in pieces of _WV_PIECE samples into one
    temporary .npy file (disk: 8 bytes per sample), and its wavelet variance is streamed from
    that file as the record's own (`_haar_wv_file`). The records are those of
    `_simulate_model` with the same generator."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="gyrodrift-bootstrap.") as d:
        path = Path(d) / "replicate.npy"
        while True:
            _spool_replicate(path, _ModelStream(terms, p, n, rng, _WV_PIECE))
            mm = np.load(path, mmap_mode="r")
            wb = _haar_wv_file(mm, rate_hz, max_level)
            if wb is None:  # a replicate of extreme magnitude: in memory, as the record
                wb = haar_wv(np.array(mm), rate_hz, max_level=max_level)
            del mm
            yield wb


def _gm_offsets(terms: tuple[str, ...]) -> list[tuple[int, int]]:
    """(index of the log variance in theta, GM number from 1) of each Gauss-Markov term."""
    out: list[tuple[int, int]] = []
    k = 0
    for t in terms:
        if t == "GM":
            out.append((k, len(out) + 1))
        k += 2 if t == "GM" else 1
    return out


def _pinned_gms(terms: tuple[str, ...], theta: np.ndarray, tau: np.ndarray
                ) -> dict[int, str]:
    """{index of a GM's log variance in theta: "low" or "high"} for every Gauss-Markov term
    whose correlation time stopped at a bound of `_tc_bounds` (within TC_BOUND_LOG_TOL)."""
    tc_lo, tc_hi = _tc_bounds(tau)
    out: dict[int, str] = {}
    k = 0
    for t in terms:
        if t == "GM":
            if theta[k + 1] <= math.log(tc_lo) + TC_BOUND_LOG_TOL:
                out[k] = "low"
            elif theta[k + 1] >= math.log(tc_hi) - TC_BOUND_LOG_TOL:
                out[k] = "high"
            k += 2
        else:
            k += 1
    return out


def _convert_pinned(terms: tuple[str, ...], theta: np.ndarray, tau: np.ndarray, dt: float,
                    side: str) -> tuple[tuple[str, ...], np.ndarray, list[str]]:
    """Turn each Gauss-Markov term at a correlation-time bound into what it stands for over
    the fitted scales; returns the new model, its start (log parameters) and one note per
    conversion.

    AR(1) x_t = phi x_{t-1} + u_t, stationary variance sigma^2, phi = exp(-1 / T_c) (T_c in
    samples), autocovariance sigma^2 phi^|k|:

    - T_c at the lower bound (the fit wanted it shorter still): at every scale tau >> T_c
      the Haar WV of the AR(1) tends to S(0) / tau, with S(0) = sum_k sigma^2 phi^|k| =
      sigma^2 (1 + phi) / (1 - phi) its spectral density at zero frequency (per sample).
      White noise of that per-sample variance has the same WV there (nu^2 = s2 / tau),
      so s2 = sigma^2 (1 + phi) / (1 - phi) (-> 2 sigma^2 T_c for T_c >> 1: the continuous
      PSD equivalence N^2 = 2 sigma^2 T_c), N = sqrt(s2 dt) / 60.
    - T_c at the upper bound (the fit wanted it longer still): over scales tau << T_c the
      increments x_t - x_{t-1} = u_t - (1 - phi) x_{t-1} are u_t up to a mean reversion of
      order tau / T_c, i.e. a random walk of increment variance g2 = var u =
      sigma^2 (1 - phi^2), K = 60 sqrt(g2 / dt).

    The converted variance is added to the model's white noise (random walk) if it has one.
    Only the terms at the bound `side` ("low" or "high") are converted.
    """
    pins = {k: v for k, v in _pinned_gms(terms, theta, tau).items() if v == side}
    p = np.exp(theta)
    tc_lo, tc_hi = _tc_bounds(tau)
    single: dict[str, float] = {}
    gms: list[tuple[float, float]] = []
    notes: list[str] = []
    k = 0
    g = 0
    for t in terms:
        if t != "GM":
            single[t] = single.get(t, 0.0) + float(p[k])
            k += 1
            continue
        g += 1
        sigma2, tc = float(p[k]), float(p[k + 1])
        phi = math.exp(-1.0 / tc)
        head = (f"GM{g} (sigma {math.sqrt(sigma2):.4g}, T_c {tc * dt:.4g} s) stopped at the "
                f"{'lower' if pins.get(k) == 'low' else 'upper'} bound of its correlation "
                f"time ({(tc_lo if pins.get(k) == 'low' else tc_hi) * dt:.4g} s)")
        if pins.get(k) == "low":
            s2 = sigma2 * (1.0 + phi) / (1.0 - phi)
            single["N"] = single.get("N", 0.0) + s2
            notes.append(f"{head}: it is white noise over the fitted scales; converted to white "
                         f"noise of the same spectral density at zero frequency (N = "
                         f"{math.sqrt(s2 * dt) / 60.0:.4g} deg/sqrt(h)) and refitted")
        elif pins.get(k) == "high":
            g2 = sigma2 * (1.0 - phi * phi)
            single["K"] = single.get("K", 0.0) + g2
            notes.append(f"{head}: it is a random walk over the fitted scales; converted to a "
                         f"random walk of the same increment variance (K = "
                         f"{60.0 * math.sqrt(g2 / dt):.4g} deg/h/sqrt(h)) and refitted")
        else:
            gms.append((sigma2, tc))
        k += 2
    new_terms = tuple(t for t in TERMS[:-1] if t in single) + ("GM",) * len(gms)
    theta_new = [math.log(single[t]) for t in TERMS[:-1] if t in single]
    for sigma2, tc in sorted(gms, key=lambda v: v[1]):
        theta_new += [math.log(sigma2), math.log(tc)]
    return new_terms, np.array(theta_new), notes


def _resolve_pinned(fit: _Fit, omega: np.ndarray, tau: np.ndarray, dt: float,
                    refit: Callable[[tuple[str, ...], np.ndarray], tuple[_Fit, np.ndarray]]
                    ) -> tuple[_Fit, np.ndarray, list[str]]:
    """Convert Gauss-Markov terms at a correlation-time bound (`_convert_pinned`) and refit.

    At the lower bound the conversion to white noise is always made (the fit wanted a
    shorter correlation time than half a sample, or an eighth of the shortest scale: white
    at every fitted scale). The upper bound is an eighth of the longest scale, so a term
    there is a random walk over the shorter scales but levels off at the longest ones, like
    bias instability: it is converted to a random walk only if the converted model's J is
    not worse by more than the nested-selection margin (WIC_MARGIN plus twice the
    parameters dropped, one per term: what select_nested would accept); otherwise it is
    kept, with a note that its correlation time is only a lower limit (its interval's upper
    end is then unbounded, `_make_params`)."""
    notes: list[str] = []
    tried_high = False
    while True:
        pins = _pinned_gms(fit.terms, fit.theta, tau)
        if "low" in pins.values():
            terms, start, conv = _convert_pinned(fit.terms, fit.theta, tau, dt, "low")
            notes += conv
            fit, omega = refit(terms, start)
            continue
        n_high = sum(1 for v in pins.values() if v == "high")
        if n_high and not tried_high:
            tried_high = True
            terms, start, conv = _convert_pinned(fit.terms, fit.theta, tau, dt, "high")
            f2, o2 = refit(terms, start)
            if f2.objective <= fit.objective + WIC_MARGIN + 2.0 * n_high:
                notes += conv
                fit, omega = f2, o2
                continue
            notes.append(
                f"{n_high} Gauss-Markov term(s) at the upper bound of the correlation time "
                f"({_tc_bounds(tau)[1] * dt:.4g} s): bias-instability-like over the record, "
                f"T_c is only a lower limit (a random walk in its place fits worse: J "
                f"{f2.objective:.4g} against {fit.objective:.4g})")
        return fit, omega, notes


def _check(wv: WaveletVariance, lo: np.ndarray, hi: np.ndarray, fit: _Fit, tau: np.ndarray
           ) -> FitCheck:
    """The fitted WV against the measured one at every scale (statistic J / dof)."""
    dof = max(wv.nu2.size - _n_params(fit.terms), 1)
    return check_fit(wv.tau_s, wv.nu2, lo, hi,
                     theoretical_wv(fit.terms, np.exp(fit.theta), tau),
                     np.ones(wv.nu2.size, dtype=bool), statistic=fit.objective / dof,
                     dof=dof, what="wavelet variance", x_name="tau", x_unit="s")


@dataclass
class _Selection:
    """Every candidate fitted with one common weight (identify_gmwm, model="auto")."""
    omega: np.ndarray
    fits: dict[tuple[str, ...], _Fit]
    wics: dict[tuple[str, ...], float]
    holding: dict[tuple[str, ...], float]
    fit_notes: dict[tuple[str, ...], list[str]]
    reduced: list[str]
    terms: tuple[str, ...]


def _select_common(top: tuple[str, ...], wv: WaveletVariance, tau: np.ndarray,
                   lo: np.ndarray, hi: np.ndarray, dt: float, omega: np.ndarray
                   ) -> _Selection:
    """Fit every sub-model of top with the weight omega^-1 (the same for all), convert
    Gauss-Markov terms at a correlation-time bound, check each fit at every scale, and
    select by WIC (select_nested) among the candidates whose check holds (if none does,
    among those that leave the measured WV at the fewest scales)."""
    chol_c = _chol(omega)

    def refit(t: tuple[str, ...], start: np.ndarray) -> tuple[_Fit, np.ndarray]:
        return _fit_model(t, wv.nu2, tau, chol_c, start=start), omega

    fits: dict[tuple[str, ...], _Fit] = {}
    fit_notes: dict[tuple[str, ...], list[str]] = {}
    reduced: list[str] = []
    for cand in _sub_models(top):
        # the drift alone is deterministic: not a noise model
        if _n_params(cand) >= wv.nu2.size or cand == ("R",):
            continue
        f0 = _fit_model(cand, wv.nu2, tau, chol_c)
        f1, _, conv = _resolve_pinned(f0, omega, tau, dt, refit)
        if f1.terms != cand:
            reduced.append(f"{_model_str(cand)} -> {_model_str(f1.terms)}")
        if f1.terms not in fits or f1.objective < fits[f1.terms].objective:
            fits[f1.terms] = f1
            # the notes of a conversion, or of a GM kept at its upper bound
            fit_notes[f1.terms] = conv
    wics = {c: _wic(f) for c, f in fits.items()}
    failed = {c: _check(wv, lo, hi, fits[c], tau).n_failed for c in fits}
    holding = {c: w for c, w in wics.items() if failed[c] == 0}
    # none holds: the candidates that leave the measured curve at the fewest scales
    fewest = min(failed.values())
    pool = holding or {c: w for c, w in wics.items() if failed[c] == fewest}
    return _Selection(omega, fits, wics, holding, fit_notes, reduced, select_nested(pool))


def _widen_by_model_set(params: tuple[GmwmParam, ...], near: list[tuple[str, ...]],
                        sel: _Selection, tau: np.ndarray, dt: float, ci: float,
                        omega_data: np.ndarray, nu2: np.ndarray
                        ) -> tuple[tuple[GmwmParam, ...], list[str]]:
    """Widen the intervals of N and K (the values a user carries into a filter) to cover
    those of every eligible candidate within MODEL_SET_DELTA of the selected one's WIC that
    has the term (model uncertainty: the data do not tell those models apart, and under
    misspecification their estimates differ by more than one model's interval; cf. the
    model-averaged intervals of Buckland, Burnham & Augustin, Biometrics 53 (1997) 603)."""
    lo: dict[str, float] = {}
    hi: dict[str, float] = {}
    for c in near:
        f = sel.fits[c]
        cov, _ = _robust_param_cov(c, f.theta, tau, sel.omega, omega_data, nu2)
        for q in _make_params(c, f.theta, cov, dt, ci, None):
            if q.name in ("N", "K"):
                lo[q.name] = min(lo.get(q.name, math.inf), q.ci_low)
                hi[q.name] = max(hi.get(q.name, -math.inf), q.ci_high)
    out = []
    widened = []
    for q in params:
        if q.name in lo and (lo[q.name] < q.ci_low or hi[q.name] > q.ci_high):
            a, b = min(q.ci_low, lo[q.name]), max(q.ci_high, hi[q.name])
            dens = _DENSITY[q.name][0]
            q = GmwmParam(q.name, q.value, q.unit, q.se, a, b, q.density, q.density_unit,
                          a * dens, b * dens)
            widened.append(q.name)
        out.append(q)
    return tuple(out), widened


def identify_gmwm(x: np.ndarray, rate_hz: float, model: str = "auto", *,
                  max_model: str = DEFAULT_MAX_MODEL, ci: float = 0.95, bootstrap: int = 0,
                  seed: int = 0, max_level: int | None = None,
                  tau_range: tuple[float, float] | None = None,
                  convert_bounds: bool = True) -> GmwmResult:
    """GMWM fit of a composite noise model to a rate record (module docstring).

    Parameters
    ----------
    x
        1-D rate record, deg/h (the units of every printed value follow from this). A
        float64 numpy.memmap longer than FILE_BACKED_MIN samples is read from its file in
        chunks (its wavelet variance from the streamed Allan variance): the memory does not
        grow with the record.
    rate_hz
        sample rate, Hz.
    model
        "auto" (WIC selection among the sub-models of max_model) or terms joined by
        "+": Q, N, K, R, GM (GM up to 3 times), e.g. "Q+N+GM+K".
    max_model
        the largest model "auto" considers.
    ci
        two-sided probability of the parameter intervals.
    bootstrap
        0 for asymptotic intervals; B > 0 for B parametric-bootstrap refits.
    seed
        seed of the bootstrap.
    max_level
        highest wavelet level J (default floor(log2 N) - 1).
    tau_range
        (min, max) scale tau_j = 2^j dt in s of the levels fitted (default
        all); e.g. to leave out a vibration peak at short scales. The covariance is
        that of the levels kept.
    convert_bounds
        a named model's Gauss-Markov term whose correlation time stops at
        a bound is turned into the white noise or random walk it is and the model
        refitted (`_resolve_pinned`; the notes say so). False keeps the named model
        (simulation studies of its estimator); a correlation time at a bound then
        gets a one-sided interval. Selection (model="auto") always converts.

    Raises
    ------
    GyrodriftValueError
        bad record (not 1-D, NaN/Inf, too short), bad model, bad ci.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(1).standard_normal(4096) * 30.0  # white, 30 deg/h per sample
    >>> res = identify_gmwm(x, 100.0, model="N")
    >>> p = res.param("N")
    >>> p.unit, p.ci_low < 30.0 * 0.1 / 60.0 < p.ci_high   # N = sigma sqrt(dt) / 60
    ('deg/sqrt(h)', True)
    """
    wv_file = None
    if (is_file_backed(x) and np.asarray(x).dtype == np.float64
            and len(x) > FILE_BACKED_MIN):
        # A long memory-mapped record is read from its file in chunks (bounded memory).
        _check_record(np.nan_to_num(x[:16]), rate_hz)  # rate, shape, dtype; NaN below
        wv_file = _haar_wv_file(x, rate_hz, max_level)
    if wv_file is not None:
        n_samples = len(x)
    else:
        arr = _check_record(x, rate_hz)
        n_samples = int(arr.size)
    if not 0.0 < ci < 1.0:
        raise GyrodriftValueError(f"ci must be in (0, 1), got {ci!r}")
    if not isinstance(bootstrap, (int, np.integer)) or bootstrap < 0:
        raise GyrodriftValueError(f"bootstrap must be an integer >= 0, got {bootstrap!r}")
    scale = 1.0 if wv_file is not None else normalising_scale(arr)
    if scale != 1.0:  # an extreme-magnitude record: fitted scaled, results scaled back
        return _scaled_back(identify_gmwm(arr / scale, rate_hz, model, max_model=max_model,
                                          ci=ci, bootstrap=bootstrap, seed=seed,
                                          max_level=max_level, tau_range=tau_range), scale)
    dt = 1.0 / float(rate_hz)
    wv = wv_file if wv_file is not None else haar_wv(arr, rate_hz, max_level=max_level)
    if tau_range is not None:
        wv = _subset(wv, tau_range)
    if np.any(wv.nu2 <= 0):
        raise GyrodriftValueError("x: the record is constant at some scale (zero wavelet variance)")
    tau = 2.0 ** wv.level.astype(np.float64)
    lo, hi = wv.interval(ci)
    candidates: tuple[tuple[str, float], ...] = ()
    wic = None
    notes: list[str] = []
    near: list[tuple[str, ...]] = []
    if model == "auto":
        top = parse_model(max_model)
        if wv.nu2.size < _n_params(top) + 1:
            raise GyrodriftValueError(f"{wv.nu2.size} scales cannot identify {max_model}")
        weight = "common"
        omega_np = wv_covariance_nonparametric(wv)
        sel = _select_common(top, wv, tau, lo, hi, dt, omega_np)
        if not sel.holding:
            # No candidate follows the measured WV within its sampling precision and the
            # check's tolerance: the shortest scales, whose precision is highest, then
            # dictate the fit of a model that cannot follow their shape (a sensor's
            # anti-alias filter, quantization, vibration) and the misfit is pushed to the
            # other scales. A model-error allowance of MODEL_ERROR_REL nu_hat_j per scale,
            # independent between scales, is added to the common covariance (the
            # discrepancy term of model calibration, Kennedy & O'Hagan 2001): a misfit
            # of the check's tolerance is then a 2-sigma event at every scale.
            omega_me = omega_np + np.diag((MODEL_ERROR_REL * wv.nu2) ** 2)
            sel_me = _select_common(top, wv, tau, lo, hi, dt, omega_me)
            notes.append(
                f"no candidate model follows the measured wavelet variance within its "
                f"sampling precision; refitted with a model-error allowance of "
                f"{100 * MODEL_ERROR_REL:g} % per scale in the weight")
            sel = sel_me
        terms, fit, omega = sel.terms, sel.fits[sel.terms], sel.omega
        wics = sel.wics
        candidates = tuple(sorted(((_model_str(c), float(w)) for c, w in wics.items()),
                                  key=lambda cw: cw[1]))
        wic = float(wics[terms])
        near = [c for c in sel.holding if c != terms
                and sel.holding[c] <= wic + MODEL_SET_DELTA]
        notes += sel.fit_notes[terms]
        if sel.reduced:
            notes.append(f"{len(sel.reduced)} candidates with a Gauss-Markov term at a "
                         "correlation-time bound were scored as the model they reduce to ("
                         + ", ".join(sel.reduced[:3]) + (", ..." if len(sel.reduced) > 3
                                                          else "") + ")")
        if not sel.holding:
            notes.append("no candidate model describes the measured wavelet variance at every "
                         "scale: the selected one leaves it at the fewest scales (then the "
                         "smallest WIC) and is approximate")
    else:
        terms = parse_model(model)
        if _n_params(terms) >= wv.nu2.size:
            raise GyrodriftValueError(f"{wv.nu2.size} scales cannot identify {_model_str(terms)} "
                             f"({_n_params(terms)} parameters): record too short")
        weight = "efficient"
        fit, omega = _weighted_lsq(terms, wv, tau)
        if convert_bounds:
            fit, omega, conv = _resolve_pinned(
                fit, omega, tau, dt, lambda t, _start: _weighted_lsq(t, wv, tau))
            notes += conv
        terms = fit.terms
    check = _check(wv, lo, hi, fit, tau)
    dof = check.dof
    p_value = float(scipy.stats.chi2.sf(fit.objective, dof))
    approximate = p_value < 1.0 - MISFIT_P or not check.holds
    inflate = max(1.0, fit.objective / dof) if approximate else 1.0
    if model == "auto":
        omega_data = omega_np
    else:
        # the sieve's covariance, its variances raised to the named model's where that is
        # larger: fitted to the measured WV, the sieve understates the longest scales'
        # variance when they happen to be low, which the discrepancy estimate would take
        # for misfit
        omega_data = _raise_diag(wv_covariance_nonparametric(wv), np.diag(omega))
    cov, discrepancy = _robust_param_cov(terms, fit.theta, tau, omega, omega_data, wv.nu2)
    if approximate:
        notes.append(
            f"the model is approximate: J = {fit.objective:.4g} on {dof} degrees of freedom "
            f"(p = {p_value:.2g})"
            + ("" if check.holds else f", {check.n_failed} of {wv.nu2.size} scales outside "
               "the measured interval and tolerance")
            + f"; the intervals hold a model discrepancy of {100 * discrepancy:.3g} % of the "
              "wavelet variance per scale")
    boot = None
    if bootstrap:
        rng = np.random.default_rng(seed)
        p_hat = np.exp(fit.theta)
        chol = _chol(omega)
        boots = []
        # a file-backed record's replicates are simulated and analysed in pieces, as the
        # record itself (the same random numbers as in memory)
        top_level = int(wv.level[-1])
        replicates: Generator[WaveletVariance, None, None] = (
            _bootstrap_wv_file(terms, p_hat, n_samples, rng, rate_hz, top_level)
            if wv_file is not None else
            (haar_wv(_simulate_model(terms, p_hat, n_samples, rng), rate_hz, max_level=top_level)
             for _ in itertools.repeat(None)))
        with contextlib.closing(replicates):  # removes the temporary file now
            for wb in itertools.islice(replicates, int(bootstrap)):
                if tau_range is not None:
                    wb = _subset(wb, tau_range)
                boots.append(_fit_model(terms, wb.nu2, tau, chol, start=fit.theta).theta)
        boot = np.array(boots)
    params = _make_params(terms, fit.theta, cov, dt, ci, boot, inflate)
    if model == "auto" and near:
        params, widened = _widen_by_model_set(params, near, sel, tau, dt, ci, omega_data,
                                              wv.nu2)
        if widened:
            notes.append(
                f"the interval of {' and '.join(widened)} covers the intervals of the "
                f"models within {MODEL_SET_DELTA:g} of the selected one's WIC (model "
                f"uncertainty): {', '.join(_model_str(c) for c in near)}")
    pins = _pinned_gms(terms, fit.theta, tau)
    if pins:
        # a correlation time at its upper bound is only a lower limit (no finite upper
        # end), one at its lower bound only an upper limit (lower end 0)
        gm_of = dict(_gm_offsets(terms))
        side = {f"GM{gm_of[k]}_tau": v for k, v in pins.items()}
        params = tuple(
            p if p.name not in side else
            GmwmParam(p.name, p.value, p.unit, math.inf, p.ci_low, math.inf)
            if side[p.name] == "high" else
            GmwmParam(p.name, p.value, p.unit, math.inf, 0.0, p.ci_high)
            for p in params)
    p_nat = np.exp(fit.theta)
    comps: dict[str, np.ndarray] = {}
    k = 0
    g = 0
    for t in terms:
        width = 2 if t == "GM" else 1
        name = t
        if t == "GM":
            g += 1
            name = f"GM{g}"
        comps[name] = _component_wv(t, p_nat[k:k + width], tau)
        k += width
    res = GmwmResult(
        model=_model_str(terms), params=params, rate_hz=float(rate_hz), n_samples=n_samples,
        tau_s=wv.tau_s, wv=wv.nu2, wv_ci_low=lo, wv_ci_high=hi,
        wv_fit=theoretical_wv(terms, p_nat, tau), wv_components=comps,
        objective=fit.objective, wic=wic, candidates=candidates, ci=float(ci),
        ci_method="bootstrap" if bootstrap else "asymptotic", param_cov=cov, check=check,
        approximate=approximate, weight=weight, notes=tuple(notes))
    long = _long_scale_k(wv, omega_data, terms, dt, ci)
    res = replace(res, k_long=None if long is None else long[0])
    res = replace(res, k_resolved=_resolve_k(res, long))
    imp = res.implied()
    if imp["K_resolved"] and long is not None and long[1]:
        notes.append(
            f"K = {imp['K']:.4g} [{imp['K_ci_low']:.4g}, {imp['K_ci_high']:.4g}] "
            f"deg/h/sqrt(h) from the longest {LONG_SCALE_LEVELS} scales with a flicker floor "
            f"(the model's own random walk: {imp['K_model']:.4g})")
    elif not imp["K_resolved"] and imp["K_model"] > 0.0:
        kl = res.k_long
        notes.append(
            f"K is not resolved by the record (the random walk's interval is not within a "
            f"factor {K_RESOLVED_RATIO:g}, or it carries less than "
            f"{100 * K_RESOLVED_SHARE:g} % of the longest scale"
            + ("" if kl is None else f"; the long-scale fit with a flicker floor gives "
               f"{kl[0]:.4g} [{kl[1]:.4g}, {kl[2]:.4g}], {100 * kl[3]:.0f} %")
            + f"); report the upper limit K <= {imp['K_upper_limit']:.4g} deg/h/sqrt(h), "
              f"not the model's {imp['K_model']:.4g}")
    return replace(res, notes=tuple(notes))



def _scaled_back(res: GmwmResult, c: float) -> GmwmResult:
    """The GMWM result of ``x`` from that of ``x / c`` (c a power of two, identify_gmwm of a
    record of extreme magnitude, which overflowed or underflowed before): parameters in the
    record's units (Q, N, K, R, GM sigma, their densities and intervals) by c, correlation
    times (unit "s") unchanged, wavelet variances by c^2 (inf where that exceeds float64);
    the covariance of the log parameters, the J statistic and WIC do not depend on c."""
    def param(p: GmwmParam) -> GmwmParam:
        if p.unit == "s":
            return p
        def opt(v: float | None) -> float | None:
            return None if v is None else v * c
        return replace(p, value=p.value * c, se=p.se * c, ci_low=p.ci_low * c,
                       ci_high=p.ci_high * c, density=opt(p.density),
                       density_ci_low=opt(p.density_ci_low),
                       density_ci_high=opt(p.density_ci_high))

    c2 = c * c
    with np.errstate(over="ignore"):
        kl = None if res.k_long is None else (
            res.k_long[0] * c, res.k_long[1] * c, res.k_long[2] * c, res.k_long[3])
        kr = None if res.k_resolved is None else (
            res.k_resolved[0] * c, res.k_resolved[1] * c, res.k_resolved[2] * c)
        return replace(res, params=tuple(param(p) for p in res.params), wv=res.wv * c2,
                       k_long=kl, k_resolved=kr,
                       wv_ci_low=res.wv_ci_low * c2, wv_ci_high=res.wv_ci_high * c2,
                       wv_fit=res.wv_fit * c2,
                       wv_components={k: v * c2 for k, v in res.wv_components.items()})
