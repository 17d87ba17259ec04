"""Loading gyro records for analysis: .npy (memory-mapped when possible), .csv with a column
choice, and the replay harness's IMU logs (.bin/.gdf, .log candump, .asc, .blf; the IMU csv
with the replay columns is recognised by its header), and the PSINS `.imu` text log (gyro
angle increments, `gyrodrift.io.psins`). Every record becomes a rate in deg/h. Six-channel
records (gyro and accelerometer) are read by `gyrodrift.io.imu_data.load_imu`.

Units (`units=`): rates "deg/h", "deg/s", "rad/s"; angle increments per sample "arcsec",
"deg", "rad" (divided by dt). NaN/Inf rows are never dropped silently: nan_policy="refuse"
(default) raises with their count, "drop" removes them and reports the count in
`Record.n_dropped` (dropping samples joins the neighbours in time; the caller decides whether
that is acceptable).
"""

from __future__ import annotations

import csv
import math
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrodrift.defaults import RATE_MAX_HZ as _RATE_MAX_HZ
from gyrodrift.defaults import RATE_MIN_HZ as _RATE_MIN_HZ
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.io.spool import (
    BLOCK_ROWS,
    SampleSpool,
    chunked_median,
    iter_row_blocks,
    iter_text_tables,
)
from gyrodrift.units import (
    DEFAULT_TIME_UNITS,
    GYRO_INPUT_UNITS,
    INCREMENT_UNITS,
    RATE_UNITS,
    TIME_UNITS,
)

__all__ = ["UNITS", "Record", "is_file_backed", "is_number", "iter_chunks", "load_npy",
           "load_record", "rate_from_time", "to_deg_h"]

