// Fused multi-tau kernels for the overlapping Hadamard, modified Allan and total variances
// (the in-memory fast path; the per-tau streaming kernels of deviation_hadamard.hpp,
// deviation_modified.hpp and deviation_total.hpp remain the chunked path and the oracle).
//
// Same scheme as OadevFused (allan.hpp): every factor of a group is served from one pass.
// With X the phase (X_v = sum_{u<v} y_u; for the total variance y* is the evenly reflected
// record of deviation_total.hpp), each estimator's running quantity at term t is a fixed
// combination of phase values at four offsets:
//   ohdev, mdev: H_t = X_{t+3m} - 3 X_{t+2m} + 3 X_{t+m} - X_t             (SP 1065 eq. 20)
//   totdev:      D_t = X*_{t+1+m} - 2 X*_{t+1} + X*_{t+1-m}, t = 0..N-2     (eq. 25)
// and the modified variance sums V_t^2 with V_{t+1} = V_t + H_t (eq. 14). The record is cut
// into blocks of B terms; for block b the stretches of y every factor reads (its offsets;
// nearby offsets share one segment) become local prefix sums Q of (y - level) in double, and
//   H_{b+i} = H_b + sum_s c_s (Q_s[i] - Q_s[0])
// costs four loads and a few flops per factor and term, with no dependency chain; the
// modified variance then runs V through the block as eight independent chains (their
// starting values from the chains' sums, a second pass), so its adds pipeline too.
// Precision: H_b (and V_b) are carried from block to block in long double (block increments
// are differences of doubles); Q spans one segment (a few B samples) of data minus a line
// (the block's level plus the record's rate ramp times the sample index, fused_common.hpp
// RampLine), so its rounding is ~B eps (sigma + the data's excursion from that line over the
// block's streams) however long the record and however steep its ramp. The line cancels
// exactly: a constant because the coefficients sum to zero, the slope because they also
// annihilate a linear phase-rate term (third differences; the increments of totdev's second
// differences), except where totdev's windows reach its mirrored ends, where the reflected
// line leaves slope E(t) (ramp_edge), added back in closed form; the start values remove
// the same line and add back what it contributes to V and D. Measured on 1e6 samples of
// unit noise plus a 1e4-sigma ramp: <= 4e-13 relative to the long double kernels (it was
// up to 2.6e-8 with one level per block). V integrates H inside a
// block only: its double rounding spans at most one block of 1024 terms before it is folded
// into the long double carry. Squares are summed per block in double, then into long double.
// The starting values (term 0) are range sums of (y - level) in double, eight lanes.
// No allocation: fixed-capacity plan (MaxTaus factors) plus a caller-owned double workspace
// of workspace_doubles() elements; no exceptions; false on bad input or non-finite sums.
#pragma once
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "deviation_hadamard.hpp"
#include "deviation_modified.hpp"
#include "deviation_total.hpp"
#include "fused_common.hpp"

