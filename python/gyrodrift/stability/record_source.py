"""A rate record read in aligned chunks, in memory or from a file (memmap), with the evenly
reflected ends of NIST SP 1065's TOTVAR extension: the one reader the deviation kernels and
the noise-type identification stream from."""

from __future__ import annotations

import mmap
from collections.abc import Iterator

import numpy as np

from gyrodrift.errors import GyrodriftValueError

__all__ = ["RecordSource"]


class RecordSource:
    """The rate record as float64 chunks: pieces(start, stop) over the virtual index range of
    the evenly reflected record (SP 1065's TOTVAR extension: y*_{-1-k} = y_k,
    y*_{N+k} = y_{N-1-k}), read from the file for a memmap, as views otherwise; phase input
    is differenced chunk by chunk. Each piece is at most `chunk` samples.

    Examples
    --------
    >>> src = RecordSource(np.arange(4.0), "rate", 1.0, chunk=3)
    >>> [p.tolist() for p in src.pieces(-2, 6)]  # reflected at both ends, in chunks of 3
    [[1.0, 0.0, 0.0], [1.0, 2.0, 3.0], [3.0, 2.0]]
    """

    def __init__(self, data: np.ndarray, kind: str, rate_hz: float, chunk: int) -> None:
        self.data = data
        self.phase = kind == "phase"
        self.rate_hz = rate_hz
        self.chunk = chunk
        self.n = data.shape[0] - (1 if self.phase else 0)
        self.file = (isinstance(data, np.memmap) and isinstance(data.base, mmap.mmap)
                     and data.flags.c_contiguous)

    def _read(self, start: int, stop: int) -> np.ndarray:
        """Rate samples [start, stop) of the real record (0 <= start <= stop <= n)."""
        hi = stop + (1 if self.phase else 0)
        if self.file:
            mm = self.data
            assert isinstance(mm, np.memmap)  # self.file implies it (constructor)
            name = str(mm.filename)
            with open(name, "rb") as fh:
                fh.seek(mm.offset + start * mm.dtype.itemsize)
                raw = np.fromfile(fh, dtype=mm.dtype, count=hi - start)
            if raw.size != hi - start:
                raise GyrodriftValueError(f"{name}: file shorter than its header says")
        else:
            raw = self.data[start:hi]
        raw = np.asarray(raw, dtype=np.float64)
        if self.phase:
            raw = np.diff(raw) * self.rate_hz
        bad = int(np.count_nonzero(~np.isfinite(raw)))
        if bad:
            raise GyrodriftValueError(f"data: {bad} NaN/Inf samples in [{start}, {stop}); drop or "
                             "repair them first")
        return np.ascontiguousarray(raw)

    def pieces(self, start: int, stop: int) -> Iterator[np.ndarray]:
        """y*[start:stop) in chunks of exactly `chunk` samples (the last one shorter), so
        that streams at different offsets stay aligned; each chunk is assembled from at most
        three reads (left mirror, record, right mirror)."""
        n = self.n
        for a in range(start, stop, self.chunk):
            b = min(a + self.chunk, stop)
            parts = []
            if a < 0:  # k in [a, min(b, 0)) -> y[-1-k]: y[-min(b,0) : -a] reversed
                parts.append(self._read(-min(b, 0), -a)[::-1])
            if max(a, 0) < min(b, n):
                parts.append(self._read(max(a, 0), min(b, n)))
            if b > n:  # k in [max(a, n), b) -> y[2n-1-k]: y[2n-b : 2n-max(a,n)] reversed
                parts.append(self._read(2 * n - b, 2 * n - max(a, n))[::-1])
            yield np.ascontiguousarray(parts[0] if len(parts) == 1 else np.concatenate(parts))

    raw_pieces = pieces
