// ENU strapdown mechanization from gyro angle and accelerometer velocity increments.
// Per sample (Python reference gyrodrift.align.strapdown, same order of operations):
//   coning   phi_k = dth_k + (1/12) dth_{k-1} x dth_k          (one-plus-previous sample)
//   sculling dv_sf = dv_k + 1/2 dth_k x dv_k + (1/12)(dth_{k-1} x dv_k + dv_{k-1} x dth_k)
//   velocity v_k = v_{k-1} + (I - 1/2 [w_in dt x]) C_b^n dv_sf + (g - (2 w_ie + w_en) x v) dt
//   position trapezoid of v; attitude q_k = q(-w_in dt) q_{k-1} q(phi_k), renormalised.
// No heap, noexcept, deterministic; step() returns false (state untouched) on non-finite input.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "attitude.hpp"
#include "earth.hpp"

namespace gyrodrift {

template <class Scalar>
class Strapdown {
 public:
  using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
  using Mat3 = Eigen::Matrix<Scalar, 3, 3>;

  Strapdown() noexcept { reset(Quat<Scalar>(Scalar(1), Scalar(0), Scalar(0), Scalar(0)), Vec3::Zero(), Vec3::Zero()); }

  // pos = [lat rad, lon rad, h m].
  void reset(const Quat<Scalar>& q_nb, const Vec3& vn_m_s, const Vec3& pos) noexcept {
    q_ = qnormalize(q_nb);
    vn_ = vn_m_s;
    pos_ = pos;
    prev_dth_.setZero();
    prev_dv_.setZero();
  }

  // One sample. dvn_out receives C_b^n dv_sf (specific-force velocity increment in n).
  bool step(const Vec3& dth, const Vec3& dv, Scalar dt_s, Vec3& dvn_out) noexcept {
    if (!dth.allFinite() || !dv.allFinite() || !(dt_s > Scalar(0))) return false;
    earth_.update(pos_(0), pos_(2), vn_);
    const Scalar twelfth = Scalar(1) / Scalar(12);
    const Vec3 phi = dth + twelfth * prev_dth_.cross(dth);
    const Vec3 dv_sf = dv + Scalar(0.5) * dth.cross(dv) +
                       twelfth * (prev_dth_.cross(dv) + prev_dv_.cross(dth));
    const Mat3 cnb = q2dcm(q_);
    Vec3 dvn = cnb * dv_sf;
    dvn = dvn - Scalar(0.5) * (earth_.wnin * dt_s).cross(dvn);
    const Vec3 v_new =
        vn_ + dvn + (earth_.gn - (Scalar(2) * earth_.wnie + earth_.wnen).cross(vn_)) * dt_s;
    const Vec3 vm = Scalar(0.5) * (vn_ + v_new);
    Vec3 dpos;
    dpos << vm(1) / earth_.rm_h_m, vm(0) / (earth_.rn_h_m * std::cos(pos_(0))), vm(2);
    pos_ += dpos * dt_s;
    vn_ = v_new;
    q_ = qnormalize(qmul(rv2q<Scalar>(-earth_.wnin * dt_s), qmul(q_, rv2q(phi))));
    prev_dth_ = dth;
    prev_dv_ = dv;
    dvn_out = dvn;
    return true;
  }

  const Quat<Scalar>& q() const noexcept { return q_; }
  const Vec3& vn() const noexcept { return vn_; }
  const Vec3& pos() const noexcept { return pos_; }
  Quat<Scalar>& q_mut() noexcept { return q_; }
  Vec3& vn_mut() noexcept { return vn_; }
  Vec3& pos_mut() noexcept { return pos_; }
  const EarthParams<Scalar>& earth() const noexcept { return earth_; }

 private:
  Quat<Scalar> q_;
  Vec3 vn_;
  Vec3 pos_;
  Vec3 prev_dth_;
  Vec3 prev_dv_;
  EarthParams<Scalar> earth_;
};

}  // namespace gyrodrift
