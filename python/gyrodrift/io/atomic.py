"""The one way an output is written, with one rule for what is already at the target.

- **Nothing, or a regular file**: the output is written to a temporary file beside it and
  renamed over it when complete (atomic on one file system); on any exception or Ctrl-C the
  temporary file is removed and the target is left as it was. The file gets the usual umask
  permissions (mkstemp alone would make it private).
- **A symbolic link**: followed. The file it leads to is replaced as above (the temporary file
  goes beside that file) and the link stays a link; a link to a device, FIFO or socket is
  written through as below. A dangling link creates the file it names, as the shell's ``>``
  does (its directory must exist).
- **A device, FIFO or socket** (``/dev/null``, ``/dev/stdout``, a named pipe, a terminal),
  and any path through ``/proc`` (``/dev/stdout`` when the output is redirected to a file):
  written through, never replaced. The output is made in a private temporary directory and,
  when complete, copied into the target opened for writing (without creating anything), so a
  failed command still writes nothing; a write error (``/dev/full``: no space left, a reader
  that went away) is raised as :class:`OSError`. When the target is the process's own
  standard output, the bytes go to file descriptor 1 (after anything already printed).
- **A directory** (or a link to one): refused with :class:`IsADirectoryError`.

Examples
--------
>>> import os, tempfile
>>> d = tempfile.mkdtemp()
>>> path = atomic_write_text(os.path.join(d, "a.txt"), "one\\n")
>>> path.read_text(), sorted(os.listdir(d))
('one\\n', ['a.txt'])
>>> os.symlink("a.txt", os.path.join(d, "link.txt"))
>>> _ = atomic_write_text(os.path.join(d, "link.txt"), "two\\n")  # the link's file is replaced
>>> os.path.islink(os.path.join(d, "link.txt")), path.read_text()
(True, 'two\\n')
>>> _ = atomic_write_text(os.devnull, "nothing\\n")  # written through; the device stays
>>> output_target(os.devnull).kind
'stream'
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import stat
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

__all__ = ["OutputTarget", "atomic_output", "atomic_write_text", "is_stdout", "output_target"]

_MAX_LINKS = 40  # the kernel's own limit on symbolic links in one lookup (ELOOP)


@dataclass(frozen=True)
class OutputTarget:
    """Where an output goes and how (the module's rule).

    Attributes
    ----------
    path : the path as given.
    kind : ``"file"`` (replaced atomically: absent, a regular file, or a link to one) or
        ``"stream"`` (written through: a device, FIFO, socket, or a path through ``/proc``).
    real : for ``"file"``, the path that is replaced (a link's final target); for
        ``"stream"``, the path as given (opening it follows the links).
    exists : whether something is at ``real`` now.

    Examples
    --------
    >>> import tempfile
    >>> t = output_target(os.path.join(tempfile.mkdtemp(), "new.txt"))
    >>> t.kind, t.exists
    ('file', False)
    """

    path: Path
    kind: str
    real: Path
    exists: bool


def _follow_links(p: Path) -> tuple[Path, bool]:
    """The path a chain of symbolic links leads to (directories resolved as the kernel does),
    and whether the chain passes through /proc (a descriptor's "magic" link, whose text need
    not name a path at all: ``pipe:[1234]``)."""
    cur = Path(os.path.abspath(p))
    through_proc = False
    for _ in range(_MAX_LINKS):
        cur = Path(os.path.realpath(cur.parent)) / cur.name
        if cur.parts[1:2] == ("proc",):
            through_proc = True
        if not cur.is_symlink():
            return cur, through_proc
        cur = cur.parent / os.readlink(cur)
    raise OSError(errno.ELOOP, os.strerror(errno.ELOOP), str(p))


def output_target(path: str | os.PathLike[str]) -> OutputTarget:
    """Classify an output location by the module's rule; a directory (or a link to one) is an
    :class:`IsADirectoryError`, a link chain too long (or a loop) an :class:`OSError`.

    Examples
    --------
    >>> output_target(os.devnull).kind
    'stream'
    >>> output_target(tempfile.gettempdir())
    Traceback (most recent call last):
    ...
    IsADirectoryError: [Errno 21] Is a directory: '...'
    """
    p = Path(path)
    real, through_proc = _follow_links(p)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        st = None
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise OSError(errno.EISDIR, os.strerror(errno.EISDIR), str(p))  # IsADirectoryError
    if st is not None and (through_proc or not stat.S_ISREG(st.st_mode)):
        return OutputTarget(p, "stream", p, True)
    if through_proc:  # a descriptor link whose file is gone: nothing to write through
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), str(p))
    return OutputTarget(p, "file", real, st is not None)


def is_stdout(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is this process's standard output (``/dev/stdout``, ``/dev/fd/1``,
    the terminal or pipe it is): the command line then prints its own lines on stderr.

    Examples
    --------
    >>> is_stdout(os.path.join(tempfile.gettempdir(), "no-such-file"))
    False
    """
    try:
        return os.path.samestat(os.stat(path), os.fstat(1))
    except (OSError, ValueError):
        return False


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str], *, suffix: str | None = None
                  ) -> Iterator[Path]:
    """Yield a temporary path to write the output to; on success it becomes ``path`` by the
    module's rule (renamed over a regular file, copied into a device or FIFO), on any
    exception or Ctrl-C it is removed and ``path`` is left as it was.

    Parameters
    ----------
    path : the output location.
    suffix : the temporary file's suffix (default: the target's), for writers that choose the
        format from it (``numpy.save``, matplotlib's ``savefig``).

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
    target = output_target(path)
    sfx = target.real.suffix if suffix is None else suffix
    if target.kind == "stream":
        with tempfile.TemporaryDirectory(prefix="gyrodrift-out-") as d:
            tmp = Path(d) / f"output{sfx}"
            yield tmp
            if not tmp.is_file():  # e.g. numpy.save appends .npy to a name without it
                raise AssertionError(f"the writer made no file at {tmp.name!r}; give "
                                     "atomic_output the suffix it needs (suffix=)")
            _write_through(target.path, tmp)
        return
    parent = target.real.parent
    if not parent.is_dir():
        raise FileNotFoundError(errno.ENOENT, f"directory {parent} does not exist", str(path))
    fd, name = tempfile.mkstemp(prefix=f".{target.real.name}.", suffix=f".part{sfx}",
                                dir=parent)
    os.close(fd)
    tmp = Path(name)
    umask = os.umask(0o022)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it 0600; the result gets the usual mode
        yield tmp
        os.replace(tmp, target.real)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _write_through(target: Path, src: Path) -> None:
    """Copy ``src`` into the stream ``target`` opened for writing (never created or
    replaced); every write and the close are checked (``/dev/full`` fails there)."""
    if is_stdout(target):
        with contextlib.suppress(ValueError, AttributeError):
            sys.stdout.flush()  # what was printed before comes first
        fd = os.dup(1)
    else:
        flags = os.O_WRONLY | getattr(os, "O_NOCTTY", 0)
        if stat.S_ISREG(os.stat(target).st_mode):  # a regular file behind a /proc link
            flags |= os.O_TRUNC
        fd = os.open(target, flags)
    try:
        with os.fdopen(fd, "wb") as out, src.open("rb") as fh:  # buffered: no short writes
            shutil.copyfileobj(fh, out, 1 << 20)
    except OSError as exc:
        if exc.filename is not None:
            raise
        raise type(exc)(exc.errno, exc.strerror, str(target)) from None


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
