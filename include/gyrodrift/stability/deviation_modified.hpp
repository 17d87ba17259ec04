// Modified Allan variance of rate data in O(N) per averaging factor (NIST SP 1065 eq. 14);
// the time variance is TVAR = tau^2 / 3 MVAR (eq. 15), formed by the caller.
//
// Rate input y_0..y_{N-1}, phase x_k = tau0 (y_0 + ... + y_{k-1}) (N + 1 phase points),
// S_i = y_i + ... + y_{i+m-1}, D_i = S_{i+m} - S_i (so x_{i+2m} - 2 x_{i+m} + x_i = tau0 D_i):
//   Mod sigma^2(m tau0) = 1 / (2 m^4 n) sum_{j=0}^{n-1} V_j^2,   V_j = sum_{i=j}^{j+m-1} D_i,
//   n = (N + 1) - 3m + 1 = N - 3m + 2.
// Running updates, O(1) per term:
//   V_{j+1} = V_j + (D_{j+m} - D_j) = V_j + H_j,  H_j = S_{j+2m} - 2 S_{j+m} + S_j,
//   H_{j+1} = H_j + y_{j+3m} - 3 y_{j+2m} + 3 y_{j+m} - y_j.
// Precision: V integrates H, so a plain running H (whose rounding random-walks) would make
// V's error grow like N^1.5 2^-64; H is therefore carried with its rounding error (TwoSum,
// Knuth), which keeps it within ~1 ulp, and V's own error only random-walks (sqrt(N) 2^-64).
// Every quantity is a difference of samples, so a large constant rate cancels exactly.
//
// Streaming: seed_diff, seed_inner, advance, finish take any split of their index ranges;
// mdev() is the whole-array driver. No allocation, no exceptions.
#pragma once
#include <cmath>
#include <cstddef>

namespace gyrodrift {

template <class Accum = long double>
struct ModAllanSums {
  Accum diff{0};   // running D (seed stage)
  Accum third{0};  // running H
  Accum comp{0};   // rounding error of the running H (TwoSum)
  Accum inner{0};  // running V
  Accum sum_sq{0};
  std::size_t terms{0};
};

// Largest m leaving at least 2 terms (n = N - 3m + 2 >= 2; allantools.mdev drops n <= 1).
inline std::size_t mdev_max_m(std::size_t n_data) noexcept {
  return n_data >= 3 ? n_data / 3 : 0;
}

inline std::size_t mdev_terms(std::size_t n_data, std::size_t m) noexcept {
  if (m == 0 || 3 * m > n_data) return 0;
  return n_data - 3 * m + 2;
}

// Step 1: D_0 = sum_{k<m} (y[m+k] - y[k]); lo = &y[k0], hi = &y[m+k0], any split of k < m.
template <class Scalar, class Accum>
inline void mdev_rate_seed_diff(ModAllanSums<Accum>& s, const Scalar* lo, const Scalar* hi,
                                std::size_t n) noexcept {
  Accum part{0};
  for (std::size_t k = 0; k < n; ++k) {
    part += static_cast<Accum>(hi[k]) - static_cast<Accum>(lo[k]);
  }
  s.diff += part;
}

// Step 2 (after all of step 1): for i = 0..m-1 (y_s = &y[i0 + s m], s = 0..2), V += D_i and
// D_{i+1} = D_i + y_{i+2m} - 2 y_{i+m} + y_i. At the end V = V_0 and H_0 = D_m - D_0 is the
// sum of the same increments.
template <class Scalar, class Accum>
inline void mdev_rate_seed_inner(ModAllanSums<Accum>& s, const Scalar* y0, const Scalar* y1,
                                 const Scalar* y2, std::size_t n) noexcept {
  Accum d = s.diff;
  Accum v = s.inner;
  Accum h{0};
  for (std::size_t k = 0; k < n; ++k) {
    v += d;
    const Accum inc = (static_cast<Accum>(y2[k]) - static_cast<Accum>(y1[k])) -
                      (static_cast<Accum>(y1[k]) - static_cast<Accum>(y0[k]));
    d += inc;
    h += inc;
  }
  s.diff = d;
  s.inner = v;
  s.third += h;
}

// TwoSum (Knuth): t = a + b rounded, returns the exact error a + b - t (no branch).
template <class Accum>
inline Accum two_sum_err(Accum a, Accum b, Accum t) noexcept {
  const Accum bb = t - a;
  return (a - (t - bb)) + (b - bb);
}

// Step 3: terms j = j0..j0+n-1 given y_s = &y[j0 + s m], s = 0..3: adds V_j^2, V += H_j,
// H moves to H_{j+1}. Call for n_terms - 2 terms in total (the last H update then reads
// y[N-1]), then mdev_rate_finish() adds the last two terms.
template <class Scalar, class Accum>
inline void mdev_rate_advance(ModAllanSums<Accum>& s, const Scalar* y0, const Scalar* y1,
                              const Scalar* y2, const Scalar* y3, std::size_t n) noexcept {
  Accum v = s.inner;
  Accum h = s.third;
  Accum c = s.comp;
  Accum sq{0};
  for (std::size_t j = 0; j < n; ++j) {
    sq += v * v;
    v += h + c;
    const Accum inc = (static_cast<Accum>(y3[j]) - static_cast<Accum>(y0[j])) +
                      Accum(3) * (static_cast<Accum>(y1[j]) - static_cast<Accum>(y2[j]));
    const Accum t = h + inc;
    c += two_sum_err(h, inc, t);
    h = t;
  }
  s.inner = v;
  s.third = h;
  s.comp = c;
  s.sum_sq += sq;
  s.terms += n;
}

// Step 4: the last two terms, V_{n-2}^2 and V_{n-1}^2 = (V_{n-2} + H_{n-2})^2.
template <class Accum>
inline void mdev_rate_finish(ModAllanSums<Accum>& s) noexcept {
  s.sum_sq += s.inner * s.inner;
  s.inner += s.third + s.comp;
  s.sum_sq += s.inner * s.inner;
  s.terms += 2;
}

// Mod sigma^2 = sum V^2 / (2 m^4 n), (rate units)^2; false if no terms or not finite.
template <class Accum, class Out>
inline bool mdev_sigma2(const ModAllanSums<Accum>& s, std::size_t m, Out& out) noexcept {
  if (s.terms == 0 || m == 0) return false;
  const Accum mm = static_cast<Accum>(m);
  const Accum v = s.sum_sq / (Accum(2) * mm * mm * mm * mm * static_cast<Accum>(s.terms));
  if (!std::isfinite(v)) return false;
  out = static_cast<Out>(v);
  return true;
}

template <class Scalar, class Out, class Accum = long double>
inline bool mdev(const Scalar* y, std::size_t n_data, const std::size_t* m, std::size_t n_m,
                 Out* sigma2, std::size_t* terms) noexcept {
  const std::size_t max_m = mdev_max_m(n_data);
  for (std::size_t j = 0; j < n_m; ++j) {
    const std::size_t mj = m[j];
    if (mj == 0 || mj > max_m) return false;
    const std::size_t n = mdev_terms(n_data, mj);
    ModAllanSums<Accum> s;
    mdev_rate_seed_diff(s, y, y + mj, mj);
    mdev_rate_seed_inner(s, y, y + mj, y + 2 * mj, mj);
    mdev_rate_advance(s, y, y + mj, y + 2 * mj, y + 3 * mj, n - 2);
    mdev_rate_finish(s);
    if (!mdev_sigma2(s, mj, sigma2[j])) return false;
    if (terms != nullptr) terms[j] = s.terms;
  }
  return true;
}

}  // namespace gyrodrift
