// Fine-alignment Kalman filter with zero-velocity measurements, 12 or 15 states.
// States (psi-angle ENU error model, PSINS "Ft" form), N = 15:
//   x = [phi (rad), dv^n (m/s), dp (ENU m), eps^b (gyro drift rad/s), nabla^b (accel bias m/s^2)]
// N = 12 drops dp. Error model (paper 004 sec. 3.1, standard SINS error equations):
//   phi'  = -[w_in x] phi + M_av dv + M_ap dp - C_b^n eps
//   dv'   = [f^n x] phi - [(2 w_ie + w_en) x] dv + M_vp dp + C_b^n nabla
//   dp'   = dv,  eps' = 0 + w,  nabla' = 0 + w
// Discretisation over T: Phi = I + F T + (F T)^2 / 2, Q_k = (Phi Q Phi^T + Q) T / 2.
// Update: S = H P H^T + R solved by an explicit 3x3 Cholesky (never an explicit inverse; the papers' gain
// P C^T (C P + R)^-1 is the known erratum for P C^T (C P C^T + R)^-1), Joseph form
// P = (I - K H) P (I - K H)^T + K R K^T, symmetrise, diagonal floors. The state is zero before
// each update (closed-loop feedback by the caller), so x = K z.
// Fixed-size, no heap, noexcept; a failed step (non-finite input, S not positive definite,
// non-finite result) returns false and leaves P unchanged.
// Python reference: gyrodrift.align.fine_kf.
#pragma once
#include <Eigen/Core>
#include <cmath>

#include "attitude.hpp"
#include "earth.hpp"

namespace gyrodrift {

template <class Scalar, int N>
class FineAlignKF {
  static_assert(N == 12 || N == 15, "FineAlignKF has 12 or 15 states");

 public:
  using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
  using Mat3 = Eigen::Matrix<Scalar, 3, 3>;
  using VecN = Eigen::Matrix<Scalar, N, 1>;
  using MatN = Eigen::Matrix<Scalar, N, N>;
  static constexpr int kEb = (N == 15) ? 9 : 6;  // gyro drift block
  static constexpr int kDb = kEb + 3;             // accelerometer bias block
  static constexpr int kDp = 6;                   // position block (N == 15 only)

  FineAlignKF() noexcept {
    P_.setIdentity();
    q_.setZero();
    floor_.setZero();
    R_.setIdentity();
    x_.setZero();
  }

  bool reset(const VecN& p0_diag, const VecN& q_diag, const Vec3& r_diag,
             const VecN& floor_diag) noexcept {
    if (!p0_diag.allFinite() || !q_diag.allFinite() || !r_diag.allFinite() ||
        !floor_diag.allFinite() || (p0_diag.array() <= Scalar(0)).any() ||
        (q_diag.array() < Scalar(0)).any() || (r_diag.array() <= Scalar(0)).any() ||
        (floor_diag.array() < Scalar(0)).any())
      return false;
    P_ = p0_diag.asDiagonal();
    q_ = q_diag;
    R_ = r_diag.asDiagonal();
    floor_ = floor_diag;
    x_.setZero();
    return true;
  }

  // Replaces the process-noise PSD diagonal (e.g. the heading acquisition stage of
  // AlignPipeline); P and x are kept. Returns false (and keeps the old Q) on invalid input.
  bool set_process_noise(const VecN& q_diag) noexcept {
    if (!q_diag.allFinite() || (q_diag.array() < Scalar(0)).any()) return false;
    q_ = q_diag;
    return true;
  }

  // Continuous-time F at the current navigation state (C_b^n, f^n, Earth parameters, latitude).
  static void transition(const Mat3& cnb, const Vec3& fn, const EarthParams<Scalar>& ep,
                         Scalar lat_rad, MatN& f) noexcept {
    f.setZero();
    f.template block<3, 3>(0, 0) = -skew(ep.wnin);
    f(0, 4) = -Scalar(1) / ep.rm_h_m;
    f(1, 3) = Scalar(1) / ep.rn_h_m;
    f(2, 3) = ep.tan_lat / ep.rn_h_m;
    f.template block<3, 3>(0, kEb) = -cnb;
    f.template block<3, 3>(3, 0) = skew(fn);
    f.template block<3, 3>(3, 3) = -skew(Vec3(Scalar(2) * ep.wnie + ep.wnen));
    f.template block<3, 3>(3, kDb) = cnb;
    if constexpr (N == 15) {
      using C = EarthConstants<Scalar>;
      f(1, 7) = -C::rate_rad_s * std::sin(lat_rad) / ep.rm_h_m;
      f(2, 7) = C::rate_rad_s * std::cos(lat_rad) / ep.rm_h_m;
      f(5, 8) = C::g_dh_per_s2;
      f.template block<3, 3>(6, 3).setIdentity();
    }
  }

