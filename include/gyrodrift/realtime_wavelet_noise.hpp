// Incremental median(|d1|) of the symmetric-extended sliding window (the noise estimate of
// the real-time threshold denoiser, paper 000 sec. 2.3 / paper 004 sec. 2.2).
//
// Window w = x[s..t] (N samples, s = t - N + 1), ext = [w, reverse(w)] (2N, periodic),
// d1[k] = sum_i G[i] ext[(2k + m0 + i) mod 2N], k = 0..N-1, G = the 2M-tap high-pass
// (pywt rec_hi), m0 = 1 - M. Three kinds of level-1 coefficients:
//   * first-half interior (support inside w):  d1[k] = u[s + 2k], u[tau] = sum_i G[i] x[tau+m0+i]
//   * second-half interior (inside reverse(w)): d1[k] = v[t + N - 2k], v[sig] = sum_i G[i] x[sig-m0-i]
//   * 4M boundary coefficients straddling a junction of the extension: computed directly.
// u and v are causal FIR streams (one new value each per input). The interior values used at
// time t are those of one parity (s's for u, t's for v); per parity class the set is a
// sliding window that loses one value and gains one every second sample, kept sorted by a
// binary-search insert/erase. The median of the union (N = 2 x interior + boundary values)
// is found by selection over three sorted sequences in O(log N).
//
// Fixed capacity, no heap, noexcept. Values are |d1| (the median is of magnitudes).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

namespace gyrodrift {

template <class Scalar, std::size_t N, std::size_t MaxTaps = 16>
class SlidingDetailMedian {
  static_assert((N & (N - 1)) == 0 && N >= 4, "N must be a power of two");
  static constexpr std::size_t kHalf = N / 2;

 public:
  // g: high-pass taps G[0..taps), taps even, 2 <= taps <= MaxTaps, taps <= N / 2.
  bool configure(const Scalar* g, std::size_t taps) noexcept {
    if (taps < 2 || taps > MaxTaps || taps % 2 != 0 || taps > N / 2) return false;
    taps_ = taps;
    for (std::size_t i = 0; i < taps; ++i) g_[i] = g[i];
    const std::size_t m = taps / 2;  // m0 = 1 - m
    // First half: 2k + m0 >= 0 and 2k + m0 + taps - 1 <= N - 1.
    k1_lo_ = m / 2;                  // ceil((m - 1) / 2)
    k1_hi_ = (N - m - 1) / 2;        // floor((N - 1 - m) / 2)
    // Second half: 2k + m0 >= N and 2k + m0 + taps - 1 <= 2N - 1.
    k2_lo_ = kHalf + k1_lo_;
    k2_hi_ = kHalf + k1_hi_;
    configured_ = true;
    reset();
    return true;
  }

  void reset() noexcept {
    n_seen_ = 0;
    for (int p = 0; p < 2; ++p) {
      u_init_[p] = false;
      v_init_[p] = false;
      u_n_[p] = 0;
      v_n_[p] = 0;
    }
  }

  // Call once per accepted sample, after it is in the window. w: the last N samples, oldest
  // first (entries before the first sample are ignored). Returns median(|d1|) once
  // n_seen >= N (the window is full), else 0.
  Scalar update(const Scalar* w) noexcept {
    if (!configured_) return Scalar(0);
    const std::size_t t = n_seen_++;  // stream index of the newest sample
    const std::size_t m = taps_ / 2;
    // x[t - a] = w[N - 1 - a].
    if (t + 1 >= taps_) {
      // u[tau], tau = t - m: x[tau + m0 + i] = x[t - (taps - 1 - i)].
      Scalar u = Scalar(0), v = Scalar(0);
      for (std::size_t i = 0; i < taps_; ++i) u += g_[i] * w[N - taps_ + i];
      // v[sig], sig = t - m + 1: x[sig - m0 - i] = x[t - i].
      for (std::size_t i = 0; i < taps_; ++i) v += g_[i] * w[N - 1 - i];
      u_ring_[(t - m) & (N - 1)] = std::fabs(u);
      v_ring_[(t - m + 1) & (N - 1)] = std::fabs(v);
    }
    if (t + 1 < N) return Scalar(0);
    const std::size_t s = t + 1 - N;

    // First-half interior, parity of s: tau = s + 2k, k in [k1_lo, k1_hi].
    const int pu = static_cast<int>(s & 1u);
    const std::size_t tau_lo = s + 2 * k1_lo_, tau_hi = s + 2 * k1_hi_;
    if (!u_init_[pu] || !slide(u_sorted_[pu], u_n_[pu], u_ring_[(tau_lo - 2) & (N - 1)],
                                u_ring_[tau_hi & (N - 1)])) {
      u_n_[pu] = 0;
      for (std::size_t tau = tau_lo; tau <= tau_hi; tau += 2) u_sorted_[pu][u_n_[pu]++] = u_ring_[tau & (N - 1)];
      std::sort(u_sorted_[pu], u_sorted_[pu] + u_n_[pu]);
      u_init_[pu] = true;
    }
    // Second-half interior, parity of t: sig = t + N - 2k, k in [k2_lo, k2_hi].
    const int pv = static_cast<int>(t & 1u);
    const std::size_t sig_lo = t + N - 2 * k2_hi_, sig_hi = t + N - 2 * k2_lo_;
    if (!v_init_[pv] || !slide(v_sorted_[pv], v_n_[pv], v_ring_[(sig_lo - 2) & (N - 1)],
                                v_ring_[sig_hi & (N - 1)])) {
      v_n_[pv] = 0;
      for (std::size_t sig = sig_lo; sig <= sig_hi; sig += 2) v_sorted_[pv][v_n_[pv]++] = v_ring_[sig & (N - 1)];
      std::sort(v_sorted_[pv], v_sorted_[pv] + v_n_[pv]);
      v_init_[pv] = true;
    }
    // Boundary coefficients: k outside both interior ranges.
    std::size_t nb = 0;
    for (std::size_t k = 0; k < N; ++k) {
      if ((k >= k1_lo_ && k <= k1_hi_) || (k >= k2_lo_ && k <= k2_hi_)) continue;
      Scalar d = Scalar(0);
      for (std::size_t i = 0; i < taps_; ++i) {
        // ext index e = (2k + m0 + i) mod 2N, m0 = 1 - m.
        const std::size_t e = (2 * k + 2 * N + 1 + i - m) & (2 * N - 1);
        d += g_[i] * (e < N ? w[e] : w[2 * N - 1 - e]);
      }
      const Scalar a = std::fabs(d);
      std::size_t j = nb++;  // insertion sort (at most 4 x taps/2 values)
      while (j > 0 && bnd_[j - 1] > a) {
        bnd_[j] = bnd_[j - 1];
        --j;
      }
      bnd_[j] = a;
    }
    // N even: median = mean of ranks N/2 - 1 and N/2 (0-based) of the union.
    Scalar lo = Scalar(0), hi = Scalar(0);
    select_pair(u_sorted_[pu], u_n_[pu], v_sorted_[pv], v_n_[pv], bnd_, nb, kHalf - 1, lo, hi);
    return (lo + hi) * Scalar(0.5);
  }

