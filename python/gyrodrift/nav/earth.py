"""The one Earth model of the package: WGS-84 ellipsoid, normal gravity and Earth rate in the
East-North-Up navigation frame, radians in.

It is the Python twin of ``include/gyrodrift/nav/earth.hpp`` (same constants, same gravity
series), used by the simulators, the alignment study and the alignment references.

Frames: n = local level East-North-Up, b = body (X right, Y forward, Z up), i0/ib0 = the n and
b frames frozen in inertial space at the start of coarse alignment.

Examples
--------
>>> round(gravity_m_s2(0.0, 0.0), 7)
9.7803268
>>> EARTH_RATE_RAD_S
7.2921151467e-05
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "EARTH_RATE_RAD_S",
    "GRAVITY_B1",
    "GRAVITY_B2",
    "GRAVITY_DH_PER_S2",
    "GRAVITY_EQ_M_S2",
    "WGS84_A_M",
    "WGS84_E2",
    "WGS84_F",
    "EarthParams",
    "earth_params",
    "earth_rate_n_rad_s",
    "gravity_m_s2",
]

WGS84_A_M = 6378137.0  # semi-major axis, m
WGS84_F = 1.0 / 298.257223563  # flattening
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared
EARTH_RATE_RAD_S = 7.2921151467e-5  # Omega (WGS-84), rad/s
# Normal gravity at the equator and the series in sin^2 L, sin^4 L plus the free-air
# gradient (the PSINS/Yan Gongmin form of the WGS-84 normal gravity, as nav/earth.hpp; within
# 8e-5 m/s^2 = 8e-6 g of the Somigliana closed form, largest at the poles, see
# tests/test_simulate.py).
GRAVITY_EQ_M_S2 = 9.7803267714
GRAVITY_B1 = 5.27094e-3
GRAVITY_B2 = 2.32718e-5
GRAVITY_DH_PER_S2 = 3.086e-6  # d g / d h, (m/s^2)/m



def gravity_m_s2(lat_rad: float, h_m: float = 0.0) -> float:
    """Normal gravity magnitude at a latitude and height, m/s^2.

    Parameters
    ----------
    lat_rad : float
        Geodetic latitude, rad.
    h_m : float
        Height above the ellipsoid, m.

    Returns
    -------
    float
        g = g_eq (1 + b1 sin^2 L + b2 sin^4 L) - (dg/dh) h.

    Examples
    --------
    >>> round(gravity_m_s2(math.radians(45.0)) - gravity_m_s2(math.radians(45.0), 1000.0), 6)
    0.003086
    """
    s2 = math.sin(lat_rad) ** 2
    g0 = GRAVITY_EQ_M_S2 * (1.0 + GRAVITY_B1 * s2 + GRAVITY_B2 * s2 * s2)
    return g0 - GRAVITY_DH_PER_S2 * h_m


def earth_rate_n_rad_s(lat_rad: float) -> np.ndarray:
    """Earth rate in the ENU frame, [0, W cos L, W sin L], rad/s.

    Examples
    --------
    >>> bool(earth_rate_n_rad_s(0.0)[1] == EARTH_RATE_RAD_S)
    True
    """
    return np.array([0.0, EARTH_RATE_RAD_S * math.cos(lat_rad),
                     EARTH_RATE_RAD_S * math.sin(lat_rad)])


@dataclass(frozen=True)
class EarthParams:
    """Earth quantities at a position and velocity (all in the ENU frame).

    Examples
    --------
    >>> ep = earth_params(0.5, 0.0, np.zeros(3))
    >>> bool(ep.rn_h_m > ep.rm_h_m)
    True
    """

    rm_h_m: float  # meridian radius + height, m
    rn_h_m: float  # prime-vertical radius + height, m
    wnie: np.ndarray  # Earth rate in n, rad/s
    wnen: np.ndarray  # transport rate in n, rad/s
    wnin: np.ndarray  # wnie + wnen, rad/s
    gn: np.ndarray  # gravity vector in n, [0, 0, -g], m/s^2
    tan_lat: float


def earth_params(lat_rad: float, h_m: float, vn_m_s: np.ndarray) -> EarthParams:
    """Radii of curvature, Earth and transport rates and gravity at a position and velocity.

    Parameters
    ----------
    lat_rad, h_m : float
        Latitude (rad) and height (m).
    vn_m_s : array of 3
        Velocity in the ENU frame, m/s.

    Examples
    --------
    >>> ep = earth_params(0.0, 0.0, np.zeros(3))
    >>> round(ep.rn_h_m)
    6378137
    """
    sl, cl = math.sin(lat_rad), math.cos(lat_rad)
    sq = 1.0 - WGS84_E2 * sl * sl
    rn = WGS84_A_M / math.sqrt(sq)
    rm = rn * (1.0 - WGS84_E2) / sq
    rm_h, rn_h = rm + h_m, rn + h_m
    tl = sl / cl
    wnie = earth_rate_n_rad_s(lat_rad)
    wnen = np.array([-vn_m_s[1] / rm_h, vn_m_s[0] / rn_h, vn_m_s[0] * tl / rn_h])
    gn = np.array([0.0, 0.0, -gravity_m_s2(lat_rad, h_m)])
    return EarthParams(rm_h, rn_h, wnie, wnen, wnie + wnen, gn, tl)
