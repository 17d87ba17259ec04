"""Input and output helpers shared by every subcommand (the conventions of CONTRIBUTING.md).

- input record: positional ``INPUT``, ``--column``, ``--rate-hz``, ``--gyro-units``,
  ``--drop-nan``, ``--force-rate``, ``--time-units``
  (:func:`add_input_args`, :func:`record_from_args`);
- ``--json`` (:func:`add_json_arg`) printed by the one JSON writer :func:`emit_json`;
- ``--progress auto|always|never`` (:func:`add_progress_arg`, :func:`progress_enabled`): auto
  shows a bar only when stderr is a terminal;
- ``--ci P`` with the library's ``ONE_SIGMA_CI`` as default (:func:`add_ci_arg`);
- CSV tables written with the digits the numbers carry (:func:`write_csv`: floats as
  ``repr`` (the shortest string that reads back to the same double, at most ``%.17g``
  digits), integers as integers);
- output files: every location checked before the work (:func:`check_output`,
  :func:`check_out_dir`), every file written by the one rule of :mod:`gyrodrift.io.atomic`
  (:func:`atomic_output`: a file is replaced atomically, a symbolic link is followed, a
  device or FIFO is written through, a directory is refused), so a failed or interrupted
  command leaves no partial output; the human-readable lines go to stderr when an output is
  stdout itself (:func:`human_stream`).

Examples
--------
>>> import argparse
>>> p = argparse.ArgumentParser()
>>> add_progress_arg(p)
>>> progress_enabled(p.parse_args(["--progress", "never"]))
False
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.errors import GyrodriftError, GyrodriftValueError
from gyrodrift.io.atomic import atomic_output, is_stdout, output_target
from gyrodrift.io.json_text import json_default, json_text, strict_json_value
from gyrodrift.io.records import Record, load_record
from gyrodrift.stability import IEEE952_TERMS
from gyrodrift.units import DEFAULT_GYRO_UNITS, DEFAULT_TIME_UNITS, GYRO_INPUT_UNITS, TIME_UNITS

__all__ = [
    "DEFAULT_FIT_TERMS",
    "PROGRESS_CHOICES",
    "add_ar_method_arg",
    "add_ci_arg",
    "add_gyro_units_arg",
    "add_input_args",
    "add_json_arg",
    "add_progress_arg",
    "add_self_check_arg",
    "add_time_units_arg",
    "check_out_dir",
    "check_output",
    "check_rate_hz",
    "emit_json",
    "emit_json_line",
    "format_csv_value",
    "human_stream",
    "json_default",
    "progress_enabled",
    "record_from_args",
    "require_units",
    "self_check_exit",
    "write_csv",
]

PROGRESS_CHOICES = ("auto", "always", "never")
#: ``--terms`` unless told otherwise: every IEEE Std 952 term (gyrodrift.stability).
DEFAULT_FIT_TERMS = ",".join(IEEE952_TERMS)


def add_input_args(p: argparse.ArgumentParser, *, required: bool = True) -> None:
    """Add the input-record arguments: ``INPUT``, ``--column``, ``--rate-hz``, ``--gyro-units``,
    ``--drop-nan``, ``--force-rate``, ``--time-units``.

    Examples
    --------
    >>> p = argparse.ArgumentParser()
    >>> add_input_args(p)
    >>> p.parse_args(["x.npy", "--rate-hz", "100"]).rate_hz
    100.0
    """
    p.add_argument("input", nargs=None if required else "?",
                   help="record: .npy, .csv, PSINS .imu, or an IMU log (.bin/.gdf/.log/.asc/.blf)")
    p.add_argument("--column",
                   help="csv column name or index, npy column index, or IMU-log gyro axis x|y|z")
    p.add_argument("--rate-hz", type=float,
                   help="sample rate, Hz (required for .npy; csv and logs give it by their time "
                        "column)")
    add_gyro_units_arg(p)
    p.add_argument("--drop-nan", action="store_true",
                   help="drop NaN/Inf samples (their count is reported); default: refuse")
    p.add_argument("--force-rate", action="store_true",
                   help="use --rate-hz even where it contradicts the file's own time column")
    add_time_units_arg(p)


def add_time_units_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--time-units`` (the units of a text record's time column; choices and default
    from the one units table, :data:`gyrodrift.units.TIME_UNITS` and
    :data:`gyrodrift.units.DEFAULT_TIME_UNITS`).

    Examples
    --------
    >>> p = argparse.ArgumentParser(); add_time_units_arg(p)
    >>> p.parse_args([]).time_units, p.parse_args(["--time-units", "ns"]).time_units
    ('s', 'ns')
    """
    p.add_argument("--time-units", choices=tuple(TIME_UNITS), default=DEFAULT_TIME_UNITS,
                   help="units of the time column of a text record: s, ms, us or ns (default "
                        f"{DEFAULT_TIME_UNITS}; the rate it gives must lie within 1e-06..1e+09 "
                        "Hz, like --rate-hz)")


