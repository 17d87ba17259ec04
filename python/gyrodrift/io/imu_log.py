"""IMU record logs in every format the replay harness reads: the project's binary frame log,
CSV, and CAN logs (candump `.log`, Vector `.asc`, `.blf`) through python-can's writers/readers.

`write_imu_log` is also what `gyrodrift simulate` calls, so that a replay works with no
recorded input. `read_imu_log` returns a whole log; `ImuLogBlocks` gives the same samples in
blocks, in bounded memory (what the analysis readers use).
"""

from __future__ import annotations

import csv
import os
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from gyrodrift.codecs import FRAME_SIZE, INPUT_BASE_ID, TYPE_INPUT, SampleAssembler, encode_sample
from gyrodrift.codecs.can_signals import (
    SignalMap,
    SignalSampleAssembler,
    decode_table_text,
    load_signal_map,
)
from gyrodrift.codecs.wire import (
    Samples,
    StreamDecoder,
    encode_frames,
    make_samples,
)
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.io.atomic import atomic_output, atomic_write_text

__all__ = [
    "BLOCK_SAMPLES",
    "CAN_FORMATS",
    "CHUNK_BYTES",
    "CSV_COLUMNS",
    "FORMATS",
    "SUFFIX_FORMATS",
    "ImuLogBlocks",
    "log_format",
    "read_imu_log",
    "write_decode_table",
    "write_imu_log",
    "write_samples",
]

# Suffix -> format name. "bin" is a plain concatenation of 42-byte input frames, exactly the
# bytes the IMU puts on its serial line.
SUFFIX_FORMATS: dict[str, str] = {
    ".bin": "bin",
    ".gdf": "bin",
    ".csv": "csv",
    ".log": "candump",
    ".asc": "asc",
    ".blf": "blf",
}
FORMATS: tuple[str, ...] = ("bin", "csv", "candump", "asc", "blf")
CAN_FORMATS: tuple[str, ...] = ("candump", "asc", "blf")
CSV_COLUMNS: tuple[str, ...] = (
    "t_s", "seq", "flags", "gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s",
    "accel_x_m_s2", "accel_y_m_s2", "accel_z_m_s2",
)


@dataclass
class CanLogReport:
    """Where every frame of a CAN log went (`read_imu_log` of a candump/asc/blf log).

    frames_total == imu_frames_used + imu_frames_dropped + imu_frames_ignored + remote_frames
    + error_frames + sum(foreign_frames_by_id.values()). Foreign frames are counted by ID:
    standard IDs as '0x123', extended ones as '0x18fef100 ext' (an extended frame is never
    the IMU's, whatever its number). imu_frames_dropped are IMU-ID frames that did not make a
    complete sample (incomplete samples at the start and end of a capture, orphan or duplicate
    halves, a bad DLC); incomplete_samples counts such samples. With a user's DBC
    (`signals=`), imu_frames_ignored are frames of its mapped messages that carry none of the
    mapped signals (another multiplexer page).
    """

    frames_total: int = 0
    imu_samples: int = 0
    imu_frames_used: int = 0
    imu_frames_dropped: int = 0
    incomplete_samples: int = 0
    orphan_frames: int = 0
    duplicate_frames: int = 0
    bad_dlc: int = 0
    imu_frames_ignored: int = 0  # user DBC: an IMU message carrying no mapped signal
    remote_frames: int = 0
    error_frames: int = 0
    foreign_frames_by_id: dict[str, int] = field(default_factory=dict)

    @property
    def foreign_frames(self) -> int:
        return sum(self.foreign_frames_by_id.values())

    @property
    def unaccounted(self) -> int:
        return (self.frames_total - self.imu_frames_used - self.imu_frames_dropped
                - self.imu_frames_ignored - self.remote_frames - self.error_frames
                - self.foreign_frames)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def summary(self) -> str:
        """One line: '1234 frames: 1000 IMU frames used (250 samples), ...'."""
        parts = [f"{self.frames_total} frames: {self.imu_frames_used} IMU frames used "
                 f"({self.imu_samples} samples)"]
        if self.imu_frames_dropped:
            parts.append(f"{self.imu_frames_dropped} IMU frames dropped "
                         f"({self.incomplete_samples} incomplete samples, {self.orphan_frames} "
                         f"orphan, {self.duplicate_frames} duplicate, {self.bad_dlc} bad DLC)")
        if self.imu_frames_ignored:
            parts.append(f"{self.imu_frames_ignored} IMU-message frames without mapped "
                         "signals")
        by_id = ", ".join(f"{k} {v}" for k, v in sorted(self.foreign_frames_by_id.items()))
        parts.append(f"foreign {self.foreign_frames}" + (f" ({by_id})" if by_id else ""))
        parts.append(f"remote {self.remote_frames}")
        parts.append(f"error {self.error_frames}")
        return ", ".join(parts)


