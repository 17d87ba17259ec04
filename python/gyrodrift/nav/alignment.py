"""C++ fast path (gyrodrift._core, header nav/align_pipeline.hpp) behind the same interface as
the plain-loop references in this package."""

from __future__ import annotations

import numpy as np

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.nav.align_config import AlignConfig, AlignResult

__all__ = [
    "coarse_align",
    "run_alignment",
    "strapdown_run",
]



def _n3(name: str, a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype != np.float64:
        raise GyrodriftTypeError(f"{name}: expected float64 increments, got {a.dtype}")
    if a.ndim != 2 or a.shape[1] != 3:
        raise GyrodriftValueError(f"{name}: expected shape (n, 3), got {a.shape}")
    return np.ascontiguousarray(a)


def run_alignment(dtheta: np.ndarray, dv: np.ndarray, cfg: AlignConfig) -> AlignResult:
    """Whole alignment in C++ (GIL released), the same histories as `run_alignment_reference`.

    Parameters
    ----------
    dtheta, dv : (n, 3) float64
        Gyro angle increments (rad) and velocity increments (m/s) per sample.
    cfg : AlignConfig

    Returns
    -------
    AlignResult
        Per-KF-update histories, `bad_samples` (non-finite samples counted and skipped) and
        `failed` and `reason` (why it failed, "" otherwise). A run that produced no
        solution at all (e.g. an all-NaN record) is failed, with the reason.

    Examples
    --------
    >>> from gyrodrift.nav import scenario, imu_increments
    >>> sc = scenario("static")
    >>> dth, dv = imu_increments(sc, 400 * 70, 1 / 400)
    >>> res = run_alignment(dth, dv, AlignConfig(lat_rad=sc.lat_rad, h_m=sc.h_m))
    >>> res.failed, res.att.shape[1]
    (False, 3)
    """
    lib = core("align")
    c = lib.AlignRunConfig()
    s = c.settings
    s.dt_s, s.lat_rad, s.lon_rad, s.h_m = (float(cfg.dt_s), float(cfg.lat_rad),
                                            float(cfg.lon_rad), float(cfg.h_m))
    s.coarse_samples = int(cfg.coarse_samples())
    s.coarse_position_integral = bool(cfg.coarse_position_integral)
    s.kf_every = int(cfg.kf_every)
    s.accel_delay_samples = int(cfg.accel_delay_samples)
    s.heading_stage_cycles = int(cfg.heading_stage_cycles())
    s.heading_stage_q = float(cfg.heading_stage_q)
    c.settings = s
    c.n_states = int(cfg.n_states)
    c.p0_diag, c.q_diag, c.floor_diag = cfg.p0_diag(), cfg.q_diag(), cfg.floor_diag()
    c.r_diag = np.full(3, cfg.zv_sigma_m_s ** 2)
    # cfg.taps are newest first (gyrodrift.filters.fir); the C++ pipeline takes them oldest first.
    c.taps = [] if cfg.taps is None else np.asarray(cfg.taps, dtype=np.float64)[::-1]
    out = lib.align_run(_n3("dtheta", dtheta), _n3("dv", dv), c)
    return AlignResult(out["t_s"], out["att"], out["eb"], out["db"], out["p_phi"],
                       out["coarse_cnb"], int(out["bad_samples"]), bool(out["failed"]),
                       str(out.get("reason", "")))


def strapdown_run(dtheta: np.ndarray, dv: np.ndarray, dt_s: float, q0: np.ndarray,
                  v0: np.ndarray,
                  pos0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """C++ strapdown over increments: (q history, v history, final position, skipped count).

    Examples
    --------
    >>> q0, pos0 = np.array([1.0, 0, 0, 0]), np.array([0.7, 2.0, 0.0])
    >>> q, v, pos, bad = strapdown_run(np.zeros((10, 3)), np.zeros((10, 3)), 0.01, q0,
    ...                                np.zeros(3), pos0)
    >>> q.shape, v.shape, bad
    ((10, 4), (10, 3), 0)
    """
    return core("align").strapdown_run(_n3("dtheta", dtheta), _n3("dv", dv), float(dt_s),
                                 np.asarray(q0, dtype=np.float64), np.asarray(v0, dtype=np.float64),
                                 np.asarray(pos0, dtype=np.float64))


def coarse_align(dtheta: np.ndarray, dv: np.ndarray, dt_s: float, lat_rad: float, h_m: float,
                 position_integral: bool = True) -> np.ndarray:
    """C++ inertial-frame coarse alignment over the whole window; C_b^n at its end.

    Examples
    --------
    >>> from gyrodrift.nav import imu_increments, scenario
    >>> sc = scenario("static")
    >>> dth, dv = imu_increments(sc, 4000, 0.01)
    >>> c = coarse_align(dth, dv, 0.01, sc.lat_rad, sc.h_m)
    >>> bool(np.allclose(c @ c.T, np.eye(3)))  # a rotation matrix
    True
    """
    return core("align").coarse_align(_n3("dtheta", dtheta), _n3("dv", dv), float(dt_s),
                                float(lat_rad), float(h_m), bool(position_integral))