 private:
  // Sorted array: erase one copy of `out` and insert `in`. False if `out` is not found
  // (non-finite data), then the caller rebuilds the class from the ring.
  static bool slide(Scalar* a, std::size_t n, Scalar out, Scalar in) noexcept {
    Scalar* pos = std::lower_bound(a, a + n, out);
    if (pos == a + n || !(*pos == out)) return false;
    Scalar* ins = std::lower_bound(a, a + n, in);
    if (ins <= pos) {  // shift [ins, pos) right by one
      std::copy_backward(ins, pos, pos + 1);
      *ins = in;
    } else {  // shift (pos, ins) left by one
      std::copy(pos + 1, ins, pos);
      *(ins - 1) = in;
    }
    return true;
  }

  // Elements of ranks r and r+1 of the union of three sorted arrays (a, b, c).
  static void select_pair(const Scalar* a, std::size_t na, const Scalar* b, std::size_t nb,
                          const Scalar* c, std::size_t nc, std::size_t r, Scalar& first,
                          Scalar& second) noexcept {
    std::size_t k = r;  // discard k smallest elements, O(log) rounds
    while (k > 0) {
      const std::size_t step = k / 3 > 0 ? k / 3 : 1;
      const std::size_t sa = std::min(step, na), sb = std::min(step, nb), sc = std::min(step, nc);
      // The array with the smallest probe: its first s elements are among the k smallest.
      int pick = -1;
      Scalar best = Scalar(0);
      if (sa > 0) { pick = 0; best = a[sa - 1]; }
      if (sb > 0 && (pick < 0 || b[sb - 1] < best)) { pick = 1; best = b[sb - 1]; }
      if (sc > 0 && (pick < 0 || c[sc - 1] < best)) { pick = 2; best = c[sc - 1]; }
      if (pick == 0) { a += sa; na -= sa; k -= sa; }
      else if (pick == 1) { b += sb; nb -= sb; k -= sb; }
      else if (pick == 2) { c += sc; nc -= sc; k -= sc; }
      else break;  // all empty (cannot happen: r < total)
    }
    for (int out = 0; out < 2; ++out) {  // pop the two smallest heads
      int pick = -1;
      Scalar best = Scalar(0);
      if (na > 0) { pick = 0; best = a[0]; }
      if (nb > 0 && (pick < 0 || b[0] < best)) { pick = 1; best = b[0]; }
      if (nc > 0 && (pick < 0 || c[0] < best)) { pick = 2; best = c[0]; }
      if (pick == 0) { ++a; --na; }
      else if (pick == 1) { ++b; --nb; }
      else if (pick == 2) { ++c; --nc; }
      (out == 0 ? first : second) = best;
    }
  }

  bool configured_ = false;
  std::size_t taps_ = 0;
  std::size_t k1_lo_ = 0, k1_hi_ = 0, k2_lo_ = 0, k2_hi_ = 0;
  std::size_t n_seen_ = 0;
  Scalar g_[MaxTaps] = {};
  Scalar u_ring_[N] = {};
  Scalar v_ring_[N] = {};
  Scalar u_sorted_[2][kHalf] = {};
  Scalar v_sorted_[2][kHalf] = {};
  std::size_t u_n_[2] = {0, 0};
  std::size_t v_n_[2] = {0, 0};
  bool u_init_[2] = {false, false};
  bool v_init_[2] = {false, false};
  Scalar bnd_[4 * MaxTaps] = {};
};

}  // namespace gyrodrift
