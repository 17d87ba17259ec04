// Expected Allan variance of noise models at octave-spaced averaging times tau = 2^k / rate:
// the reference curve health alarms compare a streaming Allan variance against.
//
// ar2_white_avar: the drift model "AR(2) drift + white noise" (the model fit_drift_model fits,
// filters/drift_likelihood.hpp):
//   x_k = a1 x_{k-1} + a2 x_{k-2} + w_k, w_k ~ N(0, q);  y_k = mean + x_k + v_k, v_k ~ N(0, r).
// For a stationary rate with cluster sums S_j of m samples, every squared difference of
// consecutive cluster means has the same expectation, so the non-overlapped (and the
// overlapped) Allan variance has the exact expectation
//   sigma^2(m) = (D(m) - C(m)) / m^2 + r / m,
// D(m) = Var(S_0) and C(m) = Cov(S_1, S_0) of the drift (the white part adds r / m). With the
// state X_k = [x_k, x_{k-1}], F = [[a1, a2], [1, 0]], P = [[g0, g1], [g1, g0]] its stationary
// covariance and A_m = I + F + ... + F^(m-1):
//   C(m) = e1' A_m F A_m P e1,   D(2m) = 2 D(m) + 2 C(m),   A_2m = A_m (I + F^m),
// so each octave costs a few 2x2 products (no sum over m lags). Exact in exact arithmetic;
// D and C are both near m^2 g0 where the drift is smooth over a cluster, so the difference
// loses about log10(g0 / (m^2 sigma^2_drift)) digits: compute the reference in double (on the
// target once, at configuration) and round it to float afterwards.
// The numpy reference (gyrodrift.reference.model_allan) sums the autocovariance directly,
// D(m) = m g(0) + 2 sum_{j<m} (m - j) g(j), sigma^2(m) = (4 D(m) - D(2m)) / (2 m^2).
//
// ar2_white_edf_per_term: the equivalent degrees of freedom per term of n consecutive squared
// differences at each octave under the same model (what a test of a block of n terms against
// the expected value may use): with the phase x (cumulated rate), its structure D(t) =
// Var(x_t - x_0) (D(jm) by the same doubling, D((j+1)m) = D(jm) + D(m) + 2 e1' A_m F A_jm P e1,
// plus the white part jm r), the covariance of second differences h clusters apart is
// C(h) = -1/2 sum_l w_l D(|h + l| m), w = (1, -4, 6, -4, 1), rho(h) = C(h) / C(0) and
// edf / n = n / (n + 2 sum_{h<n} (n - h) rho(h)^2). A smooth drift (the rising side of the
// AR(2) hump) has strongly correlated differences: few degrees of freedom per term.
//
// ieee952_avar: the IEEE Std 952-1997 (Annex C) terms at tau: 3 Q^2 / tau^2 + N^2 / tau +
// (0.664 B)^2 + K^2 tau / 3 (0.664 = sqrt(2 ln2 / pi), valid for tau well above the sample
// period), in the terms' consistent units (e.g. rad, rad/s/sqrt(Hz), rad/s, rad/s*sqrt(Hz)).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "../filters/drift_likelihood.hpp"

