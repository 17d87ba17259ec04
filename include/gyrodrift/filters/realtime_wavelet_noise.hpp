// Streaming level-1 coefficients of the symmetric-extended sliding window, and the
// incremental median(|d1|) noise estimate of the real-time threshold denoiser (paper 000
// sec. 2.3 / paper 004 sec. 2.2).
//
// Window w = x[s..t] (N samples, s = t - N + 1), ext = [w, reverse(w)] (2N, periodic). For a
// 2M-tap analysis filter F (pywt rec_lo for cA, rec_hi for cD), m0 = 1 - M:
//   c[k] = sum_i F[i] ext[(2k + m0 + i) mod 2N], k = 0..N-1.
// Three kinds of coefficients:
//   * first-half interior (support inside w):  c[k] = u[s + 2k], u[tau] = sum_i F[i] x[tau+m0+i]
//   * second-half interior (inside reverse(w)): c[k] = v[t + N - 2k], v[sig] = sum_i F[i] x[sig-m0-i]
//   * about 2M boundary coefficients straddling a junction of the extension: computed directly.
// u and v are causal FIR streams (one new value each per input sample), kept in rings.
//
// SlidingDetailMedian: the interior values used at time t are those of one parity (s's for
// u, t's for v); per parity class the set is a sliding window that loses one value and gains
// one every second sample, kept sorted by binary-search insert/erase. The median of the union
// (2 x interior + boundary = N values) is found by selection over three sorted sequences in
// O(log N) instead of an O(N) selection per sample.
//
// Fixed capacity, no heap, noexcept.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace gyrodrift {

template <class Scalar, std::size_t N, std::size_t MaxTaps = 16>
class Level1Stream {
  static_assert((N & (N - 1)) == 0 && N >= 4, "N must be a power of two");

 public:
  // f: analysis taps F[0..taps), taps even, 2 <= taps <= MaxTaps, taps <= N / 2.
  bool configure(const Scalar* f, std::size_t taps) noexcept {
    if (taps < 2 || taps > MaxTaps || taps % 2 != 0 || taps > N / 2) return false;
    taps_ = taps;
    for (std::size_t i = 0; i < taps; ++i) f_[i] = f[i];
    const std::size_t m = taps / 2;  // m0 = 1 - m
    k1_lo_ = m / 2;                  // first half: 2k + m0 >= 0, i.e. k >= ceil((m - 1) / 2)
    k1_hi_ = (N - m - 1) / 2;        // 2k + m0 + taps - 1 <= N - 1
    k2_lo_ = N / 2 + k1_lo_;         // second half: the same inside [N, 2N)
    k2_hi_ = N / 2 + k1_hi_;
    configured_ = true;
    reset();
    return true;
  }

  void reset() noexcept { n_seen_ = 0; }
  bool configured() const noexcept { return configured_; }

  // Once per accepted sample, after it entered the window w (last N samples, oldest first).
  // Returns the stream index t of the newest sample.
  std::size_t update(const Scalar* w) noexcept {
    const std::size_t t = n_seen_++;
    if (t + 1 >= taps_) {
      const std::size_t m = taps_ / 2;
      Scalar u = Scalar(0), v = Scalar(0);
      // u[t - m]: x[tau + m0 + i] = x[t - (taps - 1 - i)] = w[N - taps + i].
      for (std::size_t i = 0; i < taps_; ++i) u += f_[i] * w[N - taps_ + i];
      // v[t - m + 1]: x[sig - m0 - i] = x[t - i] = w[N - 1 - i].
      for (std::size_t i = 0; i < taps_; ++i) v += f_[i] * w[N - 1 - i];
      u_ring_[(t - m) & (N - 1)] = u;
      v_ring_[(t - m + 1) & (N - 1)] = v;
    }
    return t;
  }

  bool interior(std::size_t k) const noexcept {
    return (k >= k1_lo_ && k <= k1_hi_) || (k >= k2_lo_ && k <= k2_hi_);
  }

  // Coefficient k computed directly from the window (any k; used for boundary ones).
  Scalar direct(const Scalar* w, std::size_t k) const noexcept {
    const std::size_t m = taps_ / 2;
    Scalar c = Scalar(0);
    for (std::size_t i = 0; i < taps_; ++i) {
      const std::size_t e = (2 * k + 2 * N + 1 + i - m) & (2 * N - 1);  // (2k + m0 + i) mod 2N
      c += f_[i] * (e < N ? w[e] : w[2 * N - 1 - e]);
    }
    return c;
  }

  // The full band c[0..N) of the current (full) window whose newest sample has index t.
  void assemble(const Scalar* w, std::size_t t, Scalar* out) const noexcept {
    assemble_interior(t, out);
    for (std::size_t k = 0; k < k1_lo_; ++k) out[k] = direct(w, k);
    for (std::size_t k = k1_hi_ + 1; k < k2_lo_; ++k) out[k] = direct(w, k);
    for (std::size_t k = k2_hi_ + 1; k < N; ++k) out[k] = direct(w, k);
  }

