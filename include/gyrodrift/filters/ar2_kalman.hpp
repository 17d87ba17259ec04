// AR(2)-Kalman filter for gyro random drift (paper 000 sec. 2.2, paper 002 sec. 3).
//
// State X_k = [x_k, x_{k-1}]^T of the demeaned rate x = y - mean,
//   X_k = A X_{k-1} + B V_k,  A = [[a1, a2], [1, 0]],  B = diag(1, 0),  V_k = [r_k, 0]^T
//   Z_k = C X_k + W_k,        C = [1, 0],  var(r_k) = q,  var(W_k) = r
// with X_0 = 0 and P_0 = p0 I (papers: P_0 = I). One step:
//   predict  X- = A X,  P- = A P A^T + B Q B^T = A P A^T + diag(q, 0)
//   gain     K = P- C^T (C P- C^T + r)^-1   (the papers print (C P- + R)^-1: erratum, C^T is
//            needed for the 1x1 innovation covariance); C P- C^T + r is a scalar, so K is a
//            division, never an inverse
//   update   X = X- + K (z - C X-),  P = (I - K C) P- (I - K C)^T + K r K^T  (Joseph form)
// Output: C X + mean (same units as y).
// Defaults (papers): q = sigma2 of the model, r = variance of the AR(2) estimation error.
//
// Robustness: a NaN/Inf sample is a predict-only step and increments fault_count(); an update
// that would make the state or covariance non-finite (e.g. overflowing input) is rejected the
// same way, so the state never becomes NaN. A finite sample beyond filter_input_limit()
// (input_range.hpp) is treated like NaN: it would drive the state towards overflow, after
// which even the predict-only step could not keep it finite. The model mean must lie within
// that limit (bad_argument otherwise). A filter built from an invalid configuration
// (non-stationary model, q < 0, r <= 0, non-finite numbers; see status()) passes samples
// through unchanged. No heap, no exceptions; step() is noexcept.
// Speed: P, K do not depend on the data, so once P reaches its floating-point fixed point the
// step only updates the state (set_covariance_latch(); outputs are bit-identical).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "ar2_model.hpp"
#include "input_range.hpp"

namespace gyrodrift {

namespace detail {

template <class Scalar>
Ar2Status ar2_filter_config_status(const Ar2Model<Scalar>& m, Scalar q, Scalar r, Scalar p0) noexcept {
  if (!std::isfinite(m.a1) || !std::isfinite(m.a2) || !std::isfinite(m.mean) || !std::isfinite(q) ||
      !std::isfinite(r) || !std::isfinite(p0)) {
    return Ar2Status::non_finite;
  }
  if (!ar2_is_stationary(m.a1, m.a2)) return Ar2Status::non_stationary;
  if (q < Scalar(0) || !(r > Scalar(0)) || p0 < Scalar(0) || !filter_input_ok(m.mean)) {
    return Ar2Status::bad_argument;
  }
  return Ar2Status::ok;
}

}  // namespace detail

template <class Scalar>
class Ar2Kalman {
 public:
  using Vector2 = Eigen::Matrix<Scalar, 2, 1>;
  using Matrix2 = Eigen::Matrix<Scalar, 2, 2>;

  // q, r: variances (units of y squared); p0: initial covariance P_0 = p0 I.
  Ar2Kalman(const Ar2Model<Scalar>& model, Scalar q, Scalar r, Scalar p0 = Scalar(1)) noexcept
      : a1_(model.a1), a2_(model.a2), mean_(model.mean), q_(q), r_(r), p0_(p0),
        status_(detail::ar2_filter_config_status(model, q, r, p0)) {
    reset();
  }

  // Filtered sample (same units as y, mean included).
  Scalar step(Scalar y) noexcept {
    if (status_ != Ar2Status::ok) return y;
    const Scalar x0 = a1_ * x_(0) + a2_ * x_(1);
    const Scalar x1 = x_(0);
    const Scalar z = y - mean_;
    if (latched_ && filter_input_ok(z)) {
      // Covariance at its floating-point fixed point: the recursion in full_step() would
      // recompute exactly these P-, K and P, so only the state is updated (bit-identical).
      const Scalar v = z - x0;
      const Scalar nx0 = x0 + k_(0) * v;
      const Scalar nx1 = x1 + k_(1) * v;
      if (std::isfinite(nx0 + nx1)) {
        x_ << nx0, nx1;
        return nx0 + mean_;
      }
    }
    return full_step(x0, x1, z);
  }

