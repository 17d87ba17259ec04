"""`gyrodrift fit`: maximum-likelihood identification of the drift model of a record
(AR(2) + white, AR(1) + white, white), the chosen model, and its steady-state Kalman filter.

When the drift lives at times much longer than a sample (the Allan minimum lies far out),
the models are fitted to block averages of the record at a lower rate (the block length
chosen automatically and stated) and the filter is converted back to the record's rate.
Prints one row per model (log-likelihood, AIC, BIC, parameters with standard errors, the
Ljung-Box p-value of the innovations), the model chosen by the lowest AIC (or BIC with
--criterion bic), the filter's steady-state gain, DC gain and -3 dB bandwidth. -o FILE writes
the filter configuration: a .toml processor configuration (schema "gyrodrift.processor",
version 1: the fitted ar2_kalman stage, steady_state = true, on the gyro channel of the
record, in rad/s; pass_through elsewhere), or .json with the fields of --json; a device, FIFO
or the standard output without a suffix (-o /dev/stdout) gets the .toml, and the table then
goes to stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    add_input_args,
    add_json_arg,
    check_output,
    emit_json,
    human_stream,
    record_from_args,
)
from gyrodrift.io.atomic import atomic_write_text, output_target
from gyrodrift.io.json_text import json_text
from gyrodrift.units import DPH

__all__ = ["config_toml", "register", "run"]

#: deg/h -> rad/s (the record is in deg/h; the configuration in SI).


def register(subparsers: Any) -> None:
    """Add the ``fit`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["fit", "gyro.csv", "--rate-hz", "100", "-o", "processor.toml"])
    >>> args.criterion, args.output
    ('aic', 'processor.toml')
    """
    p = subparsers.add_parser("fit", help="ML drift model (AR(2)/AR(1)/white + white noise), "
                              "its Kalman filter and configuration",
                              description=__doc__.splitlines()[0])
    add_input_args(p)
    p.add_argument("--criterion", choices=("aic", "bic"), default="aic",
                   help="model choice: lowest AIC (default) or BIC")
    p.add_argument("-o", "--output", help="write the filter configuration (.toml processor "
                   "configuration, or .json)")
    add_json_arg(p)
    p.set_defaults(func=run)


def _gyro_channel(column: str | None) -> str:
    c = (column or "").strip().lower()
    return f"g{c[-1]}" if c and c[-1] in "xyz" else "gx"


def config_toml(fit: Any, rate_hz: float, channel: str, source: str,
                fit_rate_hz: float | None = None) -> str:
    """The processor configuration (canonical text) with the fitted steady-state
    AR(2)-Kalman stage on `channel` (values converted from deg/h to rad/s), the other channels
    passed through.

    Its ``[meta]`` table (read by no processor) records the fit: model, tuning, identified,
    fit_rate_hz, loglike, ar_identified, and, when the fit found a second maximum across the
    fold a2 = 0, fold_a2 and fold_loglike (as ``gyrodrift fit`` prints them, at fit_rate_hz).

    Examples
    --------
    >>> import numpy as np
    >>> from gyrodrift.filters.drift_model import compare_drift_models
    >>> from scipy.signal import lfilter
    >>> rng = np.random.default_rng(1)  # AR(2) drift (a1 0.6, a2 0.2) under white noise, deg/h
    >>> x = lfilter([1.0], [1.0, -0.6, -0.2], rng.normal(0, 1, 4000)) + rng.normal(0, 0.5, 4000)
    >>> best = compare_drift_models(x, 100.0).best
    >>> text = config_toml(best, 100.0, "gz", "gyro.csv")
    >>> text.splitlines()[1:3]
    ['schema = "gyrodrift.processor"', 'version = 1']
    >>> from gyrodrift.imu.config import parse_config
    >>> parse_config(text).channels[2].stages[0].steady_state
    True
    >>> dict(parse_config(text).meta)["ar_identified"]
    True
    """
    from gyrodrift.imu.config import drift_filter_config, dumps_config

    # The filter's parameters: the fit's, or the minimax q = r tuning when the fit could not
    # tell drift from white noise (fit.tuning).
    a1, a2, q, r = fit.filter_params
    meta: tuple[tuple[str, Any], ...] = (
        ("written_by", "gyrodrift fit"), ("record", os.path.basename(source)),
        ("model", str(fit.model)), ("tuning", str(fit.tuning)),
        ("identified", "yes" if fit.identified else
         "no: the record cannot tell drift from white noise (filter tuned at q = r)"),
        ("fit_rate_hz", float(rate_hz if fit_rate_hz is None else fit_rate_hz)),
        ("loglike", float(fit.loglike)), ("ar_identified", bool(fit.ar_identified)))
    if math.isfinite(fit.fold_loglike):  # the other maximum across a2 = 0, when there is one
        meta += (("fold_a2", float(fit.fold_a2)), ("fold_loglike", float(fit.fold_loglike)))
    cfg = drift_filter_config(channel, a1=a1, a2=a2, mean=fit.mean * DPH, q=q * DPH * DPH,
                              r=max(r, 1e-12 * (q + r)) * DPH * DPH, sample_rate_hz=rate_hz,
                              meta=meta)
    return dumps_config(cfg)


def _decimation(x: np.ndarray, rate_hz: float) -> tuple[int, float]:
    """(block length, tau of the Allan minimum in s) for the drift fit
    (gyrodrift.filters.drift_model.choose_decimation on the octave Allan deviation)."""
    from gyrodrift.filters.drift_model import choose_decimation
    from gyrodrift.stability.allan import oadev

    if x.size < 64:
        return 1, math.nan
    try:
        a = oadev(x, rate_hz, taus="octave", progress=False)
    except ValueError:
        return 1, math.nan
    ok = a.adev > 0
    if not np.any(ok):
        return 1, math.nan
    tau_min = float(a.tau_s[ok][np.argmin(a.adev[ok])])
    return choose_decimation(a.tau_s, a.adev, rate_hz, int(x.size)), tau_min


def _output_format(output: str | None) -> str | None:
    """The format of -o: its suffix (.toml or .json); a device, FIFO or the standard output
    without one (``-o /dev/stdout``) gets the processor configuration (.toml)."""
    if not output:
        return None
    suffix = Path(output).suffix.lower()
    if suffix in (".toml", ".json"):
        return suffix
    if not suffix:
        with contextlib.suppress(OSError):
            if output_target(output).kind == "stream":
                return ".toml"
    raise CliError(f"-o/--output: unknown suffix {suffix!r}; use .toml or .json")


def _fmt(v: float, se: float) -> str:
    if not math.isfinite(se):
        return f"{v:.5g}"
    return f"{v:.5g}±{se:.2g}"


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift fit``; returns the exit code.

    Examples
    --------
    An AR(2) drift (a1 0.6, a2 0.2) under white noise, deg/h at 100 Hz; the AR(2) model wins:

    >>> import os, tempfile, numpy as np
    >>> from scipy.signal import lfilter
    >>> rng = np.random.default_rng(1)
    >>> x = lfilter([1.0], [1.0, -0.6, -0.2], rng.normal(0, 1, 4000)) + rng.normal(0, 0.5, 4000)
    >>> tmp = tempfile.TemporaryDirectory(); np.save(os.path.join(tmp.name, "gyro.npy"), x)
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> run(p.parse_args(["fit", os.path.join(tmp.name, "gyro.npy"), "--rate-hz", "100",
    ...                   "--gyro-units", "deg/h"]))
    # .../gyro.npy: 4000 samples at 100 Hz, units deg/h (q, r in (deg/h)^2); ...
    model             loglike ...
    ...
    chosen: ar2+white (lowest AIC)
    ...
    0
    >>> tmp.cleanup()
    """
    from gyrodrift.filters.ar2 import Ar2FitError
    from gyrodrift.filters.drift_model import (
        block_average,
        compare_drift_models,
        drift_params_at_rate,
    )

    fmt = _output_format(args.output)
    check_output(args.output, "-o")  # before the work
    # A memory-mapped .npy record stays on file: the Allan deviation, the block averages and
    # the drift model's likelihood read it in pieces (bounded memory).
    rec = record_from_args(args)
    x = (rec.rate_deg_h if isinstance(rec.rate_deg_h, np.memmap)
         else np.asarray(rec.rate_deg_h, dtype=np.float64))
    factor, tau_min = _decimation(x, rec.rate_hz)
    fit_rate = rec.rate_hz / factor
    try:
        cmp_ = compare_drift_models(block_average(x, factor) if factor > 1 else x, fit_rate,
                                    criterion=args.criterion)
    except (Ar2FitError, ValueError) as exc:
        raise CliError(str(exc)) from exc
    best = cmp_.best
    note = ""
    if factor > 1:
        try:
            mapped = drift_params_at_rate(*best.filter_params, factor)
            best = dataclasses.replace(best, filter_params=mapped, rate_hz=rec.rate_hz)
        except ValueError as exc:  # no slower model at the original rate: fit it there
            note = f"not decimated: {exc}"
            factor, fit_rate = 1, rec.rate_hz
            try:
                cmp_ = compare_drift_models(x, fit_rate, criterion=args.criterion)
            except (Ar2FitError, ValueError) as exc2:
                raise CliError(str(exc2)) from exc2
            best = cmp_.best
    decimation = {"factor": factor, "fit_rate_hz": fit_rate, "tau_allan_min_s": tau_min,
                  "filter_params_at_rate_hz": rec.rate_hz, "note": note}
    try:
        resp = best.response()
    except ValueError as exc:  # e.g. the steady-state Riccati recursion did not converge
        raise CliError(f"the {best.model} filter of this record: {exc}") from exc
    payload = {"record": rec.summary(), "units": {"rate": "deg/h", "q": "(deg/h)^2",
                                                   "r": "(deg/h)^2", "mean": "deg/h"},
               **cmp_.as_dict(), "decimation": decimation,
               "filter_params": list(best.filter_params), "filter": resp.as_dict()}
    if args.output:
        out = Path(args.output)
        if fmt == ".toml":
            text = config_toml(best, rec.rate_hz, _gyro_channel(args.column), rec.source,
                               fit_rate_hz=fit_rate)
        else:
            text = json_text(payload) + "\n"
        atomic_write_text(out, text)
        payload["output"] = str(out)
    # An output that is stdout itself (-o /dev/stdout) keeps stdout to itself: the table
    # (or --json) goes to stderr.
    with contextlib.redirect_stdout(human_stream(args.output)):
        _report(args, rec, cmp_, best, resp, payload, factor, fit_rate, tau_min, note)
    return 0


def _report(args: argparse.Namespace, rec: Any, cmp_: Any, best: Any, resp: Any,
            payload: dict[str, Any], factor: int, fit_rate: float, tau_min: float,
            note: str) -> None:
    if args.json:
        emit_json(payload)
        return
    print(f"# {rec.source}: {rec.n} samples at {rec.rate_hz:g} Hz, units deg/h "
          "(q, r in (deg/h)^2); ± = standard error (observed information)")
    if factor > 1:
        print(f"# fitted at {fit_rate:g} Hz: block averages of {factor} samples, chosen from "
              f"the Allan minimum at tau = {tau_min:.4g} s (the drift lives at times much "
              f"longer than a sample); the table is at {fit_rate:g} Hz, the filter below is "
              f"converted back to {rec.rate_hz:g} Hz")
    elif note:
        print(f"# {note}")
    print(f"{'model':<10} {'loglike':>14} {'AIC':>14} {'BIC':>14} {'a1':>16} {'a2':>16} "
          f"{'q':>18} {'r':>18} {'mean deg/h':>18} {'LB p':>8}")
    for f in cmp_.fits:
        se = f.stderr
        print(f"{f.model:<10} {f.loglike:14.6g} {f.aic:14.6g} {f.bic:14.6g} "
              f"{_fmt(f.a1, se['a1']):>16} {_fmt(f.a2, se['a2']):>16} {_fmt(f.q, se['q']):>18} "
              f"{_fmt(f.r, se['r']):>18} {_fmt(f.mean, se['mean']):>18} "
              f"{f.ljung_box.pvalue:8.3g}")
    print(f"chosen: {cmp_.chosen} (lowest {args.criterion.upper()})")
    if best.model != "white":
        d01, d10 = best.split_drop
        if best.identified:
            print(f"drift/white split identified (profile log-likelihood drop {d01:.3g} at "
                  f"r/q = 0.1, {d10:.3g} at r/q = 10); filter tuned by maximum likelihood")
        else:
            a1, a2, q, _ = best.filter_params
            print(f"drift/white split NOT identified (profile log-likelihood drop {d01:.3g} "
                  f"at r/q = 0.1, {d10:.3g} at r/q = 10: both < 4 or one zero, no BIC gain "
                  "over the white model, or a standard error that does not exist): the "
                  "record cannot tell "
                  f"drift from white noise; filter tuned at q = r (minimax over all splits): "
                  f"a1 {a1:.5g}, a2 {a2:.5g}, q = r = {q:.5g}")
    if math.isfinite(best.fold_loglike):
        gap = best.loglike - best.fold_loglike
        if best.ar_identified:
            print(f"a2 next to the fold a2 = 0: a second maximum across it at a2 "
                  f"{best.fold_a2:.4g}, {gap:.3g} log-likelihood units lower; the fit is the "
                  "higher one")
        else:
            print(f"AR part NOT identified: maxima on both sides of a2 = 0 (a2 {best.a2:.4g} "
                  f"and {best.fold_a2:.4g}) within {gap:.2g} log-likelihood units; the record "
                  "does not tell the sign of a2 and the standard errors describe the first "
                  "one only")
    if factor > 1:
        a1, a2, q, r = best.filter_params
        print(f"filter at {rec.rate_hz:g} Hz: a1 {a1:.6g}, a2 {a2:.6g}, q {q:.5g}, r {r:.5g} "
              f"(from the {fit_rate:g} Hz fit: poles to the power 1/{factor}, drift variance "
              f"kept, r x {factor})")
    bw = "none below Nyquist" if resp.bandwidth_hz is None else f"{resp.bandwidth_hz:.4g} Hz"
    print(f"steady-state gain K = ({resp.gain[0]:.6g}, {resp.gain[1]:.6g}), "
          f"DC gain {resp.dc_gain:.4g}, -3 dB bandwidth {bw}")
    if args.output:
        print(f"configuration written to {args.output}")
