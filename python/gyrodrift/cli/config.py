"""`gyrodrift config`: validate, show or write a processor configuration file, or emit it as a
constexpr C++ header for firmware (README: Processor configuration file)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from gyrodrift.cli import CliError

__all__ = ["ACTIONS", "register", "run"]

ACTIONS = ("validate", "show", "write-default", "emit-cpp")


def register(subparsers: Any) -> None:
    """Add the ``config`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["config", "validate", "processor.toml"])
    >>> args.action, args.file, args.namespace
    ('validate', 'processor.toml', 'gyrodrift_config')
    """
    p = subparsers.add_parser(
        "config", help="processor configuration file: validate, show, write-default, emit-cpp",
        description=__doc__.splitlines()[0])
    p.add_argument("action", nargs="?",
                   help="validate FILE | show FILE | write-default -o FILE | emit-cpp FILE -o H")
    p.add_argument("file", nargs="?", help="configuration file (TOML)")
    p.add_argument("-o", "--output", default=None,
                   help="output file (write-default: the TOML file; emit-cpp: the C++ header)")
    p.add_argument("--emit-cpp", default=None, metavar="FILE.hpp",
                   help="same as `emit-cpp FILE -o FILE.hpp`")
    p.add_argument("--namespace", default="gyrodrift_config", help="C++ namespace (emit-cpp)")
    p.add_argument("--json", action="store_true", help="show: the configuration as JSON")
    p.set_defaults(func=run)


def _output(args: argparse.Namespace) -> Path:
    from gyrodrift.cli.common import check_output

    out = check_output(args.output, "-o")
    assert out is not None
    return out


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift config``; returns the exit code.

    Examples
    --------
    Write the default configuration, then check it:

    >>> import os, tempfile
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory(); path = os.path.join(tmp.name, "processor.toml")
    >>> run(p.parse_args(["config", "write-default", "-o", path]))
    wrote .../processor.toml
    0
    >>> run(p.parse_args(["config", "validate", path]))
    /.../processor.toml: ok
    0
    >>> tmp.cleanup()
    """
    from gyrodrift.cli.common import human_stream
    from gyrodrift.imu.config import ConfigError, default_config, dumps_config, load_config
    from gyrodrift.io.atomic import atomic_write_text

    action = args.action
    if args.emit_cpp:
        if action is not None and args.file is None:  # `config FILE --emit-cpp H`
            args.file, action = action, "emit-cpp"
        if action not in ("emit-cpp", "validate"):
            raise CliError("--emit-cpp FILE.hpp goes with a configuration FILE only")
        action, args.output = "emit-cpp", args.emit_cpp
    if action not in ACTIONS:
        raise CliError(f"give an action: {', '.join(ACTIONS)} (got {action!r})")
    try:
        if action == "write-default":
            if not args.output:
                raise CliError("write-default needs -o FILE")
            out = _output(args)
            atomic_write_text(out, dumps_config(default_config()))
            print(f"wrote {out}", file=human_stream(out))
            return 0
        if not args.file:
            raise CliError(f"{action} needs a configuration FILE")
        cfg = load_config(args.file)
        if action == "validate":
            print(f"{args.file}: ok")
        elif action == "show":
            if args.json:
                from gyrodrift.cli.common import emit_json

                emit_json(cfg.as_dict())
            else:
                sys.stdout.write(dumps_config(cfg))
        else:  # emit-cpp
            from gyrodrift.imu.firmware_header import emit_cpp

            if not args.output:
                raise CliError("emit-cpp needs -o FILE.hpp")
            out = _output(args)
            atomic_write_text(out, emit_cpp(cfg, args.namespace, source=Path(args.file).name))
            print(f"wrote {out}", file=human_stream(out))
    except ConfigError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"{exc.filename or args.file}: {exc.strerror or exc}") from None
    return 0
