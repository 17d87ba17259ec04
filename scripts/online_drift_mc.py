#!/usr/bin/env python3
"""Monte Carlo: the online-retuned AR(2)-Kalman filter against the offline ML filter, the
papers' tuning and the configured model, on stationary records and on records whose noise
changes halfway.

For the papers' two correlated AR(2) pairs and r/q in {1, 3} (q = 1 before any change),
simulate AR(2) drift plus white noise on a constant offset and filter the record with the
steady-state AR(2)-Kalman filter tuned five ways; the MSE is against the simulated drift
(offset + x_k, which only a simulation knows), after the first 500 samples:
  optimum    - the true model's gain (piecewise on a changing record): the yardstick;
  configured - a fixed configured model, 20 % off in a1, a2 = a2/2 + 0.03, q x1.5, r x0.7
               (stationary records), or the first half's true model (changing records);
  online     - gyrodrift.filters.online.OnlineDriftIdentifier run over the record, the gain
               of in_use() applied from the sample after each retune (the configured gain
               before the first); stationary: no forgetting; changing: memory_blocks = 100,
               adapt_ar off (q and r tracked);
  ml         - gyrodrift.fit_drift_model on the whole record (.kalman()): the offline optimum
               a navigation computer cannot have while it runs;
  papers     - the papers' recipe: Yule-Walker AR(2) on the noisy record, q = sigma2, r = its
               prediction-error variance (gyrodrift.fit_ar2 defaults).
Prints one row per case (averaged over seeds) with the ratios to the optimum.

    python scripts/online_drift_mc.py            # fast: 1 seed, 240000 samples
    python scripts/online_drift_mc.py --full     # the docs run: 5 seeds, 480000 samples
    python scripts/online_drift_mc.py --convergence   # online estimate vs offline ML fit
    python scripts/online_drift_mc.py --convergence --samples 960000 --seeds 5

--convergence: for both pairs, r/q in {1, 3} and seeds 1-3 (--seeds), 240000 samples
(--samples), no forgetting, the configured model as above; prints (online - ML) / (the offline
fit's standard error) for a1, a2, q, r, mean after the last sample, the likelihood distance
sqrt(2 (log L(ML) - log L(online))) on the same record, and the offline fit's a2.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass

import gyrodrift
import numpy as np
import scipy.linalg
from gyrodrift._native import core
from gyrodrift.filters.online import DriftParams, OnlineDriftIdentifier, OnlineDriftSettings
from scipy.signal import lfilter

PAIRS = ((0.6868, -0.0213), (0.2297, 0.1638))
RATIOS = (1.0, 3.0)
CHANGES = ("none", "r x2", "q x2")
MEAN = 9.7
SKIP = 500


@dataclass(frozen=True)
class Case:
    """One simulated record: pair, r/q, the change halfway, length, seed."""

    a1: float
    a2: float
    ratio: float
    change: str
    n: int
    seed: int


def simulate(case: Case) -> tuple[np.ndarray, np.ndarray, tuple[float, float], tuple[float, float]]:
    """Record, true drift (offset included), (q, r) before and after the halfway change."""
    rng = np.random.default_rng(case.seed)
    q1, r1 = 1.0, case.ratio
    q2, r2 = (q1, 2 * r1) if case.change == "r x2" else (2 * q1, r1) if case.change == "q x2" \
        else (q1, r1)
    h = case.n // 2
    w = np.r_[rng.normal(0, math.sqrt(q1), h + 2000), rng.normal(0, math.sqrt(q2), case.n - h)]
    x = lfilter([1.0], [1.0, -case.a1, -case.a2], w)[2000:]
    v = np.r_[rng.normal(0, math.sqrt(r1), h), rng.normal(0, math.sqrt(r2), case.n - h)]
    truth = MEAN + x
    return truth + v, truth, (q1, r1), (q2, r2)


def gain_filter(y: np.ndarray, a1: np.ndarray, a2: np.ndarray, k0: np.ndarray, k1: np.ndarray,
                mean: np.ndarray) -> np.ndarray:
    """Constant-gain AR(2)-Kalman filter with per-sample model and gain arrays (piecewise
    constant): X- = A X, X = X- + K (y - mean - x0-); returns x0 + mean."""
    out = np.empty_like(y)
    x0 = x1 = 0.0
    for k in range(len(y)):
        p0 = a1[k] * x0 + a2[k] * x1
        e = y[k] - mean[k] - p0
        x0, x1 = p0 + k0[k] * e, x0 + k1[k] * e
        out[k] = x0 + mean[k]
    return out


def steady_state_gain(p: DriftParams) -> tuple[float, float]:
    """Steady-state Kalman gain (k0, k1) of a model: the stabilising DARE solution (scipy)."""
    a = np.array([[p.a1, p.a2], [1.0, 0.0]])
    c = np.array([[1.0], [0.0]])
    pp = scipy.linalg.solve_discrete_are(a.T, c, np.diag([p.q, 0.0]), np.array([[p.r]]))
    f = pp[0, 0] + p.r
    return float(pp[0, 0] / f), float(pp[1, 0] / f)


def piecewise(n: int, starts: list[int], values: list[float]) -> np.ndarray:
    """Array of length n taking values[i] from starts[i] on."""
    out = np.empty(n)
    for i, s in enumerate(starts):
        out[s:] = values[i]
    return out


def model_filter(y: np.ndarray, m: DriftParams, starts: list[int] | None = None,
                 models: list[DriftParams] | None = None) -> np.ndarray:
    """The steady-state filter of one model, or of models[i] from starts[i] on."""
    models = models or [m]
    starts = starts or [0]
    gains = [steady_state_gain(p) for p in models]
    n = len(y)
    return gain_filter(y, piecewise(n, starts, [p.a1 for p in models]),
                       piecewise(n, starts, [p.a2 for p in models]),
                       piecewise(n, starts, [float(g[0]) for g in gains]),
                       piecewise(n, starts, [float(g[1]) for g in gains]),
                       piecewise(n, starts, [p.mean for p in models]))


def online_settings(change: str) -> OnlineDriftSettings:
    """The identifier's settings of the study (stationary: converge; changing: track)."""
    if change == "none":
        return OnlineDriftSettings(block_samples=400, retune_blocks=25, min_samples=60000)
    return OnlineDriftSettings(block_samples=400, retune_blocks=25, min_samples=60000,
                               memory_blocks=100.0, adapt_ar=False)


