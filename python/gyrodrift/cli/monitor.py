"""`gyrodrift monitor`: run the gyro monitor the target runs over a record, sample by sample
through the C++ core in the target's float state: streaming Allan statistics, online noise
estimates (N, B, K with intervals), online re-identification of the drift model with its
retuned Kalman gain, and latched health alarms. One report per --report-every-s: a table, or
JSON lines (--json).

The alarms compare against a reference model: the configuration's (--config: the gyro
channel's ar2_kalman stage, and the monitor settings of the configuration file), or, without
--config, the model identified from the first --learn-s seconds of the record (the drift
model as `gyrodrift fit` identifies it, the Allan variance as `gyrodrift allan` fits it).
--reidentify recursive|lag re-identifies the drift model online with that method (default:
as the configuration's monitor section says; off without --config). --png plots the online
estimates over time beside the offline fit (`gyrodrift allan`'s default fit) of the whole
record and of each half, with the alarms. --fail-on-alarm makes the exit code 3 when an alarm
was raised.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from typing import Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    add_input_args,
    check_output,
    emit_json_line,
    record_from_args,
)
from gyrodrift.errors import GyrodriftError
from gyrodrift.imu.schema import IDENTIFIERS
from gyrodrift.units import DPH

__all__ = ["ALARM_EXIT", "register", "run"]

#: Exit code of ``--fail-on-alarm`` when an alarm was raised (the outputs are written first).
ALARM_EXIT = 3
#: The span the reference is learned from without --config, s.
DEFAULT_LEARN_S = 600.0


def register(subparsers: Any) -> None:
    """Add the ``monitor`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["monitor", "gyro.npy", "--rate-hz", "100", "--gyro-units",
    ...                      "deg/h"])
    >>> args.learn_s, args.report_every_s, args.channel, args.fail_on_alarm, args.reidentify
    (600.0, None, None, False, None)
    """
    p = subparsers.add_parser("monitor", help="online noise estimates, drift re-identification "
                              "and health alarms over a record, as the target runs them",
                              description=__doc__.split("\n\n")[0])
    add_input_args(p)
    p.add_argument("--config", metavar="FILE",
                   help="processor configuration file: the gyro channel's ar2_kalman stage is "
                        "the reference model, its monitor section the settings (default: learn "
                        "the reference from the first --learn-s seconds)")
    p.add_argument("--channel", choices=("gx", "gy", "gz"),
                   help="the configuration's gyro channel whose model is the reference "
                        "(default: the axis letter of --column, else gx)")
    p.add_argument("--learn-s", type=float, default=DEFAULT_LEARN_S,
                   help="without --config: seconds at the start of the record the reference "
                        f"model is identified from (default {DEFAULT_LEARN_S:g}; the record "
                        "must be longer than this plus one report interval)")
    p.add_argument("--reidentify", choices=IDENTIFIERS, default=None,
                   help="re-identify the drift model online and retune the filter gain with "
                        "this method: recursive (a recursive estimator updated every block; "
                        "with the configuration's memory_s it follows a change, but it does not "
                        "settle on the offline maximum-likelihood fit on every record) or lag "
                        "(whole-record lag statistics and their maximum-likelihood fit every "
                        "retune_s: converges to the offline fit of the samples seen). Default: "
                        "the configuration's [monitor] reidentify and identifier; off without "
                        "--config")
    p.add_argument("--report-every-s", type=float, default=None,
                   help="seconds between two reports (one table row or JSON line each; "
                        "default: the monitor settings' report_interval_s, 10 s unless the "
                        "configuration says otherwise)")
    p.add_argument("--png", help="write a plot of the online N, B and K over time with their "
                                 "intervals, beside the offline fit of the whole record and of "
                                 "each half, with the time each alarm was raised")
    p.add_argument("--fail-on-alarm", action="store_true",
                   help=f"exit with code {ALARM_EXIT} (after writing every output) when a "
                        "health alarm was raised")
    p.add_argument("--json", action="store_true",
                   help="print JSON lines on stdout, one JSON object per report (no table)")
    p.set_defaults(func=run)


def _channel(args: argparse.Namespace) -> str:
    if args.channel:
        return str(args.channel)
    c = (args.column or "").strip().lower()
    return f"g{c[-1]}" if c and c[-1] in "xyz" else "gx"


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift monitor``; returns the exit code.

    Examples
    --------
    The monitor over 30 s of an AR(2) drift (a1 0.6, a2 0.2) under white noise, deg/h at
    100 Hz, the reference learned from the first 20 s, a report every 5 s:

    >>> import os, tempfile, numpy as np
    >>> from scipy.signal import lfilter
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory(); rec = os.path.join(tmp.name, "gyro.npy")
    >>> rng = np.random.default_rng(1)
    >>> np.save(rec, lfilter([1.0], [1.0, -0.6, -0.2], rng.normal(0, 1, 3000))
    ...         + rng.normal(0, 0.5, 3000))
    >>> run(p.parse_args(["monitor", rec, "--rate-hz", "100", "--gyro-units", "deg/h",
    ...                   "--learn-s", "20", "--report-every-s", "5"]))
    # .../gyro.npy: 3000 samples at 100 Hz, channel gx; reference learned from 0..20 s
    ...
         30 ...
    health: no alarm raised
    0
    >>> tmp.cleanup()
    """
    from gyrodrift.imu.config import MonitorConfig
    from gyrodrift.imu.monitor import run_monitor

    for flag, value in (("--learn-s", args.learn_s), ("--report-every-s", args.report_every_s)):
        if value is not None and not (math.isfinite(value) and value > 0.0):
            raise CliError(f"{flag} {value:g}: give a positive number of seconds")
    check_output(args.png, "--png")
    cfg = None
    if args.config is not None:
        from gyrodrift.imu.config import load_config

        try:
            cfg = load_config(args.config)
        except GyrodriftError as exc:
            raise CliError(f"{args.config}: {exc}") from exc
    settings = cfg.monitor if cfg is not None else MonitorConfig()
    if args.reidentify is not None:
        settings = replace(settings, reidentify=True, identifier=args.reidentify)
    every_s = settings.report_interval_s if args.report_every_s is None else args.report_every_s
    rec = record_from_args(args, mmap=False)
    if settings.reidentify:  # one gyro: its fit applied within one retune interval
        try:
            settings.check_fit_delay(rec.rate_hz, 1)
        except GyrodriftError as exc:
            raise CliError(f"{args.config or rec.source}: {exc}") from exc
    channel = _channel(args)
    y = np.asarray(rec.rate_deg_h, dtype=np.float64) * DPH
    duration_s = rec.n / rec.rate_hz
    if duration_s < every_s:
        raise CliError(f"{rec.source}: the record ({duration_s:.6g} s) is shorter than one "
                       f"report interval ({every_s:g} s)")
    reference = _reference(args, cfg, channel, y, rec.rate_hz, rec.source, duration_s,
                           every_s, settings.octaves)
    checks: dict[str, Any] = {}
    if cfg is not None:  # the processor's per-sample checks of this channel
        checks = {"saturation": cfg.channel(channel).saturation,
                  "stuck_samples": cfg.channel(channel).stuck_samples}
    try:
        trace = run_monitor(y, rec.rate_hz, reference, settings=settings,
                            report_every_s=every_s, dtype=np.float32, **checks)
    except GyrodriftError as exc:
        raise CliError(f"{rec.source}: {exc}") from exc
    from gyrodrift.report.monitor import first_alarms, trace_rows

    rows = trace_rows(trace)
    alarms = first_alarms(trace)
    if args.png:
        from gyrodrift.report.monitor import plot_monitor, segment_fits

        half = duration_s / 2.0
        whole, *halves = segment_fits(y, rec.rate_hz, [(0.0, duration_s), (0.0, half),
                                                       (half, duration_s)])
        plot_monitor(trace, args.png, fits=halves, fits_label="offline fit, each half",
                     whole=whole, learn_s=reference.learn_s if reference.source == "learned"
                     else 0.0, title=f"gyrodrift monitor: {rec.source} {channel}")
    if args.json:
        for row in rows:
            emit_json_line(row)
    else:
        _print_text(rec, channel, reference, rows, alarms, trace)
    if args.fail_on_alarm and alarms:
        print(f"gyrodrift monitor: alarm raised: {', '.join(alarms)}", file=sys.stderr)
        return ALARM_EXIT
    return 0


def _reference(args: argparse.Namespace, cfg: Any, channel: str, y: np.ndarray,
               rate_hz: float, source: str, duration_s: float, every_s: float,
               octaves: int) -> Any:
    """The reference model: the configuration's, or learned from the first --learn-s s."""
    from gyrodrift.imu.monitor import reference_from_config, reference_from_record

    if cfg is not None:
        cfg_rate = float(cfg.timing.sample_rate_hz)
        if not math.isclose(cfg_rate, rate_hz, rel_tol=1e-6):
            raise CliError(f"{args.config}: the configuration is for {cfg_rate:g} Hz, the record "
                           f"is sampled at {rate_hz:g} Hz (its drift model is per sample)")
        try:
            return reference_from_config(cfg, channel)
        except GyrodriftError as exc:
            raise CliError(f"{args.config}: {exc}") from exc
    if duration_s < args.learn_s + every_s:
        raise CliError(f"{source}: the record ({duration_s:.6g} s) is shorter than the learning "
                       f"span plus one report interval ({args.learn_s:g} + {every_s:g} s): "
                       "give a shorter --learn-s, or --config")
    try:
        return reference_from_record(y, rate_hz, args.learn_s, octaves)
    except GyrodriftError as exc:
        raise CliError(f"{source}: {exc}") from exc


def _fmt_term(row: dict[str, Any], name: str, unit: str) -> str:
    v, lo, hi = (row[f"{name}_{p}{unit}"] for p in ("", "lo_", "hi_"))
    if name == "k" and row["k_upper_limit"]:
        return f"< {hi:.3g}" if hi is not None else "-"
    if v is None:
        return "-"
    if lo is None or hi is None:
        return f"{v:.3g}"
    return f"{v:.3g} [{lo:.3g}, {hi:.3g}]"


def _print_text(rec: Any, channel: str, reference: Any, rows: list[dict[str, Any]],
                alarms: dict[str, float], trace: Any) -> None:
    where = (f"reference learned from 0..{reference.learn_s:g} s" if reference.source == "learned"
             else "reference from the configuration")
    lag = trace.identifier == "lag"
    reid = any(r["status"] != "off" for r in rows)
    print(f"# {rec.source}: {rec.n} samples at {rec.rate_hz:g} Hz, channel {channel}; {where}")
    print("# N deg/sqrt(h), B deg/h, K deg/h/sqrt(h) with intervals; the model in use q, r "
          "(deg/h)^2; re-identification: " + (trace.identifier if reid else "off")
          + "; retunes: accepted/refused" + ("; fit: the last fit's status" if lag else ""))
    print(f"{'t (s)':>9} {'N':>28} {'B':>28} {'K':>28} {'a1':>8} {'a2':>8} {'q':>9} "
          f"{'r':>9} {'gain':>17} {'status':>14} {'retunes':>8}"
          + (f" {'fit':>15}" if lag else "") + "  health")
    for r in rows:
        gain = f"{r['gain'][0]:.3g},{r['gain'][1]:.3g}"
        retunes = f"{r.get('retunes', 0)}/{r.get('refused_retunes', 0)}"
        fit = f" {r['fit_status'] or '-':>15}" if lag else ""
        print(f"{r['t_s']:9.6g} {_fmt_term(r, 'n', 'deg_rt_h'):>28} "
              f"{_fmt_term(r, 'b', 'deg_h'):>28} {_fmt_term(r, 'k', 'deg_h_rt_h'):>28} "
              f"{r['a1']:8.4g} {r['a2']:8.4g} {r['q_deg_h_sq']:9.3g} {r['r_deg_h_sq']:9.3g} "
              f"{gain:>17} {r['status']:>14} {retunes:>8}{fit}  {','.join(r['health']) or 'ok'}")
    if not alarms:
        print("health: no alarm raised")
        return
    for name, when in alarms.items():
        trip = trace.trips.get(name, {})
        detail = ", ".join(f"{k} {v:.4g}" for k, v in trip.items()
                           if isinstance(v, (int, float)))
        print(f"alarm {name}: first raised at {when:g} s" + (f" ({detail})" if detail else ""))