#: The input units a gyro record may be in (gyrodrift.units: rates, then angle increments).
UNITS: tuple[str, ...] = GYRO_INPUT_UNITS
LOG_SUFFIXES = (".bin", ".gdf", ".log", ".asc", ".blf")
GYRO_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class Record:
    """A rate record in deg/h.

    rate_deg_h may be a read-only numpy.memmap (a 1-D float64 .npy in deg/h without NaN, or
    a record of 2^20 samples or more normalized into a temporary file: `load_record`), which
    the analyses read in chunks; use np.asarray(rate_deg_h) to load it.

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
    # CAN logs: one line on where every frame of the capture went (CanLogReport.summary).
    log_summary: str = ""

    @property
    def n(self) -> int:
        return int(self.rate_deg_h.shape[0])

    @property
    def dt_s(self) -> float:
        return 1.0 / self.rate_hz

    def summary(self) -> dict[str, object]:
        return {"source": self.source, "column": self.column, "units_in": self.units_in,
                "rate_hz": self.rate_hz, "n_total": self.n_total, "n_used": self.n,
                "n_dropped_nonfinite": self.n_dropped,
                **({"log": self.log_summary} if self.log_summary else {})}


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
        return v * RATE_UNITS[units].to_deg_h
    if units in INCREMENT_UNITS:
        # increment [unit] per dt [s] -> deg/s -> deg/h
        return v * (INCREMENT_UNITS[units].to_deg_h * rate_hz * 3600.0)
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
            raise GyrodriftValueError(f"{source}: {len(names)} columns {names}; choose one with "
                             "--column")
        return candidates[0]
    if isinstance(column, int) or (isinstance(column, str) and column.isdigit()):
        idx = int(column)
        if not 0 <= idx < len(names):
            raise GyrodriftValueError(f"{source}: column {idx} out of range (0..{len(names) - 1})")
        return idx
    if column not in names:
        raise GyrodriftValueError(f"{source}: no column {column!r}; columns are {names}")
    return names.index(column)


def rate_from_time(t: np.ndarray, source: str, *, time_units: str | None = None) -> float:
    """Sample rate from a time column; gaps (missing samples) or steps back are an error,
    because Allan/PSD analysis assumes uniform sampling and would silently mis-time them.
    ``time_units``: the units of ``t`` ("s", "ms", "us", "ns"; seconds when None), given by
    the text readers so that an error can name the units the column's step suggests. The
    rate must lie within RATE_MIN_HZ..RATE_MAX_HZ (the range a given --rate-hz has) and the
    times within MAX_TIME_S: a time column in other units than the reader assumed fails one
    of them. The steps are taken from the first time (exact for integer counts of ms, us or
    ns since an epoch) before they are scaled to seconds.

    Examples
    --------
    >>> rate_from_time(np.arange(5) * 0.01, "log.csv")  # seconds in, Hz out
    100.0
    >>> rate_from_time(np.arange(5) * 1e7, "log.csv", time_units="s")  # nanoseconds
    Traceback (most recent call last):
    ...
    gyrodrift.errors.GyrodriftValueError: log.csv: time step 1e+07 s gives ... looks like
    nanoseconds (100 Hz): give --time-units ns (time_units='ns')
    """
    if is_file_backed(t):
        return _rate_from_time_file(t, source, time_units)
    t = np.asarray(t, dtype=np.float64)
    t = t[np.isfinite(t)]
    if t.size < 2:
        raise GyrodriftValueError(f"{source}: cannot infer the sample rate from the time column")
    f = TIME_UNITS[time_units or "s"]
    dt = np.diff(t - t[0]) * f
    dt_med = float(np.median(dt))
    if not dt_med > 0:
        raise GyrodriftValueError(f"{source}: time column is not increasing")
    _check_time_scale(dt_med, float(np.max(np.abs(t[[0, -1]]))) * f, source, time_units)
    # 25 % slack covers timestamp rounding (e.g. 6-decimal CSV times, CAN log clocks).
    gaps = int(np.count_nonzero(dt > 1.25 * dt_med))
    backs = int(np.count_nonzero(dt < 0.75 * dt_med))
    if gaps or backs:
        raise GyrodriftValueError(
            f"{source}: non-uniform time column: {gaps} gaps (missing samples) "
            f"and {backs} short or backward steps against the median step "
            f"{dt_med:.6g} s; Allan/PSD analysis needs uniform sampling")
    return 1.0 / dt_med


def _rate_from_time_file(t: np.ndarray, source: str, time_units: str | None) -> float:
    """`rate_from_time` of a file-backed time column (:func:`is_file_backed`), read in
    pieces: the same steps, median (`gyrodrift.io.spool.chunked_median`, exact), checks and
    messages, in memory independent of the record's length."""
    first = last = 0.0
    n_finite = 0
    for piece in iter_chunks(t, BLOCK_ROWS):
        fin = piece[np.isfinite(piece)]
        if fin.size:
            first = float(fin[0]) if n_finite == 0 else first
            last = float(fin[-1])
            n_finite += int(fin.size)
    if n_finite < 2:
        raise GyrodriftValueError(f"{source}: cannot infer the sample rate from the time column")
    f = TIME_UNITS[time_units or "s"]

    def steps() -> Iterator[np.ndarray]:
        prev: np.ndarray | None = None  # the last time of the previous piece, minus the first
        for piece in iter_chunks(t, BLOCK_ROWS):
            u = piece[np.isfinite(piece)] - first
            if prev is not None:
                u = np.concatenate((prev, u))
            if u.size:
                prev = u[-1:]
            if u.size > 1:
                yield np.diff(u) * f

    dt_med = chunked_median(steps)
    if not dt_med > 0:
        raise GyrodriftValueError(f"{source}: time column is not increasing")
    _check_time_scale(dt_med, max(abs(first), abs(last)) * f, source, time_units)
    gaps = backs = 0
    for dt in steps():
        gaps += int(np.count_nonzero(dt > 1.25 * dt_med))
        backs += int(np.count_nonzero(dt < 0.75 * dt_med))
    if gaps or backs:
        raise GyrodriftValueError(
            f"{source}: non-uniform time column: {gaps} gaps (missing samples) "
            f"and {backs} short or backward steps against the median step "
            f"{dt_med:.6g} s; Allan/PSD analysis needs uniform sampling")
    return 1.0 / dt_med


