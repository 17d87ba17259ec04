"""Reading a published Allan-deviation curve (another tool's output, a datasheet's table) so
that it can be fitted like a measured one (`gyrodrift allan --curve`).

Format: CSV (comma, semicolon or whitespace separated) with a header line naming the columns:

- ``tau_s`` (also ``tau``, ``t``, ``taus``): averaging time, s;
- ``adev`` (also ``sigma``, ``dev``, ``oadev``, ``allan_deviation``): the Allan deviation, in
  the units the caller states;
- optional ``edf``: the equivalent degrees of freedom of each point; or optional ``count``
  (also ``n``, ``ns``, ``clusters``, ``num_clusters``): the number of clusters (averages) of
  length tau in the record, from which edf = count - 1 (the non-overlapping estimator's; the
  overlapping one has more, so the intervals are conservative);
- without either, the record length ``duration_s`` gives count = floor(duration_s / tau).

Lines starting with ``#`` are comments. allantools' output (taus, devs, errors, ns) written
as columns ``tau_s,adev,adev_error,n`` reads as is (``n``: its count of terms, used as the
count).

Examples
--------
>>> import os, tempfile
>>> path = os.path.join(tempfile.mkdtemp(), "curve.csv")
>>> _ = open(path, "w").write("tau_s,adev,count\\n1,0.5,1000\\n10,0.16,100\\n100,0.05,10\\n")
>>> c = read_allan_curve(path, units="deg/s")
>>> c.adev.tolist(), c.edf.tolist(), c.edf_from
([1800.0, 576.0, 180.0], [999.0, 99.0, 9.0], 'count')
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.units import ACCEL_UNITS, RATE_UNITS

__all__ = ["CURVE_UNITS", "AllanCurve", "read_allan_curve"]

#: Units an Allan-deviation curve may be in: gyro rates (converted to deg/h) or
#: accelerations (converted to m/s^2).
CURVE_UNITS: tuple[str, ...] = (*RATE_UNITS, *ACCEL_UNITS)

_TAU = ("tau_s", "tau", "t", "taus", "tau (s)")
_ADEV = ("adev", "sigma", "dev", "oadev", "allan_deviation", "devs")
_EDF = ("edf",)
_COUNT = ("count", "n", "ns", "clusters", "num_clusters", "n_clusters")


@dataclass(frozen=True, eq=False)
class AllanCurve:
    """A published Allan-deviation curve in the package's units.

    Attributes
    ----------
    tau_s
        averaging times, s (increasing).
    adev
        Allan deviation, deg/h (gyro) or m/s^2 (accelerometer).
    edf
        equivalent degrees of freedom per point.
    sensor
        "gyro" or "accel".
    unit
        "deg/h" or "m/s^2".
    units_in
        the file's unit.
    edf_from
        "edf", "count" or "duration" (where the edf came from).
    source
        the file.

    Examples
    --------
    >>> c = AllanCurve(np.array([1.0]), np.array([2.0]), np.array([9.0]), "gyro", "deg/h",
    ...                "deg/h", "edf", "x.csv")
    >>> c.as_dict()["edf"]
    [9.0]
    """

    tau_s: np.ndarray
    adev: np.ndarray
    edf: np.ndarray
    sensor: str
    unit: str
    units_in: str
    edf_from: str
    source: str

    def as_dict(self) -> dict[str, object]:
        return {"source": self.source, "sensor": self.sensor, "unit": self.unit,
                "units_in": self.units_in, "edf_from": self.edf_from,
                "tau_s": self.tau_s.tolist(), "adev": self.adev.tolist(),
                "edf": self.edf.tolist()}


def _find(names: list[str], wanted: tuple[str, ...]) -> int | None:
    for i, n in enumerate(names):
        if n in wanted:
            return i
    return None


def read_allan_curve(path: str | Path, *, units: str,
                     duration_s: float | None = None) -> AllanCurve:
    """Read an Allan-deviation curve (module docstring) in `units` (one of CURVE_UNITS).

    Raises
    ------
    GyrodriftValueError
        unknown units, no header, missing columns, non-positive or non-increasing taus,
        non-finite values, fewer than 3 points, no count/edf and no `duration_s`.

    Examples
    --------
    >>> import os, tempfile
    >>> path = os.path.join(tempfile.mkdtemp(), "c.txt")
    >>> _ = open(path, "w").write("# a curve\\ntau adev\\n1 1e-3\\n2 7e-4\\n4 5e-4\\n")
    >>> c = read_allan_curve(path, units="m/s^2", duration_s=40.0)
    >>> c.sensor, c.edf.tolist()
    ('accel', [39.0, 19.0, 9.0])
    """
    p = Path(path)
    if units not in CURVE_UNITS:
        raise GyrodriftValueError(f"curve units must be one of {', '.join(CURVE_UNITS)}, "
                                  f"got {units!r}")
    if not p.is_file():
        raise FileNotFoundError(f"no such file: {p}")
    lines = [ln.strip() for ln in p.read_text(errors="replace").splitlines()]
    lines = [ln for ln in lines if ln and not ln.startswith("#")]
    if not lines:
        raise GyrodriftValueError(f"{p}: no data")
    split = re.compile(r"[,;\s]+")
    names = [n.strip().strip('"').lower() for n in split.split(lines[0]) if n.strip()]
    i_tau, i_dev = _find(names, _TAU), _find(names, _ADEV)
    if i_tau is None or i_dev is None:
        raise GyrodriftValueError(
            f"{p}: the header {names} needs a tau column ({', '.join(_TAU)}) and an Allan "
            f"deviation column ({', '.join(_ADEV)})")
    i_edf, i_count = _find(names, _EDF), _find(names, _COUNT)
    rows = []
    for k, ln in enumerate(lines[1:], start=2):
        cells = [c for c in split.split(ln) if c]
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            raise GyrodriftValueError(f"{p}: data line {k}: not numbers: {ln!r}") from None
        if len(cells) != len(names):
            raise GyrodriftValueError(f"{p}: data line {k} has {len(cells)} values for "
                                      f"{len(names)} columns")
    if len(rows) < 3:
        raise GyrodriftValueError(f"{p}: {len(rows)} points; a fit needs at least 3")
    arr = np.asarray(rows, dtype=np.float64)
    tau, dev = arr[:, i_tau], arr[:, i_dev]
    if not (np.all(np.isfinite(tau)) and np.all(np.isfinite(dev))):
        raise GyrodriftValueError(f"{p}: tau and adev must be finite")
    if np.any(tau <= 0) or np.any(np.diff(tau) <= 0):
        raise GyrodriftValueError(f"{p}: taus must be positive and increasing")
    if np.any(dev < 0):
        raise GyrodriftValueError(f"{p}: an Allan deviation cannot be negative")
    if i_edf is not None:
        edf, edf_from = arr[:, i_edf], "edf"
    elif i_count is not None:
        edf, edf_from = arr[:, i_count] - 1.0, "count"
    elif duration_s is not None:
        if not (math.isfinite(duration_s) and duration_s > 0):
            raise GyrodriftValueError(f"duration must be positive, got {duration_s!r}")
        edf, edf_from = np.floor(duration_s / tau) - 1.0, "duration"
    else:
        raise GyrodriftValueError(
            f"{p}: no edf or count column: give the length of the record the curve came "
            "from (command line: --duration-s) so that each point's degrees of freedom are "
            "known")
    if not np.all(np.isfinite(edf)) or np.any(edf < 1.0):
        raise GyrodriftValueError(
            f"{p}: every point needs at least 2 clusters (edf >= 1); the longest tau "
            f"{tau[-1]:g} s has edf {edf[-1]:g}")
    if units in RATE_UNITS:
        sensor, unit, f = "gyro", "deg/h", RATE_UNITS[units].to_deg_h
    else:
        sensor, unit, f = "accel", "m/s^2", ACCEL_UNITS[units]
    return AllanCurve(tau, dev * f, edf, sensor, unit, units, edf_from, str(p))
