"""The `gyrodrift` command line: one module per subcommand in this package.

Each module `gyrodrift.cli.<name>` defines `register(subparsers) -> None`, which adds its
subparser and sets `func` (called with the parsed args, returning the exit code).
"""

from __future__ import annotations

import argparse
import importlib
import sys

# Subcommand modules, in the order `gyrodrift --help` lists them.
SUBCOMMAND_MODULES: list[str] = [
    "demo",
    "replay",
    "simulate",
    "filter",
    "allan",
    "psd",
    "compare",
    "wavelet_response",
    "align",
    "characterize",
    "fleet",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gyrodrift",
        description="Optical-gyro drift removal: filters, Allan/PSD analysis, CAN/serial replay.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(f"gyrodrift.cli.{name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        print(f"gyrodrift {args.command}: error: {exc}", file=sys.stderr)
        return 2


class CliError(Exception):
    """A user-facing error: printed as one line, exit code 2, no traceback."""


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
