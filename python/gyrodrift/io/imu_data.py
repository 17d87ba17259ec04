"""Multi-channel IMU records for `gyrodrift characterize` and `gyrodrift fleet`.

`load_imu(path)` reads up to six channels (gyro x, y, z in rad/s; accelerometer x, y, z in
m/s^2) from:

- ``.npy``: a (n, k) array (k = 3: gyro only; k = 6: gyro then accelerometer; or named with
  ``columns=``), with ``rate_hz`` given. With ``spool_dir=`` the array is memory-mapped and
  copied in chunks of rows to one float64 file per channel, which the Allan code then reads
  in chunks (bounded memory whatever the record length: what a fleet worker does).
- CSV and whitespace- or semicolon-separated text (``.csv``, ``.txt``, ``.dat``, ``.tsv``),
  with or without a header line; a time column is detected (header ``t``, ``t_s``, ``time``,
  ``timestamp``, ``stamp``; without a header, a strictly increasing first column when there are
  4 or 7 columns) or given (``time_column=``); its steps are checked for gaps and reordering
  exactly as the one-channel reader does (`gyrodrift.io.records`).
- the PSINS ``.imu`` text log (angle and velocity increments per sample;
  `gyrodrift.io.psins`), converted to rates by dividing by the sample interval.
- the replay harness's IMU logs (``.bin``/``.gdf``, candump ``.log``, ``.asc``, ``.blf`` and
  its CSV; `gyrodrift.io.imu_log`), with their sequence numbers checked for lost samples.
  Text records, PSINS and IMU logs are read in blocks, their channels kept in memory or,
  from ``gyrodrift.io.spool.SPOOL_MIN_SAMPLES`` samples on (six channels: a sixth of it
  each), in temporary files returned as memory maps (bounded memory whatever the record's
  length).
- ROS bags (``.bag`` rosbag1; a rosbag2 directory or its ``.db3``/``.mcap`` file), read with
  the pure-Python ``rosbags`` package: one ``sensor_msgs/msg/Imu`` topic (``topic=``; the
  error lists the Imu topics when it is missing or ambiguous), timestamps from the message
  headers (the bag's receive time where a header stamp is zero), checked like a time column.
  The messages are read in blocks (BAG_BLOCK_MESSAGES), each block's columns appended to
  temporary float64 files from BAG_SPOOL_MIN_MESSAGES messages on (bounded memory whatever
  the bag's length; a rosbag1 index is read one chunk's record at a time).

NaN/Inf samples follow `nan_policy` as in `gyrodrift.io.records`: "refuse" (default) raises with
their
count, "drop" removes the rows (all channels) and reports the count.

Examples
--------
>>> import numpy as np, tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> np.save(d / "imu.npy", np.zeros((100, 6)) + np.arange(6))
>>> rec = load_imu(d / "imu.npy", rate_hz=100.0)
>>> rec.names
('gyro_x', 'gyro_y', 'gyro_z', 'accel_x', 'accel_y', 'accel_z')
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import math
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift import units
from gyrodrift.errors import GyrodriftError, GyrodriftValueError
from gyrodrift.io import spool as _spool
from gyrodrift.io.records import (
    LOG_SUFFIXES,
    RATE_MAX_HZ,
    RATE_MIN_HZ,
    is_file_backed,
    is_number,
    iter_chunks,
    load_npy,
    rate_from_time,
)
from gyrodrift.io.spool import BLOCK_ROWS, SPOOL_MIN_SAMPLES, SampleSpool, iter_text_tables
from gyrodrift.units import (
    ACCEL_INCREMENT_UNITS,
    DEFAULT_TIME_UNITS,
    INCREMENT_UNITS,
    RATE_UNITS,
    TIME_UNITS,
)

__all__ = [
    "ACCEL_UNITS",
    "CHANNELS",
    "GYRO_UNITS",
    "UNITS_CARRIED_KINDS",
    "ImuData",
    "NpyChannels",
    "bag_imu_topics",
    "check_reader_options",
    "check_units_plausible",
    "input_kind",
    "load_imu",
    "units_carried",
]

#: Channel names in their canonical order (SI units inside: rad/s and m/s^2).
CHANNELS: tuple[str, ...] = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")
#: gyro input unit -> factor to rad/s (increments "rad", "deg", "arcsec": to rad, divided by dt)
GYRO_UNITS: dict[str, float] = {u: f.to_rad_s for u, f in (*RATE_UNITS.items(),
                                                          *INCREMENT_UNITS.items())}
#: accelerometer input unit -> factor to m/s^2 (increments "m/s" are divided by dt).
ACCEL_UNITS: dict[str, float] = {**units.ACCEL_UNITS, **ACCEL_INCREMENT_UNITS}
_INCREMENT_UNITS = (*INCREMENT_UNITS, *ACCEL_INCREMENT_UNITS)
TEXT_SUFFIXES = (".csv", ".txt", ".dat", ".tsv")
BAG_SUFFIXES = (".bag", ".db3", ".mcap")
IMU_MSGTYPES = ("sensor_msgs/msg/Imu", "sensor_msgs/Imu")

_TIME_RE = re.compile(r"^(%?time|t|t_s|time_s|timestamp|stamp|sec|secs|seconds)([ _(\[].*)?$")
_GYRO_RE = re.compile(r"^(gyro|gyr|gyroscope|omega|w|g|angular_velocity|ang_vel)[ _.\-]?([xyz])"
                      r"(\b|_|$|[ (\[])")
_ACCEL_RE = re.compile(r"^(accel|acc|accelerometer|a|f|linear_acceleration|lin_acc)[ _.\-]?"
                       r"([xyz])(\b|_|$|[ (\[])")


@dataclass(frozen=True)
class ImuData:
    """Up to six IMU channels on one uniform time base.

    Attributes
    ----------
    channels
        name ("gyro_x" .. "accel_z") -> 1-D float64 samples in rad/s (gyro) or m/s^2
        (accelerometer); a read-only numpy.memmap for spooled records.
    rate_hz
        sample rate, Hz.
    source
        the file (or bag) read.
    fmt
        input kind ("npy", "text", "psins", "replay-log", "rosbag1", "rosbag2").
    n_total
        samples in the file before any were dropped.
    n_dropped
        rows removed by nan_policy="drop".
    detail
        what the reader decided (columns, units, topic, time column), for reports.

    Examples
    --------
    >>> rec = ImuData({"gyro_z": np.zeros(4)}, rate_hz=100.0, source="x", fmt="npy", n_total=4)
    >>> rec.names, rec.n, rec.duration_s
    (('gyro_z',), 4, 0.04)
    """

    channels: dict[str, np.ndarray]
    rate_hz: float
    source: str
    fmt: str
    n_total: int
    n_dropped: int = 0
    detail: dict[str, object] = field(default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.channels)

    @property
    def n(self) -> int:
        return int(next(iter(self.channels.values())).shape[0])

    @property
    def dt_s(self) -> float:
        return 1.0 / self.rate_hz

    @property
    def duration_s(self) -> float:
        return self.n / self.rate_hz

    def summary(self) -> dict[str, object]:
        return _record_summary(self.source, self.fmt, self.rate_hz, self.n_total, self.n,
                               self.n_dropped, self.names, self.detail)


def _record_summary(source: str, fmt: str, rate_hz: float, n_total: int, n: int,
                    n_dropped: int, names: Sequence[str], detail: dict[str, object]
                    ) -> dict[str, object]:
    return {"source": source, "format": fmt, "rate_hz": rate_hz, "n_total": n_total,
            "n_used": n, "duration_s": n / rate_hz, "n_dropped_nonfinite": n_dropped,
            "channels": list(names), **detail}


def input_kind(path: str | Path) -> str:
    """The reader `load_imu` uses for a path (no file content read except a CSV header).

    Examples
    --------
    >>> [input_kind(p) for p in ("a.npy", "a.csv", "a.bag", "a.imu", "a.bin")]
    ['npy', 'text', 'rosbag1', 'psins', 'replay-log']
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "rosbag2"
        raise GyrodriftValueError(f"{p}: a directory that is not a rosbag2 bag (no metadata.yaml)")
    if suffix == ".bag":
        return "rosbag1"
    if suffix in (".db3", ".mcap"):
        return "rosbag2"
    if suffix == ".npy":
        return "npy"
    if suffix == ".imu":
        return "psins"
    if suffix in LOG_SUFFIXES:
        return "replay-log"
    if suffix in TEXT_SUFFIXES:
        if suffix == ".csv" and p.is_file():
            with p.open(encoding="utf-8-sig", errors="replace") as fh:
                first = fh.readline()
            if "gyro_z_rad_s" in first and "seq" in first:
                return "replay-log"
        return "text"
    raise GyrodriftValueError(
        f"{p}: unsupported input {suffix!r}: use .npy, .csv/.txt/.dat/.tsv text, "
        f"PSINS .imu, an IMU log ({', '.join(LOG_SUFFIXES)}), or a ROS bag "
        "(.bag, a rosbag2 directory, .db3, .mcap)")


