"""The one atomic file write: a temporary file beside the target, renamed over it on success,
removed on any exception or Ctrl-C, so a failed or interrupted command leaves no partial
output. The file gets the usual umask permissions (mkstemp alone would make it private).

Examples
--------
>>> import os, tempfile
>>> d = tempfile.mkdtemp()
>>> path = atomic_write_text(os.path.join(d, "a.txt"), "one\\n")
>>> path.read_text(), sorted(os.listdir(d))
('one\\n', ['a.txt'])
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["atomic_output", "atomic_write_text"]


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path`` (same suffix, so writers that infer the format
    from it work); on success it is renamed over ``path`` (atomic on one file system), on
    any exception or Ctrl-C it is removed and ``path`` is left as it was.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> f = os.path.join(tempfile.mkdtemp(), "a.npy")
    >>> with atomic_output(f) as tmp:
    ...     np.save(tmp, np.zeros(3))
    >>> np.load(f).shape
    (3,)
    """
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    fd, name = tempfile.mkstemp(prefix=f".{p.name}.", suffix=f".part{p.suffix}", dir=parent)
    os.close(fd)
    tmp = Path(name)
    umask = os.umask(0o022)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it 0600; the result gets the usual mode
    try:
        yield tmp
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through :func:`atomic_output`; returns the path.

    Examples
    --------
    >>> import os, tempfile
    >>> d = tempfile.mkdtemp()
    >>> atomic_write_text(os.path.join(d, "b.txt"), "two\\n").read_text()
    'two\\n'
    """
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
