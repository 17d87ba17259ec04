#!/usr/bin/env python3
"""Monte Carlo: how close the maximum-likelihood-tuned AR(2)-Kalman filter gets to the optimum.

For the papers' four AR(2) pairs and r/q in {0.3, 1, 3} (q = 1), simulate stationary AR(2)
drift plus white noise on a constant offset, and filter the record with the steady-state
AR(2)-Kalman filter tuned three ways:
  true   - the true model (a1, a2, q, r, mean): the DARE optimum, the best a linear filter can do;
  ml     - gyrodrift.fit_drift_model(record) (maximum likelihood, ar2+white), .kalman(): the
           ML tuning, or the minimax q = r tuning when the fit finds the drift/white split
           not identified (the last column counts those seeds);
  papers - the papers' recipe: Yule-Walker AR(2) on the noisy record, q = sigma2, r = the
           AR(2) one-step prediction-error variance (gyrodrift.fit_ar2 defaults).
Prints the mean squared error against the simulated drift (offset + x_k, which only a
simulation knows), averaged over seeds, and ml/true, papers/true, raw/true.

    python scripts/drift_montecarlo.py [--n 60000] [--seeds 20]
"""

from __future__ import annotations

import argparse
import math

import gyrodrift
import numpy as np
from scipy.signal import lfilter

PAPER_PAIRS = [(-0.0340, 0.0252), (0.6868, -0.0213), (0.2297, 0.1638), (-0.0069, 0.0113)]
RATIOS = (0.3, 1.0, 3.0)


def one_run(a1: float, a2: float, q: float, r: float, n: int, seed: int,
            mean: float = 9.7) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    x = lfilter([1.0], [1.0, -a1, -a2], rng.normal(0.0, math.sqrt(q), n + 2000))[2000:]
    truth = mean + x
    y = truth + rng.normal(0.0, math.sqrt(r), n)
    skip = 500  # start-up transient of the filters

    def mse(est: np.ndarray) -> float:
        return float(np.mean((est[skip:] - truth[skip:]) ** 2))

    true_model = gyrodrift.Ar2Model(a1=a1, a2=a2, sigma2=q, mean=mean)
    out = {"raw": mse(y),
           "true": mse(gyrodrift.kalman_filter(y, true_model, q=q, r=r, steady_state=True))}
    fit = gyrodrift.fit_drift_model(y, rate_hz=100.0)
    out["ml"] = mse(fit.kalman().process(y))
    out["minimax"] = 0.0 if fit.identified else 1.0
    papers = gyrodrift.fit_ar2(y)
    out["papers"] = mse(gyrodrift.kalman_filter(y, papers, steady_state=True))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=60000)
    ap.add_argument("--seeds", type=int, default=20)
    args = ap.parse_args()
    print(f"# n = {args.n} samples, {args.seeds} seeds per row, q = 1; MSE against the true drift")
    print(f"{'a1':>8} {'a2':>8} {'r/q':>5} {'raw':>8} {'papers':>8} {'ML':>8} {'true':>8} "
          f"{'ML/true':>8} {'pap/true':>8} {'ML/raw':>8} {'minimax':>8}")
    worst = 0.0
    for a1, a2 in PAPER_PAIRS:
        for ratio in RATIOS:
            runs = [one_run(a1, a2, 1.0, ratio, args.n, seed) for seed in range(args.seeds)]
            m = {k: float(np.mean([run[k] for run in runs])) for k in runs[0]}
            worst = max(worst, m["ml"] / m["true"])
            print(f"{a1:8.4f} {a2:8.4f} {ratio:5.1f} {m['raw']:8.4f} {m['papers']:8.4f} "
                  f"{m['ml']:8.4f} {m['true']:8.4f} {m['ml'] / m['true']:8.4f} "
                  f"{m['papers'] / m['true']:8.4f} {m['ml'] / m['raw']:8.4f} "
                  f"{round(m['minimax'] * args.seeds):>5}/{args.seeds}")
    print(f"# worst ML/true ratio: {worst:.4f}")


if __name__ == "__main__":
    main()
