"""WGS-84 Earth model for the ENU navigation frame (reference for include/gyrodrift/nav_earth.hpp).

Frames: n = local level East-North-Up, b = body (X right, Y forward, Z up), i0/ib0 = the
n and b frames frozen in inertial space at the start of coarse alignment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

WGS84_A_M = 6378137.0  # semi-major axis
WGS84_F = 1.0 / 298.257223563  # flattening
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared
EARTH_RATE_RPS = 7.2921151467e-5  # Omega, rad/s
# Normal gravity at the equator and the series in sin^2 L, sin^4 L plus the free-air
# gradient (the PSINS/Yan Gongmin form of the WGS-84 normal gravity, 1e-7 g accuracy).
GRAVITY_EQ_MPS2 = 9.7803267714
GRAVITY_B1 = 5.27094e-3
GRAVITY_B2 = 2.32718e-5
GRAVITY_DH_PER_S2 = 3.086e-6  # d g / d h, (m/s^2)/m

DEG = np.pi / 180.0
ARCSEC = DEG / 3600.0
ARCMIN = DEG / 60.0
DPH = DEG / 3600.0  # deg/h in rad/s
UG = 9.80665e-6  # micro-g in m/s^2 (conventional g)
DPSH = DEG / 60.0  # deg/sqrt(h) in rad/sqrt(s)


def gravity_mps2(lat_rad: float, h_m: float) -> float:
    """Normal gravity magnitude at latitude and height (m/s^2)."""
    s2 = np.sin(lat_rad) ** 2
    g0 = GRAVITY_EQ_MPS2 * (1.0 + GRAVITY_B1 * s2 + GRAVITY_B2 * s2 * s2)
    return g0 - GRAVITY_DH_PER_S2 * h_m


@dataclass
class EarthParams:
    """Earth quantities at a position and velocity (all in the ENU frame)."""

    rm_h_m: float  # meridian radius + height
    rn_h_m: float  # prime-vertical radius + height
    wnie: np.ndarray  # Earth rate in n, rad/s
    wnen: np.ndarray  # transport rate in n, rad/s
    wnin: np.ndarray  # wnie + wnen
    gn: np.ndarray  # gravity vector in n, [0, 0, -g]
    tan_lat: float


def earth_params(lat_rad: float, h_m: float, vn_mps: np.ndarray) -> EarthParams:
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    sq = 1.0 - WGS84_E2 * sl * sl
    rn = WGS84_A_M / np.sqrt(sq)
    rm = rn * (1.0 - WGS84_E2) / sq
    rm_h, rn_h = rm + h_m, rn + h_m
    tl = sl / cl
    wnie = np.array([0.0, EARTH_RATE_RPS * cl, EARTH_RATE_RPS * sl])
    wnen = np.array([-vn_mps[1] / rm_h, vn_mps[0] / rn_h, vn_mps[0] * tl / rn_h])
    gn = np.array([0.0, 0.0, -gravity_mps2(lat_rad, h_m)])
    return EarthParams(rm_h, rn_h, wnie, wnen, wnie + wnen, gn, tl)
