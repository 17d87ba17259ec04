"""`gyrodrift identify`: noise model of a gyro record with units and intervals, by the IEEE
Std 952 NNLS Allan fit (with model selection, the default), GMWM (generalized method of wavelet
moments, with model selection) or the IEEE 952 slope method; one table, optional JSON and
plot."""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

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
    record_from_args,
    self_check_exit,
)
from gyrodrift.stability import DEFAULT_IDENTIFIER, NOISE_IDENTIFIERS
from gyrodrift.stability.self_check import check_lines, check_summary, fit_check_of

if TYPE_CHECKING:
    from gyrodrift.stability.gmwm import GmwmResult

__all__ = ["IDENTIFIER_OPTIONS", "format_terms", "gm_resolution_notes", "register", "run"]

#: One row of the printed table: name, value, unit, low, high, density, its unit, low, high.
Row = tuple[str, float, str, float | None, float | None, float | None, str | None,
            float | None, float | None]


def _num(v: float | None) -> str:
    return "n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.4g}"


def format_terms(rows: Sequence[Row], ci: float) -> list[str]:
    """The terms table: value and interval in IEEE Std 952 units, then the continuous-time
    density (rad/s/sqrt(Hz), rad/s^2/sqrt(Hz)) where the term has one.

    Examples
    --------
    >>> lines = format_terms([("N", 0.05, "deg/sqrt(h)", 0.049, 0.051, 1.45e-5,
    ...                        "rad/s/sqrt(Hz)", 1.43e-5, 1.48e-5)], 0.95)
    >>> lines[0]
    '# intervals: 95.00 % two-sided'
    >>> lines[2].split()[:5]
    ['N', '0.05', '0.049', '0.051', 'deg/sqrt(h)']
    """
    head = (f"{'term':<10} {'value':>11} {'ci_low':>11} {'ci_high':>11} {'unit':<14} "
            f"{'density':>11} {'ci_low':>11} {'ci_high':>11} {'density unit':<16}")
    lines = [f"# intervals: {100 * ci:.2f} % two-sided", head]
    for name, val, unit, lo, hi, dens, dunit, dlo, dhi in rows:
        lines.append(f"{name:<10} {_num(val):>11} {_num(lo):>11} {_num(hi):>11} {unit:<14} "
                     f"{_num(dens):>11} {_num(dlo):>11} {_num(dhi):>11} {dunit or '':<16}")
    return lines


def register(subparsers: Any) -> None:
    """Add the ``identify`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["identify", "gyro.csv", "--identifier", "gmwm"])
    >>> args.identifier, args.model, args.bootstrap
    ('gmwm', None, None)
    """
    p = subparsers.add_parser("identify", help="noise model with intervals (GMWM, Allan fit)",
                              description=__doc__)
    add_input_args(p)
    p.add_argument("--identifier", choices=NOISE_IDENTIFIERS, default=DEFAULT_IDENTIFIER,
                   help="noise identifier: allan-nnls (IEEE 952 weighted NNLS fit of the Allan "
                        "variance with term selection), gmwm (generalized method of wavelet "
                        "moments, with model selection) or slope (IEEE 952 slope read-offs) "
                        f"(default {DEFAULT_IDENTIFIER})")
    # Identifier-specific options default to None so that run() can refuse one given to an
    # identifier that would ignore it; their working defaults are in IDENTIFIER_OPTIONS.
    p.add_argument("--model",
                   help="gmwm: 'auto' (WIC selection, the default) or terms joined by '+' from "
                        "Q, N, K, R, GM (GM up to 3 times), e.g. Q+N+GM+K")
    p.add_argument("--max-model",
                   help="gmwm --model auto: the largest model considered (default "
                        "Q+N+K+R+GM+GM)")
    p.add_argument("--bootstrap", type=int,
                   help="gmwm: parametric-bootstrap replicates for the intervals (default 0: "
                        "asymptotic)")
    p.add_argument("--seed", type=int, help="gmwm: bootstrap seed (default 0)")
    p.add_argument("--fit-range",
                   help="allan-nnls: the taus fitted; gmwm: the scales tau_j = 2^j dt fitted; "
                        "TMIN:TMAX in s (either side may be empty)")
    p.add_argument("--terms", help="allan-nnls: IEEE 952 terms the fit may use, comma-separated "
                   f"(default {DEFAULT_FIT_TERMS})")
    p.add_argument("--no-select", action="store_true", default=None,
                   help="allan-nnls: keep every term the NNLS gives a non-zero value")
    add_ci_arg(p)
    p.add_argument("--png", help="plot: wavelet variance (gmwm) or Allan deviation with the fit")
    add_self_check_arg(p)
    add_json_arg(p)
    add_progress_arg(p)
    p.set_defaults(func=run)