def check_reader_options(path: str | Path, time_units: str = DEFAULT_TIME_UNITS,
                         time_column: str | int | None = None, topic: str | None = None) -> str:
    """Refuse reading options the record cannot use, instead of ignoring them: time units
    other than the default or a time column for anything but a text record (a .npy record
    has no time column, logs and bags carry their own time base), a topic for anything but a
    ROS bag; returns the record's kind (`input_kind`).

    Examples
    --------
    >>> check_reader_options("imu.csv", "ns")
    'text'
    >>> check_reader_options("imu.npy", "ns")
    Traceback (most recent call last):
    ...
    gyrodrift.errors.GyrodriftValueError: imu.npy: --time-units (time_units=) applies to the \
time column of a text record; a npy record carries its own time base
    """
    p = Path(path)
    if time_units not in TIME_UNITS:
        raise GyrodriftValueError(f"unknown time units {time_units!r}; choose one of "
                                  f"{', '.join(TIME_UNITS)}")
    kind = input_kind(p)
    if time_units != DEFAULT_TIME_UNITS and kind != "text":
        raise GyrodriftValueError(f"{p}: --time-units (time_units=) applies to the time column "
                                  f"of a text record; a {kind} record carries its own time base")
    if time_column is not None and kind != "text":
        raise GyrodriftValueError(f"{p}: --time-column (time_column=) applies to a text record; "
                                  f"a {kind} record has no time column to choose")
    if topic is not None and kind not in ("rosbag1", "rosbag2"):
        raise GyrodriftValueError(f"{p}: --topic (topic=) applies to a ROS bag, not to a {kind} "
                                  "record")
    return kind


def load_imu(
    path: str | Path,
    *,
    rate_hz: float | None = None,
    columns: Sequence[str] | None = None,
    time_column: str | int | None = None,
    time_units: str = DEFAULT_TIME_UNITS,
    topic: str | None = None,
    gyro_units: str = "rad/s",
    accel_units: str = "m/s^2",
    nan_policy: str = "refuse",
    spool_dir: str | Path | None = None,
    chunk_rows: int = 1 << 18,
) -> ImuData:
    """Read an IMU record (module docstring).

    Parameters
    ----------
    rate_hz : required for .npy and for text without a time column; otherwise checked
        against nothing and used instead of the time column's rate when given.
    columns : channel name per data column (time column excluded), "-" to skip one; default
        from the header, or gyro x, y, z (3 columns) / gyro then accel (6 columns).
    time_column : text only: header name or index, "none" for no time column; default:
        detected.
    time_units : text only: the units of the time column, "s", "ms", "us" or "ns"
        (gyrodrift.units.TIME_UNITS). The rate it gives is checked like a given rate_hz, so a
        time column in other units than these is refused, naming the units its step
        suggests.
    topic : ROS bags: the sensor_msgs/msg/Imu topic (needed when the bag has several).
    gyro_units, accel_units : units of text/.npy columns (GYRO_UNITS, ACCEL_UNITS); logs,
        bags and PSINS files carry their own.
    nan_policy : "refuse" or "drop" (rows with any NaN/Inf channel).
    spool_dir : .npy only: write one float64 file per channel there, in chunks of
        `chunk_rows` rows, and return memory maps of them (bounded memory).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = Path(d) / "imu.csv"  # time column and three gyro columns, rad/s
    ...     _ = path.write_text("t,gx,gy,gz\\n0.00,0.1,0.2,0.3\\n0.01,0.1,0.2,0.3\\n"
    ...                         "0.02,0.1,0.2,0.3\\n")
    ...     rec = load_imu(path)
    >>> rec.names, rec.rate_hz, rec.fmt, rec.channels["gyro_z"]
    (('gyro_x', 'gyro_y', 'gyro_z'), 100.0, 'text', array([0.3, 0.3, 0.3]))
    """
    p = Path(path)
    _check_args(p, nan_policy, gyro_units, accel_units, rate_hz)
    kind = check_reader_options(p, time_units, time_column, topic)
    if kind == "npy":
        if spool_dir is not None:
            return _spool_npy(p, rate_hz, columns, gyro_units, accel_units, Path(spool_dir),
                              chunk_rows, nan_policy)
        return _load_npy(p, rate_hz, columns, gyro_units, accel_units, nan_policy)
    if kind == "text":
        return _load_text(p, rate_hz, columns, time_column, gyro_units, accel_units, nan_policy,
                          time_units)
    if kind == "psins":
        return _load_psins(p, nan_policy)
    if kind == "replay-log":
        return _load_replay_log(p, rate_hz, nan_policy)
    return _load_bag(p, kind, topic, rate_hz, nan_policy)


# ---------------------------------------------------------------------------------- helpers

def _check_args(p: Path, nan_policy: str, gyro_units: str, accel_units: str,
                rate_hz: float | None) -> None:
    """Refuse what no reader can use, before any is opened: a missing path, or one that is
    neither a regular file nor a directory (a FIFO or device would block or never end; a
    directory is read only as a rosbag2 bag), unknown policies or units, a rate outside
    RATE_MIN_HZ..RATE_MAX_HZ."""
    if not p.exists():
        raise FileNotFoundError(f"no such file: {p}")
    if not (p.is_file() or p.is_dir()):
        raise GyrodriftValueError(f"{p}: not a regular file (a FIFO, socket or device); give "
                                  "a record file")
    if nan_policy not in ("refuse", "drop"):
        raise GyrodriftValueError(f"nan_policy must be 'refuse' or 'drop', got {nan_policy!r}")
    if gyro_units not in GYRO_UNITS:
        raise GyrodriftValueError(
            f"unknown gyro units {gyro_units!r}; choose one of {list(GYRO_UNITS)}")
    if accel_units not in ACCEL_UNITS:
        raise GyrodriftValueError(f"unknown accel units {accel_units!r}; choose one of "
                         f"{list(ACCEL_UNITS)}")
    if rate_hz is not None and not (isinstance(rate_hz, int | float) and math.isfinite(rate_hz)
                                    and RATE_MIN_HZ <= rate_hz <= RATE_MAX_HZ):
        raise GyrodriftValueError(f"sample rate must be within {RATE_MIN_HZ:g}..{RATE_MAX_HZ:g} "
                                  f"Hz, got {rate_hz!r}")


def _default_names(k: int, source: str) -> list[str]:
    if k == 6:
        return list(CHANNELS)
    if k == 3:
        return list(CHANNELS[:3])
    if k == 1:
        return ["gyro_z"]
    raise GyrodriftValueError(
        f"{source}: {k} data columns; name them with columns= (CLI --column-channels, "
        f"e.g. gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z; '-' skips one)")


def _check_names(names: Sequence[str], k: int, source: str) -> list[str]:
    names = [n.strip() for n in names]
    if len(names) != k:
        raise GyrodriftValueError(
            f"{source}: {k} data columns but {len(names)} channel names {names}")
    used = [n for n in names if n != "-"]
    bad = [n for n in used if n not in CHANNELS]
    if bad:
        raise GyrodriftValueError(
            f"{source}: unknown channel names {bad}; use {', '.join(CHANNELS)} "
            "or '-'")
    if len(set(used)) != len(used):
        raise GyrodriftValueError(f"{source}: a channel is named twice in {names}")
    if not used:
        raise GyrodriftValueError(f"{source}: no channel selected")
    return names


