// WGS-84 Earth model for the ENU navigation frame: radii of curvature, Earth and transport
// rate, normal gravity. Frames: n = East-North-Up, b = body (X right, Y forward, Z up).
// Python reference: gyrodrift.align.earth.
#pragma once
#include <Eigen/Core>
#include <cmath>

namespace gyrodrift {

template <class Scalar>
struct EarthConstants {
  static constexpr Scalar a_m = Scalar(6378137.0);                    // WGS-84 semi-major axis
  static constexpr Scalar f = Scalar(1.0 / 298.257223563);             // flattening
  static constexpr Scalar e2 = Scalar((1.0 / 298.257223563) * (2.0 - 1.0 / 298.257223563));
  static constexpr Scalar rate_rad_s = Scalar(7.2921151467e-5);         // Omega
  // Normal gravity g0 (1 + b1 sin^2 L + b2 sin^4 L) - dg/dh h (WGS-84 series, PSINS form).
  static constexpr Scalar g_eq_m_s2 = Scalar(9.7803267714);
  static constexpr Scalar g_b1 = Scalar(5.27094e-3);
  static constexpr Scalar g_b2 = Scalar(2.32718e-5);
  static constexpr Scalar g_dh_per_s2 = Scalar(3.086e-6);
};

template <class Scalar>
inline Scalar gravity_m_s2(Scalar lat_rad, Scalar h_m) noexcept {
  using C = EarthConstants<Scalar>;
  const Scalar s = std::sin(lat_rad);
  const Scalar s2 = s * s;
  return C::g_eq_m_s2 * (Scalar(1) + C::g_b1 * s2 + C::g_b2 * s2 * s2) - C::g_dh_per_s2 * h_m;
}

// Earth quantities at a position and velocity (evaluated once per mechanization sample).
template <class Scalar>
struct EarthParams {
  using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
  Scalar rm_h_m{0};  // meridian radius + height
  Scalar rn_h_m{0};  // prime-vertical radius + height
  Scalar tan_lat{0};
  Vec3 wnie = Vec3::Zero();  // Earth rate in n (rad/s)
  Vec3 wnen = Vec3::Zero();  // transport rate in n (rad/s)
  Vec3 wnin = Vec3::Zero();  // wnie + wnen
  Vec3 gn = Vec3::Zero();    // gravity [0, 0, -g]

  void update(Scalar lat_rad, Scalar h_m, const Vec3& vn_m_s) noexcept {
    using C = EarthConstants<Scalar>;
    const Scalar sl = std::sin(lat_rad);
    const Scalar cl = std::cos(lat_rad);
    const Scalar sq = Scalar(1) - C::e2 * sl * sl;
    const Scalar rn = C::a_m / std::sqrt(sq);
    const Scalar rm = rn * (Scalar(1) - C::e2) / sq;
    rm_h_m = rm + h_m;
    rn_h_m = rn + h_m;
    tan_lat = sl / cl;
    wnie << Scalar(0), C::rate_rad_s * cl, C::rate_rad_s * sl;
    wnen << -vn_m_s(1) / rm_h_m, vn_m_s(0) / rn_h_m, vn_m_s(0) * tan_lat / rn_h_m;
    wnin = wnie + wnen;
    gn << Scalar(0), Scalar(0), -gravity_m_s2(lat_rad, h_m);
  }
};

}  // namespace gyrodrift
