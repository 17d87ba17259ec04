#!/usr/bin/env python3
"""The drift model fitted from whole-record lag statistics, against the offline ML fit, on
the records of `scripts/online_drift_mc.py --convergence`.

For both of the papers' pairs, r/q in {1, 3}, seeds 1..SEEDS and each record length: the
record (the same as --convergence at that length) is pushed in chunks of 4096 samples into
`gyrodrift.reference.lag_drift.LagStatisticsReference` (L lags), the model is fitted from
those statistics alone (`lag_drift_fit`, the exact likelihood to rho^L or Whittle's), and
compared with `gyrodrift.fit_drift_model` on the whole record: z = (lag fit - ML) / (the
offline fit's standard error) for a1, a2, q, r, mean, and the signed likelihood distance
d_LL = sign(D) sqrt(``|D|``), D = 2 (log L(ML) - log L(lag fit)), both log-likelihoods exact
(the core's Kalman filter on the record); a negative d_LL means the lag fit's likelihood is
the higher one.

    python scripts/online_whittle_proto.py                       # 240000 samples, 5 seeds
    python scripts/online_whittle_proto.py --samples 240000 480000 960000 --kind whittle
    python scripts/online_whittle_proto.py --samples 240000 480000 960000 --cpp --float32

--cpp: the statistics and the fit of the C++ core instead (`gyrodrift.filters.LagStatistics`
at L = 32, `gyrodrift.filters.lag_drift_fit`, the fit in double); with --float32 the float
state the target keeps. --cpp --no-head --kind whittle --lags 12: the C++ statistics without
the first samples (bound at L = 12) and their fit (Whittle's likelihood without them).

    python scripts/online_whittle_proto.py --samples 240000 960000 --kind whittle --no-head \
        --lags 12 --cpp --float32
"""

from __future__ import annotations

import argparse
import math
import time
from types import SimpleNamespace

import gyrodrift
import numpy as np
from gyrodrift._native import core
from gyrodrift.filters import LagStatistics
from gyrodrift.filters import lag_drift_fit as cpp_fit
from gyrodrift.reference.lag_drift import LagStatisticsReference, lag_drift_fit, lag_loglike
from online_drift_mc import PAIRS, RATIOS, Case, simulate