namespace gyrodrift {

namespace detail {

// 2x2 matrix, row-major {m00, m01, m10, m11}: the products of the model's companion matrix.
template <class Scalar>
struct Mat2 {
  Scalar a, b, c, d;
};
template <class Scalar>
constexpr Mat2<Scalar> mat2_mul(const Mat2<Scalar>& x, const Mat2<Scalar>& y) noexcept {
  return {x.a * y.a + x.b * y.c, x.a * y.b + x.b * y.d, x.c * y.a + x.d * y.c,
          x.c * y.b + x.d * y.d};
}

}  // namespace detail

// Expected Allan variance of AR(2) drift (a1, a2, driving variance q) + white noise (variance r)
// at m = 2^k samples, k = 0 .. octaves - 1, into avar[k] ((units of y)^2). False (avar
// untouched) for a non-stationary AR(2), q or r negative or not finite, q + r == 0, avar null.
template <class Scalar>
bool ar2_white_avar(Scalar a1, Scalar a2, Scalar q, Scalar r, std::size_t octaves,
                    Scalar* avar) noexcept {
  const Scalar one = Scalar(1);
  if (avar == nullptr || !std::isfinite(a1) || !std::isfinite(a2) || !std::isfinite(q) ||
      !std::isfinite(r) || q < Scalar(0) || r < Scalar(0) || !(q + r > Scalar(0))) {
    return false;
  }
  // stationarity: the roots of z^2 - a1 z - a2 inside the unit circle
  if (!(a2 < one && a2 > -one && a1 + a2 < one && a2 - a1 < one)) return false;
  Scalar g0 = Scalar(0);
  Scalar g1 = Scalar(0);
  if (q > Scalar(0)) drift_stationary_covariance(a1, a2, q, g0, g1);
  using M2 = detail::Mat2<Scalar>;
  const auto mul = [](const M2& x, const M2& y) noexcept { return detail::mat2_mul(x, y); };
  const M2 f{a1, a2, one, Scalar(0)};
  const M2 p{g0, g1, g1, g0};
  M2 a_m{one, Scalar(0), Scalar(0), one};  // A_1 = I
  M2 f_m = f;                              // F^1
  Scalar d_m = g0;                         // D(1)
  Scalar m = one;
  for (std::size_t k = 0; k < octaves; ++k) {
    const M2 cm = mul(mul(mul(a_m, f), a_m), p);
    const Scalar c_m = cm.a;  // e1' A F A P e1
    const Scalar drift = (d_m - c_m) / (m * m);
    avar[k] = (drift > Scalar(0) ? drift : Scalar(0)) + r / m;
    d_m = Scalar(2) * (d_m + c_m);
    const M2 i_plus{one + f_m.a, f_m.b, f_m.c, one + f_m.d};
    a_m = mul(a_m, i_plus);
    f_m = mul(f_m, f_m);
    m = Scalar(2) * m;
  }
  return true;
}

// edf per term of n squared differences at m = 2^k, k < octaves (see the header comment), into
// out[k]; false (out untouched) for an invalid model (as ar2_white_avar), n < 1 or out null.
// Cost: O(n) 2x2 products per octave. Compute in double (fourth differences of D cancel).
template <class Scalar>
bool ar2_white_edf_per_term(Scalar a1, Scalar a2, Scalar q, Scalar r, std::size_t octaves,
                            std::uint32_t n, Scalar* out) noexcept {
  Scalar probe = Scalar(0);
  if (out == nullptr || n < 1 || !ar2_white_avar(a1, a2, q, r, 1, &probe)) return false;
  const Scalar one = Scalar(1);
  Scalar g0 = Scalar(0);
  Scalar g1 = Scalar(0);
  if (q > Scalar(0)) drift_stationary_covariance(a1, a2, q, g0, g1);
  using M2 = detail::Mat2<Scalar>;
  const auto mul = [](const M2& x, const M2& y) noexcept { return detail::mat2_mul(x, y); };
  const auto add = [](const M2& x, const M2& y) noexcept {
    return M2{x.a + y.a, x.b + y.b, x.c + y.c, x.d + y.d};
  };
  const M2 f{a1, a2, one, Scalar(0)};
  const M2 p{g0, g1, g1, g0};
  M2 a_m{one, Scalar(0), Scalar(0), one};  // A_m
  M2 f_m = f;                              // F^m
  Scalar d_m = g0;                         // D_drift(m)
  Scalar m = one;
  for (std::size_t k = 0; k < octaves; ++k) {
    // walk j = 0 .. n + 1 keeping D(jm) for the last five j
    Scalar dj[5] = {Scalar(0), Scalar(0), Scalar(0), Scalar(0), Scalar(0)};  // D((j-4)m) .. D(jm)
    const M2 a_m_f = mul(a_m, f);
    M2 a_jm{Scalar(0), Scalar(0), Scalar(0), Scalar(0)};  // A_0 = 0
    M2 f_jm{one, Scalar(0), Scalar(0), one};              // F^0
    Scalar d_drift = Scalar(0);                           // D_drift(0)
    Scalar c0 = Scalar(0);
    Scalar sum = Scalar(0);
    const Scalar nn = static_cast<Scalar>(n);
    for (long long j = 0; j <= static_cast<long long>(n) + 1; ++j) {
      const Scalar d_total = d_drift + static_cast<Scalar>(j) * m * r;
      for (int i = 0; i < 4; ++i) dj[i] = dj[i + 1];
      dj[4] = d_total;
      // C(h) at h = j - 2 needs D(|h + l| m), l = -2..2 (D is even), i.e. up to D(jm)
      const long long h = j - 2;
      if (h >= 0 && h < static_cast<long long>(n)) {
        Scalar dv[5];
        for (int l = -2; l <= 2; ++l) {
          const long long t = h + l;
          const long long at = t < 0 ? -t : t;
          dv[l + 2] = dj[4 - (j - at)];
        }
        const Scalar c = Scalar(-0.5) * (dv[0] - Scalar(4) * dv[1] + Scalar(6) * dv[2] -
                                         Scalar(4) * dv[3] + dv[4]);
        if (h == 0) {
          c0 = c;
        } else if (c0 > Scalar(0)) {
          const Scalar rho = c / c0;
          sum += (nn - static_cast<Scalar>(h)) * rho * rho;
        }
      }
      // advance to j + 1: D((j+1)m) = D(jm) + D(m) + 2 e1' A_m F A_jm P e1
      const M2 cross = mul(mul(a_m_f, a_jm), p);
      d_drift = d_drift + d_m + Scalar(2) * cross.a;
      a_jm = add(a_jm, mul(f_jm, a_m));
      f_jm = mul(f_jm, f_m);
    }
    out[k] = c0 > Scalar(0) ? nn / (nn + Scalar(2) * sum) : one;
    // next octave: D(2m), A_2m, F^2m
    const M2 cm = mul(mul(mul(a_m, f), a_m), p);
    d_m = Scalar(2) * (d_m + cm.a);
    const M2 i_plus{one + f_m.a, f_m.b, f_m.c, one + f_m.d};
    a_m = mul(a_m, i_plus);
    f_m = mul(f_m, f_m);
    m = Scalar(2) * m;
  }
  return true;
}

// IEEE Std 952 Allan variance of quantization q_angle (angle units), angle random walk n,
// bias instability b (flicker floor 0.664 b) and rate random walk k at tau_s > 0.
template <class Scalar>
Scalar ieee952_avar(Scalar q_angle, Scalar n, Scalar b, Scalar k, Scalar tau_s) noexcept {
  const Scalar floor = Scalar(0.66428) * b;
  return Scalar(3) * q_angle * q_angle / (tau_s * tau_s) + n * n / tau_s + floor * floor +
         k * k * tau_s / Scalar(3);
}

}  // namespace gyrodrift