namespace gyrodrift {

enum class FusedDeviation : std::uint8_t { ohdev, mdev, totdev };

namespace fused_detail {

// Adds sum_i v_i and (First) sum_i (u0 + i) v_i, v_i = p[i step] - (a + slope i), i < len, to
// the eight lanes a0, a1 (step +1 or -1, a template argument so the +1 loop vectorizes).
template <int Step, bool First, class Scalar>
GYRODRIFT_FUSED_INLINE void moments_run(const Scalar* p, std::size_t len, double u0,
                                        double a, double slope, double* a0,
                                        double* a1) noexcept {
  constexpr std::size_t kLanes = 8;
  double w[kLanes];
  double line[kLanes];  // a + slope (i + l), advanced by 8 slope: exact on the RampLine grid
  for (std::size_t l = 0; l < kLanes; ++l) {
    w[l] = u0 + static_cast<double>(l);
    line[l] = a + slope * static_cast<double>(l);
  }
  const double step = slope * static_cast<double>(kLanes);
  std::size_t i = 0;
  for (; i + kLanes <= len; i += kLanes) {
    for (std::size_t l = 0; l < kLanes; ++l) {
      const double v = static_cast<double>(p[static_cast<std::ptrdiff_t>(i + l) * Step]) - line[l];
      line[l] += step;
      a0[l] += v;
      if (First) {
        a1[l] += w[l] * v;
        w[l] += static_cast<double>(kLanes);  // exact: integers below 2^53
      }
    }
  }
  for (; i < len; ++i) {
    const double v = static_cast<double>(p[static_cast<std::ptrdiff_t>(i) * Step]) -
                     (a + slope * static_cast<double>(i));
    a0[0] += v;
    if (First) a1[0] += (u0 + static_cast<double>(i)) * v;
  }
}

// sum_{u < len} v_u and (First) sum u v_u in double, eight lanes, v_u = y*[start + u] -
// (level + slope k_u), k_u the sample index y*[start + u] comes from; y* is y itself or
// (reflect) its even reflection, start may be negative then.
template <bool First, class Scalar>
GYRODRIFT_FUSED_INLINE void range_moments(const Scalar* y, std::size_t n, bool reflect,
                                          std::ptrdiff_t start, std::size_t len, double level,
                                          double slope, double& s0, double& s1) noexcept {
  constexpr std::size_t kLanes = 8;
  double a0[kLanes] = {};
  double a1[kLanes] = {};
  const auto sn = static_cast<std::ptrdiff_t>(n);
  std::size_t u = 0;
  while (u < len) {
    // One piece: a stretch read forwards (inside) or backwards (a mirrored end).
    const std::ptrdiff_t k = start + static_cast<std::ptrdiff_t>(u);
    std::size_t piece = len - u;
    const auto ud = static_cast<double>(u);
    if (!reflect || (k >= 0 && k < sn)) {
      const auto room = static_cast<std::size_t>(sn - k);
      if (reflect && room < piece) piece = room;
      moments_run<1, First>(y + k, piece, ud, level + slope * static_cast<double>(k), slope,
                            a0, a1);
    } else if (k < 0) {
      const auto room = static_cast<std::size_t>(-k);
      if (room < piece) piece = room;
      moments_run<-1, First>(y + (-1 - k), piece, ud,
                             level + slope * static_cast<double>(-1 - k), -slope, a0, a1);
    } else {
      moments_run<-1, First>(y + (2 * sn - 1 - k), piece, ud,
                             level + slope * static_cast<double>(2 * sn - 1 - k), -slope, a0,
                             a1);
    }
    u += piece;
  }
  for (std::size_t w = kLanes / 2; w > 0; w /= 2) {
    for (std::size_t l = 0; l < w; ++l) {
      a0[l] += a0[l + w];
      a1[l] += a1[l + w];
    }
  }
  s0 = a0[0];
  s1 = a1[0];
}

// sum h[i], i < n, in eight independent lanes (a plain loop would be one add chain).
GYRODRIFT_FUSED_INLINE double lane_sum(const double* h, std::size_t n) noexcept {
  constexpr std::size_t kLanes = 8;
  double acc[kLanes] = {};
  std::size_t i = 0;
  for (; i + kLanes <= n; i += kLanes) {
    for (std::size_t k = 0; k < kLanes; ++k) acc[k] += h[i + k];
  }
  for (; i < n; ++i) acc[0] += h[i];
  for (std::size_t w = kLanes / 2; w > 0; w /= 2) {
    for (std::size_t k = 0; k < w; ++k) acc[k] += acc[k + w];
  }
  return acc[0];
}

#if GYRODRIFT_ALLAN_X86_DISPATCH
// c[k] = (row[k], row[q + k], row[2 q + k], row[3 q + k]) for k < 4 (row = h + i).
__attribute__((target("avx2,fma"), always_inline)) inline void columns4_avx2(
    const double* row, std::size_t q, __m256d* c) noexcept {
  const __m256d r0 = _mm256_loadu_pd(row);
  const __m256d r1 = _mm256_loadu_pd(row + q);
  const __m256d r2 = _mm256_loadu_pd(row + 2 * q);
  const __m256d r3 = _mm256_loadu_pd(row + 3 * q);
  const __m256d t0 = _mm256_unpacklo_pd(r0, r1);
  const __m256d t1 = _mm256_unpackhi_pd(r0, r1);
  const __m256d t2 = _mm256_unpacklo_pd(r2, r3);
  const __m256d t3 = _mm256_unpackhi_pd(r2, r3);
  c[0] = _mm256_permute2f128_pd(t0, t2, 0x20);
  c[1] = _mm256_permute2f128_pd(t1, t3, 0x20);
  c[2] = _mm256_permute2f128_pd(t0, t2, 0x31);
  c[3] = _mm256_permute2f128_pd(t1, t3, 0x31);
}

// The chains of integrate_sq() with AVX2: G groups of four chains, one register each,
// four terms of each chain per step (a 4x4 transpose of h[c q + i .. + 3]); per chain the
// same operations in the same order as the scalar loop (acc += V^2, then V += h), the
// squares of even and odd steps in two accumulators. Steps i < q4 (a multiple of 4); start
// and acc updated in place. The scalar chains are latency-bound (one dependent add per
// chain and term); here the adds of G registers overlap.
template <std::size_t G>
__attribute__((target("avx2,fma"))) inline void chains_avx2(const double* h, std::size_t q,
                                                            std::size_t q4, double* start,
                                                            double* acc) noexcept {
  __m256d s[G];
  __m256d a0[G];
  __m256d a1[G];
  for (std::size_t g = 0; g < G; ++g) {
    s[g] = _mm256_loadu_pd(start + 4 * g);
    a0[g] = _mm256_setzero_pd();
    a1[g] = _mm256_setzero_pd();
  }
  for (std::size_t i = 0; i < q4; i += 4) {
    __m256d c[G][4];
    for (std::size_t g = 0; g < G; ++g) columns4_avx2(h + 4 * g * q + i, q, c[g]);
    for (std::size_t k = 0; k < 4; k += 2) {
      for (std::size_t g = 0; g < G; ++g) {
        a0[g] = _mm256_fmadd_pd(s[g], s[g], a0[g]);
        s[g] = _mm256_add_pd(s[g], c[g][k]);
      }
      for (std::size_t g = 0; g < G; ++g) {
        a1[g] = _mm256_fmadd_pd(s[g], s[g], a1[g]);
        s[g] = _mm256_add_pd(s[g], c[g][k + 1]);
      }
    }
  }
  for (std::size_t g = 0; g < G; ++g) {
    _mm256_storeu_pd(start + 4 * g, s[g]);
    _mm256_storeu_pd(acc + 4 * g,
                     _mm256_add_pd(_mm256_loadu_pd(acc + 4 * g), _mm256_add_pd(a0[g], a1[g])));
  }
}
#endif

// The modified variance inside a block: h[i] = k0 + ((p3 - p0) + 3 (p1 - p2))[i] for
// i < n_h (H_{b+i}); terms V_{b+i}, i < len, V_{b+i+1} = V_{b+i} + h[i], V_b = v0.
// Adds sum V^2 to sq and returns sum h (V_{b+n_h} - V_b). In pieces of kPiece terms:
// h into a stack buffer (vectorized), the sums of h over eight stretches (so each
// stretch's starting V is known), then the eight stretches as independent chains.
template <bool Wide>
GYRODRIFT_FUSED_INLINE long double integrate_sq(const double* p0, const double* p1,
                                                const double* p2, const double* p3,
                                                std::size_t len, std::size_t n_h, double k0,
                                                long double v0, long double& sq) noexcept {
  constexpr std::size_t kPiece = 1024;
  constexpr std::size_t kChains = 8;
  alignas(32) double h[kPiece];
  long double v = v0;
  for (std::size_t a = 0; a < len; a += kPiece) {
    const std::size_t cnt = len - a < kPiece ? len - a : kPiece;
    // the last term of the record has no successor: n_h may end inside the piece
    const std::size_t nh = n_h > a ? (n_h - a < cnt ? n_h - a : cnt) : 0;
    for (std::size_t i = 0; i < nh; ++i) {
      h[i] = k0 + ((p3[a + i] - p0[a + i]) + 3.0 * (p1[a + i] - p2[a + i]));
    }
    for (std::size_t i = nh; i < cnt; ++i) h[i] = 0.0;
    const std::size_t q = cnt / kChains;
    // stretch c: terms [c q, (c + 1) q), the last one to cnt
    double part[kChains];
    for (std::size_t c = 0; c < kChains; ++c) {
      const std::size_t hi = c + 1 == kChains ? cnt : (c + 1) * q;
      part[c] = lane_sum(h + c * q, hi - c * q);
    }
    double start[kChains];
    double acc[kChains] = {};
    const double vd = static_cast<double>(v);
    double run = 0.0;
    for (std::size_t c = 0; c < kChains; ++c) {
      start[c] = vd + run;
      run += part[c];
    }
    std::size_t i0 = 0;
#if GYRODRIFT_ALLAN_X86_DISPATCH
    if constexpr (Wide) {
      static_assert(kChains % 4 == 0, "chains_avx2 runs groups of four chains");
      i0 = q & ~std::size_t{3};
      chains_avx2<kChains / 4>(h, q, i0, start, acc);
    }
#endif
    for (std::size_t i = i0; i < q; ++i) {
      for (std::size_t c = 0; c < kChains; ++c) {
        acc[c] += start[c] * start[c];
        start[c] += h[c * q + i];
      }
    }
    double tail = start[kChains - 1];
    double tail_acc = 0.0;
    for (std::size_t i = kChains * q; i < cnt; ++i) {
      tail_acc += tail * tail;
      tail += h[i];
    }
    double s = tail_acc;
    for (std::size_t c = 0; c < kChains; ++c) s += acc[c];
    sq += static_cast<long double>(s);
    // V after the piece, carried in long double from the stretches' sums (not from the
    // chains' end values, which carry the double rounding of their start)
    for (std::size_t c = 0; c < kChains; ++c) v += static_cast<long double>(part[c]);
  }
  return v;
}

}  // namespace fused_detail

template <std::size_t MaxTaus = 64>
class DeviationFused {
 public:
  static constexpr std::size_t kStreams = 4;
  static constexpr std::size_t kMaxOffsets = kStreams * MaxTaus;
  // Terms per tile inside a block: the streams of a tile (~2 per factor x 16 kB) stay in L2.
  static constexpr std::size_t kTile = 2048;