  // out[k] = step(in[k]) for k < n (bit-identical: same operations in the same order), with
  // the latched stretches run in a tight loop whose state lives in registers. in and out may
  // be the same buffer.
  void process(const Scalar* in, Scalar* out, std::size_t n) noexcept {
    std::size_t k = 0;
    while (k < n) {
      if (latched_ && status_ == Ar2Status::ok) {
        const Scalar a1 = a1_, a2 = a2_, mean = mean_, k0 = k_(0), k1 = k_(1);
        Scalar s0 = x_(0), s1 = x_(1);
        for (; k < n; ++k) {
          const Scalar x0 = a1 * s0 + a2 * s1;
          const Scalar z = in[k] - mean;
          if (!filter_input_ok(z)) break;  // NaN/Inf/out of range: the full step handles it
          const Scalar v = z - x0;
          const Scalar nx0 = x0 + k0 * v;
          const Scalar nx1 = s0 + k1 * v;
          if (!std::isfinite(nx0 + nx1)) break;  // fault (or NaN input): the full step handles it
          s0 = nx0;
          s1 = nx1;
          out[k] = nx0 + mean;
        }
        x_ << s0, s1;
        if (k == n) break;
      }
      out[k] = step(in[k]);
      ++k;
    }
  }

  // The covariance recursion does not depend on the data: once P reaches a floating-point
  // fixed point (P_k == P_{k-1} bit for bit) the filter skips recomputing it until a fault
  // step perturbs P. Outputs are bit-identical either way; disable for constant per-step
  // execution time (the worst case, e.g. for WCET budgets).
  void set_covariance_latch(bool enabled) noexcept {
    latch_enabled_ = enabled;
    if (!enabled) latched_ = false;
  }
  bool covariance_latched() const noexcept { return latched_; }

  // Back to X_0 = 0, P_0 = p0 I, zero faults: identical behaviour to a new filter.
  void reset() noexcept {
    x_.setZero();
    P_ = Matrix2::Identity() * p0_;
    k_.setZero();
    faults_ = 0;
    latched_ = false;
  }

  std::uint32_t fault_count() const noexcept { return faults_; }
  Ar2Status status() const noexcept { return status_; }
  const Vector2& state() const noexcept { return x_; }        // demeaned [x_k, x_{k-1}]
  const Matrix2& covariance() const noexcept { return P_; }
  Scalar q() const noexcept { return q_; }
  Scalar r() const noexcept { return r_; }

 private:
  // Predict + Joseph update given the predicted state (x0, x1) and demeaned sample z; a
  // non-finite z or update is a predict-only step.
  Scalar full_step(Scalar x0, Scalar x1, Scalar z) noexcept {
    latched_ = false;
    // Predict (P symmetric: only p00, p01, p11 are formed, then mirrored).
    const Scalar p00 = P_(0, 0), p01 = P_(0, 1), p11 = P_(1, 1);
    const Scalar m00 = a1_ * p00 + a2_ * p01;  // (A P)_00
    const Scalar m01 = a1_ * p01 + a2_ * p11;  // (A P)_01
    const Scalar pp00 = m00 * a1_ + m01 * a2_ + q_;
    const Scalar pp01 = m00;
    const Scalar pp11 = p00;
    if (filter_input_ok(z)) {
      const Scalar s = pp00 + r_;  // C P- C^T + r, > 0 since r > 0 and P- >= 0
      const Scalar k0 = pp00 / s;
      const Scalar k1 = pp01 / s;
      const Scalar v = z - x0;
      const Scalar nx0 = x0 + k0 * v;
      const Scalar nx1 = x1 + k1 * v;
      // Joseph form with I - K C = [[1 - k0, 0], [-k1, 1]].
      const Scalar g = Scalar(1) - k0;
      const Scalar j00 = g * pp00;
      const Scalar j01 = g * pp01;
      const Scalar j10 = pp01 - k1 * pp00;
      const Scalar j11 = pp11 - k1 * pp01;
      const Scalar np00 = j00 * g + r_ * k0 * k0;
      const Scalar np01 = j01 - j00 * k1 + r_ * k0 * k1;
      const Scalar np11 = j11 - j10 * k1 + r_ * k1 * k1;
      if (std::isfinite(nx0 + nx1 + np00 + np01 + np11)) {
        x_ << nx0, nx1;
        const Matrix2 before = P_;
        store_p(np00, np01, np11);
        if (latch_enabled_ && P_ == before) {
          latched_ = true;
          k_ << k0, k1;
        }
        return nx0 + mean_;
      }
    }
    // Predict-only step (missing/corrupt sample or rejected update).
    ++faults_;
    x_ << x0, x1;
    store_p(pp00, pp01, pp11);
    return x0 + mean_;
  }

  // Symmetric by construction; diagonal clamped at 0 against rounding (P is PSD in exact
  // arithmetic, Joseph form keeps it so up to rounding).
  void store_p(Scalar p00, Scalar p01, Scalar p11) noexcept {
    P_(0, 0) = p00 > Scalar(0) ? p00 : Scalar(0);
    P_(1, 1) = p11 > Scalar(0) ? p11 : Scalar(0);
    P_(0, 1) = p01;
    P_(1, 0) = p01;
  }

  Scalar a1_, a2_, mean_, q_, r_, p0_;
  Ar2Status status_;
  Vector2 x_, k_;  // k_: gain cached while the covariance is latched
  Matrix2 P_;
  std::uint32_t faults_ = 0;
  bool latch_enabled_ = true, latched_ = false;
};

}  // namespace gyrodrift
