"""`gyrodrift filter`: filter a rate record and print the before/after standard deviation.

Methods: the AR model filter (ar), the AR(2)-Kalman filter (kalman), offline wavelet
denoising (wavelet: db4 or db8, soft or hard threshold), bior3.7 wavelet-packet denoising
(wpacket) or the real-time sliding-window wavelet prefilter (realtime-wavelet: forced, soft
or hard). The C++ core runs in double or float (the MCU build). The filtered record is written
to .npy or .csv (t_s, rate_deg_h)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    add_ar_method_arg,
    add_input_args,
    add_json_arg,
    check_output,
    emit_json,
    human_stream,
    record_from_args,
    write_csv,
)
from gyrodrift.io.atomic import atomic_output

__all__ = ["METHODS", "register", "run"]

METHODS = ("ar", "kalman", "wavelet", "wpacket", "realtime-wavelet")


def register(subparsers: Any) -> None:
    """Add the ``filter`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["filter", "gyro.csv", "-o", "out.npy", "--filter", "wavelet",
    ...                       "--threshold", "soft"])
    >>> args.filter, args.wavelet, args.threshold, args.core
    ('wavelet', 'db8', 'soft', 'double')
    """
    p = subparsers.add_parser("filter", help="AR / AR(2)-Kalman / wavelet filters",
                              description=__doc__)
    add_input_args(p)
    p.add_argument("-o", "--output", required=True,
                   help="filtered record: .npy (rate, deg/h) or .csv (t_s, rate_deg_h)")
    p.add_argument("--filter", choices=METHODS, default="kalman",
                   help="filter: ar (AR model filter), kalman (AR(2)-Kalman filter, the "
                        "default), wavelet (offline wavelet denoising), wpacket (bior3.7 "
                        "wavelet-packet denoising) or realtime-wavelet (sliding-window prefilter)")
    p.add_argument("--core", choices=("double", "float"), default="double",
                   help="scalar type of the C++ core (float = the MCU build)")
    add_ar_method_arg(p)
    p.add_argument("--kalman-q", type=float, default=None,
                   help="Kalman process variance, (deg/h)^2 (default: the fitted sigma2)")
    p.add_argument("--kalman-r", type=float, default=None,
                   help="Kalman measurement variance, (deg/h)^2 (default: the fitted model's "
                        "one-step prediction-error variance)")
    p.add_argument("--steady-state", action="store_true",
                   help="constant-gain (steady-state) Kalman filter")
    p.add_argument("--wavelet", choices=("db4", "db8"), default="db8",
                   help="wavelet of the wavelet and realtime-wavelet methods (default db8)")
    p.add_argument("--level", type=int, default=None,
                   help="decomposition level J (default 5; wpacket 4)")
    p.add_argument("--window", type=int, default=256,
                   help="real-time wavelet window N, a power of two (default 256)")
    p.add_argument("--threshold", choices=("forced", "soft", "hard"), default=None,
                   help="threshold mode (default: soft for wavelet and wpacket, forced for "
                        "realtime-wavelet; forced is realtime-wavelet only)")
    add_json_arg(p)
    p.set_defaults(func=run)


def _run_filter(x: np.ndarray, args: argparse.Namespace) -> tuple[np.ndarray, dict[str, Any]]:
    import gyrodrift

    dtype = np.float32 if args.core == "float" else np.float64
    info: dict[str, Any] = {"method": args.filter, "core": args.core}
    if args.filter in ("ar", "kalman"):
        model = gyrodrift.fit_ar2(x, method=args.ar_method)
        assert isinstance(model, gyrodrift.Ar2Model)  # x is 1-D: one model
        info["ar2"] = {"a1": model.a1, "a2": model.a2, "sigma2": model.sigma2,
                       "mean": model.mean, "method": args.ar_method}
        if args.filter == "ar":
            return np.asarray(gyrodrift.ar_filter(x.astype(dtype), model)), info
        info["kalman"] = {"q": model.sigma2 if args.kalman_q is None else args.kalman_q,
                          "r": model.measurement_variance if args.kalman_r is None
                          else args.kalman_r, "steady_state": bool(args.steady_state)}
        return np.asarray(gyrodrift.kalman_filter(x.astype(dtype), model, q=args.kalman_q,
                                                  r=args.kalman_r,
                                                  steady_state=args.steady_state)), info
    if args.filter == "wavelet":
        level = args.level or 5
        mode = args.threshold or "soft"
        if mode == "forced":
            raise CliError("--threshold forced is the real-time prefilter's mode: use "
                           "--filter realtime-wavelet, or soft/hard")
        info |= {"wavelet": args.wavelet, "level": level, "threshold": mode}
        return np.asarray(gyrodrift.wavelet_denoise(x, wavelet=args.wavelet, level=level,
                                                    mode=mode, dtype=dtype)), info
    if args.filter == "wpacket":
        if args.core == "float":
            raise CliError("wpacket runs in Python (PyWavelets, float64) only; drop --core float")
        level = args.level or 4
        mode = args.threshold or "soft"
        if mode == "forced":
            raise CliError("wpacket thresholds are soft or hard")
        info |= {"wavelet": "bior3.7", "level": level, "threshold": mode}
        return np.asarray(gyrodrift.wavelet_packet_denoise(x, wavelet="bior3.7", level=level,
                                                           mode=mode)), info
    level = args.level or 5
    mode = args.threshold or "forced"
    info |= {"wavelet": args.wavelet, "level": level, "window": args.window, "threshold": mode}
    rt = gyrodrift.RealtimeWavelet(args.wavelet, window=args.window, level=level, mode=mode,
                                   dtype=dtype)
    return np.asarray(rt.filter(x)), info


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift filter``; returns the exit code.

    Examples
    --------
    The AR(2)-Kalman filter (the default filter) on a white-noise record halves its spread:

    >>> import os, tempfile, numpy as np
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory(); rec = os.path.join(tmp.name, "gyro.npy")
    >>> np.save(rec, np.random.default_rng(0).normal(0.0, 1.0, 4096))
    >>> run(p.parse_args(["filter", rec, "--rate-hz", "100", "--gyro-units", "deg/h",
    ...                   "-o", rec.replace("gyro", "f")]))
    kalman (double): std 0.99756 -> 0.49867 deg/h; wrote .../f.npy
    0
    >>> tmp.cleanup()
    """
    out = Path(args.output)
    if out.suffix.lower() not in (".npy", ".csv"):
        raise CliError(f"output must end in .npy or .csv, got {out.name!r}")
    check_output(out, "-o")
    rec = record_from_args(args, mmap=False)
    x = np.ascontiguousarray(rec.rate_deg_h, dtype=np.float64)
    try:
        y, info = _run_filter(x, args)
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    y = y.astype(np.float64)
    if out.suffix.lower() == ".npy":
        with atomic_output(out) as tmp:
            np.save(tmp, y)
    else:
        write_csv(out, ["t_s", "rate_deg_h"], [np.arange(y.size) / rec.rate_hz, y])
    result = {"record": rec.summary(), "filter": info, "output": str(out),
              "std_in_deg_h": float(np.std(x)), "std_out_deg_h": float(np.std(y))}
    if args.json:
        emit_json(result)
    else:
        print(f"{args.filter} ({args.core}): std {result['std_in_deg_h']:.5g} -> "
              f"{result['std_out_deg_h']:.5g} deg/h; wrote {out}", file=human_stream(out))
    return 0
