"""IMU record logs in every format the replay harness reads: the project's binary frame log,
CSV, and CAN logs (candump `.log`, Vector `.asc`, `.blf`) through python-can's writers/readers.

`write_imu_log` is also what `gyrodrift simulate` calls, so that a replay works with no
recorded input.
"""

from __future__ import annotations

import csv
from pathlib import Path

import can
import numpy as np

from gyrodrift.codecs import FRAME_SIZE, INPUT_BASE_ID, TYPE_INPUT, SampleAssembler, encode_sample
from gyrodrift.replay.wire import (
    Samples,
    decode_stream,
    encode_frames,
    make_samples,
)

__all__ = [
    "CAN_FORMATS",
    "CSV_COLUMNS",
    "FORMATS",
    "SUFFIX_FORMATS",
    "log_format",
    "read_imu_log",
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


def log_format(path: str | Path, fmt: str | None = None) -> str:
    """The format name of a log: `fmt` if given, else from the file suffix."""
    if fmt is not None:
        if fmt not in FORMATS:
            raise ValueError(f"unknown log format {fmt!r}; choose one of {', '.join(FORMATS)}")
        return fmt
    suffix = Path(path).suffix.lower()
    if suffix not in SUFFIX_FORMATS:
        known = ", ".join(sorted(SUFFIX_FORMATS))
        raise ValueError(f"cannot tell the log format of {path!s} from its suffix; "
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


def write_samples(path: str | Path, samples: Samples, fmt: str | None = None) -> Path:
    path = Path(path)
    kind = log_format(path, fmt)
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
            raise ValueError(f"{kind} logs must end in {suffix}, got {path.name}")
        t_s = samples.t_s
        with can.Logger(str(path)) as writer:
            for k in range(len(samples)):
                # The DBC encoding (cantools) of the sample's four frames, all at its time.
                for m in encode_sample(int(samples.seq[k]), samples.channels[k],
                                       flags=int(samples.flags[k]), base_id=INPUT_BASE_ID):
                    m.timestamp = float(t_s[k])
                    m.channel = 0
                    writer.on_message_received(m)
    return path


def read_imu_log(path: str | Path, fmt: str | None = None) -> Samples:
    """Read a log back as wire samples (seq, flags, t_us, float32 channels).

    Bad content is an error with the reason, never silently dropped: a binary log with CRC
    errors, garbage or a truncated tail, or a CAN log with incomplete samples, raises
    ValueError.

    Examples
    --------
    >>> import tempfile, os
    >>> path = os.path.join(tempfile.mkdtemp(), "imu.bin")
    >>> _ = write_imu_log(path, np.arange(5) / 400.0, np.ones((5, 3)), np.zeros((5, 3)))
    >>> s = read_imu_log(path)
    >>> len(s), s.channels.shape, float(s.channels[0, 0])
    (5, (5, 6), 1.0)
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no such log: {path}")
    kind = log_format(path, fmt)
    if kind == "bin":
        data = path.read_bytes()
        if len(data) < FRAME_SIZE:
            raise ValueError(f"{path}: {len(data)} bytes, shorter than one {FRAME_SIZE}-byte frame")
        dec = decode_stream(data)
        bad = {"crc_errors": dec.crc_errors, "garbage_bytes": dec.garbage_bytes,
               "truncated_bytes": dec.truncated_bytes,
               "non_input_frames": int(np.count_nonzero(dec.frame_type != TYPE_INPUT))}
        if any(bad.values()):
            raise ValueError(f"{path}: corrupted binary frame log: {bad}")
        return dec.samples
    if kind == "csv":
        return _read_csv(path)
    asm = SampleAssembler(base_id=INPUT_BASE_ID)
    seq: list[int] = []
    flags: list[int] = []
    values: list[tuple[float, ...]] = []
    stamps: list[float] = []
    for m in can.LogReader(str(path)):
        if m.is_error_frame:
            continue
        s = asm.push(m)
        if s is not None:
            seq.append(s.seq)
            flags.append(s.flags)
            values.append(s.values)
            stamps.append(m.timestamp)  # CAN carries no sample time: the log's time is it
    asm.finish()
    st = asm.stats
    if st.incomplete_samples or st.orphan_frames or st.foreign_frames or st.bad_dlc:
        raise ValueError(f"{path}: {st.incomplete_samples} incomplete samples (can_incomplete), "
                         f"{st.orphan_frames} orphan frames, {st.foreign_frames} frames with "
                         f"foreign IDs, {st.bad_dlc} with a bad DLC")
    if not seq:
        raise ValueError(f"{path}: no IMU samples (CAN IDs 0x100..0x103) in the log")
    return Samples(np.asarray(seq, np.uint16), np.asarray(flags, np.uint16),
                   np.round(np.asarray(stamps) * 1e6).astype(np.uint64),
                   np.asarray(values, np.float32).reshape(-1, 6))


def _read_csv(path: Path) -> Samples:
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None or tuple(h.strip() for h in header) != CSV_COLUMNS:
            raise ValueError(f"{path}: expected CSV header {','.join(CSV_COLUMNS)}")
        rows = [r for r in reader if r]
    if not rows:
        raise ValueError(f"{path}: no data rows")
    try:
        arr = np.asarray(rows, dtype=np.float64)
    except ValueError as exc:
        raise ValueError(f"{path}: non-numeric CSV field ({exc})") from None
    if arr.shape[1] != len(CSV_COLUMNS):
        raise ValueError(f"{path}: expected {len(CSV_COLUMNS)} columns, got {arr.shape[1]}")
    t_s = arr[:, 0]
    if not np.all(np.isfinite(t_s)) or t_s[0] < 0 or np.any(np.diff(t_s) < 0):
        raise ValueError(f"{path}: t_s must be finite, >= 0 and non-decreasing")
    return Samples(arr[:, 1].astype(np.uint16), arr[:, 2].astype(np.uint16),
                   np.round(t_s * 1e6).astype(np.uint64), arr[:, 3:9].astype(np.float32))
