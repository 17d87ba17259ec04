"""`gyrodrift fleet`: characterize every log matching a glob on Dask (dask.distributed): one
task per log, results written per log as they finish, resumable, failed logs listed with their
reason, and a fleet summary (distribution per parameter and axis, spec flags, one HTML page).
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
from typing import Any

from gyrodrift.cli import CliError
from gyrodrift.cli.characterize import add_analysis_args, add_imu_input_args
from gyrodrift.cli.common import (
    add_json_arg,
    add_progress_arg,
    emit_json,
    progress_enabled,
    require_units,
)
from gyrodrift.errors import GyrodriftError
from gyrodrift.workflows.fleet import DEFAULT_MEMORY_BUDGET_MIB

__all__ = ["register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``fleet`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["fleet", "logs/*.npy", "--out-dir", "fleet", "--rate-hz", "400"])
    >>> args.input, args.workers, args.identifier, args.redo
    (['logs/*.npy'], 2, 'allan-nnls', False)
    """
    p = subparsers.add_parser("fleet", help="characterize many IMU logs on Dask, fleet summary",
                              description=__doc__.splitlines()[0])
    p.add_argument("input", metavar="GLOB", nargs="+",
                   help="log files or glob patterns (quote them; ** recurses)")
    p.add_argument("--out-dir", required=True,
                   help="output directory: per-unit results and the fleet summary")
    p.add_argument("--workers", type=int, default=2,
                   help="LocalCluster worker processes (default 2; 0: serial, no Dask)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="use an existing dask.distributed scheduler (e.g. tcp://127.0.0.1:8786)")
    p.add_argument("--redo", action="store_true",
                   help="characterize again the logs whose results are already in --out-dir "
                        "(default: skip them, so an interrupted fleet resumes; a result whose "
                        "options or log changed is redone either way)")
    p.add_argument("--spec", help="JSON limits per parameter; units outside are flagged")
    p.add_argument("--memory-budget-mib", type=float, default=DEFAULT_MEMORY_BUDGET_MIB,
                   metavar="MIB",
                   help="a .npy log's channel (8 bytes per sample) is read into memory when "
                        "it fits this (one channel at a time per worker), else spooled to "
                        f"a float64 file per channel; 0: always spool (default "
                        f"{DEFAULT_MEMORY_BUDGET_MIB:g})")
    add_imu_input_args(p)
    add_analysis_args(p)
    add_json_arg(p)
    add_progress_arg(p)
    p.set_defaults(func=run)


def _carried(path: str) -> bool:
    from gyrodrift.io.imu_data import units_carried

    try:
        return units_carried(path)
    except GyrodriftError:
        return True  # an unsupported input: the worker reports it


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift fleet``; returns the exit code.

    Examples
    --------
    One unit with three white gyro channels (rad/s), characterized in this process (no Dask):

    >>> import os, tempfile, numpy as np
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory(); rec = os.path.join(tmp.name, "unit1.npy")
    >>> np.save(rec, np.random.default_rng(0).normal(0.0, 1e-4, (4096, 3)))
    >>> out = os.path.join(tmp.name, "fleet")
    >>> run(p.parse_args(["fleet", rec, "--rate-hz", "100", "--gyro-units", "rad/s",
    ...                   "--column-channels", "gyro_x,gyro_y,gyro_z", "--workers", "0",
    ...                   "--out-dir", out]))
    fleet: 1 done (0 already done, skipped), 0 failed, 0 outside the spec; summary: .../summary.html
    0
    >>> tmp.cleanup()
    """
    from gyrodrift.workflows.fleet import FleetOptions, load_spec, run_fleet

    paths: list[str] = []
    for pat in args.input:
        hits = sorted(glob.glob(pat, recursive=True)) if glob.has_magic(pat) else [pat]
        if not hits:
            raise CliError(f"no log matches {pat!r}")
        paths.extend(h for h in hits if h not in paths)
    if args.drop_nan:
        raise CliError("--drop-nan is not offered for fleets: a log with NaN/Inf is reported "
                       "as failed; characterize it alone to decide")
    try:
        spec = load_spec(args.spec) if args.spec else None
    except (OSError, ValueError, GyrodriftError) as exc:
        raise CliError(str(exc)) from exc
    # --time-units, --time-column and --topic where they cannot apply are refused before the
    # work, as the single-file commands do (a .npy log has no time column; logs and bags
    # carry their own time base; only bags have topics)
    from gyrodrift.io.imu_data import check_reader_options, input_kind

    for p in paths:
        try:
            input_kind(p)
        except GyrodriftError:
            continue  # an unsupported input: the worker reports it
        try:
            check_reader_options(p, args.time_units, args.time_column, args.topic)
        except GyrodriftError as exc:
            raise CliError(str(exc)) from exc
    # the units of records that do not carry them are never guessed (gyrodrift.units)
    need = [p for p in paths if not _carried(p)]
    if need:
        require_units(need[0], "--gyro-units", args.gyro_units)
        if args.column_channels is None or "accel" in args.column_channels:
            require_units(need[0], "--accel-units", args.accel_units)
    try:
        opts = FleetOptions(
            rate_hz=args.rate_hz,
            columns=(tuple(args.column_channels.split(",")) if args.column_channels
                     else None),
            time_column=args.time_column, time_units=args.time_units, topic=args.topic,
            gyro_units=args.gyro_units or "rad/s", accel_units=args.accel_units or "m/s^2",
            ci=args.ci, taus=args.taus,
            terms=tuple(t.strip().upper() for t in args.terms.split(",") if t.strip()),
            method=args.identifier, memory_budget_mib=args.memory_budget_mib)
    except GyrodriftError as exc:
        raise CliError(str(exc)) from exc
    show = progress_enabled(args)
    root = os.path.commonpath([os.path.abspath(p) for p in paths]) if len(paths) > 1 else None
    try:
        summary = run_fleet([os.path.abspath(p) for p in paths], args.out_dir, opts=opts,
                            workers=args.workers, scheduler=args.scheduler, force=args.redo,
                            spec=spec, root=root, progress=show)
    except (OSError, ValueError, GyrodriftError) as exc:
        raise CliError(str(exc)) from exc
    if args.json:
        emit_json(summary)
    else:
        redone = (f"; {summary['n_redone']} redone: options or input changed"
                  if summary["n_redone"] else "")
        print(f"fleet: {summary['n_done']} done ({summary['n_skipped']} already done, skipped"
              f"{redone}), {summary['n_failed']} failed, "
              f"{len({f['unit'] for f in summary['flagged']})} "
              f"outside the spec; summary: {os.path.join(args.out_dir, 'summary.html')}")
        for r in summary["redone"]:
            print(f"redone: {r['path']}: {r['reason']}")
        for f in summary["failed"]:
            print(f"failed: {f['path']}: {f['reason']}")
        for f in summary["flagged"]:
            print(f"outside spec: {f['unit']} {f['parameter']} {f['channel']} = "
                  f"{f['value']:.4g} ({f['limit']})")
    for w in summary["warnings"]:
        print(f"gyrodrift fleet: warning: {w}", file=sys.stderr)
    return 1 if summary["n_failed"] else 0