def run_case(case: Case) -> dict[str, float]:
    """MSE of each tuning on one record (see the module docstring), plus the online run's
    retunes, refused retunes and final status."""
    y, truth, (q1, r1), (q2, r2) = simulate(case)
    n = len(y)
    h = n // 2

    def mse(est: np.ndarray) -> float:
        return float(np.mean((est[SKIP:] - truth[SKIP:]) ** 2))

    a1, a2 = case.a1, case.a2
    true1, true2 = DriftParams(a1, a2, q1, r1, MEAN), DriftParams(a1, a2, q2, r2, MEAN)
    if case.change == "none":
        configured = DriftParams(0.8 * a1, 0.5 * a2 + 0.03, 1.5 * q1, 0.7 * r1, MEAN)
    else:
        configured = true1
    out = {"optimum": mse(model_filter(y, true1, [0, h], [true1, true2])),
           "configured": mse(model_filter(y, configured))}
    ident = OnlineDriftIdentifier(configured, online_settings(case.change))
    trace = ident.push(y)
    # The gain in use from the sample after each block end (the configured one before).
    starts = [0] + [min(int(s), n) for s in trace.samples]
    use = [configured] + [DriftParams(*row) for row in trace.in_use.tolist()]
    k0 = [steady_state_gain(configured)[0]] + [g[0] for g in trace.gain.tolist()]
    k1 = [steady_state_gain(configured)[1]] + [g[1] for g in trace.gain.tolist()]
    est = gain_filter(y, piecewise(n, starts, [p.a1 for p in use]),
                      piecewise(n, starts, [p.a2 for p in use]), piecewise(n, starts, k0),
                      piecewise(n, starts, k1), piecewise(n, starts, [p.mean for p in use]))
    out["online"] = mse(est)
    fit = gyrodrift.fit_drift_model(y, rate_hz=400.0)
    out["ml"] = mse(fit.kalman().process(y))
    out["papers"] = mse(gyrodrift.kalman_filter(y, gyrodrift.fit_ar2(y), steady_state=True))
    out["retunes"] = float(ident.retunes)
    out["refused"] = float(ident.refused_retunes)
    out["tracking"] = 1.0 if ident.status == "tracking" else 0.0
    return out


