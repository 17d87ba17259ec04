// Exact Gaussian log-likelihood of the drift model "AR(2) drift + white measurement noise",
// evaluated by the Kalman filter (prediction-error decomposition), for maximum-likelihood
// identification of a1, a2, q, r and the mean from a record.
//
// Model (the AR(2) of papers 000/002 eq. 1 plus white rate noise):
//   x_k = a1 x_{k-1} + a2 x_{k-2} + w_k,   w_k ~ N(0, q)
//   y_k = mean + x_k + v_k,                  v_k ~ N(0, r)
// AR(1) + white is a2 = 0; white noise alone is a1 = a2 = q = 0.
// State X_k = [x_k, x_{k-1}]^T, A = [[a1, a2], [1, 0]], Q = diag(q, 0), H = [1, 0].
//
// Prediction-error decomposition (Harvey 1989, eq. 3.4.7; Durbin & Koopman 2012, eq. 7.2):
//   log L = -1/2 sum_k ( log 2 pi + log F_k + e_k^2 / F_k ),
//   e_k = y_k - mean - H X_k|k-1,  F_k = H P_k|k-1 H^T + r,
// with the exact (stationary) initial state X_1|0 = 0, P_1|0 = the AR(2) autocovariance matrix
// [[g0, g1], [g1, g0]], the solution of the discrete Lyapunov equation P = A P A^T + Q, in closed
// form from the Yule-Walker equations g1 = a1 g0 / (1 - a2), g0 = a1 g1 + a2 g2 + q,
// g2 = a1 g1 + a2 g0:
//   g0 = q (1 - a2) / ((1 + a2) ((1 - a2)^2 - a1^2)).
//
// The mean enters e_k linearly: running the same filter on the constant sequence 1 gives
// innovations g_k with e_k(mean + d) = e_k(mean) - d g_k (the gains do not depend on the data).
// So one pass returns the sums S_ee = sum e^2/F, S_eg = sum e g / F, S_gg = sum g^2 / F, and
// the log-likelihood at any mean + d is exactly
//   -1/2 (n log 2 pi + S_logF + S_ee - 2 d S_eg + d^2 S_gg),
// its maximiser d = S_eg / S_gg (the GLS mean). Scaling q and r by s scales every F_k by s, so
// the caller can also concentrate out a common scale (s = (S_ee - S_eg^2 / S_gg) / n).
//
// Allocation-free, noexcept, templated on Scalar; the sums are blocked (64 plain additions, then
// a compensated Neumaier addition) so a float build stays within ~1e-6 relative of the double
// result on long records at little cost.
// Once the covariance recursion reaches its fixed point (change <= 4 eps relative) it is latched
// and only the two state recursions run (the remaining change is below rounding).
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>

#include "ar2_model.hpp"

namespace gyrodrift {

template <class Scalar>
struct DriftModelParams {
  Scalar a1, a2;  // AR coefficients of the drift (a2 = 0: AR(1); both 0 with q = 0: white)
  Scalar q;       // drift driving-noise variance, (units of y)^2, >= 0
  Scalar r;       // white measurement-noise variance, (units of y)^2, >= 0 (q + r > 0)
  Scalar mean;    // constant rate offset, units of y
};

template <class Scalar>
struct DriftLikelihoodSums {
  std::size_t n = 0;
  Scalar sum_log_f = Scalar(0);  // sum log F_k
  Scalar sum_ee = Scalar(0);     // sum e_k^2 / F_k at the given mean
  Scalar sum_eg = Scalar(0);     // sum e_k g_k / F_k
  Scalar sum_gg = Scalar(0);     // sum g_k^2 / F_k

