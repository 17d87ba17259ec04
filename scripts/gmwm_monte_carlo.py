#!/usr/bin/env python3
"""Monte Carlo evidence for GMWM: interval coverage, RMSE against the IEEE Std 952
NNLS Allan fit, and model-selection hit rate, on composite models simulated by
gyrodrift.simulation.records (100 Hz, deg/h).

    PYTHONPATH=python:build/dev-NAME/py python scripts/gmwm_monte_carlo.py [--reps 200]
        [--select-reps K] [--n 16384] [--workers 1] [--max-model Q+N+K+R+GM+GM] [--case C]
        [--lengths 14,15,16,17] [--progress]

The validation evidence in the documentation is at --n 32768 (328 s, 66 correlation
times of case 3's slowest Gauss-Markov term), 200 replicates, selection on all; --n 16384
(the default, which tests/test_gmwm.py uses) is its short-record row.

Per replicate (seed = case seed + replicate): the true model is fitted by GMWM (model=<true>,
asymptotic 95 % intervals), model="auto" selects among the sub-models of --max-model by WIC
(on the first --select-reps replicates: it costs ~50 true-model fits),
and the Allan deviation (octave taus, gyrodrift.oadev) is fitted by the IEEE 952 NNLS
(ieee952.identify, all five terms). Printed per case and parameter: the true value, the
coverage of the nominal 95 % interval, GMWM's and the Allan fit's RMSE and their ratio (the
Allan fit has no Gauss-Markov term: n/a there), and the selection hit rate.
tests/test_gmwm.py runs a smaller fixed-seed version through `run_case`.

With --lengths L1,L2,..: only the model selection, on records of 2^L samples for each L (the
same seeds, the first --reps replicates), printed as one hit-rate row per case and length with
the record length in correlation times of the case's slowest Gauss-Markov term; the coverage
and RMSE tables are not run (they are evaluated at --n only).

With --misspecified, --preset P or --k-resolution: the model selection on the misspecified
(flicker) cases, the simulator presets or the well-specified cases with a random walk, and
the K a user reads (`GmwmResult.implied()`): how often it is resolved, whether the resolved
K is within 30 % and its interval holds the generating K, and whether the upper limit
holds where it is not resolved.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

# Single-threaded BLAS before numpy loads: the fits solve 13 x 13 systems, where a threaded
# BLAS only wakes its threads (20 ms of wall time per call on a loaded 2-core machine).
# Only when run as a script (importing it, as the tests do, leaves the environment alone).
if __name__ == "__main__":
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

RATE_HZ = 100.0


@dataclass(frozen=True)
class Case:
    name: str
    model: str
    sim: dict[str, object]  # gyrodrift.simulation.records keyword arguments
    truth: dict[str, float]  # GMWM parameter name -> true value (IEEE units)
    seed: int


CASES = (
    Case("white + random walk", "N+K",
         {"n_deg_rt_h": 0.05, "k_deg_h_rt_h": 400.0},
         {"N": 0.05, "K": 400.0}, 1000),
    Case("white + quantization + Gauss-Markov + random walk", "Q+N+K+GM",
         {"q_deg": 0.3 / 3600.0, "n_deg_rt_h": 0.05, "k_deg_h_rt_h": 400.0,
          "gm": ((10.0, 0.3),)},
         {"Q": 0.3, "N": 0.05, "K": 400.0, "GM1_sigma": 10.0, "GM1_tau": 0.3}, 2000),
    Case("white + two Gauss-Markov", "N+GM+GM",
         {"n_deg_rt_h": 0.05, "gm": ((20.0, 0.1), (10.0, 5.0))},
         {"N": 0.05, "GM1_sigma": 20.0, "GM1_tau": 0.1, "GM2_sigma": 10.0, "GM2_tau": 5.0},
         3000),
)

@dataclass(frozen=True)
class Misspecified:
    """A record outside every candidate family: flicker (bias instability) noise, optionally
    passed through a moving average of `average` samples (a sensor's decimation filter; it
    leaves the spectral density at zero frequency, hence N, unchanged)."""
    name: str
    sim: dict[str, float]  # gyrodrift.simulate keyword arguments
    average: int
    n: int
    seed: int

    @property
    def truth(self) -> dict[str, float]:
        return {"N": float(self.sim.get("n_deg_rt_h", 0.0)),
                "K": float(self.sim.get("k_deg_h_rt_h", 0.0))}


MISSPECIFIED = (
    Misspecified("white + flicker + random walk", {"n_deg_rt_h": 0.3, "b_deg_h": 5.0,
                                                   "k_deg_h_rt_h": 60.0}, 1, 1 << 17, 5000),
    Misspecified("white + flicker + random walk, 2-sample average",
                 {"n_deg_rt_h": 0.3, "b_deg_h": 5.0, "k_deg_h_rt_h": 60.0}, 2, 1 << 17, 6000),
    Misspecified("ADIS16405-like: white + flicker + random walk, 2-sample average",
                 {"n_deg_rt_h": 2.0, "b_deg_h": 30.0, "k_deg_h_rt_h": 100.0}, 2, 1 << 16, 7000),
)


def misspecified_record(case: Misspecified, rep: int) -> np.ndarray:
    """Replicate rep of a misspecified case (seed case.seed + rep), deg/h."""
    import gyrodrift

    pad = case.average
    x = gyrodrift.simulate(n=case.n + pad, rate_hz=RATE_HZ, seed=case.seed + rep,
                           **case.sim).rate_deg_h  # type: ignore[arg-type]
    if case.average > 1:
        c = np.concatenate(([0.0], np.cumsum(x)))
        x = (c[case.average:] - c[:-case.average]) / case.average
    return np.asarray(x[-case.n:], dtype=np.float64)


def one_misspecified(case: Misspecified, rep: int, max_model: str = "Q+N+K+R+GM+GM"
                     ) -> dict[str, object]:
    """Model selection on one misspecified record: the selected model, the N and K it
    implies, the implied N's interval, the misfit flag."""
    from gyrodrift.stability.gmwm import identify_gmwm

    res = identify_gmwm(misspecified_record(case, rep), RATE_HZ, model="auto",
                        max_model=max_model)
    imp = res.implied()
    # the implied N's interval (the N term's, or by the delta method where a short GM
    # holds white noise); nan where the model implies no white noise
    n_lo, n_hi = ((imp["N_ci_low"], imp["N_ci_high"]) if imp["N"] > 0
                  else (math.nan, math.nan))
    return {"selected": res.model, "N": imp["N"], "K": imp["K"], "N_lo": n_lo, "N_hi": n_hi,
            "approximate": res.approximate, "holds": bool(res.check is not None
                                                          and res.check.holds),
            "K_resolved": bool(imp["K_resolved"]), "K_lo": imp["K_ci_low"],
            "K_hi": imp["K_ci_high"], "K_ul": imp["K_upper_limit"], "K_model": imp["K_model"]}


