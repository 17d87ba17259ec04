"""SINS initial alignment on a rocking base (paper 004): truth simulation by exact
inversion, the C++ alignment pipeline (strapdown, inertial-frame coarse alignment, 12/15-state
fine-alignment Kalman filter, the real-time wavelet prefilter as an FIR), Monte Carlo study and
real-data run.

The plain-loop numpy references (`Strapdown`, `InertialCoarseAlign`, `FineAlignKF`,
`run_alignment_reference`) are the oracles of ``include/gyrodrift/nav/*.hpp`` and live in
`gyrodrift.reference.align`; the Earth model is `gyrodrift.nav.earth`, the prefilter's FIR
`gyrodrift.filters.fir`.

Examples
--------
>>> from gyrodrift.nav import AlignConfig
>>> AlignConfig().n_states
15
"""

from __future__ import annotations

from gyrodrift.nav.align_config import AlignConfig, AlignResult
from gyrodrift.nav.alignment import coarse_align, run_alignment, strapdown_run
from gyrodrift.nav.attitude import dcm2euler, euler2dcm, misalignment
from gyrodrift.nav.trajectory import SCENARIOS, Scenario, imu_increments, scenario, truth_at

__all__ = [
    "SCENARIOS",
    "AlignConfig",
    "AlignResult",
    "Scenario",
    "coarse_align",
    "dcm2euler",
    "euler2dcm",
    "imu_increments",
    "misalignment",
    "run_alignment",
    "scenario",
    "strapdown_run",
    "truth_at",
]
