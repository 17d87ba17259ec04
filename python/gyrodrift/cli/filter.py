"""`gyrodrift filter`: filter a rate record and print the before/after standard deviation.

Methods: the AR model filter (ar), the AR(2)-Kalman filter (kalman), offline wavelet
denoising (wavelet: db4 or db8, soft or hard threshold), bior3.7 wavelet-packet denoising
(wpacket) or the real-time sliding-window wavelet prefilter (realtime-wavelet: forced, soft
or hard). The C++ core runs in double or float (the MCU build). The filtered record is written
to .npy or .csv (t_s, rate_deg_h).

A memory-mapped .npy record longer than 2^20 samples is filtered in pieces (the ar, kalman and
realtime-wavelet filters' state carried from piece to piece; the offline wavelet and wpacket
denoisers from windows of the record, the whole record's output), the output written piece
by piece: the memory does not grow with the record, with either --core."""

from __future__ import annotations

import argparse
import math
import warnings
from collections.abc import Callable, Iterator
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
    format_csv_value,
    human_stream,
    record_from_args,
    write_csv,
)
from gyrodrift.io.atomic import atomic_output
from gyrodrift.io.records import is_file_backed, iter_chunks

__all__ = ["METHODS", "register", "run"]

METHODS = ("ar", "kalman", "wavelet", "wpacket", "realtime-wavelet")
#: The methods that filter a long memory-mapped record in pieces.
PIECEWISE_METHODS = ("ar", "kalman", "realtime-wavelet", "wavelet", "wpacket")
#: A memory-mapped record longer than this (samples) is filtered in pieces of _PIECE.
FILE_BACKED_MIN = 1 << 20
_PIECE = 1 << 20


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
            return np.asarray(gyrodrift.ar_filter(x, model, dtype=dtype)), info
        info["kalman"] = {"q": model.sigma2 if args.kalman_q is None else args.kalman_q,
                          "r": model.measurement_variance if args.kalman_r is None
                          else args.kalman_r, "steady_state": bool(args.steady_state)}
        return np.asarray(gyrodrift.kalman_filter(x, model, q=args.kalman_q, r=args.kalman_r,
                                                  steady_state=args.steady_state,
                                                  dtype=dtype)), info
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
    y = np.asarray(rt.filter(x))
    info["faults"] = int(np.sum(rt.fault_counts))
    return y, info


class _Moments:
    """Running count, mean and sum of squared deviations of pieces of a record (the
    pairwise update of Chan, Golub and LeVeque 1979): the standard deviation of the whole
    record without holding it, equal to numpy.std's to rounding."""

    def __init__(self) -> None:
        self.n, self.mean, self.m2 = 0, 0.0, 0.0

    def add(self, a: np.ndarray) -> None:
        if a.size == 0:
            return
        mean = float(np.mean(a))
        m2 = float(np.sum(np.square(a - mean)))
        n = self.n + a.size
        delta = mean - self.mean
        self.m2 += m2 + delta * delta * self.n * a.size / n
        self.mean += delta * a.size / n
        self.n = n

    @property
    def std(self) -> float:
        return math.sqrt(self.m2 / self.n) if self.n else math.nan


