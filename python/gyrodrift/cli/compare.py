"""`gyrodrift compare`: the 2006 paper's Table 1 (raw, db8 wavelet, bior3.7 wavelet packet,
AR model, AR(2)-Kalman), our measured rows beside the published ones, with PNG overlays of
the Allan deviations and PSDs and a markdown + CSV report."""

from __future__ import annotations

import argparse
from typing import Any

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    add_input_args,
    add_json_arg,
    add_progress_arg,
    check_out_dir,
    emit_json,
    progress_enabled,
    record_from_args,
)

__all__ = ["register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``compare`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["compare", "--seed", "3"])
    >>> args.input, args.seed, args.out_dir, args.progress
    (None, 3, 'compare_out', 'auto')
    """
    p = subparsers.add_parser("compare", help="paper 2006 Table 1: filters compared by Allan/PSD",
                              description=__doc__)
    add_input_args(p, required=False)
    p.add_argument("--out-dir", default="compare_out",
                   help="report directory: table.md, table.csv and the PNG overlays "
                        "(default compare_out)")
    p.add_argument("--seed", type=int, default=None,
                   help="without INPUT: seed of the simulated default record (default: the "
                        "library's fixed seed)")
    add_json_arg(p)
    add_progress_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift compare``; returns the exit code.

    Examples
    --------
    The paper's Table 1 on a white-noise record instead of the default simulated one:

    >>> import os, tempfile, numpy as np
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory(); rec = os.path.join(tmp.name, "gyro.npy")
    >>> np.save(rec, np.random.default_rng(0).normal(0.0, 1.0, 4096))
    >>> run(p.parse_args(["compare", rec, "--rate-hz", "100", "--gyro-units", "deg/h",
    ...                   "--out-dir", tmp.name]))
    Record: .../gyro.npy, 4096 samples at 100 Hz. AR(2) of the raw record: ...
    ...
    | original | ours (measured) | 0.0001574 | 0.001614 | 0.007557 | 0.9976 |
    ...
    0
    >>> tmp.cleanup()
    """
    from gyrodrift.papers import table1 as compare

    if args.out_dir is not None:
        check_out_dir(args.out_dir)
    try:
        if args.input is None:
            x = rate = None
            if args.seed is not None:
                x, rate = compare.default_record(seed=args.seed)
                source = f"default simulated record, seed {args.seed}"
            else:
                source = ""
        else:
            rec = record_from_args(args)  # a long .npy record is read in pieces
            x, rate, source = rec.rate_deg_h, rec.rate_hz, rec.source
        report = compare.run_compare(x, rate, out_dir=args.out_dir, source=source,
                                     progress=progress_enabled(args))
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    if args.json:
        emit_json(report.as_dict())
        return 0
    print(report.markdown())
    print("files: " + ", ".join(f"{k}={v}" for k, v in report.files.items()))
    return 0
