"""gyrodrift: random-drift removal for optical gyroscopes, and the evidence that it works.

The public API is re-exported here (see ``__all__``); the C++ core is ``gyrodrift._core``
(loaded through ``gyrodrift._native``), and ``gyrodrift.reference`` holds the numpy /
PyWavelets / scipy oracles written straight from the equations, against which the core is
tested. Conventions (unit suffixes, results, errors): CONTRIBUTING.md.

- AR(2) identification and filters: `fit_ar2`, `Ar2Model`, `Ar2FitError`, `ar_filter`,
  `kalman_filter`, `KalmanFilter`.
- Simulation: `simulate`, `simulate_imu`, `NoiseTerms`, `GyroRecord`, `ImuRecord`.
- Wavelets: `wavelet_denoise`, `RealtimeWavelet`, `forced_fir_taps`,
  `wavelet_packet_denoise`, `best_basis`.
- Analysis: `oadev`, `AllanResult`, `identify_noise`, `paper_fit`, `slope_method`,
  `welch_psd`, `load_record`.
- IMU processor and replay: `ImuProcessor`, `ImuConfig`, `ImuChannelConfig`,
  `ReplayOptions`, `run_replay`, `read_imu_log`, `write_imu_log` (the replay names import
  python-can, cantools and pyserial on first use only).
- Alignment: `AlignConfig`, `run_alignment`.
- GMWM noise-model identification with intervals and selection: `identify_gmwm`,
  `GmwmResult` (the Allan fit with selection is `gyrodrift.stability.allan_fit`).
- Errors: `GyrodriftError`, `GyrodriftValueError`, `GyrodriftTypeError`.

Examples
--------
>>> import gyrodrift
>>> rec = gyrodrift.simulate(n=1000, rate_hz=100.0, n_deg_rt_h=0.01, seed=1)
>>> model = gyrodrift.fit_ar2(rec.rate_deg_h)
>>> model.stationary
True
"""

from __future__ import annotations

# First: Ctrl-C while the `gyrodrift` command starts is one line (see the module).
from gyrodrift import _startup as _startup  # isort: skip

import importlib as _importlib
import pkgutil as _pkgutil
from typing import TYPE_CHECKING as _TYPE_CHECKING
from typing import Any as _Any

# Lets a development build of the extension (`scripts/dev-build`, PYTHONPATH=python:build/<dir>/py)
# supply gyrodrift._core next to the pure-Python sources. Installed wheels are unaffected.
__path__ = _pkgutil.extend_path(__path__, __name__)

__version__ = "0.1.0"

# --- errors (light: every other name is imported on first use) ---
from gyrodrift.errors import GyrodriftError as GyrodriftError
from gyrodrift.errors import GyrodriftTypeError as GyrodriftTypeError
from gyrodrift.errors import GyrodriftValueError as GyrodriftValueError

# --- imported on first use (PEP 562), so that `import gyrodrift` and every `gyrodrift`
# command start without numpy, scipy, the C++ core, python-can, ...: a command then
# reaches its own error handling (one line on Ctrl-C) within milliseconds ---
_LAZY = {
    "Ar2FitError": "gyrodrift.filters.ar2",
    "Ar2Model": "gyrodrift.filters.ar2",
    "KalmanFilter": "gyrodrift.filters.ar2",
    "ar_filter": "gyrodrift.filters.ar2",
    "fit_ar2": "gyrodrift.filters.ar2",
    "kalman_filter": "gyrodrift.filters.ar2",
    "GyroRecord": "gyrodrift.simulation.records",
    "ImuRecord": "gyrodrift.simulation.records",
    "NoiseTerms": "gyrodrift.simulation.records",
    "simulate": "gyrodrift.simulation.records",
    "simulate_imu": "gyrodrift.simulation.records",
    "forced_fir_taps": "gyrodrift.filters.fir",
    "RealtimeWavelet": "gyrodrift.filters.wavelet",
    "wavelet_denoise": "gyrodrift.filters.wavelet",
    "best_basis": "gyrodrift.filters.wavelet_packet",
    "wavelet_packet_denoise": "gyrodrift.filters.wavelet_packet",
    "load_record": "gyrodrift.io.records",
    "AllanResult": "gyrodrift.stability.allan",
    "oadev": "gyrodrift.stability.allan",
    "deviation": "gyrodrift.stability.deviations",
    "hdev": "gyrodrift.stability.deviations",
    "mdev": "gyrodrift.stability.deviations",
    "ohdev": "gyrodrift.stability.deviations",
    "tdev": "gyrodrift.stability.deviations",
    "totdev": "gyrodrift.stability.deviations",
    "identify_noise": "gyrodrift.stability.ieee952",
    "paper_fit": "gyrodrift.stability.ieee952",
    "slope_method": "gyrodrift.stability.ieee952",
    "welch_psd": "gyrodrift.stability.psd",
    "ImuChannelConfig": "gyrodrift.imu.processor",
    "ImuConfig": "gyrodrift.imu.processor",
    "ImuProcessor": "gyrodrift.imu.processor",
    "AlignConfig": "gyrodrift.nav",
    "run_alignment": "gyrodrift.nav",
    "ReplayOptions": "gyrodrift.replay",
    "read_imu_log": "gyrodrift.replay",
    "run_replay": "gyrodrift.replay",
    "write_imu_log": "gyrodrift.replay",
    "DriftModelFit": "gyrodrift.filters.drift_model",
    "compare_drift_models": "gyrodrift.filters.drift_model",
    "fit_drift_model": "gyrodrift.filters.drift_model",
    "GmwmResult": "gyrodrift.stability.gmwm",
    "identify_gmwm": "gyrodrift.stability.gmwm",
}