def log_format(path: str | Path, fmt: str | None = None) -> str:
    """The format name of a log: `fmt` if given, else from the file suffix.

    Examples
    --------
    >>> log_format("flight.log"), log_format("bench.blf"), log_format("x.dat", "bin")
    ('candump', 'blf', 'bin')
    """
    if fmt is not None:
        if fmt not in FORMATS:
            raise GyrodriftValueError(f"unknown log format {fmt!r}; choose one of "
                                      f"{', '.join(FORMATS)}")
        return fmt
    suffix = Path(path).suffix.lower()
    if suffix not in SUFFIX_FORMATS:
        known = ", ".join(sorted(SUFFIX_FORMATS))
        raise GyrodriftValueError(f"cannot tell the log format of {path!s} from its suffix; "
                                  f"use one of {known} or pass fmt")
    return SUFFIX_FORMATS[suffix]


def write_imu_log(path: str | Path, t_s: np.ndarray, gyro_rad_s: np.ndarray,
                  accel_m_s2: np.ndarray, fmt: str | None = None) -> Path:
    """Write an IMU record (t_s (n,), gyro_rad_s (n, 3), accel_m_s2 (n, 3)) as a log file.

    The format comes from `fmt` ("bin", "csv", "candump", "asc", "blf") or the suffix. Values
    are stored as float32 (what the wire carries); sequence numbers count from 0 and wrap at
    65536. Returns the path written.

    Examples
    --------
    >>> import tempfile, os
    >>> path = os.path.join(tempfile.mkdtemp(), "imu.bin")
    >>> t = np.arange(5) / 400.0
    >>> write_imu_log(path, t, np.zeros((5, 3)), np.zeros((5, 3))).suffix
    '.bin'
    """
    path = Path(path)
    kind = log_format(path, fmt)
    samples = make_samples(t_s, gyro_rad_s, accel_m_s2)
    write_samples(path, samples, kind)
    return path


def write_decode_table(smap: SignalMap, path: str | Path) -> Path:
    """Write the decode table of a user's DBC
    (:func:`gyrodrift.codecs.can_signals.decode_table_text`) to `path` for
    ``gyrodrift-loop --can-signals``, by the one output rule
    (:mod:`gyrodrift.io.atomic`: a file replaced whole or not at all, a link followed, a
    device or FIFO written through); returns the path.

    Examples
    --------
    >>> import tempfile
    >>> from gyrodrift.codecs.can_frames import load_dbc
    >>> from gyrodrift.codecs.can_signals import SignalRef
    >>> names = dict(gx="IMU_GyroXY.GyroX", gy="IMU_GyroXY.GyroY", gz="IMU_GyroZ.GyroZ",
    ...              ax="IMU_AccelXY.AccelX", ay="IMU_AccelXY.AccelY", az="IMU_AccelZ.AccelZ")
    >>> smap = SignalMap(load_dbc(), {r: SignalRef(*s.split(".")) for r, s in names.items()})
    >>> with tempfile.TemporaryDirectory() as d:
    ...     print(write_decode_table(smap, Path(d) / "imu.cansig").read_text().splitlines()[0])
    gyrodrift-can-signals 1
    """
    return atomic_write_text(path, decode_table_text(smap))


