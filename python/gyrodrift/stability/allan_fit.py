"""IEEE Std 952 Allan-variance fit with an automatic fit range, term choice, model selection,
a self-check and misspecification-robust intervals (the default noise identifier of
`gyrodrift allan`, `identify` and `characterize`).

Model (IEEE Std 952-1997 Annex C, table C.2; tau in s, sigma in deg/h)::

    sigma^2(tau) = C_-2 / tau^2 + C_-1 / tau + C_0 + C_1 tau + C_2 tau^2,   C_k >= 0
    Q = sqrt(C_-2 / 3) arcsec, N = sqrt(C_-1) / 60 deg/sqrt(h), B = sqrt(C_0 pi / (2 ln 2))
    deg/h, K = 60 sqrt(3 C_1) deg/h/sqrt(h), R = 3600 sqrt(2 C_2) deg/h^2.

The flat C_0 is the exact Allan variance of flicker (1/f) rate noise for averaging times well
above the sample period and below the record's low-frequency end, so the model's shape is right
for bias instability; what goes wrong on real records is how the fit weighs the points.

Objective (log scale). The fit minimises::

    chi2 = sum_i w_i (log sigma_hat_i^2 - log sigma_model_i^2)^2,  w_i = 1 / (2 / edf_i + d^2)

over C_k >= 0 (scipy.optimize.least_squares, bounds, started from the weighted NNLS of
`ieee952.identify`). 2 / edf_i is the variance of the log of a chi-squared variance estimate
with edf_i degrees of freedom; d = MODEL_DISCREPANCY (10 % of sigma^2, 5 % of sigma) is the
relative error the five-term model is allowed at any tau (output filters, vibration lines and
Gauss-Markov humps of real sensors), so that the short taus, whose edf run to 1e5, do not
decide every term alone. The old objective, squared residuals of sigma^2 divided by the squared
*model*, is bounded when the model overshoots ((v - m)^2 / m^2 -> 1 as m -> infinity) but not
when it undershoots; on a curve the model cannot follow it lifts a flat B far above the curve
(3-5x the Allan minimum on real MEMS records, 40x on the tactical-mems preset). The log residual
is symmetric.

Fit range. Unless the caller gives `fit_range`, the range is chosen automatically and stated
(`AllanFit.range_note`): taus with a positive deviation and edf >= MIN_FIT_EDF, then, one at a
time, the end tau (shortest or longest) whose standardised residual
``|log sigma_hat^2 - log sigma_model^2| sqrt(w)`` exceeds TRIM_SIGMAS is removed and the model
refitted, while more than max(5, terms + 1) taus and at least 1 - MAX_TRIM_SHARE of the
eligible taus remain: a sensor's output filter bends the
first taus below the N line, a warm-up or the record's end bends the last ones; both are outside
the five-term model. Taus inside the range are never removed: where the model leaves them, the
self-check says so; and where the model falls below a left-out tau (edf >= MIN_FIT_EDF), or
rises above one beyond the longest fitted tau, by more than EXTRAPOLATION_FACTOR, the model fails
its self-check too (a model above the curve at the short end is the output filter's bend).

Model selection: IC = chi2 + 2 p (Akaike, chi2 playing -2 log-likelihood) with p the number of
non-zero terms; terms at zero are dropped; then, while removing a remaining term does not
increase IC, the term whose removal gives the smallest IC is dropped (backward elimination).

Self-check: `AllanFit.check` (`gyrodrift.stability.fit_check.check_fit`) compares the fitted
deviation with the measured one and its 95 % chi-squared interval (from the edf) at every tau;
`AllanFit.approximate` is True when a used tau fails it or the reduced chi2 exceeds its 99 %
point: the output then says the model is approximate.

Intervals (misspecification-robust). The coefficients' covariance is the sandwich::

    cov(C) = H^-1 J' W (V_s + d^2 C) W J H^-1,   H = J' W J,

J = d log sigma_model^2 / d C at the used taus, W = diag(w_i) the fit's weight, and the
covariance of the measured log Allan variances in two parts:

- V_s, their sampling covariance. With the record length and sample rate (``n_samples``,
  ``rate_hz``; every used tau an octave multiple of the sample period) it is the Gaussian
  covariance of the estimated Allan variances, exact for the record length, under the octave
  sieve spectrum that `gyrodrift.stability.gmwm.wv_covariance_nonparametric` matches to the
  measured curve (the overlapping Allan variance at tau = m dt is twice the Haar wavelet
  variance of level log2(2m), with the same coefficients); it depends on the data only, not
  on the fitted model, and holds the strong correlation of neighbouring octaves under flicker
  and random-walk noise that a diagonal 2 / edf misses. Without them, 2 / edf_i on the
  diagonal with the correlation C below.
- d^2 C, the model discrepancy (Kennedy & O'Hagan 2001): what the five-term model misses
  (an output filter's bend, a Gauss-Markov hump, a warm-up) treated as a random relative
  error of the curve, with the correlation C_ij of the Allan filters at tau_i and tau_j over
  log-frequency (`gmwm.allan_kernel_corr`: a misfit of the spectrum shows at the taus whose
  filters see its band; C = 0.60 for adjacent octaves, 0.22 two octaves apart; computed for
  flicker noise, whose power per log-frequency is flat). Its variance d^2 is estimated from
  the residuals r = log sigma_hat^2 - log sigma_model^2 by moments: with M = I - J H^-1 J' W
  (the fit's residual maker) and A = diag(V_s)^-1::

      d^2 = max(0, [r' A r - tr(A M V_s M')] / tr(A M C M')),

  the excess of the residuals over their sampling variance, weighted where the curve is
  measured precisely enough to show it (`AllanFit.discrepancy` = d, relative sd of sigma^2).

The quantile is Student's t with dof = used taus - kept terms (the discrepancy's variance is
estimated from the residuals). Model uncertainty: each term's interval is widened to cover
its intervals in every model tried by the selection whose IC is within MODEL_SET_DELTA = 4 of
the selected one's (`AllanFit.model_set`): on the tactical-mems preset the selection drops
K on about 45 % of the records (keeping N+B or N+B+R), B then carries K's share of the
minimum (+16 % on those records), and the selected model's own intervals cover the
generating B on 67-76 % of them. Each term's interval is
the delta method on the log scale, value exp(+-t se_log), se_log = se(C) / (2 C). The Monte
Carlo coverage on the `gyrodrift.simulation.presets` records
(docs/validation/noise-identification.md, on seeds other than those the construction was
checked on during development) is the check.

Datasheet read-off: `AllanFit.b_readoff` is the minimum of the measured Allan deviation over
the taus with edf >= READOFF_MIN_EDF, divided by 0.664, at `b_readoff_tau_s`, with the
chi-squared interval of the deviation there; it overstates B where N, K or other terms still
contribute at the minimum. K is reported as identified only where the fitted K line carries at
least half of the model variance at the longest fitted tau (the record shows the +1/2 slope)
and the record measures it to K_MAX_REL_ERROR (30 %): its interval, taken at probability
K_ID_PROB (90 %) from the same standard errors, lies inside [K / 1.3, K / 0.7], so that the
estimate is within 30 % of the true K with that probability. A wider rule (an interval within
a factor 3) picked the records whose K came out high (a larger K line carries more of the
model, so its relative interval is narrower) and reported K 1.29x the generating value as a
median on the tactical-mems preset. Otherwise `AllanFit.upper_limits["K"]` gives the K whose
line alone reaches the upper end of the measured interval at some fitted tau (the largest K
the curve allows), and the K term, if kept, is marked ``identified = False`` (its value and
interval are still given: an estimate the record does not pin down to 30 %).

Examples
--------
>>> import numpy as np
>>> from gyrodrift.stability.ieee952 import allan_model_deg_h
>>> tau = np.logspace(-1, 3, 20)
>>> adev = allan_model_deg_h(tau, n_deg_rt_h=0.01, k_deg_h_rt_h=0.5)
>>> fit = fit_allan(tau, adev, np.full(20, 1e4))
>>> [t.name for t in fit.terms], fit.dropped, fit.check.holds
(['N', 'K'], ('Q', 'B', 'R'), True)
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.stats

from gyrodrift._scale import scale_for_peak
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.stability import IEEE952_TERMS, gmwm, ieee952
from gyrodrift.stability.fit_check import FitCheck, check_fit
from gyrodrift.units import TERM_UNITS

__all__ = ["ALLAN_TERMS", "EXTRAPOLATION_FACTOR", "K_ID_PROB", "K_MAX_REL_ERROR",
           "MAX_TRIM_SHARE", "MIN_FIT_EDF",
           "MODEL_DISCREPANCY", "MODEL_SET_DELTA", "READOFF_MIN_EDF", "TRIM_SIGMAS",
           "AllanFit", "AllanTerm", "fit_allan", "parse_fit_range",
           "parse_terms", "slope_readouts"]

#: Relative error of sigma^2 the five-term model is allowed at any tau (module docstring).
MODEL_DISCREPANCY = 0.1
#: Taus with fewer equivalent degrees of freedom are left out of an automatic fit range.
MIN_FIT_EDF = 3.0
#: An end tau whose standardised log residual exceeds this leaves an automatic range.
TRIM_SIGMAS = 2.0
#: The largest share of the eligible taus the automatic range may leave out (beyond it, a
#: model that misses the curve is flagged rather than fitted to a narrower window).
MAX_TRIM_SHARE = 0.5
#: A tau left out of an automatic range where the model differs from the measured deviation
#: by more than this factor makes the model fail its self-check.
EXTRAPOLATION_FACTOR = 3.0
#: The datasheet read-off of B looks for the minimum over taus with at least these edf.
READOFF_MIN_EDF = 10.0
#: Probability of the measured interval the self-check compares against.
CHECK_CI = 0.95
#: K counts as identified only if the record measures it to this relative error ...
K_MAX_REL_ERROR = 0.3
#: ... with this probability (module docstring).
K_ID_PROB = 0.9
#: Models whose IC is within this of the selected one's widen its intervals (model
#: uncertainty; the same margin as GMWM's model set).
MODEL_SET_DELTA = 4.0

#: Term letter -> power k of tau in sigma^2.
ALLAN_TERMS: dict[str, int] = {"Q": -2, "N": -1, "B": 0, "K": 1, "R": 2}
#: Terms reported as densities too (Kalibr-style SI): factor from the display unit, SI unit.
_DENSITY = {n: (TERM_UNITS["gyro"][n].from_ieee, TERM_UNITS["gyro"][n].si) for n in ("N", "K")}


def _coef_to_value(name: str, c: float) -> float:
    if name == "Q":
        return math.sqrt(c / 3.0)
    if name == "N":
        return math.sqrt(c) / 60.0
    if name == "B":
        return math.sqrt(c) / ieee952.B_FLOOR_FACTOR
    if name == "K":
        return 60.0 * math.sqrt(3.0 * c)
    return 3600.0 * math.sqrt(2.0 * c)


def parse_terms(text: str | tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """'Q,N,B' -> ('Q', 'N', 'B') in canonical order; ValueError on unknown terms.

    Examples
    --------
    >>> parse_terms("n,b"), parse_terms(("N", "K"))
    (('N', 'B'), ('N', 'K'))
    """
    items = text.split(",") if isinstance(text, str) else list(text)
    out = [s.strip().upper() for s in items if s.strip()]
    bad = [s for s in out if s not in ALLAN_TERMS]
    if bad or not out:
        raise GyrodriftValueError(
            f"terms must be a comma-separated subset of Q,N,B,K,R, got {text!r}")
    return tuple(t for t in ALLAN_TERMS if t in out)


def parse_fit_range(text: str) -> tuple[float, float]:
    """'TMIN:TMAX' in s (either side may be empty: open) -> (tmin, tmax).

    Examples
    --------
    >>> parse_fit_range("0.1:10"), parse_fit_range("1e-2:100")
    ((0.1, 10.0), (0.01, 100.0))
    """
    parts = text.split(":")
    if len(parts) != 2:
        raise GyrodriftValueError(f"fit range must be TMIN:TMAX in seconds, got {text!r}")
    try:
        lo = float(parts[0]) if parts[0].strip() else 0.0
        hi = float(parts[1]) if parts[1].strip() else math.inf
    except ValueError:
        raise GyrodriftValueError(f"fit range must be TMIN:TMAX in seconds, got {text!r}") from None
    if not (lo >= 0.0 and hi > lo) or math.isnan(lo) or math.isnan(hi):
        raise GyrodriftValueError(f"fit range needs 0 <= TMIN < TMAX, got {text!r}")
    return lo, hi


@dataclass(frozen=True)
class AllanTerm:
    """One identified term in IEEE Std 952 units with its interval (probability AllanFit.ci);
    density: the continuous-time density for N (rad/s/sqrt(Hz)) and K (rad/s^2/sqrt(Hz)).

    Examples
    --------
    >>> from gyrodrift.stability.allan import oadev
    >>> r = oadev(np.random.default_rng(0).normal(0.0, 1.0, 8192), 100.0)  # white, deg/h
    >>> n = fit_allan(r.tau_s, r.adev, r.edf).term("N")
    >>> n.name, n.unit, round(n.value, 4), n.density_unit
    ('N', 'deg/sqrt(h)', 0.0017, 'rad/s/sqrt(Hz)')
    """

    name: str
    value: float
    unit: str
    ci_low: float
    ci_high: float
    coeff: float  # C_k, (deg/h)^2 s^k
    density: float | None = None
    density_unit: str | None = None
    density_ci_low: float | None = None
    density_ci_high: float | None = None
    identified: bool = True

    def as_dict(self) -> dict[str, object]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}

    def scaled(self, c: float) -> AllanTerm:
        """The term of the curve c times this one (values, intervals and densities x c, the
        coefficient x c^2).

        Examples
        --------
        >>> t = AllanTerm("N", 0.5, "deg/sqrt(h)", 0.4, 0.6, 900.0)
        >>> t.scaled(2.0).value, t.scaled(2.0).coeff
        (1.0, 3600.0)
        """
        def opt(v: float | None) -> float | None:
            return None if v is None else v * c

        return dataclasses.replace(
            self, value=self.value * c, ci_low=self.ci_low * c, ci_high=self.ci_high * c,
            coeff=self.coeff * c * c, density=opt(self.density),
            density_ci_low=opt(self.density_ci_low), density_ci_high=opt(self.density_ci_high))


@dataclass(frozen=True, eq=False)
class AllanFit:
    """Result of `fit_allan`.

    Attributes
    ----------
    terms
        the kept terms with intervals.
    requested
        the terms asked for.
    dropped
        the requested terms not kept (zero in the NNLS or not improving IC).
    tau_min_s, tau_max_s
        the fit range actually used (first and last tau inside).
    fit_used
        per input tau, whether it was in the fit.
    fit_adev
        fitted total deviation at every input tau (deg/h).
    components
        each kept term's deviation at every input tau (deg/h).
    check
        the self-check of the fitted curve against the measured one (every fit).
    ic
        the information criterion of the kept model.
    chi2
        its weighted residual.
    ci
        interval probability.
    dof
        used taus minus kept terms.
    scale
        max(1, chi2 / dof), the reduced chi-square (reported; the intervals use the
        sandwich of the module docstring).
    approximate
        the model does not describe the curve within its errors (the check
        fails or chi2 / dof exceeds its 99 % point); the values are approximate.
    range_source
        "automatic" or "user".
    range_note
        which taus were fitted and why.
    b_readoff, b_readoff_tau_s, b_readoff_ci_low, b_readoff_ci_high
        the datasheet read-off min adev / 0.664 (deg/h), its tau and interval
        (probability ci).
    upper_limits
        terms the record cannot identify, with the largest value the curve
        allows (K, deg/h/sqrt(h)).
    discrepancy
        the model discrepancy d (relative sd of sigma^2 per tau) estimated from the
        residuals (module docstring).
    covariance_source
        "sieve" (the sampling covariance of the curve from the record length and rate)
        or "edf" (2 / edf with the Allan-filter correlation).
    model_set
        the other models within MODEL_SET_DELTA of the selected one's IC, whose
        intervals the terms' cover.

    Examples
    --------
    >>> from gyrodrift.stability.allan import oadev
    >>> r = oadev(np.random.default_rng(0).normal(0.0, 1.0, 8192), 100.0)
    >>> fit = fit_allan(r.tau_s, r.adev, r.edf, terms="N,B")
    >>> fit.requested, fit.names, fit.fit_adev.shape == r.tau_s.shape
    (('N', 'B'), ('N',), True)
    """

    terms: tuple[AllanTerm, ...]
    requested: tuple[str, ...]
    dropped: tuple[str, ...]
    tau_min_s: float
    tau_max_s: float
    fit_used: np.ndarray
    fit_adev: np.ndarray
    components: dict[str, np.ndarray] = field(repr=False)
    check: FitCheck = field(repr=False)
    ic: float = math.nan
    chi2: float = math.nan
    ci: float = 0.95
    dof: int = 0
    scale: float = 1.0
    approximate: bool = False
    range_source: str = "automatic"
    range_note: str = ""
    b_readoff: float = math.nan
    b_readoff_tau_s: float = math.nan
    b_readoff_ci_low: float = math.nan
    b_readoff_ci_high: float = math.nan
    upper_limits: dict[str, float] = field(default_factory=dict)
    discrepancy: float = 0.0
    covariance_source: str = "edf"
    model_set: tuple[tuple[str, ...], ...] = ()

    def scaled(self, c: float) -> AllanFit:
        """The fit of the curve c times this one's: every term, fitted and component
        deviation, read-off and upper limit x c (coefficients x c^2); the check, the
        statistic and the range do not depend on the scale."""
        return dataclasses.replace(
            self, terms=tuple(t.scaled(c) for t in self.terms), fit_adev=self.fit_adev * c,
            components={k: v * c for k, v in self.components.items()},
            b_readoff=self.b_readoff * c, b_readoff_ci_low=self.b_readoff_ci_low * c,
            b_readoff_ci_high=self.b_readoff_ci_high * c,
            upper_limits={k: v * c for k, v in self.upper_limits.items()})

    def term(self, name: str) -> AllanTerm:
        for t in self.terms:
            if t.name == name:
                return t
        raise KeyError(f"{name} is not in the fitted model ({', '.join(self.names)})")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.terms)

    def value(self, name: str) -> float:
        """The term's value, 0.0 if it was dropped."""
        return self.term(name).value if name in self.names else 0.0

    def notes(self) -> list[str]:
        """Lines to print under the terms: the fitted range, the datasheet read-off of B
        beside the fitted B, upper limits, and the warnings when the model is approximate."""
        out = [f"fitted {self.range_note}; dropped (no gain in chi2 + 2p): "
               f"{', '.join(self.dropped) or 'none'}"]
        if math.isfinite(self.b_readoff):
            fitted = (f"fitted B = {self.value('B'):.4g} deg/h" if "B" in self.names
                      else "B not in the fitted model")
            out.append(f"datasheet read-off B = min adev / 0.664 = {self.b_readoff:.4g} deg/h "
                       f"[{self.b_readoff_ci_low:.4g}, {self.b_readoff_ci_high:.4g}] at tau = "
                       f"{self.b_readoff_tau_s:.4g} s ({fitted}; the read-off includes what "
                       "N, K and other terms add at the minimum)")
        if self.model_set:
            out.append("intervals cover those of the models within "
                       f"{MODEL_SET_DELTA:g} of the selected one's IC: "
                       + ", ".join("+".join(m) for m in self.model_set))
        for name, value in self.upper_limits.items():
            out.append(f"{name} not identified by this record (its slope is not seen, or not "
                       f"measured to {100 * K_MAX_REL_ERROR:.0f} % with "
                       f"{100 * K_ID_PROB:.0f} % probability): "
                       f"{name} <= {value:.4g} {TERM_UNITS['gyro'][name].ieee}")
        if self.approximate:
            out.extend(self.check.warnings or (
                f"model is approximate: chi2 / dof = {self.chi2 / max(self.dof, 1):.3g} "
                f"(dof {self.dof}); model discrepancy {100 * self.discrepancy:.3g} % of "
                f"sigma^2 per tau in the intervals",))
        return out

    def as_dict(self) -> dict[str, object]:
        return {
            "terms": [t.as_dict() for t in self.terms],
            "requested": list(self.requested),
            "dropped": list(self.dropped),
            "tau_min_s": self.tau_min_s,
            "tau_max_s": self.tau_max_s,
            "ic": self.ic,
            "chi2": self.chi2,
            "ci": self.ci,
            "dof": self.dof,
            "scale": self.scale,
            "approximate": self.approximate,
            "range_source": self.range_source,
            "range_note": self.range_note,
            "b_readoff": {"value": self.b_readoff, "tau_s": self.b_readoff_tau_s,
                          "ci_low": self.b_readoff_ci_low,
                          "ci_high": self.b_readoff_ci_high, "unit": "deg/h"},
            "upper_limits": dict(self.upper_limits),
            "discrepancy": self.discrepancy,
            "covariance_source": self.covariance_source,
            "model_set": ["+".join(m) for m in self.model_set],
            "check": self.check.as_dict(),
        }