def k_summary(rows: list[dict[str, object]], true_k: list[float]) -> dict[str, float]:
    """The K a user reads: where resolved, the share within 30 % of the generating K and
    the share whose interval covers it; elsewhere the share whose upper limit holds; and
    the selected model's own random walk (K_model) / true, median."""
    res = [bool(r["K_resolved"]) for r in rows]
    kr = [float(r["K"]) / t for r, t, ok in zip(rows, true_k, res, strict=True)  # type: ignore[arg-type]
          if ok]
    cov = [float(r["K_lo"]) <= t <= float(r["K_hi"])  # type: ignore[arg-type]
           for r, t, ok in zip(rows, true_k, res, strict=True) if ok]
    ul = [float(r["K_ul"]) >= t for r, t, ok in zip(rows, true_k, res, strict=True)  # type: ignore[arg-type]
          if not ok]
    km = [float(r["K_model"]) / t for r, t in zip(rows, true_k, strict=True)]  # type: ignore[arg-type]
    return {"resolved": float(sum(res)), "n": float(len(rows)),
            "within_30": float(np.sum(np.abs(np.array(kr) - 1.0) <= 0.3)),
            "covers": float(sum(cov)), "ul_holds": float(sum(ul)),
            "unresolved": float(len(ul)), "k_model_median": float(np.median(km))}