#: option -> (the identifiers that use it, its value when not given)
IDENTIFIER_OPTIONS: dict[str, tuple[tuple[str, ...], object]] = {
    "model": (("gmwm",), "auto"),
    "max_model": (("gmwm",), "Q+N+K+R+GM+GM"),
    "bootstrap": (("gmwm",), 0),
    "seed": (("gmwm",), 0),
    "terms": (("allan-nnls",), DEFAULT_FIT_TERMS),
    "no_select": (("allan-nnls",), False),
    "fit_range": (("gmwm", "allan-nnls"), None),
}


def _check_identifier_options(args: argparse.Namespace) -> None:
    """Refuse an option the chosen identifier would ignore (a fit of other terms or models than
    asked for, printed without a word), then fill in the defaults of the unset ones."""
    for name, (identifiers, default) in IDENTIFIER_OPTIONS.items():
        if getattr(args, name) is None:
            setattr(args, name, default)
        elif args.identifier not in identifiers:
            raise CliError(f"--{name.replace('_', '-')} applies to --identifier "
                           f"{' and '.join(identifiers)}, not {args.identifier}")


def gm_resolution_notes(res: GmwmResult) -> list[str]:
    """Notes for each Gauss-Markov term whose correlation time lies below the smallest fitted
    scale (the fit allows T_c down to an eighth of it).

    At scales above T_c a Gauss-Markov process looks like white noise (its Haar wavelet
    variance tends to 2 sigma^2 T_c / tau), so sigma and T_c are not separately resolved there
    and the same data are about as well described with N in the GM's place.

    Examples
    --------
    >>> import numpy as np
    >>> from gyrodrift.stability.gmwm import identify_gmwm
    >>> x = np.random.default_rng(1).normal(0.0, 10.0, 1 << 13)
    >>> gm_resolution_notes(identify_gmwm(x, 100.0, model="N"))
    []
    """
    lo = float(min(res.tau_s))
    names = {p.name for p in res.params}
    return [f"GM{k}: T_c {res.value(f'GM{k}_tau'):.4g} s lies below the smallest fitted scale "
            f"{lo:.4g} s: over the fitted scales it acts much like white noise, sigma and T_c "
            f"are not separately resolved; compare the model with N in its place"
            for k in (1, 2, 3) if f"GM{k}_tau" in names and res.value(f"GM{k}_tau") < lo]


