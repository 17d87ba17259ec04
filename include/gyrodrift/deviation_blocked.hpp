// Fast whole-array drivers for the overlapping Hadamard, modified Allan and total variances
// (the running sums of deviation_hadamard.hpp / deviation_modified.hpp / deviation_total.hpp
// restructured for speed), used for records in memory.
//
// The running chains (H for ohdev, D for totdev, H and V for mdev) are carried in double
// inside blocks of kBlock terms, as prefix sums of the per-term increments computed into a
// small stack buffer: the increments vectorize, the prefix runs as four independent chains
// (the adds pipeline) and the squares are summed in 16 lanes. Precision: every R terms
// (a "segment", R = max(kSegment, 8 m) for H/D, max(kSegmentMod, 16 m) for mdev) the chain
// is restarted from its exact value recomputed in long double in O(m) from the samples,
// so its double rounding (which random-walks, and which mdev integrates once more) never
// accumulates over more than one segment: relative error ~ R^(1/2) 2^-53 for H/D and
// ~ R^(3/2) 2^-53 / m for V (below 1e-13 with these R). The increments
// (y3 - y0) + 3 (y1 - y2) are differences of samples; for a gyro with a large constant rate
// the samples are within a factor 2 of each other and these differences are exact
// (Sterbenz), so a large offset costs no precision. Segment restarts cost O(m) per R >= 8 m
// terms, so the total stays O(N) per factor.
// No allocation (fixed stack buffers), no exceptions; false on bad m or non-finite sums.
#pragma once
#include <cmath>
#include <cstddef>

#include "deviation_hadamard.hpp"
#include "deviation_modified.hpp"
#include "deviation_total.hpp"

