"""Reader for the PSINS text IMU log format (e.g. lasergyro.imu) and the
real-data alignment-consistency run.

Format (the file's own header): `%` comment lines; data line 1 = pitch0, roll0, yaw0 (deg),
VE0, VN0, VU0 (m/s); line 2 = lat0 (deg), lon0 (deg), h0 (m), t0 (s), sampling interval (ms),
g (m/s^2); line 3 = gyro scale factors (arcsec/count) x3, accelerometer scale factors
(ug*s/count) x3; then one line of six integer counts gx gy gz ax ay az per sample.
Axes X right, Y forward, Z up (the same body frame as this package).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gyrodrift.defaults import RATE_MAX_HZ, RATE_MIN_HZ
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.units import ARCSEC, DEG, UG

__all__ = [
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
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    header: list[np.ndarray] = []
    rows: list[str] = []
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark is no header value
    except UnicodeDecodeError as exc:
        raise GyrodriftValueError(f"{path}: not a PSINS text log (byte {exc.start} is not "
                                  "UTF-8; a binary file?)") from None
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s.startswith("%"):
            continue
        if len(header) < 3:
            try:
                vals = np.array([float(v) for v in s.split()])
            except ValueError:
                raise GyrodriftValueError(
                    f"{path}:{lineno}: header line is not numeric") from None
            if vals.size != 6:
                raise GyrodriftValueError(
                    f"{path}:{lineno}: header line needs 6 values, got {vals.size}")
            header.append(vals)
            continue
        rows.append(s)
    if len(header) < 3:
        raise GyrodriftValueError(f"{path}: missing the three PSINS header lines")
    if not rows:
        raise GyrodriftValueError(f"{path}: no data lines")
    try:
        counts = np.loadtxt(rows, dtype=np.float64, ndmin=2)
    except ValueError as exc:
        raise GyrodriftValueError(f"{path}: malformed data line ({exc})") from None
    if counts.shape[1] != 6:
        raise GyrodriftValueError(f"{path}: data lines need 6 counts, got {counts.shape[1]}")
    if not np.isfinite(counts).all():
        raise GyrodriftValueError(f"{path}: non-finite counts in the data lines")
    l1, l2, l3 = header
    dt_s = l2[4] / 1000.0
    if not dt_s > 0:
        raise GyrodriftValueError(f"{path}: sampling interval must be > 0 ms, got {l2[4]}")
    if not RATE_MIN_HZ <= 1.0 / dt_s <= RATE_MAX_HZ:  # the range a given --rate-hz has
        raise GyrodriftValueError(
            f"{path}: sampling interval {l2[4]:g} ms gives a sample rate of {1.0 / dt_s:.3g} "
            f"Hz, outside {RATE_MIN_HZ:g}..{RATE_MAX_HZ:g} Hz")
    return PsinsRecord(
        att0_deg=l1[:3], vn0_m_s=l1[3:], lat_rad=l2[0] * DEG, lon_rad=l2[1] * DEG, h_m=l2[2],
        t0_s=l2[3], dt_s=dt_s, g_m_s2=l2[5],
        dtheta=np.ascontiguousarray(counts[:, :3] * l3[:3] * ARCSEC),
        # ug*s -> m/s with 1 ug = 9.80665e-6 m/s^2 (conventional g).
        dv=np.ascontiguousarray(counts[:, 3:] * l3[3:] * UG),
    )
