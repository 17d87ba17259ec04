"""Loading gyro records for analysis: .npy (memory-mapped when possible), .csv with a column
choice, and the replay harness's IMU logs (.bin/.gdf, .log candump, .asc, .blf; the IMU csv
with the replay columns is recognised by its header). Every record becomes a rate in deg/h.

Units (`units=`): rates "deg/h", "deg/s", "rad/s"; angle increments per sample "arcsec",
"deg", "rad" (divided by dt). NaN/Inf rows are never dropped silently: nan_policy="refuse"
(default) raises with their count, "drop" removes them and reports the count in
`Record.n_dropped` (dropping samples joins the neighbours in time; the caller decides whether
that is acceptable).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrodrift.errors import GyrodriftValueError

__all__ = ["RATE_UNITS", "UNITS", "Record", "load_record", "to_deg_h"]

RAD_TO_DEG = 180.0 / math.pi
#: rate unit -> factor to deg/h
RATE_UNITS: dict[str, float] = {"deg/h": 1.0, "deg/s": 3600.0, "rad/s": RAD_TO_DEG * 3600.0}
#: angle-increment unit -> factor to deg (divided by dt afterwards)
INCREMENT_UNITS: dict[str, float] = {"arcsec": 1.0 / 3600.0, "deg": 1.0, "rad": RAD_TO_DEG}
UNITS: tuple[str, ...] = (*RATE_UNITS, *INCREMENT_UNITS)
LOG_SUFFIXES = (".bin", ".gdf", ".log", ".asc", ".blf")
GYRO_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class Record:
    """A rate record in deg/h.

    rate_deg_h may be a read-only numpy.memmap (large .npy in deg/h without NaN), which the
    Allan code reads in chunks; use np.asarray(rate_deg_h) to load it.

    Examples
    --------
    >>> r = Record(np.zeros(10), 100.0, "x.npy", "0", "deg/h", 10, 0)
    >>> r.n, r.dt_s
    (10, 0.01)
    """

    rate_deg_h: np.ndarray
    rate_hz: float
    source: str
    column: str
    units_in: str
    n_total: int
    n_dropped: int

    @property
    def n(self) -> int:
        return int(self.rate_deg_h.shape[0])

    @property
    def dt_s(self) -> float:
        return 1.0 / self.rate_hz

    def summary(self) -> dict[str, object]:
        return {"source": self.source, "column": self.column, "units_in": self.units_in,
                "rate_hz": self.rate_hz, "n_total": self.n_total, "n_used": self.n,
                "n_dropped_nonfinite": self.n_dropped}


def to_deg_h(values: np.ndarray, units: str, rate_hz: float) -> np.ndarray:
    """Convert a rate or per-sample angle increment to deg/h (new float64 array).

    Examples
    --------
    >>> to_deg_h(np.array([1.0]), "deg/s", 100.0).tolist()
    [3600.0]
    >>> to_deg_h(np.array([1.0]), "arcsec", 100.0).tolist()  # 1 arcsec per sample at 100 Hz
    [100.0]
    """
    v = np.asarray(values, dtype=np.float64)
    if units in RATE_UNITS:
        return v * RATE_UNITS[units]
    if units in INCREMENT_UNITS:
        # increment [unit] per dt [s] -> deg/s -> deg/h
        return v * (INCREMENT_UNITS[units] * rate_hz * 3600.0)
    raise GyrodriftValueError(f"unknown units {units!r}; choose one of {', '.join(UNITS)}")


def _apply_nan_policy(x: np.ndarray, nan_policy: str, source: str) -> tuple[np.ndarray, int]:
    bad = ~np.isfinite(x)
    n_bad = int(np.count_nonzero(bad))
    if n_bad == 0:
        return x, 0
    if nan_policy == "drop":
        return x[~bad], n_bad
    raise GyrodriftValueError(
        f"{source}: {n_bad} of {x.size} samples are NaN/Inf; pass nan_policy='drop' "
        "(CLI: --drop-nan) to remove them explicitly"
    )


def _pick_column(names: list[str], column: str | int | None, source: str) -> int:
    if column is None:
        candidates = [i for i, n in enumerate(names) if n.lower() not in ("t", "t_s", "time")]
        if len(candidates) != 1:
            raise GyrodriftValueError(
                f"{source}: {len(names)} columns {names}; choose one with column=")
        return candidates[0]
    if isinstance(column, int) or (isinstance(column, str) and column.isdigit()):
        idx = int(column)
        if not 0 <= idx < len(names):
            raise GyrodriftValueError(f"{source}: column {idx} out of range (0..{len(names) - 1})")
        return idx
    if column not in names:
        raise GyrodriftValueError(f"{source}: no column {column!r}; columns are {names}")
    return names.index(column)


def _rate_from_time(t: np.ndarray, source: str) -> float:
    """Sample rate from a time column; gaps (missing samples) or steps back are an error,
    because Allan/PSD analysis assumes uniform sampling and would silently mis-time them."""
    t = t[np.isfinite(t)]
    if t.size < 2:
        raise GyrodriftValueError(f"{source}: cannot infer the sample rate from the time column")
    dt = np.diff(t)
    dt_med = float(np.median(dt))
    if not dt_med > 0:
        raise GyrodriftValueError(f"{source}: time column is not increasing")
    # 25 % slack covers timestamp rounding (e.g. 6-decimal CSV times, CAN log clocks).
    gaps = int(np.count_nonzero(dt > 1.25 * dt_med))
    backs = int(np.count_nonzero(dt < 0.75 * dt_med))
    if gaps or backs:
        raise GyrodriftValueError(
            f"{source}: non-uniform time column: {gaps} gaps (missing samples) "
            f"and {backs} short or backward steps against the median step "
            f"{dt_med:.6g} s; Allan/PSD analysis needs uniform sampling")
    return 1.0 / dt_med


def load_record(
    path: str | Path,
    *,
    column: str | int | None = None,
    rate_hz: float | None = None,
    units: str = "deg/h",
    nan_policy: str = "refuse",
    mmap: bool = True,
) -> Record:
    """Load one gyro channel as a rate in deg/h (module docstring).

    column: .csv column name or index; .npy column index of a 2-D array; for IMU logs the
    gyro axis "x", "y", "z" (default "z"). rate_hz: required for .npy; for .csv it is taken
    from a t_s/time column when not given; for logs from the timestamps.

    Examples
    --------
    >>> import tempfile, os
    >>> path = os.path.join(tempfile.mkdtemp(), "rate.npy")
    >>> np.save(path, np.full(100, 3.0))
    >>> rec = load_record(path, rate_hz=10.0, units="deg/s")
    >>> rec.n, float(rec.rate_deg_h[0])  # deg/s -> deg/h
    (100, 10800.0)
    """
    p = Path(path)
    source = str(p)
    if not p.exists():
        raise FileNotFoundError(f"no such file: {p}")
    if nan_policy not in ("refuse", "drop"):
        raise GyrodriftValueError(f"nan_policy must be 'refuse' or 'drop', got {nan_policy!r}")
    if units not in UNITS:
        raise GyrodriftValueError(f"unknown units {units!r}; choose one of {', '.join(UNITS)}")
    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0):
        raise GyrodriftValueError(f"rate must be positive and finite, got {rate_hz!r}")
    suffix = p.suffix.lower()
    header_names: list[str] | None = None
    if suffix == ".csv":
        with p.open(newline="") as fh:
            first = next(csv.reader(fh), None)
        if first is None:
            raise GyrodriftValueError(f"{source}: empty file")
        header_names = [c.strip() for c in first]
    is_replay_csv = header_names is not None and "gyro_z_rad_s" in header_names
    if suffix in LOG_SUFFIXES or is_replay_csv:
        return _load_log(p, column, rate_hz, units, nan_policy)
    if suffix == ".npy":
        arr = np.load(p, mmap_mode="r" if mmap else None, allow_pickle=False)
        if arr.ndim == 2:
            idx = 0 if column is None and arr.shape[1] == 1 else None
            if idx is None:
                if column is None:
                    raise GyrodriftValueError(
                        f"{source}: array of shape {arr.shape}; choose a column")
                idx = _pick_column([str(i) for i in range(arr.shape[1])], column, source)
            col_name = str(idx)
            values = np.asarray(arr[:, idx])
        elif arr.ndim == 1:
            if column not in (None, 0, "0"):
                raise GyrodriftValueError(f"{source}: 1-D array has no column {column!r}")
            col_name = "0"
            values = arr
        else:
            raise GyrodriftValueError(
                f"{source}: expected a 1-D or 2-D array, got shape {arr.shape}")
        if not np.issubdtype(values.dtype, np.floating) and not np.issubdtype(
                values.dtype, np.integer):
            raise GyrodriftValueError(f"{source}: expected numbers, got dtype {values.dtype}")
        if rate_hz is None:
            raise GyrodriftValueError(f"{source}: a .npy record carries no sample rate; "
                             "give --rate-hz (rate_hz=)")
        n_total = int(values.shape[0])
        keep_mapped = (isinstance(values, np.memmap) and units == "deg/h"
                       and values.dtype == np.float64)
        if keep_mapped:
            n_bad = _count_nonfinite_chunked(values)
            if n_bad == 0:
                return Record(values, float(rate_hz), source, col_name, units, n_total, 0)
        x = to_deg_h(np.asarray(values), units, rate_hz)
        x, dropped = _apply_nan_policy(x, nan_policy, source)
        return Record(x, float(rate_hz), source, col_name, units, n_total, dropped)
    if suffix == ".csv":
        assert header_names is not None
        has_header = not all(_is_number(c) for c in header_names)
        names = header_names if has_header else [str(i) for i in range(len(header_names))]
        idx = _pick_column(names, column, source)
        try:
            # Rows with a wrong number of fields are an error (never dropped silently);
            # unparseable cells become NaN and go through the NaN policy.
            table = np.genfromtxt(p, delimiter=",", skip_header=1 if has_header else 0,
                                  dtype=np.float64, invalid_raise=True, ndmin=2)
        except ValueError as exc:
            detail = "; ".join(part.strip() for part in str(exc).splitlines() if part.strip())
            raise GyrodriftValueError(f"{source}: malformed CSV: {detail}") from exc
        if table.size == 0:
            raise GyrodriftValueError(f"{source}: no data rows")
        if table.shape[1] != len(names):
            raise GyrodriftValueError(f"{source}: rows have {table.shape[1]} fields, header has "
                             f"{len(names)}")
        values = table[:, idx]
        if rate_hz is None:
            t_idx = next((i for i, n in enumerate(names) if n.lower() in ("t_s", "time", "t")),
                         None)
            if t_idx is None:
                raise GyrodriftValueError(f"{source}: no t_s/time column to infer the rate; "
                                 "give --rate-hz (rate_hz=)")
            rate_hz = _rate_from_time(table[:, t_idx], source)
        x = to_deg_h(values, units, rate_hz)
        x, dropped = _apply_nan_policy(x, nan_policy, source)
        return Record(x, float(rate_hz), source, names[idx], units, int(values.size), dropped)
    raise GyrodriftValueError(
        f"{source}: unsupported file type {suffix!r} (use .npy, .csv, or an IMU "
        f"log {', '.join(LOG_SUFFIXES)})")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _count_nonfinite_chunked(values: np.ndarray, chunk: int = 1 << 22) -> int:
    n_bad = 0
    for lo in range(0, values.shape[0], chunk):
        n_bad += int(np.count_nonzero(~np.isfinite(values[lo:lo + chunk])))
    return n_bad


def _load_log(p: Path, column: str | int | None, rate_hz: float | None, units: str,
              nan_policy: str) -> Record:
    from gyrodrift.replay.logs import read_imu_log  # the "replay" area's reader

    axis_name = "z" if column is None else str(column).lower()
    if axis_name not in GYRO_AXES:
        raise GyrodriftValueError(f"{p}: IMU logs hold gyro axes x, y, z; got column {column!r}")
    samples = read_imu_log(p)
    gyro_rad_s = samples.channels[:, GYRO_AXES[axis_name]].astype(np.float64)
    if rate_hz is None:
        rate_hz = _rate_from_time(samples.t_s, str(p))
    log_units = "rad/s" if units == "deg/h" else units  # logs carry rad/s unless told
    x = to_deg_h(gyro_rad_s, log_units, rate_hz)
    x, dropped = _apply_nan_policy(x, nan_policy, str(p))
    return Record(x, float(rate_hz), str(p), f"gyro_{axis_name}", log_units,
                  int(gyro_rad_s.size), dropped)