def k_cells(k: dict[str, float]) -> str:
    """Table cells: K resolved, within 30 % / covers (of the resolved), upper limit holds
    (of the others), K_model / true median."""
    return (f"{k['resolved']:.0f} of {k['n']:.0f} | {k['within_30']:.0f} / {k['covers']:.0f} | "
            f"{k['ul_holds']:.0f} of {k['unresolved']:.0f} | {k['k_model_median']:.2f}")


def run_misspecified(case: Misspecified, reps: int, workers: int = 1,
                     max_model: str = "Q+N+K+R+GM+GM") -> dict[str, object]:
    """Selection, accuracy of the implied N and K, coverage of N's 95 % interval."""
    if workers > 1:
        with ProcessPoolExecutor(workers) as ex:
            rows = list(ex.map(one_misspecified, [case] * reps, range(reps),
                               [max_model] * reps))
    else:
        rows = [one_misspecified(case, r, max_model) for r in range(reps)]
    t = case.truth
    n_err = np.array([float(r["N"]) / t["N"] - 1.0 for r in rows])  # type: ignore[arg-type]
    cover = [float(r["N_lo"]) <= t["N"] <= float(r["N_hi"]) for r in rows]  # type: ignore[arg-type]
    sel = [str(r["selected"]) for r in rows]
    return {"reps": reps, "selected": {m: sel.count(m) for m in sorted(set(sel))},
            "k": k_summary(rows, [t["K"]] * len(rows)),
            "n_err_median": float(np.median(np.abs(n_err))),
            "n_err_max": float(np.max(np.abs(n_err))),
            "n_within_10": float(np.mean(np.abs(n_err) <= 0.10)),
            "n_coverage": float(np.mean(cover)),
            "approximate": float(np.mean([bool(r["approximate"]) for r in rows]))}


def one_preset(name: str, rep: int, n: int, max_model: str = "Q+N+K+R+GM+GM"
               ) -> dict[str, object]:
    """Model selection on replicate rep (seed 9000 + rep) of a simulator preset
    (gyrodrift.simulation.presets): selected model, implied N and K, N's interval."""
    from gyrodrift.simulation.presets import simulate_preset
    from gyrodrift.stability.gmwm import identify_gmwm

    rec = simulate_preset(name, n, 9000 + rep)
    res = identify_gmwm(rec.gyro_deg_h, rec.rate_hz, model="auto", max_model=max_model)
    imp = res.implied()
    # the implied N's interval (the N term's, or by the delta method where a short GM
    # holds white noise); nan where the model implies no white noise
    n_lo, n_hi = ((imp["N_ci_low"], imp["N_ci_high"]) if imp["N"] > 0
                  else (math.nan, math.nan))
    return {"selected": res.model, "N": imp["N"], "K": imp["K"], "N_lo": n_lo, "N_hi": n_hi,
            "approximate": res.approximate, "true_N": rec.truth.n_deg_rt_h,
            "true_K": rec.truth.k_deg_h_rt_h, "K_ul": imp["K_upper_limit"],
            "K_resolved": bool(imp["K_resolved"]), "K_lo": imp["K_ci_low"],
            "K_hi": imp["K_ci_high"], "K_model": imp["K_model"]}


