// Coarse alignment on a rocking base by the inertial-frame gravity method.
//   C_b^n(t) = C_i0^n(t) C_ib0^i0 C_b^ib0(t)
// C_b^ib0 from the gyro increments (coning-corrected, from I); C_i0^n(t) is the Earth rotation
// of the ENU frame about u = [0, cos L, sin L] by Omega t; C_ib0^i0 (constant) from the
// specific force integrated in both inertial frames at t1 = T/2 and t2 = T:
//   V^i0(t) = int C_n^i0 [0 0 g] dtau (closed form), V^ib0(t) = sum C_b^ib0 (dv + rot + scul).
// Position-integral variant (default): S = int V dtau, with the least-squares projection onto t
// (beta = sum t_k S_k / sum t_k^2) removed in both frames so that the unknown sway velocity at
// t = 0 (a term v0 t) drops out; the bounded lever-arm sway then enters as a bounded
// displacement against a gravity signal growing as t^2..t^4.
// C_ib0^i0 = M(a_i0, b_i0) M(a_ib0, b_ib0)^T with the TRIAD frame M(a, b) = [a, a x b,
// a x (a x b)] normalised (orthonormal by construction, no SVD needed).
// Python reference: gyrodrift.align.coarse (same operations, double results within 1e-9).
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "attitude.hpp"
#include "earth.hpp"

namespace gyrodrift {

namespace nav_detail {
// 1 - cos x, x - sin x and x^2/2 - (1 - cos x) without cancellation for |x| < 0.5 (Horner form
// of the Taylor series, error < x^12/12!); exact formulas above.
template <class Scalar>
inline Scalar one_minus_cos(Scalar x) noexcept {
  if (std::fabs(x) >= Scalar(0.5)) return Scalar(1) - std::cos(x);
  const Scalar x2 = x * x;
  return x2 / Scalar(2) *
         (Scalar(1) - x2 / Scalar(12) *
                          (Scalar(1) - x2 / Scalar(30) *
                                           (Scalar(1) - x2 / Scalar(56) * (Scalar(1) - x2 / Scalar(90)))));
}
template <class Scalar>
inline Scalar x_minus_sin(Scalar x) noexcept {
  if (std::fabs(x) >= Scalar(0.5)) return x - std::sin(x);
  const Scalar x2 = x * x;
  return x * x2 / Scalar(6) *
         (Scalar(1) - x2 / Scalar(20) *
                          (Scalar(1) - x2 / Scalar(42) *
                                           (Scalar(1) - x2 / Scalar(72) * (Scalar(1) - x2 / Scalar(110)))));
}
template <class Scalar>
inline Scalar half_x2_minus_one_minus_cos(Scalar x) noexcept {
  if (std::fabs(x) >= Scalar(0.5)) return x * x / Scalar(2) - (Scalar(1) - std::cos(x));
  const Scalar x2 = x * x;
  return x2 * x2 / Scalar(24) *
         (Scalar(1) - x2 / Scalar(30) *
                          (Scalar(1) - x2 / Scalar(56) *
                                           (Scalar(1) - x2 / Scalar(90) * (Scalar(1) - x2 / Scalar(132)))));
}
}  // namespace nav_detail

// V^i0(t) (velocity variant) or S^i0(t) (position variant) of [0, 0, g] rotated with the Earth.
template <class Scalar>
inline Eigen::Matrix<Scalar, 3, 1> gravity_integral_i0(Scalar t_s, Scalar lat_rad, Scalar g_m_s2,
                                                       bool position) noexcept {
  const Scalar w = EarthConstants<Scalar>::rate_rad_s;
  const Scalar sl = std::sin(lat_rad), cl = std::cos(lat_rad);
  const Scalar x = w * t_s;
  Scalar a, b, c;
  if (!position) {
    a = nav_detail::one_minus_cos(x) / w;
    b = nav_detail::x_minus_sin(x) / w;
    c = t_s - b;
  } else {
    a = nav_detail::x_minus_sin(x) / (w * w);
    b = nav_detail::half_x2_minus_one_minus_cos(x) / (w * w);
    c = Scalar(0.5) * t_s * t_s - b;
  }
  Eigen::Matrix<Scalar, 3, 1> v;
  v << g_m_s2 * cl * a, g_m_s2 * sl * cl * b, g_m_s2 * (c + sl * sl * b);
  return v;
}

// C_n(t)^i0 (Rodrigues rotation by Omega t about the polar axis expressed in i0).
template <class Scalar>
inline Eigen::Matrix<Scalar, 3, 3> earth_rotation_i0_n(Scalar t_s, Scalar lat_rad) noexcept {
  Eigen::Matrix<Scalar, 3, 1> u(Scalar(0), std::cos(lat_rad), std::sin(lat_rad));
  const Scalar x = EarthConstants<Scalar>::rate_rad_s * t_s;
  const Eigen::Matrix<Scalar, 3, 3> ux = skew(u);
  return Eigen::Matrix<Scalar, 3, 3>::Identity() + std::sin(x) * ux +
         nav_detail::one_minus_cos(x) * (ux * ux);
}

// TRIAD frame; false if a and b are (nearly) parallel or zero.
template <class Scalar>
inline bool triad(const Eigen::Matrix<Scalar, 3, 1>& a, const Eigen::Matrix<Scalar, 3, 1>& b,
                  Eigen::Matrix<Scalar, 3, 3>& m) noexcept {
  const Eigen::Matrix<Scalar, 3, 1> c = a.cross(b);
  const Eigen::Matrix<Scalar, 3, 1> d = a.cross(c);
  const Scalar na = a.norm(), nc = c.norm(), nd = d.norm();
  if (!(na > Scalar(0)) || !(nc > Scalar(0)) || !(nd > Scalar(0))) return false;
  m.col(0) = a / na;
  m.col(1) = c / nc;
  m.col(2) = d / nd;
  return m.allFinite();
}

template <class Scalar>
class InertialCoarseAlign {
 public:
  using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
  using Mat3 = Eigen::Matrix<Scalar, 3, 3>;

