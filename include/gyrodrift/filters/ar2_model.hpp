// AR(2) drift model and its identification from a block of samples.
//
// Model (paper 000 eq. 1, paper 002 eq. 1):  y_k - m = a1 (y_{k-1} - m) + a2 (y_{k-2} - m) + r_k,
// r_k white with variance sigma2, m the mean (constant drift), kept in the model.
//
// Three estimators, all allocation-free and noexcept:
//   * Yule-Walker from biased (1/n) autocovariances c0, c1, c2 of the demeaned data, either
//     two-pass over a buffer (fit_ar2) or streaming (Ar2YuleWalkerAccumulator, lag-0..2 sums
//     of the data shifted by its first sample, mean corrected exactly at the end);
//   * Burg (order 2), from read-only passes over the caller's buffer: the stage-1 forward and
//     backward errors are recomputed from three consecutive samples, so no work array;
//   * forward-backward least squares (MATLAB `ar` default 'fb' approach): minimise the sum of
//     squared forward and backward one-step prediction errors; sigma2 = cost / (2 (n - 2)).
// Every fit rejects, with a status naming the cause: too few samples, constant data,
// NaN/Inf, or a model whose characteristic roots are on/outside the unit circle.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace gyrodrift {

template <class Scalar>
struct Ar2Model {
  Scalar a1, a2, sigma2, mean;  // sigma2: driving-noise variance, units of y squared
};

// Status of identification and of filter construction.
enum class Ar2Status : std::uint8_t {
  ok = 0,
  too_short,       // fewer than kAr2MinSamples samples
  constant,        // all samples equal: no autocovariance to fit
  non_finite,      // NaN or Inf in the data or in an argument
  non_stationary,  // roots of z^2 - a1 z - a2 on or outside the unit circle (or singular fit)
  bad_argument,    // null pointer, negative variance, r <= 0, ...
  not_converged,   // steady-state Riccati iteration hit its bound
};

inline const char* to_string(Ar2Status s) noexcept {
  switch (s) {
    case Ar2Status::ok: return "ok";
    case Ar2Status::too_short: return "too short";
    case Ar2Status::constant: return "constant";
    case Ar2Status::non_finite: return "non-finite";
    case Ar2Status::non_stationary: return "non-stationary";
    case Ar2Status::bad_argument: return "bad argument";
    case Ar2Status::not_converged: return "not converged";
  }
  return "unknown";
}

enum class Ar2Method : std::uint8_t { yule_walker = 0, burg = 1, least_squares = 2 };

// Below 8 samples the lag-2 autocovariance rests on at most 6 products: no variance
// estimate worth the name (the papers fit records of thousands of samples).
inline constexpr std::size_t kAr2MinSamples = 8;

// Stationarity triangle of an AR(2): both roots of z^2 - a1 z - a2 strictly inside the
// unit circle  <=>  |a2| < 1, a1 + a2 < 1, a2 - a1 < 1. "On the circle" is decided with a
// margin of 64 eps (rounding of a fit to an exactly periodic record lands within a few eps).
template <class Scalar>
inline bool ar2_is_stationary(Scalar a1, Scalar a2) noexcept {
  const Scalar one = Scalar(1) - Scalar(64) * std::numeric_limits<Scalar>::epsilon();
  return std::isfinite(a1) && std::isfinite(a2) && a2 < one && a2 > -one && a1 + a2 < one &&
         a2 - a1 < one;
}