  // m: strictly increasing factors, each 1 <= m <= the estimator's max_m; block >= 16.
  bool plan(std::size_t n_data, FusedDeviation dev, const std::size_t* m, std::size_t n_m,
            std::size_t block) noexcept {
    n_m_ = 0;
    if (n_m == 0 || n_m > MaxTaus || block < 16) return false;
    const std::size_t max_m = dev == FusedDeviation::ohdev  ? ohdev_max_m(n_data)
                              : dev == FusedDeviation::mdev ? mdev_max_m(n_data)
                                                            : totdev_max_m(n_data);
    for (std::size_t j = 0; j < n_m; ++j) {
      if (m[j] == 0 || m[j] > max_m || (j > 0 && m[j] <= m[j - 1])) return false;
    }
    dev_ = dev;
    n_data_ = n_data;
    block_ = block;
    reflect_ = dev == FusedDeviation::totdev;
    // Signed offsets (phase index relative to the term index), shifted by origin_ >= them.
    origin_ = reflect_ ? 1 - static_cast<std::ptrdiff_t>(m[n_m - 1]) : 0;
    std::size_t offsets[kMaxOffsets];
    std::size_t n_off = 0;
    for (std::size_t j = 0; j < n_m; ++j) {
      m_[j] = m[j];
      const auto ms = static_cast<std::ptrdiff_t>(m[j]);
      std::ptrdiff_t off[kStreams];
      if (reflect_) {
        n_terms_[j] = totdev_terms(n_data);
        off[0] = 1 - ms;
        off[1] = 1;
        off[2] = 1 + ms;
        off[3] = 1 + ms;  // unused (coefficient 0)
      } else {
        n_terms_[j] = dev == FusedDeviation::ohdev ? ohdev_terms(n_data, m[j])
                                                   : mdev_terms(n_data, m[j]);
        for (std::size_t s = 0; s < kStreams; ++s) off[s] = static_cast<std::ptrdiff_t>(s) * ms;
      }
      for (std::size_t s = 0; s < kStreams; ++s) {
        rel_[j][s] = static_cast<std::size_t>(off[s] - origin_);
        offsets[n_off++] = rel_[j][s];
      }
    }
    // sort (insertion; at most 4 * MaxTaus values) and drop duplicates
    for (std::size_t i = 1; i < n_off; ++i) {
      const std::size_t v = offsets[i];
      std::size_t k = i;
      while (k > 0 && offsets[k - 1] > v) {
        offsets[k] = offsets[k - 1];
        --k;
      }
      offsets[k] = v;
    }
    std::size_t n_u = 0;
    for (std::size_t i = 0; i < n_off; ++i) {
      if (n_u == 0 || offsets[i] != offsets[n_u - 1]) offsets[n_u++] = offsets[i];
    }
    n_seg_ = fused_detail::plan_segments(offsets, n_u, block, seg_start_, seg_len_, seg_q_,
                                         workspace_);
    max_terms_ = 0;
    for (std::size_t j = 0; j < n_m; ++j) {
      if (n_terms_[j] > max_terms_) max_terms_ = n_terms_[j];
      anchor_every_[j] = 16 * m[j] > block ? (16 * m[j] + block - 1) / block : 1;
      for (std::size_t s = 0; s < kStreams; ++s) {
        stream_[j][s] = fused_detail::segment_position(seg_start_, seg_q_, n_seg_, rel_[j][s]);
      }
      // the four streams in one segment (one run of Q): positions alone cannot tell, two
      // segments may sit back to back in the workspace as in the data
      std::size_t k = n_seg_ - 1;
      while (seg_start_[k] > rel_[j][0]) --k;
      one_segment_[j] = rel_[j][kStreams - 1] < seg_start_[k] + seg_len_[k];
      for (std::size_t s = 0; s < kStreams; ++s) {
        std::size_t ks = n_seg_ - 1;
        while (seg_start_[ks] > rel_[j][s]) --ks;
        seg_of_[j][s] = ks;
      }
    }
    // ohdev, m = 1 and 2 first: their seven streams q + 0..6 of one run of Q, which holds
    // at least B + 9 values (sum_sq_third_pair12_avx2 reads up to q[B + 7])
    pair12_ = false;
    if (dev == FusedDeviation::ohdev && n_m >= 2 && m[0] == 1 && m[1] == 2 &&
        stream_[0][0] == seg_q_[0] && seg_start_[0] == 0 && seg_len_[0] >= block + 9) {
      pair12_ = true;
      for (std::size_t s = 0; s < kStreams; ++s) {
        pair12_ = pair12_ && stream_[0][s] == seg_q_[0] + s && stream_[1][s] == seg_q_[0] + 2 * s;
      }
    }
    n_m_ = n_m;
    return true;
  }

