"""Ctrl-C while the `gyrodrift` command starts: one line and exit code 130, not a traceback.

Imported first by the package's ``__init__``. When the process is the `gyrodrift` command
(``python -m gyrodrift``: ``sys.argv[0]`` is "-m" while the package is located and imported;
the installed script: its name), SIGINT ends it at once with the line the command's own
handler prints, until `gyrodrift.cli.main` gives Ctrl-C back to Python (KeyboardInterrupt,
handled there) by `restore`. An import of the package by any other program leaves its signal
handling alone. Only modules the interpreter has already loaded, and the built-in _signal,
are used before the handler is in place.

Examples
--------
>>> import signal
>>> signal.getsignal(signal.SIGINT) is interrupt_at_start_up  # pytest is not the command
False
"""

from __future__ import annotations

import os
import sys

__all__ = ["interrupt_at_start_up", "restore"]


def interrupt_at_start_up(signum: int, frame: object) -> None:
    """The start-up SIGINT handler: "gyrodrift: interrupted" on stderr, exit code 130."""
    os.write(2, b"gyrodrift: interrupted\n")
    os._exit(130)


def _is_command() -> bool:
    argv0 = sys.argv[0] if sys.argv else ""
    if argv0 == "-m":  # python [options] -m MODULE: only the package itself is the command
        orig = list(getattr(sys, "orig_argv", []))
        return any(orig[i] == "-m" and orig[i + 1] == "gyrodrift" for i in range(len(orig) - 1))
    return os.path.basename(argv0) in ("gyrodrift", "gyrodrift.exe")


def restore() -> None:
    """Python's own SIGINT handling again (KeyboardInterrupt), if the start-up handler is set."""
    import signal

    try:
        if signal.getsignal(signal.SIGINT) is interrupt_at_start_up:
            signal.signal(signal.SIGINT, signal.default_int_handler)
    except ValueError:  # not the main thread: nothing was set here
        pass


if _is_command():
    # _signal (built in, what the signal module wraps): importing `signal` would first load
    # `enum`, tens of milliseconds on a busy machine in which Ctrl-C would still be a trace.
    import _signal  # type: ignore[import-not-found]

    if _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler:
        _signal.signal(_signal.SIGINT, interrupt_at_start_up)