namespace detail {

// Shared final checks of every estimator.
template <class Scalar>
Ar2Status ar2_finish(Scalar a1, Scalar a2, Scalar sigma2, Scalar mean, Ar2Model<Scalar>& out) noexcept {
  if (!std::isfinite(sigma2) || !ar2_is_stationary(a1, a2)) return Ar2Status::non_stationary;
  out.a1 = a1;
  out.a2 = a2;
  out.sigma2 = sigma2 > Scalar(0) ? sigma2 : Scalar(0);
  out.mean = mean;
  return Ar2Status::ok;
}

// Yule-Walker from biased autocovariances (c0 > 0):
//   [c0 c1; c1 c0] [a1; a2] = [c1; c2],  sigma2 = c0 - a1 c1 - a2 c2.
template <class Scalar>
Ar2Status ar2_from_autocov(Scalar c0, Scalar c1, Scalar c2, Scalar mean, Ar2Model<Scalar>& out) noexcept {
  if (!(c0 > Scalar(0)) || !std::isfinite(c0) || !std::isfinite(c1) || !std::isfinite(c2)) {
    return Ar2Status::constant;
  }
  const Scalar rho1 = c1 / c0;
  const Scalar rho2 = c2 / c0;
  const Scalar det = Scalar(1) - rho1 * rho1;
  if (!(det > Scalar(0))) return Ar2Status::non_stationary;
  const Scalar a1 = rho1 * (Scalar(1) - rho2) / det;
  const Scalar a2 = (rho2 - rho1 * rho1) / det;
  const Scalar sigma2 = c0 * (Scalar(1) - a1 * rho1 - a2 * rho2);
  return ar2_finish(a1, a2, sigma2, mean, out);
}

// Pass 1 over a buffer: finiteness, constancy, mean.
template <class Scalar>
Ar2Status ar2_scan(const Scalar* y, std::size_t n, Scalar& mean) noexcept {
  if (y == nullptr && n != 0) return Ar2Status::bad_argument;
  if (n < kAr2MinSamples) return Ar2Status::too_short;
  Scalar sum = Scalar(0);
  bool all_equal = true;
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(y[i])) return Ar2Status::non_finite;
    all_equal = all_equal && (y[i] == y[0]);
    sum += y[i];
  }
  if (all_equal) return Ar2Status::constant;
  mean = sum / static_cast<Scalar>(n);
  if (!std::isfinite(mean)) return Ar2Status::non_finite;  // overflow of the sum
  return Ar2Status::ok;
}

template <class Scalar>
Ar2Status fit_yule_walker(const Scalar* y, std::size_t n, Scalar mean, Ar2Model<Scalar>& out) noexcept {
  Scalar s0 = Scalar(0), s1 = Scalar(0), s2 = Scalar(0);
  Scalar d1 = Scalar(0), d2 = Scalar(0);  // demeaned y_{i-1}, y_{i-2}
  for (std::size_t i = 0; i < n; ++i) {
    const Scalar d = y[i] - mean;
    s0 += d * d;
    if (i >= 1) s1 += d * d1;
    if (i >= 2) s2 += d * d2;
    d2 = d1;
    d1 = d;
  }
  const Scalar inv_n = Scalar(1) / static_cast<Scalar>(n);
  return ar2_from_autocov(s0 * inv_n, s1 * inv_n, s2 * inv_n, mean, out);
}

// Burg, order 2 (reflection coefficients by the harmonic-mean rule):
//   stage 1: f_k = b_k = x_k;  k1 = -2 sum_{k>=1} f_k b_{k-1} / sum_{k>=1} (f_k^2 + b_{k-1}^2)
//   stage 2: f1_k = x_k + k1 x_{k-1}, b1_k = x_{k-1} + k1 x_k  (k >= 1)
//            k2 = -2 sum_{k>=2} f1_k b1_{k-1} / sum_{k>=2} (f1_k^2 + b1_{k-1}^2)
//   E0 = sum x^2 / n, E_m = E_{m-1} (1 - k_m^2);  polynomial 1 + alpha1 z^-1 + alpha2 z^-2 by
//   Levinson: alpha1 = k1 (1 + k2), alpha2 = k2; AR coefficients a_i = -alpha_i.
template <class Scalar>
Ar2Status fit_burg(const Scalar* y, std::size_t n, Scalar mean, Ar2Model<Scalar>& out) noexcept {
  Scalar e0 = Scalar(0), num1 = Scalar(0), den1 = Scalar(0);
  for (std::size_t i = 0; i < n; ++i) {
    const Scalar x = y[i] - mean;
    e0 += x * x;
    if (i >= 1) {
      const Scalar xp = y[i - 1] - mean;
      num1 += x * xp;
      den1 += x * x + xp * xp;
    }
  }
  if (!(den1 > Scalar(0))) return Ar2Status::constant;
  const Scalar k1 = Scalar(-2) * num1 / den1;
  Scalar num2 = Scalar(0), den2 = Scalar(0);
  for (std::size_t i = 2; i < n; ++i) {
    const Scalar x0 = y[i] - mean, x1 = y[i - 1] - mean, x2 = y[i - 2] - mean;
    const Scalar f = x0 + k1 * x1;  // f1_i
    const Scalar b = x2 + k1 * x1;  // b1_{i-1}
    num2 += f * b;
    den2 += f * f + b * b;
  }
  if (!(den2 > Scalar(0))) return Ar2Status::non_stationary;
  const Scalar k2 = Scalar(-2) * num2 / den2;
  const Scalar sigma2 = e0 / static_cast<Scalar>(n) * (Scalar(1) - k1 * k1) * (Scalar(1) - k2 * k2);
  return ar2_finish(-(k1 * (Scalar(1) + k2)), -k2, sigma2, mean, out);
}