  // ohdev, AVX2: taus m, 2 m next to each other summed in one pass (six stream loads for two
  // taus instead of eight); off sums each alone (tests compare the two).
  void use_pairs(bool on) noexcept { pairs_ = on; }

  std::size_t workspace_doubles() const noexcept { return workspace_; }
  std::size_t factors() const noexcept { return n_m_; }

  // Runs the planned factors over y[0..n_data); writes sigma2[j] in (rate units)^2 (for
  // mdev the modified Allan variance; tdev is formed by the caller) and terms[j] (may be
  // null). False if not planned, the workspace is too small, or a sum is not finite
  // (outputs untouched).
  template <class Scalar, class Out>
  bool run(const Scalar* y, double* workspace, std::size_t workspace_len, Out* sigma2,
           std::size_t* terms) noexcept {
    const DeviationFused* whole[1] = {this};
    return accumulate(y, workspace, workspace_len, 0, max_terms_) &&
           finish_parts(whole, 1, sigma2, terms);
  }

  // Term indices of part k of `parts` equal stretches (multiples of the block): workers
  // can run the parts of one plan side by side (each its own object and workspace, planned
  // alike) and finish_parts() adds their sums in part order, so the result does not depend
  // on how many workers ran them. Parts after the first start from values recomputed
  // from the samples (anchor), not carried.
  std::size_t part_begin(std::size_t k, std::size_t parts) const noexcept {
    if (k == 0 || parts == 0) return 0;
    if (k >= parts) return max_terms_;
    const std::size_t blocks = (max_terms_ + block_ - 1) / block_;
    return (blocks * k / parts) * block_;
  }

  // The sums of terms [b_begin, b_end) of every factor (b_begin a multiple of the block).
  template <class Scalar>
  bool accumulate(const Scalar* y, double* workspace, std::size_t workspace_len,
                  std::size_t b_begin, std::size_t b_end) noexcept {
    if (n_m_ == 0 || workspace_len < workspace_ || b_begin % block_ != 0) return false;
    // from the whole record, so every part (and thread count) removes the same line
    line_ = fused_detail::ramp_line(y, n_data_);
    // the level of (y - slope k) at b_begin: the line the start values remove
    double c = 0.0;
    {
      const std::size_t k0 = b_begin < n_data_ ? b_begin : 0;
      const std::size_t n_level = n_data_ - k0 < 64 ? n_data_ - k0 : 64;
      long double level{0};
      for (std::size_t i = 0; i < n_level; ++i) {
        level += static_cast<long double>(y[k0 + i]) -
                 static_cast<long double>(line_.slope) * static_cast<long double>(k0 + i);
      }
      if (n_level > 0) c = line_.snap(static_cast<double>(level / n_level));
    }
    for (std::size_t j = 0; j < n_m_; ++j) {
      sum_sq_[j] = 0;
      // ohdev / totdev factors read from one segment take H_b (D_b) from the first block's Q
      // (blocks_impl)
      if (n_terms_[j] > b_begin && !h_from_q(j)) start_at(y, j, b_begin, c);
    }
    const std::size_t stop = b_end < max_terms_ ? b_end : max_terms_;
#if GYRODRIFT_ALLAN_X86_DISPATCH
    if (fused_detail::wide_simd()) {
      blocks_wide(y, workspace, b_begin, stop);
    } else {
      blocks(y, workspace, b_begin, stop);
    }
#else
    blocks(y, workspace, b_begin, stop);
#endif
    return true;
  }

