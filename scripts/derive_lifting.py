#!/usr/bin/env python3
"""Derive lifting factorizations of Daubechies db4/db8 in high precision and emit C++ headers.

Method (Daubechies & Sweldens 1998, "Factoring wavelet transforms into lifting steps"):

1. The Daubechies filter dbN (2N taps) is built in 60-digit arithmetic by spectral
   factorization of P(y) = sum_k C(N-1+k, k) y^k, y = (2 - z - 1/z)/4, keeping the roots
   inside the unit circle (extremal phase, PyWavelets' `dbN`). It is checked against
   PyWavelets' double coefficients (1e-15).
2. PyWavelets' periodized analysis is cA[k] = sum_m hA[m] x[2k+m], cD[k] = sum_m hD[m] x[2k+m]
   with m = -(N-1)..N (read off impulse responses of `pywt.dwt(mode="periodization")`,
   hA = rec_lo, hD = rec_hi). With e[k] = x[2k], o[k] = x[2k+1] and the operator
   z^j s[k] = s[k+j], the analysis polyphase matrix is Pa = [[Ae, Ao], [De, Do]].
3. The Euclidean algorithm on the first row (Ae, Ao): a predict step o += p e is the right
   factor [[1,0],[p,1]] and turns the row into (Ae - p Ao, Ao); an update e += u o turns it
   into (Ae, Ao - u Ae). Each division may cancel the dividend's leading terms, trailing
   terms, or one of each, so there are many factorizations. All of them are enumerated;
   when the row is (K z^s, 0) the remaining matrix is diag(K z^s, D') [[1,0],[C'/D',1]]
   (det Pa is a monomial), i.e. one more predict and the output scaling/rotation.
4. Each factorization is checked in exact-ish arithmetic (60 digits) against the filter
   bank, and its float32 error is measured against pywt in double on unit-variance noise.
   The chosen one minimises the largest |lifting coefficient| (ties: float32 error).

Run:  python3 scripts/derive_lifting.py            # prints the table, rewrites the headers
      python3 scripts/derive_lifting.py --check    # exit 1 if the headers differ
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import mpmath as mp
import numpy as np
import pywt

mp.mp.dps = 60
REPO = Path(__file__).resolve().parent.parent

Laurent = dict[int, mp.mpf]  # power -> coefficient; operator z^j s[k] = s[k+j]


def daubechies_rec_lo(n_vm: int) -> list[mp.mpf]:
    """Extremal-phase Daubechies lowpass (PyWavelets' rec_lo of dbN), 60 digits."""
    p_coefs = [mp.binomial(n_vm - 1 + k, k) for k in range(n_vm)]  # P(y), ascending powers
    y_roots = mp.polyroots(list(reversed(p_coefs)), maxsteps=400, extraprec=400)
    z_roots = []
    for y in y_roots:
        # z + 1/z = 2 - 4y  ->  z^2 - (2 - 4y) z + 1 = 0; keep the root inside the unit circle.
        b = 2 - 4 * y
        disc = mp.sqrt(b * b - 4)
        r1, r2 = (b + disc) / 2, (b - disc) / 2
        z_roots.append(r1 if abs(r1) < 1 else r2)
    poly = [mp.mpc(1)]
    for r in z_roots:  # multiply by (z - r), coefficients ascending in z
        poly = (
            [(-r) * poly[0]] + [poly[i - 1] - r * poly[i] for i in range(1, len(poly))] + [poly[-1]]
        )
    for _ in range(n_vm):  # multiply by (1 + z)
        poly = [poly[0]] + [poly[i - 1] + poly[i] for i in range(1, len(poly))] + [poly[-1]]
    h = [mp.re(c) for c in poly]
    scale = mp.sqrt(2) / mp.fsum(h)
    h = [c * scale for c in h]
    ref = np.array(pywt.Wavelet(f"db{n_vm}").rec_lo)
    if np.max(np.abs(np.array([float(c) for c in h]) - ref)) > 1e-14:
        h = list(reversed(h))
    err = np.max(np.abs(np.array([float(c) for c in h]) - ref))
    assert err < 1e-14, f"db{n_vm}: spectral factor does not match PyWavelets ({err})"
    return h


def analysis_polyphase(n_vm: int) -> tuple[list[list[Laurent]], int]:
    h = daubechies_rec_lo(n_vm)
    taps = 2 * n_vm
    g = [(-1) ** k * h[taps - 1 - k] for k in range(taps)]  # rec_hi
    assert (
        np.max(np.abs(np.array([float(c) for c in g]) - pywt.Wavelet(f"db{n_vm}").rec_hi)) < 1e-14
    )
    m0 = -(n_vm - 1)
    # Confirm the index map on PyWavelets itself (impulse responses, n = 4 * taps).
    n = 4 * taps
    k_probe = n // 4
    for i in range(n):
        x = np.zeros(n)
        x[i] = 1.0
        ca, cd = pywt.dwt(x, f"db{n_vm}", mode="periodization")
        m = (i - 2 * k_probe) % n
        m = m - n if m > n // 2 else m
        want_a = float(h[m - m0]) if m0 <= m < m0 + taps else 0.0
        want_d = float(g[m - m0]) if m0 <= m < m0 + taps else 0.0
        assert abs(ca[k_probe] - want_a) < 1e-14 and abs(cd[k_probe] - want_d) < 1e-14
    ae: Laurent = {}
    ao: Laurent = {}
    de: Laurent = {}
    do: Laurent = {}
    for idx in range(taps):
        m = m0 + idx
        j, par = divmod(m, 2)
        (ao if par else ae)[j] = h[idx]
        (do if par else de)[j] = g[idx]
    return [[ae, ao], [de, do]], m0


def trim(p: Laurent) -> Laurent:
    big = max((abs(v) for v in p.values()), default=mp.mpf(0))
    return {k: v for k, v in p.items() if abs(v) > big * mp.mpf(10) ** -40 and abs(v) > 0}


def mul(a: Laurent, b: Laurent) -> Laurent:
    out: dict[int, mp.mpf] = {}
    for i, x in a.items():
        for j, y in b.items():
            out[i + j] = out.get(i + j, 0) + x * y
    return out


def sub(a: Laurent, b: Laurent) -> Laurent:
    out = dict(a)
    for k, v in b.items():
        out[k] = out.get(k, 0) - v
    return trim(out)


def span(p: Laurent) -> int:
    return max(p) - min(p) + 1 if p else 0


def quotient(a: Laurent, b: Laurent, n_top: int) -> Laurent:
    """Quotient q with len(a) - len(b) + 1 terms cancelling n_top leading and the rest
    trailing terms of a (len(a - q b) = len(b) - 1 generically)."""
    nq = span(a) - span(b) + 1
    q: Laurent = {}
    r = dict(a)
    for _ in range(n_top):  # leading terms, highest power first
        pw = max(r) - max(b)
        q[pw] = r[max(r)] / b[max(b)]
        r = sub(r, mul({pw: q[pw]}, b))
    for _ in range(nq - n_top):  # trailing terms, lowest power first
        pw = min(r) - min(b)
        q[pw] = r[min(r)] / b[min(b)]
        r = sub(r, mul({pw: q[pw]}, b))
    return q


@dataclass
class Step:
    target: int  # 1: predict (odd += p even), 0: update (even += u odd)
    poly: Laurent


@dataclass
class Factorization:
    steps: list[Step]
    k_a: mp.mpf  # cA[k] = k_a * band[band_a][k + shift_a]
    shift_a: int
    k_d: mp.mpf  # cD[k] = k_d * band[1 - band_a][k + shift_d]
    shift_d: int
    band_a: int

    def max_coef(self) -> float:
        return max(float(abs(v)) for s in self.steps for v in s.poly.values())


def finish(ae: Laurent, ao: Laurent, de: Laurent, do: Laurent, steps: list[Step]) -> Factorization:
    """Row 0 is reduced to a monomial and a zero: split off the last step and the scaling."""
    if not ao:  # row 0 = (K z^s, 0): M = diag(K z^s, D') [[1,0],[C'/D',1]]
        assert len(ae) == 1 and len(do) == 1
        (s, k), (t, dk) = next(iter(ae.items())), next(iter(do.items()))
        p = {pw - t: v / dk for pw, v in de.items()}
        return Factorization([*steps, Step(1, p)] if p else steps, k, s, dk, t, 0)
    # row 0 = (0, K z^s): M = [[0, K z^s],[C', D']]; cA comes from the odd band.
    assert len(ao) == 1 and len(de) == 1
    (s, k), (t, ck) = next(iter(ao.items())), next(iter(de.items()))
    u = {pw - t: v / ck for pw, v in do.items()}
    return Factorization([*steps, Step(0, u)] if u else steps, k, s, ck, t, 1)


def factorizations(
    ae: Laurent, ao: Laurent, de: Laurent, do: Laurent, steps: list[Step], turn: int
):
    """All factorizations (depth-first over the quotient choices)."""
    if not ae or not ao:
        yield finish(ae, ao, de, do, steps)
        return
    if turn == 0:  # reduce Ae by Ao: predict p, col0 -= p col1
        nq = span(ae) - span(ao) + 1
        if nq < 1:
            return
        for n_top in range(nq + 1):
            p = quotient(ae, ao, n_top)
            yield from factorizations(
                sub(ae, mul(p, ao)), ao, sub(de, mul(p, do)), do, [*steps, Step(1, p)], 1
            )
    else:  # reduce Ao by Ae: update u, col1 -= u col0
        nq = span(ao) - span(ae) + 1
        if nq < 1:
            return
        for n_top in range(nq + 1):
            u = quotient(ao, ae, n_top)
            yield from factorizations(
                ae, sub(ao, mul(u, ae)), de, sub(do, mul(u, de)), [*steps, Step(0, u)], 0
            )


def apply(f: Factorization, x: np.ndarray, dtype: type) -> tuple[np.ndarray, np.ndarray]:
    """Forward one level with the factorization, in `dtype` arithmetic (periodic)."""
    bands = [x[0::2].astype(dtype).copy(), x[1::2].astype(dtype).copy()]
    for st in f.steps:
        other = bands[1 - st.target]
        acc = np.zeros_like(other)
        for pw, c in sorted(st.poly.items()):
            acc = acc + dtype(float(c)) * np.roll(other, -pw)
        bands[st.target] = bands[st.target] + acc
    ca = dtype(float(f.k_a)) * np.roll(bands[f.band_a], -f.shift_a)
    cd = dtype(float(f.k_d)) * np.roll(bands[1 - f.band_a], -f.shift_d)
    return ca, cd


def candidates(n_vm: int) -> list[Factorization]:
    pa, _ = analysis_polyphase(n_vm)
    (ae, ao), (de, do) = pa
    out: list[Factorization] = []
    for first in (0, 1):
        out.extend(factorizations(ae, ao, de, do, [], first))
    return out


def float32_error(f: Factorization, wavelet: str, rng: np.random.Generator) -> float:
    x = rng.standard_normal(4096)
    ca, cd = pywt.dwt(x, wavelet, mode="periodization")
    fa, fd = apply(f, x, np.float32)
    return float(max(np.max(np.abs(fa - ca)), np.max(np.abs(fd - cd))))


def direct_float32_error(wavelet: str, rng: np.random.Generator) -> float:
    x = rng.standard_normal(4096)
    ca, cd = pywt.dwt(x, wavelet, mode="periodization")
    w = pywt.Wavelet(wavelet)
    n_vm = len(w.rec_lo) // 2
    h = np.array(w.rec_lo, dtype=np.float32)
    g = np.array(w.rec_hi, dtype=np.float32)
    x32 = x.astype(np.float32)
    fa = np.zeros(len(ca), np.float32)
    fd = np.zeros(len(cd), np.float32)
    for idx in range(len(h)):  # direct 2N-tap convolution, accumulated in float32
        xs = np.roll(x32, -(idx - (n_vm - 1)))[0::2]
        fa = fa + h[idx] * xs
        fd = fd + g[idx] * xs
    return float(max(np.max(np.abs(fa - ca)), np.max(np.abs(fd - cd))))


def choose(n_vm: int) -> tuple[Factorization, dict[str, float]]:
    wavelet = f"db{n_vm}"
    cands = candidates(n_vm)
    rng = np.random.default_rng(7)
    x = rng.standard_normal(256)
    ca, cd = pywt.dwt(x, wavelet, mode="periodization")
    good = []
    for f in cands:
        fa, fd = apply(f, x, np.float64)
        if max(np.max(np.abs(fa - ca)), np.max(np.abs(fd - cd))) < 1e-12:
            good.append(f)
    good.sort(key=lambda f: f.max_coef())
    best = good[:12]
    errs = [float32_error(f, wavelet, np.random.default_rng(11)) for f in best]
    i = min(range(len(best)), key=lambda i: (best[i].max_coef() >= 1.0, errs[i]))
    stats = {
        "candidates": len(cands),
        "exact": len(good),
        "max_coef_min": good[0].max_coef(),
        "max_coef_max": good[-1].max_coef(),
        "float32_err": errs[i],
        "direct_float32_err": direct_float32_error(wavelet, np.random.default_rng(11)),
    }
    return best[i], stats


def lit(v: mp.mpf) -> str:
    return mp.nstr(v, 25, min_fixed=-5, max_fixed=5, strip_zeros=False)


def emit_header(n_vm: int, f: Factorization, stats: dict[str, float]) -> str:
    name = f"db{n_vm}"
    max_taps = max(len(s.poly) for s in f.steps)
    lines = [
        "// GENERATED by scripts/derive_lifting.py -- do not edit.",
        f"// Lifting factorization of {name}",
        f"// (PyWavelets '{name}', periodization): {len(f.steps)} lifting steps + scaling.",
        "// Forward one level on x (even length n, h = n/2), e[k] = x[2k], o[k] = x[2k+1]:",
        "//   for each step:",
        "//     band[target][k] += sum_j coef[j] * band[1-target][(k + first + j) mod h]",
        "//   cA[k] = k_a * band[band_a][(k + shift_a) mod h],",
        "//   cD[k] = k_d * band[1-band_a][(k + shift_d) mod h]",
        "// which equals pywt.dwt(x, '" + name + "', mode='periodization') with NO index shift.",
        f"// Derivation: Euclidean algorithm over {int(stats['candidates'])} quotient choices, "
        f"{int(stats['exact'])} exact;",
        f"// largest |coef| over them ranges {stats['max_coef_min']:.3g} .. "
        f"{stats['max_coef_max']:.3g}; chosen: {f.max_coef():.6f}, K = {float(f.k_a):.6f}.",
        f"// float32 max error vs pywt (4096 N(0,1) samples): lifting {stats['float32_err']:.3g}, "
        f"direct {2 * n_vm}-tap {stats['direct_float32_err']:.3g}.",
        "#pragma once",
        "",
        "#include <cstddef>",
        "",
        '#include "lifting_step.hpp"',
        "",
        "namespace gyrodrift {",
        "",
        "template <class Scalar>",
        f"struct LiftingCoefficients{name.capitalize()} {{",
        f"  static constexpr int kSteps = {len(f.steps)};",
        f"  static constexpr std::size_t kMaxTaps = {max_taps};",
        f"  static constexpr int kFilterLength = {2 * n_vm};",
        f"  static constexpr int kBandA = {f.band_a};",
        f"  static constexpr int kShiftA = {f.shift_a};",
        f"  static constexpr int kShiftD = {f.shift_d};",
        f"  static constexpr Scalar kA = Scalar({lit(f.k_a)});",
        f"  static constexpr Scalar kD = Scalar({lit(f.k_d)});",
        f"  static constexpr Scalar kInvA = Scalar({lit(1 / f.k_a)});",
        f"  static constexpr Scalar kInvD = Scalar({lit(1 / f.k_d)});",
        "  static constexpr LiftingStep<Scalar, kMaxTaps> kStep[kSteps] = {",
    ]
    for s in f.steps:
        pws = sorted(s.poly)
        first = pws[0]
        coefs = [s.poly.get(p, mp.mpf(0)) for p in range(first, first + max_taps)]
        assert pws[-1] - first < max_taps
        cs = ", ".join(f"Scalar({lit(c)})" for c in coefs)
        lines.append(f"      {{{s.target}, {first}, {pws[-1] - first + 1}, {{{cs}}}}},")
    lines += ["  };", "};", "", "}  // namespace gyrodrift", ""]
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare with the headers, write nothing")
    args = ap.parse_args()
    status = 0
    for n_vm in (4, 8):
        f, stats = choose(n_vm)
        text = emit_header(n_vm, f, stats)
        print(f"db{n_vm}: steps={len(f.steps)} max|c|={f.max_coef():.6f} K={float(f.k_a):.9f}")
        for key, val in stats.items():
            print(f"  {key}: {val:.4g}")
        for s in f.steps:
            kind = "predict" if s.target == 1 else "update "
            print(
                f"  {kind} "
                + "  ".join(f"z^{p}:{mp.nstr(v, 17)}" for p, v in sorted(s.poly.items()))
            )
        path = REPO / "include" / "gyrodrift" / "filters" / f"lifting_coefficients_db{n_vm}.hpp"
        if args.check:
            if not path.exists() or path.read_text() != text:
                print(f"MISMATCH: {path} differs from the derivation", file=sys.stderr)
                status = 1
        else:
            path.write_text(text)
    return status


if __name__ == "__main__":
    sys.exit(main())