  // Exact log-likelihood at the given parameters (mean included).
  Scalar loglike() const noexcept {
    const Scalar log_2pi = Scalar(1.8378770664093454835606594728112353L);
    return Scalar(-0.5) * (static_cast<Scalar>(n) * log_2pi + sum_log_f + sum_ee);
  }
};

namespace detail {

// Neumaier compensated sum: exact to about one rounding of the total, whatever n.
template <class Scalar>
struct CompensatedSum {
  Scalar s = Scalar(0), c = Scalar(0);
  void add(Scalar v) noexcept {
    const Scalar t = s + v;
    if (std::fabs(s) >= std::fabs(v)) {
      c += (s - t) + v;
    } else {
      c += (v - t) + s;
    }
    s = t;
  }
  Scalar value() const noexcept { return s + c; }
};

}  // namespace detail

// Checks the parameters: finite, q >= 0, r >= 0, q + r > 0 (so every F_k > 0), (a1, a2) inside
// the stationarity triangle (ar2_model.hpp). q = 0 is allowed: the drift is then identically 0.
template <class Scalar>
inline Ar2Status drift_params_status(const DriftModelParams<Scalar>& p) noexcept {
  if (!std::isfinite(p.a1) || !std::isfinite(p.a2) || !std::isfinite(p.q) || !std::isfinite(p.r) ||
      !std::isfinite(p.mean)) {
    return Ar2Status::non_finite;
  }
  if (p.q < Scalar(0) || p.r < Scalar(0) || !(p.q + p.r > Scalar(0))) return Ar2Status::bad_argument;
  if (!ar2_is_stationary(p.a1, p.a2)) return Ar2Status::non_stationary;
  return Ar2Status::ok;
}

// Stationary autocovariances (g0, g1) of the AR(2) drift (see the header comment).
template <class Scalar>
inline void drift_stationary_covariance(Scalar a1, Scalar a2, Scalar q, Scalar& g0, Scalar& g1) noexcept {
  const Scalar one = Scalar(1);
  const Scalar d = (one + a2) * ((one - a2) * (one - a2) - a1 * a1);
  g0 = q * (one - a2) / d;
  g1 = a1 * g0 / (one - a2);
}

// Log-likelihood sums of y[0], y[stride], ..., y[(n-1) stride] (stride in elements, so a column
// of an (n, 3) row-major array is y = data + axis, stride = 3). If std_innov is not null, the
// standardised innovations e_k / sqrt(F_k) at the given mean are written to
// std_innov[k * innov_stride]. Returns bad_argument for null y / n == 0 / stride == 0 or bad
// variances, non_stationary, or non_finite (parameters, data, or an overflowing recursion);
// `out` is only written on ok.
template <class Scalar>
Ar2Status drift_likelihood(const Scalar* y, std::size_t n, std::ptrdiff_t stride,
                           const DriftModelParams<Scalar>& p, DriftLikelihoodSums<Scalar>& out,
                           Scalar* std_innov = nullptr, std::ptrdiff_t innov_stride = 1) noexcept {
  if (y == nullptr || n == 0 || stride == 0 || (std_innov != nullptr && innov_stride == 0)) {
    return Ar2Status::bad_argument;
  }
  const Ar2Status ps = drift_params_status(p);
  if (ps != Ar2Status::ok) return ps;
  const Scalar a1 = p.a1, a2 = p.a2, q = p.q, r = p.r, mean = p.mean;
  const Scalar eps4 = Scalar(4) * std::numeric_limits<Scalar>::epsilon();

  Scalar p00, p01;
  drift_stationary_covariance(a1, a2, q, p00, p01);
  Scalar p11 = p00;
  // Predicted states of the data (x0, x1) and of the constant-1 sequence (c0, c1).
  Scalar x0 = Scalar(0), x1 = Scalar(0), c0 = Scalar(0), c1 = Scalar(0);
  detail::CompensatedSum<Scalar> slog, see, seg, sgg;
  Scalar f = Scalar(0), inv_f = Scalar(0), log_f = Scalar(0), k0 = Scalar(0), k1 = Scalar(0);
  const Scalar* yk = y;
  std::size_t k = 0;
  // One filter step with the current gain; plain partial sums (b_*) are folded into the
  // compensated totals every kBlock samples, so the hot loop has no compensation branches
  // and the rounding error stays ~ (kBlock eps + n eps^2) relative.
  constexpr std::size_t kBlock = 64;
  Scalar b_log = Scalar(0), b_ee = Scalar(0), b_eg = Scalar(0), b_gg = Scalar(0);
  std::size_t in_block = 0;
  bool bad_sample = false;
  auto step = [&](std::size_t idx) noexcept {
    const Scalar v = *yk;
    bad_sample = bad_sample || !std::isfinite(v);
    const Scalar e = (v - mean) - x0;
    const Scalar g = Scalar(1) - c0;
    b_log += log_f;
    b_ee += e * e * inv_f;
    b_eg += e * g * inv_f;
    b_gg += g * g * inv_f;
    if (std_innov != nullptr) std_innov[static_cast<std::ptrdiff_t>(idx) * innov_stride] = e / std::sqrt(f);
    // Update then predict: X = A (X + K e), the same for the constant sequence.
    const Scalar u0 = x0 + k0 * e, u1 = x1 + k1 * e;
    x0 = a1 * u0 + a2 * u1;
    x1 = u0;
    const Scalar w0 = c0 + k0 * g, w1 = c1 + k1 * g;
    c0 = a1 * w0 + a2 * w1;
    c1 = w0;
    yk += stride;
    if (++in_block == kBlock) {
      slog.add(b_log);
      see.add(b_ee);
      seg.add(b_eg);
      sgg.add(b_gg);
      b_log = b_ee = b_eg = b_gg = Scalar(0);
      in_block = 0;
    }
  };
  // Phase 1: covariance recursion until it reaches its fixed point.
  bool latched = false;
  for (; k < n && !latched; ++k) {
    f = p00 + r;
    if (!(f > Scalar(0)) || !std::isfinite(f)) return Ar2Status::non_finite;
    inv_f = Scalar(1) / f;
    log_f = std::log(f);
    k0 = p00 * inv_f;
    k1 = p01 * inv_f;
    // Filtered covariance P - K H P, then predicted A P A^T + Q.
    const Scalar f00 = p00 - k0 * p00;
    const Scalar f01 = p01 - k0 * p01;
    const Scalar f11 = p11 - k1 * p01;
    const Scalar n00 = a1 * a1 * f00 + Scalar(2) * a1 * a2 * f01 + a2 * a2 * f11 + q;
    const Scalar n01 = a1 * f00 + a2 * f01;
    const Scalar n11 = f00;
    const Scalar change = std::fabs(n00 - p00) + std::fabs(n01 - p01) + std::fabs(n11 - p11);
    const Scalar scale = std::fabs(n00) + std::fabs(n01) + std::fabs(n11);
    // Latch once the next F and gain equal these to rounding.
    latched = change <= eps4 * scale;
    p00 = n00;
    p01 = n01;
    p11 = n11;
    step(k);
  }
  // Phase 2: constant F and gain.
  for (; k < n; ++k) step(k);
  if (bad_sample) return Ar2Status::non_finite;
  slog.add(b_log);
  see.add(b_ee);
  seg.add(b_eg);
  sgg.add(b_gg);
  if (!std::isfinite(see.value() + slog.value() + x0)) return Ar2Status::non_finite;
  out.n = n;
  out.sum_log_f = slog.value();
  out.sum_ee = see.value();
  out.sum_eg = seg.value();
  out.sum_gg = sgg.value();
  return Ar2Status::ok;
}

}  // namespace gyrodrift
