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

from types import ModuleType

__all__ = ["core"]

_MISSING = (
    "gyrodrift._core (the C++ extension) is not available: install the package "
    "(`pip install .`) or build it for development (`scripts/dev-build NAME`, then set "
    "PYTHONPATH as it prints)"
)


def core(area: str | None = None, attr: str | None = None) -> ModuleType:
    """Return ``gyrodrift._core``, importing it on first use.

    Parameters
    ----------
    area : str, optional
        Binding area the caller needs (ar2, wavelet, allan, imu, align); named in the message
        when ``attr`` is missing.
    attr : str, optional
        A name the area defines; checked so that a build without the area fails clearly.

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
    >>> core("ar2", "ar2_fit").__name__
    'gyrodrift._core'
    """
    try:
        from gyrodrift import _core
    except ImportError as exc:
        raise ImportError(_MISSING) from exc
    if attr is not None and not hasattr(_core, attr):
        raise ImportError(
            f"gyrodrift._core was built without the {area or attr!r} binding area "
            "(BINDINGS in scripts/dev-build / GYRODRIFT_BINDINGS in CMake)"
        )
    return _core
