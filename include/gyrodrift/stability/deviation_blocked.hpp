// Non-overlapping Hadamard variance for many averaging factors in one pass over a record in
// memory (the fast path of gyrodrift.hdev; hdev_rate_push in deviation_hadamard.hpp is the
// streaming kernel and the oracle).
//
// Per factor the block sums Z_k of m samples are needed, H = Z_{k+2} - 2 Z_{k+1} + Z_k
// (SP 1065 eq. 18). When a factor is a multiple of a smaller one (octave grids: every one),
// its block sums are sums of r = m_j / m_i consecutive block sums of that smaller factor, so
// the levels form a cascade: the record is read once in chunks of kChunk samples, the first
// level(s) sum samples, every other level sums its parent's block sums emitted for the same
// chunk. Work: ~2 N additions for an octave grid instead of N per factor.
// Precision: the sums are in double over (y - (c + slope k)), the record's rate line
// (fused_common.hpp RampLine: c the level of the first 64 samples, slope the ramp, k the
// sample index; exact values). A line cancels from H exactly in real arithmetic (block sums
// of a line are a line in the block index; the weights 1, -2, 1 annihilate it), so a large
// constant rate or a steep ramp costs nothing (1e4 sigma over 1e6 samples: 6e-13 relative
// against the long double kernel on octave taus, 3e-11 before; 3e-9 before on a decade
// grid, whose factors without a divisor in the grid sum up to m samples); an octave
// cascade is a pairwise
// summation, whose rounding grows like log2(m) eps |Z|. Each level's H^2 are summed in
// sixteen lanes per chunk, then into long double. m = 1 (H_i = y_{i+2} - 2 y_{i+1} + y_i,
// the overlapping and non-overlapping cases coincide) is one vectorized pass over y.
// No allocation (caller-owned workspace of workspace_len() doubles, <= 2 kChunk + 2 factors),
// no exceptions; false on bad factors or non-finite sums.
#pragma once
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "deviation_hadamard.hpp"
#include "fused_common.hpp"

namespace gyrodrift {
namespace hdev_detail {

// sum_k (z[k+2] - 2 z[k+1] + z[k])^2 for k + 2 < n (differences of neighbours first).
template <class V>
GYRODRIFT_FUSED_INLINE double second_diff_sq(const V* z, std::size_t n) noexcept {
  if (n < 3) return 0.0;
  return fused_detail::sum_sq16(n - 2, [&](std::size_t i) {
    return (static_cast<double>(z[i + 2]) - static_cast<double>(z[i + 1])) -
           (static_cast<double>(z[i + 1]) - static_cast<double>(z[i]));
  });
}

}  // namespace hdev_detail

template <std::size_t MaxTaus = 64>
class HdevCascade {
 public:
  static constexpr std::size_t kChunk = 1 << 14;

  bool plan(std::size_t n_data, const std::size_t* m, std::size_t n_m) noexcept {
    n_m_ = 0;
    if (n_m == 0 || n_m > MaxTaus) return false;
    const std::size_t max_m = hdev_max_m(n_data);
    std::size_t offset = 0;
    for (std::size_t j = 0; j < n_m; ++j) {
      if (m[j] == 0 || m[j] > max_m || (j > 0 && m[j] <= m[j - 1])) return false;
      m_[j] = m[j];
      parent_[j] = kRaw;
      for (std::size_t i = j; i-- > 0;) {
        if (m_[i] > 1 && m[j] % m_[i] == 0) {  // m = 1 is computed apart: children read y
          parent_[j] = i;
          break;
        }
      }
      ratio_[j] = parent_[j] == kRaw ? m[j] : m[j] / m_[parent_[j]];
      // emitted block sums per chunk: at most kChunk / m + 1, after the two carried ones
      buf_[j] = offset;
      offset += kChunk / m[j] + 4;
    }
    n_data_ = n_data;
    workspace_ = offset;
    n_m_ = n_m;
    return true;
  }

  std::size_t workspace_len() const noexcept { return workspace_; }