  // sigma2[j], terms[j] (may be null) from the sums of parts[0..n_parts) (same plan), added
  // in that order. False if a variance is not finite (outputs untouched).
  template <class Out>
  static bool finish_parts(const DeviationFused* const* parts, std::size_t n_parts, Out* sigma2,
                           std::size_t* terms) noexcept {
    const DeviationFused& f = *parts[0];
    long double value[MaxTaus];
    for (std::size_t j = 0; j < f.n_m_; ++j) {
      long double sum{0};
      for (std::size_t k = 0; k < n_parts; ++k) sum += parts[k]->sum_sq_[j];
      const long double mm = static_cast<long double>(f.m_[j]);
      const long double n = static_cast<long double>(f.n_terms_[j]);
      if (f.dev_ == FusedDeviation::ohdev) {
        value[j] = sum / (6.0L * mm * mm * n);
      } else if (f.dev_ == FusedDeviation::mdev) {
        value[j] = sum / (2.0L * mm * mm * mm * mm * n);
      } else {
        value[j] = sum / (2.0L * mm * mm * n);
      }
      if (!std::isfinite(value[j])) return false;
    }
    for (std::size_t j = 0; j < f.n_m_; ++j) {
      sigma2[j] = static_cast<Out>(value[j]);
      if (terms != nullptr) terms[j] = f.n_terms_[j];
    }
    return true;
  }

 private:
  // The running values of factor j at term b (< its term count) from the samples. For mdev
  // the last term (b = n - 1) has V but no H (it would read X_{N+1}): V_b = V_{b-1} + H_{b-1}.
  template <class Scalar>
  void start_at(const Scalar* y, std::size_t j, std::size_t b, double c) noexcept {
    if (!reflect_ && b + 3 * m_[j] > n_data_) {
      anchor(y, j, b - 1, c);
      inner_[j] += chain_[j];
      return;
    }
    anchor(y, j, b, c);
  }

  // The running values of factor j at term b from the samples (O(m), double, eight lanes):
  // H_b = R_2 - 2 R_1 + R_0 (R_k the sum of (y - c) over [b + k m, b + (k + 1) m)) and, for
  // mdev, V_b = sum_{i<m} D_{b+i} = sum_v w(v) (y_v - c) with w = -(u + 1) on the first
  // range, 2u - m + 2 on the second, m - 1 - u on the third (u the index inside the range;
  // from V_b = P_{b+3m} - 3 P_{b+2m} + 3 P_{b+m} - P_b, P the prefix sum of the phase); for
  // totdev D_b = (X*_{b+1+m} - X*_{b+1}) - (X*_{b+1} - X*_{b+1-m}). The sums are of
  // y - (c + slope k) (the RampLine); the line cancels from H (a third difference), adds
  // slope m^3 to V (m second differences) and slope (m^2 + E(b)) to D (ramp_edge): added
  // back. Needs b + 3m <= N (ohdev,
  // mdev).
  template <class Scalar>
  GYRODRIFT_FUSED_INLINE void anchor(const Scalar* y, std::size_t j, std::size_t b,
                                     double c) noexcept {
    const std::size_t m = m_[j];
    const auto ms = static_cast<std::ptrdiff_t>(m);
    const auto bs = static_cast<std::ptrdiff_t>(b);
    double r0 = 0.0;
    double r1 = 0.0;
    double r2 = 0.0;
    double u0 = 0.0;
    double u1 = 0.0;
    double u2 = 0.0;
    const double slope = line_.slope;
    if (reflect_) {
      fused_detail::range_moments<false>(y, n_data_, true, bs + 1 - ms, m, c, slope, r0, u0);
      fused_detail::range_moments<false>(y, n_data_, true, bs + 1, m, c, slope, r1, u1);
      const long double mm = static_cast<long double>(m);
      chain_[j] = (static_cast<long double>(r1) - static_cast<long double>(r0)) +
                  (static_cast<long double>(slope) * mm * mm + ramp_edge(j, b));
      return;
    }
    const auto moments = [&](std::ptrdiff_t start, double& r, double& u) {
      if (dev_ == FusedDeviation::mdev) {
        fused_detail::range_moments<true>(y, n_data_, false, start, m, c, slope, r, u);
      } else {
        fused_detail::range_moments<false>(y, n_data_, false, start, m, c, slope, r, u);
      }
    };
    moments(bs, r0, u0);
    moments(bs + ms, r1, u1);
    moments(bs + 2 * ms, r2, u2);
    chain_[j] = (static_cast<long double>(r2) - 2.0L * static_cast<long double>(r1)) +
                static_cast<long double>(r0);
    if (dev_ == FusedDeviation::mdev) {
      const long double mm = static_cast<long double>(m);
      // V sums m second differences: the line adds slope m^3
      inner_[j] = ((-static_cast<long double>(u0) - static_cast<long double>(r0)) +
                   (2.0L * static_cast<long double>(u1) + (2.0L - mm) * r1) +
                   ((mm - 1.0L) * static_cast<long double>(r2) - static_cast<long double>(u2))) +
                  static_cast<long double>(slope) * mm * mm * mm;
    }
  }

