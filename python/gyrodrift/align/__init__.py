"""SINS initial alignment on a rocking base (issue 6, paper 004): truth simulation by exact
inversion, ENU strapdown, inertial-frame coarse alignment, 12/15-state fine-alignment Kalman
filter, the real-time wavelet prefilter as an FIR, Monte Carlo study and real-data run.

Plain-loop numpy references (`*_reference`, `Strapdown`, `InertialCoarseAlign`, `FineAlignKF`)
are the oracles for the C++ headers include/gyrodrift/nav_*.hpp used by `run_alignment`.
"""

from __future__ import annotations

from .attitude import dcm2euler, euler2dcm, misalignment
from .coarse import InertialCoarseAlign
from .earth import ARCMIN, ARCSEC, DEG, DPH, DPSH, EARTH_RATE_RPS, UG, gravity_mps2
from .fast import coarse_align, run_alignment, strapdown_run
from .fine_kf import FineAlignKF
from .pipeline import AlignConfig, run_alignment_reference
from .prefilter import apply_realtime, group_delay_dc_samples, realtime_wavelet_taps
from .strapdown import Strapdown
from .trajectory import SCENARIOS, Scenario, imu_increments, scenario, truth_at

__all__ = [
    "ARCMIN", "ARCSEC", "DEG", "DPH", "DPSH", "EARTH_RATE_RPS", "SCENARIOS", "UG",
    "AlignConfig", "FineAlignKF", "InertialCoarseAlign", "Scenario", "Strapdown",
    "apply_realtime", "coarse_align", "dcm2euler", "euler2dcm", "gravity_mps2",
    "group_delay_dc_samples", "imu_increments", "misalignment", "realtime_wavelet_taps",
    "run_alignment", "run_alignment_reference", "scenario", "strapdown_run", "truth_at",
]