def _solve(tau: np.ndarray, var: np.ndarray, wt: np.ndarray, names: tuple[str, ...]
           ) -> tuple[np.ndarray, np.ndarray, float]:
    """Log-scale weighted fit (module docstring): coefficients (for names), model, chi2."""
    import scipy.optimize

    powers = np.array([ALLAN_TERMS[n] for n in names])
    a = tau[:, None] ** powers[None, :].astype(np.float64)
    # column scale: the coefficient each term alone would need at the median tau
    scale = np.median(var[:, None] / a, axis=0)
    a_s = a * scale[None, :]
    logv = np.log(var)
    sw = np.sqrt(wt)
    start = ieee952.identify(tau, np.sqrt(var), None, powers=tuple(int(p) for p in powers))
    c0 = np.asarray(start.coeffs)[[list(ALLAN_TERMS).index(n) for n in names]]
    u0 = np.maximum(c0 / scale, 1e-3)

    def model(u: np.ndarray) -> np.ndarray:
        return np.maximum(a_s @ u, 1e-300 * float(np.max(var)))

    def fun(u: np.ndarray) -> np.ndarray:
        return np.asarray(sw * (np.log(model(u)) - logv))

    def jac(u: np.ndarray) -> np.ndarray:
        return np.asarray((sw / model(u))[:, None] * a_s)

    sol = scipy.optimize.least_squares(fun, u0, jac=jac, bounds=(0.0, np.inf), method="trf",
                                       xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=500)
    u = np.asarray(sol.x, dtype=np.float64)
    m = model(u)
    # a term below 1e-6 of the model at every fitted tau is zero (the bound)
    share = (a_s * u[None, :]) / m[:, None]
    u = np.where(np.max(share, axis=0) < 1e-6, 0.0, u)
    m = model(u)
    chi2 = float(np.sum(wt * (np.log(m) - logv) ** 2))
    return u * scale, m, chi2


