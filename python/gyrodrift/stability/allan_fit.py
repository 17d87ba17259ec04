"""IEEE Std 952 Allan-variance fit with a fit range, term choice, model selection and an
interval on every coefficient (the command line's `gyrodrift allan` fit).

Model (IEEE Std 952-1997 Annex C, table C.2; tau in s, sigma in deg/h):

    sigma^2(tau) = C_-2 / tau^2 + C_-1 / tau + C_0 + C_1 tau + C_2 tau^2,   C_k >= 0
    Q = sqrt(C_-2 / 3) arcsec, N = sqrt(C_-1) / 60 deg/sqrt(h), B = sqrt(C_0 pi / (2 ln 2))
    deg/h, K = 60 sqrt(3 C_1) deg/h/sqrt(h), R = 3600 sqrt(2 C_2) deg/h^2.

Fit: `ieee952.identify` (weighted NNLS of sigma^2, each tau weighted by its inverse variance
edf / (2 sigma_model^4), iteratively reweighted) on the taus inside `fit_range`, with the
chosen terms.

Model selection (default): the weighted residual sum of squares
chi2 = sum_i (edf_i / 2) (sigma_hat_i^2 - sigma_model_i^2)^2 / sigma_model_i^4 plays the
role of -2 log-likelihood (the Gaussian approximation of a chi-squared variance estimate),
and IC = chi2 + 2 p (Akaike) with p the number of non-zero terms. Terms the NNLS sets to zero
are dropped; then, while removing a remaining term does not increase IC, the term whose
removal gives the smallest IC is dropped (backward elimination). Dropped terms are listed.

Intervals: from the covariance of the weighted least-squares coefficients of the kept terms,
Cov(C) = (A' W A)^-1 with W = diag(edf_i / (2 sigma_model_i^4)) (the weighted NNLS
covariance, the constraint inactive at the solution), mapped to each term by the delta method
on the log scale (value exp(+-z se_log), se_log = se(C) / (2 C)). The Allan variances at
neighbouring taus are correlated (overlapping clusters); W ignores that, so these intervals
are optimistic where many taus share one term: gyrodrift.identify_gmwm carries the full
covariance.

Example
-------
>>> import numpy as np
>>> from gyrodrift.stability.ieee952 import allan_model_deg_h
>>> tau = np.logspace(-1, 3, 20)
>>> adev = allan_model_deg_h(tau, n_deg_rt_h=0.01, k_deg_h_rt_h=0.5)
>>> fit = fit_allan(tau, adev, np.full(20, 1e4))
>>> [t.name for t in fit.terms], fit.dropped
(['N', 'K'], ('Q', 'B', 'R'))
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.stats

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.stability import IEEE952_TERMS, ieee952
from gyrodrift.units import TERM_UNITS

__all__ = ["ALLAN_TERMS", "AllanFit", "AllanTerm", "fit_allan", "parse_fit_range",
           "parse_terms", "slope_readouts"]

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
    >>> n.name, n.unit, round(n.value, 5), n.density_unit
    ('N', 'deg/sqrt(h)', 0.00167, 'rad/s/sqrt(Hz)')
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

    def as_dict(self) -> dict[str, object]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True, eq=False)
class AllanFit:
    """Result of `fit_allan`.

    Attributes:
        terms: the kept terms with intervals; requested: the terms asked for; dropped: the
            requested terms not kept (zero in the NNLS or not improving IC).
        tau_min_s, tau_max_s: the fit range actually used (first and last tau inside).
        fit_used: per input tau, whether it was in the fit.
        fit_adev: fitted total deviation at every input tau (deg/h).
        components: each kept term's deviation at every input tau (deg/h).
        ic: the information criterion of the kept model; chi2: its weighted residual.
        ci: interval probability.

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
    ic: float = math.nan
    chi2: float = math.nan
    ci: float = 0.95

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
        }


def _nnls(tau: np.ndarray, var: np.ndarray, edf: np.ndarray, names: tuple[str, ...]
          ) -> tuple[np.ndarray, np.ndarray, float]:
    """Coefficients (for names), model variance at tau, chi2."""
    powers = tuple(ALLAN_TERMS[n] for n in names)
    fit = ieee952.identify(tau, np.sqrt(var), edf, powers=powers)
    c_all = np.asarray(fit.coeffs)
    idx = [list(ALLAN_TERMS).index(n) for n in names]
    c = c_all[idx]
    model = (tau[:, None] ** np.array(powers)[None, :]) @ c
    model = np.maximum(model, 1e-300)
    chi2 = float(np.sum(edf / 2.0 * (var - model) ** 2 / model**2))
    return c, model, chi2