def _piecewise_filter(x: np.ndarray, args: argparse.Namespace
                      ) -> tuple[Callable[[Iterator[np.ndarray]], Iterator[np.ndarray]],
                                 dict[str, Any], Callable[[], int]]:
    """(outputs of the record's pieces, info, faults so far) of a stateful method: the AR(2)
    model fitted in passes over the pieces (`fit_ar2_chunks`), the C++ filter's state carried
    from one piece to the next, so that the pieces' outputs are the one-call path's."""
    import gyrodrift
    from gyrodrift.filters.ar2 import ar_filter_pieces, fit_ar2_chunks
    from gyrodrift.filters.wavelet import as_core_dtype

    dtype = np.float32 if args.core == "float" else np.float64
    info: dict[str, Any] = {"method": args.filter, "core": args.core}
    if args.filter == "realtime-wavelet":
        level = args.level or 5
        mode = args.threshold or "forced"
        info |= {"wavelet": args.wavelet, "level": level, "window": args.window,
                 "threshold": mode}
        rt = gyrodrift.RealtimeWavelet(args.wavelet, window=args.window, level=level,
                                       mode=mode, dtype=dtype)
        return (lambda ps: (np.asarray(rt.filter(p)) for p in ps)), info, (
            lambda: int(np.sum(rt.fault_counts)))

    def checked_pieces() -> Iterator[np.ndarray]:
        start = 0
        for p in iter_chunks(x, _PIECE):  # float core: a value it cannot hold, named first
            if dtype == np.float32:
                as_core_dtype(p, dtype, start=start)
            start += p.size
            yield p

    model = fit_ar2_chunks(checked_pieces, args.ar_method)
    info["ar2"] = {"a1": model.a1, "a2": model.a2, "sigma2": model.sigma2,
                   "mean": model.mean, "method": args.ar_method}
    if args.filter == "ar":
        return (lambda ps: ar_filter_pieces(ps, model, dtype)), info, lambda: 0
    info["kalman"] = {"q": model.sigma2 if args.kalman_q is None else args.kalman_q,
                      "r": model.measurement_variance if args.kalman_r is None
                      else args.kalman_r, "steady_state": bool(args.steady_state)}
    kf = gyrodrift.KalmanFilter(model, q=args.kalman_q, r=args.kalman_r,
                                steady_state=args.steady_state, dtype=dtype)
    def kalman_pieces(ps: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
        start = 0
        for p in ps:  # a value beyond float32 is refused with its index in the record
            yield np.asarray(kf.process(as_core_dtype(p, dtype, start=start)))
            start += p.size

    return kalman_pieces, info, lambda: kf.fault_count


def _denoised_pieces(x: np.ndarray, args: argparse.Namespace
                     ) -> tuple[Iterator[np.ndarray], dict[str, Any]]:
    """The offline wavelet or wavelet-packet denoiser's output in pieces
    (`gyrodrift.filters.wavelet_file`), with the info `_run_filter` reports."""
    from gyrodrift.filters import wavelet_file

    info: dict[str, Any] = {"method": args.filter, "core": args.core}
    level = args.level or (5 if args.filter == "wavelet" else 4)
    mode = args.threshold or "soft"
    if args.filter == "wavelet":
        if mode == "forced":
            raise CliError("--threshold forced is the real-time prefilter's mode: use "
                           "--filter realtime-wavelet, or soft/hard")
        info |= {"wavelet": args.wavelet, "level": level, "threshold": mode}
        dtype = np.float32 if args.core == "float" else np.float64
        return wavelet_file.wavelet_denoise_pieces(x, args.wavelet, level, mode,
                                                   piece=_PIECE, dtype=dtype), info
    if args.core == "float":
        raise CliError("wpacket runs in Python (PyWavelets, float64) only; drop --core float")
    if mode == "forced":
        raise CliError("wpacket thresholds are soft or hard")
    info |= {"wavelet": "bior3.7", "level": level, "threshold": mode}
    return wavelet_file.wavelet_packet_denoise_pieces(x, "bior3.7", level, mode,
                                                      piece=_PIECE), info


def _write_pieces(out: Path, n: int, rate_hz: float, pieces: Iterator[np.ndarray]) -> None:
    """The filtered record's pieces written one after the other to `out` (.npy: a float64
    header for n samples, then the samples; .csv: t_s, rate_deg_h as `write_csv` writes
    them), through the one output rule."""
    with atomic_output(out) as tmp:
        if out.suffix.lower() == ".npy":
            with open(tmp, "wb") as fh:
                np.lib.format.write_array_header_1_0(
                    fh, {"descr": np.lib.format.dtype_to_descr(np.dtype(np.float64)),
                         "fortran_order": False, "shape": (n,)})
                for y in pieces:
                    y.tofile(fh)
        else:
            with open(tmp, "w", newline="") as fh:
                fh.write("t_s,rate_deg_h\n")
                start = 0
                for y in pieces:
                    t = np.arange(start, start + y.size) / rate_hz
                    fh.writelines(f"{format_csv_value(a)},{format_csv_value(b)}\n"
                                  for a, b in zip(t.tolist(), y.tolist(), strict=True))
                    start += y.size


def _run_piecewise(x: np.ndarray, args: argparse.Namespace, out: Path, rate_hz: float
                   ) -> tuple[dict[str, Any], float, float]:
    """Filter a file-backed record in pieces into `out`: (info, std in, std out)."""
    m_in, m_out = _Moments(), _Moments()
    if args.filter in ("wavelet", "wpacket"):
        outputs, info = _denoised_pieces(x, args)
        faults: Callable[[], int] = lambda: 0  # noqa: E731
        for p in iter_chunks(x, _PIECE):
            m_in.add(p)
    else:
        run, info, faults = _piecewise_filter(x, args)

        def inputs() -> Iterator[np.ndarray]:
            for p in iter_chunks(x, _PIECE):
                m_in.add(p)
                yield p

        outputs = run(inputs())

    def filtered() -> Iterator[np.ndarray]:
        for p in outputs:
            y = p.astype(np.float64)
            m_out.add(y)
            yield y

    _write_pieces(out, int(x.shape[0]), rate_hz, filtered())
    if args.filter == "realtime-wavelet":
        info["faults"] = faults()
    elif faults():
        warnings.warn(f"{args.filter}: {faults()} non-finite or out-of-range sample(s) were "
                      "replaced by the filter's prediction", RuntimeWarning, stacklevel=2)
    return info, m_in.std, m_out.std


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
    rec = record_from_args(args)
    raw = rec.rate_deg_h
    if (args.filter in PIECEWISE_METHODS and is_file_backed(raw) and raw.dtype == np.float64
            and raw.shape[0] > FILE_BACKED_MIN):
        try:
            info, std_in, std_out = _run_piecewise(raw, args, out, rec.rate_hz)
        except ValueError as exc:
            raise CliError(str(exc)) from exc
    else:
        x = np.ascontiguousarray(raw, dtype=np.float64)
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
        std_in, std_out = float(np.std(x)), float(np.std(y))
    if info.get("faults"):
        warnings.warn(f"{args.filter} ({args.core}): {info['faults']} sample(s) skipped by "
                      "the filter (non-finite, or beyond what its arithmetic holds); each "
                      "repeats the previous output", RuntimeWarning, stacklevel=2)
    result = {"record": rec.summary(), "filter": info, "output": str(out),
              "std_in_deg_h": std_in, "std_out_deg_h": std_out}
    if args.json:
        emit_json(result)
    else:
        print(f"{args.filter} ({args.core}): std {result['std_in_deg_h']:.5g} -> "
              f"{result['std_out_deg_h']:.5g} deg/h; wrote {out}", file=human_stream(out))
    return 0
