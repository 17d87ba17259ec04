"""Whole-record lag statistics of a rate record, kept sample by sample on the C++ core the
target runs (include/gyrodrift/filters/lag_statistics.hpp), from which the exact likelihood
of the drift model (that of :func:`gyrodrift.filters.drift_model.fit_drift_model`) follows.

State of the accepted samples y_0 .. y_{n-1}, with w_t = y_t - c and c = y_0 (the centre):
n, sum_t w_t (``total``), the lag products P_k = sum_{t>=k} w_t w_{t-k} for k = 0..L
(``products``, L = 32), the first min(n, L) values of w (``head``) and the last min(n, L)
(``tail``, oldest first). Fixed memory and L + 1 products per sample, whatever n; every sum
is carried as a compensated pair (about twice the precision of the state's scalar) and read
out in float64. Non-finite samples are refused and counted (``rejected``).

The attribute names are those of the numpy reference's statistics
(``gyrodrift.reference.lag_drift``), whose likelihood and fit take either. Measurements:
docs/validation/online-identification.md, "Whole-record statistics".

``dtype=np.float32`` runs the float state the microcontroller uses.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftValueError

__all__ = ["LagStatistics"]


class LagStatistics:
    """Streaming whole-record lag statistics (L = 32 lags) of a rate record.

    Parameters
    ----------
    dtype : numpy dtype, optional
        ``np.float64`` (default) or ``np.float32`` (the float state of the target).

    Raises
    ------
    GyrodriftValueError
        Another dtype.

    Examples
    --------
    >>> st = LagStatistics()
    >>> st.push([1.0, 2.0, 4.0]), st.push([3.0, float("nan")])  # w = 0, 1, 3, 2
    (3, 1)
    >>> st.n, st.rejected, st.centre, st.total
    (4, 1, 1.0, 6.0)
    >>> st.products[:3].tolist(), st.head.tolist(), st.tail.tolist()
    ([14.0, 9.0, 2.0], [0.0, 1.0, 3.0, 2.0], [0.0, 1.0, 3.0, 2.0])
    >>> st.lags, LagStatistics(dtype=np.float32).state_bytes
    (32, 552)
    """

    #: L, the largest lag kept.
    lags: int = 32

    def __init__(self, *, dtype: DTypeLike = np.float64) -> None:
        self._dtype = np.dtype(dtype)
        lib = core("drift")
        if self._dtype == np.float64:
            cls = lib.LagStatistics
        elif self._dtype == np.float32:
            cls = lib.LagStatisticsF32
        else:
            raise GyrodriftValueError(f"dtype must be float64 or float32, got {self._dtype}")
        self._impl: Any = cls()
        if int(self._impl.lags) != self.lags:
            raise AssertionError(f"the C++ statistics keep {self._impl.lags} lags, not {self.lags}")

    def push(self, y: ArrayLike) -> int:
        """Add rate samples in time order (GIL released); returns the number accepted.

        Non-finite samples are skipped and counted in :attr:`rejected`. Pushing a record in
        chunks of any size gives the same state as pushing it at once.

        Raises
        ------
        GyrodriftValueError
            y is not one-dimensional.
        """
        arr = np.ascontiguousarray(y, dtype=self._dtype)
        if arr.ndim != 1:
            raise GyrodriftValueError(f"y: expected a 1-D array, got shape {arr.shape}")
        return int(self._impl.push(arr))

    def reset(self) -> None:
        """Forget every sample and the rejected count."""
        self._impl.reset()

    @property
    def dtype(self) -> np.dtype[Any]:
        """The precision of the state (float64 or float32)."""
        return self._dtype

    @property
    def n(self) -> int:
        """Samples accepted so far."""
        return int(self._impl.n)

    @property
    def rejected(self) -> int:
        """Non-finite samples skipped so far."""
        return int(self._impl.rejected)

    @property
    def centre(self) -> float:
        """c, the first accepted sample (0 before it)."""
        return float(self._impl.centre)

    @property
    def total(self) -> float:
        """sum_t w_t."""
        return float(self._impl.total)

    @property
    def products(self) -> np.ndarray:
        """The lag products P_0 .. P_L (float64, L + 1 values)."""
        return np.asarray(self._impl.products)

    @property
    def head(self) -> np.ndarray:
        """The first min(n, L) values of w (float64)."""
        return np.asarray(self._impl.head)

    @property
    def tail(self) -> np.ndarray:
        """The last min(n, L) values of w, oldest first (float64)."""
        return np.asarray(self._impl.tail)

    @property
    def state_bytes(self) -> int:
        """Size of the C++ statistics' state in this precision (bytes)."""
        return int(self._impl.state_bytes)