#: Subpackages and modules reachable as attributes (`gyrodrift.stability`), imported on
#: first use as the eager imports above once made them.
_SUBMODULES = frozenset({
    "cli", "codecs", "defaults", "errors", "filters", "imu", "io", "nav", "papers",
    "reference", "replay", "report", "simulation", "stability", "units", "workflows",
})

_ON_FIRST_USE = frozenset({"gyrodrift.replay", "gyrodrift.filters.drift_model",
                           "gyrodrift.stability.gmwm"})

if _TYPE_CHECKING:  # the static view of the names above
    from gyrodrift.filters.ar2 import Ar2FitError as Ar2FitError
    from gyrodrift.filters.ar2 import Ar2Model as Ar2Model
    from gyrodrift.filters.ar2 import KalmanFilter as KalmanFilter
    from gyrodrift.filters.ar2 import ar_filter as ar_filter
    from gyrodrift.filters.ar2 import fit_ar2 as fit_ar2
    from gyrodrift.filters.ar2 import kalman_filter as kalman_filter
    from gyrodrift.filters.drift_model import DriftModelFit as DriftModelFit
    from gyrodrift.filters.drift_model import compare_drift_models as compare_drift_models
    from gyrodrift.filters.drift_model import fit_drift_model as fit_drift_model
    from gyrodrift.filters.fir import forced_fir_taps as forced_fir_taps
    from gyrodrift.filters.wavelet import RealtimeWavelet as RealtimeWavelet
    from gyrodrift.filters.wavelet import wavelet_denoise as wavelet_denoise
    from gyrodrift.filters.wavelet_packet import best_basis as best_basis
    from gyrodrift.filters.wavelet_packet import wavelet_packet_denoise as wavelet_packet_denoise
    from gyrodrift.imu.processor import ImuChannelConfig as ImuChannelConfig
    from gyrodrift.imu.processor import ImuConfig as ImuConfig
    from gyrodrift.imu.processor import ImuProcessor as ImuProcessor
    from gyrodrift.io.records import load_record as load_record
    from gyrodrift.nav import AlignConfig as AlignConfig
    from gyrodrift.nav import run_alignment as run_alignment
    from gyrodrift.replay import ReplayOptions as ReplayOptions
    from gyrodrift.replay import read_imu_log as read_imu_log
    from gyrodrift.replay import run_replay as run_replay
    from gyrodrift.replay import write_imu_log as write_imu_log
    from gyrodrift.simulation.records import GyroRecord as GyroRecord
    from gyrodrift.simulation.records import ImuRecord as ImuRecord
    from gyrodrift.simulation.records import NoiseTerms as NoiseTerms
    from gyrodrift.simulation.records import simulate as simulate
    from gyrodrift.simulation.records import simulate_imu as simulate_imu
    from gyrodrift.stability.allan import AllanResult as AllanResult
    from gyrodrift.stability.allan import oadev as oadev
    from gyrodrift.stability.deviations import deviation as deviation
    from gyrodrift.stability.deviations import hdev as hdev
    from gyrodrift.stability.deviations import mdev as mdev
    from gyrodrift.stability.deviations import ohdev as ohdev
    from gyrodrift.stability.deviations import tdev as tdev
    from gyrodrift.stability.deviations import totdev as totdev
    from gyrodrift.stability.gmwm import GmwmResult as GmwmResult
    from gyrodrift.stability.gmwm import identify_gmwm as identify_gmwm
    from gyrodrift.stability.ieee952 import identify_noise as identify_noise
    from gyrodrift.stability.ieee952 import paper_fit as paper_fit
    from gyrodrift.stability.ieee952 import slope_method as slope_method
    from gyrodrift.stability.psd import welch_psd as welch_psd

__all__ = [
    "AlignConfig",
    "AllanResult",
    "Ar2FitError",
    "Ar2Model",
    "GmwmResult",
    "GyroRecord",
    "GyrodriftError",
    "GyrodriftTypeError",
    "GyrodriftValueError",
    "ImuChannelConfig",
    "ImuConfig",
    "ImuProcessor",
    "ImuRecord",
    "KalmanFilter",
    "NoiseTerms",
    "RealtimeWavelet",
    "ReplayOptions",
    "__version__",
    "ar_filter",
    "best_basis",
    "deviation",
    "fit_ar2",
    "forced_fir_taps",
    "hdev",
    "identify_gmwm",
    "identify_noise",
    "kalman_filter",
    "load_record",
    "mdev",
    "oadev",
    "ohdev",
    "paper_fit",
    "read_imu_log",
    "run_alignment",
    "run_replay",
    "simulate",
    "simulate_imu",
    "slope_method",
    "tdev",
    "totdev",
    "wavelet_denoise",
    "wavelet_packet_denoise",
    "welch_psd",
    "write_imu_log",
]


def __getattr__(name: str) -> _Any:
    """Import the _LAZY names and the _SUBMODULES on first use (PEP 562)."""
    if name in _LAZY:
        value = getattr(_importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    if name in _SUBMODULES:
        # The modules the names above come from, as the package once imported them all at
        # once (so `gyrodrift.simulation.records` is there after `import gyrodrift`); the
        # replay, drift-model and GMWM modules stay on first use of their names.
        for module in sorted(set(_LAZY.values()) - _ON_FIRST_USE):
            _importlib.import_module(module)
        return _importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'gyrodrift' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY) | _SUBMODULES)