#: Times beyond this (about 3000 years) are no record's: a time column in ms, us or ns (an
#: epoch count, or a long record from zero) read as seconds.
MAX_TIME_S = 1e11
_TIME_UNIT_NAMES = {"s": "seconds", "ms": "milliseconds", "us": "microseconds",
                    "ns": "nanoseconds"}
#: The rates a hint about the time column's units considers plausible for an IMU record.
_HINT_RATE_HZ = (1e-2, 1e6)


def _check_time_scale(dt_s: float, t_max_s: float, source: str, time_units: str | None) -> None:
    """Refuse a time column whose step or values no record has (module docstring)."""
    rate = 1.0 / dt_s
    if RATE_MIN_HZ <= rate <= RATE_MAX_HZ and t_max_s <= MAX_TIME_S:
        return
    if not RATE_MIN_HZ <= rate <= RATE_MAX_HZ:
        what = (f"time step {dt_s:.6g} s gives a sample rate of {rate:.3g} Hz, outside "
                f"{RATE_MIN_HZ:g}..{RATE_MAX_HZ:g} Hz")
    else:
        what = f"times up to {t_max_s:.6g} s ({t_max_s / 3.15576e7:.3g} years)"
    hint = ""
    if time_units is not None:
        raw_dt, raw_max = dt_s / TIME_UNITS[time_units], t_max_s / TIME_UNITS[time_units]
        best: tuple[float, str, float] | None = None
        for u, f in TIME_UNITS.items():
            r = 1.0 / (raw_dt * f)
            if (u != time_units and _HINT_RATE_HZ[0] <= r <= _HINT_RATE_HZ[1]
                    and raw_max * f <= MAX_TIME_S):
                score = abs(math.log10(r / 300.0))  # typical IMU rates: 100 Hz .. 1 kHz
                if best is None or score < best[0]:
                    best = (score, u, r)
        if best is not None:
            hint = (f"; the time column looks like {_TIME_UNIT_NAMES[best[1]]} "
                    f"({best[2]:.3g} Hz): give --time-units {best[1]} (time_units={best[1]!r})")
        else:
            hint = "; check the units of the time column (--time-units, time_units=)"
    raise GyrodriftValueError(f"{source}: {what}{hint}")


