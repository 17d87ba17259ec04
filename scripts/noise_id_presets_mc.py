#!/usr/bin/env python3
"""Monte Carlo of the default noise identification (the IEEE 952 Allan fit) on the realistic,
misspecified presets of `gyrodrift.simulation.presets`: accuracy of N, K and the fitted B
against the generating values, of the datasheet read-off against the true curve's minimum,
the coverage of the intervals, the misfit flag rate and the automatic fit ranges.

    PYTHONPATH=python:build/dev-NAME/py python scripts/noise_id_presets_mc.py \\
        [--records 100] [--length 1.0] [--preset NAME ...] [--seed0 0] [--ci 0.95] [--jobs 1]

Seeds seed0, seed0 + 1, ... (fixed: the same command gives the same table; seeds 1000..1099
were used while developing the intervals, 2000..2099 for the validation table). --length
scales each preset's default record length. The fit gets the record's length and rate (the
sampling covariance of its intervals), as `gyrodrift allan`, `identify` and `characterize`
do. tests/test_noise_presets.py runs a small version with
thresholds; docs/validation/noise-identification.md holds the full run.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass, field

import numpy as np
from gyrodrift.simulation.presets import PRESETS, simulate_preset
from gyrodrift.stability.allan import oadev
from gyrodrift.stability.allan_fit import AllanFit, fit_allan


@dataclass
class Tally:
    """Per-preset results of the Monte Carlo."""

    n_ratio: list[float] = field(default_factory=list)
    n_cover: list[bool] = field(default_factory=list)
    b_ratio: list[float] = field(default_factory=list)      # fitted B / generating B (0: dropped)
    b_cover: list[bool] = field(default_factory=list)       # fitted B interval holds generating B
    ro_ratio: list[float] = field(default_factory=list)     # read-off / true-curve read-off
    ro_cover: list[bool] = field(default_factory=list)
    k_ratio: list[float] = field(default_factory=list)      # identified K / generating K
    k_cover: list[bool] = field(default_factory=list)
    k_limit_holds: list[bool] = field(default_factory=list)  # upper limit >= generating K
    # standardised squared errors (log(estimate / truth) / se_log)^2, se_log = log(high /
    # value) / 1.96: about 1 on average for honest intervals, far below 1 for inflated ones
    z2: dict[str, list[float]] = field(default_factory=lambda: {"N": [], "B": []})
    approximate: list[bool] = field(default_factory=list)
    n_used: list[int] = field(default_factory=list)
    tau_lo: list[float] = field(default_factory=list)
    tau_hi: list[float] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)


def _z2(value: float, high: float, truth: float) -> float:
    se_log = math.log(high / value) / 1.96
    return (math.log(value / truth) / se_log) ** 2 if se_log > 0 else math.inf


def run_one(name: str, n: int, seed: int, ci: float) -> tuple[AllanFit, object, float]:
    """Simulate one record, fit it; returns the fit, the truth and the fit's wall time."""
    rec = simulate_preset(name, n, seed)
    r = oadev(rec.gyro_deg_h, rec.rate_hz, progress=False, ci=ci, threads=1)
    t0 = time.perf_counter()
    fit = fit_allan(r.tau_s, r.adev, r.edf, ci=ci, n_samples=r.n_samples, rate_hz=r.rate_hz)
    return fit, rec.truth, time.perf_counter() - t0


def _run_star(a: tuple[str, int, int, float]) -> tuple[AllanFit, object, float]:
    return run_one(*a)


