"""The `gyrodrift` command line: one module per subcommand in this package.

Each module `gyrodrift.cli.<name>` defines `register(subparsers) -> None`, which adds its
subparser and sets `func` (called with the parsed args, returning the exit code).
"""

from __future__ import annotations

import argparse
import importlib
import sys

from gyrodrift.errors import GyrodriftError

__all__ = ["SUBCOMMAND_MODULES", "CliError", "build_parser", "main"]

# Subcommand modules, in the order `gyrodrift --help` lists them.
SUBCOMMAND_MODULES: list[str] = [
    "demo",
    "replay",
    "simulate",
    "filter",
    "allan",
    "identify",
    "psd",
    "compare",
    "wavelet_response",
    "align",
]


def build_parser() -> argparse.ArgumentParser:
    """The ``gyrodrift`` parser with every subcommand registered.

    Examples
    --------
    >>> sub = next(a for a in build_parser()._actions if a.dest == "command")
    >>> list(sub.choices)  # each module's register() added its subcommand
    ['demo', 'replay', 'simulate', 'filter', 'allan', 'psd', 'compare', 'wavelet-response', 'align']
    """
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
    >>> main(["simulate", "-o", out, "--n", "100"])  # doctest: +ELLIPSIS
    wrote .../r.npy (rate deg/h, 100 samples at 400 Hz, seed 0)
    0
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except GyrodriftError as exc:
        print(f"gyrodrift {args.command}: error: {exc}", file=sys.stderr)
        return 2


class CliError(GyrodriftError):
    """A user-facing error: printed as one line, exit code 2, no traceback.

    Examples
    --------
    >>> issubclass(CliError, GyrodriftError)
    True
    """


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