  template <bool Wide, class Scalar>
  GYRODRIFT_FUSED_INLINE void blocks_impl(const Scalar* y, double* workspace,
                                          std::size_t b_begin, std::size_t b_end) noexcept {
    const std::size_t bsz = block_;
    std::size_t n_active = n_m_;
    const auto sn = static_cast<std::ptrdiff_t>(n_data_);
    // virtual samples y*[k] exist for k < v_end (the reflected record ends at 2N - 2)
    const std::ptrdiff_t v_end = reflect_ ? 2 * sn - 1 : sn;
    for (std::size_t b = b_begin; b < b_end; b += bsz) {
      // factors are sorted by m: for ohdev/mdev the largest m has the fewest terms
      while (n_active > 0 && n_terms_[n_active - 1] <= b) --n_active;
      // One line level + slope k (k the sample index; for totdev the source index of the
      // reflected record) removed from all streams of this block: it cancels exactly, the
      // coefficients annihilating a constant and a line (totdev: up to ramp_edge(), which
      // the terms and the carry add back).
      const std::ptrdiff_t base = static_cast<std::ptrdiff_t>(b) + origin_;
      const std::size_t n_level = 64;
      double level = 0.0;
      for (std::size_t i = 0; i < n_level; ++i) {
        std::ptrdiff_t k = base + static_cast<std::ptrdiff_t>(i) + 1;
        if (k > v_end - 1) k = v_end - 1;
        if (k < 1 - sn) k = 1 - sn;
        level += static_cast<double>(totdev_reflected(y, n_data_, k)) -
                 line_.slope * static_cast<double>(source_index(k));
      }
      const double mean = line_.snap(level / static_cast<double>(n_level));
      std::size_t reach = 0;
      for (std::size_t j = 0; j < n_active; ++j) {
        if (rel_[j][kStreams - 1] > reach) reach = rel_[j][kStreams - 1];
      }
      // Each segment's prefix sums only as far as this block's active streams read them:
      // Q[0 .. off + L], L = B where the factor carries its values on to the next block
      // (Q[B]), else its last term's index (the last block of a factor, and factors whose
      // terms end inside it). A full segment holds span + B values; the record's last block
      // and the largest factors need much less.
      std::size_t need[kMaxOffsets];
      for (std::size_t k = 0; k < n_seg_; ++k) need[k] = 0;
      for (std::size_t j = 0; j < n_active; ++j) {
        const std::size_t left = n_terms_[j] - b;
        const std::size_t last = left > bsz ? bsz : left - 1;
        for (std::size_t s = 0; s < kStreams; ++s) {
          const std::size_t k = seg_of_[j][s];
          const std::size_t upto = rel_[j][s] - seg_start_[k] + last;
          if (upto > need[k]) need[k] = upto;
        }
      }
      std::size_t done[kMaxOffsets];
      for (std::size_t k = 0; k < n_seg_ && seg_start_[k] <= reach; ++k) {
        const std::ptrdiff_t start = base + static_cast<std::ptrdiff_t>(seg_start_[k]);
        const std::size_t avail = v_end > start ? static_cast<std::size_t>(v_end - start) : 0;
        std::size_t len = seg_len_[k] - 1 < avail ? seg_len_[k] - 1 : avail;
        if (need[k] < len) len = need[k];
        prefix_virtual<Wide>(y, start, len, mean, workspace + seg_q_[k]);
        done[k] = len;
      }
      // Start values: k0[j] = (H_b or D_b) minus the combination of the Q at i = 0.
      double k0[MaxTaus];
      for (std::size_t j = 0; j < n_active; ++j) {
        const Streams p = streams(workspace, j);
        if (b == b_begin && h_from_q(j)) {
          // H_b = R_2 - 2 R_1 + R_0 with R_k the sum of (y - line) over [b + k m, b + (k+1) m)
          // = Q[(k+1) m] - Q[k m]: the combination of this block's Q at i = 0 when the
          // streams lie in one segment (the line cancels; totdev: D_b = R_1 - R_0 on the
          // reflected record, plus what the line gives D). Same data and rounding class as
          // the terms themselves; saves the O(2-3 m) start sums per factor.
          const auto q = [&](std::size_t s) { return static_cast<long double>(p[s][0]); };
          if (reflect_) {
            const long double mm = static_cast<long double>(m_[j]);
            chain_[j] = ((q(2) - 2.0L * q(1)) + q(0)) +
                        (static_cast<long double>(line_.slope) * mm * mm + ramp_edge(j, b));
          } else if (one_segment_[j]) {
            chain_[j] = (q(3) - q(0)) + 3.0L * (q(1) - q(2));
          } else {
            // ohdev, streams in several segments (the largest factors): the phase at each
            // stream relative to the first segment's start, chained through each segment's
            // last computed Q and the sum over the gap to the next segment's start (a few
            // thousand samples at 1e6) instead of the 3 m-sample start sums.
            long double x[kStreams];
            long double acc = 0.0L;
            std::size_t k = seg_of_[j][0];
            for (std::size_t s = 0; s < kStreams; ++s) {
              while (k < seg_of_[j][s]) {
                acc += static_cast<long double>(workspace[seg_q_[k] + done[k]]);
                const std::size_t g0 = seg_start_[k] + done[k];
                if (seg_start_[k + 1] > g0) {
                  double r = 0.0;
                  double u = 0.0;
                  fused_detail::range_moments<false>(
                      y, n_data_, false, base + static_cast<std::ptrdiff_t>(g0),
                      seg_start_[k + 1] - g0, mean,
                      line_.slope, r, u);
                  acc += static_cast<long double>(r);
                }
                ++k;
              }
              x[s] = acc + static_cast<long double>(p[s][0]);
            }
            chain_[j] = (x[3] - x[0]) + 3.0L * (x[1] - x[2]);
          }
        }
        if (reflect_) {
          k0[j] = static_cast<double>(chain_[j] - ramp_edge(j, b)) -
                  ((p[2][0] - 2.0 * p[1][0]) + p[0][0]);
          continue;
        }
        if (dev_ == FusedDeviation::mdev && b > b_begin && b + 3 * m_[j] <= n_data_ &&
            (b / bsz) % anchor_every_[j] == 0) {
          // Modified variance: V integrates H, so the rounding of the carried H and of the
          // Q sums would random-walk into V over the whole record (~sqrt(N) eps); V and H
          // are recomputed from the samples every max(B, 16 m) terms instead (O(m) each:
          // at most 3/16 of a sample per term), so it never accumulates beyond that.
          anchor(y, j, b, mean);
        }
        k0[j] = static_cast<double>(chain_[j]) -
                ((p[3][0] - p[0][0]) + 3.0 * (p[1][0] - p[2][0]));
      }
      // The block's terms in tiles of kTile, every factor per tile, so the streams a tile
      // reads stay in the core's cache (the whole workspace may not fit).
      for (std::size_t t0 = 0; t0 < bsz; t0 += kTile) {
        for (std::size_t j = 0; j < n_active; ++j) {
          const std::size_t left = n_terms_[j] - b;
          const std::size_t len = left < bsz ? left : bsz;
          if (t0 >= len) continue;
          const std::size_t cnt = len - t0 < kTile ? len - t0 : kTile;
          const Streams p = streams(workspace, j);
#if GYRODRIFT_ALLAN_X86_DISPATCH
          if constexpr (Wide) {
            if (dev_ == FusedDeviation::ohdev && pairs_ && j + 1 < n_active &&
                stream_[j + 1][0] == stream_[j][0] && stream_[j + 1][1] == stream_[j][2]) {
              const std::size_t left2 = n_terms_[j + 1] - b;
              const std::size_t len2 = left2 < bsz ? left2 : bsz;
              if (t0 < len2 && (len2 - t0 < kTile ? len2 - t0 : kTile) == cnt) {
                const Streams p2 = streams(workspace, j + 1);
                double out2[2];
                if (j == 0 && pair12_ &&
                    reinterpret_cast<std::uintptr_t>(p[0] + t0) % 32 == 0) {
                  fused_detail::sum_sq_third_pair12_avx2(p[0] + t0, cnt, k0, out2);
                } else {
                  fused_detail::sum_sq_third_pair_avx2(p[0] + t0, p[1] + t0, p[2] + t0,
                                                       p[3] + t0, p2[2] + t0, p2[3] + t0, cnt,
                                                       k0 + j, out2);
                }
                sum_sq_[j] += static_cast<long double>(out2[0]);
                sum_sq_[j + 1] += static_cast<long double>(out2[1]);
                ++j;
                continue;
              }
            }
          }
#endif
          if (reflect_) {
            const std::size_t t_first = b + t0;
            if (t_first + 1 >= m_[j] && t_first + cnt + m_[j] <= n_data_) {
              sum_sq_[j] += static_cast<long double>(
                  fused_detail::sum_sq_second(p[0] + t0, p[1] + t0, p[2] + t0, cnt, k0[j]));
            } else {
              sum_sq_[j] += static_cast<long double>(
                  sum_sq_second_edge<Wide>(p[0] + t0, p[1] + t0, p[2] + t0, cnt, k0[j], t_first,
                                           j));
            }
          } else if (dev_ == FusedDeviation::ohdev) {
            sum_sq_[j] += static_cast<long double>(fused_detail::sum_sq_third(
                p[0] + t0, p[1] + t0, p[2] + t0, p[3] + t0, cnt, k0[j]));
          } else {
            // H_{b+i} exists for b + i <= n - 2 (it reads X_N at most)
            const std::size_t n_h = left - 1 < bsz ? left - 1 : bsz;
            const std::size_t nh = n_h > t0 ? (n_h - t0 < cnt ? n_h - t0 : cnt) : 0;
            inner_[j] = fused_detail::integrate_sq<Wide>(p[0] + t0, p[1] + t0, p[2] + t0,
                                                         p[3] + t0, cnt, nh, k0[j], inner_[j],
                                                         sum_sq_[j]);
          }
        }
      }
      // Carry H (D) to the next block: exact differences of doubles, in long double.
      for (std::size_t j = 0; j < n_active; ++j) {
        const std::size_t left = n_terms_[j] - b;
        const Streams p = streams(workspace, j);
        const auto d = [&](std::size_t s) {
          return static_cast<long double>(p[s][bsz]) - static_cast<long double>(p[s][0]);
        };
        if (reflect_) {
          if (left > bsz) {
            chain_[j] += ((d(2) - 2.0L * d(1)) + d(0)) + (ramp_edge(j, b + bsz) - ramp_edge(j, b));
          }
        } else if (dev_ == FusedDeviation::ohdev ? left > bsz : left > bsz + 1) {
          chain_[j] += (d(3) - d(0)) + 3.0L * (d(1) - d(2));
        }
      }
    }
  }

