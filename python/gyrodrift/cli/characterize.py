"""`gyrodrift characterize`: every channel of an IMU record (3 gyros + 3 accelerometers, or the
subset present): Allan deviation with intervals, noise terms with intervals, a per-axis table,
one plot per sensor type, and the outputs filter users need (--json, --kalibr imu.yaml, --html).
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    DEFAULT_FIT_TERMS,
    add_ci_arg,
    add_gyro_units_arg,
    add_json_arg,
    add_progress_arg,
    add_self_check_arg,
    add_time_units_arg,
    check_out_dir,
    check_output,
    emit_json,
    human_stream,
    progress_enabled,
    require_units,
    self_check_exit,
)
from gyrodrift.errors import GyrodriftError
from gyrodrift.io.imu_data import (
    ImuData,
    bag_imu_topics,
    check_units_plausible,
    load_imu,
    units_carried,
)
from gyrodrift.stability import DEFAULT_IDENTIFIER, MODEL_IDENTIFIERS
from gyrodrift.stability.self_check import check_summary
from gyrodrift.units import ACCEL_INPUT_UNITS, DEFAULT_ACCEL_UNITS

__all__ = ["add_analysis_args", "add_imu_input_args", "imu_from_args", "register", "run"]


def add_imu_input_args(p: argparse.ArgumentParser) -> None:
    """Input options of the multi-channel readers (gyrodrift.io.imu_data).

    Examples
    --------
    >>> p = argparse.ArgumentParser(); add_imu_input_args(p)
    >>> args = p.parse_args(["--rate-hz", "200", "--column-channels", "gyro_x,-,gyro_z"])
    >>> args.rate_hz, args.column_channels, args.gyro_units, args.drop_nan
    (200.0, 'gyro_x,-,gyro_z', None, False)
    """
    p.add_argument("--rate-hz", type=float, help="sample rate, Hz (required for .npy and for "
                   "text without a time column)")
    p.add_argument("--column-channels", metavar="CHANNELS",
                   help="the channel of each data column, in column order, comma-separated from "
                        "gyro_x, gyro_y, gyro_z, accel_x, accel_y, accel_z, '-' to skip "
                        "(default: from the header, or gyro x,y,z[,accel x,y,z] for 3 [6] "
                        "columns)")
    p.add_argument("--time-column", help="text: time column name/index, or 'none' (default: "
                   "detected)")
    add_time_units_arg(p)
    p.add_argument("--topic", help="ROS bag: the sensor_msgs/msg/Imu topic (listed when absent)")
    add_gyro_units_arg(p)
    p.add_argument("--accel-units", choices=ACCEL_INPUT_UNITS, default=DEFAULT_ACCEL_UNITS,
                   help="units of the accelerometer data of a .npy or text record: m/s^2, g, "
                        "or m/s (per-sample velocity increments) (required for those when "
                        "they hold accelerometer columns, never guessed; logs and bags carry "
                        "m/s^2)")
    p.add_argument("--drop-nan", action="store_true",
                   help="drop rows with NaN/Inf (their count is reported); default: refuse")


def imu_from_args(args: argparse.Namespace, path: str | None = None, **kw: Any) -> ImuData:
    """Load the IMU record named by the parsed options (:func:`add_imu_input_args`); a bad file is a
    :class:`~gyrodrift.cli.CliError`.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> p = argparse.ArgumentParser(); add_imu_input_args(p)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = os.path.join(d, "imu.npy")
    ...     np.save(path, np.zeros((100, 3)))
    ...     rec = imu_from_args(p.parse_args(["--rate-hz", "100", "--gyro-units", "rad/s"]), path)
    >>> rec.names, rec.rate_hz
    (('gyro_x', 'gyro_y', 'gyro_z'), 100.0)
    """
    src = path or args.input
    try:
        carried = units_carried(src)
    except GyrodriftError:
        carried = True  # an unsupported input: load_imu says so
    try:
        # placeholders where the file carries its units or the sensor is absent (checked below)
        rec = load_imu(src, rate_hz=args.rate_hz,
                       columns=(args.column_channels.split(",") if args.column_channels
                                else None),
                       time_column=args.time_column, time_units=args.time_units,
                       topic=args.topic,
                       gyro_units=args.gyro_units or "rad/s",
                       accel_units=args.accel_units or "m/s^2",
                       nan_policy="drop" if args.drop_nan else "refuse", **kw)
    except (OSError, ValueError, GyrodriftError) as exc:
        raise CliError(str(exc)) from exc
    if carried:
        return rec
    for sensor, flag, given in (("gyro", "--gyro-units", args.gyro_units),
                                ("accel", "--accel-units", args.accel_units)):
        if given is None and any(n.startswith(sensor) for n in rec.names):
            require_units(src, flag, None)
    try:
        check_units_plausible(rec, args.gyro_units or "rad/s", args.accel_units or "m/s^2")
    except GyrodriftError as exc:
        raise CliError(str(exc)) from exc
    return rec


def add_analysis_args(p: argparse.ArgumentParser) -> None:
    """Analysis options shared by ``characterize`` and ``fleet``: ``--identifier``,
    ``--terms``, ``--taus``, ``--ci``.

    Examples
    --------
    >>> p = argparse.ArgumentParser(); add_analysis_args(p)
    >>> args = p.parse_args([])
    >>> args.identifier, args.terms, args.taus
    ('allan-nnls', 'Q,N,B,K,R', 'octave')
    """
    p.add_argument("--identifier", choices=MODEL_IDENTIFIERS, default=DEFAULT_IDENTIFIER,
                   help="noise identifier: allan-nnls (IEEE 952 weighted NNLS fit of the Allan "
                        "variance with term selection) or gmwm (generalized method of wavelet "
                        f"moments) (default {DEFAULT_IDENTIFIER})")
    p.add_argument("--terms", default=DEFAULT_FIT_TERMS,
                   help=f"IEEE 952 terms the fit may use, comma-separated (default "
                        f"{DEFAULT_FIT_TERMS})")
    p.add_argument("--taus", choices=("octave", "decade", "all"), default="octave",
                   help="Allan tau grid (default octave)")
    add_ci_arg(p)


def register(subparsers: Any) -> None:
    """Add the ``characterize`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["characterize", "imu.npy", "--rate-hz", "400"])
    >>> args.identifier, args.terms, args.taus, round(args.ci, 4)
    ('allan-nnls', 'Q,N,B,K,R', 'octave', 0.6827)
    """
    p = subparsers.add_parser("characterize", help="whole-IMU noise characterization, Kalibr "
                              "imu.yaml, HTML report", description=__doc__.splitlines()[0])
    p.add_argument("input", help="record: .npy (n, k), CSV/text, PSINS .imu, an IMU log, or a "
                   "ROS bag (.bag, rosbag2 directory, .db3, .mcap)")
    add_imu_input_args(p)
    add_analysis_args(p)
    p.add_argument("--kalibr", metavar="FILE", help="write Kalibr's imu.yaml")
    p.add_argument("--kalibr-axis", choices=("worst", "x", "y", "z"), default="worst",
                   help="axis exported to Kalibr (default: the worst per parameter)")
    p.add_argument("--html", metavar="FILE", help="write a self-contained HTML report")
    p.add_argument("--out-dir", help="output directory of the plots (gyro.png, accel.png)")
    add_self_check_arg(p, "; characterize also simulates the identified model (same length "
                          "and rate), identifies it again and reports whether each term is "
                          "recovered inside its interval")
    p.add_argument("--seed", type=int, default=0, help="seed of the self-check simulation")
    add_json_arg(p)
    add_progress_arg(p)
    p.set_defaults(func=run)


def _terms(text: str) -> list[str]:
    return [t.strip().upper() for t in text.split(",") if t.strip()]


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift characterize``; returns the exit code.

    A .npy record is spooled in chunks to one float64 file per channel in a temporary
    directory (the rows with a NaN/Inf channel dropped with --drop-nan), which the Allan
    analysis reads in chunks; a long text record is parsed in blocks of lines into
    temporary files likewise (gyrodrift.io.imu_data): the command's memory does not grow
    with the record.

    Examples
    --------
    Three white gyro channels (1e-4 rad/s per sample at 100 Hz): N = 1e-4 * sqrt(0.01 s):

    >>> import os, tempfile, numpy as np
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory(); rec = os.path.join(tmp.name, "imu.npy")
    >>> np.save(rec, np.random.default_rng(0).normal(0.0, 1e-4, (4096, 3)))
    >>> run(p.parse_args(["characterize", rec, "--rate-hz", "100", "--gyro-units", "rad/s"]))
    # .../imu.npy (npy): 4096 samples at 100 Hz, 40.96 s; channels gyro_x, gyro_y, gyro_z
    # method allan-nnls, intervals at probability 0.6827
    ...
    gyro_x   N      1.021e-05 ... rad/s/sqrt(Hz) ... deg/sqrt(h)
    ...
    0
    >>> tmp.cleanup()
    """
    import tempfile

    from gyrodrift.io.imu_data import input_kind

    try:
        npy = input_kind(Path(args.input)) == "npy"
    except (OSError, ValueError, GyrodriftError):
        npy = False  # the reader reports it
    if not npy:
        return _run(args, None)
    with tempfile.TemporaryDirectory(prefix="gyrodrift-characterize.") as spool:
        return _run(args, spool)


def _run(args: argparse.Namespace, spool_dir: str | None) -> int:
    """`run` with the record spooled to `spool_dir` (a .npy record), or read whole."""
    from gyrodrift.workflows import characterize as ch

    check_output(args.kalibr, "--kalibr")  # every output location before the work
    check_output(args.html, "--html")
    check_out_dir(args.out_dir)
    if args.input and Path(args.input).suffix.lower() in (".bag", ".db3", ".mcap") \
            and args.topic is None:
        try:
            topics = bag_imu_topics(args.input)
        except (OSError, ValueError) as exc:
            raise CliError(str(exc)) from exc
        if len(topics) != 1:
            listing = ", ".join(f"{t} ({n} messages)" for t, n in topics.items()) or "none"
            raise CliError(f"{args.input}: choose a sensor_msgs/msg/Imu topic with --topic; "
                           f"the bag has: {listing}")
    rec = imu_from_args(args, spool_dir=spool_dir) if spool_dir else imu_from_args(args)
    show = progress_enabled(args)

    def progress(name: str) -> None:
        if show:
            print(f"characterize: {name}", file=sys.stderr, flush=True)

    try:
        res = ch.characterize(rec, ci=args.ci, taus=args.taus, terms=_terms(args.terms),
                              method=args.identifier, progress=progress)
        kalibr, refused = None, None
        if args.kalibr:  # a refused export is an error: nothing is written
            kalibr = ch.kalibr_yaml(res, args.kalibr_axis)
        elif args.html:  # the report says why there is no Kalibr file
            try:
                kalibr = ch.kalibr_yaml(res, args.kalibr_axis)
            except GyrodriftError as exc:
                refused = str(exc)
        sc = (ch.self_check(res, seed=args.seed, taus=args.taus, terms=_terms(args.terms))
              if args.self_check else None)
        kalibr_warns = ch.kalibr_warnings(res, args.kalibr_axis)
    except (ValueError, GyrodriftError) as exc:
        raise CliError(str(exc)) from exc
    files = ch.write_outputs(res, kalibr=kalibr, kalibr_path=args.kalibr, html_path=args.html,
                             out_dir=args.out_dir, self_check=sc, kalibr_axis=args.kalibr_axis,
                             kalibr_refused=refused)
    checks: list[tuple[str, Any]] = [(c.channel, c.check) for c in res.channels
                                     if c.check is not None]
    if kalibr_warns:  # a widened band or a random walk the record does not show
        checks.append(("the noise terms (see the warnings)", SimpleNamespace(holds=False)))
    # An output that is stdout itself (--kalibr /dev/stdout) keeps stdout to itself.
    with contextlib.redirect_stdout(human_stream(args.kalibr, args.html)):
        _report(args, ch, res, rec, sc, files, kalibr_warns, refused)
    return self_check_exit(args, checks)


def _report(args: argparse.Namespace, ch: Any, res: Any, rec: ImuData, sc: Any,
            files: dict[str, Any], kalibr_warns: list[str], refused: str | None) -> None:
    if args.json:
        payload = res.as_dict()
        payload["kalibr"] = {k: {"value": v, "channel": c, "unit": t.unit} for k, (v, c, t)
                             in ch.kalibr_values(res, args.kalibr_axis).items()}
        payload["kalibr_warnings"] = kalibr_warns
        payload["simulation_check"] = None if sc is None else sc.as_dict()
        payload["files"] = files
        emit_json(payload)
        return
    r = res.record
    print(f"# {r['source']} ({r['format']}): {r['n_used']} samples at {r['rate_hz']:g} Hz, "
          f"{r['duration_s']:.6g} s; channels {', '.join(rec.names)}"
          + (f"; {rec.n_dropped} rows with NaN/Inf dropped" if rec.n_dropped else ""))
    print(f"# method {res.method}, intervals at probability {res.ci:.4g}")
    print(f"{'channel':8} {'term':4} {'value':>11} {'ci_low':>11} {'ci_high':>11} {'unit':18} "
          f"{'value':>11} {'ci_low':>11} {'ci_high':>11} unit")
    for row in ch.table_rows(res):
        print(f"{row['channel']:8} {row['term']:4} {row['value']:11.4g} {row['ci_low']:11.4g} "
              f"{row['ci_high']:11.4g} {row['unit']:18} {row['ieee_value']:11.4g} "
              f"{row['ieee_low']:11.4g} {row['ieee_high']:11.4g} {row['ieee_unit']}")
    for c in res.channels:
        scale = c.extra.get("band_scale")
        if isinstance(scale, float) and scale > 1.0:
            print(f"# {c.channel}: no model of the chosen terms fits inside the Allan interval "
                  f"band; band widened x{scale:.3g} for the term intervals (misfit)")
        if c.check is not None:
            print(f"# {c.channel} {check_summary(c.check)}")
    for w in kalibr_warns:
        print(f"WARNING: {w}")
    if sc is not None:
        n_in = sum(bool(row["inside"]) for row in sc.rows)
        print(f"self-check (seed {sc.seed}): {n_in} of {len(sc.rows)} terms recovered inside "
              "their intervals" + ("" if sc.all_inside else "; NOT recovered: " + ", ".join(
                  f"{row['channel']} {row['term']}" for row in sc.rows if not row["inside"])))
    for k, v in files.items():
        if v:
            print(f"wrote {k}: {v}")
    if refused:
        print(f"# Kalibr export not possible: {refused}")