def convergence(seeds: int = 3, n: int = 240000, extra: dict[str, float] | None = None
                ) -> None:
    """Print the online estimate's distance to the offline ML fit in offline standard errors,
    and as a likelihood distance, sqrt(2 (log L(ML) - log L(online))) on the same record (the
    Mahalanobis distance in the offline fit's information for a quadratic likelihood: below 1
    puts every parameter, and every combination of them, within one standard error). extra:
    settings of the identifier changed from the study's."""
    settings = {"block_samples": 400, "retune_blocks": 50, "min_samples": 100000, **(extra or {})}
    loglike = core("drift").drift_loglike
    if extra:
        print(f"# settings changed: {extra}")
    print(f"# {n} samples; (online - ML) / offline stderr; d_LL = sqrt(2 (logL_ML - "
          "logL_online)); a2_ML: the offline fit's a2")
    print(f"{'a1':>7} {'a2':>7} {'r/q':>4} {'seed':>4} {'z_a1':>6} {'z_a2':>6} {'z_q':>6} "
          f"{'z_r':>6} {'z_mean':>6} {'d_LL':>5} {'a2_ML':>7} {'ident':>5} {'status':>9}")
    names = ("a1", "a2", "q", "r", "mean")
    worst: dict[tuple[float, float], list[float]] = {}
    t0 = time.monotonic()
    for a1, a2 in PAIRS:
        for ratio in RATIOS:
            for seed in range(1, seeds + 1):
                y, _, _, _ = simulate(Case(a1, a2, ratio, "none", n, seed))
                fit = gyrodrift.fit_drift_model(y, rate_hz=400.0)
                ident = OnlineDriftIdentifier(
                    DriftParams(0.8 * a1, 0.5 * a2 + 0.03, 1.5, 0.7 * ratio, 0.0),
                    OnlineDriftSettings(**settings))  # type: ignore[arg-type]
                ident.push(y)
                est = ident.estimate
                z = [(getattr(est, k) - getattr(fit, k)) / fit.stderr[k] for k in names]
                ll_ml = loglike(y, fit.a1, fit.a2, fit.q, fit.r, fit.mean)[0]
                ll_on = loglike(y, est.a1, est.a2, est.q, est.r, est.mean)[0]
                d_ll = math.sqrt(max(2.0 * (ll_ml - ll_on), 0.0))
                worst.setdefault((a1, a2), []).append(max(abs(v) for v in z[:4]))
                print(f"{a1:7.4f} {a2:7.4f} {ratio:4.1f} {seed:4d} "
                      + " ".join(f"{v:+6.2f}" for v in z)
                      + f" {d_ll:5.2f} {fit.a2:+7.4f} {fit.identified!s:>5} {ident.status:>9}")
    for (a1, a2), zs in worst.items():
        within = sum(v <= 1.0 for v in zs)
        print(f"# ({a1}, {a2}): {within} of {len(zs)} records within 1 standard error, "
              f"largest |z| {max(zs):.2f}")
    print(f"# {time.monotonic() - t0:.0f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="5 seeds, 480000 samples (docs run)")
    ap.add_argument("--seed", type=int, default=1, help="first seed")
    ap.add_argument("--convergence", action="store_true",
                    help="the online estimate against the offline ML fit instead")
    ap.add_argument("--samples", type=int, default=240000,
                    help="--convergence: record length (default 240000)")
    ap.add_argument("--seeds", type=int, default=3,
                    help="--convergence: seeds 1..SEEDS per pair and r/q (default 3)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="--convergence: an OnlineDriftSettings field changed from the study's "
                         "(repeatable), e.g. --set warmup_blocks=25")
    args = ap.parse_args()
    if args.convergence:
        extra: dict[str, float] = {}
        defaults = OnlineDriftSettings().as_dict()
        for item in args.set:
            name, sep, value = item.partition("=")
            if not sep or name not in defaults:
                ap.error(f"--set: expected NAME=VALUE, NAME a field of OnlineDriftSettings, "
                         f"got {item!r}")
            kind = type(defaults[name])
            try:
                extra[name] = (value.lower() in ("1", "true")) if kind is bool else kind(value)
            except ValueError:
                ap.error(f"--set: {name} expects a {kind.__name__}, got {value!r}")
        convergence(seeds=args.seeds, n=args.samples, extra=extra)
        return
    seeds, n = (5, 480000) if args.full else (1, 240000)
    t0 = time.monotonic()
    print(f"# {n} samples, {seeds} seed(s) per row, q = 1 before the change; MSE against the "
          "true drift, ratio to the optimum")
    print(f"{'a1':>7} {'a2':>7} {'r/q':>4} {'change':>6} {'optimum':>8} {'config':>7} "
          f"{'online':>7} {'ML':>7} {'papers':>7} {'retunes':>7} {'refused':>7} {'tracking':>8}")
    for change in CHANGES:
        for a1, a2 in PAIRS:
            for ratio in RATIOS:
                rows = [run_case(Case(a1, a2, ratio, change, n, args.seed + s))
                        for s in range(seeds)]
                m = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
                opt = m["optimum"]
                print(f"{a1:7.4f} {a2:7.4f} {ratio:4.1f} {change:>6} {opt:8.4f} "
                      f"{m['configured'] / opt:7.3f} {m['online'] / opt:7.3f} "
                      f"{m['ml'] / opt:7.3f} {m['papers'] / opt:7.3f} {m['retunes']:7.1f} "
                      f"{m['refused']:7.1f} {m['tracking']:8.2f}")
    print(f"# {time.monotonic() - t0:.0f} s")


if __name__ == "__main__":
    main()
