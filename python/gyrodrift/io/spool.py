"""Records read and normalized in bounded memory, for the readers of `gyrodrift.io.records`
and `gyrodrift.io.imu_data`.

- :class:`SampleSpool`: float64 samples appended in pieces; kept in memory below
  :data:`SPOOL_MIN_SAMPLES`, from there on written to a file in a temporary directory and
  returned as a read-only memory map (which the analyses read in chunks with file reads).
  The directory is removed when no array refers to the mapping any more, or at the latest
  when the interpreter exits. Disk: 8 bytes per sample.
- :func:`iter_row_blocks`: the rows of a (memory-mapped) .npy array in blocks, read with
  plain file reads (pages touched through a mapping would stay resident in the process).
- :func:`iter_text_tables`: a text table parsed in blocks of lines (by ``numpy.loadtxt``,
  or ``numpy.genfromtxt`` where loadtxt refuses a block), every block with the column count
  of the first data line and the file's line numbers in its errors, as one call of
  genfromtxt on the whole file gives them.
- :func:`chunked_median`: the exact median of values produced in pieces (``numpy.median``'s
  value), by a radix selection over the values' bit patterns: memory does not grow with
  their number.
"""

from __future__ import annotations

import itertools
import os
import re
import shutil
import tempfile
import warnings
import weakref
from collections.abc import Callable, Iterable, Iterator
from types import TracebackType
from typing import IO

import numpy as np

from gyrodrift.errors import GyrodriftValueError

__all__ = ["BLOCK_ROWS", "SPOOL_MIN_SAMPLES", "TEXT_BLOCK_LINES", "SampleSpool",
           "chunked_median", "iter_row_blocks", "iter_text_tables"]

#: Records with at least this many samples are normalized into a temporary file; shorter
#: ones stay in memory (8 MB at most).
SPOOL_MIN_SAMPLES = 1 << 20
#: Rows of a .npy array read at a time.
BLOCK_ROWS = 1 << 18
#: Lines of a text table parsed at a time (``numpy.genfromtxt``, where it parses a block,
#: holds a few hundred bytes per line: about 20 MB per block).
TEXT_BLOCK_LINES = 1 << 16


class SampleSpool:
    """float64 samples appended in pieces, in memory while fewer than `memory_max`, from
    there on in a temporary file (module docstring).

    Use it as a context manager: an error inside the block removes the file; `finish`
    returns the samples (an array, or a read-only ``numpy.memmap`` of the file).

    Parameters
    ----------
    memory_max
        the number of samples from which they go to the file (default
        :data:`SPOOL_MIN_SAMPLES`); 0 writes every sample to the file.
    name
        the file's name stem (for messages and debugging).

    Examples
    --------
    >>> with SampleSpool(memory_max=3) as spool:
    ...     spool.append(np.arange(2.0))
    ...     spool.append(np.arange(2.0, 5.0))
    ...     x = spool.finish()
    >>> type(x).__name__, x.tolist()
    ('memmap', [0.0, 1.0, 2.0, 3.0, 4.0])
    """

    def __init__(self, memory_max: int | None = None, name: str = "record") -> None:
        self.n = 0
        self._memory_max = int(SPOOL_MIN_SAMPLES if memory_max is None else memory_max)
        self._name = name
        self._parts: list[np.ndarray] = []
        self._dir: str | None = None
        self._fh: IO[bytes] | None = None
        self._done = False

    @property
    def on_file(self) -> bool:
        """Whether the samples went to the temporary file."""
        return self._dir is not None

    def append(self, values: np.ndarray) -> None:
        """Append `values` (converted to float64; copied, so a reused buffer may follow)."""
        v = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
        if self._fh is None and self.n + v.size >= self._memory_max:
            self._dir = tempfile.mkdtemp(prefix="gyrodrift-record.")
            self._fh = open(os.path.join(self._dir, f"{self._name}.f64"), "wb")
            for part in self._parts:
                self._fh.write(part.data)
            self._parts = []
        if self._fh is not None:
            self._fh.write(v.data)
        else:
            self._parts.append(v.copy())
        self.n += int(v.size)

    def finish(self) -> np.ndarray:
        """The samples: an in-memory array, or a read-only memory map of the file (removed
        with its directory when no array refers to the mapping, or at exit)."""
        self._done = True
        if self._fh is None:
            return np.concatenate(self._parts) if self._parts else np.empty(0)
        self._fh.close()
        assert self._dir is not None
        if self.n == 0:  # a file of zero bytes cannot be mapped
            shutil.rmtree(self._dir, ignore_errors=True)
            return np.empty(0)
        mm = np.memmap(os.path.join(self._dir, f"{self._name}.f64"), dtype=np.float64,
                       mode="r", shape=(self.n,))
        # every view of the map (and every array made from one) holds the mmap object
        weakref.finalize(mm.base, shutil.rmtree, self._dir, ignore_errors=True)
        return mm

    def discard(self) -> None:
        """Remove the temporary file (if any) and forget the samples."""
        self._done = True
        self._parts = []
        if self._fh is not None:
            self._fh.close()
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self) -> SampleSpool:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is not None or not self._done:
            self.discard()