def add_gyro_units_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--gyro-units`` (the units of a gyro input column; choices from the one units
    table, :data:`gyrodrift.units.GYRO_INPUT_UNITS`; no default: a record whose format does
    not carry its units needs them stated, :func:`require_units`).

    Examples
    --------
    >>> p = argparse.ArgumentParser(); add_gyro_units_arg(p)
    >>> p.parse_args([]).gyro_units, p.parse_args(["--gyro-units", "arcsec"]).gyro_units
    (None, 'arcsec')
    """
    p.add_argument("--gyro-units", choices=GYRO_INPUT_UNITS, default=DEFAULT_GYRO_UNITS,
                   help="units of the gyro data of a .npy or text record: rates deg/h, deg/s, "
                        "rad/s; per-sample angle increments arcsec, deg, rad (required for "
                        "those, never guessed; IMU logs and ROS bags carry rad/s, PSINS logs "
                        "angle increments)")


def require_units(path: str | Path, flag: str, value: str | None) -> str | None:
    """The units given for a record, or a :class:`CliError` naming ``flag`` when the record's
    format does not carry its units and none were given (the command never guesses).

    Examples
    --------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp(); f = os.path.join(d, "gyro.npy"); np.save(f, np.zeros(3))
    >>> require_units(f, "--gyro-units", "deg/s")
    'deg/s'
    >>> require_units(f, "--gyro-units", None)
    Traceback (most recent call last):
    ...
    gyrodrift.cli.CliError: .../gyro.npy: a .npy record does not say its units: give ...
    """
    from gyrodrift.io.imu_data import units_carried
    from gyrodrift.units import ACCEL_INPUT_UNITS

    if value is not None:
        return value
    if not (Path(path).is_file() or Path(path).is_dir()):
        return None  # missing, a FIFO or a device: the reader refuses it with its own message
    try:
        carried = units_carried(path)
    except GyrodriftError:
        return None  # an unsupported file: the reader says so
    if carried:
        return None
    choices = GYRO_INPUT_UNITS if flag == "--gyro-units" else ACCEL_INPUT_UNITS
    suffix = Path(path).suffix.lower() or "text"
    raise CliError(f"{path}: a {suffix} record does not say its units: give {flag} (one of "
                   f"{', '.join(choices)})")


def record_from_args(args: argparse.Namespace, *, mmap: bool = True) -> Record:
    """Load the record the input arguments name; a bad file or value, or units neither given
    nor carried by the file, is a :class:`CliError`.

    Examples
    --------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp(); f = os.path.join(d, "x.npy"); np.save(f, np.arange(5.0))
    >>> ns = argparse.Namespace(input=f, column=None, rate_hz=10.0, gyro_units="deg/h",
    ...                         drop_nan=False)
    >>> record_from_args(ns).n
    5
    """
    units = require_units(args.input, "--gyro-units", args.gyro_units)
    try:
        return load_record(args.input, column=args.column, rate_hz=args.rate_hz,
                           units=units or "deg/h",  # the loaders' "not told": the file's own
                           nan_policy="drop" if args.drop_nan else "refuse",
                           mmap=mmap, can_signals=getattr(args, "can_signals", None),
                           force_rate=bool(getattr(args, "force_rate", False)),
                           time_units=getattr(args, "time_units", DEFAULT_TIME_UNITS))
    except (OSError, ValueError, GyrodriftError) as exc:
        raise CliError(str(exc)) from exc


def add_self_check_arg(p: argparse.ArgumentParser, extra: str = "") -> None:
    """Add ``--self-check``: exit with :data:`~gyrodrift.stability.self_check.SELF_CHECK_EXIT`
    when a fitted model does not describe its measured curve (every output carries the check
    whether or not the flag is given). ``extra``: what the command does besides.

    Examples
    --------
    >>> p = argparse.ArgumentParser(); add_self_check_arg(p)
    >>> p.parse_args([]).self_check, p.parse_args(["--self-check"]).self_check
    (False, True)
    """
    from gyrodrift.stability.self_check import SELF_CHECK_EXIT

    p.add_argument("--self-check", action="store_true",
                   help=f"self-check: exit with code {SELF_CHECK_EXIT} (after writing every "
                        "output) when a fitted noise model does not describe its measured curve "
                        "(the check and its warning lines are in every output anyway)" + extra)


def self_check_exit(args: argparse.Namespace, checks: Sequence[tuple[str, Any]]) -> int:
    """The exit code of a command that fitted noise models: 0, or
    :data:`~gyrodrift.stability.self_check.SELF_CHECK_EXIT` with one line on stderr naming
    the channels whose model does not hold when ``--self-check`` was given. ``checks``:
    (channel or "", FitCheck) pairs.

    Examples
    --------
    >>> self_check_exit(argparse.Namespace(self_check=True), [])
    0
    """
    from gyrodrift.stability.self_check import SELF_CHECK_EXIT

    failed = [label or "the record" for label, chk in checks if not chk.holds]
    if not getattr(args, "self_check", False) or not failed:
        return 0
    print(f"gyrodrift: self-check failed: the fitted model does not hold for "
          f"{', '.join(failed)}", file=sys.stderr)
    return SELF_CHECK_EXIT


def add_ar_method_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--ar-method`` (the AR(2) estimator; choices and default from
    :data:`gyrodrift.filters.ar2.AR2_METHODS` and
    :data:`~gyrodrift.filters.ar2.DEFAULT_AR2_METHOD`).

    Examples
    --------
    >>> p = argparse.ArgumentParser(); add_ar_method_arg(p)
    >>> p.parse_args([]).ar_method
    'yule-walker'
    """
    from gyrodrift.filters.ar2 import AR2_METHODS, DEFAULT_AR2_METHOD

    p.add_argument("--ar-method", choices=AR2_METHODS, default=DEFAULT_AR2_METHOD,
                   help="AR(2) estimator: yule-walker, burg or ls (forward-backward least "
                        f"squares) (default {DEFAULT_AR2_METHOD})")


