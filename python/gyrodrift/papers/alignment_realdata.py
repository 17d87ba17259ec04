"""Real-data alignment consistency on a PSINS IMU log (no heading truth): the record is cut into
equal segments, each aligned independently (coarse + fine to the segment end), with and without
the wavelet prefilter; the spread of the final headings across segments measures repeatability.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrodrift.errors import GyrodriftError, GyrodriftValueError
from gyrodrift.filters.fir import apply_fir, forced_fir_taps, group_delay_dc_samples
from gyrodrift.io.psins import PsinsRecord
from gyrodrift.nav.align_config import AlignConfig
from gyrodrift.nav.alignment import run_alignment
from gyrodrift.papers.imu_errors import kf_noise_from_samples
from gyrodrift.units import ARCSEC, DEG, DPSH, UG

__all__ = [
    "SegmentResult",
    "align_segments",
    "consistency_rows",
]


@dataclass
class SegmentResult:
    """The final attitude of one segment's alignment per configuration (degrees; heading clockwise
    from North).

    Examples
    --------
    >>> s = SegmentResult(0.0, {"raw gyro": 30.0}, {"raw gyro": 0.0}, {"raw gyro": 0.0})
    >>> s.heading_deg["raw gyro"]
    30.0
    """
    start_s: float
    heading_deg: dict[str, float]  # config label -> final heading (clockwise from North)
    pitch_deg: dict[str, float]
    roll_deg: dict[str, float]


def align_segments(rec: PsinsRecord, segment_s: float = 300.0, coarse_s: float = 60.0,
                   kf_noise: str = "spec", arw_deg_rt_h: float = 0.005,
                   zv_sigma_m_s: float = 0.02) -> list[SegmentResult]:
    """Align each full segment of the record; kf_noise 'spec' uses arw_deg_rt_h and 50 ug/rtHz,
    'samples' the per-sample scatter of the (prefiltered) segment.

    Examples
    --------
    >>> from gyrodrift.nav import imu_increments, scenario
    >>> sc = scenario("static")  # at rest, heading 330 deg
    >>> dth, dv = imu_increments(sc, 100 * 240, 0.01)  # 4 min at 100 Hz, no sensor errors
    >>> rec = PsinsRecord(np.zeros(3), np.zeros(3), sc.lat_rad, 0.0, sc.h_m, 0.0, 0.01, 9.8,
    ...                   dth, dv)
    >>> segs = align_segments(rec, segment_s=120.0, coarse_s=30.0)
    >>> len(segs), sorted(segs[0].heading_deg), round(segs[1].heading_deg["raw gyro"], 6)
    (2, ['raw gyro', 'wavelet prefilter'], 330.0)
    """
    dt = rec.dt_s
    m = round(segment_s / dt)
    if m * dt <= coarse_s + 30.0:
        raise GyrodriftValueError(f"segment of {segment_s} s leaves under 30 s of fine alignment")
    n_seg = rec.dtheta.shape[0] // m
    if n_seg < 2:
        raise GyrodriftValueError(
            f"the record holds {n_seg} segment(s) of {segment_s} s; need >= 2")
    taps = forced_fir_taps("db4", 256, 5)
    delay = round(group_delay_dc_samples(taps))
    out: list[SegmentResult] = []
    for i in range(n_seg):
        sl = slice(i * m, (i + 1) * m)
        dth = np.ascontiguousarray(rec.dtheta[sl])
        dv = np.ascontiguousarray(rec.dv[sl])
        hd: dict[str, float] = {}
        pt: dict[str, float] = {}
        rl: dict[str, float] = {}
        for label, pre in (("raw gyro", False), ("wavelet prefilter", True)):
            if kf_noise == "samples":
                arw, vrw = kf_noise_from_samples(apply_fir(dth, taps) if pre else dth, dv, dt)
            else:
                arw, vrw = arw_deg_rt_h * DPSH, 50.0 * UG
            cfg = AlignConfig(dt_s=dt, lat_rad=rec.lat_rad, lon_rad=rec.lon_rad, h_m=rec.h_m,
                              coarse_s=coarse_s, kf_every=max(1, round(0.1 / dt)),
                              arw_rad_s_rt_hz=arw, vrw_m_s2_rt_hz=vrw, zv_sigma_m_s=zv_sigma_m_s,
                              taps=taps if pre else None, accel_delay_samples=delay if pre else 0)
            res = run_alignment(dth, dv, cfg)
            if res.failed:
                raise GyrodriftError(f"alignment failed on segment {i} ({label}): {res.reason}")
            att = res.att[-1]
            hd[label] = float((-att[2] / DEG) % 360.0)
            pt[label] = float(att[0] / DEG)
            rl[label] = float(att[1] / DEG)
        out.append(SegmentResult(i * m * dt, hd, pt, rl))
    return out


def consistency_rows(segs: list[SegmentResult]) -> list[dict[str, object]]:
    """Per configuration: mean heading over the segments and the heading, pitch and roll scatter (1
    sigma, arcsec).

    Examples
    --------
    >>> segs = [SegmentResult(0.0, {"raw": 30.0}, {"raw": 0.0}, {"raw": 0.0}),
    ...         SegmentResult(300.0, {"raw": 30.01}, {"raw": 0.0}, {"raw": 0.0})]
    >>> row = consistency_rows(segs)[0]
    >>> row["config"], row["segments"], round(row["heading_range_arcsec"], 1)
    ('raw', 2, 36.0)
    """
    rows: list[dict[str, object]] = []
    for label in segs[0].heading_deg:
        h = np.array([s.heading_deg[label] for s in segs])
        h = np.unwrap(np.deg2rad(h))
        rows.append({
            "config": label, "segments": len(segs),
            "heading_mean_deg": float(np.rad2deg(h.mean()) % 360.0),
            "heading_1sigma_arcsec": float(h.std(ddof=1) / ARCSEC),
            "heading_range_arcsec": float((h.max() - h.min()) / ARCSEC),
            "pitch_1sigma_arcsec": float(np.std([s.pitch_deg[label] for s in segs], ddof=1)
                                         * 3600.0),
            "roll_1sigma_arcsec": float(np.std([s.roll_deg[label] for s in segs], ddof=1)
                                        * 3600.0),
        })
    return rows