def write_samples(path: str | Path, samples: Samples, fmt: str | None = None) -> Path:
    """Write wire-typed samples as a log (binary frames, CSV or a CAN log by the suffix or `fmt`).

    Examples
    --------
    >>> import tempfile
    >>> s = make_samples(np.arange(3) / 400.0, np.zeros((3, 3)), np.zeros((3, 3)))
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = write_samples(Path(d) / "rec.bin", s)
    ...     print(path.stat().st_size, read_imu_log(path).seq)
    126 [0 1 2]
    """
    path = Path(path)
    kind = log_format(path, fmt)
    with atomic_output(path) as tmp:  # the one output rule (gyrodrift.io.atomic)
        _write_samples(path.name, tmp, samples, kind)
    return path


def _write_samples(name: str, path: Path, samples: Samples, kind: str) -> None:
    if kind == "bin":
        path.write_bytes(encode_frames(samples, TYPE_INPUT).tobytes())
    elif kind == "csv":
        with path.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(CSV_COLUMNS)
            t_s = samples.t_s
            for k in range(len(samples)):
                # repr of a float32 widened to float64 round-trips exactly.
                w.writerow([f"{t_s[k]:.6f}", int(samples.seq[k]), int(samples.flags[k]),
                            *(repr(float(v)) for v in samples.channels[k])])
    else:
        # python-can picks the writer (CanutilsLogWriter, ASCWriter, BLFWriter) from the suffix.
        suffix = {"candump": ".log", "asc": ".asc", "blf": ".blf"}[kind]
        if path.suffix.lower() != suffix:
            raise GyrodriftValueError(f"{kind} logs must end in {suffix}, got {name}")
        t_s = samples.t_s
        with can.Logger(str(path)) as writer:
            for k in range(len(samples)):
                # The DBC encoding (cantools) of the sample's four frames, all at its time.
                for m in encode_sample(int(samples.seq[k]), samples.channels[k],
                                       flags=int(samples.flags[k]), base_id=INPUT_BASE_ID):
                    m.timestamp = float(t_s[k])
                    m.channel = 0
                    writer.on_message_received(m)


def read_imu_log(path: str | Path, fmt: str | None = None, *,
                 signals: SignalMap | str | Path | None = None) -> Samples:
    """Read a log back as wire samples (seq, flags, t_us, float32 channels).

    A binary log with CRC errors, garbage or a truncated tail raises ValueError (a frame log
    is the IMU's own stream: damage means a broken file). A CAN log is a bus capture: frames
    of other nodes (by ID), remote and error frames, and the frames of samples that are
    incomplete in the capture (its first and last, typically) are skipped and counted in
    `samples.log_report` (a `CanLogReport`, which accounts for every frame of the log); only
    a CAN log with no complete IMU sample is refused.

    signals: a user's own DBC for CAN logs, as a signal map (`gyrodrift.codecs.can_signals`:
    a SignalMap or the path of its TOML file): the frames are decoded by cantools through
    the map instead of the project's DBC; t_us is the IMU's own timestamp when the map has
    one, else the log's time.

    The whole log in memory: :class:`ImuLogBlocks` gives the same samples in blocks.

    Examples
    --------
    >>> import tempfile, os
    >>> path = os.path.join(tempfile.mkdtemp(), "imu.bin")
    >>> _ = write_imu_log(path, np.arange(5) / 400.0, np.ones((5, 3)), np.zeros((5, 3)))
    >>> s = read_imu_log(path)
    >>> len(s), s.channels.shape, float(s.channels[0, 0])
    (5, (5, 6), 1.0)
    """
    blocks = ImuLogBlocks(path, fmt, signals=signals)
    parts = list(blocks)
    return Samples(np.concatenate([b.seq for b in parts]),
                   np.concatenate([b.flags for b in parts]),
                   np.concatenate([b.t_us for b in parts]),
                   np.concatenate([b.channels for b in parts]).reshape(-1, 6),
                   log_report=blocks.report)


#: Bytes of a binary frame log read at a time (about 25000 frames).
CHUNK_BYTES = 1 << 20
#: Samples of a CAN log or CSV log per block (a CAN log's decoded frames and a CSV's rows
#: are Python objects while a block is made: a few hundred bytes per sample).
BLOCK_SAMPLES = 1 << 13


