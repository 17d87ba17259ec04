"""The one loader of the C++ extension ``gyrodrift._core``.

The extension is imported on first use so that ``import gyrodrift`` and the pure-Python
references work without it; a missing extension, or one built without a binding area, gives
one clear message.

Examples
--------
>>> from gyrodrift._native import core
>>> hasattr(core(), "ar2_fit")
True
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["AREA_PROBES", "core"]

_MISSING = (
    "gyrodrift._core (the C++ extension) is not available: install the package "
    "(`pip install .`) or build it for development (`scripts/dev-build NAME`, then set "
    "PYTHONPATH as it prints)"
)


#: One name each binding area defines: its presence tells that the extension was built with
#: the area (a development build may select a subset, GYRODRIFT_BINDINGS in CMake).
AREA_PROBES = {
    "ar2": "ar2_kalman_batch",
    "wavelet": "realtime_wavelet_max_level",
    "allan": "deviation_sigma2",
    "imu": "ImuProcessor",
    "align": "align_run",
    "drift": "drift_loglike",
}


def core(area: str | None = None) -> ModuleType:
    """Return ``gyrodrift._core``, importing it on first use.

    Parameters
    ----------
    area : str, optional
        Binding area the caller needs (a key of ``AREA_PROBES``); a build without it fails
        with a message naming the area.

    Returns
    -------
    module
        The extension module.

    Raises
    ------
    ImportError
        The extension is not built, or was built without the area.

    Examples
    --------
    >>> core("ar2").__name__
    'gyrodrift._core'
    """
    try:
        _core = importlib.import_module("gyrodrift._core")
    except ImportError as exc:
        raise ImportError(_MISSING) from exc
    if area is not None and not hasattr(_core, AREA_PROBES.get(area, f"<no area {area}>")):
        raise ImportError(
            f"gyrodrift._core was built without the {area!r} binding area "
            "(BINDINGS in scripts/dev-build / GYRODRIFT_BINDINGS in CMake)"
        )
    return _core