  // Only the interior coefficients (ring values) of that band.
  void assemble_interior(std::size_t t, Scalar* out) const noexcept {
    const std::size_t s = t + 1 - N;
    for (std::size_t k = k1_lo_; k <= k1_hi_; ++k) out[k] = u_ring_[(s + 2 * k) & (N - 1)];
    for (std::size_t k = k2_lo_; k <= k2_hi_; ++k) out[k] = v_ring_[(t + N - 2 * k) & (N - 1)];
  }

  // Boundary indices, in increasing order: [0, k1_lo), (k1_hi, k2_lo), (k2_hi, N).
  template <class Fn>
  void for_each_boundary(Fn&& fn) const noexcept {
    for (std::size_t k = 0; k < k1_lo_; ++k) fn(k);
    for (std::size_t k = k1_hi_ + 1; k < k2_lo_; ++k) fn(k);
    for (std::size_t k = k2_hi_ + 1; k < N; ++k) fn(k);
  }

  std::size_t taps_ = 0;
  std::size_t k1_lo_ = 0, k1_hi_ = 0, k2_lo_ = 0, k2_hi_ = 0;
  Scalar u_ring_[N] = {};
  Scalar v_ring_[N] = {};

 private:
  bool configured_ = false;
  std::size_t n_seen_ = 0;
  Scalar f_[MaxTaps] = {};
};

template <class Scalar, std::size_t N, std::size_t MaxTaps = 16>
class SlidingDetailMedian {
  static constexpr std::size_t kHalf = N / 2;

 public:
  // g: high-pass taps (pywt rec_hi), same conditions as Level1Stream::configure.
  bool configure(const Scalar* g, std::size_t taps) noexcept {
    const bool ok = d1_.configure(g, taps);
    reset();
    return ok;
  }

  void reset() noexcept {
    d1_.reset();
    t_ = 0;
    full_ = false;
    for (int p = 0; p < 2; ++p) {
      u_init_[p] = v_init_[p] = false;
      u_n_[p] = v_n_[p] = 0;
    }
  }

  // Once per accepted sample, after it entered the window w (last N samples, oldest first).
  // Returns median(|d1|) once the window is full, else 0.
  Scalar update(const Scalar* w) noexcept {
    if (!d1_.configured()) return Scalar(0);
    const std::size_t t = d1_.update(w);
    t_ = t;
    full_ = t + 1 >= N;
    if (!full_) return Scalar(0);
    const std::size_t s = t + 1 - N;
    const auto& st = d1_;
    // First-half interior, parity of s: tau = s + 2k, k in [k1_lo, k1_hi].
    const int pu = static_cast<int>(s & 1u);
    const std::size_t tau_lo = s + 2 * st.k1_lo_, tau_hi = s + 2 * st.k1_hi_;
    if (!u_init_[pu] || !slide(u_sorted_[pu], u_n_[pu], mag(st.u_ring_[(tau_lo - 2) & (N - 1)]),
                                mag(st.u_ring_[tau_hi & (N - 1)]))) {
      u_n_[pu] = 0;
      for (std::size_t tau = tau_lo; tau <= tau_hi; tau += 2) {
        u_sorted_[pu][u_n_[pu]++] = mag(st.u_ring_[tau & (N - 1)]);
      }
      std::sort(u_sorted_[pu], u_sorted_[pu] + u_n_[pu]);
      u_init_[pu] = true;
    }
    // Second-half interior, parity of t: sig = t + N - 2k, k in [k2_lo, k2_hi].
    const int pv = static_cast<int>(t & 1u);
    const std::size_t sig_lo = t + N - 2 * st.k2_hi_, sig_hi = t + N - 2 * st.k2_lo_;
    if (!v_init_[pv] || !slide(v_sorted_[pv], v_n_[pv], mag(st.v_ring_[(sig_lo - 2) & (N - 1)]),
                                mag(st.v_ring_[sig_hi & (N - 1)]))) {
      v_n_[pv] = 0;
      for (std::size_t sig = sig_lo; sig <= sig_hi; sig += 2) {
        v_sorted_[pv][v_n_[pv]++] = mag(st.v_ring_[sig & (N - 1)]);
      }
      std::sort(v_sorted_[pv], v_sorted_[pv] + v_n_[pv]);
      v_init_[pv] = true;
    }
    // Boundary coefficients: kept signed for assemble(), and insertion-sorted by magnitude
    // (about 2 x taps of them).
    std::size_t nb = 0;
    st.for_each_boundary([&](std::size_t k) noexcept {
      const Scalar d = st.direct(w, k);
      bnd_signed_[nb] = d;
      const Scalar a = mag(d);
      std::size_t j = nb++;
      while (j > 0 && bnd_[j - 1] > a) {
        bnd_[j] = bnd_[j - 1];
        --j;
      }
      bnd_[j] = a;
    });
    // N even: median = mean of ranks N/2 - 1 and N/2 (0-based) of the union.
    Scalar lo = Scalar(0), hi = Scalar(0);
    select_pair(u_sorted_[pu], u_n_[pu], v_sorted_[pv], v_n_[pv], bnd_, nb, kHalf - 1, lo, hi);
    return (lo + hi) * Scalar(0.5);
  }