  InertialCoarseAlign() noexcept { reset(4, Scalar(0.01), Scalar(0), Scalar(0), true); }

  // Returns false for a window shorter than 4 samples or a non-positive dt.
  bool reset(long n_samples, Scalar dt_s, Scalar lat_rad, Scalar h_m,
             bool position_integral) noexcept {
    if (n_samples < 4 || !(dt_s > Scalar(0))) return false;
    n_ = n_samples;
    dt_ = dt_s;
    lat_ = lat_rad;
    g_ = gravity_m_s2(lat_rad, h_m);
    position_ = position_integral;
    q_ << Scalar(1), Scalar(0), Scalar(0), Scalar(0);
    vib0_.setZero();
    sib0_.setZero();
    prev_dth_.setZero();
    prev_dv_.setZero();
    k_ = 0;
    v1_.setZero();
    v1_i0_.setZero();
    stt_ = Scalar(0);
    sty_b_.setZero();
    sty_i_.setZero();
    return true;
  }

  // Feed one sample; false on non-finite input (sample not used, counted by the caller).
  bool add(const Vec3& dth, const Vec3& dv) noexcept {
    if (!dth.allFinite() || !dv.allFinite()) return false;
    if (k_ >= n_) return true;
    const Scalar twelfth = Scalar(1) / Scalar(12);
    const Vec3 dv_sf = dv + Scalar(0.5) * dth.cross(dv) +
                       twelfth * (prev_dth_.cross(dv) + prev_dv_.cross(dth));
    const Vec3 dvi = q2dcm(q_) * dv_sf;
    const Vec3 v_old = vib0_;
    vib0_ += dvi;
    sib0_ += Scalar(0.5) * (v_old + vib0_) * dt_;
    const Vec3 phi = dth + twelfth * prev_dth_.cross(dth);
    q_ = qnormalize(qmul(q_, rv2q(phi)));
    prev_dth_ = dth;
    prev_dv_ = dv;
    ++k_;
    const Scalar t = static_cast<Scalar>(k_) * dt_;
    if (position_) {
      stt_ += t * t;
      sty_b_ += t * sib0_;
      sty_i_ += t * gravity_integral_i0(t, lat_, g_, true);
    }
    if (k_ == n_ / 2) vectors(v1_, v1_i0_);
    return true;
  }

  bool complete() const noexcept { return k_ >= n_; }
  long samples() const noexcept { return k_; }

  // C_b^n at the end of the window; false if incomplete or degenerate.
  bool solve(Mat3& cnb) const noexcept {
    if (k_ < n_) return false;
    Vec3 a_b, a_i0;
    vectors(a_b, a_i0);
    Mat3 m_i0, m_b;
    if (!triad(a_i0, v1_i0_, m_i0) || !triad(a_b, v1_, m_b)) return false;
    const Scalar t2 = static_cast<Scalar>(n_) * dt_;
    cnb = earth_rotation_i0_n(t2, lat_).transpose() * (m_i0 * m_b.transpose()) * q2dcm(q_);
    return cnb.allFinite();
  }

 private:
  void vectors(Vec3& v_b, Vec3& v_i0) const noexcept {
    const Scalar t = static_cast<Scalar>(k_) * dt_;
    if (!position_) {
      v_b = vib0_;
      v_i0 = gravity_integral_i0(t, lat_, g_, false);
      return;
    }
    const Scalar beta = t / stt_;
    v_b = sib0_ - beta * sty_b_;
    v_i0 = gravity_integral_i0(t, lat_, g_, true) - beta * sty_i_;
  }

  long n_{4};
  Scalar dt_{0};
  Scalar lat_{0};
  Scalar g_{0};
  bool position_{true};
  Quat<Scalar> q_;
  Vec3 vib0_, sib0_, prev_dth_, prev_dv_, v1_, v1_i0_, sty_b_, sty_i_;
  Scalar stt_{0};
  long k_{0};
};

}  // namespace gyrodrift