def _file_of(arr: np.ndarray) -> tuple[str, int] | None:
    """(file name, byte offset of element 0) of a memory-mapped .npy array (what
    ``numpy.load(mmap_mode="r")`` returns; not a view into one), else None."""
    if (isinstance(arr, np.memmap) and arr.filename is not None
            and (arr.flags.c_contiguous or arr.flags.f_contiguous)
            and arr.base is not None and not isinstance(arr.base, np.ndarray)):
        return str(arr.filename), int(arr.offset)
    return None


def iter_row_blocks(arr: np.ndarray, rows: int | None = None) -> Iterator[np.ndarray]:
    """Consecutive blocks of at most `rows` rows (default :data:`BLOCK_ROWS`) of a 1-D or
    2-D array (in its own dtype):
    read from the file with plain file reads for a memory-mapped .npy array (C or Fortran
    order), slices otherwise.

    Examples
    --------
    >>> [b.tolist() for b in iter_row_blocks(np.arange(6).reshape(3, 2), rows=2)]
    [[[0, 1], [2, 3]], [[4, 5]]]
    """
    n = int(arr.shape[0])
    rows = BLOCK_ROWS if rows is None else int(rows)
    where = _file_of(arr)
    if where is None:
        for lo in range(0, n, rows):
            yield np.asarray(arr[lo:lo + rows])
        return
    name, offset = where
    item = arr.dtype.itemsize
    k = int(np.prod(arr.shape[1:], dtype=np.int64))
    c_order = arr.ndim == 1 or arr.flags.c_contiguous
    with open(name, "rb") as fh:
        for lo in range(0, n, rows):
            m = min(rows, n - lo)
            block = np.empty((m, *arr.shape[1:]), dtype=arr.dtype,
                             order="C" if c_order else "F")
            if c_order:
                fh.seek(offset + lo * k * item)
                got = fh.readinto(block.reshape(-1).view(np.uint8).data)
                short = got != block.nbytes
            else:  # Fortran order: each column is contiguous in the file
                short = False
                for j in range(k):
                    fh.seek(offset + (j * n + lo) * item)
                    col = block[:, j]
                    short |= fh.readinto(col.view(np.uint8).data) != col.nbytes
            if short:
                raise GyrodriftValueError(f"{name}: file shorter than its header says")
            yield block


_LINE_NO = re.compile(r"Line #(\d+)")


def _shift_line_numbers(text: str, shift: int) -> str:
    """genfromtxt's "Line #N" in `text` moved by `shift` lines."""
    return _LINE_NO.sub(lambda m: f"Line #{int(m.group(1)) + shift}", text)


def _is_data_line(line: str, comments: str) -> bool:
    """Whether numpy.genfromtxt finds values on `line` (not blank once its comment is cut)."""
    return bool(line.split(comments)[0].strip(" \r\n"))