  // The signed level-1 detail band of the current full window (after update()).
  void assemble(Scalar* out) const noexcept {
    d1_.assemble_interior(t_, out);
    std::size_t i = 0;
    d1_.for_each_boundary([&](std::size_t k) noexcept { out[k] = bnd_signed_[i++]; });
  }
  bool full() const noexcept { return full_; }

 private:
  // |c| with NaN (an overflowed stream on absurd input, |x| ~ 1e38 in float) mapped to +Inf,
  // so the sorted arrays keep a strict weak order; finite data is unaffected.
  static Scalar mag(Scalar c) noexcept {
    const Scalar a = std::fabs(c);
    return a == a ? a : std::numeric_limits<Scalar>::infinity();
  }

  // Sorted array: erase one copy of `out` and insert `in`. False if `out` is not found
  // (non-finite intermediate values); the caller then rebuilds the class from the ring.
  static bool slide(Scalar* a, std::size_t n, Scalar out, Scalar in) noexcept {
    Scalar* pos = std::lower_bound(a, a + n, out);
    if (pos == a + n || !(*pos == out)) return false;
    Scalar* ins = std::lower_bound(a, a + n, in);
    if (ins <= pos) {  // shift [ins, pos) right by one over the erased slot
      std::copy_backward(ins, pos, pos + 1);
      *ins = in;
    } else {  // shift (pos, ins) left by one
      std::copy(pos + 1, ins, pos);
      *(ins - 1) = in;
    }
    return true;
  }

  // Values of ranks r and r+1 of the union of three sorted arrays. Each round discards the
  // first s <= max(1, k/3) elements of the array with the smallest probe a[s-1]: at most
  // 3s - 3 < k elements precede that probe, so all discarded ones rank below the target.
  static void select_pair(const Scalar* a, std::size_t na, const Scalar* b, std::size_t nb,
                          const Scalar* c, std::size_t nc, std::size_t r, Scalar& first,
                          Scalar& second) noexcept {
    std::size_t k = r;
    while (k > 0) {
      const std::size_t step = k / 3 > 0 ? k / 3 : 1;
      const std::size_t sa = std::min(step, na), sb = std::min(step, nb), sc = std::min(step, nc);
      int pick = -1;
      Scalar best = Scalar(0);
      if (sa > 0) {
        pick = 0;
        best = a[sa - 1];
      }
      if (sb > 0 && (pick < 0 || b[sb - 1] < best)) {
        pick = 1;
        best = b[sb - 1];
      }
      if (sc > 0 && (pick < 0 || c[sc - 1] < best)) pick = 2;
      if (pick == 0) {
        a += sa;
        na -= sa;
        k -= sa;
      } else if (pick == 1) {
        b += sb;
        nb -= sb;
        k -= sb;
      } else if (pick == 2) {
        c += sc;
        nc -= sc;
        k -= sc;
      } else {
        break;  // all empty: cannot happen for r < na + nb + nc
      }
    }
    for (int out = 0; out < 2; ++out) {  // pop the two smallest heads
      int pick = -1;
      Scalar best = Scalar(0);
      if (na > 0) {
        pick = 0;
        best = a[0];
      }
      if (nb > 0 && (pick < 0 || b[0] < best)) {
        pick = 1;
        best = b[0];
      }
      if (nc > 0 && (pick < 0 || c[0] < best)) {
        pick = 2;
        best = c[0];
      }
      if (pick == 0) {
        ++a;
        --na;
      } else if (pick == 1) {
        ++b;
        --nb;
      } else if (pick == 2) {
        ++c;
        --nc;
      }
      (out == 0 ? first : second) = best;
    }
  }

  Level1Stream<Scalar, N, MaxTaps> d1_;
  std::size_t t_ = 0;
  bool full_ = false;
  Scalar u_sorted_[2][kHalf] = {};
  Scalar v_sorted_[2][kHalf] = {};
  std::size_t u_n_[2] = {0, 0};
  std::size_t v_n_[2] = {0, 0};
  bool u_init_[2] = {false, false};
  bool v_init_[2] = {false, false};
  Scalar bnd_[4 * MaxTaps] = {};
  Scalar bnd_signed_[4 * MaxTaps] = {};
};

}  // namespace gyrodrift
