// Hadamard variances of rate data in O(N) per averaging factor (NIST SP 1065 sec. 5.2.8-5.2.9).
//
// Rate input y_0..y_{N-1} (one sample per tau0), phase x_k = tau0 (y_0 + ... + y_{k-1}),
// S_i = y_i + ... + y_{i+m-1}. The third difference of the phase is
//   x_{i+3m} - 3 x_{i+2m} + 3 x_{i+m} - x_i = tau0 H_i,   H_i = S_{i+2m} - 2 S_{i+m} + S_i,
// so (tau = m tau0)
//   overlapping (SP 1065 eq. 20): sigma^2 = 1 / (6 m^2 n) sum_{i=0}^{n-1} H_i^2,  n = N - 3m + 1,
//   non-overlapping (eq. 18): the same over i = 0, m, 2m, ... (n = floor(N/m) - 2 terms),
//     with H_{km} = Z_{k+2} - 2 Z_{k+1} + Z_k and Z_k the sum of block k of m samples.
// H_i is updated in O(1): H_{i+1} = H_i + y_{i+3m} - 3 y_{i+2m} + 3 y_{i+m} - y_i.
// Sums in `Accum` (long double by default); H and the block sums are differences of samples,
// so a large constant rate cancels before it can cost precision.
//
// Streaming: the seed / advance / finish functions take any split of the index range (records
// read in chunks); ohdev() and hdev() are the whole-array drivers. No allocation, no
// exceptions; drivers return false on bad input (m out of range, non-finite sums).
#pragma once
#include <cmath>
#include <cstddef>