def load_record(
    path: str | Path,
    *,
    column: str | int | None = None,
    rate_hz: float | None = None,
    units: str = "deg/h",
    nan_policy: str = "refuse",
    mmap: bool = True,
    can_signals: str | Path | None = None,
    force_rate: bool = False,
    time_units: str = DEFAULT_TIME_UNITS,
) -> Record:
    """Load one gyro channel as a rate in deg/h (module docstring).

    column: .csv column name or index; .npy column index of a 2-D array; for IMU logs the
    gyro axis "x", "y", "z" (default "z"). rate_hz: required for .npy; for .csv it is taken
    from a t_s/time column when not given; for logs from the timestamps. can_signals: a CAN
    log in a user's own DBC, read through this signal map (gyrodrift.codecs.can_signals).
    A rate_hz that contradicts the file's own time column (by more than 1 %) is refused
    unless force_rate. time_units: the units of a .csv record's time column ("s", "ms", "us",
    "ns"; gyrodrift.units.TIME_UNITS); the rate it gives is checked like a given rate_hz, so
    nanoseconds read as seconds are refused, naming the units the step suggests. Only
    regular files are read (a FIFO or device would block or never end).

    mmap: a 1-D float64 .npy record in deg/h without NaN/Inf is returned memory-mapped; any
    other .npy or .csv record, IMU log or PSINS .imu log of
    gyrodrift.io.spool.SPOOL_MIN_SAMPLES (2^20) samples or more is converted in blocks of
    rows (a .csv or .imu parsed in blocks of lines, a log decoded in blocks) into a float64
    file in a temporary directory (8 bytes per sample; a .csv's or log's column and time
    column too while it is read) and returned memory-mapped; the directory goes when no
    array refers to the map any more. The values are those of the conversion in memory.
    With mmap=False every record is returned in memory.

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
    _check_load_args(p, units, nan_policy, rate_hz)
    if time_units not in TIME_UNITS:
        raise GyrodriftValueError(f"unknown time units {time_units!r}; choose one of "
                                  f"{', '.join(TIME_UNITS)}")
    suffix = p.suffix.lower()
    header_names, delimiter = _read_csv_header(p) if suffix == ".csv" else (None, ",")
    is_replay_csv = header_names is not None and "gyro_z_rad_s" in header_names
    if can_signals is not None and suffix not in (".log", ".asc", ".blf"):
        raise GyrodriftValueError(f"{p}: a DBC signal map applies to CAN logs "
                                  "(.log, .asc, .blf)")
    if time_units != DEFAULT_TIME_UNITS and (suffix != ".csv" or is_replay_csv):
        raise GyrodriftValueError(f"{p}: --time-units (time_units=) applies to the time column "
                                  "of a text record; this file carries its own time base")
    if suffix in LOG_SUFFIXES or is_replay_csv:
        return _load_log(p, column, rate_hz, units, nan_policy, can_signals, force_rate, mmap)
    if suffix == ".imu":
        return _load_psins(p, column, rate_hz, units, nan_policy, mmap)
    if suffix == ".npy":
        return _load_npy_record(p, column, rate_hz, units, nan_policy, mmap)
    if suffix == ".csv":
        assert header_names is not None
        return _load_csv_record(p, header_names, delimiter, column, rate_hz, units, nan_policy,
                                force_rate, time_units, mmap)
    raise GyrodriftValueError(
        f"{p}: unsupported file type {suffix!r} (use .npy, .csv, PSINS .imu, "
        f"or an IMU log {', '.join(LOG_SUFFIXES)})")


def _check_load_args(p: Path, units: str, nan_policy: str, rate_hz: float | None) -> None:
    """Refuse what no reader can use: a missing path or one that is not a regular file (a
    FIFO or device would block or never end), an unknown NaN policy or unit, a sample rate
    outside RATE_MIN_HZ..RATE_MAX_HZ."""
    if not p.exists():
        raise FileNotFoundError(f"no such file: {p}")
    if not p.is_file():
        raise GyrodriftValueError(f"{p}: not a regular file (a directory, FIFO or device); "
                                  "give a record file")
    if nan_policy not in ("refuse", "drop"):
        raise GyrodriftValueError(f"nan_policy must be 'refuse' or 'drop', got {nan_policy!r}")
    if units not in UNITS:
        raise GyrodriftValueError(f"unknown units {units!r}; choose one of {', '.join(UNITS)}")
    if rate_hz is not None and not (math.isfinite(rate_hz)
                                    and RATE_MIN_HZ <= rate_hz <= RATE_MAX_HZ):
        raise GyrodriftValueError(
            f"sample rate must be within {RATE_MIN_HZ:g}..{RATE_MAX_HZ:g} Hz, "
            f"got {rate_hz!r}")


def _read_csv_header(p: Path) -> tuple[list[str], str]:
    """The first line of a .csv split into cells, and the delimiter: ',' or, for the
    spreadsheet export of locales with a decimal comma, ';'."""
    try:
        with p.open(newline="", encoding="utf-8-sig") as fh:  # a byte-order mark is no name
            first_line = fh.readline()
    except UnicodeDecodeError as exc:
        raise GyrodriftValueError(
            f"{p}: not a text CSV file (byte {exc.start} is not UTF-8; "
            "a binary file named .csv?)") from None
    if not first_line.strip():
        raise GyrodriftValueError(f"{p}: empty file (no header or data line first)")
    delimiter = ";" if "," not in first_line and ";" in first_line else ","
    return [c.strip() for c in next(csv.reader([first_line], delimiter=delimiter))], delimiter


def _load_npy_record(p: Path, column: str | int | None, rate_hz: float | None, units: str,
                     nan_policy: str, mmap: bool) -> Record:
    """One column of a 1-D or 2-D .npy array. A float64 deg/h 1-D array without NaN stays
    memory-mapped (read in chunks by the Allan code); anything else is normalized in blocks
    of rows (`_normalize`): in memory, or with `mmap` and SPOOL_MIN_SAMPLES samples or
    more, into a temporary file that is memory-mapped in turn."""
    source = str(p)
    arr = load_npy(p, mmap)
    if arr.ndim == 2:
        idx = 0 if column is None and arr.shape[1] == 1 else None
        if idx is None:
            if column is None:
                raise GyrodriftValueError(
                    f"{source}: array of shape {arr.shape}; choose a column")
            idx = _pick_column([str(i) for i in range(arr.shape[1])], column, source)
        col_name = str(idx)
    elif arr.ndim == 1:
        if column not in (None, 0, "0"):
            raise GyrodriftValueError(f"{source}: 1-D array has no column {column!r}")
        col_name, idx = "0", None
    else:
        raise GyrodriftValueError(
            f"{source}: expected a 1-D or 2-D array, got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.floating) and not np.issubdtype(
            arr.dtype, np.integer):
        raise GyrodriftValueError(f"{source}: expected numbers, got dtype {arr.dtype}")
    if rate_hz is None:
        raise GyrodriftValueError(f"{source}: a .npy record carries no sample rate; "
                                  "give --rate-hz (rate_hz=)")
    n_total = int(arr.shape[0])
    keep_mapped = (isinstance(arr, np.memmap) and idx is None and units == "deg/h"
                   and arr.dtype == np.float64)
    if keep_mapped:
        n_bad = _count_nonfinite_chunked(arr)
        if n_bad == 0:
            return Record(arr, float(rate_hz), source, col_name, units, n_total, 0)
        if nan_policy != "drop":
            _refuse_nonfinite(source, n_bad, n_total)
    pieces = (block if idx is None else block[:, idx] for block in iter_row_blocks(arr))
    x, dropped = _normalize(pieces, n_total, units, float(rate_hz), nan_policy, source, mmap)
    return Record(x, float(rate_hz), source, col_name, units, n_total, dropped)


def _refuse_nonfinite(source: str, n_bad: int, n_total: int) -> None:
    raise GyrodriftValueError(
        f"{source}: {n_bad} of {n_total} samples are NaN/Inf; pass nan_policy='drop' "
        "(CLI: --drop-nan) to remove them explicitly"
    )


def _normalize(pieces: Iterable[np.ndarray], n_total: int, units: str, rate_hz: float,
               nan_policy: str, source: str, mmap: bool) -> tuple[np.ndarray, int]:
    """The record's consecutive pieces converted to deg/h (`to_deg_h`, sample by sample)
    with the NaN policy applied (`_apply_nan_policy`: refused with their count, or dropped
    and counted), kept in memory, or with `mmap` from SPOOL_MIN_SAMPLES samples on in a
    temporary file returned memory-mapped (gyrodrift.io.spool; bounded memory). The same
    values as converting the whole record at once."""
    n_bad = 0
    with SampleSpool(None if mmap else sys.maxsize, name="rate_deg_h") as spool:
        for piece in pieces:
            x = to_deg_h(piece, units, rate_hz)
            good = np.isfinite(x)
            bad = x.size - int(np.count_nonzero(good))
            if bad:
                n_bad += bad
                x = x[good]
            if n_bad and nan_policy != "drop":
                continue  # counted, never kept
            spool.append(x)
        if n_bad and nan_policy != "drop":
            _refuse_nonfinite(source, n_bad, n_total)
        return spool.finish(), n_bad


def _load_csv_record(p: Path, header_names: list[str], delimiter: str,
                     column: str | int | None, rate_hz: float | None, units: str,
                     nan_policy: str, force_rate: bool, time_units: str, mmap: bool) -> Record:
    """One column of a .csv (header optional); the rate from its t_s/time/t column (in
    `time_units`) unless given (and checked against it, _resolve_rate). The table is parsed
    in blocks of lines (gyrodrift.io.spool.iter_text_tables); the column and the time column
    are kept in memory, or with `mmap` from SPOOL_MIN_SAMPLES rows on in temporary files
    (8 bytes per row each, while the record is read) that are then normalized like a .npy
    record's column."""
    source = str(p)
    has_header = not all(is_number(c) for c in header_names)
    names = header_names if has_header else [str(i) for i in range(len(header_names))]
    idx = _pick_column(names, column, source)
    t_idx = next((i for i, n in enumerate(names) if n.lower() in ("t_s", "time", "t")), None)
    memory_max = None if mmap else sys.maxsize
    with SampleSpool(memory_max, name="values") as raw, \
            SampleSpool(memory_max, name="time") as t_spool:
        _read_csv_columns(p, delimiter, 1 if has_header else 0, names, idx, t_idx, raw,
                          t_spool)
        values, t = raw.finish(), t_spool.finish()
    if t_idx is None:
        if rate_hz is None:
            raise GyrodriftValueError(f"{source}: no t_s/time column to infer the rate; "
                                      "give --rate-hz (rate_hz=)")
    else:
        rate_hz = _resolve_rate(rate_hz, t, source, force_rate, time_units)
    del t  # its temporary file goes with the last reference
    n_total = int(values.size)
    x, dropped = _normalize(iter_chunks(values, BLOCK_ROWS), n_total, units, rate_hz,
                            nan_policy, source, mmap)
    return Record(x, float(rate_hz), source, names[idx], units, n_total, dropped)