def one_k(case: Case, rep: int, n: int, max_model: str = "Q+N+K+R+GM+GM"
          ) -> dict[str, object]:
    """The K a user reads (implied()) after selection on replicate rep of a well-specified
    case with a random walk."""
    import gyrodrift
    from gyrodrift.stability.gmwm import identify_gmwm

    rec = gyrodrift.simulate(n=n, rate_hz=RATE_HZ, seed=case.seed + rep, **case.sim)  # type: ignore[arg-type]
    res = identify_gmwm(rec.rate_deg_h, RATE_HZ, model="auto", max_model=max_model)
    imp = res.implied()
    return {"selected": res.model, "K": imp["K"], "K_resolved": bool(imp["K_resolved"]),
            "K_lo": imp["K_ci_low"], "K_hi": imp["K_ci_high"], "K_ul": imp["K_upper_limit"],
            "K_model": imp["K_model"]}


#: GMWM parameter -> attribute of ieee952.NoiseFit (the Allan fit's estimate of it).
ALLAN_NAMES = {"Q": "q_arcsec", "N": "n_deg_rt_h", "K": "k_deg_h_rt_h"}


def _allan_value(fit: object, name: str) -> float:
    attr = ALLAN_NAMES[name]
    for cand in (attr,):
        if hasattr(fit, cand):
            return float(getattr(fit, cand))
    raise AttributeError(attr)


def fmt(v: float) -> str:
    return "n/a" if math.isnan(v) else f"{v:.4g}"


def one_replicate(case: Case, rep: int, n: int, max_model: str, select: bool = True
                  ) -> dict[str, object]:
    """One record: GMWM of the true model and the Allan fit; with select, also the WIC
    selection (model="auto", ~50x the cost of the true model's fit)."""
    import gyrodrift
    from gyrodrift.stability import ieee952
    from gyrodrift.stability.gmwm import identify_gmwm

    rec = gyrodrift.simulate(n=n, rate_hz=RATE_HZ, seed=case.seed + rep, **case.sim)  # type: ignore[arg-type]
    x = rec.rate_deg_h
    # the true model as named: no conversion of a correlation time at its bound
    true_fit = identify_gmwm(x, RATE_HZ, model=case.model, convert_bounds=False)
    out: dict[str, object] = {}
    if select:
        auto = identify_gmwm(x, RATE_HZ, model="auto", max_model=max_model)
        out.update(selected=auto.model, hit=auto.model == true_fit.model)
    res = gyrodrift.oadev(x, RATE_HZ, taus="octave")
    pos = res.adev > 0
    allan = ieee952.identify(res.tau_s[pos], res.adev[pos], res.edf[pos])
    for name in case.truth:
        p = true_fit.param(name)
        out[name] = (p.value, p.ci_low, p.ci_high,
                     _allan_value(allan, name) if name in ALLAN_NAMES else math.nan)
    return out


def select_one(case: Case, rep: int, n: int, max_model: str) -> str:
    """The model identify_gmwm(model="auto") selects on replicate rep of length n."""
    import gyrodrift
    from gyrodrift.stability.gmwm import identify_gmwm

    rec = gyrodrift.simulate(n=n, rate_hz=RATE_HZ, seed=case.seed + rep, **case.sim)  # type: ignore[arg-type]
    return identify_gmwm(rec.rate_deg_h, RATE_HZ, model="auto", max_model=max_model).model


def slowest_tc_s(case: Case) -> float:
    """Correlation time of the case's slowest Gauss-Markov term, s (nan without one)."""
    gms = case.sim.get("gm", ())
    return max((float(t) for _, t in gms), default=math.nan)  # type: ignore[union-attr]