def _factor(name: str, gyro_units: str, accel_units: str, rate_hz: float) -> float:
    """Multiplier from the file's unit to rad/s or m/s^2 (increments x rate)."""
    unit = gyro_units if name.startswith("gyro") else accel_units
    f = GYRO_UNITS[unit] if name.startswith("gyro") else ACCEL_UNITS[unit]
    return f * rate_hz if unit in _INCREMENT_UNITS else f


def _finish(cols: dict[str, np.ndarray], rate_hz: float, source: str, fmt: str,
            nan_policy: str, detail: dict[str, object]) -> ImuData:
    ordered = {name: cols[name] for name in CHANNELS if name in cols}
    n_total = int(next(iter(ordered.values())).shape[0])
    if n_total < 3:
        raise GyrodriftValueError(f"{source}: {n_total} samples; too short for analysis")
    bad = np.zeros(n_total, dtype=bool)
    for v in ordered.values():
        bad |= ~np.isfinite(v)
    n_bad = int(np.count_nonzero(bad))
    if n_bad:
        if nan_policy != "drop":
            raise GyrodriftValueError(
                f"{source}: {n_bad} of {n_total} samples have NaN/Inf channels; "
                "pass nan_policy='drop' (CLI: --drop-nan) to remove them")
        ordered = {k: v[~bad] for k, v in ordered.items()}
    ordered = {k: np.ascontiguousarray(v, dtype=np.float64) for k, v in ordered.items()}
    return ImuData(ordered, float(rate_hz), source, fmt, n_total, n_bad, detail)


# ---------------------------------------------------------------------------------- readers

def _load_npy(p: Path, rate_hz: float | None, columns: Sequence[str] | None, gyro_units: str,
              accel_units: str, nan_policy: str) -> ImuData:
    arr = load_npy(p)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise GyrodriftValueError(f"{p}: expected an (n, k) array, got shape {arr.shape}")
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise GyrodriftValueError(f"{p}: expected numbers, got dtype {arr.dtype}")
    if rate_hz is None:
        raise GyrodriftValueError(f"{p}: a .npy record carries no sample rate; give --rate-hz")
    names = (_check_names(columns, arr.shape[1], str(p)) if columns
             else _default_names(arr.shape[1], str(p)))
    cols = {n: np.asarray(arr[:, j], dtype=np.float64) * _factor(n, gyro_units, accel_units,
                                                                   rate_hz)
            for j, n in enumerate(names) if n != "-"}
    return _finish(cols, rate_hz, str(p), "npy", nan_policy,
                   {"columns": names, "gyro_units_in": gyro_units, "accel_units_in": accel_units})


class NpyChannels:
    """An (n, k) .npy IMU record read in chunks of rows from plain file reads (a fleet task's
    reader): one channel at a time into memory (`channel`), or all channels spooled to one
    float64 file each (`spool`). Either way at most `chunk_rows` rows of the file are held
    besides what is returned, and the values are the same bits: the file's column converted
    to float64 and multiplied by its unit factor, sample by sample.

    NaN/Inf are refused before any channel is returned: the first `channel` call (or `spool`)
    counts them over every used column in its pass and raises with their count.

    Examples
    --------
    >>> import tempfile
    >>> d = Path(tempfile.mkdtemp())
    >>> np.save(d / "imu.npy", np.arange(12, dtype=np.float32).reshape(4, 3))
    >>> r = NpyChannels(d / "imu.npy", rate_hz=100.0, gyro_units="deg/s", chunk_rows=3)
    >>> r.names, r.n, r.channel("gyro_y") * 180.0 / math.pi
    (('gyro_x', 'gyro_y', 'gyro_z'), 4, array([ 1.,  4.,  7., 10.]))
    """

    def __init__(self, path: str | Path, *, rate_hz: float | None,
                 columns: Sequence[str] | None = None, gyro_units: str = "rad/s",
                 accel_units: str = "m/s^2", chunk_rows: int = 1 << 18) -> None:
        p = Path(path)
        _check_args(p, "refuse", gyro_units, accel_units, rate_hz)
        if input_kind(p) != "npy":
            raise GyrodriftValueError(f"{p}: not a .npy record")
        base = load_npy(p)
        arr = base[:, None] if base.ndim == 1 else base
        if arr.ndim != 2:
            raise GyrodriftValueError(f"{p}: expected an (n, k) array, got shape {arr.shape}")
        if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
            raise GyrodriftValueError(f"{p}: expected numbers, got dtype {arr.dtype}")
        if rate_hz is None:
            raise GyrodriftValueError(
                f"{p}: a .npy record carries no sample rate; give --rate-hz")
        if chunk_rows < 1:
            raise GyrodriftValueError(f"chunk_rows must be >= 1, got {chunk_rows}")
        n = int(arr.shape[0])
        if n < 3:
            raise GyrodriftValueError(f"{p}: {n} samples; too short for analysis")
        names = (_check_names(columns, arr.shape[1], str(p)) if columns
                 else _default_names(arr.shape[1], str(p)))
        self.path = p
        self.rate_hz = float(rate_hz)
        self.n = n
        self.chunk_rows = int(chunk_rows)
        self._base = base
        self._arr = arr
        # The file holds rows one after the other (C order; a 1-D record too) from the offset.
        self._c_order = isinstance(base, np.memmap) and bool(base.flags.c_contiguous)
        self._offset = int(base.offset) if isinstance(base, np.memmap) else 0
        self._idx = {name: j for j, name in enumerate(names) if name != "-"}
        self._factor = {name: _factor(name, gyro_units, accel_units, self.rate_hz)
                        for name in self._idx}
        self._checked = False
        #: used channels in canonical order
        self.names: tuple[str, ...] = tuple(c for c in CHANNELS if c in self._idx)
        self.detail: dict[str, object] = {"columns": names, "gyro_units_in": gyro_units,
                                          "accel_units_in": accel_units, "chunked": True}

    def _blocks(self) -> Iterator[tuple[int, np.ndarray]]:
        """(first row, rows as stored: an (m, k) block of the file's dtype), in order. The
        block is one buffer, refilled for the next rows: use it before asking for the next.
        Plain file reads into that buffer, never touching a mapping: mapped pages of a
        1e7-sample record would count in the worker's resident memory (and stay there until
        evicted); and no new buffer per chunk: a Dask worker's allocator (the nanny sets
        MALLOC_TRIM_THRESHOLD_) maps and page-faults every large allocation afresh."""
        arr, n, k = self._arr, self.n, int(self._arr.shape[1])
        if not self._c_order:  # Fortran order or a 1-D record: slices of the mapping
            for lo in range(0, n, self.chunk_rows):
                yield lo, np.asarray(arr[lo:lo + self.chunk_rows])
            return
        buf = np.empty((min(self.chunk_rows, n), k), dtype=arr.dtype)
        with open(self.path, "rb") as src:
            src.seek(self._offset)
            for lo in range(0, n, self.chunk_rows):
                block = buf[:min(self.chunk_rows, n - lo)]
                want = block.nbytes
                got = src.readinto(block.reshape(-1).view(np.uint8).data)
                if got != want:
                    raise GyrodriftValueError(
                        f"{self.path}: file shorter than its header says")
                yield lo, block

    def _scaled(self, block: np.ndarray, name: str, out: np.ndarray) -> np.ndarray:
        """out = the column as float64 times its unit factor (the product in float64)."""
        return np.multiply(block[:, self._idx[name]], self._factor[name], out=out,
                           dtype=np.float64)

    def _refuse(self, n_bad: int) -> None:
        self._checked = True
        if n_bad:
            raise GyrodriftValueError(
                f"{self.path}: {n_bad} NaN/Inf values; the chunked reader refuses them "
                "(repair the record, or characterize it alone with --drop-nan)")

    def channel(self, name: str) -> np.ndarray:
        """One channel as a contiguous float64 array in SI units (one pass over the file;
        memory: the channel plus one chunk of rows)."""
        if name not in self._idx:
            raise KeyError(name)
        out = np.empty(self.n)
        check = not self._checked
        rows = min(self.chunk_rows, self.n)
        scratch, finite = np.empty(rows), np.empty(rows, dtype=bool)
        n_bad = 0
        for lo, block in self._blocks():
            m = block.shape[0]
            self._scaled(block, name, out[lo:lo + m])
            if check:
                for c in self._idx:
                    col = out[lo:lo + m] if c == name else self._scaled(block, c, scratch[:m])
                    n_bad += m - int(np.count_nonzero(np.isfinite(col, out=finite[:m])))
        if check:
            self._refuse(n_bad)
        return out

    def spool(self, spool_dir: str | Path, nan_policy: str = "refuse") -> ImuData:
        """Every channel copied to `spool_dir/<name>.f64` (raw float64), returned as read-only
        memory maps (which the Allan code reads in chunks: bounded memory). NaN/Inf:
        `nan_policy` "refuse" raises with their count; "drop" removes the rows where any
        used channel has one and reports their count (as `load_imu` does)."""
        if nan_policy not in ("refuse", "drop"):
            raise GyrodriftValueError(
                f"nan_policy must be 'refuse' or 'drop', got {nan_policy!r}")
        spool = Path(spool_dir)
        spool.mkdir(parents=True, exist_ok=True)
        rows = min(self.chunk_rows, self.n)
        # one buffer per channel only where rows may be dropped (all channels' values are
        # needed before a row is written); one buffer for all channels otherwise
        one = np.empty(rows)
        scratch = {name: np.empty(rows) if nan_policy == "drop" else one for name in self._idx}
        finite, ok = np.empty(rows, dtype=bool), np.empty(rows, dtype=bool)
        n_bad = n_rows_bad = n_kept = 0
        raw = {name: open(spool / f"{name}.f64", "wb") for name in self._idx}
        try:
            for _, block in self._blocks():
                m = block.shape[0]
                ok[:m] = True
                for name in self._idx:
                    col = self._scaled(block, name, scratch[name][:m])
                    np.isfinite(col, out=finite[:m])
                    n_bad += m - int(np.count_nonzero(finite[:m]))
                    ok[:m] &= finite[:m]
                    if nan_policy != "drop":
                        raw[name].write(col.data)
                if nan_policy != "drop":
                    continue
                kept = int(np.count_nonzero(ok[:m]))
                n_rows_bad += m - kept
                n_kept += kept
                for name, fh in raw.items():
                    col = scratch[name][:m]
                    fh.write((col if kept == m else col[ok[:m]]).data)
        finally:
            for fh in raw.values():
                fh.close()
        if nan_policy != "drop":
            self._refuse(n_bad)
            n_kept = self.n
        n_dropped = n_rows_bad if nan_policy == "drop" else 0
        cols: dict[str, np.ndarray] = {}
        for name in self.names:
            path = spool / f"{name}.f64"
            cols[name] = (np.memmap(path, dtype=np.float64, mode="r", shape=(n_kept,))
                          if n_kept else np.empty(0))
        return ImuData(cols, self.rate_hz, str(self.path), "npy", self.n, n_dropped,
                       dict(self.detail))

    def summary(self) -> dict[str, object]:
        """What `ImuData.summary` gives for this record (the same dict as `spool`'s)."""
        return _record_summary(str(self.path), "npy", self.rate_hz, self.n, self.n, 0,
                               self.names, self.detail)