class ImuLogBlocks:
    """The samples of an IMU log (:func:`read_imu_log`'s formats and checks) in blocks of
    wire samples, in bounded memory whatever the log's length: a binary log decoded
    `chunk_bytes` at a time (frames cut by a chunk's end carried to the next,
    :class:`gyrodrift.codecs.wire.StreamDecoder`), a CAN log's frames reassembled and
    handed on every `block_samples` samples, a CSV log parsed `block_samples` rows at a
    time. The blocks put together are :func:`read_imu_log`'s samples, and every count and
    error is the same: a damaged binary log, a CSV whose times go back and a CAN log without
    a sample raise when the iteration reaches the end of the file (after the last block);
    a row of a CSV that is not 9 numbers raises when its block is parsed.

    After the iteration, `report` is the CAN log's :class:`CanLogReport` (None for a
    binary or CSV log). The path, format and signal map are checked when the object is
    made; every iteration reads the file again.

    Parameters
    ----------
    path, fmt, signals
        as :func:`read_imu_log`.
    block_samples
        samples per block of a CAN or CSV log (default :data:`BLOCK_SAMPLES`).
    chunk_bytes
        bytes of a binary log decoded at a time (default :data:`CHUNK_BYTES`).

    Examples
    --------
    >>> import tempfile, os
    >>> path = os.path.join(tempfile.mkdtemp(), "imu.log")
    >>> _ = write_imu_log(path, np.arange(5) / 400.0, np.ones((5, 3)), np.zeros((5, 3)))
    >>> blocks = ImuLogBlocks(path, block_samples=2)
    >>> [b.seq.tolist() for b in blocks]
    [[0, 1], [2, 3], [4]]
    >>> blocks.report.imu_frames_used
    20
    """

    def __init__(self, path: str | Path, fmt: str | None = None, *,
                 signals: SignalMap | str | Path | None = None,
                 block_samples: int | None = None, chunk_bytes: int | None = None) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise FileNotFoundError(f"no such log: {self.path}")
        self.kind = log_format(self.path, fmt)
        if signals is not None and self.kind not in CAN_FORMATS:
            raise GyrodriftValueError(f"{self.path}: a DBC signal map applies to CAN logs "
                                      f"({', '.join(CAN_FORMATS)}), not to {self.kind}")
        self._smap: SignalMap | None = None
        if signals is not None:
            self._smap = signals if isinstance(signals, SignalMap) else load_signal_map(signals)
        self.block_samples = int(BLOCK_SAMPLES if block_samples is None else block_samples)
        self.chunk_bytes = int(CHUNK_BYTES if chunk_bytes is None else chunk_bytes)
        if self.block_samples < 1 or self.chunk_bytes < 1:
            raise GyrodriftValueError("block_samples and chunk_bytes must be >= 1")
        # the CAN log's frame accounting, once the iteration ended (None for other logs)
        self.report: CanLogReport | None = None

    def __iter__(self) -> Iterator[Samples]:
        self.report = None
        if self.kind == "bin":
            return self._bin()
        if self.kind == "csv":
            return _csv_blocks(self.path, self.block_samples)
        if self._smap is not None:
            return self._can(self._smap)
        return self._can(None)

    def _bin(self) -> Iterator[Samples]:
        path = self.path
        dec = StreamDecoder()
        non_input = 0
        with path.open("rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            if size < FRAME_SIZE:
                raise GyrodriftValueError(f"{path}: {size} bytes, shorter than one "
                                          f"{FRAME_SIZE}-byte frame")
            while True:
                data = fh.read(self.chunk_bytes)
                part = dec.feed(data, final=not data)
                non_input += int(np.count_nonzero(part.frame_type != TYPE_INPUT))
                if len(part.samples):
                    yield part.samples
                if not data:
                    break
        bad = {"crc_errors": dec.crc_errors, "garbage_bytes": dec.garbage_bytes,
               "truncated_bytes": dec.truncated_bytes, "non_input_frames": non_input}
        if any(bad.values()):
            raise GyrodriftValueError(f"{path}: corrupted binary frame log: {bad}")

    def _can(self, smap: SignalMap | None) -> Iterator[Samples]:
        rep = CanLogReport()
        blocks = (_can_log_blocks(self.path, rep, self.block_samples) if smap is None
                  else _can_log_blocks_with_map(self.path, smap, rep, self.block_samples))
        yield from blocks
        self.report = rep


def _frame_key(m: can.Message) -> str:
    """How a foreign frame is counted: its ID, standard '0x123' or extended '0x18fef100 ext'."""
    if m.is_extended_id:
        return f"{m.arbitration_id:#010x} ext"
    return f"{m.arbitration_id:#05x}"


def _imu_frames(path: Path, rep: CanLogReport,
                is_imu: Callable[[can.Message], bool]) -> Iterator[can.Message]:
    """The IMU's data frames of a CAN log; every other frame is counted in `rep` (error and
    remote frames separately, foreign data frames by ID) and skipped."""
    for m in can.LogReader(str(path)):
        rep.frames_total += 1
        if m.is_error_frame:
            rep.error_frames += 1
        elif m.is_remote_frame:
            rep.remote_frames += 1
        elif not is_imu(m):
            key = _frame_key(m)
            rep.foreign_frames_by_id[key] = rep.foreign_frames_by_id.get(key, 0) + 1
        else:
            yield m


class _SampleBlock:
    """Completed samples of a CAN log, collected until a block is full."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.n = 0
        self.seq: list[int] = []
        self.flags: list[int] = []
        self.values: list[tuple[float, ...]] = []
        self.stamps: list[float] = []  # the CAN-log reader: the log's times, in s
        self.stamps_us: list[int] = []  # the signal-map reader: the sample times, in us

    @property
    def full(self) -> bool:
        return len(self.seq) >= self.size

    def take(self, with_map: bool) -> Samples:
        """The collected samples as wire samples (the lists emptied), typed as the whole-log
        readers type them."""
        if with_map:
            out = Samples(np.asarray(self.seq, np.uint16), np.zeros(len(self.seq), np.uint16),
                          np.asarray(self.stamps_us, np.uint64),
                          np.asarray(self.values, np.float64).astype(np.float32)
                          .reshape(-1, 6))
        else:
            out = Samples(np.asarray(self.seq, np.uint16), np.asarray(self.flags, np.uint16),
                          np.round(np.asarray(self.stamps, np.float64) * 1e6).astype(np.uint64),
                          np.asarray(self.values, np.float32).reshape(-1, 6))
        self.n += len(self.seq)
        self.seq, self.flags, self.values, self.stamps, self.stamps_us = [], [], [], [], []
        return out


def _can_log_blocks(path: Path, rep: CanLogReport, block_samples: int) -> Iterator[Samples]:
    """IMU samples of a CAN log in blocks; every other frame is skipped and counted in `rep`
    (a bus capture normally carries other nodes' traffic). Refused only when no IMU sample
    is found."""
    asm = SampleAssembler(base_id=INPUT_BASE_ID)
    block = _SampleBlock(block_samples)

    def is_imu(m: can.Message) -> bool:
        return not m.is_extended_id and 0 <= m.arbitration_id - INPUT_BASE_ID < 4

    for m in _imu_frames(path, rep, is_imu):
        s = asm.push(m)
        if s is not None:
            block.seq.append(s.seq)
            block.flags.append(s.flags)
            block.values.append(s.values)
            block.stamps.append(m.timestamp)  # CAN carries no sample time: the log's time is it
            if block.full:
                yield block.take(with_map=False)
    asm.finish()
    st = asm.stats
    rep.imu_frames_used = st.frames_used
    rep.imu_frames_dropped = st.frames_dropped
    rep.incomplete_samples = st.incomplete_samples
    rep.orphan_frames = st.orphan_frames
    rep.duplicate_frames = st.duplicate_frames
    rep.bad_dlc = st.bad_dlc
    rep.imu_samples = block.n + len(block.seq)
    if rep.unaccounted:  # an internal error, never a property of the input
        raise AssertionError(f"{path}: CAN log accounting does not balance: {rep.as_dict()}")
    if not rep.imu_samples:
        raise GyrodriftValueError(f"{path}: no IMU samples (CAN IDs 0x100..0x103) in the log; "
                                  f"{rep.summary()}")
    if block.seq:
        yield block.take(with_map=False)


def _can_log_blocks_with_map(path: Path, smap: SignalMap, rep: CanLogReport,
                             block_samples: int) -> Iterator[Samples]:
    """IMU samples of a CAN log through a user's DBC and signal map, in blocks (the same
    accounting)."""
    asm = SignalSampleAssembler(smap)
    block = _SampleBlock(block_samples)
    for m in _imu_frames(path, rep, asm.is_mapped):
        s = asm.push(m)
        if s is not None:
            block.seq.append(s.seq)
            block.values.append(s.values)
            block.stamps_us.append(s.t_us if s.t_us is not None else round(m.timestamp * 1e6))
            if block.full:
                yield block.take(with_map=True)
    asm.finish()
    st = asm.stats
    rep.imu_frames_used = st.frames_used
    rep.imu_frames_dropped = st.frames_dropped
    rep.imu_frames_ignored = st.ignored_frames
    rep.incomplete_samples = st.incomplete_samples
    rep.bad_dlc = st.bad_dlc
    rep.imu_samples = block.n + len(block.seq)
    if rep.unaccounted:
        raise AssertionError(f"{path}: CAN log accounting does not balance: {rep.as_dict()}")
    if not rep.imu_samples:
        raise GyrodriftValueError(f"{path}: no IMU samples through the signal map {smap.source}; "
                                  f"{rep.summary()}")
    if block.seq:
        yield block.take(with_map=True)


def _csv_rows_array(path: Path, rows: list[list[str]], lines: list[int]) -> np.ndarray:
    """The rows of a CSV log block as an (m, 9) float64 array. The first row (in file order)
    that is not 9 numbers is refused, naming its line: the verdict does not depend on how
    the file is cut into blocks."""
    width = len(CSV_COLUMNS)
    wrong = next((k for k, r in enumerate(rows) if len(r) != width), len(rows))
    try:
        arr = np.asarray(rows[:wrong], dtype=np.float64).reshape(-1, width)
    except ValueError:
        for k, r in enumerate(rows[:wrong]):
            try:
                np.asarray(r, dtype=np.float64)
            except ValueError as exc:
                raise GyrodriftValueError(f"{path}: line {lines[k]}: non-numeric CSV field "
                                          f"({exc})") from None
        raise
    if wrong < len(rows):
        raise GyrodriftValueError(f"{path}: line {lines[wrong]}: expected {width} columns, "
                                  f"got {len(rows[wrong])}")
    return arr


def _csv_blocks(path: Path, block_samples: int) -> Iterator[Samples]:
    """The harness's CSV log in blocks of rows. Times that are not finite, negative or go
    back are refused after the last row (a malformed row later in the file is named
    first, as the whole-file parse does)."""
    n = 0
    bad_time = False
    last_t = -np.inf
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            if header is None or tuple(h.strip() for h in header) != CSV_COLUMNS:
                raise GyrodriftValueError(f"{path}: expected CSV header {','.join(CSV_COLUMNS)}")
            while True:
                rows: list[list[str]] = []
                lines: list[int] = []
                for r in reader:
                    if r:
                        rows.append(r)
                        lines.append(reader.line_num)
                        if len(rows) >= block_samples:
                            break
                if not rows:
                    break
                arr = _csv_rows_array(path, rows, lines)
                t_s = arr[:, 0]
                if not bad_time:
                    bad_time = (not np.all(np.isfinite(t_s)) or (n == 0 and t_s[0] < 0)
                                or t_s[0] < last_t or bool(np.any(np.diff(t_s) < 0)))
                    last_t = float(t_s[-1])
                n += arr.shape[0]
                yield Samples(arr[:, 1].astype(np.uint16), arr[:, 2].astype(np.uint16),
                              np.round(t_s * 1e6).astype(np.uint64),
                              arr[:, 3:9].astype(np.float32))
    except UnicodeDecodeError as exc:
        raise GyrodriftValueError(f"{path}: not a text CSV log (byte {exc.start} of a line "
                                  "is not UTF-8; a binary file?)") from None
    if n == 0:
        raise GyrodriftValueError(f"{path}: no data rows")
    if bad_time:
        raise GyrodriftValueError(f"{path}: t_s must be finite, >= 0 and non-decreasing")