def _read_csv_columns(p: Path, delimiter: str, skip: int, names: list[str], idx: int,
                      t_idx: int | None, out: SampleSpool, t_out: SampleSpool) -> None:
    """Column `idx` (and the time column `t_idx`) of a .csv's numbers, appended block by
    block to `out` (`t_out`). Rows with a wrong number of fields are an error (never dropped
    silently); unparseable cells become NaN in the parse and are named by
    _check_text_cells."""
    n_rows = 0
    try:
        with p.open(encoding="utf-8-sig") as fh:
            for _ in range(skip):
                next(fh, None)
            for table, lines, line_no in iter_text_tables(
                    fh, delimiter=delimiter, first_line_no=skip + 1,
                    malformed=f"{p}: malformed CSV"):
                if table.shape[0] == 0:
                    continue
                if table.shape[1] != len(names):
                    raise GyrodriftValueError(f"{p}: rows have {table.shape[1]} fields, header "
                                              f"has {len(names)}")
                _check_text_cells(p, table, [i for i in (idx, t_idx) if i is not None], names,
                                  delimiter, lines, line_no)
                out.append(table[:, idx])
                if t_idx is not None:
                    t_out.append(table[:, t_idx])
                n_rows += table.shape[0]
    except UnicodeDecodeError as exc:
        raise GyrodriftValueError(
            f"{p}: not a text CSV file (byte {exc.start} of a line is "
            "not UTF-8; a binary file named .csv?)") from None
    if n_rows == 0:
        raise GyrodriftValueError(f"{p}: no data rows (header only?)")


