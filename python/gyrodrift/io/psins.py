"""Reader for the PSINS text IMU log format (e.g. lasergyro.imu) and the
real-data alignment-consistency run.

Format (the file's own header): `%` comment lines; data line 1 = pitch0, roll0, yaw0 (deg),
VE0, VN0, VU0 (m/s); line 2 = lat0 (deg), lon0 (deg), h0 (m), t0 (s), sampling interval (ms),
g (m/s^2); line 3 = gyro scale factors (arcsec/count) x3, accelerometer scale factors
(ug*s/count) x3; then one line of six integer counts gx gy gz ax ay az per sample.
Axes X right, Y forward, Z up (the same body frame as this package).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrodrift.defaults import RATE_MAX_HZ, RATE_MIN_HZ
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.units import ARCSEC, DEG, UG

__all__ = [
    "BLOCK_LINES",
    "PsinsBlocks",
    "PsinsRecord",
    "read_psins_imu",
]


@dataclass
class PsinsRecord:
    """A PSINS IMU log: initial attitude (deg) and velocity, position, timing, and the per-sample
    increments (rad, m/s).

    Examples
    --------
    >>> rec = PsinsRecord(np.zeros(3), np.zeros(3), 0.6, 2.0, 380.0, 0.0, 0.01, 9.79,
    ...                   np.zeros((5, 3)), np.zeros((5, 3)))
    >>> rec.dt_s, rec.dtheta.shape
    (0.01, (5, 3))
    """
    att0_deg: np.ndarray  # pitch, roll, yaw (approximate, as written in the file)
    vn0_m_s: np.ndarray
    lat_rad: float
    lon_rad: float
    h_m: float
    t0_s: float
    dt_s: float
    g_m_s2: float
    dtheta: np.ndarray  # (n, 3) rad
    dv: np.ndarray  # (n, 3) m/s


def read_psins_imu(path: str | Path) -> PsinsRecord:
    """Parse a PSINS IMU log. Raises ValueError with the line number on malformed input.
    The whole log in memory: :class:`PsinsBlocks` gives the same increments in blocks.

    Examples
    --------
    >>> import tempfile
    >>> text = ("% a PSINS log\\n0 0 30 0 0 0\\n34.2 108.9 380 0 10 9.79\\n"
    ...         "0.01 0.01 0.01 50 50 50\\n1 2 3 0 0 196\\n1 2 3 0 0 196\\n")
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = Path(d) / "bench.imu"
    ...     _ = path.write_text(text)
    ...     rec = read_psins_imu(path)
    >>> rec.dt_s, rec.dtheta.shape, round(float(np.rad2deg(rec.lat_rad)), 1)
    (0.01, (2, 3), 34.2)
    >>> rec.dtheta[0] / ARCSEC  # counts x 0.01 arcsec/count
    array([0.01, 0.02, 0.03])
    """
    blocks = PsinsBlocks(path)
    parts = list(blocks)
    return PsinsRecord(
        att0_deg=blocks.att0_deg, vn0_m_s=blocks.vn0_m_s, lat_rad=blocks.lat_rad,
        lon_rad=blocks.lon_rad, h_m=blocks.h_m, t0_s=blocks.t0_s, dt_s=blocks.dt_s,
        g_m_s2=blocks.g_m_s2,
        dtheta=np.ascontiguousarray(np.concatenate([d for d, _ in parts])),
        dv=np.ascontiguousarray(np.concatenate([v for _, v in parts])),
    )


#: Data lines of a PSINS log parsed at a time.
BLOCK_LINES = 1 << 16


def _lines(path: Path) -> Iterator[tuple[int, str]]:
    """(line number, text) of every line of a UTF-8 file (a byte-order mark dropped), split
    as ``str.splitlines`` splits the whole text, read one line at a time; a byte that is not
    UTF-8 is refused with its offset in the file."""
    lineno = 0
    offset = 0
    with path.open("rb") as fh:
        for raw in fh:
            skip = 3 if offset == 0 and raw.startswith(b"\xef\xbb\xbf") else 0
            try:
                text = raw[skip:].decode("utf-8")
            except UnicodeDecodeError as exc:
                raise GyrodriftValueError(
                    f"{path}: not a PSINS text log (byte {offset + skip + exc.start} is not "
                    "UTF-8; a binary file?)") from None
            offset += len(raw)
            for line in text.splitlines() or [""]:
                lineno += 1
                yield lineno, line


def _data(line: str) -> str:
    """A data line's text without its comment ('%' lines; '#' to the end of a line), or ''."""
    s = line.strip()
    return "" if s.startswith("%") else s.split("#", 1)[0].strip()


