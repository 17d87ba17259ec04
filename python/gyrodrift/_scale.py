"""The power of two that brings a record of extreme magnitude into the range where sums of
squares and optimiser steps neither overflow nor underflow.

Estimators whose results scale with the record (a variance by c^2, a deviation by c) run on
``x / c`` and scale their results back: dividing by a power of two is exact (short of
subnormal numbers), and records inside the safe range are left as they are (c = 1).

Examples
--------
>>> import math
>>> import numpy as np
>>> c = normalising_scale(np.array([3e150, -1.0]))
>>> normalising_scale(np.array([1.0, -3.0])), c / 2 <= 3e150 < c, math.log2(c).is_integer()
(1.0, True, True)
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["SAFE_EXPONENT", "normalising_scale", "scale_for_peak"]

#: A record whose largest magnitude has a binary exponent within +-SAFE_EXPONENT is left as
#: it is: its squares (and sums of 1e9 of them) stay within float64 by a wide margin.
SAFE_EXPONENT = 64


def normalising_scale(a: np.ndarray) -> float:
    """1.0, or the power of two c with max|a| / c in [0.5, 1) when max|a| is outside
    [2^-SAFE_EXPONENT, 2^SAFE_EXPONENT]; 1.0 for an empty, all-zero or non-finite record
    (left to the estimator's own checks). Reads the record twice (max, min), no copy."""
    if a.size == 0:
        return 1.0
    return scale_for_peak(max(float(np.max(a)), -float(np.min(a))))


def scale_for_peak(peak: float) -> float:
    """`normalising_scale` of a record whose largest magnitude is `peak` (for a record read
    in pieces: the largest of the pieces' peaks).

    Examples
    --------
    >>> scale_for_peak(3.0), scale_for_peak(0.0), scale_for_peak(2.0**-70) == 2.0**-69
    (1.0, 1.0, True)
    >>> scale_for_peak(1.7e308) == 2.0**1023
    True
    """
    if not math.isfinite(peak) or peak == 0.0:
        return 1.0
    exponent = math.frexp(peak)[1]
    # 2^1024 is not a double: the largest records get 2^1023 (max / c in [1, 2)).
    return 1.0 if abs(exponent) <= SAFE_EXPONENT else math.ldexp(1.0, min(exponent, 1023))
