#!/usr/bin/env python3
"""How well can ANY estimator that sees only the record tune the drift filter? Fisher information,
Cramer-Rao bounds and a two-point (Le Cam) bound for the papers' four AR(2) pairs.

Model: x_k = a1 x_{k-1} + a2 x_{k-2} + w_k (var q = 1), y_k = x_k + v_k (var r), n samples.

1. Cramer-Rao: Whittle's Fisher information (gyrodrift.drift_fisher_information; the test holds
   it to the numerical Hessian of the exact expected log-likelihood) in (a1, a2, q, r); the
   bound on the standard error of the drift share w = q / (q + r), of log(r/q), and of the
   first steady-state Kalman gain k0. Beside it, the range of k0 that keeps the filter's mean
   squared error (MSE) within 10 % of the optimum (exact MSE of a steady-state filter with
   gain k on the true model, spectral integral).
2. Two-point bound (any estimator, biased or not): model A (the case) and model B, the AR(2) +
   white model with r/q = 10x (or 1/10x) A's that is closest to A in Kullback-Leibler
   divergence (minimised over B's a1, a2, q). Pinsker: the records' distributions differ by at
   most TV <= sqrt(KL / 2) in total variation. For any filter tuned from the record,
   max(E_A[L_A], E_B[L_B]) >= (1 - TV) / 2 * min_H (L_A(H) + L_B(H)), where L = MSE / optimum - 1
   and the minimum runs over every linear filter H (pointwise in frequency, a non-causal
   filter: a lower bound for any causal one). A bound above 0.1 means that no tuning rule can
   be within 10 % of the optimum on both A and B: the goal is impossible without outside
   knowledge of r.
3. The tuning when the split is not identified (nearly white drift, gain g): error
   (1 - g)^2 q + g^2 r; its worst case over all splits of q + r = T is T/4 at g = 1/2 (q = r),
   against T for the raw record (g = 1) and T for the white model's constant output (g = 0).

    python scripts/drift_identifiability.py [--n 60000]
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import scipy.optimize
from gyrodrift.filters.drift_model import drift_fisher_information

PAPER_PAIRS = [(-0.0340, 0.0252), (0.6868, -0.0213), (0.2297, 0.1638), (-0.0069, 0.0113)]
RATIOS = (0.3, 1.0, 3.0)
NF = 1 << 14
OMEGA = (np.arange(NF) + 0.5) * (math.pi / NF)
Z1 = np.exp(-1j * OMEGA)


def spectrum_x(a1: float, a2: float, q: float) -> np.ndarray:
    return q / np.abs(1.0 - a1 * Z1 - a2 * Z1 * Z1) ** 2


def dare(a1: float, a2: float, q: float, r: float) -> tuple[np.ndarray, float]:
    """Steady-state gain K and filtered error variance of x_k (the optimum MSE)."""
    a = np.array([[a1, a2], [1.0, 0.0]])
    p = np.diag([q, q])
    for _ in range(100000):
        f = p[0, 0] + r
        k = p[:, 0] / f
        pf = p - np.outer(k, p[0, :])
        pn = a @ pf @ a.T
        pn[0, 0] += q
        if np.max(np.abs(pn - p)) <= 1e-15 * np.max(np.abs(p)):
            p = pn
            break
        p = pn
    f = p[0, 0] + r
    return p[:, 0] / f, float(p[0, 0] - p[0, 0] ** 2 / f)


def response(a1: float, a2: float, k: np.ndarray) -> np.ndarray:
    """H(e^{iw}) of the steady-state filter x^_k = C X_k|k: X = (I - K C) A X_prev + K y."""
    a = np.array([[a1, a2], [1.0, 0.0]])
    abar = (np.eye(2) - np.outer(k, [1.0, 0.0])) @ a
    # (I - abar z^-1)^-1 K, first component, in closed form for the 2x2 case.
    m00 = 1.0 - abar[0, 0] * Z1
    m01 = -abar[0, 1] * Z1
    m10 = -abar[1, 0] * Z1
    m11 = 1.0 - abar[1, 1] * Z1
    det = m00 * m11 - m01 * m10
    return (m11 * k[0] - m01 * k[1]) / det


def mse_of(h: np.ndarray, sx: np.ndarray, r: float) -> float:
    """MSE of the filter output against x for y = x + v (mean over [0, pi] = the integral)."""
    return float(np.mean(np.abs(1.0 - h) ** 2 * sx + np.abs(h) ** 2 * r))


def gain_tolerance(a1: float, a2: float, r: float) -> tuple[float, float]:
    """Range of k0 (second gain component scaled with it) keeping MSE <= 1.1 x optimum."""
    k, opt = dare(a1, a2, 1.0, r)
    sx = spectrum_x(a1, a2, 1.0)

    def excess(c: float) -> float:
        return mse_of(response(a1, a2, k * c), sx, r) / opt - 1.1

    lo = scipy.optimize.brentq(excess, 1e-6, 1.0)
    hi_end = 1.0 / k[0] if k[0] > 0 else 10.0
    hi = scipy.optimize.brentq(excess, 1.0, hi_end) if excess(hi_end) > 0 else hi_end
    return float(k[0] * lo), float(k[0] * hi)


def crb(a1: float, a2: float, r: float, n: int) -> tuple[float, float, float, float]:
    """(k0, CRB se of w, of log(r/q), of k0) at q = 1."""
    q = 1.0
    info = drift_fisher_information(a1, a2, q, r, n)
    cov = np.linalg.inv(info)
    s = q + r
    gw = np.array([0.0, 0.0, r / s**2, -q / s**2])
    glr = np.array([0.0, 0.0, -1.0 / q, 1.0 / r])
    th = np.array([a1, a2, q, r])
    k0 = dare(*th)[0][0]
    gk = np.zeros(4)
    for i in range(4):
        e = np.zeros(4)
        e[i] = 1e-6
        gk[i] = (dare(*(th + e))[0][0] - dare(*(th - e))[0][0]) / 2e-6
    return (float(k0), math.sqrt(gw @ cov @ gw), math.sqrt(glr @ cov @ glr),
            math.sqrt(gk @ cov @ gk))


def kl_whittle(sa: np.ndarray, sb: np.ndarray, n: int) -> float:
    """KL(P_A || P_B) of n samples of two stationary Gaussian records (Whittle)."""
    ratio = sa / sb
    return float(0.5 * n * np.mean(ratio - 1.0 - np.log(ratio)))


def two_point(a1: float, a2: float, r_a: float, r_b_over_q: float, n: int
              ) -> tuple[tuple[float, float, float, float], float, float, float]:
    """The closest model B with r/q = r_b_over_q; (B, KL, TV bound, minimax lower bound)."""
    sa = spectrum_x(a1, a2, 1.0) + r_a

    def kl_of(p: np.ndarray) -> float:
        b1, b2, log_q = p
        if not (abs(b2) < 0.99 and abs(b1) < 0.99 * (1.0 - b2)):
            return 1e12
        qb = math.exp(log_q)
        return kl_whittle(sa, spectrum_x(b1, b2, qb) + r_b_over_q * qb, n)

    s_tot = float(np.mean(sa))
    q0 = s_tot / (1.0 + r_b_over_q)
    best = None
    for scale in (1.0, 0.5, 2.0):  # first order, B matches q a: a_B ~ a_A / q_B
        p0 = np.array([max(min(a1 / q0 * scale, 0.9), -0.9),
                       max(min(a2 / q0 * scale, 0.9), -0.9), math.log(q0)])
        res = scipy.optimize.minimize(kl_of, p0, method="Nelder-Mead",
                                      options={"xatol": 1e-9, "fatol": 1e-10, "maxiter": 4000})
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    b1, b2, log_q = best.x
    qb = math.exp(log_q)
    rb = r_b_over_q * qb
    kl = float(best.fun)
    tv = min(1.0, math.sqrt(kl / 2.0))
    # min over all linear filters of L_A + L_B, pointwise in frequency.
    _, opt_a = dare(a1, a2, 1.0, r_a)
    _, opt_b = dare(b1, b2, qb, rb)
    alpha = spectrum_x(a1, a2, 1.0) / opt_a + spectrum_x(b1, b2, qb) / opt_b
    beta = r_a / opt_a + rb / opt_b
    min_sum = float(np.mean(alpha * beta / (alpha + beta))) - 2.0
    bound = 0.5 * (1.0 - tv) * max(min_sum, 0.0)
    return (float(b1), float(b2), qb, rb), kl, tv, bound


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=60000)
    args = ap.parse_args()
    n = args.n
    print(f"# 1. Cramer-Rao bounds at n = {n} samples (q = 1); k0 range: MSE within 10 % of the "
          "optimum")
    print("| a1 | a2 | r/q | k0 optimum | k0 range for 10 % | CRB se(k0) | CRB se(q/(q+r)) | "
          "CRB se(log r/q) |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for a1, a2 in PAPER_PAIRS:
        for rho in RATIOS:
            k0, se_w, se_lr, se_k = crb(a1, a2, rho, n)
            lo, hi = gain_tolerance(a1, a2, rho)
            print(f"| {a1:.4f} | {a2:.4f} | {rho:g} | {k0:.3f} | {lo:.3f}-{hi:.3f} | {se_k:.3g} | "
                  f"{se_w:.3g} | {se_lr:.3g} |")
    print()
    print(f"# 2. Two-point bound at n = {n}: A = the case, B = the closest AR(2) + white model "
          "with r/q 10x (or 1/10x) A's")
    print("| a1 | a2 | r/q A | B: a1, a2, q, r | k0 A | k0 B | KL(A, B) | TV <= | "
          "max(E L_A, E L_B) >= |")
    print("| ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: |")
    for a1, a2 in (PAPER_PAIRS[0], PAPER_PAIRS[3]):
        for rho in RATIOS:
            rb = rho * 10.0 if rho <= 1.0 else rho / 10.0
            b, kl, tv, bound = two_point(a1, a2, rho, rb, n)
            print(f"| {a1:.4f} | {a2:.4f} | {rho:g} | {b[0]:.4f}, {b[1]:.4f}, {b[2]:.3f}, "
                  f"{b[3]:.3f} | {dare(a1, a2, 1.0, rho)[0][0]:.3f} | {dare(*b)[0][0]:.3f} | "
                  f"{kl:.3g} | {tv:.3f} | {bound:.3f} |")
    print()
    print("# 3. White drift, total variance T = q + r: MSE / T of three tunings and the optimum")
    print("| r/q | optimum | raw record (g = 1) | white model, constant output (g = 0) | "
          "q = r (g = 1/2) | worst case over all r/q |")
    print("| ---: | ---: | ---: | ---: | ---: | --- |")
    for rho in (0.1, 0.3, 1.0, 3.0, 10.0):
        w = 1.0 / (1.0 + rho)
        print(f"| {rho:g} | {w * (1 - w):.4f} | {1 - w:.4f} | {w:.4f} | 0.2500 | "
              "raw 1, white 1, q = r 0.25 |")


if __name__ == "__main__":
    main()
