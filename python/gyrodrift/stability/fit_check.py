"""The self-check that travels with every fitted noise model: does the model describe the
measured curve (Allan deviation per averaging time, or wavelet variance per scale)?

A point passes when the fitted value lies inside the measured value's interval, or within
`tolerance` of it as a ratio (the interval alone is too strict where the record is long and
the interval narrow, the ratio alone too lax where it is short). The model holds when every
point used in the fit passes. A point outside the fit range is reported but does not make
the model fail: the user chose (or the fit chose and stated) the range.

Every output of a fit (text, JSON, CSV, HTML, Kalibr yaml, configuration file) carries
`FitCheck.as_dict()` or its `warnings`; `--self-check` turns `holds == False` into a
non-zero exit.

Examples
--------
>>> import numpy as np
>>> tau = np.array([1.0, 10.0, 100.0])
>>> meas = np.array([1.0, 0.32, 0.10])
>>> chk = check_fit(tau, meas, meas * 0.9, meas * 1.1, np.array([1.02, 0.31, 0.25]),
...                 np.array([True, True, True]), statistic=40.0, dof=1,
...                 what="Allan deviation", x_name="tau", x_unit="s")
>>> chk.holds, chk.n_failed, round(chk.worst_ratio, 2)
(False, 1, 2.5)
>>> chk.warnings[0].split(";")[0].split(" (")[1]
'worst 2.5x at tau = 100 s)'
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyrodrift.errors import GyrodriftValueError

__all__ = ["DEFAULT_TOLERANCE", "FitCheck", "check_fit"]

#: Default ratio tolerance of a point outside its interval (fitted / measured within
#: [1 / (1 + tol), 1 + tol]). 25 %: about the half-width of a 95 % Allan-deviation interval
#: at 30 degrees of freedom, so a point closer than that is within what the estimate can tell.
DEFAULT_TOLERANCE = 0.25


@dataclass(frozen=True, eq=False)
class FitCheck:
    """Whether a fitted model describes the measured curve, point by point.

    Attributes
    ----------
    what
        the curve's name ("Allan deviation", "wavelet variance").
    x_name, x_unit
        the abscissa ("tau", "s").
    x
        abscissa of every point.
    ratio
        fitted / measured at every point.
    inside
        the fitted value lies inside the measured interval.
    passed
        inside, or the ratio within `tolerance`.
    used
        the point was in the fit.
    statistic
        the fit statistic (reduced chi-square: chi2 / dof; nan if not defined).
    dof
        its degrees of freedom.
    tolerance
        ratio tolerance (see module docstring).
    holds
        every used point passed.
    warnings
        lines to show the user (empty when the model holds).

    Examples
    --------
    >>> one = np.array([1.0])
    >>> chk = check_fit(one, 2 * one, 1.8 * one, 2.2 * one, 2.1 * one, np.array([True]))
    >>> chk.holds, chk.n_failed, chk.as_dict()["n_used"]
    (True, 0, 1)
    """

    what: str
    x_name: str
    x_unit: str
    x: np.ndarray
    ratio: np.ndarray
    inside: np.ndarray
    passed: np.ndarray
    used: np.ndarray
    statistic: float
    dof: int
    tolerance: float
    holds: bool
    warnings: tuple[str, ...] = field(default=())

    @property
    def n_failed(self) -> int:
        """Number of used points that failed."""
        return int(np.count_nonzero(self.used & ~self.passed))

    @property
    def worst_ratio(self) -> float:
        """The used point's fitted / measured ratio farthest from 1 (on the log scale)."""
        r = self.ratio[self.used & np.isfinite(self.ratio) & (self.ratio > 0)]
        if r.size == 0:
            return math.nan
        return float(r[np.argmax(np.abs(np.log(r)))])

    def as_dict(self) -> dict[str, object]:
        """JSON-ready summary (lists for the per-point arrays)."""
        return {
            "holds": self.holds,
            "what": self.what,
            "statistic": self.statistic,
            "dof": self.dof,
            "tolerance": self.tolerance,
            "n_used": int(np.count_nonzero(self.used)),
            "n_failed": self.n_failed,
            "worst_ratio": self.worst_ratio,
            f"{self.x_name}_{self.x_unit}": [float(v) for v in self.x],
            "ratio": [float(v) for v in self.ratio],
            "inside": [bool(v) for v in self.inside],
            "passed": [bool(v) for v in self.passed],
            "used": [bool(v) for v in self.used],
            "warnings": list(self.warnings),
        }


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def check_fit(x: np.ndarray, measured: np.ndarray, low: np.ndarray, high: np.ndarray,
              fitted: np.ndarray, used: np.ndarray, *, statistic: float = math.nan,
              dof: int = 0, tolerance: float = DEFAULT_TOLERANCE,
              what: str = "Allan deviation", x_name: str = "tau",
              x_unit: str = "s") -> FitCheck:
    """Check a fitted curve against the measured one with its interval [low, high].

    All arrays have one entry per point (same shape). A non-finite fitted value fails.

    Examples
    --------
    >>> import numpy as np
    >>> m = np.array([2.0, 1.0])
    >>> chk = check_fit(np.array([0.1, 1.0]), m, m * 0.8, m * 1.2, m * 1.1,
    ...                 np.array([True, True]))
    >>> chk.holds, chk.warnings
    (True, ())
    """
    x = np.asarray(x, dtype=float)
    measured = np.asarray(measured, dtype=float)
    low = np.asarray(low, dtype=float)
    high = np.asarray(high, dtype=float)
    fitted = np.asarray(fitted, dtype=float)
    used = np.asarray(used, dtype=bool)
    shapes = {a.shape for a in (x, measured, low, high, fitted, used)}
    if len(shapes) != 1:
        raise GyrodriftValueError(f"check_fit needs arrays of one shape, got {sorted(shapes)}")
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = fitted / measured
    finite = np.isfinite(fitted) & np.isfinite(ratio) & (ratio > 0)
    inside = finite & (fitted >= low) & (fitted <= high)
    near = finite & (np.abs(np.log(np.where(finite, ratio, 1.0))) <= math.log1p(tolerance))
    passed = inside | near
    holds = bool(np.all(passed[used])) and bool(np.any(used))
    warnings: list[str] = []
    chk = FitCheck(what=what, x_name=x_name, x_unit=x_unit, x=x, ratio=ratio, inside=inside,
                   passed=passed, used=used, statistic=float(statistic), dof=int(dof),
                   tolerance=float(tolerance), holds=holds)
    if not np.any(used):
        warnings.append(f"model does not hold: no {x_name} was used in the fit")
    elif not holds:
        bad = used & ~passed
        r = np.where(bad & finite, ratio, np.nan)
        if np.any(np.isfinite(r)):
            i = int(np.nanargmax(np.abs(np.log(np.where(np.isfinite(r), r, 1.0)))))
            worst = f"worst {_fmt(float(ratio[i]))}x at {x_name} = {_fmt(float(x[i]))} {x_unit}"
        else:
            worst = "the fitted values are not finite"
        warnings.append(
            f"model does not hold: the fitted {what} leaves the measured one at "
            f"{int(np.count_nonzero(bad))} of {int(np.count_nonzero(used))} fitted {x_name} "
            f"({worst}); the values are approximate")
    object.__setattr__(chk, "warnings", tuple(warnings))
    return chk
