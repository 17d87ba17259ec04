"""Alignment settings and result, shared by the C++ fast path (`gyrodrift.nav.run_alignment`)
and the plain-loop reference (`gyrodrift.reference.align.run_alignment_reference`).

Examples
--------
>>> cfg = AlignConfig(dt_s=0.01, coarse_s=30.0)
>>> cfg.coarse_samples()
3000
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gyrodrift.defaults import DEFAULT_SAMPLE_RATE_HZ
from gyrodrift.units import ARCMIN, DEG, DPH, UG

__all__ = ["AlignConfig", "AlignResult"]


@dataclass
class AlignConfig:
    """Alignment settings; angles rad, rates rad/s, noise densities per sqrt(s).

    Examples
    --------
    >>> AlignConfig(dt_s=0.01).coarse_samples()  # 60 s of coarse alignment
    6000
    """

    dt_s: float = 1.0 / DEFAULT_SAMPLE_RATE_HZ
    lat_rad: float = 39.0 * DEG
    lon_rad: float = 116.0 * DEG
    h_m: float = 50.0
    coarse_s: float = 60.0
    coarse_position_integral: bool = True
    n_states: int = 15
    kf_every: int = 40  # samples per KF cycle (400 Hz / 40 = 10 Hz)
    p0_phi_rad: np.ndarray = field(default_factory=lambda: np.array([1.0, 1.0, 10.0]) * DEG)
    p0_dv_m_s: float = 0.5
    p0_dp_m: float = 1.0
    p0_eb_rad_s: float = 0.02 * DPH
    p0_db_m_s2: float = 100.0 * UG
    arw_rad_s_rt_hz: float = 0.001 * DEG / 60.0  # gyro angle random walk (process noise)
    vrw_m_s2_rt_hz: float = 10.0 * UG  # accelerometer velocity random walk
    eb_rw: float = 0.0  # gyro drift random walk (rad/s/sqrt(s))
    db_rw: float = 0.0
    dp_q: float = 0.0  # position process noise (m^2/s), absorbs lever-arm sway
    zv_sigma_m_s: float = 0.01  # zero-velocity measurement noise
    # Heading acquisition stage (two-stage fine alignment for a large coarse heading error):
    # during the first heading_stage_s of fine alignment the Up attitude process noise gets
    # heading_stage_q (rad^2/s) added, so the small-angle filter keeps following the heading
    # while the nonlinear error (sin psi, 1 - cos psi) is still large instead of becoming
    # overconfident; then the filter continues with the specification noise. 0 = off.
    heading_stage_s: float = 0.0
    heading_stage_q: float = 0.0
    floor_phi_rad: float = 0.01 * ARCMIN / 60.0
    floor_dv_m_s: float = 1e-6
    floor_dp_m: float = 1e-6
    floor_eb_rad_s: float = 1e-6 * DPH
    floor_db_m_s2: float = 0.01 * UG
    # gyro prefilter FIR taps, newest first (gyrodrift.filters.fir); None = off
    taps: np.ndarray | None = None
    accel_delay_samples: int = 0  # delay matching the prefilter's group delay

    def heading_stage_cycles(self) -> int:
        """KF cycles (predictions) that use the acquisition noise."""
        return round(self.heading_stage_s / (self.kf_every * self.dt_s))

    def q_stage_diag(self) -> np.ndarray:
        q = self.q_diag()
        q[2] += self.heading_stage_q
        return q

    def coarse_samples(self) -> int:
        return round(self.coarse_s / self.dt_s)

    def p0_diag(self) -> np.ndarray:
        parts = [np.asarray(self.p0_phi_rad) ** 2, np.full(3, self.p0_dv_m_s ** 2)]
        if self.n_states == 15:
            parts.append(np.full(3, self.p0_dp_m ** 2))
        parts += [np.full(3, self.p0_eb_rad_s ** 2), np.full(3, self.p0_db_m_s2 ** 2)]
        return np.concatenate(parts)

    def q_diag(self) -> np.ndarray:
        parts = [np.full(3, self.arw_rad_s_rt_hz ** 2), np.full(3, self.vrw_m_s2_rt_hz ** 2)]
        if self.n_states == 15:
            parts.append(np.full(3, self.dp_q))
        parts += [np.full(3, self.eb_rw ** 2), np.full(3, self.db_rw ** 2)]
        return np.concatenate(parts)

    def floor_diag(self) -> np.ndarray:
        parts = [np.full(3, self.floor_phi_rad ** 2), np.full(3, self.floor_dv_m_s ** 2)]
        if self.n_states == 15:
            parts.append(np.full(3, self.floor_dp_m ** 2))
        parts += [np.full(3, self.floor_eb_rad_s ** 2), np.full(3, self.floor_db_m_s2 ** 2)]
        return np.concatenate(parts)


@dataclass(frozen=True)
class AlignResult:
    """Histories of an alignment run, one row per KF update.

    Attributes
    ----------
    t_s : (m,) time each solution refers to, s (end of the KF cycle from the first input
        sample, minus the accelerometer delay that matches the prefilter).
    att : (m, 3) pitch, roll, yaw, rad.
    eb, db : (m, 3) estimated gyro drift (rad/s) and accelerometer bias (m/s^2).
    p_phi : (m, 3) standard deviation of the attitude error states, rad.
    coarse_cnb : (3, 3) C_b^n at the end of coarse alignment.
    bad_samples : non-finite samples counted and skipped (C++ pipeline; 0 for the reference).
    failed : the pipeline stopped (coarse solve or KF numerics failed).
    reason : why it failed ("" when it did not; filled when the binding reports one).

    Examples
    --------
    >>> r = AlignResult(np.zeros(1), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)),
    ...                 np.zeros((1, 3)), np.eye(3))
    >>> sorted(r.as_dict())[:3]
    ['att', 'bad_samples', 'coarse_cnb']
    """

    t_s: np.ndarray
    att: np.ndarray
    eb: np.ndarray
    db: np.ndarray
    p_phi: np.ndarray
    coarse_cnb: np.ndarray
    bad_samples: int = 0
    failed: bool = False
    reason: str = ""

    def as_dict(self) -> dict[str, object]:
        """JSON-ready values (arrays as nested lists)."""
        return {"t_s": self.t_s.tolist(), "att": self.att.tolist(), "eb": self.eb.tolist(),
                "db": self.db.tolist(), "p_phi": self.p_phi.tolist(),
                "coarse_cnb": self.coarse_cnb.tolist(), "bad_samples": int(self.bad_samples),
                "failed": bool(self.failed), "reason": self.reason}
