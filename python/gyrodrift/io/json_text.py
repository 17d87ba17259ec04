"""Strict JSON text for every file and stream the package writes.

Python's ``json`` writes NaN and Infinity as bare words, which strict parsers (JavaScript,
jq, serde, Go) refuse. Results carry NaN where a value does not exist (a fit outside its
range, an interval that is not defined), so every writer goes through `json_text`, which
writes them as ``null``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.errors import GyrodriftTypeError

__all__ = ["json_default", "json_text", "strict_json_value"]


def json_default(obj: Any) -> Any:
    """``json`` fallback for numpy scalars and arrays, paths and dataclass results.

    Examples
    --------
    >>> json_default(np.float32(0.5)), json_default(np.arange(2))
    (0.5, [0, 1])
    """
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    as_dict = getattr(obj, "as_dict", None)
    if callable(as_dict):
        return as_dict()
    raise GyrodriftTypeError(f"not JSON serialisable: {type(obj).__name__}")


def strict_json_value(obj: Any) -> Any:
    """``obj`` with every NaN/Inf float (Python, numpy scalar or array element) as None.

    Examples
    --------
    >>> strict_json_value({"a": [1.0, float("nan")], "b": np.array([np.inf, 2.0])})
    {'a': [1.0, None], 'b': [None, 2.0]}
    """
    if isinstance(obj, float | np.floating):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict_json_value(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [strict_json_value(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return strict_json_value(obj.tolist())
    as_dict = getattr(obj, "as_dict", None)
    if callable(as_dict) and not isinstance(obj, type):
        return strict_json_value(as_dict())
    return obj


def json_text(payload: Any, indent: int = 2) -> str:
    """``payload`` as strict JSON text (NaN/Inf as null), numpy and results converted.

    Examples
    --------
    >>> print(json_text({"n": np.int64(3), "fit": float("nan")}, indent=0))
    {
    "n": 3,
    "fit": null
    }
    """
    return json.dumps(strict_json_value(payload), indent=indent, default=json_default,
                      allow_nan=False)