  bool predict(const MatN& f, Scalar t_s) noexcept {
    if (!f.allFinite() || !(t_s > Scalar(0))) return false;
    // lazyProduct: coefficient-based fixed-size products, so no GEMM blocking workspace (which
    // could fall back to the heap) is compiled in; 15^3 MACs at 10 Hz are negligible. The
    // N x N temporaries are members (ws_*), not stack frames: on a Cortex-M4F the float
    // 15-state filter would otherwise need ~5.5 KiB of stack in this function.
    MatN& ft = ws_a_;
    MatN& phi = ws_b_;
    MatN& tmp = ws_c_;
    ft = f * t_s;
    phi.noalias() = ft.lazyProduct(ft);
    phi = MatN::Identity() + ft + Scalar(0.5) * phi;
    ft.noalias() = phi * q_.asDiagonal();  // ft now holds Phi Q
    tmp.noalias() = ft.lazyProduct(phi.transpose());  // Phi Q Phi^T
    tmp += MatN(q_.asDiagonal());
    tmp *= Scalar(0.5) * t_s;  // Q_k (trapezoid)
    ft.noalias() = phi.lazyProduct(P_);  // Phi P
    tmp.noalias() += ft.lazyProduct(phi.transpose());  // P_new = Phi P Phi^T + Q_k
    if (!tmp.allFinite()) return false;
    P_ = tmp;
    hygiene();
    return true;
  }

  // Zero-velocity update with z = v^n; x() then holds the errors to feed back.
  bool update(const Vec3& z) noexcept {
    x_.setZero();
    if (!z.allFinite()) return false;
    const Mat3 s = P_.template block<3, 3>(3, 3) + R_;
    // K^T = S^-1 H P by an explicit 3x3 Cholesky S = L L^T and two triangular substitutions.
    Mat3 l = Mat3::Zero();
    for (int j = 0; j < 3; ++j) {
      Scalar d = s(j, j);
      for (int m = 0; m < j; ++m) d -= l(j, m) * l(j, m);
      if (!(d > Scalar(0))) return false;  // S not positive definite (or NaN)
      l(j, j) = std::sqrt(d);
      for (int i = j + 1; i < 3; ++i) {
        Scalar v = s(i, j);
        for (int m = 0; m < j; ++m) v -= l(i, m) * l(j, m);
        l(i, j) = v / l(j, j);
      }
    }
    Eigen::Matrix<Scalar, 3, N> kt = P_.template middleRows<3>(3);
    for (int c = 0; c < N; ++c) {
      for (int i = 0; i < 3; ++i) {  // forward: L y = b
        Scalar v = kt(i, c);
        for (int m = 0; m < i; ++m) v -= l(i, m) * kt(m, c);
        kt(i, c) = v / l(i, i);
      }
      for (int i = 2; i >= 0; --i) {  // backward: L^T x = y
        Scalar v = kt(i, c);
        for (int m = i + 1; m < 3; ++m) v -= l(m, i) * kt(m, c);
        kt(i, c) = v / l(i, i);
      }
    }
    const Eigen::Matrix<Scalar, N, 3> k = kt.transpose();
    MatN& a = ws_a_;
    MatN& a_p = ws_b_;
    MatN& p_new = ws_c_;
    a.setIdentity();
    a.template middleCols<3>(3) -= k;
    a_p.noalias() = a.lazyProduct(P_);
    const Eigen::Matrix<Scalar, N, 3> k_r = k * R_;
    p_new.noalias() = a_p.lazyProduct(a.transpose());
    p_new.noalias() += k_r.lazyProduct(k.transpose());
    const VecN x = k * z;
    if (!p_new.allFinite() || !x.allFinite()) return false;
    P_ = p_new;
    hygiene();
    x_ = x;
    return true;
  }

  const MatN& P() const noexcept { return P_; }
  const VecN& x() const noexcept { return x_; }

 private:
  void hygiene() noexcept {
    P_ = Scalar(0.5) * (P_ + P_.transpose()).eval();
    for (int i = 0; i < N; ++i) {
      if (P_(i, i) < floor_(i)) P_(i, i) = floor_(i);
    }
  }

  MatN P_;
  MatN ws_a_, ws_b_, ws_c_;  // workspace of predict()/update() (see predict())
  VecN q_;
  VecN floor_;
  Mat3 R_;
  VecN x_;
};

}  // namespace gyrodrift
