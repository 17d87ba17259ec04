"""The fit self-check of any fitted noise model (an Allan fit, a GMWM fit), whether or not the
fit carries it yet, and the lines every output writes from it.

`fit_check_of(result, curve)` returns the result's own `check` when it has one, and otherwise
computes it with :func:`gyrodrift.stability.fit_check.check_fit` from what the result holds
(GMWM: the wavelet variance and its interval) or from the measured curve it was fitted to
(an Allan fit: the Allan deviation with its interval, `curve`).

Each point is checked against the measured value's chi-squared interval of a simultaneous
CHECK_CI band, or against the ratio tolerance of
:data:`gyrodrift.stability.fit_check.DEFAULT_TOLERANCE`.

The fit statistic is the reduced chi-square: the weighted residual sum of squares over its
degrees of freedom (points used minus terms fitted); about 1 when the model describes the
curve, much larger when it does not.

Examples
--------
>>> import numpy as np
>>> from gyrodrift.stability.allan import oadev
>>> from gyrodrift.stability.allan_fit import fit_allan
>>> r = oadev(np.random.default_rng(0).normal(0.0, 1.0, 8192), 100.0)
>>> chk = fit_check_of(fit_allan(r.tau_s, r.adev, r.edf), r)
>>> chk.holds, chk.what, check_lines(chk, "gyro_x")
(True, 'Allan deviation', [])
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.stability.allan import chi2_interval
from gyrodrift.stability.fit_check import FitCheck, check_fit

__all__ = ["CHECK_CI", "SELF_CHECK_EXIT", "allan_check", "check_lines", "check_summary",
           "fit_check_of"]

#: Probability of the simultaneous band the measured points are checked against: each used
#: point's chi-squared interval at 1 - (1 - CHECK_CI) / (points used) (Bonferroni), so that a
#: model that is right fails its check with probability below 5 % whatever the number of
#: points (the user's --ci, one sigma by default, would fail a right model at a third of the
#: points).
CHECK_CI = 0.95

#: Exit code of a command run with ``--self-check`` when a fitted model does not hold
#: (2 is a user error, 1 a failed job of a fleet).
SELF_CHECK_EXIT = 3


def _band_p(n_used: int) -> float:
    return 1.0 - (1.0 - CHECK_CI) / max(n_used, 1)


def allan_check(tau_s: np.ndarray, adev: np.ndarray, edf: np.ndarray, fit_adev: np.ndarray,
                used: np.ndarray, *, chi2: float = math.nan, n_terms: int = 0) -> FitCheck:
    """The self-check of a fitted Allan deviation: each point against the measured one's
    chi-squared interval of the simultaneous CHECK_CI band (module docstring), the fit
    statistic chi2 / (points used - n_terms).

    Examples
    --------
    >>> import numpy as np
    >>> tau = np.array([1.0, 10.0, 100.0]); adev = np.array([1.0, 0.32, 0.1])
    >>> chk = allan_check(tau, adev, np.array([1e4, 1e3, 1e2]), adev * [1.0, 1.0, 3.0],
    ...                   np.array([True, True, True]))
    >>> chk.holds, chk.n_failed
    (False, 1)
    """
    used = np.asarray(used, dtype=bool)
    n_used = int(np.count_nonzero(used))
    dev = np.asarray(adev, dtype=float)
    e = np.asarray(edf, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        lo, hi = chi2_interval(dev, np.where(e > 0, e, np.nan), _band_p(n_used))
    dof = max(n_used - int(n_terms), 0)
    stat = chi2 / dof if dof > 0 and math.isfinite(chi2) else math.nan
    return check_fit(np.asarray(tau_s, dtype=float), dev, lo, hi, fit_adev, used,
                     statistic=stat, dof=dof, what="Allan deviation", x_name="tau", x_unit="s")


def _allan_fit_check(fit: Any, curve: Any) -> FitCheck:
    tau = np.asarray(curve.tau_s, dtype=float)
    if tau.shape != np.asarray(fit.fit_adev).shape:
        raise GyrodriftValueError("the Allan fit and the curve have different averaging times")
    return allan_check(tau, curve.adev, curve.edf, fit.fit_adev, fit.fit_used,
                       chi2=float(getattr(fit, "chi2", math.nan)), n_terms=len(fit.terms))


def _gmwm_check(res: Any) -> FitCheck:
    import scipy.stats  # heavy: only where a GMWM result is checked

    nu2 = np.asarray(res.wv, dtype=float)
    n = nu2.size
    # eta_j = max(M_j / 2^j, 1), M_j = N - 2^j + 1 (gyrodrift.stability.gmwm's interval)
    width = np.rint(np.asarray(res.tau_s, dtype=float) * float(res.rate_hz))
    eta = np.maximum((float(res.n_samples) - width + 1.0) / width, 1.0)
    p_low = (1.0 - _band_p(n)) / 2.0
    lo = nu2 * eta / scipy.stats.chi2.ppf(1.0 - p_low, eta)
    hi = nu2 * eta / scipy.stats.chi2.ppf(p_low, eta)
    dof = max(n - len(res.params), 0)
    stat = float(res.objective) / dof if dof > 0 else math.nan
    return check_fit(res.tau_s, nu2, lo, hi, res.wv_fit, np.ones(n, dtype=bool),
                     statistic=stat, dof=dof, what="wavelet variance", x_name="scale",
                     x_unit="s")


def fit_check_of(result: Any, curve: Any = None) -> FitCheck:
    """The self-check of a fitted noise model: ``result.check`` when the fit carries one,
    else computed (module docstring).

    Parameters
    ----------
    result : an :class:`~gyrodrift.stability.allan_fit.AllanFit` or a
        :class:`~gyrodrift.stability.gmwm.GmwmResult`.
    curve : the :class:`~gyrodrift.stability.allan.AllanResult` an Allan fit was fitted to
        (tau_s, adev, ci_low, ci_high on the same averaging times); not needed for GMWM.

    Examples
    --------
    >>> import numpy as np
    >>> from gyrodrift.stability.gmwm import identify_gmwm
    >>> res = identify_gmwm(np.random.default_rng(2).standard_normal(4096), 10.0, model="N")
    >>> chk = fit_check_of(res)
    >>> chk.what, chk.x_name, chk.holds
    ('wavelet variance', 'tau', True)
    """
    own = getattr(result, "check", None)
    if isinstance(own, FitCheck):
        return own
    if hasattr(result, "wv_fit"):
        return _gmwm_check(result)
    if hasattr(result, "fit_adev") and hasattr(result, "fit_used"):
        if curve is None:
            raise GyrodriftValueError("the self-check of an Allan fit needs the measured curve")
        return _allan_fit_check(result, curve)
    raise GyrodriftValueError(f"no self-check for a {type(result).__name__}")


def check_lines(chk: FitCheck, label: str = "") -> list[str]:
    """The warning lines of a check, each prefixed by ``label`` (a channel) when given; empty
    when the model holds.

    Examples
    --------
    >>> import numpy as np
    >>> m = np.array([1.0, 0.5])
    >>> chk = check_fit(np.array([1.0, 2.0]), m, m * 0.9, m * 1.1, m * 3.0,
    ...                 np.array([True, True]))
    >>> check_lines(chk, "gyro_z")[0][:40]
    'WARNING: gyro_z: model does not hold: th'
    """
    pre = f"{label}: " if label else ""
    return [f"WARNING: {pre}{w}" for w in chk.warnings]


def check_summary(chk: FitCheck) -> str:
    """One line: the fit statistic, how many points passed and the worst ratio.

    Examples
    --------
    >>> import numpy as np
    >>> m = np.array([1.0, 0.5, 0.4])
    >>> chk = check_fit(np.array([1.0, 2.0, 4.0]), m, m * 0.9, m * 1.1, m * 1.05,
    ...                 np.array([True, True, True]), statistic=1.5, dof=1)
    >>> print(check_summary(chk).replace("; ", ";\\n"))
    self-check: model holds;
    chi2/dof 1.5 (dof 1);
    3 of 3 fitted tau within the interval or 25 %;
    worst fitted/measured 1.05
    """
    n_used = int(np.count_nonzero(chk.used))
    stat = "n/a" if math.isnan(chk.statistic) else f"{chk.statistic:.3g}"
    return (f"self-check: model {'holds' if chk.holds else 'does NOT hold'}; chi2/dof {stat} "
            f"(dof {chk.dof}); {n_used - chk.n_failed} of {n_used} fitted {chk.x_name} within "
            f"the interval or {100 * chk.tolerance:.3g} %; worst fitted/measured "
            f"{chk.worst_ratio:.3g}")