def _spool_npy(p: Path, rate_hz: float | None, columns: Sequence[str] | None, gyro_units: str,
               accel_units: str, spool: Path, chunk_rows: int, nan_policy: str) -> ImuData:
    """Chunked copy of an (n, k) .npy to one float64 file per channel; memory ~ chunk_rows x
    k. NaN/Inf are refused (counted over all chunks first) or their rows dropped."""
    return NpyChannels(p, rate_hz=rate_hz, columns=columns, gyro_units=gyro_units,
                       accel_units=accel_units, chunk_rows=chunk_rows).spool(spool, nan_policy)


def _split(line: str, delim: str | None) -> list[str]:
    return [c.strip() for c in (line.split(delim) if delim else line.split())]


def _header_channel(name: str) -> str | None:
    low = name.strip().lower()
    for prefix, rx in (("gyro", _GYRO_RE), ("accel", _ACCEL_RE)):
        m = rx.match(low)
        if m:
            return f"{prefix}_{m.group(2)}"
    return None


#: The header names the text reader recognises (case-insensitive; _TIME_RE, _GYRO_RE,
#: _ACCEL_RE), for the message that refuses a header with none of them.
RECOGNISED_NAMES = ("time: t, t_s, time, time_s, timestamp, stamp, sec; gyro: gyro_x, gyr_x, "
                    "gx, wx, omega_x, angular_velocity_x (y, z alike); accelerometer: accel_x, "
                    "acc_x, ax, fx, linear_acceleration_x (y, z alike)")


def _read_text_columns(p: Path, delim: str | None, skip: int) -> list[np.ndarray]:
    """The columns of a text table after its first `skip` lines, parsed in blocks of lines
    as numpy.genfromtxt parses them (gyrodrift.io.spool.iter_text_tables: by numpy.loadtxt
    where it accepts the block): rows with a wrong number of fields are an error (never
    dropped silently), unparseable cells become NaN and go
    through the NaN policy. Each column is an array, or from SPOOL_MIN_SAMPLES rows on a
    memory map of a temporary file (8 bytes per row and column)."""
    source = str(p)
    spools: list[SampleSpool] = []
    with contextlib.ExitStack() as stack:
        try:
            with p.open(encoding="utf-8-sig") as fh:  # a byte-order mark is not part of a name
                for _ in range(skip):
                    next(fh, None)
                for table, _lines, _no in iter_text_tables(
                        fh, delimiter=delim, first_line_no=skip + 1,
                        malformed=f"{source}: malformed text table"):
                    if table.shape[0] == 0:
                        continue
                    if not spools:
                        spools = [stack.enter_context(SampleSpool(name=f"column{j}"))
                                  for j in range(table.shape[1])]
                    for j, sp in enumerate(spools):
                        sp.append(table[:, j])
        except UnicodeDecodeError as exc:
            raise GyrodriftValueError(f"{source}: not a text table (byte {exc.start} of a line "
                                      "is not UTF-8; a binary file?)") from None
        if not spools:
            raise GyrodriftValueError(f"{source}: no data rows")
        return [sp.finish() for sp in spools]


def _strictly_increasing(t: np.ndarray) -> bool:
    """``numpy.all(numpy.diff(t) > 0)``, read in pieces (a file-backed column too)."""
    prev: np.ndarray | None = None
    for piece in iter_chunks(t, BLOCK_ROWS):
        u = piece if prev is None else np.concatenate((prev, piece))
        if u.size > 1 and not bool(np.all(np.diff(u) > 0)):
            return False
        prev = u[-1:]
    return True