NAMES = ("a1", "a2", "q", "r", "mean")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, nargs="+", default=[240000],
                    help="record lengths (default 240000)")
    ap.add_argument("--seeds", type=int, default=5, help="seeds 1..SEEDS (default 5)")
    ap.add_argument("--lags", type=int, default=32, help="L (default 32)")
    ap.add_argument("--kind", choices=("exact", "whittle"), default="exact",
                    help="likelihood from the lag statistics (default exact)")
    ap.add_argument("--float32", action="store_true",
                    help="round the statistics to float32 before the fit (what compensated "
                         "float sums on the target hold at best)")
    ap.add_argument("--no-head", action="store_true",
                    help="with --kind whittle: the first L samples replaced by the record's "
                         "mean in the mean's correction (a target that keeps no first samples)")
    ap.add_argument("--cpp", action="store_true",
                    help="the C++ core's statistics (L = 32, or 12 with --no-head) and fit; "
                         "--float32: its float state")
    ap.add_argument("--check", action="store_true",
                    help="also print the lag likelihood against the core's at the ML fit")
    args = ap.parse_args()
    if args.no_head and args.kind != "whittle":
        ap.error("--no-head needs --kind whittle (the exact likelihood uses the first samples)")
    no_head_cls = f"LagStatisticsNoHead{args.lags}" + ("F32" if args.float32 else "")
    if args.cpp and args.no_head and not hasattr(core("drift"), no_head_cls):
        ap.error(f"--cpp --no-head: no C++ statistics without the first samples at L = {args.lags}")
    if args.cpp and args.no_head and args.check:
        ap.error("--check reads the statistics with the reference: not with --cpp --no-head")
    if args.cpp and not args.no_head and args.lags != LagStatistics.lags:
        ap.error(f"--cpp keeps L = {LagStatistics.lags} with the first samples")
    loglike = core("drift").drift_loglike
    f32 = (", statistics rounded to float32" if args.float32 else "") + (
        ", no first samples" if args.no_head else "")
    if args.cpp:
        f32 = (", C++ statistics" + (" without the first samples" if args.no_head else "")
               + (" (float state)" if args.float32 else "") + " and fit")
    print(f"# kind {args.kind}, L = {args.lags}{f32}; z = (lag fit - ML) / offline stderr; "
          "d_LL = sign(D) sqrt(|D|), D = 2 (logL_ML - logL_lag) (exact likelihoods)")
    print(f"{'n':>7} {'a1':>7} {'a2':>7} {'r/q':>4} {'seed':>4} {'z_a1':>6} {'z_a2':>6} "
          f"{'z_q':>6} {'z_r':>6} {'z_mean':>6} {'d_LL':>6} {'a2_ML':>7} {'a2_lag':>7} "
          f"{'rho^L':>7}")
    t0 = time.monotonic()
    summary: dict[tuple[int, float], list[tuple[float, float]]] = {}
    for n in sorted(args.samples):
        for a1, a2 in PAIRS:
            for ratio in RATIOS:
                for seed in range(1, args.seeds + 1):
                    y = simulate(Case(a1, a2, ratio, "none", n, seed))[0]
                    if args.cpp and args.no_head:
                        lib = core("drift")
                        bound = getattr(lib, no_head_cls)()
                        yy = y.astype(np.float32) if args.float32 else y
                        for i in range(0, n, 4096):
                            bound.push(yy[i:i + 4096])
                        out = lib.lag_drift_fit(bound)  # Whittle's without the first samples
                        est = SimpleNamespace(**dict(zip(NAMES, out[1:6], strict=True)),
                                              truncation=out[7], status=out[0].name)
                    elif args.cpp:
                        st = LagStatistics(dtype=np.float32 if args.float32 else np.float64)
                        for i in range(0, n, 4096):
                            st.push(y[i:i + 4096])
                        est = cpp_fit(st, kind=args.kind)
                    else:
                        st = LagStatisticsReference(args.lags)
                        for i in range(0, n, 4096):
                            st.push(y[i:i + 4096])
                        if args.no_head:
                            st.head = np.full(st.lags, st.total / st.n)
                        if args.float32:
                            st.total = float(np.float32(st.total))
                            for name in ("products", "head", "tail"):
                                setattr(st, name, getattr(st, name).astype(np.float32)
                                        .astype(np.float64))
                        est = lag_drift_fit(st, args.kind)
                    fit = gyrodrift.fit_drift_model(y, rate_hz=400.0)
                    z = [(getattr(est, k) - getattr(fit, k)) / fit.stderr[k] for k in NAMES]
                    ll_ml = loglike(y, fit.a1, fit.a2, fit.q, fit.r, fit.mean)[0]
                    ll_lag = loglike(y, est.a1, est.a2, est.q, est.r, est.mean)[0]
                    dd = 2.0 * (ll_ml - ll_lag)
                    d_ll = math.copysign(math.sqrt(abs(dd)), dd)
                    if args.check:
                        at_ml = lag_loglike(st, fit.a1, fit.a2, fit.q, fit.r, fit.mean,
                                            args.kind)
                        print(f"# at the ML fit: core {ll_ml:.6f}, lag statistics {at_ml:.6f}")
                    summary.setdefault((n, a1), []).append((max(abs(v) for v in z), d_ll))
                    print(f"{n:7d} {a1:7.4f} {a2:7.4f} {ratio:4.1f} {seed:4d} "
                          + " ".join(f"{v:+6.2f}" for v in z)
                          + f" {d_ll:+6.2f} {fit.a2:+7.4f} {est.a2:+7.4f}"
                          f" {est.truncation:7.1e}", flush=True)
    print("# samples, pair: records within 1 SE (every parameter and the mean); largest |z|; "
          "records with a higher exact likelihood than the offline fit; d_LL range")
    for (n, a1), rows in sorted(summary.items()):
        zs = [r[0] for r in rows]
        ds = [r[1] for r in rows]
        print(f"# {n} {a1}: {sum(v <= 1 for v in zs)} of {len(zs)}; {max(zs):.3f}; "
              f"{sum(d < 0 for d in ds)}; {min(ds):+.3f} to {max(ds):+.3f}")
    print(f"# {time.monotonic() - t0:.0f} s")


if __name__ == "__main__":
    main()
