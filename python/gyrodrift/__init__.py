"""gyrodrift: random-drift removal for optical gyroscopes, and the evidence that it works.

The public API is re-exported here; `gyrodrift.reference` holds the numpy/PyWavelets
reference implementations written straight from the equations, against which the C++
core (`gyrodrift._core`) is tested.
"""

from __future__ import annotations

import pkgutil as _pkgutil

# Lets a development build of the extension (`scripts/dev-build`, PYTHONPATH=python:build/<dir>/py)
# supply gyrodrift._core next to the pure-Python sources. Installed wheels are unaffected.
__path__ = _pkgutil.extend_path(__path__, __name__)

__version__ = "0.1.0"

# --- foundation (issue 2): simulator, AR(2) identification, AR and AR(2)-Kalman filters ---
from gyrodrift.ar2 import Ar2FitError as Ar2FitError
from gyrodrift.ar2 import Ar2Model as Ar2Model
from gyrodrift.ar2 import KalmanFilter as KalmanFilter
from gyrodrift.ar2 import ar_filter as ar_filter
from gyrodrift.ar2 import fit_ar2 as fit_ar2
from gyrodrift.ar2 import kalman_filter as kalman_filter
from gyrodrift.simulate import GyroRecord as GyroRecord
from gyrodrift.simulate import ImuRecord as ImuRecord
from gyrodrift.simulate import NoiseTerms as NoiseTerms
from gyrodrift.simulate import simulate as simulate
from gyrodrift.simulate import simulate_imu as simulate_imu

# --- wavelets (issue 3) ---
from gyrodrift.wavelet import RealtimeWavelet as RealtimeWavelet
from gyrodrift.wavelet import forced_fir_taps as forced_fir_taps
from gyrodrift.wavelet import wavelet_denoise as wavelet_denoise
from gyrodrift.wavelet_packet import best_basis as best_basis
from gyrodrift.wavelet_packet import wavelet_packet_denoise as wavelet_packet_denoise

# --- Allan / PSD / analysis (issue 4) ---
# isort: split
from gyrodrift.allan import AllanResult as AllanResult
from gyrodrift.allan import oadev as oadev
from gyrodrift.io import load_record as load_record
from gyrodrift.noise_id import identify_noise as identify_noise
from gyrodrift.noise_id import paper_fit as paper_fit
from gyrodrift.noise_id import slope_method as slope_method
from gyrodrift.psd import welch_psd as welch_psd

# --- IMU processor, codecs, replay (issue 5) ---
# isort: split
from gyrodrift.imu import ImuChannelConfig as ImuChannelConfig
from gyrodrift.imu import ImuConfig as ImuConfig
from gyrodrift.imu import ImuProcessor as ImuProcessor
from gyrodrift.replay import ReplayOptions as ReplayOptions
from gyrodrift.replay import read_imu_log as read_imu_log
from gyrodrift.replay import run_replay as run_replay
from gyrodrift.replay import write_imu_log as write_imu_log

# --- alignment (issue 6) ---
# isort: split
from gyrodrift.align import AlignConfig as AlignConfig
from gyrodrift.align import run_alignment as run_alignment

# --- GMWM noise identification (issue 11) ---
# isort: split
from gyrodrift.gmwm import GmwmResult as GmwmResult
from gyrodrift.gmwm import identify_gmwm as identify_gmwm