def _select(tau: np.ndarray, var: np.ndarray, wt: np.ndarray, names: tuple[str, ...],
            select: bool) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, float,
                                   dict[tuple[str, ...], tuple[np.ndarray, np.ndarray, float]]]:
    """Kept terms, their coefficients, the model and chi2 (backward elimination on IC), and
    every model tried (terms -> coefficients, model, chi2)."""
    tried: dict[tuple[str, ...], tuple[np.ndarray, np.ndarray, float]] = {}

    def solve(sub: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, float]:
        if sub not in tried:
            tried[sub] = _solve(tau, var, wt, sub)
        return tried[sub]

    kept = names
    c, model, chi2 = solve(kept)
    if not select:
        return kept, c, model, chi2, tried
    nz = tuple(n for n, ck in zip(kept, c, strict=True) if ck > 0)
    if nz and nz != kept:
        kept = nz
        c, model, chi2 = solve(kept)
    ic = chi2 + 2.0 * len(kept)
    while len(kept) > 1:
        trials = []
        for drop in kept:
            sub = tuple(n for n in kept if n != drop)
            cs, ms, x2 = solve(sub)
            trials.append((x2 + 2.0 * np.count_nonzero(cs > 0), sub, cs, ms, x2))
        best = min(trials, key=lambda t: t[0])
        if best[0] > ic:
            break
        _, kept, c, model, chi2 = best
        nz = tuple(n for n, ck in zip(kept, c, strict=True) if ck > 0)
        if nz and nz != kept:
            kept = nz
            c, model, chi2 = solve(kept)
        ic = chi2 + 2.0 * len(kept)
    return kept, c, model, chi2, tried


