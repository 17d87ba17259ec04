"""`gyrodrift simulate`: a seeded gyro rate record (IEEE Std 952 terms plus an AR(2) drift)
written to .npy or .csv, or a six-channel static IMU log for replay (bin/.gdf frame log,
candump .log, Vector .asc, .blf)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    add_json_arg,
    check_output,
    check_rate_hz,
    emit_json,
    human_stream,
    write_csv,
)
from gyrodrift.defaults import DEFAULT_SAMPLE_RATE_HZ
from gyrodrift.io.atomic import atomic_output

__all__ = ["LOG_FORMATS", "LOG_SUFFIXES", "register", "run"]

#: --format choice -> write_imu_log format.
LOG_FORMATS = {"bin": "bin", "candump": "candump", "asc": "asc", "blf": "blf"}
LOG_SUFFIXES = {".bin", ".gdf", ".log", ".asc", ".blf"}


def register(subparsers: Any) -> None:
    """Add the ``simulate`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["simulate", "-o", "gyro.csv", "--duration-s", "60"])
    >>> args.duration_s, args.rate_hz, args.seed
    (60.0, 400.0, 0)
    """
    p = subparsers.add_parser("simulate", help="simulate a gyro record or an IMU log",
                              description=__doc__)
    p.add_argument("-o", "--output", required=True,
                   help=".npy or .csv (t_s, rate_deg_h), or an IMU log (.bin/.gdf/.log/.asc/.blf)")
    length = p.add_mutually_exclusive_group(required=True)
    length.add_argument("--samples", type=int, help="record length, samples")
    length.add_argument("--duration-s", type=float, help="duration, s")
    p.add_argument("--rate-hz", type=float, default=DEFAULT_SAMPLE_RATE_HZ,
                   help=f"sample rate, Hz (default {DEFAULT_SAMPLE_RATE_HZ:g})")
    p.add_argument("--quant-arcsec", type=float, default=0.0,
                   help="quantization noise Q, arcsec (default 0)")
    p.add_argument("--arw-deg-rt-h", type=float, default=0.0,
                   help="angle random walk N, deg/sqrt(h) (default 0)")
    p.add_argument("--bias-inst-deg-h", type=float, default=0.0,
                   help="bias instability B, deg/h (default 0)")
    p.add_argument("--rrw-deg-h-rt-h", type=float, default=0.0,
                   help="rate random walk K, deg/h/sqrt(h) (default 0)")
    p.add_argument("--ramp-deg-h2", type=float, default=0.0,
                   help="rate ramp R, deg/h^2 (default 0)")
    p.add_argument("--bias-deg-h", type=float, default=0.0, help="constant bias, deg/h (default 0)")
    p.add_argument("--ar2", metavar="A1,A2",
                   help="AR(2) drift component with coefficients A1, A2 (needs --ar2-sigma2)")
    p.add_argument("--ar2-sigma2", type=float, default=None,
                   help="driving-noise variance of the AR(2) drift, (deg/h)^2")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--format", choices=tuple(LOG_FORMATS),
                   help="IMU log format (default: from the output suffix)")
    add_json_arg(p)
    p.set_defaults(func=run)


def parse_ar2(text: str | None, flag: str = "--ar2") -> tuple[float, float] | None:
    """``"A1,A2"`` -> (a1, a2); None stays None; anything else is a :class:`CliError`.

    Examples
    --------
    >>> parse_ar2("0.6868,-0.0213")
    (0.6868, -0.0213)
    """
    if text is None:
        return None
    try:
        a1, a2 = (float(v) for v in text.split(","))
    except ValueError:
        raise CliError(f"{flag} {text!r}: expected A1,A2 (two numbers)") from None
    return a1, a2


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift simulate``; returns the exit code.

    Examples
    --------
    >>> import argparse, os, tempfile
    >>> p = argparse.ArgumentParser(); register(p.add_subparsers())
    >>> out = os.path.join(tempfile.mkdtemp(), "r.csv")
    >>> args = p.parse_args(["simulate", "-o", out, "--samples", "3", "--rate-hz", "10",
    ...                       "--arw-deg-rt-h", "0.01"])
    >>> run(args)  # doctest: +ELLIPSIS
    wrote .../r.csv (rate deg/h, 3 samples at 10 Hz, seed 0)
    0
    >>> open(out).readline().strip()
    't_s,rate_deg_h'
    """
    import gyrodrift

    out = Path(args.output)
    suffix = out.suffix.lower()
    kw = {"q_deg": args.quant_arcsec / 3600.0, "n_deg_rt_h": args.arw_deg_rt_h,
          "b_deg_h": args.bias_inst_deg_h, "k_deg_h_rt_h": args.rrw_deg_h_rt_h,
          "r_deg_h2": args.ramp_deg_h2, "bias_deg_h": args.bias_deg_h}
    ab = parse_ar2(args.ar2)
    ar2: tuple[float, float, float] | None = None
    if ab is not None:
        s2 = args.ar2_sigma2
        if s2 is None or not (s2 >= 0 and math.isfinite(s2)):
            raise CliError("--ar2 needs --ar2-sigma2 S2 >= 0, the driving-noise variance in "
                           "(deg/h)^2")
        ar2 = (ab[0], ab[1], math.sqrt(s2))
    elif args.ar2_sigma2 is not None:
        raise CliError("--ar2-sigma2 needs --ar2 A1,A2")
    is_log = args.format is not None or suffix in LOG_SUFFIXES
    if not is_log and suffix not in (".npy", ".csv"):
        raise CliError(f"cannot tell what to write from {out.name!r}: use .npy, .csv, or an "
                       "IMU log suffix (.bin .gdf .log .asc .blf) / --format")
    if not is_log and ar2 is None and not any(kw.values()):
        # (an IMU log still carries gravity and the Earth rate: a clean static log is useful)
        raise CliError("no noise term and no bias given: the record would be all zeros; give "
                       "at least one of --quant-arcsec, --arw-deg-rt-h, --bias-inst-deg-h, "
                       "--rrw-deg-h-rt-h, --ramp-deg-h2, --bias-deg-h, --ar2")
    check_rate_hz(args.rate_hz)
    check_output(out, "-o")
    try:
        if is_log:
            from gyrodrift.io.imu_log import write_imu_log

            if ar2 is not None:
                raise CliError("--ar2 is not available for IMU logs (static IMU simulator)")
            imu = gyrodrift.simulate_imu(n=args.samples, duration_s=args.duration_s,
                                         rate_hz=args.rate_hz, gyro=gyrodrift.NoiseTerms(**kw),
                                         seed=args.seed)
            t_s = np.arange(imu.gyro_rad_s.shape[0]) / args.rate_hz
            fmt = LOG_FORMATS[args.format] if args.format else None
            with atomic_output(out) as tmp:
                write_imu_log(tmp, t_s, imu.gyro_rad_s, imu.accel_m_s2, fmt=fmt)
            n = int(t_s.size)
            kind = f"imu log ({fmt or suffix})"
        else:
            rec = gyrodrift.simulate(n=args.samples, duration_s=args.duration_s,
                                     rate_hz=args.rate_hz,
                                     ar2=ar2, seed=args.seed, **kw)
            n = rec.n
            if suffix == ".npy":
                with atomic_output(out) as tmp:
                    np.save(tmp, rec.rate_deg_h)
            else:
                write_csv(out, ["t_s", "rate_deg_h"], [rec.t_s, rec.rate_deg_h])
            kind = "rate deg/h"
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    info = {"output": str(out), "kind": kind, "n": n, "rate_hz": args.rate_hz,
            "seed": args.seed, "terms": kw | {"ar2": None if ar2 is None else list(ar2)}}
    if args.json:
        emit_json(info)
    else:
        print(f"wrote {out} ({kind}, {n} samples at {args.rate_hz:g} Hz, seed {args.seed})",
              file=human_stream(out))
    return 0