def hit_rates_by_length(case: Case, reps: int, log2_lengths: list[int], max_model: str,
                        workers: int = 1) -> list[dict[str, object]]:
    """Selection hit rate of `case` on records of 2^L samples, L in log2_lengths (seeds case
    seed + 0 .. reps - 1 at every length)."""
    out = []
    for lg in log2_lengths:
        n = 1 << lg
        if workers > 1:
            with ProcessPoolExecutor(workers) as ex:
                sel = list(ex.map(select_one, [case] * reps, range(reps), [n] * reps,
                                  [max_model] * reps))
        else:
            sel = [select_one(case, r, n, max_model) for r in range(reps)]
        out.append({"log2_n": lg, "n": n, "record_s": n / RATE_HZ,
                    "hit_rate": float(np.mean([m == case.model for m in sel])),
                    "selected": {m: sel.count(m) for m in sorted(set(sel))}})
    return out


def run_case(case: Case, reps: int, n: int = 1 << 14, max_model: str = "Q+N+K+R+GM+GM",
             workers: int = 1, select_reps: int | None = None, progress: bool = False
             ) -> dict[str, object]:
    """Run `reps` replicates (seeds case.seed + 0 .. reps - 1), the WIC selection on the
    first `select_reps` of them (default all); returns per-parameter coverage, RMSEs,
    ratio, hit rate. progress (one worker): one line per replicate on stderr (replicate,
    selected model, estimates, interval, Allan value), so a long run's partial result can
    be read."""
    n_sel = reps if select_reps is None else min(select_reps, reps)
    sel = [r < n_sel for r in range(reps)]
    if workers > 1:
        with ProcessPoolExecutor(workers) as ex:
            rows = list(ex.map(one_replicate, [case] * reps, range(reps), [n] * reps,
                               [max_model] * reps, sel))
    else:
        rows = []
        for r in range(reps):
            rows.append(one_replicate(case, r, n, max_model, sel[r]))
            if progress:
                print(f"rep {r} seed {case.seed + r} cpu {time.process_time():.0f} s: {rows[-1]}",
                      file=sys.stderr, flush=True)
    srows = rows[:n_sel]
    summary: dict[str, object] = {
        "select_reps": n_sel,
        "hit_rate": float(np.mean([r["hit"] for r in srows])) if srows else math.nan,
        "selected": {m: sum(1 for r in srows if r["selected"] == m)
                     for m in sorted({str(r["selected"]) for r in srows})},
        "params": {},
    }
    for name, true in case.truth.items():
        vals = np.array([r[name] for r in rows], dtype=np.float64)  # type: ignore[misc]
        est, lo, hi, al = vals.T
        cover = float(np.mean((lo <= true) & (true <= hi)))
        rmse_g = float(np.sqrt(np.mean((est - true) ** 2)))
        rmse_a = float(np.sqrt(np.mean((al - true) ** 2))) if name in ALLAN_NAMES else math.nan
        summary["params"][name] = {  # type: ignore[index]
            "true": true, "coverage": cover, "rmse_gmwm": rmse_g, "rmse_allan": rmse_a,
            "ratio": rmse_g / rmse_a if name in ALLAN_NAMES else math.nan,
            "mean_gmwm": float(np.mean(est)),
            "mean_allan": float(np.mean(al)) if name in ALLAN_NAMES else math.nan,
        }
    return summary


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=200)
    ap.add_argument("--n", type=int, default=1 << 14)
    ap.add_argument("--select-reps", type=int, default=None,
                    help="run the WIC selection on the first K replicates only (default all)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--max-model", default="Q+N+K+R+GM+GM")
    ap.add_argument("--case", type=int, action="append",
                    help="run only these cases (1-based; repeatable; default all)")
    ap.add_argument("--progress", action="store_true",
                    help="one line per replicate on stderr (one worker)")
    ap.add_argument("--lengths", default=None,
                    help="log2 record lengths, e.g. 14,15,16,17: selection hit rate only")
    ap.add_argument("--misspecified", action="store_true",
                    help="run the misspecified (flicker) cases: selection, implied N and K, "
                         "coverage of N")
    ap.add_argument("--preset", action="append",
                    help="run GMWM selection on this simulator preset (repeatable; records "
                         "of --n samples)")
    ap.add_argument("--k-resolution", action="store_true",
                    help="the K a user reads after selection on the well-specified cases "
                         "with a random walk (records of --n samples)")
    args = ap.parse_args(argv)
    if args.k_resolution:
        print(f"# K after GMWM selection on well-specified records: {args.reps} replicates "
              f"per case, {args.n} samples at {RATE_HZ:g} Hz, among the sub-models of "
              f"{args.max_model}, nominal 95 % intervals")
        print("| case | selected | K resolved | resolved K: within 30 % / interval covers | "
              "K not resolved: upper limit holds | model's K / true: median | CPU s |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        for k, case in enumerate(CASES, 1):
            if "K" not in case.truth or (args.case and k not in args.case):
                continue
            c0 = time.process_time()
            rows = [one_k(case, r, args.n, args.max_model) for r in range(args.reps)]
            sel = [str(r["selected"]) for r in rows]
            ks = k_summary(rows, [case.truth["K"]] * len(rows))
            print(f"| {k}: {case.name} (K {case.truth['K']:g}) | "
                  + ", ".join(f"{m} x{sel.count(m)}" for m in sorted(set(sel)))
                  + f" | {k_cells(ks)} | {time.process_time() - c0:.0f} |")
            sys.stdout.flush()
        return 0
    if args.preset:
        print(f"# GMWM selection on simulator presets: {args.reps} replicates (seeds 9000 + "
              f"0 .. {args.reps - 1}), {args.n} samples, among the sub-models of "
              f"{args.max_model}, nominal 95 % intervals")
        print("| preset | selected | implied N / true: median, worst | N within 10 % | K "
              "resolved | resolved K: within 30 % / interval covers | K not resolved: upper "
              "limit holds | model's K / true: median | N has an interval / covers | flagged "
              "approximate | CPU s |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for name in args.preset:
            c0 = time.process_time()
            rows = [one_preset(name, r, args.n, args.max_model) for r in range(args.reps)]
            nr = np.array([float(r["N"]) / float(r["true_N"]) for r in rows])  # type: ignore[arg-type]
            has = [not math.isnan(float(r["N_lo"])) for r in rows]  # type: ignore[arg-type]
            cov = [h and float(r["N_lo"]) <= float(r["true_N"]) <= float(r["N_hi"])  # type: ignore[arg-type]
                   for h, r in zip(has, rows, strict=True)]
            sel = [str(r["selected"]) for r in rows]
            worst = float(nr[np.argmax(np.abs(nr - 1.0))])
            ks = k_summary(rows, [float(r["true_K"]) for r in rows])  # type: ignore[arg-type]
            print(f"| {name} | " + ", ".join(f"{m} x{sel.count(m)}" for m in sorted(set(sel)))
                  + f" | {np.median(nr):.3f}, {worst:.3f} | "
                  f"{100 * np.mean(np.abs(nr - 1) <= 0.1):.0f} % | {k_cells(ks)} | "
                  f"{sum(has)} / {sum(cov)} | "
                  f"{100 * np.mean([bool(r['approximate']) for r in rows]):.0f} % | "
                  f"{time.process_time() - c0:.0f} |")
            sys.stdout.flush()
        return 0
    if args.misspecified:
        print(f"# GMWM on misspecified records: {args.reps} replicates per case, {RATE_HZ:g} Hz, "
              f"selection among the sub-models of {args.max_model}, nominal 95 % intervals")
        print("| case | n | selected | implied N: median abs error, within 10 % | K resolved | "
              "resolved K: within 30 % / interval covers | K not resolved: upper limit holds | "
              "model's K / true: median | coverage of N | flagged approximate | CPU s |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for k, mcase in enumerate(MISSPECIFIED, 1):
            if args.case and k not in args.case:
                continue
            c0 = time.process_time()
            m = run_misspecified(mcase, args.reps, args.workers, args.max_model)
            print(f"| {mcase.name} (N {mcase.truth['N']:g}, K {mcase.truth['K']:g}, B "
                  f"{mcase.sim['b_deg_h']:g}) | 2^{mcase.n.bit_length() - 1} | "
                  + ", ".join(f"{mm} x{c}" for mm, c in m["selected"].items())  # type: ignore[attr-defined]
                  + f" | {100 * m['n_err_median']:.1f} %, {100 * m['n_within_10']:.0f} % | "  # type: ignore[operator]
                  f"{k_cells(m['k'])} | "  # type: ignore[arg-type]
                  f"{100 * m['n_coverage']:.0f} % | {100 * m['approximate']:.0f} % | "  # type: ignore[operator]
                  f"{time.process_time() - c0:.0f} |")
            sys.stdout.flush()
        return 0
    if args.lengths:
        lgs = [int(v) for v in args.lengths.split(",")]
        print(f"# GMWM model selection hit rate vs record length: {args.reps} replicates per "
              f"case and length (seeds case seed + 0 .. {args.reps - 1}), {RATE_HZ:g} Hz, "
              f"among the sub-models of {args.max_model}")
        print("| case | true model | n | record s | slowest T_c spans | hit rate | "
              "selected | CPU s |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- |")
        for k, case in enumerate(CASES, 1):
            if args.case and k not in args.case:
                continue
            for lg in lgs:
                c0 = time.process_time()
                row = hit_rates_by_length(case, args.reps, [lg], args.max_model,
                                          args.workers)[0]
                tc = slowest_tc_s(case)
                span = "n/a" if math.isnan(tc) else f"{row['record_s'] / tc:.0f} T_c"
                print(f"| {k} | {case.model} | 2^{lg} | {row['record_s']:g} | {span} | "
                      f"{100 * row['hit_rate']:.0f} % | "  # type: ignore[operator]
                      + ", ".join(f"{m} x{c}" for m, c in row["selected"].items())  # type: ignore[attr-defined]
                      + f" | {time.process_time() - c0:.0f} |")
                sys.stdout.flush()
        return 0
    print(f"# GMWM Monte Carlo: {args.reps} replicates per case, n = {args.n} samples at "
          f"{RATE_HZ:g} Hz, model selection among the sub-models of {args.max_model}, "
          f"nominal 95 % asymptotic intervals")
    for k, case in enumerate(CASES, 1):
        if args.case and k not in args.case:
            continue
        t0 = time.perf_counter()
        c0 = time.process_time()
        s = run_case(case, args.reps, args.n, args.max_model, args.workers, args.select_reps,
                     progress=args.progress)
        dt = time.perf_counter() - t0
        print(f"\n## {case.name} (true model {case.model}; {dt:.0f} s wall, "
              f"{time.process_time() - c0:.0f} s CPU in this process)")
        print(f"model selection hit rate: {100 * s['hit_rate']:.1f} % of "
              f"{s['select_reps']} replicates  selected: "
              + ", ".join(f"{m} x{c}" for m, c in s["selected"].items()))  # type: ignore[union-attr]
        print("| parameter | true | coverage of 95 % CI | GMWM mean | GMWM RMSE | "
              "Allan NNLS mean | Allan NNLS RMSE | RMSE ratio GMWM/Allan |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- |")
        for name, p in s["params"].items():  # type: ignore[union-attr]
            units = {"Q": "arcsec", "N": "deg/sqrt(h)", "K": "deg/h/sqrt(h)"}.get(
                name, "s" if name.endswith("_tau") else "deg/h")
            print(f"| {name} ({units}) | {p['true']:g} | {100 * p['coverage']:.1f} % | "
                  f"{fmt(p['mean_gmwm'])} | {fmt(p['rmse_gmwm'])} | {fmt(p['mean_allan'])} | "
                  f"{fmt(p['rmse_allan'])} | {fmt(p['ratio'])} |")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