// Forward-backward least squares: rows (x_k; x_{k-1}, x_{k-2}) for k = 2..n-1 and
// (x_{k-2}; x_{k-1}, x_k) for the backward predictor with the same coefficients.
// Normal equations G a = h with
//   G = sum [x_{k-1}^2 + x_{k-1}^2, x_{k-1} x_{k-2} + x_{k-1} x_k; ., x_{k-2}^2 + x_k^2]
//   h = sum [x_k x_{k-1} + x_{k-2} x_{k-1}; x_k x_{k-2} + x_{k-2} x_k]
// solved by Cramer's rule (2x2, determinant checked); sigma2 = residual SS / (2 (n - 2)).
template <class Scalar>
Ar2Status fit_least_squares(const Scalar* y, std::size_t n, Scalar mean, Ar2Model<Scalar>& out) noexcept {
  Scalar g00 = Scalar(0), g01 = Scalar(0), g11 = Scalar(0), h0 = Scalar(0), h1 = Scalar(0),
         yy = Scalar(0);
  for (std::size_t i = 2; i < n; ++i) {
    const Scalar x0 = y[i] - mean, x1 = y[i - 1] - mean, x2 = y[i - 2] - mean;
    g00 += Scalar(2) * x1 * x1;
    g01 += x1 * (x2 + x0);
    g11 += x2 * x2 + x0 * x0;
    h0 += x1 * (x0 + x2);
    h1 += Scalar(2) * x0 * x2;
    yy += x0 * x0 + x2 * x2;
  }
  const Scalar det = g00 * g11 - g01 * g01;
  if (!(det > std::numeric_limits<Scalar>::epsilon() * g00 * g11)) return Ar2Status::non_stationary;
  const Scalar a1 = (h0 * g11 - g01 * h1) / det;
  const Scalar a2 = (g00 * h1 - g01 * h0) / det;
  // Residual SS at the optimum: yy - a^T h (normal equations).
  const Scalar rss = yy - a1 * h0 - a2 * h1;
  const Scalar sigma2 = rss / static_cast<Scalar>(2 * (n - 2));
  return ar2_finish(a1, a2, sigma2, mean, out);
}

}  // namespace detail

// Identify an AR(2) model from y[0..n). Reads the buffer (2 or 3 passes), writes `out` only
// on success. No allocation, no exceptions.
template <class Scalar>
Ar2Status fit_ar2(const Scalar* y, std::size_t n, Ar2Method method, Ar2Model<Scalar>& out) noexcept {
  Scalar mean = Scalar(0);
  const Ar2Status s = detail::ar2_scan(y, n, mean);
  if (s != Ar2Status::ok) return s;
  switch (method) {
    case Ar2Method::yule_walker: return detail::fit_yule_walker(y, n, mean, out);
    case Ar2Method::burg: return detail::fit_burg(y, n, mean, out);
    case Ar2Method::least_squares: return detail::fit_least_squares(y, n, mean, out);
  }
  return Ar2Status::bad_argument;
}