def _sampling_cov(tau: np.ndarray, var: np.ndarray, edf: np.ndarray, used: np.ndarray,
                  n_samples: int | None, rate_hz: float | None) -> tuple[np.ndarray, str]:
    """Covariance of log sigma_hat^2 at the used taus (module docstring): the Gaussian
    covariance of the estimated Allan variances under the octave sieve of
    `gmwm.wv_covariance_nonparametric` (record length and octave taus known), else
    2 / edf per tau with the Allan-filter overlap as the correlation."""
    ok = np.isfinite(var) & (var > 0) & np.isfinite(edf) & (edf > 0)
    if n_samples is not None and rate_hz is not None and n_samples >= 16:
        m = tau[ok] * float(rate_hz)
        lev = np.log2(np.maximum(m, 1e-300))
        octave = np.abs(m - np.round(m)) <= 1e-6 * m
        octave &= np.abs(lev - np.round(lev)) <= 1e-9
        octave &= 2.0 ** (np.round(lev) + 1.0) <= n_samples
        if np.all(octave[used[ok]]):
            keep = octave
            level = np.round(lev[keep]).astype(np.int64) + 1
            if np.unique(level).size == level.size and level.size >= 2:
                n = int(n_samples)
                big_l = 2.0 ** level
                m_coef = n - big_l + 1.0
                wv = gmwm.WaveletVariance(
                    tau_s=big_l / float(rate_hz), level=level, nu2=var[ok][keep] / 2.0,
                    n_coeffs=m_coef.astype(np.int64), eta=np.maximum(m_coef / big_l, 1.0),
                    rate_hz=float(rate_hz), n_samples=n)
                cov_wv = gmwm.wv_covariance_nonparametric(wv)
                pos = np.flatnonzero(ok)[keep]
                sel = np.searchsorted(pos, np.flatnonzero(used))
                v = var[used]
                return 4.0 * cov_wv[np.ix_(sel, sel)] / np.outer(v, v), "sieve"
    sd = np.sqrt(2.0 / edf[used])
    return np.outer(sd, sd) * gmwm.allan_kernel_corr(tau[used]), "edf"