def add_json_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--json`` (the machine-readable result on stdout).

    Examples
    --------
    >>> p = argparse.ArgumentParser(); add_json_arg(p)
    >>> p.parse_args(["--json"]).json
    True
    """
    p.add_argument("--json", action="store_true",
                   help="print the result as one JSON object on stdout (no table)")


def add_progress_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--progress auto|always|never`` (default auto: a bar only on a terminal).

    Examples
    --------
    >>> p = argparse.ArgumentParser(); add_progress_arg(p)
    >>> p.parse_args([]).progress
    'auto'
    """
    p.add_argument("--progress", choices=PROGRESS_CHOICES, default="auto",
                   help="progress bar on stderr: auto (only when stderr is a terminal), "
                        "always or never (default auto)")


def progress_enabled(args: argparse.Namespace, stream: IO[str] | None = None) -> bool:
    """Whether to draw progress: ``always``; ``never``; ``auto`` when ``stream`` (stderr by
    default) is a terminal.

    Examples
    --------
    >>> import io
    >>> progress_enabled(argparse.Namespace(progress="auto"), io.StringIO())
    False
    >>> progress_enabled(argparse.Namespace(progress="always"))
    True
    """
    choice = getattr(args, "progress", "auto")
    if choice == "always":
        return True
    if choice == "never":
        return False
    s = sys.stderr if stream is None else stream
    try:
        return bool(s.isatty())
    except (AttributeError, ValueError):
        return False