// Variance of the one-step AR(2) prediction error of `model` on y[0..n) (k = 2..n-1): the
// papers' R, "variance of the AR(2) estimation error" (paper 000 sec. 2.2, paper 002 sec. 3).
// Returns NaN if n < 3 or y is null.
template <class Scalar>
Scalar ar2_residual_variance(const Scalar* y, std::size_t n, const Ar2Model<Scalar>& model) noexcept {
  if (y == nullptr || n < 3) return std::numeric_limits<Scalar>::quiet_NaN();
  Scalar ss = Scalar(0);
  for (std::size_t i = 2; i < n; ++i) {
    const Scalar e = (y[i] - model.mean) - model.a1 * (y[i - 1] - model.mean) -
                     model.a2 * (y[i - 2] - model.mean);
    ss += e * e;
  }
  return ss / static_cast<Scalar>(n - 2);
}

// Streaming Yule-Walker for on-target re-identification: push samples one at a time, fit at
// any point. Sums of lags 0..2 are taken of d_i = y_i - y_0 (a shift that keeps a large
// constant drift from cancelling the small random part), then centred exactly:
//   sum_{i=k}^{n-1} (d_i - m)(d_{i-k} - m) = S_k - m (sum_{i>=k} d_i + sum_{i<=n-1-k} d_i) + (n-k) m^2.
// Non-finite samples are not summed; they are counted and make fit() return non_finite.
template <class Scalar>
class Ar2YuleWalkerAccumulator {
 public:
  void reset() noexcept { *this = Ar2YuleWalkerAccumulator(); }

  void push(Scalar y) noexcept {
    if (!std::isfinite(y)) {
      ++non_finite_;
      return;
    }
    if (n_ == 0) shift_ = y;
    const Scalar d = y - shift_;
    sum_ += d;
    s0_ += d * d;
    if (n_ >= 1) s1_ += d * last1_;
    if (n_ >= 2) s2_ += d * last2_;
    if (n_ == 0) head0_ = d;
    if (n_ == 1) head1_ = d;
    if (d != Scalar(0)) varied_ = true;
    last2_ = last1_;
    last1_ = d;
    ++n_;
  }

  std::size_t count() const noexcept { return n_; }
  std::size_t non_finite_count() const noexcept { return non_finite_; }

  Ar2Status fit(Ar2Model<Scalar>& out) const noexcept {
    if (non_finite_ != 0) return Ar2Status::non_finite;
    if (n_ < kAr2MinSamples) return Ar2Status::too_short;
    if (!varied_) return Ar2Status::constant;
    const Scalar n = static_cast<Scalar>(n_);
    const Scalar m = sum_ / n;
    // last1_ = d_{n-1}, last2_ = d_{n-2}
    const Scalar c0 = s0_ - Scalar(2) * m * sum_ + n * m * m;
    const Scalar c1 = s1_ - m * ((sum_ - head0_) + (sum_ - last1_)) + (n - Scalar(1)) * m * m;
    const Scalar c2 = s2_ - m * ((sum_ - head0_ - head1_) + (sum_ - last1_ - last2_)) +
                      (n - Scalar(2)) * m * m;
    if (!std::isfinite(c0) || !std::isfinite(m)) return Ar2Status::non_finite;
    return detail::ar2_from_autocov(c0 / n, c1 / n, c2 / n, m + shift_, out);
  }

 private:
  std::size_t n_ = 0, non_finite_ = 0;
  Scalar shift_ = Scalar(0), sum_ = Scalar(0), s0_ = Scalar(0), s1_ = Scalar(0), s2_ = Scalar(0);
  Scalar head0_ = Scalar(0), head1_ = Scalar(0), last1_ = Scalar(0), last2_ = Scalar(0);
  bool varied_ = false;
};

}  // namespace gyrodrift
