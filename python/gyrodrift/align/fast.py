"""C++ fast path (gyrodrift._core, header nav_align_pipeline.hpp) behind the same interface as
the plain-loop references in this package."""

from __future__ import annotations

from typing import Any

import numpy as np

from gyrodrift import _native

from .config import AlignConfig

__all__ = [
    "coarse_align",
    "run_alignment",
    "strapdown_run",
]


def _core() -> Any:  # lazily: the pure-Python references work without the extension
    return _native.core("align", "align_run")


def _n3(name: str, a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    if a.dtype != np.float64:
        raise TypeError(f"{name}: expected float64 increments, got {a.dtype}")
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (n, 3), got {a.shape}")
    return np.ascontiguousarray(a)


def run_alignment(dtheta: np.ndarray, dv: np.ndarray, cfg: AlignConfig) -> dict[str, np.ndarray]:
    """Whole alignment in C++ (GIL released). Same outputs as `run_alignment_reference`, plus
    `bad_samples` (non-finite samples counted and skipped) and `failed`."""
    # cfg.taps are newest first (gyrodrift.fir); the C++ pipeline takes them oldest first.
    taps = (np.zeros(0) if cfg.taps is None
            else np.ascontiguousarray(np.asarray(cfg.taps, dtype=np.float64)[::-1]))
    return _core().align_run(
        _n3("dtheta", dtheta), _n3("dv", dv), float(cfg.dt_s), float(cfg.lat_rad),
        float(cfg.lon_rad), float(cfg.h_m), int(cfg.coarse_samples()),
        bool(cfg.coarse_position_integral), int(cfg.n_states), int(cfg.kf_every),
        cfg.p0_diag(), cfg.q_diag(), np.full(3, cfg.zv_sigma_m_s ** 2), cfg.floor_diag(), taps,
        int(cfg.accel_delay_samples), int(cfg.heading_stage_cycles()),
        float(cfg.heading_stage_q))


def strapdown_run(dtheta: np.ndarray, dv: np.ndarray, dt_s: float, q0: np.ndarray,
                  v0: np.ndarray,
                  pos0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """C++ strapdown over increments: (q history, v history, final position, skipped count)."""
    return _core().strapdown_run(_n3("dtheta", dtheta), _n3("dv", dv), float(dt_s),
                                 np.asarray(q0, dtype=np.float64), np.asarray(v0, dtype=np.float64),
                                 np.asarray(pos0, dtype=np.float64))


def coarse_align(dtheta: np.ndarray, dv: np.ndarray, dt_s: float, lat_rad: float, h_m: float,
                 position_integral: bool = True) -> np.ndarray:
    """C++ inertial-frame coarse alignment over the whole window; C_b^n at its end."""
    return _core().coarse_align(_n3("dtheta", dtheta), _n3("dv", dv), float(dt_s),
                                float(lat_rad), float(h_m), bool(position_integral))