def add_ci_arg(p: argparse.ArgumentParser) -> None:
    """Add ``--ci P`` (confidence level, default the library's ``ONE_SIGMA_CI`` = 0.6827).

    Examples
    --------
    >>> p = argparse.ArgumentParser(); add_ci_arg(p)
    >>> round(p.parse_args([]).ci, 4)
    0.6827
    """
    from gyrodrift.stability.allan import ONE_SIGMA_CI

    p.add_argument("--ci", type=float, default=ONE_SIGMA_CI,
                   help="confidence-interval probability (default 0.6827, one sigma)")


def emit_json(payload: Any, stream: IO[str] | None = None) -> None:
    """Write ``payload`` as indented JSON and a newline (stdout by default): the one JSON
    writer of the command line.

    Examples
    --------
    >>> emit_json({"n": np.int64(3), "x": np.float64(0.25), "fit": float("nan")})
    {
      "n": 3,
      "x": 0.25,
      "fit": null
    }
    """
    out = sys.stdout if stream is None else stream
    out.write(json_text(payload, indent=2))  # NaN/Inf as null: strict JSON
    out.write("\n")


def emit_json_line(payload: Any, stream: IO[str] | None = None) -> None:
    """Write ``payload`` as one line of JSON (JSON lines: one object per line, stdout by
    default), by the same rules as :func:`emit_json` (strict JSON: NaN/Inf as null).

    Examples
    --------
    >>> emit_json_line({"t_s": 10.0, "health": [], "b": float("nan")})
    {"t_s": 10.0, "health": [], "b": null}
    """
    import json

    out = sys.stdout if stream is None else stream
    out.write(json.dumps(strict_json_value(payload), default=json_default, allow_nan=False))
    out.write("\n")