def _finish_scaled(cols: dict[str, tuple[np.ndarray, float]], rate_hz: float, source: str,
                   fmt: str, nan_policy: str, detail: dict[str, object]) -> ImuData:
    """`_finish` of the channels `column * factor`: in memory for in-memory columns, else
    in pieces into temporary files (gyrodrift.io.spool.SampleSpool), the same values and
    the same NaN policy (rows with a NaN/Inf channel refused with their count, or dropped)."""
    if not any(is_file_backed(c) for c, _ in cols.values()):
        return _finish({n: c * f for n, (c, f) in cols.items()}, rate_hz, source, fmt,
                       nan_policy, detail)
    ordered = [n for n in CHANNELS if n in cols]
    n_total = int(cols[ordered[0]][0].shape[0])
    if n_total < 3:
        raise GyrodriftValueError(f"{source}: {n_total} samples; too short for analysis")
    n_bad = 0
    with contextlib.ExitStack() as stack:
        out = {n: stack.enter_context(SampleSpool(name=n)) for n in ordered}
        pieces = zip(*(iter_chunks(cols[n][0], BLOCK_ROWS) for n in ordered), strict=True)
        for group in pieces:
            scaled = [piece * cols[n][1] for n, piece in zip(ordered, group, strict=True)]
            ok = np.logical_and.reduce([np.isfinite(v) for v in scaled])
            bad = ok.size - int(np.count_nonzero(ok))
            n_bad += bad
            if n_bad and nan_policy != "drop":
                continue  # counted, never kept
            for n, v in zip(ordered, scaled, strict=True):
                out[n].append(v if bad == 0 else v[ok])
        if n_bad and nan_policy != "drop":
            raise GyrodriftValueError(
                f"{source}: {n_bad} of {n_total} samples have NaN/Inf channels; "
                "pass nan_policy='drop' (CLI: --drop-nan) to remove them")
        channels = {n: out[n].finish() for n in ordered}
    return ImuData(channels, float(rate_hz), source, fmt, n_total, n_bad, detail)


def _load_text(p: Path, rate_hz: float | None, columns: Sequence[str] | None,
               time_column: str | int | None, gyro_units: str, accel_units: str,
               nan_policy: str, time_units: str) -> ImuData:
    source = str(p)
    first = None
    skip = 0
    try:
        with p.open(encoding="utf-8-sig") as fh:  # a byte-order mark is not part of a name
            for line in fh:
                skip += 1
                if line.strip() and not line.lstrip().startswith(("#", "%")):
                    first = line.strip()
                    break
    except UnicodeDecodeError as exc:
        raise GyrodriftValueError(f"{source}: not a text table (byte {exc.start} of a line is "
                                  "not UTF-8; a binary file?)") from None
    if first is None:
        raise GyrodriftValueError(f"{source}: empty file")
    delim = "," if "," in first else (";" if ";" in first else None)
    cells = _split(first, delim)
    has_header = not all(is_number(c) for c in cells)
    table = _read_text_columns(p, delim, skip if has_header else skip - 1)
    k = len(table)
    if k != len(cells):
        raise GyrodriftValueError(
            f"{source}: rows have {k} fields, the first line has {len(cells)}")
    header = cells if has_header else [str(i) for i in range(k)]
    # Time column.
    t_idx: int | None
    if time_column is None:
        t_idx = next((i for i, n in enumerate(header) if _TIME_RE.match(n.lower())), None) \
            if has_header else None
        if t_idx is None and not has_header and k in (4, 7) and columns is None:
            if table[0].shape[0] > 1 and _strictly_increasing(table[0]):
                t_idx = 0
    elif str(time_column).lower() == "none":
        t_idx = None
    elif isinstance(time_column, int) or str(time_column).isdigit():
        t_idx = int(time_column)
        if not 0 <= t_idx < k:
            raise GyrodriftValueError(f"{source}: time column {t_idx} out of range (0..{k - 1})")
    else:
        if time_column not in header:
            raise GyrodriftValueError(
                f"{source}: no time column {time_column!r}; columns are {header}")
        t_idx = header.index(str(time_column))
    data_idx = [i for i in range(k) if i != t_idx]
    if columns:
        names = _check_names(columns, len(data_idx), source)
    elif has_header:
        mapped = [_header_channel(header[i]) for i in data_idx]
        if all(m is None for m in mapped):
            # A header that names no channel says what its columns are, just not in words
            # this reader knows: never map them to gyro and accelerometer by their count.
            raise GyrodriftValueError(
                f"{source}: no column of the header {header} is a channel this reader "
                f"recognises ({RECOGNISED_NAMES}); name the channel of each data column with "
                "--column-channels (columns=), '-' to skip one")
        names = [m if m is not None else "-" for m in mapped]
        _check_names(names, len(data_idx), source)
    else:
        names = _default_names(len(data_idx), source)
    if t_idx is not None:
        t_rate = rate_from_time(table[t_idx], source, time_units=time_units)
        rate_hz = t_rate if rate_hz is None else rate_hz
    if rate_hz is None:
        raise GyrodriftValueError(f"{source}: no time column to infer the rate; give --rate-hz")
    scaled = {n: (table[i], _factor(n, gyro_units, accel_units, rate_hz))
              for i, n in zip(data_idx, names, strict=True) if n != "-"}
    del table  # the columns' temporary files go with their last reference
    return _finish_scaled(scaled, rate_hz, source, "text", nan_policy,
                   {"columns": names, "time_column": None if t_idx is None else header[t_idx],
                    "time_units": time_units,
                    "header": has_header, "delimiter": delim or "whitespace",
                    "gyro_units_in": gyro_units, "accel_units_in": accel_units})


class _ChannelSpool:
    """The six channels of a log or PSINS record, appended in blocks of rows to one
    :class:`gyrodrift.io.spool.SampleSpool` each, with `_finish`'s NaN policy applied row by
    row as they come: rows with a NaN/Inf channel are counted, and dropped ("drop") or, once
    there is one, no row is kept any more ("refuse": the caller raises after its other
    checks, with the count). The six channels together stay in memory up to
    SPOOL_MIN_SAMPLES samples (8 MB), as one column does: a record of six channels just
    below SPOOL_MIN_SAMPLES samples would otherwise hold 48 MB."""

    def __init__(self, stack: contextlib.ExitStack, nan_policy: str) -> None:
        self.nan_policy = nan_policy
        memory_max = _spool.SPOOL_MIN_SAMPLES // len(CHANNELS)
        self.spools = [stack.enter_context(SampleSpool(memory_max, name=name))
                       for name in CHANNELS]
        self.n_total = 0
        self.n_bad = 0

    def append(self, block: np.ndarray) -> None:
        """Rows of an (m, 6) float64 block in CHANNELS order."""
        ok = np.isfinite(block).all(axis=1)
        bad = int(block.shape[0] - np.count_nonzero(ok))
        self.n_total += int(block.shape[0])
        self.n_bad += bad
        if self.n_bad and self.nan_policy != "drop":
            return  # counted, never kept
        kept = block if bad == 0 else block[ok]
        for j, sp in enumerate(self.spools):
            sp.append(kept[:, j])

    def finish(self, source: str) -> dict[str, np.ndarray]:
        """The channels (arrays, or memory maps of temporary files from SPOOL_MIN_SAMPLES
        samples on), after `_finish`'s checks: at least 3 samples, NaN/Inf refused or
        dropped."""
        if self.n_total < 3:
            raise GyrodriftValueError(f"{source}: {self.n_total} samples; too short for "
                                      "analysis")
        if self.n_bad and self.nan_policy != "drop":
            raise GyrodriftValueError(
                f"{source}: {self.n_bad} of {self.n_total} samples have NaN/Inf channels; "
                "pass nan_policy='drop' (CLI: --drop-nan) to remove them")
        return {name: sp.finish() for name, sp in zip(CHANNELS, self.spools, strict=True)}


def _load_psins(p: Path, nan_policy: str) -> ImuData:
    """A PSINS .imu log read in blocks of lines (gyrodrift.io.psins.PsinsBlocks): the
    increments divided by the sample interval, each channel kept in memory, or from
    SPOOL_MIN_SAMPLES samples on in a temporary file (memory map)."""
    from gyrodrift.io.psins import PsinsBlocks

    blocks = PsinsBlocks(p)
    rate = 1.0 / blocks.dt_s
    with contextlib.ExitStack() as stack:
        out = _ChannelSpool(stack, nan_policy)
        for dtheta, dv in blocks:
            out.append(np.concatenate([dtheta * rate, dv * rate], axis=1))
        channels = out.finish(str(p))
    return ImuData(channels, float(rate), str(p), "psins", out.n_total, out.n_bad,
                   {"units_in": "angle increments (arcsec counts) and velocity increments "
                                "(ug*s counts) per sample, divided by dt"})