def tally(name: str, n: int, seeds: range, ci: float, jobs: int = 1) -> tuple[Tally, object]:
    """Run the records of one preset (``jobs`` worker processes; the result does not depend
    on it: each record is simulated from its own seed)."""
    out = Tally()
    truth = None
    args = [(name, n, seed, ci) for seed in seeds]
    if jobs > 1:
        import multiprocessing

        with multiprocessing.get_context("fork").Pool(jobs) as pool:
            results = pool.map(_run_star, args, chunksize=1)
    else:
        results = [run_one(*a) for a in args]
    for fit, truth, sec in results:
        t = truth
        out.seconds.append(sec)
        out.approximate.append(fit.approximate)
        out.n_used.append(int(fit.fit_used.sum()))
        out.tau_lo.append(fit.tau_min_s)
        out.tau_hi.append(fit.tau_max_s)
        if "N" in fit.names:
            nt = fit.term("N")
            out.n_ratio.append(nt.value / t.n_deg_rt_h)  # type: ignore[attr-defined]
            out.n_cover.append(nt.ci_low <= t.n_deg_rt_h <= nt.ci_high)  # type: ignore[attr-defined]
            out.z2["N"].append(_z2(nt.value, nt.ci_high, t.n_deg_rt_h))  # type: ignore[attr-defined]
        else:
            out.n_ratio.append(0.0)
            out.n_cover.append(False)
        if "B" in fit.names:
            bt = fit.term("B")
            out.b_ratio.append(bt.value / t.b_deg_h)  # type: ignore[attr-defined]
            out.b_cover.append(bt.ci_low <= t.b_deg_h <= bt.ci_high)  # type: ignore[attr-defined]
            out.z2["B"].append(_z2(bt.value, bt.ci_high, t.b_deg_h))  # type: ignore[attr-defined]
        else:
            out.b_ratio.append(0.0)
            out.b_cover.append(False)
        out.ro_ratio.append(fit.b_readoff / t.b_min_deg_h)  # type: ignore[attr-defined]
        out.ro_cover.append(
            fit.b_readoff_ci_low <= t.b_min_deg_h <= fit.b_readoff_ci_high)  # type: ignore[attr-defined]
        k_true = t.k_deg_h_rt_h  # type: ignore[attr-defined]
        if "K" in fit.upper_limits:
            out.k_limit_holds.append(fit.upper_limits["K"] >= k_true)
        elif "K" in fit.names:
            kt = fit.term("K")
            out.k_ratio.append(kt.value / k_true)
            out.k_cover.append(kt.ci_low <= k_true <= kt.ci_high)
    return out, truth


def _q(v: list[float]) -> str:
    if not v:
        return "-"
    a = np.asarray(v)
    return f"{np.median(a):.3f} [{np.percentile(a, 5):.2f}, {np.percentile(a, 95):.2f}]"


def _pct(v: list[bool]) -> str:
    return "-" if not v else f"{100.0 * np.mean(v):.0f} % ({len(v)})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--records", type=int, default=100, help="records per preset")
    ap.add_argument("--length", type=float, default=1.0,
                    help="factor on each preset's default record length")
    ap.add_argument("--preset", action="append", choices=list(PRESETS), help="presets to run")
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--ci", type=float, default=0.95)
    ap.add_argument("--jobs", type=int, default=1, help="worker processes")
    args = ap.parse_args()
    names = args.preset or list(PRESETS)
    t_start = time.perf_counter()
    print(f"# {args.records} records per preset, {args.ci:.0%} intervals, seeds "
          f"{args.seed0}..{args.seed0 + args.records - 1}")
    print("| preset | samples | N ratio | N cover | fitted B ratio | B kept | B cover "
          "| read-off ratio | read-off cover | K identified | K ratio | K cover "
          "| K limit holds | approximate | true read-off / B (tau) |")
    print("|" + " --- |" * 15)
    for name in names:
        n = max(1024, round(PRESETS[name].default_n_samples * args.length))
        res, truth = tally(name, n, range(args.seed0, args.seed0 + args.records), args.ci,
                           args.jobs)
        kept_b = [x for x in res.b_ratio if x > 0]
        cover_b = [c for c, x in zip(res.b_cover, res.b_ratio, strict=True) if x > 0]
        t = truth
        print(f"| {name} | {n} | {_q(res.n_ratio)} | {_pct(res.n_cover)} | {_q(kept_b)} "
              f"| {_pct([x > 0 for x in res.b_ratio])} | {_pct(cover_b)} "
              f"| {_q(res.ro_ratio)} | {_pct(res.ro_cover)} "
              f"| {len(res.k_ratio)}/{args.records} | {_q(res.k_ratio)} | {_pct(res.k_cover)} "
              f"| {_pct(res.k_limit_holds)} | {_pct(res.approximate)} "
              f"| {t.b_min_deg_h / t.b_deg_h:.3f} ({t.tau_b_min_s:.4g} s) |")  # type: ignore[attr-defined]
        print(f"#   {name}: fitted taus {np.median(res.n_used):.0f} (median), range "
              f"{np.median(res.tau_lo):.3g}..{np.median(res.tau_hi):.3g} s (median ends); "
              f"fit {1e3 * np.median(res.seconds):.0f} ms per record (median)")
    print(f"# total {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    main()