def _robust_cov(jac: np.ndarray, wt: np.ndarray, resid: np.ndarray, v_s: np.ndarray,
                corr: np.ndarray) -> tuple[np.ndarray, float]:
    """Sandwich covariance of the coefficients (module docstring) and the model discrepancy
    d (relative sd of sigma^2 per tau) estimated from the residuals by moments."""
    info = jac.T @ (jac * wt[:, None])
    bread = np.linalg.pinv(info)
    resid_maker = np.eye(wt.size) - jac @ bread @ (jac.T * wt[None, :])
    a = 1.0 / np.diag(v_s)
    den = float(np.einsum("i,ij,ji->", a, resid_maker, corr @ resid_maker.T))
    excess = float(np.sum(a * resid**2)) - float(
        np.einsum("i,ij,ji->", a, resid_maker, v_s @ resid_maker.T))
    d2 = max(0.0, excess / den) if den > 0 else 0.0
    v = v_s + d2 * corr
    g = jac.T * wt[None, :]
    return bread @ g @ v @ g.T @ bread, math.sqrt(d2)


def _fmt_tau(t: float) -> str:
    return f"{t:.3g} s"


def fit_allan(tau_s: np.ndarray, adev: np.ndarray, edf: np.ndarray, *,
              terms: str | tuple[str, ...] = IEEE952_TERMS,
              fit_range: tuple[float, float] | str | None = None, select: bool = True,
              ci: float = 0.95, n_samples: int | None = None,
              rate_hz: float | None = None) -> AllanFit:
    """Allan-variance fit (module docstring). tau_s in s, adev in deg/h, edf per tau.

    ``fit_range`` (s, "TMIN:TMAX" or a pair) fixes the fitted taus; None chooses them
    automatically (module docstring) and says which in ``range_note``. ``n_samples`` (rate
    samples of the record behind the curve) and ``rate_hz`` give the intervals the curve's
    sampling covariance (module docstring); without them (a published curve) they use
    2 / edf with the Allan-filter correlation.

    Raises
    ------
    ValueError
        bad curve, bad terms / fit range, fewer taus in the range than terms.

    Examples
    --------
    >>> from gyrodrift.stability.allan import oadev
    >>> rng = np.random.default_rng(0)  # white noise 1 deg/h per sample at 100 Hz: N only
    >>> r = oadev(rng.normal(0.0, 1.0, 8192), 100.0)
    >>> fit = fit_allan(r.tau_s, r.adev, r.edf)
    >>> fit.names, fit.dropped, fit.check.holds, fit.approximate
    (('N',), ('Q', 'B', 'K', 'R'), True, False)
    >>> n = fit.term("N")  # sigma * sqrt(dt) / 60 = 1 * 0.1 / 60 deg/sqrt(h)
    >>> round(n.value, 4), n.ci_low < 1 / 600 < n.ci_high
    (0.0017, True)
    """
    from gyrodrift.stability.allan import chi2_interval

    tau = np.asarray(tau_s, dtype=np.float64)
    dev = np.asarray(adev, dtype=np.float64)
    e = np.asarray(edf, dtype=np.float64)
    if tau.ndim != 1 or tau.shape != dev.shape or tau.shape != e.shape:
        raise GyrodriftValueError("tau_s, adev and edf must be 1-D of equal length")
    if not 0.0 < ci < 1.0:
        raise GyrodriftValueError(f"ci must be in (0, 1), got {ci!r}")
    ok = np.isfinite(dev)
    c_dev = scale_for_peak(float(np.max(np.abs(dev[ok]))) if np.any(ok) else 0.0)
    if c_dev != 1.0:
        # A curve of extreme magnitude (its variances or weights overflow or underflow):
        # fitted scaled by a power of two (exact), the fit scaled back.
        return fit_allan(tau, dev / c_dev, e, terms=terms, fit_range=fit_range, select=select,
                         ci=ci, n_samples=n_samples, rate_hz=rate_hz).scaled(c_dev)
    names = parse_terms(terms) if not isinstance(terms, tuple) else parse_terms(list(terms))
    user_range = fit_range is not None
    lo, hi = (parse_fit_range(fit_range) if isinstance(fit_range, str)
              else (fit_range if fit_range is not None else (0.0, math.inf)))
    finite = np.isfinite(dev) & np.isfinite(e) & np.isfinite(tau)
    ok_all = finite & (dev > 0) & (e > 0)
    used = finite & (tau >= lo * (1 - 1e-12)) & (tau <= hi * (1 + 1e-12)) & (dev > 0) & (e > 0)
    n_low_edf = 0
    if not user_range:
        n_low_edf = int(np.count_nonzero(used & (e < MIN_FIT_EDF)))
        used &= e >= MIN_FIT_EDF
    if np.count_nonzero(used) < len(names):
        raise GyrodriftValueError(
            f"{int(np.count_nonzero(used))} taus with a positive deviation"
            + ("" if user_range else f" and edf >= {MIN_FIT_EDF:g}")
            + f" in the fit range {lo:g}:{hi:g} s cannot identify {len(names)} terms")
    var_all = np.where(used, dev, 1.0) ** 2
    wt_all = 1.0 / (2.0 / np.where(used, e, 1.0) + MODEL_DISCREPANCY**2)
    trimmed_short = trimmed_long = 0
    # Never more than MAX_TRIM_SHARE of the eligible taus: trimming is for the ends a sensor's
    # output filter or a warm-up bends, not a way to shrink the range until any model fits.
    min_kept = max(5, len(names) + 1,
                   math.ceil((1.0 - MAX_TRIM_SHARE) * np.count_nonzero(used)))
    while True:
        idx = np.flatnonzero(used)
        kept, c, model, chi2, tried = _select(tau[idx], var_all[idx], wt_all[idx], names,
                                              select)
        if user_range or idx.size <= min_kept:
            break
        z = np.abs(np.log(var_all[idx] / model)) * np.sqrt(wt_all[idx])
        end = 0 if z[0] >= z[-1] else -1
        if z[end] <= TRIM_SIGMAS:
            break
        used[idx[end]] = False
        if end == 0:
            trimmed_short += 1
        else:
            trimmed_long += 1
    idx = np.flatnonzero(used)
    t_u, var_u, wt_u, e_u = tau[idx], var_all[idx], wt_all[idx], e[idx]
    ic = chi2 + 2.0 * len(kept)
    dof = max(int(idx.size) - len(kept), 0)
    scale = max(1.0, chi2 / dof) if dof > 0 else 1.0
    powers = np.array([ALLAN_TERMS[n] for n in kept])
    jac = (t_u[:, None] ** powers[None, :].astype(np.float64)) / model[:, None]
    v_s, cov_source = _sampling_cov(tau, np.where(ok_all, dev, 1.0) ** 2, e, used,
                                    n_samples, rate_hz)
    cov, discrepancy = _robust_cov(jac, wt_u, np.log(var_u / model), v_s,
                                   gmwm.allan_kernel_corr(t_u))
    z = (float(scipy.stats.t.ppf(0.5 + ci / 2.0, dof)) if dof > 0
         else float(scipy.stats.norm.ppf(0.5 + ci / 2.0)))
    corr = gmwm.allan_kernel_corr(t_u)

    def intervals(terms: tuple[str, ...], coef: np.ndarray, m: np.ndarray, cv: np.ndarray
                  ) -> dict[str, tuple[float, float, float]]:
        res = {}
        for k, name in enumerate(terms):
            ck = float(coef[k])
            if ck <= 0.0:
                continue
            se_log = math.sqrt(max(float(cv[k, k]), 0.0)) / (2.0 * ck)
            val = _coef_to_value(name, ck)
            # a term at the edge of zero in a neighbouring model can have se_log > 700
            half = z * se_log
            res[name] = (val, val * math.exp(-half) if half < 700.0 else 0.0,
                         val * math.exp(half) if half < 700.0 else math.inf)
        return res

    ivs = intervals(kept, c, model, cov)
    # model uncertainty: each term's interval covers its intervals in the models whose IC
    # is within MODEL_SET_DELTA of the selected one's
    near = []
    for sub, (cs, ms, x2) in tried.items():
        p_sub = int(np.count_nonzero(cs > 0))
        if sub == kept or p_sub != len(sub) or x2 + 2.0 * p_sub > ic + MODEL_SET_DELTA:
            continue
        pw = np.array([ALLAN_TERMS[n] for n in sub])
        jac_s = (t_u[:, None] ** pw[None, :].astype(np.float64)) / ms[:, None]
        cov_s, _ = _robust_cov(jac_s, wt_u, np.log(var_u / ms), v_s, corr)
        near.append(sub)
        for name, (_, lo_s, hi_s) in intervals(sub, cs, ms, cov_s).items():
            if name in ivs:
                val, lo_v, hi_v = ivs[name]
                ivs[name] = (val, min(lo_v, lo_s), max(hi_v, hi_s))
    out = []
    for k, name in enumerate(kept):
        if name not in ivs:
            continue
        val, lo_v, hi_v = ivs[name]
        ck = float(c[k])
        dens = _DENSITY.get(name)
        out.append(AllanTerm(
            name, val, TERM_UNITS["gyro"][name].ieee, lo_v, hi_v, ck,
            None if dens is None else val * dens[0], None if dens is None else dens[1],
            None if dens is None else lo_v * dens[0], None if dens is None else hi_v * dens[0]))
    kept_names = tuple(t.name for t in out)
    comps = {t.name: np.sqrt(t.coeff * tau ** ALLAN_TERMS[t.name]) for t in out}
    total = np.sqrt(sum((v**2 for v in comps.values()), np.zeros_like(tau)))
    # K identified only where its line carries half the model variance at the longest tau
    # and its K_ID_PROB interval lies within K_MAX_REL_ERROR of the value (module docstring)
    upper: dict[str, float] = {}
    if "K" in names:
        k_share = (float(comps["K"][idx[-1]] ** 2 / total[idx[-1]] ** 2)
                   if "K" in comps and total[idx[-1]] > 0 else 0.0)
        k_measured = False
        k_term = next((t for t in out if t.name == "K"), None)
        if k_term is not None and k_term.ci_low > 0.0 and math.isfinite(k_term.ci_high):
            z_id = (float(scipy.stats.t.ppf(0.5 + K_ID_PROB / 2.0, dof)) if dof > 0
                    else float(scipy.stats.norm.ppf(0.5 + K_ID_PROB / 2.0)))
            # the same standard errors (each side) at probability K_ID_PROB
            lo_id = k_term.value * (k_term.ci_low / k_term.value) ** (z_id / z)
            hi_id = k_term.value * (k_term.ci_high / k_term.value) ** (z_id / z)
            k_measured = (lo_id >= k_term.value / (1.0 + K_MAX_REL_ERROR)
                          and hi_id <= k_term.value / (1.0 - K_MAX_REL_ERROR))
        if k_share < 0.5 or not k_measured:
            _, hi_ci = chi2_interval(dev[idx], e_u, ci)
            upper["K"] = float(np.min(60.0 * np.sqrt(3.0 * hi_ci**2 / t_u)))
            out = [t if t.name != "K" else dataclasses.replace(t, identified=False)
                   for t in out]
    # self-check against the measured 95 % interval
    ok = finite & (dev > 0) & (e > 0)
    m_lo, m_hi = chi2_interval(np.where(ok, dev, np.nan), np.where(ok, e, 1.0), CHECK_CI)
    check = check_fit(tau, dev, np.where(ok, m_lo, np.nan), np.where(ok, m_hi, np.nan), total,
                      used, statistic=chi2 / dof if dof > 0 else math.nan, dof=dof)
    if not user_range:
        # taus the automatic range left out still have to be near the model: a model that
        # leaves the curve by a large factor just outside its range (an R or K line fitted to
        # a hump, a flat B) does not describe the record, whatever it does inside the range
        # (a model above the curve at the short end is a sensor's output filter, which the
        # automatic range leaves out by design: not a misfit)
        elig = ok & (e >= MIN_FIT_EDF) & ~used
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = total / dev
        far = elig & ((ratio < 1.0 / EXTRAPOLATION_FACTOR)
                      | ((ratio > EXTRAPOLATION_FACTOR) & (tau > float(t_u.max()))))
        if np.any(far):
            j = int(np.flatnonzero(far)[np.argmax(np.abs(np.log(total[far] / dev[far])))])
            check = dataclasses.replace(check, holds=False, warnings=(*check.warnings, (
                f"model does not hold: outside the fitted range it leaves the measured Allan "
                f"deviation by more than {EXTRAPOLATION_FACTOR:g}x at {int(far.sum())} tau "
                f"(worst {total[j] / dev[j]:.3g}x at tau = {tau[j]:.3g} s); the values are "
                f"approximate")))
    approximate = (not check.holds) or (
        dof > 0 and chi2 > float(scipy.stats.chi2.ppf(0.99, dof)))
    # datasheet read-off of B
    ro = ok & (e >= READOFF_MIN_EDF)
    b_ro = b_ro_tau = b_ro_lo = b_ro_hi = math.nan
    if np.any(ro):
        j = int(np.flatnonzero(ro)[np.argmin(dev[ro])])
        r_lo, r_hi = chi2_interval(dev[j:j + 1], e[j:j + 1], ci)
        f = ieee952.B_FLOOR_FACTOR
        b_ro, b_ro_tau = float(dev[j] / f), float(tau[j])
        b_ro_lo, b_ro_hi = float(r_lo[0] / f), float(r_hi[0] / f)
    source = "user" if user_range else "automatic"
    note = f"taus {_fmt_tau(float(t_u.min()))}..{_fmt_tau(float(t_u.max()))}"
    if user_range:
        note += " (the range given)"
    else:
        why = []
        if trimmed_short:
            why.append(f"{trimmed_short} shortest left out: the model leaves them by more "
                       f"than {TRIM_SIGMAS:g} sigma")
        if trimmed_long:
            why.append(f"{trimmed_long} longest left out: the model leaves them by more than "
                       f"{TRIM_SIGMAS:g} sigma")
        if n_low_edf:
            why.append(f"{n_low_edf} with edf < {MIN_FIT_EDF:g} left out")
        note += " chosen automatically" + (f" ({'; '.join(why)})" if why else "")
    return AllanFit(
        terms=tuple(out), requested=names,
        dropped=tuple(n for n in names if n not in kept_names),
        tau_min_s=float(t_u.min()), tau_max_s=float(t_u.max()), fit_used=used,
        fit_adev=total, components=comps, check=check, ic=float(ic), chi2=float(chi2),
        ci=float(ci), dof=dof, scale=float(scale), approximate=bool(approximate),
        range_source=source, range_note=note, b_readoff=b_ro, b_readoff_tau_s=b_ro_tau,
        b_readoff_ci_low=b_ro_lo, b_readoff_ci_high=b_ro_hi, upper_limits=upper,
        discrepancy=float(discrepancy), covariance_source=cov_source, model_set=tuple(near))