def _load_replay_log(p: Path, rate_hz: float | None, nan_policy: str) -> ImuData:
    """A replay harness log read in blocks (gyrodrift.io.imu_log.ImuLogBlocks): sequence
    numbers checked across the blocks, times and channels kept in memory, or from
    SPOOL_MIN_SAMPLES samples on in temporary files (memory maps)."""
    from gyrodrift.io.imu_log import ImuLogBlocks

    blocks = ImuLogBlocks(p, "csv" if p.suffix.lower() == ".csv" else None)
    lost = 0
    prev: np.ndarray | None = None  # the last sequence number of the previous block
    with contextlib.ExitStack() as stack:
        t_spool = stack.enter_context(SampleSpool(name="t_s"))
        out = _ChannelSpool(stack, nan_policy)
        for s in blocks:
            seq = np.asarray(s.seq, dtype=np.int64)
            if prev is not None:
                seq = np.concatenate((prev, seq))
            lost += int(np.count_nonzero(np.diff(seq) % 65536 != 1))
            prev = seq[-1:]
            t_spool.append(s.t_s)
            out.append(np.asarray(s.channels, dtype=np.float64))
        if out.n_total < 3:
            raise GyrodriftValueError(f"{p}: {out.n_total} samples; too short for analysis")
        if lost:
            raise GyrodriftValueError(
                f"{p}: {lost} breaks in the sequence numbers (lost, repeated or "
                "reordered samples); Allan/PSD analysis needs uniform sampling")
        t_s = t_spool.finish()
        t_rate = rate_from_time(t_s, str(p))
        del t_s  # its temporary file goes with the last reference
        channels = out.finish(str(p))
    rate = t_rate if rate_hz is None else rate_hz
    return ImuData(channels, float(rate), str(p), "replay-log", out.n_total, out.n_bad,
                   {"units_in": "rad/s, m/s^2"})


def _bag_paths(p: Path, kind: str) -> Path:
    # AnyReader opens a rosbag2 by its directory (metadata.yaml); a bare .db3/.mcap file inside
    # such a directory is accepted by its parent.
    if kind == "rosbag2" and p.is_file():
        if (p.parent / "metadata.yaml").is_file():
            return p.parent
        return p
    return p


_SQLITE_MAGIC = b"SQLite format 3\x00"


def _check_sqlite_complete(bag: Path, source: str) -> None:
    """Refuse a rosbag2 SQLite storage file (.db3) shorter than its own header says. SQLite
    reads the missing pages as zeros without an error (its integrity check passes too), so
    the messages stored there would come back as zeros: a cut of the last 100 bytes turns
    one message's accelerometer into 0.0. The header's page count is used only where SQLite
    itself trusts it (the version-valid-for number equals the change counter)."""
    files = sorted(bag.glob("*.db3")) if bag.is_dir() else [bag]
    for f in files:
        if f.suffix.lower() != ".db3" or not f.is_file():
            continue
        size = f.stat().st_size
        with f.open("rb") as fh:
            head = fh.read(100)
        if len(head) < 100 or not head.startswith(_SQLITE_MAGIC):
            continue  # not SQLite at all: the reader's own error names it
        page_size = int.from_bytes(head[16:18], "big")
        page_size = 65536 if page_size == 1 else page_size
        n_pages = int.from_bytes(head[28:32], "big")
        want = n_pages * page_size if n_pages and head[24:28] == head[92:96] else 0
        if size < want or (page_size and size % page_size):
            lost = (f"{want - size} of {want} bytes missing" if size < want
                    else f"{size} bytes, not a whole number of {page_size}-byte pages")
            raise GyrodriftValueError(
                f"{source}: truncated rosbag2 storage {f.name} ({lost}); SQLite would read "
                "the missing messages as zeros")


@contextlib.contextmanager
def _bag_errors(source: str, kind: str) -> Iterator[None]:
    """Any error of the bag parser (rosbags) on a damaged or truncated file, or on messages
    that are not what their connection says, as one GyrodriftValueError naming the file.
    (The parsers raise their own error classes, and on damaged data also KeyError,
    AssertionError, UnicodeDecodeError, struct.error, apsw errors, MemoryError for a
    corrupt length.)"""
    try:
        yield
    except (GyrodriftError, OSError, KeyboardInterrupt):
        raise
    except Exception as exc:
        detail = (str(exc).strip().splitlines() or [""])[0] or type(exc).__name__
        raise GyrodriftValueError(f"{source}: not a readable {kind} bag (damaged or "
                                  f"truncated?): {detail}") from exc


def bag_imu_topics(path: str | Path) -> dict[str, int]:
    """sensor_msgs/msg/Imu topics of a ROS bag -> message count.

    Examples
    --------
    >>> import tempfile
    >>> from rosbags.rosbag1 import Writer
    >>> from rosbags.typesys import Stores, get_typestore
    >>> ts = get_typestore(Stores.ROS1_NOETIC)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = Path(d) / "run.bag"
    ...     with Writer(path) as w:
    ...         _ = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
    ...         _ = w.add_connection("/note", "std_msgs/msg/String", typestore=ts)
    ...     print(bag_imu_topics(path))  # the Imu topics only, with their message counts
    {'/imu': 0}
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"no such file: {p}")
    if not (p.is_file() or p.is_dir()):
        raise GyrodriftValueError(f"{p}: not a regular file (a FIFO, socket or device); give "
                                  "a record file")
    kind = input_kind(p)
    out: dict[str, int] = {}
    with _bag_errors(str(p), kind), _open_bag(_bag_paths(p, kind)) as reader:
        for c in reader.connections:
            if c.msgtype in IMU_MSGTYPES:
                out[c.topic] = out.get(c.topic, 0) + int(c.msgcount)
    return out


def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


#: Messages of a ROS bag deserialized per block: each block's values go to the record's
#: SampleSpool objects before the next block is read.
BAG_BLOCK_MESSAGES = 1 << 16
#: Messages from which a ROS bag's seven columns (six channels and the time stamps) go to
#: temporary files: together they keep in memory what one column of SPOOL_MIN_SAMPLES
#: samples would (8 MB).
BAG_SPOOL_MIN_MESSAGES = SPOOL_MIN_SAMPLES // 7

#: Index entries of a rosbag1 topic held at a time by the lean reader (each about 140 bytes).
LEAN_INDEX_BLOCK = 1 << 14

_LEAN_READER1: type | None = None


def _lean_rosbag1_reader() -> type:
    """rosbags' rosbag1 ``Reader`` without its in-memory index of every message (about 140
    bytes per message). It reads and checks every index record at opening as rosbags does
    (the message counts come from them), but keeps only where each record is. `messages`
    of connections whose index times never decrease (each one's sorted order is its index
    order, so their merge is the order rosbags yields) merges the connections' index records
    as it reads them and lets rosbags' own `messages` read `LEAN_INDEX_BLOCK` merged entries
    at a time. A connection whose times decrease somewhere reads the whole index first, and
    the request is rosbags' `messages` unchanged."""
    global _LEAN_READER1
    if _LEAN_READER1 is not None:
        return _LEAN_READER1
    from collections import defaultdict
    from collections.abc import Collection, Generator

    from rosbags.interfaces import Connection
    from rosbags.rosbag1 import Reader

    class LeanReader1(Reader):
        def open(self) -> None:
            # connection id -> (chunk position, file position of its index record) in the
            # order rosbags reads them; message count; time order; last time
            self._records: dict[int, list[tuple[int, int]]] = defaultdict(list)
            self._counts: dict[int, int] = defaultdict(int)
            self._ordered: dict[int, bool] = defaultdict(lambda: True)
            self._last: dict[int, int] = {}
            super().open()
            self.connections = [c._replace(msgcount=self._counts[c.id])
                                for c in self.connections]

        def read_index_data(self, pos: int, indexes: dict[int, list[Any]]) -> None:
            assert self.bio is not None
            where = self.bio.tell()
            got: dict[int, list[Any]] = defaultdict(list)
            super().read_index_data(pos, got)  # rosbags' own parse and checks
            for conn, entries in got.items():
                self._records[conn].append((pos, where))
                self._counts[conn] += len(entries)
                times = [e.time for e in entries]
                if conn in self._last:
                    times.insert(0, self._last[conn])
                if times:
                    self._last[conn] = times[-1]
                if any(b < a for a, b in itertools.pairwise(times)):
                    self._ordered[conn] = False

        def _read_index(self, conn: int) -> list[Any]:
            assert self.bio is not None
            got: dict[int, list[Any]] = defaultdict(list)
            for pos, where in self._records.get(conn, []):
                self.bio.seek(where)
                super().read_index_data(pos, got)
            return got[conn]

        def _entries(self, cid: int) -> Iterator[tuple[Any, int]]:
            """Connection `cid`'s index entries (with `cid`) in file order, one index
            record at a time."""
            for pos, where in list(self._records.get(cid, [])):
                assert self.bio is not None
                self.bio.seek(where)
                got: dict[int, list[Any]] = defaultdict(list)
                super().read_index_data(pos, got)
                for entry in got[cid]:
                    yield entry, cid

        def messages(self, connections: Collection[Connection] = (),
                     start: int | None = None, stop: int | None = None
                     ) -> Generator[tuple[Connection, int, bytes], None, None]:
            self._check_open()
            conns = list(connections) or list(self.connections)
            if not all(self._ordered[c.id] for c in conns):
                self.indexes = {c.id: sorted(self._read_index(c.id)) for c in conns}
                yield from super().messages(connections, start, stop)
                return
            # each connection's entries are sorted, so their merge is rosbags' order; a
            # block of it split by connection is what rosbags' own merge yields in turn
            merged = heapq.merge(*(self._entries(c.id) for c in conns))
            while block := list(itertools.islice(merged, LEAN_INDEX_BLOCK)):
                split: dict[int, list[Any]] = {c.id: [] for c in conns}
                for entry, cid in block:
                    split[cid].append(entry)
                self.indexes = split
                yield from super().messages(conns, start, stop)
                if stop is not None and block[-1][0].time >= stop:
                    break
            self.indexes = {}

    _LEAN_READER1 = LeanReader1
    return LeanReader1


