"""`gyrodrift psd`: Welch PSD of a rate record in (deg/h)^2/Hz, log-binned PNG."""

from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    add_input_args,
    add_json_arg,
    check_output,
    emit_json,
    record_from_args,
    write_csv,
)
from gyrodrift.io.atomic import atomic_output

__all__ = ["register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``psd`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["psd", "gyro.csv", "--rate-hz", "100", "--nperseg", "1024"])
    >>> args.nperseg, args.png, args.bins_per_decade
    (1024, 'psd.png', 20)
    """
    p = subparsers.add_parser("psd", help="Welch PSD, (deg/h)^2/Hz, PNG",
                              description=__doc__)
    add_input_args(p)
    p.add_argument("--png", default="psd.png", help="output plot (default psd.png)")
    p.add_argument("--nperseg", type=int, help="Welch segment length (default: n/8, <= 65536)")
    p.add_argument("--bins-per-decade", type=int, default=20,
                   help="log-spaced frequency bins per decade of the plotted PSD (default 20)")
    p.add_argument("--csv", dest="csv_out", help="write f_hz,psd as CSV")
    add_json_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift psd``; returns the exit code.

    Examples
    --------
    A white-noise record (1 deg/h per sample at 100 Hz): a flat PSD of 2 sigma^2 dt:

    >>> import os, tempfile, numpy as np
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory(); rec = os.path.join(tmp.name, "gyro.npy")
    >>> np.save(rec, np.random.default_rng(0).normal(0.0, 1.0, 4096))
    >>> run(p.parse_args(["psd", rec, "--rate-hz", "100", "--gyro-units", "deg/h",
    ...                   "--png", rec.replace(".npy", ".png")]))
    # .../gyro.npy: 4096 samples at 100 Hz, Welch nperseg 512
    upper-band level 0.02068 (deg/h)^2/Hz -> N = 0.001695 deg/sqrt(h) if white; PNG: .../gyro.png
    0
    >>> tmp.cleanup()
    """
    from gyrodrift.report.plots import plot_psd
    from gyrodrift.stability.psd import arw_from_white_level, log_binned

    check_output(args.png, "--png")
    check_output(args.csv_out, "--csv", (".csv",))
    from gyrodrift.io.records import iter_chunks

    # A memory-mapped .npy record stays on file: read in pieces (bounded memory).
    rec = record_from_args(args)
    x = (rec.rate_deg_h if isinstance(rec.rate_deg_h, np.memmap)
         else np.asarray(rec.rate_deg_h))
    if x.size:
        first = float(x[0])
        if all(bool(np.all(p == first)) for p in iter_chunks(x, 1 << 20)):
            raise CliError(f"{rec.source}: the record is constant ({x.size} samples of "
                           f"{first:g} deg/h): its PSD is zero at every frequency, nothing "
                           "to plot")
    try:
        res = _welch_in_range(x, rec.rate_hz, args.nperseg, rec.source)
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    with atomic_output(args.png) as tmp:
        plot_psd([(rec.source, res)], tmp, bins_per_decade=args.bins_per_decade)
    if args.csv_out:
        write_csv(args.csv_out, ["f_hz", "psd_deg_h2_per_hz"], [res.f_hz, res.psd])
    # White level from the upper half of the band (where angle random walk usually rules).
    upper = res.f_hz > res.f_hz[-1] / 2
    level = float(np.median(res.psd[upper]))
    f_b, p_b = log_binned(res.f_hz, res.psd, args.bins_per_decade)
    out = {"record": rec.summary(), "nperseg": res.nperseg, "n_bins": int(res.f_hz.size),
           "white_level_deg_h_sq_hz": level, "n_arw_deg_rt_h": arw_from_white_level(level),
           "variance_from_psd_deg_h_sq": float(np.trapezoid(res.psd, res.f_hz)),
           "log_binned": {"f_hz": f_b.tolist(), "psd": p_b.tolist()},
           "files": {"png": args.png, "csv": args.csv_out}}
    if args.json:
        emit_json(out)
        return 0
    print(f"# {rec.source}: {rec.n} samples at {rec.rate_hz:g} Hz, Welch nperseg {res.nperseg}")
    print(f"upper-band level {level:.4g} (deg/h)^2/Hz -> N = "
          f"{out['n_arw_deg_rt_h']:.4g} deg/sqrt(h) if white; PNG: {args.png}")
    return 0


def _welch_in_range(x: np.ndarray, rate_hz: float, nperseg: int | None, source: str) -> Any:
    """The Welch PSD of `x`, refused (one line) where it leaves the range of float64: the PSD
    is quadratic in the record, so a record of 1e200 deg/h overflows it to inf and one of
    1e-200 deg/h underflows it to 0 (N = inf or 0, silently). The record is scaled by a power
    of two for the transform and the PSD scaled back: exact (the same bits) wherever the
    PSD is representable, and the bins that are not show as inf or lost to zero."""
    from gyrodrift.io.records import iter_chunks
    from gyrodrift.stability.psd import welch_psd

    peak = 0.0
    for p in iter_chunks(x, 1 << 20):  # file reads for a memory map
        pk = float(np.max(np.abs(p))) if p.size else 0.0
        peak = pk if not pk <= peak else peak  # NaN wins: welch_psd refuses it
    scale = math.ldexp(1.0, math.frexp(peak)[1]) if peak > 0 and math.isfinite(peak) else 1.0
    res = welch_psd(x, rate_hz, nperseg=nperseg, scale=scale)
    with np.errstate(over="ignore", under="ignore"):
        psd = res.psd * scale * scale
    lost = (res.psd > 0) & (psd < np.finfo(np.float64).tiny)
    if not np.all(np.isfinite(psd)) or np.any(lost):
        level = float(np.median(res.psd[res.psd > 0])) if np.any(res.psd > 0) else 1.0
        exponent = round(math.log10(level) + 2.0 * math.log10(scale))
        raise CliError(
            f"{source}: the PSD of this record is outside the range of float64 numbers "
            f"(values up to {peak:.3g} deg/h: its PSD would be near 1e{exponent:+d} "
            "(deg/h)^2/Hz); rescale the record (--gyro-units)")
    return dataclasses.replace(res, psd=psd)

