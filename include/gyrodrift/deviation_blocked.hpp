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

}  // namespace gyrodrift
