"""The `gyrodrift` command line: one module per subcommand in this package.

Each module `gyrodrift.cli.<name>` defines `register(subparsers) -> None`, which adds its
subparser and sets `func` (called with the parsed args, returning the exit code).
"""

from __future__ import annotations

import contextlib
import os
import sys
from typing import TYPE_CHECKING

from gyrodrift._startup import restore as restore_interrupts
from gyrodrift.errors import GyrodriftError

if TYPE_CHECKING:
    import argparse

# Imports here are kept to what the interpreter has already loaded (and the light errors
# module): everything else, argparse included, loads inside main(), where Ctrl-C during
# start-up ends in one line and exit code 130, not a traceback.

__all__ = ["SUBCOMMAND_MODULES", "CliError", "build_parser", "main"]

# Subcommand modules, in the order `gyrodrift --help` lists them.
SUBCOMMAND_MODULES: list[str] = [
    "demo",
    "replay",
    "simulate",
    "filter",
    "allan",
    "fit",
    "identify",
    "monitor",
    "psd",
    "compare",
    "wavelet_response",
    "align",
    "config",
    "characterize",
    "fleet",
]


def build_parser() -> argparse.ArgumentParser:
    """The ``gyrodrift`` parser with every subcommand registered.

    Examples
    --------
    >>> sub = next(a for a in build_parser()._actions if a.dest == "command")
    >>> len(sub.choices) == len(SUBCOMMAND_MODULES)  # each module registered its subcommand
    True
    >>> list(sub.choices)[:5]
    ['demo', 'replay', 'simulate', 'filter', 'allan']
    """
    import argparse
    import importlib

    from gyrodrift import __version__

    parser = argparse.ArgumentParser(
        prog="gyrodrift",
        description="Optical-gyro drift removal: filters, Allan/PSD analysis, CAN/serial replay.",
    )
    parser.add_argument("--version", action="version", version=f"gyrodrift {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(f"gyrodrift.cli.{name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (2 for a user error, one line on stderr).

    Examples
    --------
    >>> import os, tempfile
    >>> out = os.path.join(tempfile.mkdtemp(), "r.npy")
    >>> main(["simulate", "-o", out, "--samples", "100",
    ...       "--arw-deg-rt-h", "0.01"])  # doctest: +ELLIPSIS
    wrote .../r.npy (rate deg/h, 100 samples at 400 Hz, seed 0)
    0
    """
    command = "gyrodrift"
    try:
        # The subcommands' imports (numpy, scipy, the core) run under the start-up handler
        # when this is the `gyrodrift` command: an extension module interrupted while it
        # imports turns KeyboardInterrupt into an ImportError, and nothing is written yet.
        parser = build_parser()
        args = parser.parse_args(argv)
        restore_interrupts()  # Ctrl-C from here on: KeyboardInterrupt, handled below
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        command = f"gyrodrift {args.command}"
        code = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not at interpreter exit
        return code
    except GyrodriftError as exc:
        return _fail(command, f"error: {exc}", 2)
    except BrokenPipeError:
        # `gyrodrift ... | head`: the reader left. Point stdout at /dev/null so the final
        # flush at exit cannot raise again, and say so once on stderr.
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return _fail(command, "error: output pipe closed by the reader", 2)
    except OSError as exc:  # the user's paths: missing, unreadable, unwritable, disk full
        where = f": {exc.filename}" if exc.filename else ""
        return _fail(command, f"error: {exc.strerror or exc}{where}", 2)
    except KeyboardInterrupt:
        # Partial files are removed by atomic_output; child processes by their owners'
        # context managers, which have run by now.
        return _fail(command, "interrupted", 130)
    except ImportError as exc:
        if _interrupted(exc):  # Ctrl-C inside an extension module's import (lazy imports)
            return _fail(command, "interrupted", 130)
        raise


def _interrupted(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is among the causes of `exc`."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def _fail(command: str, message: str, code: int) -> int:
    with contextlib.suppress(OSError, ValueError):
        print(f"{command}: {message}", file=sys.stderr)
    return code


class CliError(GyrodriftError):
    """A user-facing error: printed as one line, exit code 2, no traceback.

    Examples
    --------
    >>> issubclass(CliError, GyrodriftError)
    True
    """


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