namespace gyrodrift {
namespace blocked_detail {

// The helpers are always inlined so that an AVX2 build of a driver (a caller compiled with
// target("avx2,fma"), see bindings/bind_deviation.cpp) compiles them with AVX2 too.
#if defined(__GNUC__)
#define GYRODRIFT_DEV_INLINE __attribute__((always_inline)) inline
#else
#define GYRODRIFT_DEV_INLINE inline
#endif

constexpr std::size_t kBlock = 512;
constexpr std::size_t kSegment = 4096;
constexpr std::size_t kSegmentMod = 256;

// out[0] = start, out[i + 1] = out[i] + in[i] for i < len (len + 1 values); four chains
// over quarters, then the quarter offsets are added (so the adds do not wait on each other).
GYRODRIFT_DEV_INLINE void prefix(const double* in, std::size_t len, double start,
                                 double* out) noexcept {
  out[0] = start;
  const std::size_t q = len / 4;
  double s0 = start;
  double s1 = 0.0;
  double s2 = 0.0;
  double s3 = 0.0;
  for (std::size_t i = 0; i < q; ++i) {
    s0 += in[i];
    s1 += in[q + i];
    s2 += in[2 * q + i];
    s3 += in[3 * q + i];
    out[i + 1] = s0;
    out[q + i + 1] = s1;
    out[2 * q + i + 1] = s2;
    out[3 * q + i + 1] = s3;
  }
  for (std::size_t i = 4 * q; i < len; ++i) {
    s3 += in[i];
    out[i + 1] = s3;
  }
  for (std::size_t part = 1; part < 4; ++part) {
    const std::size_t lo = part * q + 1;
    const std::size_t hi = part == 3 ? len + 1 : (part + 1) * q + 1;
    const double base = out[part * q];
    for (std::size_t i = lo; i < hi; ++i) out[i] += base;
  }
}

// sum v[i]^2, i < len, in 16 independent lanes.
GYRODRIFT_DEV_INLINE double sum_sq(const double* v, std::size_t len) noexcept {
  constexpr std::size_t kLanes = 16;
  double acc[kLanes] = {};
  std::size_t i = 0;
  for (; i + kLanes <= len; i += kLanes) {
    for (std::size_t k = 0; k < kLanes; ++k) acc[k] += v[i + k] * v[i + k];
  }
  for (; i < len; ++i) acc[0] += v[i] * v[i];
  for (std::size_t w = kLanes / 2; w > 0; w /= 2) {
    for (std::size_t k = 0; k < w; ++k) acc[k] += acc[k + w];
  }
  return acc[0];
}

// Third-difference increments inc[i] = (y3 - y0) + 3 (y1 - y2) at y_s = p + j + s m.
template <class Scalar>
GYRODRIFT_DEV_INLINE void third_inc(const Scalar* p, std::size_t j, std::size_t m,
                                    std::size_t len, double* inc) noexcept {
  const Scalar* y0 = p + j;
  const Scalar* y1 = y0 + m;
  const Scalar* y2 = y1 + m;
  const Scalar* y3 = y2 + m;
  for (std::size_t i = 0; i < len; ++i) {
    inc[i] = (static_cast<double>(y3[i]) - static_cast<double>(y0[i])) +
             3.0 * (static_cast<double>(y1[i]) - static_cast<double>(y2[i]));
  }
}

// Exact H_j = S_{j+2m} - 2 S_{j+m} + S_j in long double, O(m).
template <class Scalar>
inline long double exact_third(const Scalar* y, std::size_t j, std::size_t m) noexcept {
  HadamardSums<long double> s;
  ohdev_rate_seed(s, y + j, y + j + m, y + j + 2 * m, m);
  return s.third;
}

}  // namespace blocked_detail

// Overlapping Hadamard variance of one factor m (1 <= m <= ohdev_max_m), (rate units)^2.
template <class Scalar>
GYRODRIFT_DEV_INLINE bool ohdev_blocked(const Scalar* y, std::size_t n_data, std::size_t m, double& sigma2,
                          std::size_t& terms) noexcept {
  using namespace blocked_detail;
  if (m == 0 || m > ohdev_max_m(n_data)) return false;
  const std::size_t n = ohdev_terms(n_data, m);
  const std::size_t seg = (8 * m > kSegment ? 8 * m : kSegment);
  double inc[kBlock];
  double h[kBlock + 1];
  long double sq{0};
  for (std::size_t s0 = 0; s0 < n; s0 += seg) {
    double hd = static_cast<double>(exact_third(y, s0, m));
    const std::size_t s1 = s0 + seg < n ? s0 + seg : n;
    for (std::size_t b = s0; b < s1; b += kBlock) {
      const std::size_t len = s1 - b < kBlock ? s1 - b : kBlock;
      // the last term has no successor (its increment would read y[N])
      const std::size_t n_inc = b + len == n ? len - 1 : len;
      third_inc(y, b, m, n_inc, inc);
      prefix(inc, n_inc, hd, h);
      sq += static_cast<long double>(sum_sq(h, len));
      hd = h[n_inc];
    }
  }
  return hadamard_sigma2(sq, n, m, sigma2) && (terms = n, true);
}

// Total variance of one factor m (1 <= m <= totdev_max_m): the Allan D chain on the evenly
// reflected record (deviation_total.hpp); stretches crossing an end are copied to `work`
// (3 * kBlock Scalars).
template <class Scalar>
GYRODRIFT_DEV_INLINE bool totdev_blocked(const Scalar* y, std::size_t n_data, std::size_t m, Scalar* work,
                           double& sigma2, std::size_t& terms) noexcept {
  using namespace blocked_detail;
  if (m == 0 || m > totdev_max_m(n_data)) return false;
  const std::size_t n = totdev_terms(n_data);
  const auto ms = static_cast<std::ptrdiff_t>(m);
  const std::ptrdiff_t b0 = 1 - ms;
  const std::size_t seg = (8 * m > kSegment ? 8 * m : kSegment);
  double inc[kBlock];
  double d[kBlock + 1];
  long double sq{0};
  for (std::size_t s0 = 0; s0 < n; s0 += seg) {
    long double exact{0};  // D = S*_{b+m} - S*_b, O(m)
    const std::ptrdiff_t bs = b0 + static_cast<std::ptrdiff_t>(s0);
    for (std::size_t k = 0; k < m; k += kBlock) {
      const std::size_t len = m - k < kBlock ? m - k : kBlock;
      const auto ks = static_cast<std::ptrdiff_t>(k);
      const Scalar* lo = totdev_stretch(y, n_data, bs + ks, len, work);
      const Scalar* hi = totdev_stretch(y, n_data, bs + ms + ks, len, work + kBlock);
      for (std::size_t i = 0; i < len; ++i) {
        exact += static_cast<long double>(hi[i]) - static_cast<long double>(lo[i]);
      }
    }
    double dd = static_cast<double>(exact);
    const std::size_t s1 = s0 + seg < n ? s0 + seg : n;
    for (std::size_t b = s0; b < s1; b += kBlock) {
      const std::size_t len = s1 - b < kBlock ? s1 - b : kBlock;
      const std::size_t n_inc = b + len == n ? len - 1 : len;
      const std::ptrdiff_t bb = b0 + static_cast<std::ptrdiff_t>(b);
      const Scalar* p0 = totdev_stretch(y, n_data, bb, n_inc, work);
      const Scalar* p1 = totdev_stretch(y, n_data, bb + ms, n_inc, work + kBlock);
      const Scalar* p2 = totdev_stretch(y, n_data, bb + 2 * ms, n_inc, work + 2 * kBlock);
      for (std::size_t i = 0; i < n_inc; ++i) {
        inc[i] = (static_cast<double>(p2[i]) - static_cast<double>(p1[i])) -
                 (static_cast<double>(p1[i]) - static_cast<double>(p0[i]));
      }
      prefix(inc, n_inc, dd, d);
      sq += static_cast<long double>(sum_sq(d, len));
      dd = d[n_inc];
    }
  }
  OadevSums<long double> s;
  s.sum_sq = sq;
  s.terms = n;
  return oadev_sigma2(s, m, sigma2) && (terms = n, true);
}

// Modified Allan variance of one factor m (1 <= m <= mdev_max_m): V_{j+1} = V_j + H_j,
// H_{j+1} = H_j + inc_j, both as prefix sums in double, restarted exactly every segment.
template <class Scalar>
GYRODRIFT_DEV_INLINE bool mdev_blocked(const Scalar* y, std::size_t n_data, std::size_t m, double& sigma2,
                         std::size_t& terms) noexcept {
  using namespace blocked_detail;
  if (m == 0 || m > mdev_max_m(n_data)) return false;
  const std::size_t n = mdev_terms(n_data, m);
  const std::size_t seg = (16 * m > kSegmentMod ? 16 * m : kSegmentMod);
  double inc[kBlock];
  double h[kBlock + 1];
  double v[kBlock + 1];
  long double sq{0};
  std::size_t s0 = 0;
  while (s0 < n) {
    // A segment never starts at the last term: its exact H would read y[N].
    std::size_t s1 = s0 + seg < n ? s0 + seg : n;
    if (n - s1 < 2) s1 = n;
    // Exact V_{s0} = sum_{i<m} D_{s0+i} and H_{s0} = D_{s0+m} - D_{s0} (long double, O(m)).
    ModAllanSums<long double> ex;
    mdev_rate_seed_diff(ex, y + s0, y + s0 + m, m);
    mdev_rate_seed_inner(ex, y + s0, y + s0 + m, y + s0 + 2 * m, m);
    double vd = static_cast<double>(ex.inner);
    double hd = static_cast<double>(ex.third);
    for (std::size_t b = s0; b < s1; b += kBlock) {
      const std::size_t len = s1 - b < kBlock ? s1 - b : kBlock;
      // inc_j (H_j -> H_{j+1}) reads y[j + 3m]: it exists for j <= n - 3.
      const std::size_t n_inc = n - 2 > b ? (len < n - 2 - b ? len : n - 2 - b) : 0;
      third_inc(y, b, m, n_inc, inc);
      prefix(inc, n_inc, hd, h);  // h[0..n_inc] = H_b .. H_{b+n_inc}
      const std::size_t n_v = len < n_inc + 1 ? len : n_inc + 1;
      prefix(h, n_v, vd, v);  // v[0..n_v] = V_b .. V_{b+n_v}; n_v >= len - 1 always
      sq += static_cast<long double>(sum_sq(v, len));
      vd = v[n_v];
      hd = h[n_inc];
    }
    s0 = s1;
  }
  ModAllanSums<long double> s;
  s.sum_sq = sq;
  s.terms = n;
  return mdev_sigma2(s, m, sigma2) && (terms = n, true);
}

// Non-overlapping Hadamard variance for many factors in one pass (whole record in memory).
// Per factor the block sums Z_k of m samples are needed (deviation_hadamard.hpp); when a
// factor is a multiple of a smaller one (octave grids: every one), its block sums are sums
// of r = m_j / m_i consecutive block sums of that smaller factor, so the levels form a
// cascade: the record is read once in chunks of kChunk samples, the first level(s) sum
// samples, every other level sums its parent's block sums emitted for the same chunk. Work:
// ~2 N additions for an octave grid instead of N per factor. Block sums and the sums of H^2
// are long double. m = 1 is the overlapping case (stride 1): ohdev_blocked.
// Workspace: plan() gives workspace_len() long doubles (<= 2 kChunk + factors), caller-owned.
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
      // emitted block sums per chunk: at most kChunk / m + 1
      buf_[j] = offset;
      offset += kChunk / m[j] + 2;
    }
    n_data_ = n_data;
    workspace_ = offset;
    n_m_ = n_m;
    return true;
  }

  std::size_t workspace_len() const noexcept { return workspace_; }

  template <class Scalar>
  bool run(const Scalar* y, long double* work, std::size_t work_len, double* sigma2,
           std::size_t* terms) noexcept {
    if (n_m_ == 0 || work_len < workspace_) return false;
    for (std::size_t j = 0; j < n_m_; ++j) st_[j] = HdevBlocks<long double>{};
    for (std::size_t c0 = 0; c0 < n_data_; c0 += kChunk) {
      const std::size_t len = n_data_ - c0 < kChunk ? n_data_ - c0 : kChunk;
      for (std::size_t j = 0; j < n_m_; ++j) {
        if (m_[j] == 1) continue;
        long double* out = work + buf_[j];
        std::size_t n_out = 0;
        if (parent_[j] == kRaw) {
          feed(j, y + c0, len, out, n_out);
        } else {
          feed(j, work + buf_[parent_[j]], emitted_[parent_[j]], out, n_out);
        }
        emitted_[j] = n_out;
      }
    }
    for (std::size_t j = 0; j < n_m_; ++j) {
      if (m_[j] == 1) {
        if (!ohdev_blocked(y, n_data_, 1, sigma2[j], terms[j])) return false;
        continue;
      }
      if (!hadamard_sigma2(st_[j].sum_sq, st_[j].terms, m_[j], sigma2[j])) return false;
      terms[j] = st_[j].terms;
    }
    return true;
  }

 private:
  static constexpr std::size_t kRaw = static_cast<std::size_t>(-1);

  // Adds v[0..n) (samples or parent block sums) to level j; completed block sums go to
  // out[n_out++] and into the level's H^2 sum.
  template <class V>
  void feed(std::size_t j, const V* v, std::size_t n, long double* out,
            std::size_t& n_out) noexcept {
    HdevBlocks<long double>& s = st_[j];
    const std::size_t r = ratio_[j];
    std::size_t i = 0;
    // Whole blocks while the level is between blocks: a tight loop with the state in
    // registers (the general loop below handles blocks cut by the chunk edges).
    if (s.filled == 0 && s.blocks >= 2) {
      long double z1 = s.z1;
      long double z2 = s.z2;
      long double sq_a{0};
      std::size_t done = 0;
      for (; i + r <= n; i += r) {
        long double z{0};
        if (r == 2) {
          z = static_cast<long double>(v[i]) + static_cast<long double>(v[i + 1]);
        } else {
          long double a0{0};
          long double a1{0};
          std::size_t k = 0;
          for (; k + 2 <= r; k += 2) {
            a0 += static_cast<long double>(v[i + k]);
            a1 += static_cast<long double>(v[i + k + 1]);
          }
          if (k < r) a0 += static_cast<long double>(v[i + k]);
          z = a0 + a1;
        }
        const long double h = (z - z1) - (z1 - z2);
        sq_a += h * h;
        z2 = z1;
        z1 = z;
        out[n_out++] = z;
        ++done;
      }
      s.z1 = z1;
      s.z2 = z2;
      s.sum_sq += sq_a;
      s.terms += done;
      s.blocks += done;
    }
    while (i < n) {
      const std::size_t take = (r - s.filled) < (n - i) ? (r - s.filled) : (n - i);
      long double a0{0};
      long double a1{0};
      std::size_t k = 0;
      for (; k + 2 <= take; k += 2) {
        a0 += static_cast<long double>(v[i + k]);
        a1 += static_cast<long double>(v[i + k + 1]);
      }
      if (k < take) a0 += static_cast<long double>(v[i + k]);
      s.partial += a0 + a1;
      s.filled += take;
      i += take;
      if (s.filled == r) {
        const long double z = s.partial;
        if (s.blocks >= 2) {
          const long double h = (z - s.z1) - (s.z1 - s.z2);
          s.sum_sq += h * h;
          ++s.terms;
        }
        s.z2 = s.z1;
        s.z1 = z;
        ++s.blocks;
        s.partial = 0;
        s.filled = 0;
        out[n_out++] = z;
      }
    }
  }

  std::size_t n_data_{0};
  std::size_t n_m_{0};
  std::size_t workspace_{0};
  std::size_t m_[MaxTaus]{};
  std::size_t parent_[MaxTaus]{};
  std::size_t ratio_[MaxTaus]{};
  std::size_t buf_[MaxTaus]{};
  std::size_t emitted_[MaxTaus]{};
  HdevBlocks<long double> st_[MaxTaus]{};
};

}  // namespace gyrodrift
