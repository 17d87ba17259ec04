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
// DriftLikelihoodStream gives the same pass over a record read in pieces (bounded memory).
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

// The likelihood pass over a record that arrives in pieces (a file read in chunks): begin()
// with the parameters, update() with consecutive pieces, finish() for the sums. The state
// carries the filter, the covariance latch and the partial block sums across pieces, so the
// sums are those of one pass over the whole record, bit for bit, however it is cut.
// Allocation-free and noexcept like drift_likelihood (which is begin + one update + finish).
template <class Scalar>
class DriftLikelihoodStream {
 public:
  // Checks the parameters (drift_params_status) and sets the stationary start.
  Ar2Status begin(const DriftModelParams<Scalar>& p) noexcept {
    status_ = drift_params_status(p);
    if (status_ != Ar2Status::ok) return status_;
    p_ = p;
    drift_stationary_covariance(p.a1, p.a2, p.q, p00_, p01_);
    p11_ = p00_;
    x0_ = x1_ = c0_ = c1_ = Scalar(0);
    f_ = inv_f_ = log_f_ = k0_ = k1_ = Scalar(0);
    slog_ = see_ = seg_ = sgg_ = detail::CompensatedSum<Scalar>{};
    b_log_ = b_ee_ = b_eg_ = b_gg_ = Scalar(0);
    in_block_ = 0;
    n_ = 0;
    latched_ = false;
    bad_sample_ = false;
    return status_;
  }

  // The next n samples y[0], y[stride], ...; if std_innov is not null, their standardised
  // innovations e_k / sqrt(F_k) go to std_innov[k * innov_stride] (k counted in this piece).
  // A refused piece (bad_argument, or non_finite from an overflowing recursion) ends the pass:
  // every later call returns the same status.
  Ar2Status update(const Scalar* y, std::size_t n, std::ptrdiff_t stride,
                   Scalar* std_innov = nullptr, std::ptrdiff_t innov_stride = 1) noexcept {
    if (status_ != Ar2Status::ok) return status_;
    if (n == 0) return status_;
    if (y == nullptr || stride == 0 || (std_innov != nullptr && innov_stride == 0)) {
      status_ = Ar2Status::bad_argument;
      return status_;
    }
    const Scalar a1 = p_.a1, a2 = p_.a2, q = p_.q, r = p_.r, mean = p_.mean;
    const Scalar eps4 = Scalar(4) * std::numeric_limits<Scalar>::epsilon();
    const Scalar* yk = y;
    // One filter step with the current gain; plain partial sums (b_*) are folded into the
    // compensated totals every kBlock samples, so the hot loop has no compensation branches
    // and the rounding error stays ~ (kBlock eps + n eps^2) relative.
    auto step = [&](std::size_t idx) noexcept {
      const Scalar v = *yk;
      bad_sample_ = bad_sample_ || !std::isfinite(v);
      const Scalar e = (v - mean) - x0_;
      const Scalar g = Scalar(1) - c0_;
      b_log_ += log_f_;
      b_ee_ += e * e * inv_f_;
      b_eg_ += e * g * inv_f_;
      b_gg_ += g * g * inv_f_;
      if (std_innov != nullptr) {
        std_innov[static_cast<std::ptrdiff_t>(idx) * innov_stride] = e / std::sqrt(f_);
      }
      // Update then predict: X = A (X + K e), the same for the constant sequence.
      const Scalar u0 = x0_ + k0_ * e, u1 = x1_ + k1_ * e;
      x0_ = a1 * u0 + a2 * u1;
      x1_ = u0;
      const Scalar w0 = c0_ + k0_ * g, w1 = c1_ + k1_ * g;
      c0_ = a1 * w0 + a2 * w1;
      c1_ = w0;
      yk += stride;
      if (++in_block_ == kBlock) {
        slog_.add(b_log_);
        see_.add(b_ee_);
        seg_.add(b_eg_);
        sgg_.add(b_gg_);
        b_log_ = b_ee_ = b_eg_ = b_gg_ = Scalar(0);
        in_block_ = 0;
      }
    };
    std::size_t k = 0;
    // Phase 1: covariance recursion until it reaches its fixed point.
    for (; k < n && !latched_; ++k) {
      f_ = p00_ + r;
      if (!(f_ > Scalar(0)) || !std::isfinite(f_)) {
        status_ = Ar2Status::non_finite;
        return status_;
      }
      inv_f_ = Scalar(1) / f_;
      log_f_ = std::log(f_);
      k0_ = p00_ * inv_f_;
      k1_ = p01_ * inv_f_;
      // Filtered covariance P - K H P, then predicted A P A^T + Q.
      const Scalar f00 = p00_ - k0_ * p00_;
      const Scalar f01 = p01_ - k0_ * p01_;
      const Scalar f11 = p11_ - k1_ * p01_;
      const Scalar n00 = a1 * a1 * f00 + Scalar(2) * a1 * a2 * f01 + a2 * a2 * f11 + q;
      const Scalar n01 = a1 * f00 + a2 * f01;
      const Scalar n11 = f00;
      const Scalar change = std::fabs(n00 - p00_) + std::fabs(n01 - p01_) + std::fabs(n11 - p11_);
      const Scalar scale = std::fabs(n00) + std::fabs(n01) + std::fabs(n11);
      // Latch once the next F and gain equal these to rounding.
      latched_ = change <= eps4 * scale;
      p00_ = n00;
      p01_ = n01;
      p11_ = n11;
      step(k);
    }
    // Phase 2: constant F and gain.
    for (; k < n; ++k) step(k);
    n_ += n;
    return status_;
  }