@contextlib.contextmanager
def _open_bag(bag: Path) -> Iterator[Any]:
    """rosbags' ``AnyReader`` on `bag`, open; a rosbag1 bag through `_lean_rosbag1_reader`
    (the same connections, counts, messages and errors, without a per-message index)."""
    from rosbags.highlevel import AnyReader

    reader = AnyReader([bag], default_typestore=_typestore())
    if not reader.is2:
        reader.readers = [_lean_rosbag1_reader()(bag)]
    with reader:
        yield reader


def _load_bag(p: Path, kind: str, topic: str | None, rate_hz: float | None,
              nan_policy: str, *, block_messages: int = BAG_BLOCK_MESSAGES,
              memory_max: int = BAG_SPOOL_MIN_MESSAGES) -> ImuData:
    """The bag's Imu topic read `block_messages` messages at a time into SampleSpool
    objects (from `memory_max` messages on, temporary files), the rate from the stamps,
    NaN/Inf refused or their rows dropped as `_finish` does."""
    source = str(p)
    bag = _bag_paths(p, kind)
    if kind == "rosbag2":
        _check_sqlite_complete(bag, source)
    with contextlib.ExitStack() as stack:
        spools = {name: stack.enter_context(SampleSpool(memory_max, name))
                  for name in (*CHANNELS, "t_s")}
        with _bag_errors(source, kind):
            topic, n, n_bad = _read_bag_imu(bag, source, topic, spools, nan_policy,
                                            block_messages)
        if n < 3:
            raise GyrodriftValueError(f"{source}: {topic}: {n} messages; too short for analysis")
        # Gaps and reordering are checked on the header stamps in bag order (the same check
        # as a CSV time column); times relative to the first keep the nanoseconds exact.
        t_rate = rate_from_time(spools["t_s"].finish(), f"{source} {topic}")
        rate = t_rate if rate_hz is None else rate_hz
        if n_bad and nan_policy != "drop":
            raise GyrodriftValueError(
                f"{source}: {n_bad} of {n} samples have NaN/Inf channels; "
                "pass nan_policy='drop' (CLI: --drop-nan) to remove them")
        cols = {name: spools[name].finish() for name in CHANNELS}
    return ImuData(cols, float(rate), source, kind, n, n_bad,
                   {"topic": topic, "units_in": "rad/s, m/s^2 (sensor_msgs/Imu)"})


def _read_bag_imu(bag: Path, source: str, topic: str | None, spools: dict[str, SampleSpool],
                  nan_policy: str, block_messages: int = BAG_BLOCK_MESSAGES
                  ) -> tuple[str, int, int]:
    """(topic, message count, rows with a NaN/Inf value) of the bag's one (or the chosen)
    sensor_msgs/msg/Imu topic, its messages deserialized `block_messages` at a time and
    appended to `spools`: the gyro and accelerometer channels (CHANNELS; the rows with a
    NaN/Inf value left out under nan_policy "drop", no row once one is found otherwise) and
    "t_s", the header stamps (the bag's receive time where a stamp is zero) in seconds from
    the first. Every message the index counts must be read and deserialize as an Imu."""
    if block_messages < 1:
        raise GyrodriftValueError(f"block_messages must be >= 1, got {block_messages}")
    with _open_bag(bag) as reader:
        imu: dict[str, list[Any]] = {}
        for c in reader.connections:
            if c.msgtype in IMU_MSGTYPES:
                imu.setdefault(c.topic, []).append(c)
        listing = ", ".join(f"{t} ({sum(int(c.msgcount) for c in cs)} messages)"
                            for t, cs in sorted(imu.items())) or "none"
        if topic is None:
            if len(imu) != 1:
                raise GyrodriftValueError(
                    f"{source}: choose a sensor_msgs/msg/Imu topic with --topic; "
                    f"the bag has: {listing}")
            topic = next(iter(imu))
        if topic not in imu:
            other = sorted({c.msgtype for c in reader.connections if c.topic == topic})
            what = (f"topic {topic!r} carries {', '.join(other)}, not sensor_msgs/msg/Imu"
                    if other else f"no sensor_msgs/msg/Imu topic {topic!r}")
            raise GyrodriftValueError(f"{source}: {what}; the bag's Imu topics: {listing}")
        conns = imu[topic]
        n = sum(int(c.msgcount) for c in conns)
        rows = max(1, min(block_messages, n))
        vals = np.empty((rows, 6))
        t_ns = np.empty(rows, dtype=np.int64)
        t0: list[np.int64] = []  # the first message's time
        n_bad = 0

        def flush(m: int) -> None:
            nonlocal n_bad
            if m == 0:
                return
            if not t0:
                t0.append(t_ns[0])
            spools["t_s"].append((t_ns[:m] - t0[0]).astype(np.float64) * 1e-9)
            ok = np.all(np.isfinite(vals[:m]), axis=1)
            bad = m - int(np.count_nonzero(ok))
            n_bad += bad
            if n_bad and nan_policy != "drop":
                return  # counted, never kept: the record is refused
            for j, name in enumerate(CHANNELS):
                spools[name].append(vals[:m, j] if bad == 0 else vals[:m, j][ok])

        i = k = 0
        for conn, bag_t_ns, raw in reader.messages(connections=conns):
            if i >= n:
                raise GyrodriftValueError(
                    f"{source}: more {topic} messages than the bag index says")
            try:
                msg: Any = reader.deserialize(raw, conn.msgtype)
                st = msg.header.stamp
                stamp = int(st.sec) * 1_000_000_000 + int(st.nanosec)
                w, a = msg.angular_velocity, msg.linear_acceleration
                vals[k] = (w.x, w.y, w.z, a.x, a.y, a.z)
            except Exception as exc:  # any parser error: the message is not an Imu
                detail = (str(exc).strip().splitlines() or [""])[0] or type(exc).__name__
                raise GyrodriftValueError(
                    f"{source}: {topic}: message {i} is not a valid {conn.msgtype} "
                    f"({detail})") from exc
            t_ns[k] = stamp if stamp > 0 else int(bag_t_ns)
            i += 1
            k += 1
            if k == rows:
                flush(k)
                k = 0
        flush(k)
    if i != n:
        raise GyrodriftValueError(f"{source}: {topic}: read {i} messages, the bag index says {n}")
    return topic, n, n_bad


