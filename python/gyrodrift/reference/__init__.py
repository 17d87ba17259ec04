"""Reference implementations in numpy / PyWavelets, written straight from the equations.

They are deliberately plain (loops where the equations have loops) and are the oracles the
C++ core is tested against; they are not the fast path.
"""

from __future__ import annotations

__all__ = [
    "FineAlignKF",
    "InertialCoarseAlign",
    "Strapdown",
    "adev_octaves",
    "adev_rate",
    "ar_filter",
    "fit_ar2",
    "kalman_filter",
    "oadev_phase",
    "oadev_rate",
    "process_imu",
    "realtime_wavelet",
    "run_alignment_reference",
    "steady_state_gain",
    "wavelet_denoise",
]

# --- foundation: AR(2) fits and filters ---
from gyrodrift.reference.ar2 import ar_filter as ar_filter
from gyrodrift.reference.ar2 import fit_ar2 as fit_ar2
from gyrodrift.reference.ar2 import kalman_filter as kalman_filter
from gyrodrift.reference.ar2 import steady_state_gain as steady_state_gain

# isort: split
# --- drift-model likelihood ---
from gyrodrift.reference.drift import drift_loglike as drift_loglike
from gyrodrift.reference.online_drift import OnlineDriftReference as OnlineDriftReference

# isort: split
# --- wavelets ---
from gyrodrift.reference.wavelet import realtime_wavelet as realtime_wavelet
from gyrodrift.reference.wavelet import wavelet_denoise as wavelet_denoise

# isort: split
# --- Allan ---
from gyrodrift.reference.allan import adev_octaves as adev_octaves
from gyrodrift.reference.allan import adev_rate as adev_rate
from gyrodrift.reference.allan import oadev_phase as oadev_phase
from gyrodrift.reference.allan import oadev_rate as oadev_rate

# --- deviation family ---
# isort: split
from gyrodrift.reference.deviation import hdev_phase as hdev_phase
from gyrodrift.reference.deviation import mdev_phase as mdev_phase
from gyrodrift.reference.deviation import ohdev_phase as ohdev_phase
from gyrodrift.reference.deviation import rate_to_phase as rate_to_phase
from gyrodrift.reference.deviation import tdev_phase as tdev_phase
from gyrodrift.reference.deviation import totdev_phase as totdev_phase

# isort: split
# --- GMWM ---
from gyrodrift.reference.gmwm import haar_wv as haar_wv
from gyrodrift.reference.gmwm import haar_wv_pywt as haar_wv_pywt
from gyrodrift.reference.gmwm import wv_covariance_fft as wv_covariance_fft

# --- IMU processor / codecs ---
# isort: split
from gyrodrift.reference.imu import process_imu as process_imu

# --- alignment ---
# isort: split
from gyrodrift.reference.align import FineAlignKF as FineAlignKF
from gyrodrift.reference.align import InertialCoarseAlign as InertialCoarseAlign
from gyrodrift.reference.align import Strapdown as Strapdown
from gyrodrift.reference.align import run_alignment_reference as run_alignment_reference