  template <class Scalar>
  bool run(const Scalar* y, double* work, std::size_t work_len, double* sigma2,
           std::size_t* terms) noexcept {
    if (n_m_ == 0 || work_len < workspace_) return false;
#if GYRODRIFT_ALLAN_X86_DISPATCH
    if (fused_detail::wide_simd()) {
      run_wide(y, work);
    } else {
      run_impl(y, work);
    }
#else
    run_impl(y, work);
#endif
    for (std::size_t j = 0; j < n_m_; ++j) {
      if (!hadamard_sigma2(sum_sq_[j], terms_[j], m_[j], sigma2[j])) return false;
      terms[j] = terms_[j];
    }
    return true;
  }

 private:
  static constexpr std::size_t kRaw = static_cast<std::size_t>(-1);

  template <class Scalar>
  GYRODRIFT_FUSED_INLINE void run_impl(const Scalar* y, double* work) noexcept {
    // The rate line c + slope k (k the sample index) removed from the samples: a line
    // cancels from H exactly (block sums of a line are a line in the block index; their
    // second difference is 0), and a strong ramp keeps the block sums small.
    line_ = fused_detail::ramp_line(y, n_data_);
    double c = 0.0;
    {
      const std::size_t n_level = n_data_ < 64 ? n_data_ : 64;
      long double level{0};
      for (std::size_t i = 0; i < n_level; ++i) {
        level += static_cast<long double>(y[i]) -
                 static_cast<long double>(line_.slope) * static_cast<long double>(i);
      }
      if (n_level > 0) c = line_.snap(static_cast<double>(level / n_level));
    }
    for (std::size_t j = 0; j < n_m_; ++j) {
      sum_sq_[j] = 0;
      terms_[j] = 0;
      blocks_[j] = 0;
      filled_[j] = 0;
      partial_[j] = 0.0;
      z1_[j] = 0.0;
      z2_[j] = 0.0;
      emitted_[j] = 0;
    }
    for (std::size_t c0 = 0; c0 < n_data_; c0 += kChunk) {
      const std::size_t len = n_data_ - c0 < kChunk ? n_data_ - c0 : kChunk;
      for (std::size_t j = 0; j < n_m_; ++j) {
        if (m_[j] == 1) continue;
        if (parent_[j] == kRaw) {
          feed(j, y + c0, len, c + line_.slope * static_cast<double>(c0), line_.slope, work);
        } else {
          const std::size_t p = parent_[j];
          feed(j, work + buf_[p] + 2, emitted_[p], 0.0, 0.0, work);
        }
      }
    }
    for (std::size_t j = 0; j < n_m_; ++j) {
      if (m_[j] != 1 || n_data_ < 3) continue;
      // m = 1: H_i = y_{i+2} - 2 y_{i+1} + y_i over the record (no level needed: the
      // differences of neighbouring samples are formed first)
      const double acc = hdev_detail::second_diff_sq(y, n_data_);
      const std::size_t n = n_data_ - 2;
      sum_sq_[j] = static_cast<long double>(acc);
      terms_[j] = n;
    }
  }

#if GYRODRIFT_ALLAN_X86_DISPATCH
  template <class Scalar>
  __attribute__((target("avx2,fma"))) void run_wide(const Scalar* y, double* work) noexcept {
    run_impl(y, work);
  }
#endif

