"""The one units table: unit constants, the input units each reader accepts with their factors
to SI and to the IEEE Std 952 display units, and the units of the noise terms.

Names follow CONTRIBUTING.md's unit suffixes. Factors are written as the products they are
(deg/s -> deg/h is exactly 3600), not derived by division, so conversions stay exact where
they can be.

Examples
--------
>>> RATE_UNITS["deg/s"].to_deg_h, RATE_UNITS["deg/h"].to_rad_s == DPH
(3600.0, True)
>>> TERM_UNITS["gyro"]["N"].si, TERM_UNITS["gyro"]["N"].ieee
('rad/s/sqrt(Hz)', 'deg/sqrt(h)')
>>> GYRO_INPUT_UNITS, DEFAULT_GYRO_UNITS
(('deg/h', 'deg/s', 'rad/s', 'arcsec', 'deg', 'rad'), None)
"""

from __future__ import annotations

import math
from typing import NamedTuple

__all__ = [
    "ACCEL_INCREMENT_UNITS",
    "ACCEL_INPUT_UNITS",
    "ACCEL_UNITS",
    "ARCMIN",
    "ARCSEC",
    "DEFAULT_ACCEL_UNITS",
    "DEFAULT_GYRO_UNITS",
    "DEFAULT_TIME_UNITS",
    "DEG",
    "DPH",
    "DPSH",
    "G0_M_S2",
    "GYRO_INPUT_UNITS",
    "INCREMENT_UNITS",
    "RAD_TO_DEG",
    "RATE_UNITS",
    "TERM_UNITS",
    "TIME_UNITS",
    "UG",
    "RateUnit",
    "TermUnit",
]

DEG = math.pi / 180.0  # one degree in rad
RAD_TO_DEG = 180.0 / math.pi  # one rad in degrees
ARCSEC = DEG / 3600.0  # one arcsecond in rad
ARCMIN = DEG / 60.0  # one arcminute in rad
DPH = DEG / 3600.0  # one deg/h in rad/s
DPSH = DEG / 60.0  # one deg/sqrt(h) in rad/sqrt(s)
G0_M_S2 = 9.80665  # conventional g, m/s^2
UG = 9.80665e-6  # one micro-g in m/s^2


class RateUnit(NamedTuple):
    """Factors of one gyro input unit: to rad/s (rad for increments) and to deg/h (deg).

    Examples
    --------
    >>> RATE_UNITS["rad/s"].to_deg_h == RAD_TO_DEG * 3600.0, INCREMENT_UNITS["deg"].to_deg_h
    (True, 1.0)
    """

    to_rad_s: float
    to_deg_h: float


#: Gyro rate input units.
RATE_UNITS: dict[str, RateUnit] = {
    "deg/h": RateUnit(DEG / 3600.0, 1.0),
    "deg/s": RateUnit(DEG, 3600.0),
    "rad/s": RateUnit(1.0, RAD_TO_DEG * 3600.0),
}
#: Gyro angle-increment input units (per sample; divided by dt where a rate is needed):
#: factors to rad and to deg in the same two fields.
INCREMENT_UNITS: dict[str, RateUnit] = {
    "arcsec": RateUnit(DEG / 3600.0, 1.0 / 3600.0),
    "deg": RateUnit(DEG, 1.0),
    "rad": RateUnit(1.0, RAD_TO_DEG),
}
#: Accelerometer input units -> factor to m/s^2.
ACCEL_UNITS: dict[str, float] = {"m/s^2": 1.0, "g": G0_M_S2}
#: Accelerometer velocity-increment input units -> factor to m/s (divided by dt).
ACCEL_INCREMENT_UNITS: dict[str, float] = {"m/s": 1.0}

#: Every unit a gyro input column may be in: rates, then per-sample angle increments (the
#: choices of the command line's ``--gyro-units``).
GYRO_INPUT_UNITS: tuple[str, ...] = (*RATE_UNITS, *INCREMENT_UNITS)
#: Every unit an accelerometer input column may be in: accelerations, then per-sample velocity
#: increments (the choices of ``--accel-units``).
ACCEL_INPUT_UNITS: tuple[str, ...] = (*ACCEL_UNITS, *ACCEL_INCREMENT_UNITS)
#: The command line's default ``--gyro-units``: none. A .npy or text record does not say its
#: units, and the commands never guess them (a wrong guess scales every noise term silently):
#: the flag is required for those; IMU logs and ROS bags carry rad/s, PSINS logs angle
#: increments.
DEFAULT_GYRO_UNITS: str | None = None
#: The command line's default ``--accel-units``: none, for the same reason.
DEFAULT_ACCEL_UNITS: str | None = None
#: Units a text record's time column may be in -> factor to s (the choices of
#: ``--time-units``; logs and bags carry their own time base).
TIME_UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: The default ``--time-units``: seconds.
DEFAULT_TIME_UNITS = "s"


class TermUnit(NamedTuple):
    """One IEEE Std 952 noise term's SI unit, and its display unit with the factor from SI.

    Examples
    --------
    >>> b = TERM_UNITS["accel"]["B"]
    >>> b.si, b.ieee, round(2e-4 * b.ieee_factor, 6)  # 2e-4 m/s^2 is about 20.4 ug
    ('m/s^2', 'ug', 20.394324)
    """

    si: str
    ieee_factor: float  # SI value * ieee_factor = display value
    ieee: str
    from_ieee: float  # display value * from_ieee = SI value (written exactly, not 1/ieee_factor)


#: Units of the five noise terms (Q, N, B, K, R) per sensor.
TERM_UNITS: dict[str, dict[str, TermUnit]] = {
    "gyro": {
        "Q": TermUnit("rad", RAD_TO_DEG * 3600.0, "arcsec", DEG / 3600.0),
        "N": TermUnit("rad/s/sqrt(Hz)", RAD_TO_DEG * 60.0, "deg/sqrt(h)", DEG / 60.0),
        "B": TermUnit("rad/s", RAD_TO_DEG * 3600.0, "deg/h", DEG / 3600.0),
        "K": TermUnit("rad/s^2/sqrt(Hz)", RAD_TO_DEG * 3600.0 * 60.0, "deg/h/sqrt(h)",
                      DEG / 3600.0 / 60.0),
        "R": TermUnit("rad/s^2", RAD_TO_DEG * 3600.0 * 3600.0, "deg/h^2", DEG / 3600.0 / 3600.0),
    },
    "accel": {
        "Q": TermUnit("m/s", 1.0, "m/s", 1.0),
        "N": TermUnit("m/s^2/sqrt(Hz)", 60.0, "m/s/sqrt(h)", 1.0 / 60.0),
        "B": TermUnit("m/s^2", 1.0 / 9.80665e-6, "ug", UG),
        "K": TermUnit("m/s^3/sqrt(Hz)", 60.0, "m/s^2/sqrt(h)", 1.0 / 60.0),
        "R": TermUnit("m/s^3", 1.0, "m/s^3", 1.0),
    },
}
