// Total variance of rate data in O(N) per averaging factor (NIST SP 1065 eq. 25, Howe).
//
// SP 1065 extends the N + 1 phase points x_0..x_N by reflection about both end points,
//   x*_{-j} = 2 x_0 - x_j,  x*_{N+j} = 2 x_N - x_{N-j},  j = 1..N-1,
// and sums the second differences centred on every inner point:
//   Tot sigma^2(m tau0) = 1 / (2 tau^2 (N - 1)) sum_{i=1}^{N-1} (x*_{i-m} - 2 x*_i + x*_{i+m})^2.
// On the rate y_k = (x_{k+1} - x_k) / tau0 that reflection is an even reflection of the rate,
// y*_{-1-k} = y_k and y*_{N+k} = y_{N-1-k} (k = 0..N-2), and with S*_b the sum of m samples
// of y* from b, x*_{i-m} - 2 x*_i + x*_{i+m} = tau0 (S*_{i} - S*_{i-m}): the overlapping-Allan
// running difference D_b (allan.hpp) over b = i - m = 1-m .. N-1-m, i.e.
//   Tot sigma^2 = 1 / (2 m^2 (N - 1)) sum D_b^2   (rate units)^2.
// So this header only supplies the reflected sample stream; the sums are oadev_rate_*.
// The driver copies reflected stretches into a caller-owned workspace, block by block (no
// allocation); stretches inside the record are read in place.
#pragma once
#include <cstddef>

#include "allan.hpp"

namespace gyrodrift {

// allantools.totdev keeps m < N + 1 (phase points); every such m has N - 1 terms.
inline std::size_t totdev_max_m(std::size_t n_data) noexcept { return n_data >= 3 ? n_data : 0; }

inline std::size_t totdev_terms(std::size_t n_data) noexcept {
  return n_data >= 3 ? n_data - 1 : 0;
}

// y*_k for k in [-(N-1), 2N-2] (signed index).
template <class Scalar>
inline Scalar totdev_reflected(const Scalar* y, std::size_t n_data, std::ptrdiff_t k) noexcept {
  const auto n = static_cast<std::ptrdiff_t>(n_data);
  if (k < 0) return y[-1 - k];
  if (k >= n) return y[2 * n - 1 - k];
  return y[k];
}

// Pointer to y*[start .. start+len): in place when inside the record, else copied (converted
// to Scalar) into `buf` (capacity >= len).
template <class Scalar>
inline const Scalar* totdev_stretch(const Scalar* y, std::size_t n_data, std::ptrdiff_t start,
                                    std::size_t len, Scalar* buf) noexcept {
  if (start >= 0 && static_cast<std::size_t>(start) + len <= n_data) return y + start;
  for (std::size_t i = 0; i < len; ++i) {
    buf[i] = totdev_reflected(y, n_data, start + static_cast<std::ptrdiff_t>(i));
  }
  return buf;
}

// Whole-array total variance for factors m[0..n_m) (each 1 <= m <= totdev_max_m); workspace:
// 3 * block Scalars (block >= 1). sigma2 in (rate units)^2, terms may be null.
template <class Scalar, class Out, class Accum = long double>
inline bool totdev(const Scalar* y, std::size_t n_data, const std::size_t* m, std::size_t n_m,
                   Scalar* workspace, std::size_t block, Out* sigma2,
                   std::size_t* terms) noexcept {
  const std::size_t max_m = totdev_max_m(n_data);
  if (block == 0 || workspace == nullptr) return false;
  const std::size_t n_terms = totdev_terms(n_data);
  Scalar* w0 = workspace;
  Scalar* w1 = workspace + block;
  Scalar* w2 = workspace + 2 * block;
  for (std::size_t j = 0; j < n_m; ++j) {
    const std::size_t mj = m[j];
    if (mj == 0 || mj > max_m) return false;
    const auto ms = static_cast<std::ptrdiff_t>(mj);
    const std::ptrdiff_t b0 = 1 - ms;  // first D index (i = 1)
    OadevSums<Accum> s;
    for (std::size_t k = 0; k < mj; k += block) {  // D_{b0} = S*_{b0+m} - S*_{b0}
      const std::size_t len = mj - k < block ? mj - k : block;
      const auto ks = static_cast<std::ptrdiff_t>(k);
      const Scalar* lo = totdev_stretch(y, n_data, b0 + ks, len, w0);
      const Scalar* hi = totdev_stretch(y, n_data, b0 + ms + ks, len, w1);
      oadev_rate_seed(s, lo, hi, len);
    }
    for (std::size_t t = 0; t + 1 < n_terms; t += block) {  // n_terms - 1 advances
      const std::size_t len = n_terms - 1 - t < block ? n_terms - 1 - t : block;
      const std::ptrdiff_t b = b0 + static_cast<std::ptrdiff_t>(t);
      const Scalar* p0 = totdev_stretch(y, n_data, b, len, w0);
      const Scalar* p1 = totdev_stretch(y, n_data, b + ms, len, w1);
      const Scalar* p2 = totdev_stretch(y, n_data, b + 2 * ms, len, w2);
      oadev_rate_advance(s, p0, p1, p2, len);
    }
    oadev_rate_finish(s);
    if (!oadev_sigma2(s, mj, sigma2[j])) return false;
    if (terms != nullptr) terms[j] = s.terms;
  }
  return true;
}

}  // namespace gyrodrift