  // The sums of everything passed to update() (bad_argument when nothing was; non_finite for
  // a NaN/Inf sample or sums that overflowed); `out` is only written on ok. The stream may
  // continue after it.
  Ar2Status finish(DriftLikelihoodSums<Scalar>& out) const noexcept {
    if (status_ != Ar2Status::ok) return status_;
    if (n_ == 0) return Ar2Status::bad_argument;
    if (bad_sample_) return Ar2Status::non_finite;
    detail::CompensatedSum<Scalar> slog = slog_, see = see_, seg = seg_, sgg = sgg_;
    slog.add(b_log_);
    see.add(b_ee_);
    seg.add(b_eg_);
    sgg.add(b_gg_);
    if (!std::isfinite(see.value() + slog.value() + x0_)) return Ar2Status::non_finite;
    out.n = n_;
    out.sum_log_f = slog.value();
    out.sum_ee = see.value();
    out.sum_eg = seg.value();
    out.sum_gg = sgg.value();
    return Ar2Status::ok;
  }

 private:
  static constexpr std::size_t kBlock = 64;
  DriftModelParams<Scalar> p_{};
  Ar2Status status_ = Ar2Status::bad_argument;  // until begin()
  // Covariance (p00, p01, p11), predicted states of the data (x0, x1) and of the constant-1
  // sequence (c0, c1), the current F, 1/F, log F and gain (k0, k1).
  Scalar p00_ = Scalar(0), p01_ = Scalar(0), p11_ = Scalar(0);
  Scalar x0_ = Scalar(0), x1_ = Scalar(0), c0_ = Scalar(0), c1_ = Scalar(0);
  Scalar f_ = Scalar(0), inv_f_ = Scalar(0), log_f_ = Scalar(0), k0_ = Scalar(0), k1_ = Scalar(0);
  detail::CompensatedSum<Scalar> slog_{}, see_{}, seg_{}, sgg_{};
  Scalar b_log_ = Scalar(0), b_ee_ = Scalar(0), b_eg_ = Scalar(0), b_gg_ = Scalar(0);
  std::size_t in_block_ = 0;
  std::size_t n_ = 0;
  bool latched_ = false;
  bool bad_sample_ = false;
};

// Log-likelihood sums of y[0], y[stride], ..., y[(n-1) stride] (stride in elements, so a column
// of an (n, 3) row-major array is y = data + axis, stride = 3). If std_innov is not null, the
// standardised innovations e_k / sqrt(F_k) at the given mean are written to
// std_innov[k * innov_stride]. Returns bad_argument for null y / n == 0 / stride == 0 or bad
// variances, non_stationary, or non_finite (parameters, data, or an overflowing recursion);
// `out` is only written on ok. One DriftLikelihoodStream pass over the whole record.
template <class Scalar>
Ar2Status drift_likelihood(const Scalar* y, std::size_t n, std::ptrdiff_t stride,
                           const DriftModelParams<Scalar>& p, DriftLikelihoodSums<Scalar>& out,
                           Scalar* std_innov = nullptr, std::ptrdiff_t innov_stride = 1) noexcept {
  if (y == nullptr || n == 0 || stride == 0 || (std_innov != nullptr && innov_stride == 0)) {
    return Ar2Status::bad_argument;
  }
  DriftLikelihoodStream<Scalar> stream;
  Ar2Status s = stream.begin(p);
  if (s != Ar2Status::ok) return s;
  s = stream.update(y, n, stride, std_innov, innov_stride);
  if (s != Ar2Status::ok) return s;
  return stream.finish(out);
}

}  // namespace gyrodrift
