"""`gyrodrift filter`: filter a rate record with the AR model filter, the AR(2)-Kalman filter,
db8 wavelet or bior3.7 wavelet-packet denoising, or the real-time wavelet prefilter, on the
float (MCU) or double core; writes .npy or .csv and prints the before/after deviation."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.cli.allan import add_input_args, emit_json, record_from_args

METHODS = ("ar", "kalman", "wavelet", "wpacket", "realtime-wavelet")


def register(subparsers: Any) -> None:
    p = subparsers.add_parser("filter", help="AR / AR(2)-Kalman / wavelet filters",
                              description=__doc__.splitlines()[0])
    add_input_args(p)
    p.add_argument("-o", "--output", required=True, help="filtered record (.npy or .csv)")
    p.add_argument("--method", choices=METHODS, default="kalman")
    p.add_argument("--core", choices=("double", "float"), default="double",
                   help="scalar type of the C++ core (float = the MCU build)")
    p.add_argument("--ar-method", choices=("yule-walker", "burg", "ls"), default="yule-walker")
    p.add_argument("--steady-state", action="store_true", help="constant-gain Kalman")
    p.add_argument("--level", type=int, default=None, help="wavelet level")
    p.add_argument("--window", type=int, default=256, help="real-time wavelet window")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def _run_filter(x: np.ndarray, args: argparse.Namespace) -> tuple[np.ndarray, dict[str, Any]]:
    import gyrodrift

    dtype = np.float32 if args.core == "float" else np.float64
    info: dict[str, Any] = {"method": args.method, "core": args.core}
    if args.method in ("ar", "kalman"):
        model = gyrodrift.fit_ar2(x, method=args.ar_method)
        info["ar2"] = {"a1": model.a1, "a2": model.a2, "sigma2": model.sigma2,
                       "mean": model.mean, "method": args.ar_method}
        if args.method == "ar":
            return np.asarray(gyrodrift.ar_filter(x.astype(dtype), model)), info
        return np.asarray(gyrodrift.kalman_filter(x.astype(dtype), model,
                                                  steady_state=args.steady_state)), info
    if args.method == "wavelet":
        level = args.level or 5
        info["level"] = level
        return np.asarray(gyrodrift.wavelet_denoise(x, wavelet="db8", level=level,
                                                    dtype=dtype)), info
    if args.method == "wpacket":
        if args.core == "float":
            raise CliError("wpacket runs in Python (PyWavelets, float64) only; drop --core float")
        level = args.level or 4
        info["level"] = level
        return np.asarray(gyrodrift.wavelet_packet_denoise(x, wavelet="bior3.7",
                                                           level=level)), info
    level = args.level or 5
    info |= {"level": level, "window": args.window}
    rt = gyrodrift.RealtimeWavelet("db8", window=args.window, level=level, dtype=dtype)
    return np.asarray(rt.filter(x)), info


def run(args: argparse.Namespace) -> int:
    rec = record_from_args(args, mmap=False)
    out = Path(args.output)
    if out.suffix.lower() not in (".npy", ".csv"):
        raise CliError(f"output must end in .npy or .csv, got {out.name!r}")
    x = np.ascontiguousarray(rec.rate_dph, dtype=np.float64)
    try:
        y, info = _run_filter(x, args)
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    y = y.astype(np.float64)
    if out.suffix.lower() == ".npy":
        np.save(out, y)
    else:
        t_s = np.arange(y.size) / rec.rate_hz
        np.savetxt(out, np.column_stack([t_s, y]), delimiter=",", header="t_s,rate_dph",
                   comments="", fmt="%.17g")
    result = {"record": rec.summary(), "filter": info, "output": str(out),
              "std_in_dph": float(np.std(x)), "std_out_dph": float(np.std(y))}
    if args.json:
        emit_json(result)
    else:
        print(f"{args.method} ({args.core}): std {result['std_in_dph']:.5g} -> "
              f"{result['std_out_dph']:.5g} deg/h; wrote {out}")
    return 0