#: sample rates accepted from the user or a file (gyrodrift.defaults: outside them the
#: analyses' fits overflow)
RATE_MIN_HZ = _RATE_MIN_HZ
RATE_MAX_HZ = _RATE_MAX_HZ


def _resolve_rate(given: float | None, t: np.ndarray, source: str, force: bool,
                  time_units: str | None = None) -> float:
    """The rate to use: the time column's (in time_units; s when None), or the user's if it
    agrees within 1 % (or force; or when the time column gives no rate at all, e.g. it has
    gaps)."""
    if given is not None and force:
        return float(given)
    try:
        from_time = rate_from_time(t, source, time_units=time_units)
    except ValueError:
        if given is not None:
            return float(given)
        raise
    if given is None:
        return from_time
    if abs(given - from_time) <= 0.01 * from_time:
        return float(given)
    raise GyrodriftValueError(f"{source}: --rate-hz {given:g} contradicts the file's time column "
                     f"({from_time:.6g} Hz); drop --rate-hz, or add --force-rate (force_rate=True) "
                     "to use it anyway")


def load_npy(path: str | Path, mmap: bool = True) -> np.ndarray:
    """``numpy.load`` of a .npy array (memory-mapped unless ``mmap`` is False; never pickled
    objects) with one clear message naming the file for what is not one: an empty file, a
    text or other file named .npy, a damaged header.

    Examples
    --------
    >>> import tempfile
    >>> bad = Path(tempfile.mkdtemp()) / "notes.npy"
    >>> _ = bad.write_text("1.0, 2.0\\n")
    >>> load_npy(bad)
    Traceback (most recent call last):
    ...
    gyrodrift.errors.GyrodriftValueError: .../notes.npy: not a NumPy .npy file ...
    """
    p = Path(path)
    try:
        return np.load(p, mmap_mode="r" if mmap else None, allow_pickle=False)
    except (EOFError, ValueError, OSError) as exc:
        if isinstance(exc, OSError) and not p.is_file():
            raise
        size = p.stat().st_size
        if size == 0:
            raise GyrodriftValueError(f"{p}: empty file (0 bytes), not a .npy array") from None
        with p.open("rb") as fh:
            magic = fh.read(6)
        if magic != b"\x93NUMPY":
            raise GyrodriftValueError(
                f"{p}: not a NumPy .npy file (no .npy header; a text or other "
                "file named .npy?)") from None
        raise GyrodriftValueError(f"{p}: unreadable .npy file: {exc}") from None


