"""`gyrodrift wavelet-response`: magnitude and group delay of the forced real-time wavelet
prefilter (paper 004 sec. 2.2) at a sample rate, as a PNG (and --json)."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.cli.common import add_json_arg, check_output, check_rate_hz, emit_json
from gyrodrift.defaults import (
    DEFAULT_SAMPLE_RATE_HZ,
    PREFILTER_LEVEL,
    PREFILTER_WAVELET,
    PREFILTER_WINDOW,
)
from gyrodrift.io.atomic import atomic_output

__all__ = ["cutoff_hz", "register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``wavelet-response`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["wavelet-response", "--wavelet", "db8", "--level", "4"])
    >>> args.wavelet, args.window, args.level, args.rate_hz
    ('db8', 256, 4, 400.0)
    """
    p = subparsers.add_parser(
        "wavelet-response",
        help="frequency response (magnitude, group delay) of the forced wavelet prefilter",
        description=__doc__,
    )
    p.add_argument("--wavelet", default=PREFILTER_WAVELET, choices=["db4", "db8"],
                   help=f"wavelet (default {PREFILTER_WAVELET})")
    p.add_argument("--window", type=int, default=PREFILTER_WINDOW,
                   help=f"window N, power of two (default {PREFILTER_WINDOW})")
    p.add_argument("--level", type=int, default=PREFILTER_LEVEL,
                   help=f"decomposition level J (default {PREFILTER_LEVEL})")
    p.add_argument("--rate-hz", type=float, default=DEFAULT_SAMPLE_RATE_HZ,
                   help=f"sample rate, Hz (default {DEFAULT_SAMPLE_RATE_HZ:g})")
    p.add_argument("--n-freqs", type=int, default=1024, help="frequency points (default 1024)")
    p.add_argument("--png", default="wavelet_response.png",
                   help="output plot (default wavelet_response.png)")
    add_json_arg(p)
    p.set_defaults(func=run)


def cutoff_hz(f_hz: np.ndarray, mag: np.ndarray, level_db: float) -> float:
    """First frequency where ``|H|`` falls below level_db (linear interpolation in dB).

    Examples
    --------
    >>> cutoff_hz(np.array([0.0, 1.0, 2.0]), np.array([1.0, 0.9, 0.1]), -3.0) > 1.0
    True
    """
    db = 20.0 * np.log10(np.maximum(mag, 1e-300))
    below = np.nonzero(db < level_db)[0]
    if below.size == 0 or below[0] == 0:
        return float("nan")
    i = int(below[0])
    return float(np.interp(level_db, [db[i], db[i - 1]], [f_hz[i], f_hz[i - 1]]))


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift wavelet-response``; returns the exit code.

    Examples
    --------
    The default forced db4 prefilter (J = 5, 256 samples) at 400 Hz:

    >>> import os, tempfile
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory()
    >>> run(p.parse_args(["wavelet-response", "--png", os.path.join(tmp.name, "w.png")]))
    # forced db4 J=5 N=256 at 400 Hz: -3 dB at 7.381 Hz, DC group delay 20.46 ms; PNG: .../w.png
    0
    >>> tmp.cleanup()
    """
    from gyrodrift.filters.fir import fir_group_delay
    from gyrodrift.filters.wavelet import RealtimeWavelet

    check_rate_hz(args.rate_hz)
    check_output(args.png, "--png")
    if args.n_freqs < 8:
        raise CliError("--n-freqs must be >= 8")
    try:
        filt = RealtimeWavelet(args.wavelet, args.window, args.level, "forced")
    except (ValueError, TypeError) as exc:
        raise CliError(str(exc)) from exc
    b = filt.fir_taps()
    f_hz, mag, gd_s = fir_group_delay(b, args.rate_hz, args.n_freqs)
    f3 = cutoff_hz(f_hz, mag, -3.0)
    out = {
        "wavelet": args.wavelet,
        "window": args.window,
        "level": args.level,
        "rate_hz": args.rate_hz,
        "taps_newest_first": b.tolist(),
        "dc_gain": float(b.sum()),
        "group_delay_dc_s": float(gd_s[0]),
        "cutoff_3db_hz": f3,
        "f_hz": f_hz.tolist(),
        "magnitude": mag.tolist(),
        "group_delay_s": gd_s.tolist(),
        "png": args.png,
    }
    _plot(f_hz, mag, gd_s, args, f3)
    if args.json:
        emit_json(out)
        return 0
    print(
        f"# forced {args.wavelet} J={args.level} N={args.window} at {args.rate_hz:g} Hz: "
        f"-3 dB at {f3:.4g} Hz, DC group delay {gd_s[0] * 1e3:.4g} ms; PNG: {args.png}"
    )
    return 0


def _plot(
    f_hz: np.ndarray, mag: np.ndarray, gd_s: np.ndarray, args: argparse.Namespace, f3: float
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    ax1.plot(f_hz, 20 * np.log10(np.maximum(mag, 1e-12)))
    ax1.axhline(-3.0, color="grey", lw=0.5, ls="--")
    ax1.set_ylabel("|H| (dB)")
    ax1.set_ylim(-60, 5)
    ax1.set_title(
        f"forced {args.wavelet} J={args.level} N={args.window} @ {args.rate_hz:g} Hz"
        f" (-3 dB at {f3:.3g} Hz)"
    )
    ax1.grid(True, which="both", alpha=0.3)
    ax2.plot(f_hz, gd_s * 1e3)
    ax2.set_ylabel("group delay (ms)")
    ax2.set_xlabel("frequency (Hz)")
    ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    try:
        with atomic_output(args.png) as tmp:
            fig.savefig(tmp, dpi=110)
    except OSError as exc:
        raise CliError(f"cannot write {args.png}: {exc}") from exc
    finally:
        plt.close(fig)
