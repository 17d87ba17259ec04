"""`gyrodrift demo`: the main job on an embedded default, no input file needed.

Simulates a seeded optical-gyro rate record (IEEE Std 952 terms plus an AR(2) drift with the
2001 paper's FOG coefficients), identifies its AR(2) model, filters it with the C++ AR filter
and AR(2)-Kalman filter, and prints a before/after table in the 2006 paper's format (its
Table 1: STD, and Q, N, B from the Allan-deviation fit of its eq. 8), plus the noise
reduction. A second table is the yardstick only a simulation has: the mean squared error
against the simulated drift (everything but the white noise: constant drift, AR(2) drift, bias
instability) of the raw record and of the steady-state AR(2)-Kalman filter tuned three ways:
the papers' recipe (the AR(2) fit on the noisy record, q = sigma2, r = its one-step error),
maximum likelihood (`gyrodrift.fit_drift_model`, AR(2) + white noise) and the true model (the
simulated a1, a2, q and the white-noise variance: the optimum). `--json` prints the same
numbers as one JSON object.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import numpy as np

from gyrodrift.cli.common import add_ar_method_arg, add_json_arg, emit_json

__all__ = ["DEFAULT_TERMS", "compute", "register", "run"]

#: Demo record: a FOG-class gyro at rest, deg/h. AR(2) drift (0.6868, -0.0213) is paper 002's
#: first FOG; the Earth-rate-like bias stands for the constant drift the model keeps as mean.
DEFAULT_TERMS: dict[str, Any] = {
    "n_deg_rt_h": 0.0005,  # angle random walk, deg/sqrt(h)
    "b_deg_h": 0.02,  # bias instability, deg/h
    "bias_deg_h": 9.7,  # constant drift, deg/h
    "ar2": (0.6868, -0.0213, 0.5),  # a1, a2, sigma deg/h
}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``demo`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["demo", "--duration-s", "60"])
    >>> args.duration_s, args.rate_hz, args.seed, args.ar_method
    (60.0, 100.0, 2006, 'yule-walker')
    """
    p = subparsers.add_parser(
        "demo",
        help="simulate a gyro record, filter it with the C++ AR(2)-Kalman, print before/after",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--duration-s", type=float, default=600.0, help="record length, s (default 600)")
    p.add_argument("--rate-hz", type=float, default=100.0, help="sample rate, Hz (default 100)")
    p.add_argument("--seed", type=int, default=2006, help="simulator seed (default 2006)")
    add_ar_method_arg(p)
    p.add_argument("--kalman-q", type=float, default=None,
                   help="Kalman process variance, (deg/h)^2 (default: the fitted sigma2)")
    p.add_argument("--kalman-r", type=float, default=None,
                   help="Kalman measurement variance, (deg/h)^2 (default: the AR(2) one-step "
                        "prediction-error variance)")
    p.add_argument("--steady-state", action="store_true", help="constant-gain (DARE) Kalman")
    p.add_argument("--float32", action="store_true", help="run the filters in float32")
    add_json_arg(p)
    p.set_defaults(func=run)


def _allan_numbers(x: np.ndarray, rate_hz: float) -> dict[str, float]:
    # Overlapping ADEV (octave taus) and the 2006 paper's eq. (8) fit -> Q, N, B.
    from gyrodrift import oadev, paper_fit

    res = oadev(np.asarray(x, dtype=np.float64), rate_hz, taus="octave", progress=False)
    fit = paper_fit(res.tau_s, res.adev, res.edf)
    i1 = int(np.argmin(np.abs(res.tau_s - 1.0)))
    return {
        "adev_1s_deg_h": float(res.adev[i1]),
        "adev_min_deg_h": float(np.min(res.adev)),
        "q_arcsec": fit.q_arcsec,
        "n_deg_rt_h": fit.n_deg_rt_h,
        "b_deg_h": fit.b_deg_h,
    }


def compute(args: argparse.Namespace) -> dict[str, Any]:
    """

    Examples
    --------
    >>> import argparse
    >>> p = argparse.ArgumentParser(); register(p.add_subparsers())
    >>> r = compute(p.parse_args(["demo", "--duration-s", "60"]))
    >>> r["record"]["samples"], sorted(r["table"])
    (6000, ['AR filter', 'AR(2)-Kalman', 'raw'])
    """
    from gyrodrift import Ar2Model, ar_filter, fit_ar2, kalman_filter
    from gyrodrift.cli import CliError
    from gyrodrift.simulation.records import simulate

    if not (args.duration_s > 0 and args.rate_hz > 0):
        raise CliError("--duration-s and --rate-hz must be positive")
    rec = simulate(args.duration_s, rate_hz=args.rate_hz, seed=args.seed, keep_components=True,
                   **DEFAULT_TERMS)
    x = rec.rate_deg_h
    if x.size < 1000:
        raise CliError(f"{x.size} samples is too short for a meaningful demo (>= 1000)")
    dtype = np.float32 if args.float32 else np.float64
    try:
        model = fit_ar2(x, args.ar_method)
        assert isinstance(model, Ar2Model)  # x is 1-D: one model
        filtered = {
            "AR filter": ar_filter(x, model, dtype=dtype),
            "AR(2)-Kalman": kalman_filter(
                x, model, q=args.kalman_q, r=args.kalman_r, steady_state=args.steady_state,
                dtype=dtype,
            ),
        }
    except ValueError as exc:
        raise CliError(str(exc)) from None
    signals = {"raw": x, **filtered}
    # The first second holds the filter's start-up transient (X0 = 0, P0 = I): excluded from
    # the statistics of every column alike.
    skip = round(args.rate_hz)
    table: dict[str, dict[str, float]] = {}
    for name, sig in signals.items():
        s = np.asarray(sig[skip:], dtype=np.float64)
        row = {"mean_deg_h": float(np.mean(s)), "std_deg_h": float(np.std(s))}
        row.update(_allan_numbers(s, args.rate_hz))
        table[name] = row
    raw_std = table["raw"]["std_deg_h"]
    for row in table.values():
        row["std_reduction"] = raw_std / row["std_deg_h"] if row["std_deg_h"] > 0 else math.inf
    yardstick = _yardstick(x, rec, model, args.rate_hz, skip, dtype)
    return {
        "record": {
            "samples": int(x.size),
            "rate_hz": rec.rate_hz,
            "seed": rec.seed,
            "terms": {
                k: (list(v) if isinstance(v, tuple) else v) for k, v in DEFAULT_TERMS.items()
            },
        },
        "model": {
            "method": model.method,
            "a1": model.a1,
            "a2": model.a2,
            "sigma2_deg_h_sq": model.sigma2,
            "r_deg_h_sq": model.r,
            "mean_deg_h": model.mean,
        },
        "kalman": {
            "q_deg_h_sq": model.sigma2 if args.kalman_q is None else args.kalman_q,
            "r_deg_h_sq": model.r if args.kalman_r is None else args.kalman_r,
            "steady_state": bool(args.steady_state),
            "dtype": np.dtype(dtype).name,
        },
        "table": table,
        "yardstick": yardstick,
    }


def _yardstick(x: np.ndarray, rec: Any, papers: Any, rate_hz: float, skip: int,
               dtype: Any) -> dict[str, Any]:
    """MSE against the simulated drift, steady-state filters tuned three ways (see above)."""
    from gyrodrift import Ar2Model, DriftModelFit, fit_drift_model, kalman_filter

    white = sum(rec.components[k] for k in ("arw", "quantization") if k in rec.components)
    drift = x - white
    a1, a2, sigma = DEFAULT_TERMS["ar2"]
    r_true = float(np.var(white)) if np.ndim(white) else 0.0
    true_model = Ar2Model(a1=a1, a2=a2, sigma2=sigma**2, mean=DEFAULT_TERMS["bias_deg_h"])
    ml = fit_drift_model(x, rate_hz, "ar2+white")
    assert isinstance(ml, DriftModelFit)  # x is 1-D: one fit
    rows = {
        "raw": x,
        "papers' tuning": kalman_filter(x, papers, steady_state=True, dtype=dtype),
        "ML tuning": ml.kalman(dtype=dtype).process(x),
        "true model": kalman_filter(x, true_model, q=sigma**2, r=r_true, steady_state=True,
                                    dtype=dtype),
    }
    out: dict[str, Any] = {"ml_fit": ml.as_dict(), "true_r_deg_h_sq": r_true, "rows": {}}
    for name, sig in rows.items():
        s = np.asarray(sig[skip:], dtype=np.float64)
        row = {"mse_vs_drift_deg_h_sq": float(np.mean((s - drift[skip:]) ** 2)),
               "std_deg_h": float(np.std(s))}
        row.update(_allan_numbers(s, rate_hz))
        out["rows"][name] = row
    return out


def _print_table(result: dict[str, Any], out: Any) -> None:
    rec, m, k = result["record"], result["model"], result["kalman"]
    print(
        f"gyrodrift demo: simulated gyro at rest, {rec['samples']} samples at "
        f"{rec['rate_hz']:g} Hz (seed {rec['seed']})",
        file=out,
    )
    print(
        f"AR(2) model ({m['method']}): a1 = {m['a1']:.4f}, a2 = {m['a2']:.4f}, "
        f"sigma2 = {m['sigma2_deg_h_sq']:.4g} (deg/h)^2, mean = {m['mean_deg_h']:.4f} deg/h "
        "(AR(2) part simulated as 0.6868, -0.0213; the white noise on top lowers a1)",
        file=out,
    )
    print(
        f"AR(2)-Kalman: q = {k['q_deg_h_sq']:.4g}, r = {k['r_deg_h_sq']:.4g} (deg/h)^2, "
        f"{'steady-state gain' if k['steady_state'] else 'full Joseph-form filter'}, {k['dtype']}",
        file=out,
    )
    cols = list(result["table"])
    rows = [
        ("mean (deg/h)", "mean_deg_h", "{:.4f}"),
        ("STD (deg/h)", "std_deg_h", "{:.4f}"),
        ("ADEV at 1 s (deg/h)", "adev_1s_deg_h", "{:.4f}"),
        ("ADEV minimum (deg/h)", "adev_min_deg_h", "{:.4f}"),
        ("Q (arcsec), eq. 8 fit", "q_arcsec", "{:.4g}"),
        ("N (deg/sqrt(h)), eq. 8 fit", "n_deg_rt_h", "{:.4g}"),
        ("B (deg/h), eq. 8 fit", "b_deg_h", "{:.4g}"),
        ("STD reduction (x)", "std_reduction", "{:.2f}"),
    ]
    print("", file=out)
    print("| quantity | " + " | ".join(cols) + " |", file=out)
    print("| --- |" + " ---: |" * len(cols), file=out)
    for label, key, fmt in rows:
        cells = [fmt.format(result["table"][c][key]) for c in cols]
        print(f"| {label} | " + " | ".join(cells) + " |", file=out)
    y = result["yardstick"]
    ml = y["ml_fit"]
    print("", file=out)
    print(f"Against the simulated drift (steady-state AR(2)-Kalman; ML fit a1 = {ml['a1']:.4f}, "
          f"a2 = {ml['a2']:.4f}, q = {ml['q']:.4g}, r = {ml['r']:.4g} (deg/h)^2; true r = "
          f"{y['true_r_deg_h_sq']:.4g}):", file=out)
    print("| filter | MSE vs drift ((deg/h)^2) | STD (deg/h) | ADEV at 1 s (deg/h) | "
          "ADEV minimum (deg/h) |", file=out)
    print("| --- | ---: | ---: | ---: | ---: |", file=out)
    for name, row in y["rows"].items():
        print(f"| {name} | {row['mse_vs_drift_deg_h_sq']:.4f} | {row['std_deg_h']:.4f} | "
              f"{row['adev_1s_deg_h']:.4f} | {row['adev_min_deg_h']:.4f} |", file=out)


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift demo``; returns the exit code.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> run(p.parse_args(["demo", "--duration-s", "10"]))
    gyrodrift demo: simulated gyro at rest, 1000 samples at 100 Hz (seed 2006)
    ...
    | STD (deg/h) | 0.7604 | 0.4230 | 0.4912 |
    ...
    0
    """
    result = compute(args)
    if args.json:
        emit_json(result)
    else:
        _print_table(result, sys.stdout)
    return 0