namespace gyrodrift {

template <class Accum = long double>
struct HadamardSums {
  Accum third{0};  // running H_i (overlapping); its rounding random-walks, ~sqrt(N) 2^-64
  Accum sum_sq{0};
  std::size_t terms{0};
};

// Largest m leaving at least 2 terms (the cut of allantools.ohdev, which drops n <= 1).
inline std::size_t ohdev_max_m(std::size_t n_data) noexcept {
  return n_data >= 4 ? (n_data - 1) / 3 : 0;
}

inline std::size_t ohdev_terms(std::size_t n_data, std::size_t m) noexcept {
  if (m == 0 || 3 * m > n_data) return 0;
  return n_data - 3 * m + 1;
}

// Seed H_0 = sum_{k<m} (y[2m+k] - 2 y[m+k] + y[k]); y0 = &y[k0], y1 = &y[m+k0], y2 = &y[2m+k0],
// any split of k0 = 0..m-1.
template <class Scalar, class Accum>
inline void ohdev_rate_seed(HadamardSums<Accum>& s, const Scalar* y0, const Scalar* y1,
                            const Scalar* y2, std::size_t n) noexcept {
  Accum part{0};
  for (std::size_t k = 0; k < n; ++k) {
    part += (static_cast<Accum>(y2[k]) - static_cast<Accum>(y1[k])) -
            (static_cast<Accum>(y1[k]) - static_cast<Accum>(y0[k]));
  }
  s.third += part;
}

// n terms i = i0..i0+n-1 given y_s = &y[i0 + s m], s = 0..3: adds H_i^2, moves H to H_{i+1}.
// Call for n_terms - 1 terms in total, then ohdev_rate_finish() adds the last H^2.
template <class Scalar, class Accum>
inline void ohdev_rate_advance(HadamardSums<Accum>& s, const Scalar* y0, const Scalar* y1,
                               const Scalar* y2, const Scalar* y3, std::size_t n) noexcept {
  Accum h = s.third;
  Accum sq_a{0};
  Accum sq_b{0};
  std::size_t i = 0;
  // Two terms per iteration: the H chain takes one add per two terms and the two square
  // sums are independent, so the x87 adds pipeline.
  for (; i + 2 <= n; i += 2) {
    const Accum inc0 = (static_cast<Accum>(y3[i]) - static_cast<Accum>(y0[i])) +
                       Accum(3) * (static_cast<Accum>(y1[i]) - static_cast<Accum>(y2[i]));
    const Accum inc1 =
        (static_cast<Accum>(y3[i + 1]) - static_cast<Accum>(y0[i + 1])) +
        Accum(3) * (static_cast<Accum>(y1[i + 1]) - static_cast<Accum>(y2[i + 1]));
    const Accum h1 = h + inc0;
    sq_a += h * h;
    sq_b += h1 * h1;
    h = h + (inc0 + inc1);
  }
  for (; i < n; ++i) {
    sq_a += h * h;
    h += (static_cast<Accum>(y3[i]) - static_cast<Accum>(y0[i])) +
         Accum(3) * (static_cast<Accum>(y1[i]) - static_cast<Accum>(y2[i]));
  }
  s.third = h;
  s.sum_sq += sq_a + sq_b;
  s.terms += n;
}

template <class Accum>
inline void ohdev_rate_finish(HadamardSums<Accum>& s) noexcept {
  s.sum_sq += s.third * s.third;
  s.terms += 1;
}

// sigma^2 = sum H^2 / (6 m^2 n) in (rate units)^2; false if no terms or not finite.
template <class Accum, class Out>
inline bool hadamard_sigma2(Accum sum_sq, std::size_t terms, std::size_t m, Out& out) noexcept {
  if (terms == 0 || m == 0) return false;
  const Accum mm = static_cast<Accum>(m);
  const Accum v = sum_sq / (Accum(6) * mm * mm * static_cast<Accum>(terms));
  if (!std::isfinite(v)) return false;
  out = static_cast<Out>(v);
  return true;
}

// Whole-array overlapping Hadamard variance for factors m[0..n_m); sigma2 in (rate units)^2,
// terms may be null.
template <class Scalar, class Out, class Accum = long double>
inline bool ohdev(const Scalar* y, std::size_t n_data, const std::size_t* m, std::size_t n_m,
                  Out* sigma2, std::size_t* terms) noexcept {
  const std::size_t max_m = ohdev_max_m(n_data);
  for (std::size_t j = 0; j < n_m; ++j) {
    const std::size_t mj = m[j];
    if (mj == 0 || mj > max_m) return false;
    const std::size_t n = ohdev_terms(n_data, mj);
    HadamardSums<Accum> s;
    ohdev_rate_seed(s, y, y + mj, y + 2 * mj, mj);
    ohdev_rate_advance(s, y, y + mj, y + 2 * mj, y + 3 * mj, n - 1);
    ohdev_rate_finish(s);
    if (!hadamard_sigma2(s.sum_sq, s.terms, mj, sigma2[j])) return false;
    if (terms != nullptr) terms[j] = s.terms;
  }
  return true;
}

// Non-overlapping Hadamard: block sums Z_k of m samples, H = Z_{k+2} - 2 Z_{k+1} + Z_k.
template <class Accum = long double>
struct HdevBlocks {
  Accum partial{0};     // sum of the current, unfinished block
  std::size_t filled{0};  // samples in it
  Accum z1{0};          // last complete block sum
  Accum z2{0};          // the one before
  std::size_t blocks{0};
  Accum sum_sq{0};
  std::size_t terms{0};
};

// Largest m leaving at least 2 terms (floor(N/m) - 2 >= 2).
inline std::size_t hdev_max_m(std::size_t n_data) noexcept { return n_data / 4; }

// Feeds y[0..n) (the next samples of the record, any chunking) for averaging factor m.
template <class Scalar, class Accum>
inline void hdev_rate_push(HdevBlocks<Accum>& s, std::size_t m, const Scalar* y,
                           std::size_t n) noexcept {
  std::size_t i = 0;
  while (i < n) {
    const std::size_t take = (m - s.filled) < (n - i) ? (m - s.filled) : (n - i);
    // Four partial sums: the adds pipeline instead of waiting on each other.
    Accum a0{0};
    Accum a1{0};
    Accum a2{0};
    Accum a3{0};
    std::size_t k = 0;
    for (; k + 4 <= take; k += 4) {
      a0 += static_cast<Accum>(y[i + k]);
      a1 += static_cast<Accum>(y[i + k + 1]);
      a2 += static_cast<Accum>(y[i + k + 2]);
      a3 += static_cast<Accum>(y[i + k + 3]);
    }
    for (; k < take; ++k) a0 += static_cast<Accum>(y[i + k]);
    s.partial += (a0 + a1) + (a2 + a3);
    s.filled += take;
    i += take;
    if (s.filled == m) {
      const Accum z = s.partial;
      if (s.blocks >= 2) {
        const Accum h = (z - s.z1) - (s.z1 - s.z2);
        s.sum_sq += h * h;
        ++s.terms;
      }
      s.z2 = s.z1;
      s.z1 = z;
      ++s.blocks;
      s.partial = 0;
      s.filled = 0;
    }
  }
}

template <class Scalar, class Out, class Accum = long double>
inline bool hdev(const Scalar* y, std::size_t n_data, const std::size_t* m, std::size_t n_m,
                 Out* sigma2, std::size_t* terms) noexcept {
  const std::size_t max_m = hdev_max_m(n_data);
  for (std::size_t j = 0; j < n_m; ++j) {
    const std::size_t mj = m[j];
    if (mj == 0 || mj > max_m) return false;
    HdevBlocks<Accum> s;
    hdev_rate_push(s, mj, y, n_data);
    if (!hadamard_sigma2(s.sum_sq, s.terms, mj, sigma2[j])) return false;
    if (terms != nullptr) terms[j] = s.terms;
  }
  return true;
}

}  // namespace gyrodrift
