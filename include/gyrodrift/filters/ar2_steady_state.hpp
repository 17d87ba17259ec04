// Constant-gain (steady-state) AR(2)-Kalman filter: the same model as ar2_kalman.hpp, with the
// gain K = P C^T (C P C^T + r)^-1 of the stabilising solution P of the discrete algebraic
// Riccati equation (prediction form)
//   P = A P A^T + diag(q, 0) - A P C^T (C P C^T + r)^-1 C P A^T,
// solved once at construction by iterating the filter's own predict/Joseph-update recursion
// from P = I until the covariance error, extrapolated from the contraction rate of successive
// changes, is <= 64 eps relative (at most
// kAr2RiccatiMaxIterations steps; status() reports not_converged otherwise).
// step() is then two multiply-adds per state: X- = A X, X = X- + K (z - C X-).
// NaN/Inf or out-of-range input (input_range.hpp): predict only + fault counter, as in Ar2Kalman.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>

#include "ar2_kalman.hpp"
#include "ar2_model.hpp"

namespace gyrodrift {

inline constexpr std::uint32_t kAr2RiccatiMaxIterations = 200000;

template <class Scalar>
class Ar2SteadyStateKalman {
 public:
  using Vector2 = Eigen::Matrix<Scalar, 2, 1>;
  using Matrix2 = Eigen::Matrix<Scalar, 2, 2>;

  Ar2SteadyStateKalman(const Ar2Model<Scalar>& model, Scalar q, Scalar r) noexcept
      : a1_(model.a1), a2_(model.a2), mean_(model.mean), status_(Ar2Status::ok) {
    k_.setZero();
    p_pred_.setZero();
    x_.setZero();
    status_ = detail::ar2_filter_config_status(model, q, r, Scalar(1));
    if (status_ != Ar2Status::ok) return;
    solve(q, r);
  }

  Scalar step(Scalar y) noexcept {
    if (status_ != Ar2Status::ok) return y;
    const Scalar x0 = a1_ * x_(0) + a2_ * x_(1);
    const Scalar x1 = x_(0);
    const Scalar z = y - mean_;
    if (filter_input_ok(z)) {
      const Scalar v = z - x0;
      const Scalar nx0 = x0 + k_(0) * v;
      const Scalar nx1 = x1 + k_(1) * v;
      if (std::isfinite(nx0 + nx1)) {
        x_ << nx0, nx1;
        return nx0 + mean_;
      }
    }
    ++faults_;
    x_ << x0, x1;
    return x0 + mean_;
  }

  void reset() noexcept {
    x_.setZero();
    faults_ = 0;
  }

  // Takes a model and its steady-state gain computed elsewhere (an online re-identification
  // that solved the Riccati equation itself), without solving it here. The state is carried
  // over: the filtered rate (x0 + mean) and the previous one stay where they are, re-expressed
  // as deviations from the new mean. False (nothing changed) for a filter that is not ok, a
  // non-stationary model, or a gain or mean that is not finite. predicted_covariance() and
  // iterations() keep describing the constructed model.
  bool retune(Scalar a1, Scalar a2, Scalar mean, Scalar k0, Scalar k1) noexcept {
    if (status_ != Ar2Status::ok || !ar2_is_stationary(a1, a2) || !std::isfinite(mean) || !std::isfinite(k0) ||
        !std::isfinite(k1)) {
      return false;
    }
    const Scalar shift = mean_ - mean;
    x_ << x_(0) + shift, x_(1) + shift;
    a1_ = a1;
    a2_ = a2;
    mean_ = mean;
    k_ << k0, k1;
    return true;
  }

  std::uint32_t fault_count() const noexcept { return faults_; }
  Ar2Status status() const noexcept { return status_; }
  const Vector2& gain() const noexcept { return k_; }
  // Steady-state predicted covariance (the DARE solution).
  const Matrix2& predicted_covariance() const noexcept { return p_pred_; }
  std::uint32_t iterations() const noexcept { return iterations_; }
  const Vector2& state() const noexcept { return x_; }

 private:
  void solve(Scalar q, Scalar r) noexcept {
    const Scalar tol = Scalar(64) * std::numeric_limits<Scalar>::epsilon();
    Scalar p00 = Scalar(1), p01 = Scalar(0), p11 = Scalar(1);  // P_0 = I (filtered form)
    const Scalar inf = std::numeric_limits<Scalar>::infinity();
    Scalar d1 = inf, d2 = inf;  // the two previous covariance changes
    for (std::uint32_t it = 1; it <= kAr2RiccatiMaxIterations; ++it) {
      const Scalar m00 = a1_ * p00 + a2_ * p01;
      const Scalar m01 = a1_ * p01 + a2_ * p11;
      const Scalar pp00 = m00 * a1_ + m01 * a2_ + q;
      const Scalar pp01 = m00;
      const Scalar pp11 = p00;
      const Scalar s = pp00 + r;
      const Scalar k0 = pp00 / s;
      const Scalar k1 = pp01 / s;
      const Scalar g = Scalar(1) - k0;
      const Scalar j00 = g * pp00, j01 = g * pp01;
      const Scalar j10 = pp01 - k1 * pp00, j11 = pp11 - k1 * pp01;
      Scalar n00 = j00 * g + r * k0 * k0;
      const Scalar n01 = j01 - j00 * k1 + r * k0 * k1;
      Scalar n11 = j11 - j10 * k1 + r * k1 * k1;
      if (n00 < Scalar(0)) n00 = Scalar(0);
      if (n11 < Scalar(0)) n11 = Scalar(0);
      if (!std::isfinite(n00 + n01 + n11)) {
        status_ = Ar2Status::non_finite;
        return;
      }
      // Convergence is judged on the whole covariance (the gain alone can repeat on two
      // consecutive steps while P still moves, e.g. a1 = 0). Linear convergence: with d the
      // change of P and rho its contraction rate (the larger of the last two ratios, so an
      // alternating sequence cannot fake a fast rate), the remaining error is about
      // d rho / (1 - rho); stop when that is below tol, or at the rounding floor.
      const Scalar d = std::fabs(n00 - p00) + std::fabs(n01 - p01) + std::fabs(n11 - p11);
      const Scalar scale = std::fabs(n00) + std::fabs(n01) + std::fabs(n11) +
                           std::numeric_limits<Scalar>::min();
      const Scalar r1 = d / d1, r2 = d1 / d2;
      const Scalar rho = r1 > r2 ? r1 : r2;
      d2 = d1;
      d1 = d;
      p00 = n00;
      p01 = n01;
      p11 = n11;
      const bool done = (d <= Scalar(4) * std::numeric_limits<Scalar>::epsilon() * scale) ||
                        (rho < Scalar(1) && d * rho <= tol * scale * (Scalar(1) - rho));
      if (done) {
        k_ << k0, k1;
        p_pred_ << pp00, pp01, pp01, pp11;
        iterations_ = it;
        return;
      }
    }
    iterations_ = kAr2RiccatiMaxIterations;
    status_ = Ar2Status::not_converged;
  }

  Scalar a1_, a2_, mean_;
  Ar2Status status_;
  Vector2 k_, x_;
  Matrix2 p_pred_;
  std::uint32_t faults_ = 0, iterations_ = 0;
};

}  // namespace gyrodrift