def _parse_plain(lines: list[str], delimiter: str | None, comments: str) -> np.ndarray | None:
    """The block's numbers by ``numpy.loadtxt``'s C parser (about a quarter of
    ``numpy.genfromtxt``'s time per line), or None when it refuses the block.

    loadtxt accepts fewer blocks than genfromtxt and reads every one it accepts as genfromtxt
    does: a number both read alike (Python's float syntax without underscores and
    non-ASCII digits), the same comments and delimiters. It refuses what genfromtxt reads
    otherwise or refuses with line numbers: empty, blank or non-numeric cells (genfromtxt:
    NaN), blank lines between rows that hold spaces (genfromtxt skips them), rows of another
    field count, a block without rows; such a block is parsed by genfromtxt.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = np.loadtxt(lines, delimiter=delimiter, comments=comments,
                               dtype=np.float64, ndmin=2)
    except ValueError:
        return None
    return table if table.shape[0] else None


def iter_text_tables(fh: Iterable[str], *, delimiter: str | None, first_line_no: int,
                     malformed: str = "malformed text table", comments: str = "#",
                     lines: int | None = None
                     ) -> Iterator[tuple[np.ndarray, list[str], int]]:
    """The numbers of a text table in blocks: (float64 table of the block's rows, the
    block's lines, the file line number of its first line), as ``numpy.genfromtxt`` parses
    them (cells that are not numbers become NaN; a row with another field count than the
    first data line raises GyrodriftValueError ``"<malformed>: <genfromtxt's message>"`` with
    the file's line numbers), `lines` lines at a time (default :data:`TEXT_BLOCK_LINES`). A
    block goes to ``numpy.loadtxt``'s faster parser first, which reads every block it
    accepts as genfromtxt does (`_parse_plain`), and to genfromtxt when loadtxt refuses it.

    `fh` yields the lines after any header (its first line is line `first_line_no` of the
    file, counting from 1).

    Examples
    --------
    >>> rows = ["1,2\\n", "3,4\\n", "5,x\\n"]
    >>> [(t.tolist(), n) for t, _, n in iter_text_tables(rows, delimiter=",",
    ...                                                  first_line_no=2, lines=2)]
    [([[1.0, 2.0], [3.0, 4.0]], 2), ([[5.0, nan]], 4)]
    """
    it = iter(fh)
    per_block = TEXT_BLOCK_LINES if lines is None else int(lines)
    first_data: str | None = None  # every later block starts with it: its field count rules
    line_no = first_line_no
    while True:
        block = list(itertools.islice(it, per_block))
        if not block:
            return
        feed = block if first_data is None else [first_data, *block]
        # genfromtxt numbers lines from 1 (its first line, the repeated first data line for
        # a later block): shift them to the file's numbering
        shift = line_no - (1 if first_data is None else 2)
        table = _parse_plain(feed, delimiter, comments)
        if table is None:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # "Empty input file": the caller reports it
                    table = np.genfromtxt(feed, delimiter=delimiter, comments=comments,
                                          dtype=np.float64, invalid_raise=True, ndmin=2)
            except ValueError as exc:
                text = _shift_line_numbers(str(exc), shift)
                detail = "; ".join(part.strip() for part in text.splitlines() if part.strip())
                raise GyrodriftValueError(f"{malformed}: {detail}") from None
        if first_data is not None:
            table = table[1:]
        else:
            first_data = next((s for s in block if _is_data_line(s, comments)), None)
        yield table, block, line_no
        line_no += len(block)


def _sortable(v: np.ndarray) -> np.ndarray:
    """uint64 keys ordered like the float64 values `v` (no NaN)."""
    u = np.ascontiguousarray(v, dtype=np.float64).view(np.uint64)
    sign = np.uint64(1 << 63)
    return np.where(u & sign, ~u, u | sign)


def _from_key(key: int) -> float:
    sign = 1 << 63
    u = (key ^ sign) if key & sign else (~key & ((1 << 64) - 1))
    return float(np.array([u], dtype=np.uint64).view(np.float64)[0])


def chunked_median(pieces: Callable[[], Iterator[np.ndarray]]) -> float:
    """``numpy.median`` of the concatenation of the pieces `pieces()` yields, exactly (NaN
    when one is NaN), in memory independent of their number: a radix selection over the
    values' bit patterns, 16 bits per pass (at most five passes over the pieces).

    Examples
    --------
    >>> float(chunked_median(lambda: iter([np.array([3.0, -1.0]), np.array([2.0, 7.0])])))
    2.5
    """
    n, has_nan = 0, False
    for p in pieces():
        n += int(p.size)
        has_nan = has_nan or bool(np.isnan(p).any())
    if n == 0 or has_nan:
        return float("nan")
    ranks = sorted({(n - 1) // 2, n // 2})
    prefix = dict.fromkeys(ranks, 0)
    left = {r: r for r in ranks}  # rank among the values with the prefix found so far
    for shift in (48, 32, 16, 0):
        counts = {r: np.zeros(1 << 16, dtype=np.int64) for r in ranks}
        for p in pieces():
            keys = _sortable(p)
            for r in ranks:
                k = keys if shift == 48 else keys[(keys >> np.uint64(shift + 16)) == prefix[r]]
                digit = ((k >> np.uint64(shift)) & np.uint64(0xFFFF)).astype(np.intp)
                counts[r] += np.bincount(digit, minlength=1 << 16)
        for r in ranks:
            cum = np.cumsum(counts[r])
            b = int(np.searchsorted(cum, left[r], side="right"))
            left[r] -= int(cum[b - 1]) if b else 0
            prefix[r] = (prefix[r] << 16) | b
    values = np.array([_from_key(prefix[r]) for r in ranks])
    return float(np.median(values)) if values.size == 2 else float(values[0])