def _print_check(chk: Any) -> None:
    print(check_summary(chk))
    for line in check_lines(chk):
        print(line)


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift identify``; returns the exit code.

    Examples
    --------
    The IEEE 952 Allan fit of a white-noise record (1 deg/h per sample at 100 Hz):

    >>> import os, tempfile, numpy as np
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory(); rec = os.path.join(tmp.name, "gyro.npy")
    >>> np.save(rec, np.random.default_rng(0).normal(0.0, 1.0, 4096))
    >>> run(p.parse_args(["identify", rec, "--rate-hz", "100", "--gyro-units", "deg/h"]))
    # .../gyro.npy: 4096 samples at 100 Hz, rate in deg/h
    ...
    N             0.001666 ... deg/sqrt(h) ...
    ...
    0
    >>> tmp.cleanup()
    """
    import numpy as np

    check_output(args.png, "--png")  # before the work
    # A memory-mapped .npy record is streamed from its file (bounded memory): the Allan
    # deviation, and GMWM's wavelet variance through it.
    rec = record_from_args(args)
    x = (rec.rate_deg_h if isinstance(rec.rate_deg_h, np.memmap)
         else np.asarray(rec.rate_deg_h, dtype=np.float64))
    head = (f"# {rec.source}: {rec.n} samples at {rec.rate_hz:g} Hz, rate in deg/h"
            + (f", {rec.n_dropped} NaN/Inf samples dropped" if rec.n_dropped else ""))
    # the slope method reads its lines off the whole curve: a range would be ignored
    _check_identifier_options(args)
    if args.identifier == "slope" and args.self_check:
        raise CliError("--self-check applies to --identifier allan-nnls and gmwm (the slope "
                       "read-offs fit no model to check)")
    if args.identifier == "gmwm":
        from gyrodrift.stability.allan_fit import parse_fit_range
        from gyrodrift.stability.gmwm import identify_gmwm

        try:
            tau_range = None if args.fit_range is None else parse_fit_range(args.fit_range)
            res = identify_gmwm(x, rec.rate_hz, model=args.model, max_model=args.max_model,
                                ci=args.ci, bootstrap=args.bootstrap, seed=args.seed,
                                tau_range=tau_range)
        except ValueError as exc:
            raise CliError(str(exc)) from exc
        if args.png:
            from gyrodrift.report.plots import plot_gmwm

            plot_gmwm(res, args.png, label=rec.source)
        notes = gm_resolution_notes(res)
        chk = fit_check_of(res)
        if args.json:
            emit_json({"record": rec.summary(), "method": "gmwm", "gmwm": res.as_dict(),
                       "self_check": chk.as_dict(), "notes": notes,
                       "files": {"png": args.png}})
            return self_check_exit(args, [("", chk)])
        print(head)
        print(f"GMWM model {res.model} ({res.ci_method} intervals; J = {res.objective:.4g}"
              + ("" if res.wic is None else f", WIC = {res.wic:.4g}") + ")")
        rows: list[Row] = [(p.name, p.value, p.unit, p.ci_low, p.ci_high, p.density,
                            p.density_unit, p.density_ci_low, p.density_ci_high)
                           for p in res.params]
        print("\n".join(format_terms(rows, res.ci)))
        if res.candidates:
            print("candidates (WIC): " + ", ".join(f"{m} {w:.4g}" for m, w in
                                                    res.candidates[:6]))
        print("".join(f"# note: {n}\n" for n in notes), end="")
        _print_check(chk)
        return self_check_exit(args, [("", chk)])
    from gyrodrift.stability.allan import oadev

    try:
        allan = oadev(x, rec.rate_hz, taus="octave", ci=args.ci)
    except ValueError as exc:
        raise CliError(str(exc)) from exc
    if args.identifier == "allan-nnls":
        from gyrodrift.stability.allan_fit import fit_allan

        try:
            fit = fit_allan(allan.tau_s, allan.adev, allan.edf, terms=args.terms,
                            fit_range=args.fit_range, select=not args.no_select, ci=args.ci,
                            n_samples=allan.n_samples, rate_hz=allan.rate_hz)
        except ValueError as exc:
            raise CliError(str(exc)) from exc
        if args.png:
            from gyrodrift.report.plots import plot_allan_fit

            plot_allan_fit(allan, fit, args.png, label=rec.source)
        chk = fit_check_of(fit, allan)
        if args.json:
            emit_json({"record": rec.summary(), "method": "allan-nnls", "fit": fit.as_dict(),
                       "self_check": chk.as_dict(), "files": {"png": args.png}})
            return self_check_exit(args, [("", chk)])
        print(head)
        print(f"IEEE 952 Allan fit, taus {fit.tau_min_s:g}..{fit.tau_max_s:g} s; dropped "
              f"(no IC gain): {', '.join(fit.dropped) or 'none'}")
        rows = [(t.name, t.value, t.unit, t.ci_low, t.ci_high, t.density, t.density_unit,
                 t.density_ci_low, t.density_ci_high) for t in fit.terms]
        print("\n".join(format_terms(rows, fit.ci)))
        print("\n".join(f"# {line}" for line in fit.notes()))
        _print_check(chk)
        return self_check_exit(args, [("", chk)])
    # slope method: read-offs with the interval of the Allan deviation at the read tau
    from gyrodrift.stability.allan_fit import slope_readouts

    rows = slope_readouts(allan)
    if args.png:
        from gyrodrift.report.plots import plot_allan

        plot_allan([(rec.source, allan)], args.png)
    if args.json:
        emit_json({"record": rec.summary(), "method": "slope",
                   "terms": [dict(zip(("name", "value", "unit", "ci_low", "ci_high", "density",
                                       "density_unit", "density_ci_low", "density_ci_high"),
                                      r, strict=True)) for r in rows],
                   "ci": args.ci, "files": {"png": args.png}})
        return 0
    print(head)
    print("IEEE 952 slope method (line read-offs; interval = the Allan deviation's at the "
          "read tau)")
    print("\n".join(format_terms(rows, args.ci)))
    return 0