def format_csv_value(v: Any) -> str:
    """One CSV cell: integers as integers, floats with the digits they carry (``repr``).

    Examples
    --------
    >>> format_csv_value(1.0), format_csv_value(np.int64(7)), format_csv_value(0.1)
    ('1.0', '7', '0.1')
    >>> format_csv_value(float("nan"))
    'nan'
    """
    if isinstance(v, (bool, np.bool_)):
        return str(int(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if math.isnan(f):
            return "nan"
        if math.isinf(f):
            return "inf" if f > 0 else "-inf"
        return repr(f)
    return str(v)


def write_csv(path: str | Path, header: Sequence[str], columns: Sequence[Any]) -> Path:
    """Write columns (equal-length sequences) as CSV with a header line.

    Integer columns (numpy integer dtype or Python ints) are written as integers, floats with
    ``repr`` (round-trip exact).

    Examples
    --------
    >>> import tempfile, os
    >>> f = os.path.join(tempfile.mkdtemp(), "t.csv")
    >>> _ = write_csv(f, ["m", "adev"], [np.array([1, 2]), np.array([0.5, 0.1])])
    >>> print(open(f).read(), end="")
    m,adev
    1,0.5
    2,0.1
    """
    if len(header) != len(columns):
        raise GyrodriftValueError(f"{len(header)} header names for {len(columns)} columns")
    cols = [c.tolist() if isinstance(c, np.ndarray) else list(c) for c in columns]
    n = len(cols[0]) if cols else 0
    if any(len(c) != n for c in cols):
        raise GyrodriftValueError("CSV columns differ in length")
    p = Path(path)
    with atomic_output(p) as tmp, tmp.open("w", newline="") as fh:
        fh.write(",".join(header) + "\n")
        for i in range(n):
            fh.write(",".join(format_csv_value(c[i]) for c in cols) + "\n")
    return p


def check_rate_hz(rate_hz: float, flag: str = "--rate-hz") -> float:
    """A sample rate given on the command line: finite and within the range the analyses
    handle (gyrodrift.io.records.RATE_MIN_HZ..RATE_MAX_HZ), else a :class:`CliError`.

    Examples
    --------
    >>> check_rate_hz(400.0)
    400.0
    """
    from gyrodrift.io.records import RATE_MAX_HZ, RATE_MIN_HZ

    if not (math.isfinite(rate_hz) and RATE_MIN_HZ <= rate_hz <= RATE_MAX_HZ):
        raise CliError(f"{flag} {rate_hz:g}: a sample rate must be within {RATE_MIN_HZ:g}.."
                       f"{RATE_MAX_HZ:g} Hz")
    return rate_hz


def _png_suffixes() -> tuple[str, ...]:
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(f".{k}" for k in FigureCanvasBase.get_supported_filetypes())


def check_output(path: str | Path | None, flag: str, suffixes: Sequence[str] | None = None
                 ) -> Path | None:
    """Check an output location before any work, by the rule of :mod:`gyrodrift.io.atomic`:
    its suffix is one the writer knows (``suffixes``; for ``--png`` the image formats
    matplotlib can write); it is not a directory; a file (or the file a symbolic link leads
    to) has a writable directory; a device, FIFO or socket is writable. Returns the path (None
    stays None); raises a :class:`CliError` naming the flag.

    Examples
    --------
    >>> check_output("nodir/x.npy", "-o")
    Traceback (most recent call last):
    ...
    gyrodrift.cli.CliError: -o nodir/x.npy: directory nodir does not exist
    """
    if path is None:
        return None
    p = Path(path)
    if flag == "--png" and suffixes is None:
        suffixes = _png_suffixes()
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise CliError(f"{flag} {p}: unsupported file type {p.suffix or '(none)'!r}; use one "
                       f"of {', '.join(suffixes)}")
    try:
        target = output_target(p)
    except IsADirectoryError:
        raise CliError(f"{flag} {p}: is a directory") from None
    except OSError as exc:
        raise CliError(f"{flag} {p}: {exc.strerror or exc}") from None
    if target.kind == "stream":  # a device, FIFO or socket: written through, never replaced
        if not os.access(p, os.W_OK):
            raise CliError(f"{flag} {p}: not writable (permission denied)")
        return p
    parent = target.real.parent
    if not parent.is_dir():
        shown = parent if p.is_symlink() else (p.parent if str(p.parent) else Path("."))
        raise CliError(f"{flag} {p}: directory {shown} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK) or (
            target.exists and not os.access(target.real, os.W_OK)):
        raise CliError(f"{flag} {p}: not writable (permission denied)")
    return p


def human_stream(*outputs: str | Path | None) -> IO[str]:
    """Where a command prints its human-readable lines: stdout, or stderr when one of its
    output files is the standard output itself (``-o /dev/stdout``), so that stdout carries
    the file's bytes and nothing else.

    Examples
    --------
    >>> human_stream(None, "result.npy") is sys.stdout
    True
    """
    return sys.stderr if any(o is not None and is_stdout(o) for o in outputs) else sys.stdout


def check_out_dir(path: str | Path | None, flag: str = "--out-dir") -> Path | None:
    """Check an output directory before any work: it exists and is writable, or can be made
    (its nearest existing parent is writable). Nothing is created here.

    Examples
    --------
    >>> import shutil, tempfile
    >>> d = tempfile.mkdtemp()
    >>> check_out_dir(os.path.join(d, "new", "dir")).name, os.listdir(d)  # nothing made
    ('dir', [])
    >>> open(os.path.join(d, "file"), "w").close()
    >>> check_out_dir(os.path.join(d, "file"))
    Traceback (most recent call last):
    ...
    gyrodrift.cli.CliError: --out-dir .../file: exists and is not a directory
    >>> shutil.rmtree(d)
    """
    if path is None:
        return None
    p = Path(path)
    if p.exists():
        if not p.is_dir():
            raise CliError(f"{flag} {p}: exists and is not a directory")
        if not os.access(p, os.W_OK | os.X_OK):
            raise CliError(f"{flag} {p}: not writable (permission denied)")
        return p
    base = p.parent
    while not base.exists() and base != base.parent:
        base = base.parent
    if not base.is_dir() or not os.access(base, os.W_OK | os.X_OK):
        raise CliError(f"{flag} {p}: cannot be created ({base} is not a writable directory)")
    return p