def _check_text_cells(p: Path, table: np.ndarray, cols: list[int], names: list[str],
                      delimiter: str, lines: list[str], first_line_no: int) -> None:
    """Cells genfromtxt turned into NaN although they are not empty or 'nan': name the first
    one (text in a numeric column is an error, not a missing value). `table` holds the rows
    of `lines`, the first of which is line `first_line_no` of the file."""
    nan_rows = np.flatnonzero(np.isnan(table[:, cols]).any(axis=1))
    if nan_rows.size == 0:
        return
    want = set(nan_rows.tolist())
    for r, row in enumerate(csv.reader(lines, delimiter=delimiter)):
        if r not in want:
            continue
        for c in cols:
            cell = row[c].strip() if c < len(row) else ""
            if cell and not is_number(cell):
                raise GyrodriftValueError(
                    f"{p}: line {first_line_no + r}, column {names[c]!r}: {cell!r} is "
                    "not a number")


def is_number(text: str) -> bool:
    """Whether a text cell reads as a float (a CSV header cell that does is data, not a name).

    Examples
    --------
    >>> is_number("1e-3"), is_number("nan"), is_number("gyro_x")
    (True, True, False)
    """
    try:
        float(text)
    except ValueError:
        return False
    return True


def _count_nonfinite_chunked(values: np.ndarray, chunk: int = 1 << 22) -> int:
    """Non-finite samples of a record, read in chunks. A contiguous memory map is read with
    file reads, not through the mapping: pages touched through a mapping stay resident in the
    process (its peak memory would grow with the record, 800 MB at 1e8 samples)."""
    n_bad = 0
    for piece in iter_chunks(values, chunk):
        n_bad += int(np.count_nonzero(~np.isfinite(piece)))
    return n_bad


def is_file_backed(values: object) -> bool:
    """Whether `values` is a 1-D contiguous memory map of a file, which :func:`iter_chunks`
    reads with file reads (pages touched through a mapping stay resident in the process).

    Examples
    --------
    >>> is_file_backed(np.zeros(3))
    False
    """
    return (isinstance(values, np.memmap) and values.filename is not None
            and values.ndim == 1 and values.flags.c_contiguous)


def iter_chunks(values: np.ndarray, chunk: int) -> Iterator[np.ndarray]:
    """Consecutive pieces of at most `chunk` samples of a 1-D record: read from the file for
    a file-backed memory map (:func:`is_file_backed`; the process's memory then does not grow
    with the record), views otherwise.

    Examples
    --------
    >>> [p.tolist() for p in iter_chunks(np.arange(5.0), 2)]
    [[0.0, 1.0], [2.0, 3.0], [4.0]]
    """
    if is_file_backed(values):
        assert isinstance(values, np.memmap) and values.filename is not None  # is_file_backed
        with open(values.filename, "rb") as fh:
            for lo in range(0, values.shape[0], chunk):
                count = min(chunk, values.shape[0] - lo)
                fh.seek(values.offset + lo * values.dtype.itemsize)
                piece = np.fromfile(fh, dtype=values.dtype, count=count)
                if piece.size != count:
                    raise GyrodriftValueError(
                        f"{values.filename}: file shorter than its header says")
                yield piece
        return
    for lo in range(0, values.shape[0], chunk):
        yield values[lo:lo + chunk]


