// Attitude helpers: quaternions as Eigen 4-vectors [w, x, y, z] (Hamilton product), DCMs and
// Euler angles. q_nb rotates body vectors into n. Euler angles are [pitch, roll, yaw] with
// C_b^n = Rz(yaw) Rx(pitch) Ry(roll), yaw counter-clockwise from North (PSINS convention);
// the clockwise heading is -yaw. Python reference: gyrodrift.align.attitude.
#pragma once
#include <Eigen/Core>
#include <cmath>

namespace gyrodrift {

template <class Scalar>
using Quat = Eigen::Matrix<Scalar, 4, 1>;

template <class Scalar>
inline Eigen::Matrix<Scalar, 3, 3> skew(const Eigen::Matrix<Scalar, 3, 1>& v) noexcept {
  Eigen::Matrix<Scalar, 3, 3> m;
  m << Scalar(0), -v(2), v(1), v(2), Scalar(0), -v(0), -v(1), v(0), Scalar(0);
  return m;
}

template <class Scalar>
inline Quat<Scalar> qmul(const Quat<Scalar>& p, const Quat<Scalar>& q) noexcept {
  Quat<Scalar> r;
  r << p(0) * q(0) - p(1) * q(1) - p(2) * q(2) - p(3) * q(3),
      p(0) * q(1) + p(1) * q(0) + p(2) * q(3) - p(3) * q(2),
      p(0) * q(2) - p(1) * q(3) + p(2) * q(0) + p(3) * q(1),
      p(0) * q(3) + p(1) * q(2) - p(2) * q(1) + p(3) * q(0);
  return r;
}

// Rotation vector to quaternion; Taylor series below 1e-4 rad keeps full precision.
template <class Scalar>
inline Quat<Scalar> rv2q(const Eigen::Matrix<Scalar, 3, 1>& rv) noexcept {
  const Scalar a2 = rv.squaredNorm();
  Scalar c;
  Scalar s;
  if (a2 < Scalar(1e-8)) {
    c = Scalar(1) - a2 / Scalar(8) + a2 * a2 / Scalar(384);
    s = Scalar(0.5) - a2 / Scalar(48) + a2 * a2 / Scalar(3840);
  } else {
    const Scalar a = std::sqrt(a2);
    c = std::cos(a / Scalar(2));
    s = std::sin(a / Scalar(2)) / a;
  }
  Quat<Scalar> q;
  q << c, s * rv(0), s * rv(1), s * rv(2);
  return q;
}

template <class Scalar>
inline Quat<Scalar> qnormalize(const Quat<Scalar>& q) noexcept {
  return q / std::sqrt(q.squaredNorm());
}

template <class Scalar>
inline Eigen::Matrix<Scalar, 3, 3> q2dcm(const Quat<Scalar>& q) noexcept {
  const Scalar w = q(0), x = q(1), y = q(2), z = q(3);
  Eigen::Matrix<Scalar, 3, 3> c;
  c << w * w + x * x - y * y - z * z, Scalar(2) * (x * y - w * z), Scalar(2) * (x * z + w * y),
      Scalar(2) * (x * y + w * z), w * w - x * x + y * y - z * z, Scalar(2) * (y * z - w * x),
      Scalar(2) * (x * z - w * y), Scalar(2) * (y * z + w * x), w * w - x * x - y * y + z * z;
  return c;
}

// Shepperd's method (largest pivot), sign fixed to w >= 0.
template <class Scalar>
inline Quat<Scalar> dcm2q(const Eigen::Matrix<Scalar, 3, 3>& c) noexcept {
  const Scalar tr = c(0, 0) + c(1, 1) + c(2, 2);
  const Scalar cand[4] = {tr, c(0, 0), c(1, 1), c(2, 2)};
  int k = 0;
  for (int i = 1; i < 4; ++i) {
    if (cand[i] > cand[k]) k = i;
  }
  Quat<Scalar> q;
  const Scalar four(4);
  if (k == 0) {
    const Scalar w = Scalar(0.5) * std::sqrt(Scalar(1) + tr);
    q << w, (c(2, 1) - c(1, 2)) / (four * w), (c(0, 2) - c(2, 0)) / (four * w),
        (c(1, 0) - c(0, 1)) / (four * w);
  } else if (k == 1) {
    const Scalar x = Scalar(0.5) * std::sqrt(Scalar(1) + Scalar(2) * c(0, 0) - tr);
    q << (c(2, 1) - c(1, 2)) / (four * x), x, (c(0, 1) + c(1, 0)) / (four * x),
        (c(0, 2) + c(2, 0)) / (four * x);
  } else if (k == 2) {
    const Scalar y = Scalar(0.5) * std::sqrt(Scalar(1) + Scalar(2) * c(1, 1) - tr);
    q << (c(0, 2) - c(2, 0)) / (four * y), (c(0, 1) + c(1, 0)) / (four * y), y,
        (c(1, 2) + c(2, 1)) / (four * y);
  } else {
    const Scalar z = Scalar(0.5) * std::sqrt(Scalar(1) + Scalar(2) * c(2, 2) - tr);
    q << (c(1, 0) - c(0, 1)) / (four * z), (c(0, 2) + c(2, 0)) / (four * z),
        (c(1, 2) + c(2, 1)) / (four * z), z;
  }
  return q(0) >= Scalar(0) ? q : Quat<Scalar>(-q);
}

template <class Scalar>
inline Eigen::Matrix<Scalar, 3, 3> euler2dcm(const Eigen::Matrix<Scalar, 3, 1>& att) noexcept {
  const Scalar sp = std::sin(att(0)), cp = std::cos(att(0));
  const Scalar sr = std::sin(att(1)), cr = std::cos(att(1));
  const Scalar sy = std::sin(att(2)), cy = std::cos(att(2));
  Eigen::Matrix<Scalar, 3, 3> c;
  c << cy * cr - sy * sp * sr, -sy * cp, cy * sr + sy * sp * cr,
      sy * cr + cy * sp * sr, cy * cp, sy * sr - cy * sp * cr,
      -cp * sr, sp, cp * cr;
  return c;
}

template <class Scalar>
inline Eigen::Matrix<Scalar, 3, 1> dcm2euler(const Eigen::Matrix<Scalar, 3, 3>& c) noexcept {
  const Scalar s = c(2, 1) > Scalar(1) ? Scalar(1) : (c(2, 1) < Scalar(-1) ? Scalar(-1) : c(2, 1));
  Eigen::Matrix<Scalar, 3, 1> att;
  att << std::asin(s), std::atan2(-c(2, 0), c(2, 2)), std::atan2(-c(0, 1), c(1, 1));
  return att;
}

}  // namespace gyrodrift