  // Adds v[k] - (c + slope k), k < n (samples, the line on the RampLine grid so every
  // value is exact; or the parent's block sums with c = slope = 0) to level j, so the
  // levels above sum small values however steep the ramp. Its
  // buffer holds the last two complete block sums before this call at [0, 2) and the new
  // ones from 2 on (emitted_[j] of them, which the child levels read), so H runs over the
  // buffer in one vectorized pass.
  template <class V>
  GYRODRIFT_FUSED_INLINE void feed(std::size_t j, const V* v, std::size_t n, double c,
                                   double slope, double* work) noexcept {
    // one sample minus the line (edges of blocks only: a 64-bit index converts slowly)
    const auto at = [&](std::size_t k) {
      return static_cast<double>(v[k]) - (c + slope * static_cast<double>(k));
    };
    double* z = work + buf_[j];
    const std::size_t r = ratio_[j];
    z[0] = z2_[j];
    z[1] = z1_[j];
    std::size_t out = 2;
    std::size_t i = 0;
    if (filled_[j] > 0) {  // finish the block the previous call's edge cut
      const std::size_t take = r - filled_[j] < n ? r - filled_[j] : n;
      double a = partial_[j];
      for (std::size_t k = 0; k < take; ++k) a += at(k);
      i = take;
      filled_[j] += take;
      partial_[j] = a;
      if (filled_[j] == r) {
        z[out++] = a;
        filled_[j] = 0;
        partial_[j] = 0.0;
      }
    }
    const std::size_t whole = (n - i) / r;
    if (r == 2) {
      // (v - c) in pairs, then the line's part of the pair at 2 u + i: slope (4 u + 2 i + 1);
      // an int32 counter (whole <= kChunk / 2) converts to double in the vector units
      const double first = slope * (2.0 * static_cast<double>(i) + 1.0);
      const double step = 4.0 * slope;
      const auto nw = static_cast<std::int32_t>(whole);
      for (std::int32_t k = 0; k < nw; ++k) {
        const auto u = static_cast<std::size_t>(k);
        z[out + u] = ((static_cast<double>(v[i + 2 * u]) - c) +
                      (static_cast<double>(v[i + 2 * u + 1]) - c)) -
                     (first + step * static_cast<double>(k));
      }
    } else {
      const double step = 4.0 * slope;
      for (std::size_t k = 0; k < whole; ++k) {
        const std::size_t p = i + k * r;
        // the line at p .. p + 3 in four lanes, advanced by 4 slope (exact on the grid)
        double l0 = c + slope * static_cast<double>(p);
        double l1 = l0 + slope;
        double l2 = l0 + 2.0 * slope;
        double l3 = l0 + 3.0 * slope;
        double a0 = 0.0;
        double a1 = 0.0;
        double a2 = 0.0;
        double a3 = 0.0;
        std::size_t t = 0;
        for (; t + 4 <= r; t += 4) {
          a0 += static_cast<double>(v[p + t]) - l0;
          a1 += static_cast<double>(v[p + t + 1]) - l1;
          a2 += static_cast<double>(v[p + t + 2]) - l2;
          a3 += static_cast<double>(v[p + t + 3]) - l3;
          l0 += step;
          l1 += step;
          l2 += step;
          l3 += step;
        }
        for (; t < r; ++t) a0 += at(p + t);
        z[out + k] = (a0 + a1) + (a2 + a3);
      }
    }
    out += whole;
    i += whole * r;
    if (i < n) {  // a block this call's edge cuts
      double a = partial_[j];
      for (std::size_t k = i; k < n; ++k) a += at(k);
      partial_[j] = a;
      filled_[j] += n - i;
    }
    const std::size_t fresh = out - 2;
    // triples made only of complete blocks: skip the carried slots not yet filled
    const std::size_t skip = blocks_[j] >= 2 ? 0 : 2 - blocks_[j];
    if (out > skip + 2) {
      sum_sq_[j] += static_cast<long double>(hdev_detail::second_diff_sq(z + skip, out - skip));
      terms_[j] += out - skip - 2;
    }
    if (fresh > 0) {  // z[out - 2] is the carried z1 when only one block completed
      z2_[j] = z[out - 2];
      z1_[j] = z[out - 1];
    }
    emitted_[j] = fresh;
    blocks_[j] += fresh;
  }

  std::size_t n_data_{0};
  std::size_t n_m_{0};
  std::size_t workspace_{0};
  std::size_t m_[MaxTaus]{};
  std::size_t parent_[MaxTaus]{};
  std::size_t ratio_[MaxTaus]{};
  std::size_t buf_[MaxTaus]{};
  std::size_t emitted_[MaxTaus]{};
  std::size_t blocks_[MaxTaus]{};
  std::size_t filled_[MaxTaus]{};
  fused_detail::RampLine line_{};
  double partial_[MaxTaus]{};
  double z1_[MaxTaus]{};  // last complete block sum before this chunk
  double z2_[MaxTaus]{};  // the one before it
  long double sum_sq_[MaxTaus]{};
  std::size_t terms_[MaxTaus]{};
};

}  // namespace gyrodrift