def _load_log(p: Path, column: str | int | None, rate_hz: float | None, units: str,
              nan_policy: str, can_signals: str | Path | None = None,
              force_rate: bool = False, mmap: bool = True) -> Record:
    """One gyro axis of a replay harness log, read in blocks
    (gyrodrift.io.imu_log.ImuLogBlocks): the axis and the times kept in memory, or with
    `mmap` from SPOOL_MIN_SAMPLES samples on in temporary files, then normalized like a
    .npy record's column."""
    from gyrodrift.io.imu_log import ImuLogBlocks  # the "replay" area's reader

    axis_name = "z" if column is None else str(column).lower()
    if axis_name not in GYRO_AXES:
        raise GyrodriftValueError(f"{p}: IMU logs hold gyro axes x, y, z; got column {column!r}")
    blocks = ImuLogBlocks(p, signals=can_signals)
    memory_max = None if mmap else sys.maxsize
    with SampleSpool(memory_max, name="gyro_rad_s") as raw, \
            SampleSpool(memory_max, name="time") as t_spool:
        for s in blocks:
            raw.append(s.channels[:, GYRO_AXES[axis_name]])
            t_spool.append(s.t_s)
        gyro_rad_s, t = raw.finish(), t_spool.finish()
    rate_hz = _resolve_rate(rate_hz, t, str(p), force_rate)
    del t  # its temporary file goes with the last reference
    log_units = "rad/s" if units == "deg/h" else units  # logs carry rad/s unless told
    n_total = int(gyro_rad_s.size)
    x, dropped = _normalize(iter_chunks(gyro_rad_s, BLOCK_ROWS), n_total, log_units,
                            rate_hz, nan_policy, str(p), mmap)
    return Record(x, float(rate_hz), str(p), f"gyro_{axis_name}", log_units,
                  n_total, dropped,
                  blocks.report.summary() if blocks.report is not None else "")


def _load_psins(p: Path, column: str | int | None, rate_hz: float | None, units: str,
                nan_policy: str, mmap: bool = True) -> Record:
    """One gyro axis of a PSINS .imu log (angle increments in rad per sample, divided by dt),
    read in blocks of lines (gyrodrift.io.psins.PsinsBlocks), kept as `_load_log` keeps
    its axis."""
    from gyrodrift.io.psins import PsinsBlocks  # the "align" area's reader

    axis_name = "z" if column is None else str(column).lower()
    if axis_name not in GYRO_AXES:
        raise GyrodriftValueError(
            f"{p}: PSINS .imu logs hold gyro axes x, y, z; got column {column!r}")
    if units not in ("deg/h", "rad"):
        raise GyrodriftValueError(f"{p}: PSINS .imu logs carry their own units (angle increments); "
                         f"--gyro-units {units} does not apply")
    blocks = PsinsBlocks(p)
    with SampleSpool(None if mmap else sys.maxsize, name="dtheta_rad") as raw:
        for dtheta, _ in blocks:
            raw.append(dtheta[:, GYRO_AXES[axis_name]])
        dtheta_rad = raw.finish()
    file_rate = 1.0 / blocks.dt_s
    if rate_hz is not None and not math.isclose(rate_hz, file_rate, rel_tol=1e-9):
        raise GyrodriftValueError(
            f"{p}: the file says {file_rate:g} Hz, --rate-hz says {rate_hz:g}")
    n_total = int(dtheta_rad.size)
    x, dropped = _normalize(iter_chunks(dtheta_rad, BLOCK_ROWS), n_total, "rad", file_rate,
                            nan_policy, str(p), mmap)
    return Record(x, float(file_rate), str(p), f"gyro_{axis_name}", "rad (increments)",
                  n_total, dropped)
