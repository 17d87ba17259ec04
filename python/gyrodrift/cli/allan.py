"""`gyrodrift allan`: overlapping Allan deviation table with confidence intervals, identified
noise terms (IEEE Std 952 NNLS, the 2006 paper's 3-term fit, slope method) and a PNG plot."""

from __future__ import annotations

import argparse
from typing import Any

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    add_ci_arg,
    add_input_args,
    add_json_arg,
    add_progress_arg,
    emit_json,
    progress_enabled,
    record_from_args,
    write_csv,
)

__all__ = ["register", "run"]


def register(subparsers: Any) -> None:
    """Add the ``allan`` subcommand."""
    p = subparsers.add_parser("allan", help="overlapping Allan deviation, noise terms, plot",
                              description=__doc__)
    add_input_args(p)
    p.add_argument("--taus", choices=("octave", "decade", "all"), default="octave",
                   help="averaging times: octave (m = 1, 2, 4, ...), decade (--per-decade "
                        "points per decade) or all (every m; slow on long records)")
    p.add_argument("--per-decade", type=int, default=10, help="points per decade (--taus decade)")
    add_ci_arg(p)
    p.add_argument("--noise-id", choices=("slope", "acf"), default="slope",
                   help="noise type per tau for the edf: local slope (default) or the lag-1 "
                        "autocorrelation method (loads the record into memory)")
    p.add_argument("--png", help="write a log-log plot with error bars and the fitted terms")
    p.add_argument("--csv", dest="csv_out", help="write the tau table as CSV")
    add_json_arg(p)
    add_progress_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift allan``; returns the exit code."""
    from gyrodrift import noise_id
    from gyrodrift.allan import oadev

    rec = record_from_args(args)
    # auto: a bar for long records, and only on a terminal.
    show = progress_enabled(args)
    progress: bool | str = "auto" if show and args.progress == "auto" else show
    try:
        res = oadev(rec.rate_deg_h, rec.rate_hz, taus=args.taus, per_decade=args.per_decade,
                    ci=args.ci, progress=progress,
                    alpha="acf" if args.noise_id == "acf" else None)
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    # The fits need positive deviations (a zero can occur on exactly periodic or quantized
    # data at some taus); they use the positive points and need enough of them.
    pos = res.adev > 0
    tau, dev, edf = res.tau_s[pos], res.adev[pos], res.edf[pos]
    fit = noise_id.identify(tau, dev, edf) if tau.size >= 5 else None
    paper = noise_id.paper_fit(tau, dev) if tau.size >= 3 else None
    slope = noise_id.slope_method(tau, dev) if tau.size >= 3 else None
    if args.png:
        from gyrodrift.plots import plot_allan

        plot_allan([(rec.source, res)], args.png, fit=fit)
    if args.csv_out:
        write_csv(args.csv_out,
                  ["tau_s", "m", "adev_deg_h", "ci_low_deg_h", "ci_high_deg_h", "edf", "terms"],
                  [res.tau_s, res.m, res.adev, res.ci_low, res.ci_high, res.edf, res.terms])
    if args.json:
        emit_json({"record": rec.summary(), "allan": res.as_dict(),
                   "ieee952": None if fit is None else fit.as_dict(),
                   "paper_fit": None if paper is None else paper.as_dict(),
                   "slope_method": None if slope is None else slope.as_dict(),
                   "files": {"png": args.png, "csv": args.csv_out}})
        return 0
    print(f"# {rec.source}: {rec.n} samples at {rec.rate_hz:g} Hz"
          + (f", {rec.n_dropped} NaN/Inf samples dropped" if rec.n_dropped else ""))
    print(f"{'tau_s':>12} {'adev_deg_h':>12} {'ci_low':>12} {'ci_high':>12} {'edf':>10}")
    for t, a, lo, hi, e in zip(res.tau_s, res.adev, res.ci_low, res.ci_high, res.edf,
                               strict=True):
        print(f"{t:12.5g} {a:12.5g} {lo:12.5g} {hi:12.5g} {e:10.4g}")
    if fit is not None:
        print(f"IEEE 952 fit: Q = {fit.q_arcsec:.4g} arcsec ({fit.q_deg:.4g} deg), "
              f"N = {fit.n_deg_rt_h:.4g} deg/sqrt(h), B = {fit.b_deg_h:.4g} deg/h, "
              f"K = {fit.k_deg_h_rt_h:.4g} deg/h/sqrt(h), R = {fit.r_deg_h2:.4g} deg/h/h")
    if paper is not None:
        print(f"paper 2006 eq. 8 fit: Q = {paper.q_paper:.4g} (paper's 'deg' column; "
              f"= arcsec), N = {paper.n_deg_rt_h:.4g} deg/sqrt(h), B = {paper.b_deg_h:.4g} deg/h")
    if slope is not None:
        print("slope method: " + ", ".join(
            f"{k} = {'n/a' if v is None else f'{v:.4g}'}" for k, v in slope.as_dict().items()))
    return 0
