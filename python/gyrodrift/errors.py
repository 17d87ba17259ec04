"""The package's exception types: one base class, value and type subclasses.

Every error gyrodrift raises on purpose derives from :class:`GyrodriftError`. Bad values are
:class:`GyrodriftValueError` (also a ``ValueError``), bad types :class:`GyrodriftTypeError`
(also a ``TypeError``), so ``except ValueError`` keeps working. A cause the caller may act on
is an attribute (``.cause``) set from the C++ status code through the binding, never parsed
from a message.

Examples
--------
>>> from gyrodrift.errors import GyrodriftError, GyrodriftValueError
>>> try:
...     raise GyrodriftValueError("rate_hz must be positive")
... except GyrodriftError as exc:
...     print(type(exc).__name__, isinstance(exc, ValueError))
GyrodriftValueError True
"""

from __future__ import annotations

__all__ = ["GyrodriftError", "GyrodriftTypeError", "GyrodriftValueError"]


class GyrodriftError(Exception):
    """Base class of every error gyrodrift raises on purpose.

    Examples
    --------
    >>> issubclass(GyrodriftValueError, GyrodriftError)
    True
    """


class GyrodriftValueError(GyrodriftError, ValueError):
    """A bad value (NaN, out of range, too short, wrong shape, unknown name).

    Examples
    --------
    >>> isinstance(GyrodriftValueError("x"), ValueError)
    True
    """


class GyrodriftTypeError(GyrodriftError, TypeError):
    """A bad type (non-numeric array, wrong dtype, wrong object).

    Examples
    --------
    >>> isinstance(GyrodriftTypeError("x"), TypeError)
    True
    """