# ------------------------------------------------------------------------ units plausibility

#: Kinds of input (:func:`input_kind`) whose format carries its units (logs and bags: rad/s
#: and m/s^2, sensor_msgs/Imu by definition; PSINS: angle and velocity increments); a .npy
#: or text record does not, and its units must be stated.
UNITS_CARRIED_KINDS: tuple[str, ...] = ("psins", "replay-log", "rosbag1", "rosbag2")
#: A static accelerometer triad reads 1 g; its median magnitude is taken to contradict the
#: declared unit when it lies outside this band (in g) while another unit puts it inside
#: STATIC_G_LIKELY.
STATIC_G_BAND = (0.5, 2.0)
STATIC_G_LIKELY = (0.8, 1.25)
#: A record is static when the accelerometer magnitude varies by less than this fraction of
#: its median (10th to 90th percentile) and the mean vector keeps 95 % of that magnitude.
STATIC_SPREAD = 0.2
#: Largest gyro-triad mean magnitude at rest taken as plausible, deg/h: Earth rate
#: (15.04 deg/h) plus the bias of a consumer MEMS gyro (up to about 5 deg/s).
STATIC_GYRO_MAX_DEG_H = 2.0e4
#: Below this white-noise level (deg/sqrt(h), from the per-sample standard deviation) no gyro
#: built is that quiet (the best ring-laser gyros: about 1e-4 deg/sqrt(h)).
QUIETEST_GYRO_DEG_RT_H = 1.0e-5
_SAMPLE_ROWS = 200_000


def units_carried(path: str | Path) -> bool:
    """Whether the file format at `path` carries its units (:data:`UNITS_CARRIED_KINDS`;
    the single-channel reader's IMU CSV of the replay harness is a replay log too).

    Examples
    --------
    >>> units_carried("imu.bin"), units_carried("imu.npy"), units_carried("imu.imu")
    (True, False, True)
    """
    return input_kind(path) in UNITS_CARRIED_KINDS


def _sample(x: np.ndarray) -> np.ndarray:
    step = max(1, int(x.shape[0]) // _SAMPLE_ROWS)
    if is_file_backed(x):  # every step-th sample, read from the file (not through the map)
        v = np.concatenate([p[::step] for p in iter_chunks(x, step * (BLOCK_ROWS // step + 1))])
    else:
        v = np.asarray(x[::step], dtype=np.float64)
    return v[np.isfinite(v)] if v.ndim == 1 else v


def _unit_factor(unit: str, table: dict[str, float], rate_hz: float) -> float:
    return table[unit] * (rate_hz if unit in _INCREMENT_UNITS else 1.0)


def check_units_plausible(rec: ImuData, gyro_units: str, accel_units: str) -> None:
    """Refuse a static record whose values contradict the declared units by a large factor,
    naming the likely unit (docs: guides/units.md). Only clear contradictions are refused:

    - the record is static when it has all three accelerometer axes, their magnitude varies
      by less than STATIC_SPREAD of its median and the mean vector keeps 95 % of it;
    - accelerometer: a median magnitude outside STATIC_G_BAND (in g) while another unit puts
      it inside STATIC_G_LIKELY ("1.0 m/s^2 looks like g");
    - gyro triad (static only): a mean magnitude above STATIC_GYRO_MAX_DEG_H while deg/h puts
      it at or below that; or, declared deg/h, a mean magnitude below 1 deg/h (a triad at
      rest measures Earth rate, 15 deg/h, plus its bias) with a white-noise level below
      QUIETEST_GYRO_DEG_RT_H while rad/s or deg/s puts the mean between 1 deg/h and
      STATIC_GYRO_MAX_DEG_H.

    `rec` holds the channels converted with the declared units (rad/s, m/s^2).

    Raises
    ------
    GyrodriftValueError
        naming the record, the declared unit, what was measured and the likely unit.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> a = {f"accel_{k}": rng.normal(v, 1e-3, 1000) for k, v in zip("xyz", (0.0, 0.0, 1.0))}
    >>> rec = ImuData(a, 100.0, "imu.npy", "npy", 1000)   # g values read as m/s^2
    >>> try:
    ...     check_units_plausible(rec, "rad/s", "m/s^2")
    ... except GyrodriftValueError as exc:
    ...     print(str(exc).split("): ")[-1])
    the data look like g; give the right units (command line: --accel-units g)
    """
    if not all(f"accel_{k}" in rec.channels for k in "xyz"):
        return
    acc = np.column_stack([_sample(rec.channels[f"accel_{k}"]) for k in "xyz"])
    acc = acc[np.all(np.isfinite(acc), axis=1)]
    if acc.shape[0] < 3:
        return
    norm = np.linalg.norm(acc, axis=1)
    med = float(np.median(norm))
    if not med > 0.0:
        return
    p10, p90 = np.percentile(norm, [10.0, 90.0])
    if (p90 - p10) / med > STATIC_SPREAD or np.linalg.norm(acc.mean(axis=0)) < 0.95 * med:
        return  # not static: the magnitude says nothing about the unit
    g0 = units.G0_M_S2
    rate = rec.rate_hz
    raw = med / _unit_factor(accel_units, ACCEL_UNITS, rate)
    if not STATIC_G_BAND[0] <= med / g0 <= STATIC_G_BAND[1]:
        likely = [u for u in ACCEL_UNITS if u != accel_units and STATIC_G_LIKELY[0]
                  <= raw * _unit_factor(u, ACCEL_UNITS, rate) / g0 <= STATIC_G_LIKELY[1]]
        if likely:
            raise GyrodriftValueError(
                f"{rec.source}: the accelerometer magnitude at rest is {med:.3g} m/s^2 with "
                f"accelerometer units {accel_units} (1 g = {g0} m/s^2 expected): the data look "
                f"like {likely[0]}; give the right units (command line: --accel-units "
                f"{likely[0]})")
    if not all(f"gyro_{k}" in rec.channels for k in "xyz"):
        return
    gyr = np.column_stack([_sample(rec.channels[f"gyro_{k}"]) for k in "xyz"])
    gyr = gyr[np.all(np.isfinite(gyr), axis=1)]
    if gyr.shape[0] < 3:
        return
    to_deg_h = RATE_UNITS["deg/h"].to_rad_s
    mean_deg_h = float(np.linalg.norm(gyr.mean(axis=0))) / to_deg_h
    raw_w = mean_deg_h * to_deg_h / _unit_factor(gyro_units, GYRO_UNITS, rate)

    def as_deg_h(u: str) -> float:
        return raw_w * _unit_factor(u, GYRO_UNITS, rate) / to_deg_h

    def refuse(what: str, likely: str) -> None:
        raise GyrodriftValueError(
            f"{rec.source}: the gyro triad reads {mean_deg_h:.3g} deg/h at rest with gyro "
            f"units {gyro_units} ({what}): the data look like {likely}; give the right units "
            f"(command line: --gyro-units)")

    if mean_deg_h > STATIC_GYRO_MAX_DEG_H and as_deg_h("deg/h") <= STATIC_GYRO_MAX_DEG_H:
        refuse("Earth rate 15 deg/h plus any gyro bias is far less", "deg/h")
    if gyro_units == "deg/h" and mean_deg_h < 1.0:
        n_deg_rt_h = float(np.median(gyr.std(axis=0))) / to_deg_h / math.sqrt(rate) / 60.0
        likely = [u for u in ("rad/s", "deg/s") if 1.0 <= as_deg_h(u) <= STATIC_GYRO_MAX_DEG_H]
        if 0.0 < n_deg_rt_h < QUIETEST_GYRO_DEG_RT_H and likely:
            refuse(f"Earth rate is 15 deg/h, and a white-noise level of {n_deg_rt_h:.2g} "
                   "deg/sqrt(h) is below any gyro built", " or ".join(likely))