  // ohdev or totdev factor j whose streams lie in one segment: its start value (H_b, D_b)
  // is the combination of the block's Q at i = 0 (no separate sums over the samples; mdev
  // needs V_b as well).
  bool h_from_q(std::size_t j) const noexcept {
    return dev_ == FusedDeviation::ohdev || (dev_ == FusedDeviation::totdev && one_segment_[j]);
  }

  // The four stream pointers of factor j into the workspace (Q at its offsets).
  struct Streams {
    const double* p[kStreams];
    const double* operator[](std::size_t s) const noexcept { return p[s]; }
  };
  Streams streams(const double* workspace, std::size_t j) const noexcept {
    Streams out{};
    for (std::size_t s = 0; s < kStreams; ++s) out.p[s] = workspace + stream_[j][s];
    return out;
  }

  template <class Scalar>
  void blocks(const Scalar* y, double* workspace, std::size_t b0, std::size_t b1) noexcept {
    blocks_impl<false>(y, workspace, b0, b1);
  }
#if GYRODRIFT_ALLAN_X86_DISPATCH
  template <class Scalar>
  __attribute__((target("avx2,fma"))) void blocks_wide(const Scalar* y, double* workspace,
                                                       std::size_t b0,
                                                       std::size_t b1) noexcept {
    blocks_impl<true>(y, workspace, b0, b1);
  }
#endif

  // q[0] = 0, q[t+1] = q[t] + (y*[start + t] - mean), t < len, in up to three pieces
  // (left mirror read backwards, the record, right mirror read backwards).
  // Sample index of the virtual sample y*[k] (itself inside the record; mirrored ends).
  std::ptrdiff_t source_index(std::ptrdiff_t k) const noexcept {
    const auto sn = static_cast<std::ptrdiff_t>(n_data_);
    return k < 0 ? -1 - k : (k >= sn ? 2 * sn - 1 - k : k);
  }