def fit_allan(tau_s: np.ndarray, adev: np.ndarray, edf: np.ndarray, *,
              terms: str | tuple[str, ...] = IEEE952_TERMS,
              fit_range: tuple[float, float] | str | None = None, select: bool = True,
              ci: float = 0.95) -> AllanFit:
    """Allan-variance fit (module docstring). tau_s in s, adev in deg/h, edf per tau.

    Raises:
        ValueError: bad curve, bad terms / fit range, fewer taus in the range than terms.

    Examples
    --------
    >>> from gyrodrift.stability.allan import oadev
    >>> rng = np.random.default_rng(0)  # white noise 1 deg/h per sample at 100 Hz: N only
    >>> r = oadev(rng.normal(0.0, 1.0, 8192), 100.0)
    >>> fit = fit_allan(r.tau_s, r.adev, r.edf)
    >>> fit.names, fit.dropped
    (('N',), ('Q', 'B', 'K', 'R'))
    >>> n = fit.term("N")  # sigma * sqrt(dt) / 60 = 1 * 0.1 / 60 deg/sqrt(h)
    >>> round(n.value, 5), n.ci_low < 1 / 600 < n.ci_high
    (0.00167, True)
    """
    tau = np.asarray(tau_s, dtype=np.float64)
    dev = np.asarray(adev, dtype=np.float64)
    e = np.asarray(edf, dtype=np.float64)
    if tau.ndim != 1 or tau.shape != dev.shape or tau.shape != e.shape:
        raise GyrodriftValueError("tau_s, adev and edf must be 1-D of equal length")
    if not 0.0 < ci < 1.0:
        raise GyrodriftValueError(f"ci must be in (0, 1), got {ci!r}")
    names = parse_terms(terms) if not isinstance(terms, tuple) else parse_terms(list(terms))
    lo, hi = (parse_fit_range(fit_range) if isinstance(fit_range, str)
              else (fit_range if fit_range is not None else (0.0, math.inf)))
    used = (tau >= lo * (1 - 1e-12)) & (tau <= hi * (1 + 1e-12)) & (dev > 0)
    if np.count_nonzero(used) < len(names):
        raise GyrodriftValueError(
            f"{int(np.count_nonzero(used))} taus with a positive deviation in the "
            f"fit range {lo:g}:{hi:g} s cannot identify {len(names)} terms")
    t_u, var_u, e_u = tau[used], dev[used] ** 2, e[used]
    kept = names
    c, model, chi2 = _nnls(t_u, var_u, e_u, kept)
    if select:
        kept = tuple(n for n, ci_ in zip(kept, c, strict=True) if ci_ > 0) or kept
        c, model, chi2 = _nnls(t_u, var_u, e_u, kept)
        ic = chi2 + 2.0 * len(kept)
        while len(kept) > 1:
            trials = []
            for drop in kept:
                sub = tuple(n for n in kept if n != drop)
                cs, _, x2 = _nnls(t_u, var_u, e_u, sub)
                trials.append((x2 + 2.0 * np.count_nonzero(cs > 0), sub))
            best_ic, best_sub = min(trials, key=lambda s: s[0])
            if best_ic > ic:
                break
            kept = best_sub
            c, model, chi2 = _nnls(t_u, var_u, e_u, kept)
            kept_nz = tuple(n for n, ci_ in zip(kept, c, strict=True) if ci_ > 0)
            if kept_nz and kept_nz != kept:
                kept = kept_nz
                c, model, chi2 = _nnls(t_u, var_u, e_u, kept)
            ic = chi2 + 2.0 * len(kept)
    ic = chi2 + 2.0 * len(kept)
    # interval: weighted LS covariance of the coefficients of the kept, non-zero terms
    powers = np.array([ALLAN_TERMS[n] for n in kept])
    a = t_u[:, None] ** powers[None, :]
    w = e_u / (2.0 * model**2)
    info = a.T @ (a * w[:, None])
    cov = np.linalg.pinv(info)
    z = float(scipy.stats.norm.ppf(0.5 + ci / 2.0))
    out = []
    for k, name in enumerate(kept):
        ck = float(c[k])
        if ck <= 0.0:
            continue
        se_log = math.sqrt(max(float(cov[k, k]), 0.0)) / (2.0 * ck)
        val = _coef_to_value(name, ck)
        lo_v, hi_v = val * math.exp(-z * se_log), val * math.exp(z * se_log)
        dens = _DENSITY.get(name)
        out.append(AllanTerm(
            name, val, TERM_UNITS["gyro"][name].ieee, lo_v, hi_v, ck,
            None if dens is None else val * dens[0], None if dens is None else dens[1],
            None if dens is None else lo_v * dens[0], None if dens is None else hi_v * dens[0]))
    kept_names = tuple(t.name for t in out)
    comps = {t.name: np.sqrt(t.coeff * tau ** ALLAN_TERMS[t.name]) for t in out}
    total = np.sqrt(sum((v**2 for v in comps.values()), np.zeros_like(tau)))
    return AllanFit(
        terms=tuple(out), requested=names,
        dropped=tuple(n for n in names if n not in kept_names),
        tau_min_s=float(t_u.min()), tau_max_s=float(t_u.max()), fit_used=used,
        fit_adev=total, components=comps, ic=float(ic), chi2=float(chi2), ci=float(ci))


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
