"""`gyrodrift allan`: overlapping Allan deviation table with confidence intervals, identified
noise terms (IEEE Std 952 NNLS with a fit range, term choice, model selection and an interval
on every coefficient; the 2006 paper's 3-term fit; slope method) and a PNG plot."""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    DEFAULT_FIT_TERMS,
    add_ci_arg,
    add_input_args,
    add_json_arg,
    add_progress_arg,
    add_self_check_arg,
    check_output,
    emit_json,
    progress_enabled,
    record_from_args,
    self_check_exit,
    write_csv,
)
from gyrodrift.io.atomic import atomic_output
from gyrodrift.stability.deviations import DEVIATIONS
from gyrodrift.stability.self_check import check_lines, check_summary, fit_check_of
from gyrodrift.units import ACCEL_INPUT_UNITS, DEFAULT_ACCEL_UNITS, DPH

#: Plot titles of the deviations (NIST SP 1065 names).
DEVIATION_TITLES = {"oadev": "Overlapping Allan", "mdev": "Modified Allan", "tdev": "Time",
                    "hdev": "Hadamard", "ohdev": "Overlapping Hadamard", "totdev": "Total"}

__all__ = ["ALLAN_MIN_SAMPLES", "register", "run"]

#: fewest samples the command analyses: three octave taus (m = 1, 2, 4 need 2m + 1 <= n)
ALLAN_MIN_SAMPLES = 9