class PsinsBlocks:
    """A PSINS IMU log (:func:`read_psins_imu`'s format and checks) read in blocks of
    `block_lines` data lines: the header (attributes as :class:`PsinsRecord`'s) is read
    when the object is made, and iterating gives (dtheta, dv) blocks, (m, 3) arrays in rad
    and m/s, the same values as :func:`read_psins_imu`'s. Memory: one block, whatever the
    log's length.

    The sampling interval is checked with the header; a data line that is not six finite
    numbers is refused (naming its line) when its block is read, so the verdict does not
    depend on the blocks.

    Examples
    --------
    >>> import tempfile
    >>> text = ("0 0 30 0 0 0\\n34.2 108.9 380 0 10 9.79\\n0.01 0.01 0.01 50 50 50\\n"
    ...         + "1 2 3 0 0 196\\n" * 5)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = Path(d) / "bench.imu"
    ...     _ = path.write_text(text)
    ...     blocks = PsinsBlocks(path, block_lines=2)
    ...     shapes = [dtheta.shape for dtheta, dv in blocks]
    >>> blocks.dt_s, shapes
    (0.01, [(2, 3), (2, 3), (1, 3)])
    """

    def __init__(self, path: str | Path, *, block_lines: int | None = None) -> None:
        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"{p}: no such file")
        self.path = p
        self.block_lines = int(BLOCK_LINES if block_lines is None else block_lines)
        if self.block_lines < 1:
            raise GyrodriftValueError("block_lines must be >= 1")
        header: list[np.ndarray] = []
        self._header_end = 0  # the line number of the third header line
        for lineno, line in _lines(p):
            s = line.strip()
            if not s or s.startswith("%"):
                continue
            try:
                vals = np.array([float(v) for v in s.split()])
            except ValueError:
                raise GyrodriftValueError(
                    f"{p}:{lineno}: header line is not numeric") from None
            if vals.size != 6:
                raise GyrodriftValueError(
                    f"{p}:{lineno}: header line needs 6 values, got {vals.size}")
            header.append(vals)
            if len(header) == 3:
                self._header_end = lineno
                break
        if len(header) < 3:
            raise GyrodriftValueError(f"{p}: missing the three PSINS header lines")
        l1, l2, l3 = header
        dt_s = l2[4] / 1000.0
        if not dt_s > 0:
            raise GyrodriftValueError(f"{p}: sampling interval must be > 0 ms, got {l2[4]}")
        if not RATE_MIN_HZ <= 1.0 / dt_s <= RATE_MAX_HZ:  # the range a given --rate-hz has
            raise GyrodriftValueError(
                f"{p}: sampling interval {l2[4]:g} ms gives a sample rate of {1.0 / dt_s:.3g} "
                f"Hz, outside {RATE_MIN_HZ:g}..{RATE_MAX_HZ:g} Hz")
        self.att0_deg: np.ndarray = l1[:3]
        self.vn0_m_s: np.ndarray = l1[3:]
        self.lat_rad = float(l2[0] * DEG)
        self.lon_rad = float(l2[1] * DEG)
        self.h_m = float(l2[2])
        self.t0_s = float(l2[3])
        self.dt_s = float(dt_s)
        self.g_m_s2 = float(l2[5])
        self._scale = l3
        #: data lines read by the last complete iteration
        self.n = 0

    def __iter__(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        n = 0
        rows: list[str] = []
        numbers: list[int] = []
        for lineno, line in _lines(self.path):
            if lineno <= self._header_end:
                continue
            s = _data(line)
            if s:
                rows.append(s)
                numbers.append(lineno)
                if len(rows) >= self.block_lines:
                    n += len(rows)
                    yield self._block(rows, numbers)
                    rows, numbers = [], []
        if rows:
            n += len(rows)
            yield self._block(rows, numbers)
        if n == 0:
            raise GyrodriftValueError(f"{self.path}: no data lines")
        self.n = n

    def _block(self, rows: list[str], numbers: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """(dtheta, dv) of a block of data lines: counts x scale factors (arcsec/count,
        ug*s/count) in rad and m/s."""
        try:
            counts = np.loadtxt(rows, dtype=np.float64, ndmin=2, comments=None)
            ok = counts.shape == (len(rows), 6) and bool(np.isfinite(counts).all())
        except ValueError:
            ok = False
        if not ok:  # name the first bad line, in file order, as the parse of it alone does
            for s, lineno in zip(rows, numbers, strict=True):
                try:
                    row = np.loadtxt([s], dtype=np.float64, ndmin=2, comments=None)
                except ValueError:
                    raise GyrodriftValueError(f"{self.path}:{lineno}: malformed data line "
                                              f"{s!r} (not numbers)") from None
                if row.shape[1] != 6:
                    raise GyrodriftValueError(f"{self.path}:{lineno}: a data line needs 6 "
                                              f"counts, got {row.shape[1]}")
                if not np.isfinite(row).all():
                    raise GyrodriftValueError(f"{self.path}:{lineno}: non-finite counts in "
                                              "the data line")
            raise AssertionError(f"{self.path}: lines {numbers[0]}..{numbers[-1]} parse one "
                                 "by one, not together")  # never: the checks above cover it
        l3 = self._scale
        dtheta = np.ascontiguousarray(counts[:, :3] * l3[:3] * ARCSEC)
        # ug*s -> m/s with 1 ug = 9.80665e-6 m/s^2 (conventional g).
        dv = np.ascontiguousarray(counts[:, 3:] * l3[3:] * UG)
        return dtheta, dv
