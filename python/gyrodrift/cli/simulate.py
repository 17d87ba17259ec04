"""`gyrodrift simulate`: a seeded gyro record (IEEE Std 952 terms + AR(2) drift) to .npy/.csv,
or a 6-channel static IMU log for replay (.bin/.gdf frames, .log candump, .asc, .blf)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.cli.allan import emit_json

LOG_FORMATS = {"frames": "bin", "candump": "candump", "asc": "asc", "blf": "blf"}
LOG_SUFFIXES = {".bin", ".gdf", ".log", ".asc", ".blf"}


def register(subparsers: Any) -> None:
    p = subparsers.add_parser("simulate", help="simulate a gyro record or an IMU log",
                              description=__doc__.splitlines()[0])
    p.add_argument("output", help=".npy, .csv, or an IMU log (.bin/.gdf/.log/.asc/.blf)")
    length = p.add_mutually_exclusive_group(required=True)
    length.add_argument("--n", type=int, help="number of samples")
    length.add_argument("--duration", type=float, help="duration, s")
    p.add_argument("--rate", type=float, default=400.0, help="sample rate, Hz (default 400)")
    p.add_argument("--q", type=float, default=0.0, help="quantization Q, deg")
    p.add_argument("--arw", type=float, default=0.0, help="angle random walk N, deg/sqrt(h)")
    p.add_argument("--bi", type=float, default=0.0, help="bias instability B, deg/h")
    p.add_argument("--rrw", type=float, default=0.0, help="rate random walk K, deg/h/sqrt(h)")
    p.add_argument("--ramp", type=float, default=0.0, help="rate ramp R, deg/h/h")
    p.add_argument("--bias", type=float, default=0.0, help="constant bias, deg/h")
    p.add_argument("--ar2", type=float, nargs=3, metavar=("A1", "A2", "SIGMA_DPH"),
                   help="AR(2) drift component")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--format", choices=tuple(LOG_FORMATS), help="IMU log format (else suffix)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import gyrodrift

    out = Path(args.output)
    suffix = out.suffix.lower()
    kw = {"q_deg": args.q, "n_deg_rthr": args.arw, "b_deg_h": args.bi,
          "k_deg_h_rthr": args.rrw, "r_deg_h_h": args.ramp, "bias_deg_h": args.bias}
    is_log = args.format is not None or suffix in LOG_SUFFIXES
    if not is_log and suffix not in (".npy", ".csv"):
        raise CliError(f"cannot tell what to write from {out.name!r}: use .npy, .csv, or an "
                       "IMU log suffix (.bin .gdf .log .asc .blf) / --format")
    try:
        if is_log:
            from gyrodrift.replay.logs import write_imu_log

            if args.ar2 is not None:
                raise CliError("--ar2 is not available for IMU logs (static IMU simulator)")
            imu = gyrodrift.simulate_imu(n=args.n, duration_s=args.duration, rate_hz=args.rate,
                                         gyro=gyrodrift.NoiseTerms(**kw), seed=args.seed)
            t_s = np.arange(imu.gyro_rads.shape[0]) / args.rate
            fmt = LOG_FORMATS[args.format] if args.format else None
            write_imu_log(out, t_s, imu.gyro_rads, imu.accel_mps2, fmt=fmt)
            n = int(t_s.size)
            kind = f"imu log ({fmt or suffix})"
        else:
            rec = gyrodrift.simulate(n=args.n, duration_s=args.duration, rate_hz=args.rate,
                                     ar2=tuple(args.ar2) if args.ar2 else None, seed=args.seed,
                                     **kw)
            n = rec.n
            if suffix == ".npy":
                np.save(out, rec.rate_dph)
            else:
                np.savetxt(out, np.column_stack([rec.t_s, rec.rate_dph]), delimiter=",",
                           header="t_s,rate_dph", comments="", fmt="%.17g")
            kind = "rate deg/h"
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    info = {"output": str(out), "kind": kind, "n": n, "rate_hz": args.rate, "seed": args.seed,
            "terms": kw | {"ar2": args.ar2}}
    if args.json:
        emit_json(info)
    else:
        print(f"wrote {out} ({kind}, {n} samples at {args.rate:g} Hz, seed {args.seed})")
    return 0