def slope_readouts(result: Any, tolerance: float = 0.15) -> list[tuple[Any, ...]]:
    """IEEE Std 952 slope read-offs (as `ieee952.slope_method`) of an AllanResult, each
    with the interval of the Allan deviation at the tau it is read from (the read-off is
    proportional to sigma there). Rows: (name, value, unit, ci_low, ci_high, density,
    density_unit, density_ci_low, density_ci_high); value None where no stretch has the
    term's slope.

    Examples
    --------
    >>> from gyrodrift.stability.allan import oadev
    >>> r = oadev(np.random.default_rng(0).normal(0.0, 1.0, 8192), 100.0)
    >>> rows = slope_readouts(r)
    >>> [(row[0], row[2], None if row[1] is None else round(row[1], 5)) for row in rows[1:3]]
    [('N', 'deg/sqrt(h)', 0.00168), ('B', 'deg/h', 0.04059)]
    """
    pos = result.adev > 0
    tau, sig = result.tau_s[pos], result.adev[pos]
    lo_all, hi_all = result.ci_low[pos], result.ci_high[pos]
    rows: list[tuple[Any, ...]] = []
    if tau.size < 3:
        return rows
    slope = np.gradient(np.log(sig), np.log(tau))

    def at(target: float) -> int | None:
        k = int(np.argmin(np.abs(slope - target)))
        return k if abs(slope[k] - target) <= tolerance else None

    reads: dict[str, tuple[int | None, float]] = {}
    i = at(-1.0)
    reads["Q"] = (i, 0.0 if i is None else tau[i] / math.sqrt(3.0))
    i = at(-0.5)
    reads["N"] = (i, 0.0 if i is None else math.sqrt(tau[i] / 3600.0))
    j = int(np.argmin(sig))
    reads["B"] = ((j if abs(slope[j]) <= tolerance else None), 1.0 / ieee952.B_FLOOR_FACTOR)
    i = at(0.5)
    reads["K"] = (i, 0.0 if i is None else math.sqrt(3.0 * 3600.0 / tau[i]))
    for name, (idx, factor) in reads.items():
        dens = _DENSITY.get(name)
        if idx is None:
            rows.append((name, None, TERM_UNITS["gyro"][name].ieee, None, None, None,
                         None if dens is None else dens[1], None, None))
            continue
        v, lo, hi = (float(a[idx] * factor) for a in (sig, lo_all, hi_all))
        rows.append((name, v, TERM_UNITS["gyro"][name].ieee, lo, hi,
                     None if dens is None else v * dens[0], None if dens is None else dens[1],
                     None if dens is None else lo * dens[0],
                     None if dens is None else hi * dens[0]))
    return rows