  // totdev: the removed line contributes slope (m^2 + E(t)) to D_t, E(t) = -(m-1-t)_+^2 -
  // (t+1+m-N)_+^2 (the mirrored ends of the reflected line; a window [a, a+m) reaching k
  // samples into a mirror holds k^2 more than the line there, sums of odd numbers). The
  // constant slope m^2 stays in the carried D; this is slope E(t), in long double (exact
  // integers times slope).
  long double ramp_edge(std::size_t j, std::size_t t) const noexcept {
    const long double m = static_cast<long double>(m_[j]);
    const long double tt = static_cast<long double>(t);
    const long double l = m - 1.0L - tt;
    const long double r = tt + 1.0L + m - static_cast<long double>(n_data_);
    const long double e = (l > 0.0L ? l * l : 0.0L) + (r > 0.0L ? r * r : 0.0L);
    return -static_cast<long double>(line_.slope) * e;
  }

  // sum_i (k0 + ((p2 - 2 p1) + p0)[i] + slope E(t_first + i))^2: totdev terms that read a
  // mirrored end (at most the first and the last m terms of factor j).
  template <bool Wide>
  GYRODRIFT_FUSED_INLINE double sum_sq_second_edge(const double* p0, const double* p1,
                                                   const double* p2, std::size_t len,
                                                   double k0, std::size_t t_first,
                                                   std::size_t j) const noexcept {
    const double m = static_cast<double>(m_[j]);
    const double lo = m - 1.0 - static_cast<double>(t_first);
    const double hi = static_cast<double>(t_first) + 1.0 + m - static_cast<double>(n_data_);
    const double slope = line_.slope;
#if GYRODRIFT_ALLAN_X86_DISPATCH
    if constexpr (Wide) {
      return fused_detail::sum_sq_second_edge_avx2(p0, p1, p2, len, k0, lo, hi, slope);
    }
#endif
    return fused_detail::sum_sq16(len, [&](std::size_t i) {
      const double u = static_cast<double>(i);
      const double l = lo - u > 0.0 ? lo - u : 0.0;
      const double r = hi + u > 0.0 ? hi + u : 0.0;
      return (k0 + ((p2[i] - 2.0 * p1[i]) + p0[i])) - slope * (l * l + r * r);
    });
  }

  // q[0] = 0, q[t+1] = q[t] + (y*[start + t] - (level + slope k)), k the source index of
  // y*[start + t], t < len, in up to three pieces (left mirror read backwards, the record,
  // right mirror read backwards).
  template <bool Wide, class Scalar>
  GYRODRIFT_FUSED_INLINE void prefix_virtual(const Scalar* y, std::ptrdiff_t start,
                                             std::size_t len, double level,
                                             double* q) const noexcept {
    q[0] = 0.0;
    const auto sn = static_cast<std::ptrdiff_t>(n_data_);
    const double slope = line_.slope;
    std::size_t t = 0;
    while (t < len) {
      const std::ptrdiff_t k = start + static_cast<std::ptrdiff_t>(t);
      std::size_t piece = len - t;
      const std::ptrdiff_t src = source_index(k);
      const double a = level + slope * static_cast<double>(src);
      if (k >= 0 && k < sn) {
        const auto room = static_cast<std::size_t>(sn - k);
        if (room < piece) piece = room;
        run<Wide>(y + src, 1, piece, a, slope, q + t);
      } else {
        if (k < 0) {
          const auto room = static_cast<std::size_t>(-k);
          if (room < piece) piece = room;
        }
        run<Wide>(y + src, -1, piece, a, -slope, q + t);
      }
      t += piece;
    }
  }

  template <bool Wide, class Scalar>
  static GYRODRIFT_FUSED_INLINE void run(const Scalar* y, std::ptrdiff_t step, std::size_t len,
                                         double a, double slope, double* q) noexcept {
#if GYRODRIFT_ALLAN_X86_DISPATCH
    if constexpr (Wide) {
      fused_detail::prefix_sum_avx2(y, step, len, a, slope, q);
      return;
    }
#endif
    fused_detail::prefix_sum(y, step, len, a, slope, q);
  }

  FusedDeviation dev_{FusedDeviation::ohdev};
  bool reflect_{false};
  std::ptrdiff_t origin_{0};
  std::size_t n_data_{0};
  std::size_t block_{0};
  std::size_t n_m_{0};
  std::size_t n_seg_{0};
  std::size_t workspace_{0};
  std::size_t max_terms_{0};
  std::size_t m_[MaxTaus]{};
  std::size_t n_terms_[MaxTaus]{};
  std::size_t anchor_every_[MaxTaus]{};
  bool one_segment_[MaxTaus]{};  // factor j's streams all in one segment  // mdev: blocks between exact restarts of V and H
  std::size_t rel_[MaxTaus][kStreams]{};
  std::size_t stream_[MaxTaus][kStreams]{};
  std::size_t seg_of_[MaxTaus][kStreams]{};  // the segment each stream lies in
  std::size_t seg_start_[kMaxOffsets]{};
  std::size_t seg_len_[kMaxOffsets]{};
  std::size_t seg_q_[kMaxOffsets]{};
  bool pairs_{true};
  bool pair12_{false};  // ohdev: factors 0, 1 are m = 1, 2 on one run of Q (aligned pair)
  fused_detail::RampLine line_{};  // the rate line removed in the prefix sums (accumulate)
  long double chain_[MaxTaus]{};  // H_b (ohdev, mdev) or D_b (totdev) at the block start
  long double inner_[MaxTaus]{};  // V_b (mdev)
  long double sum_sq_[MaxTaus]{};
};

}  // namespace gyrodrift