def register(subparsers: Any) -> None:
    """Add the ``allan`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["allan", "gyro.csv", "--rate-hz", "100", "--taus", "decade"])
    >>> args.taus, args.taus_per_decade, round(args.ci, 4), args.deviation
    ('decade', 10, 0.6827, 'oadev')
    """
    p = subparsers.add_parser("allan", help="overlapping Allan deviation, noise terms, plot",
                              description=__doc__)
    add_input_args(p)
    p.add_argument("--can-signals", default=None, metavar="MAP",
                   help="a CAN log in your own DBC: the signal map naming the DBC and its "
                        "channel signals (gyrodrift.codecs.can_signals)")
    p.add_argument("--taus", choices=("octave", "decade", "all"), default="octave",
                   help="averaging times: octave (m = 1, 2, 4, ...), decade (--taus-per-decade "
                        "taus per decade) or all (every m; slow on long records)")
    p.add_argument("--taus-per-decade", type=int, default=10,
                   help="averaging times per decade of tau with --taus decade (default 10)")
    add_ci_arg(p)
    p.add_argument("--noise-id", choices=("acf", "slope"), default="acf",
                   help="noise type per tau for the edf: lag-1 autocorrelation where >= 30 "
                        "averages exist, local slope beyond (acf, default; the method used is "
                        "printed per tau), or the local slope everywhere (slope)")
    p.add_argument("--deviation", choices=DEVIATIONS, default="oadev",
                   help="which deviation: overlapping Allan (default), modified Allan, time, "
                        "Hadamard, overlapping Hadamard or total (NIST SP 1065); the noise-term "
                        "fits use the Allan deviation and run for oadev only")
    p.add_argument("--fit-range", metavar="TMIN:TMAX",
                   help="IEEE 952 fit: taus in s to fit (either side may be empty; default all)")
    p.add_argument("--terms", default=DEFAULT_FIT_TERMS,
                   help="IEEE 952 fit: terms the fit may use, comma-separated (default "
                        f"{DEFAULT_FIT_TERMS})")
    p.add_argument("--no-select", action="store_true",
                   help="IEEE 952 fit: no model selection (keep every term the NNLS makes "
                        "non-zero); default: terms that do not improve the information "
                        "criterion chi2 + 2 p are dropped and listed")
    p.add_argument("--png", help="write a log-log plot with error bars, the fitted total and "
                                 "each term inside the fit range")
    p.add_argument("--csv", dest="csv_out", help="write the tau table as CSV (with the fit and "
                   "its self-check per tau)")
    p.add_argument("--curve", action="store_true",
                   help="INPUT is a published Allan-deviation curve, not a record: CSV with a "
                        "header, columns tau_s, adev and optionally edf or count (clusters); "
                        "its units by --gyro-units or --accel-units; fitted with the IEEE 952 "
                        "fit and self-checked like a measured curve")
    p.add_argument("--accel-units", choices=ACCEL_INPUT_UNITS, default=DEFAULT_ACCEL_UNITS,
                   help="units of the accelerometer data of an Allan-deviation curve "
                        "(--curve): m/s^2 or g (m/s increments do not apply)")
    p.add_argument("--duration-s", type=float,
                   help="--curve without an edf or count column: the length of the record "
                        "the curve came from, s (count = duration / tau)")
    add_self_check_arg(p)
    add_json_arg(p)
    add_progress_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift allan``; returns the exit code.

    Examples
    --------
    The Allan table of a white-noise record (1 deg/h per sample at 100 Hz) and its fit, N only:

    >>> import os, tempfile, numpy as np
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory(); rec = os.path.join(tmp.name, "gyro.npy")
    >>> np.save(rec, np.random.default_rng(0).normal(0.0, 1.0, 4096))
    >>> run(p.parse_args(["allan", rec, "--rate-hz", "100", "--gyro-units", "deg/h"]))
    # .../gyro.npy: 4096 samples at 100 Hz
         tau (s)   adev (deg/h)       ci_low      ci_high        edf alpha noise_id ...
            0.01        0.99955 ...
    ...
    N             0.001666 ... deg/sqrt(h) ...
    ...
    0
    >>> tmp.cleanup()
    """
    from gyrodrift.stability.deviations import deviation

    check_output(args.png, "--png")
    check_output(args.csv_out, "--csv", (".csv",))
    if args.curve:
        return _run_curve(args)
    for flag, given in (("--accel-units", args.accel_units), ("--duration-s", args.duration_s)):
        if given is not None:
            raise CliError(f"{flag} applies to --curve (a record's accelerometer is read by "
                           "characterize)")
    rec = record_from_args(args)
    if rec.n < ALLAN_MIN_SAMPLES:
        raise CliError(f"{rec.source}: record too short for an Allan analysis: {rec.n} "
                       f"samples, at least {ALLAN_MIN_SAMPLES} needed (three octave averaging "
                       "times, m = 1, 2, 4)")
    # auto: a bar for long records, and only on a terminal.
    show = progress_enabled(args)
    progress: bool | str = "auto" if show and args.progress == "auto" else show
    dev_name = getattr(args, "deviation", "oadev")
    try:
        res = deviation(rec.rate_deg_h, rec.rate_hz, dev_name, taus=args.taus,
                        per_decade=args.taus_per_decade, ci=args.ci, progress=progress,
                        alpha="slope" if args.noise_id == "slope" else None)
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    fit, afit, paper, slope = _fits(res, dev_name, args)
    chk = None if afit is None else fit_check_of(afit, res)
    if args.png:
        from gyrodrift.report.plots import plot_allan, plot_allan_fit

        with atomic_output(args.png) as tmp:
            if afit is not None:
                plot_allan_fit(res, afit, tmp, label=rec.source)
            else:
                plot_allan([(rec.source, res)], tmp,
                           title=f"{DEVIATION_TITLES[dev_name]} deviation",
                           symbol="sigma" if dev_name == "oadev" else dev_name)
    if args.csv_out:
        nan = np.full(res.tau_s.size, np.nan)
        write_csv(args.csv_out,
                  ["tau_s", "m", "adev_deg_h", "ci_low_deg_h", "ci_high_deg_h", "edf", "terms",
                   "fit_adev_deg_h", "fit_used", "fit_ratio", "fit_passed"],
                  [res.tau_s, res.m, res.adev, res.ci_low, res.ci_high, res.edf, res.terms,
                   nan if afit is None else afit.fit_adev,
                   np.zeros(res.tau_s.size, dtype=int) if afit is None
                   else afit.fit_used.astype(int),
                   nan if chk is None else chk.ratio,
                   np.zeros(res.tau_s.size, dtype=int) if chk is None
                   else chk.passed.astype(int)])
    if args.json:
        _emit_json(rec, res, fit, afit, paper, slope, args, chk)
    else:
        _print_text(rec, res, dev_name, afit, paper, slope, chk)
    return self_check_exit(args, [] if chk is None else [("", chk)])


def _fits(res: Any, dev_name: str, args: argparse.Namespace) -> tuple[Any, Any, Any, Any]:
    """The noise-term fits of an Allan deviation: IEEE 952 NNLS on all taus, the fit with
    range, terms and selection, the 2006 paper's eq. 8 fit and the slope method (None where
    they do not apply)."""
    from gyrodrift.stability import ieee952

    # The fits need positive deviations (a zero can occur on exactly periodic or quantized
    # data at some taus); they use the positive points and need enough of them.
    pos = res.adev > 0
    tau, dev, edf = res.tau_s[pos], res.adev[pos], res.edf[pos]
    allan_fits = dev_name == "oadev"  # the IEEE 952 model is that of the Allan variance
    fit = ieee952.identify(tau, dev, edf) if allan_fits and tau.size >= 5 else None
    afit = None
    if allan_fits:
        from gyrodrift.stability.allan_fit import fit_allan

        try:
            afit = fit_allan(res.tau_s, res.adev, res.edf, terms=args.terms,
                             fit_range=args.fit_range, select=not args.no_select, ci=res.ci,
                             n_samples=res.n_samples, rate_hz=res.rate_hz)
        except ValueError as exc:
            if args.fit_range or args.terms != DEFAULT_FIT_TERMS:
                raise CliError(str(exc)) from exc
            afit = None  # too few taus for the default fit: the table is still printed
    elif args.fit_range or args.terms != DEFAULT_FIT_TERMS:
        raise CliError("--fit-range and --terms apply to the Allan fit (--deviation oadev)")
    paper = ieee952.paper_fit(tau, dev) if allan_fits and tau.size >= 3 else None
    slope = ieee952.slope_method(tau, dev) if allan_fits and tau.size >= 3 else None
    return fit, afit, paper, slope


def _emit_json(rec: Any, res: Any, fit: Any, afit: Any, paper: Any, slope: Any,
               args: argparse.Namespace, chk: Any) -> None:
    fit_adev = (afit.fit_adev if afit is not None else np.full(res.tau_s.size, np.nan))
    used = (afit.fit_used if afit is not None else np.zeros(res.tau_s.size, dtype=bool))
    ratio = chk.ratio if chk is not None else np.full(res.tau_s.size, np.nan)
    passed = chk.passed if chk is not None else np.zeros(res.tau_s.size, dtype=bool)
    taus = [{"tau_s": float(t), "adev": float(a), "ci_low": float(lo),
             "ci_high": float(hi), "fit_adev": None if np.isnan(f) else float(f),
             "fit_used": bool(u), "fit_ratio": None if np.isnan(r) else float(r),
             "fit_passed": bool(ok)}
            for t, a, lo, hi, f, u, r, ok in zip(res.tau_s, res.adev, res.ci_low, res.ci_high,
                                                 fit_adev, used, ratio, passed, strict=True)]
    emit_json({"record": rec.summary(), "allan": res.as_dict(), "taus": taus,
               "fit": None if afit is None else afit.as_dict(),
               "self_check": None if chk is None else chk.as_dict(),
               "ieee952": None if fit is None else fit.as_dict(),
               "paper_fit": None if paper is None else paper.as_dict(),
               "slope_method": None if slope is None else slope.as_dict(),
               "files": {"png": args.png, "csv": args.csv_out}})


def _print_text(rec: Any, res: Any, dev_name: str, afit: Any, paper: Any, slope: Any,
                chk: Any) -> None:
    print(f"# {rec.source}: {rec.n} samples at {rec.rate_hz:g} Hz"
          + (f", {rec.n_dropped} NaN/Inf samples dropped" if rec.n_dropped else ""))
    if rec.log_summary:
        print(f"# CAN log: {rec.log_summary}")
    unit = "deg/h s" if dev_name == "tdev" else "deg/h"  # tdev = tau mdev / sqrt(3)
    col = f"{'adev' if dev_name == 'oadev' else dev_name} ({unit})"
    print(f"{'tau (s)':>12} {col:>14} {'ci_low':>12} {'ci_high':>12} {'edf':>10} "
          f"{'alpha':>5} {'noise_id':>8} {'fit (deg/h)':>12} {'in fit':>6} {'fit/meas':>8} "
          f"{'passes':>6}")
    noise = res.noise_id if res.noise_id is not None else ["given"] * res.m.size
    for k, (t, a, lo, hi, e, al, how) in enumerate(zip(
            res.tau_s, res.adev, res.ci_low, res.ci_high, res.edf, res.alpha, noise,
            strict=True)):
        fa = "" if afit is None else f"{afit.fit_adev[k]:12.5g}"
        fu = "" if afit is None else ("yes" if afit.fit_used[k] else "no")
        fr = "" if chk is None else f"{chk.ratio[k]:8.3g}"
        fp = "" if chk is None else ("yes" if chk.passed[k] else "NO")
        print(f"{t:12.5g} {a:14.5g} {lo:12.5g} {hi:12.5g} {e:10.4g} {int(al):5d} {how:>8} "
              f"{fa:>12} {fu:>6} {fr:>8} {fp:>6}")
    if afit is not None:
        from gyrodrift.cli.identify import format_terms

        print(f"IEEE 952 fit (log-scale weighted, taus {afit.tau_min_s:g}..{afit.tau_max_s:g} "
              "s; misspecification-robust intervals)")
        print("\n".join(format_terms(
            [(t.name, t.value, t.unit, t.ci_low, t.ci_high, t.density, t.density_unit,
              t.density_ci_low, t.density_ci_high) for t in afit.terms], afit.ci)))
        print("\n".join(f"# {line}" for line in afit.notes()))
        print(check_summary(chk))
        print("\n".join(check_lines(chk)), end="\n" if chk.warnings else "")
    if paper is not None:
        print(f"paper 2006 eq. 8 fit: Q = {paper.q_paper:.4g} (paper's 'deg' column; "
              f"= arcsec), N = {paper.n_deg_rt_h:.4g} deg/sqrt(h), B = {paper.b_deg_h:.4g} deg/h")
    if slope is not None:
        print("slope method: " + ", ".join(
            f"{k} = {'n/a' if v is None else f'{v:.4g}'}" for k, v in slope.as_dict().items()))


def _run_curve(args: argparse.Namespace) -> int:
    """``allan --curve``: fit a published Allan-deviation curve like a measured one."""
    from gyrodrift.io.curves import CURVE_UNITS, read_allan_curve
    from gyrodrift.stability.allan_fit import ALLAN_TERMS, fit_allan
    from gyrodrift.stability.ieee952 import B_FLOOR_FACTOR

    if args.png:
        raise CliError("--png plots a record's deviation; with --curve use --csv or --json")
    if args.rate_hz is not None or args.deviation != "oadev" or args.column is not None:
        raise CliError("--curve reads an Allan deviation: --rate-hz, --column and --deviation "
                       "do not apply")
    given = [u for u in (args.gyro_units, args.accel_units) if u is not None]
    if len(given) != 1:
        raise CliError("--curve needs the curve's units: give --gyro-units (deg/h, deg/s, "
                       "rad/s) or --accel-units (m/s^2, g), one of them")
    if given[0] not in CURVE_UNITS:
        raise CliError(f"--curve: an Allan deviation is in a rate or acceleration unit "
                       f"({', '.join(CURVE_UNITS)}), not {given[0]}")
    try:
        curve = read_allan_curve(args.input, units=given[0], duration_s=args.duration_s)
        afit = fit_allan(curve.tau_s, curve.adev, curve.edf, terms=args.terms,
                         fit_range=args.fit_range, select=not args.no_select, ci=args.ci)
    except (OSError, ValueError) as exc:
        raise CliError(str(exc)) from exc
    chk = fit_check_of(afit, curve)
    # every term in the curve's SI unit (U = rad/s or m/s^2): N = sqrt(C_-1) U/sqrt(Hz),
    # K = sqrt(3 C_1) U/s/sqrt(Hz), B = sqrt(C_0) / 0.664 U (module docstring of allan_fit)
    to_si = DPH if curve.sensor == "gyro" else 1.0
    si_unit = "rad/s" if curve.sensor == "gyro" else "m/s^2"
    si = {"Q": (lambda c: math.sqrt(c / 3.0) * to_si, f"{si_unit} s"),
          "N": (lambda c: math.sqrt(c) * to_si, f"{si_unit}/sqrt(Hz)"),
          "B": (lambda c: math.sqrt(c) / B_FLOOR_FACTOR * to_si, si_unit),
          "K": (lambda c: math.sqrt(3.0 * c) * to_si, f"{si_unit}/s/sqrt(Hz)"),
          "R": (lambda c: math.sqrt(2.0 * c) * to_si, f"{si_unit}/s")}
    terms_si = {t.name: {"value": si[t.name][0](t.coeff), "unit": si[t.name][1],
                         "ci_low": si[t.name][0](t.coeff) * t.ci_low / t.value,
                         "ci_high": si[t.name][0](t.coeff) * t.ci_high / t.value}
                for t in afit.terms}
    assert set(terms_si) <= set(ALLAN_TERMS)
    if args.csv_out:
        write_csv(args.csv_out, ["tau_s", "adev", "edf", "fit_adev", "fit_used", "fit_ratio",
                                 "fit_passed"],
                  [curve.tau_s, curve.adev, curve.edf, afit.fit_adev,
                   afit.fit_used.astype(int), chk.ratio, chk.passed.astype(int)])
    if args.json:
        emit_json({"curve": curve.as_dict(), "fit": afit.as_dict(), "terms_si": terms_si,
                   "self_check": chk.as_dict(), "files": {"csv": args.csv_out}})
        return self_check_exit(args, [("", chk)])
    print(f"# {curve.source}: Allan-deviation curve of a {curve.sensor}, {curve.tau_s.size} "
          f"taus {curve.tau_s[0]:.4g}..{curve.tau_s[-1]:.4g} s, in {curve.units_in} "
          f"(fitted in {curve.unit}); edf from the {curve.edf_from}")
    print(f"IEEE 952 fit (weighted NNLS, taus {afit.tau_min_s:g}..{afit.tau_max_s:g} s); "
          f"dropped (no gain in chi2 + 2p): {', '.join(afit.dropped) or 'none'}")
    print(f"# intervals: {100 * afit.ci:.2f} % two-sided")
    for name, t in terms_si.items():
        print(f"{name:<4} {t['value']:12.5g} [{t['ci_low']:.4g}, {t['ci_high']:.4g}] "
              f"{t['unit']}")
    print(check_summary(chk))
    print("\n".join(check_lines(chk)), end="\n" if chk.warnings else "")
    return self_check_exit(args, [("", chk)])
