// Equivalent degrees of freedom of the non-overlapped Allan variance and chi-square quantiles,
// small enough for the target: closed forms, no tables, no iteration, templated on Scalar.
//
// edf (moment matching, NIST SP 1065 sec. 5.2.3: edf = 2 E[S]^2 / Var[S] of the sum S of the n
// squared differences d_j of consecutive cluster means, Gaussian noise). With rho(h) the
// correlation of d_j and d_{j+h}, Var[S] = 2 sigma^4 (n + 2 sum_{h=1}^{n-1} (n - h) rho(h)^2),
// so edf = n^2 / (n (1 + 2 S) - 2 S1), S = sum rho(h)^2, S1 = sum h rho(h)^2 (the tail beyond
// h = n is negligible):
// - white rate noise (angle random walk; discrete, any m): the means are independent,
//   rho(1) = -1/2, rho(h > 1) = 0: edf = n^2 / (1.5 n - 0.5) (exact);
// - flicker rate noise (bias instability; continuous limit, m >> 1): rho(h) from the phase's
//   generalized autocovariance t^2 ln|t| through the second-difference weights (1, -2, 1):
//   rho(1) = -0.2169, rho(2) = -0.1323, rho(h) -> -0.3607 / h^2; S = 0.0677068,
//   S1 = 0.0939406: edf = n^2 / (1.1354136 n - 0.1878813);
// - random-walk rate noise (rate random walk; discrete increments, cluster of m samples): the
//   weights of the increments in d_j are a triangle of 2m - 1 samples, neighbours overlap on
//   one half: rho(1) = (m^2 - 1) / (2 (2 m^2 + 1)) (0 at m = 1, -> 1/4), rho(h > 1) = 0.
// Against Greenhall & Riley's algorithm (gyrodrift.stability.edf.edf_greenhall, non-overlapped)
// these agree within 0.5 % for flicker and random walk at m >= 4; for white noise Greenhall's
// continuous-time model differs at m < 4 while this one is exact for independent samples.
//
// Chi-square quantile: Wilson & Hilferty (1931), chi2_p(nu) ~ nu (1 - 2/(9 nu) + z_p
// sqrt(2/(9 nu)))^3, z_p the standard normal quantile from Acklam's rational approximation
// (relative error below 1.2e-9) with one Halley step left out (not needed at this accuracy).
// Accuracy against the exact quantile (scipy.stats.chi2.ppf): within 1 % for nu >= 3 and
// 1e-6 <= p <= 1 - 1e-6, within 6 % for nu >= 1 (tests/test_online_noise.py).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

namespace gyrodrift {

// The noise type whose edf is used for an octave.
enum class AllanNoise : std::uint8_t { white = 0, flicker = 1, random_walk = 2 };

// edf of the non-overlapped Allan variance from n >= 1 squared differences at averaging factor
// m >= 1 (see the header comment); 0 for n == 0. At most n.
template <class Scalar>
Scalar nonoverlapped_edf(AllanNoise noise, std::uint64_t n, std::uint64_t m) noexcept {
  if (n == 0) return Scalar(0);
  const Scalar nn = static_cast<Scalar>(n);
  Scalar s = Scalar(0.25);  // S and S1 (equal when only rho(1) is nonzero)
  Scalar s1 = Scalar(0.25);
  if (noise == AllanNoise::flicker) {
    s = Scalar(0.0677068);
    s1 = Scalar(0.0939406);
  } else if (noise == AllanNoise::random_walk) {
    const Scalar mm = static_cast<Scalar>(m < 1 ? 1 : m);
    const Scalar m2 = mm * mm;
    const Scalar rho = (m2 - Scalar(1)) / (Scalar(2) * (Scalar(2) * m2 + Scalar(1)));
    s = rho * rho;
    s1 = s;
  }
  const Scalar edf = nn * nn / (nn * (Scalar(1) + Scalar(2) * s) - Scalar(2) * s1);
  return edf < nn ? edf : nn;
}

// Standard normal quantile z with P(Z <= z) = p, 0 < p < 1 (Acklam's rational approximation);
// NaN outside (0, 1).
template <class Scalar>
Scalar normal_quantile(Scalar p) noexcept {
  if (!(p > Scalar(0)) || !(p < Scalar(1))) return std::numeric_limits<Scalar>::quiet_NaN();
  constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                          1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                          6.680131188771972e+01,  -1.328068155288572e+01};
  constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                          -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                          3.754408661907416e+00};
  const Scalar plow = Scalar(0.02425);
  if (p < plow || p > Scalar(1) - plow) {
    const Scalar pp = p < plow ? p : Scalar(1) - p;
    const Scalar q = std::sqrt(Scalar(-2) * std::log(pp));
    const Scalar num =
        ((((Scalar(c[0]) * q + Scalar(c[1])) * q + Scalar(c[2])) * q + Scalar(c[3])) * q +
         Scalar(c[4])) * q + Scalar(c[5]);
    const Scalar den =
        (((Scalar(d[0]) * q + Scalar(d[1])) * q + Scalar(d[2])) * q + Scalar(d[3])) * q + Scalar(1);
    const Scalar z = num / den;
    return p < plow ? z : -z;
  }
  const Scalar q = p - Scalar(0.5);
  const Scalar r = q * q;
  const Scalar num =
      (((((Scalar(a[0]) * r + Scalar(a[1])) * r + Scalar(a[2])) * r + Scalar(a[3])) * r +
        Scalar(a[4])) * r + Scalar(a[5])) * q;
  const Scalar den =
      ((((Scalar(b[0]) * r + Scalar(b[1])) * r + Scalar(b[2])) * r + Scalar(b[3])) * r +
       Scalar(b[4])) * r + Scalar(1);
  return num / den;
}

// Wilson-Hilferty chi-square quantile for nu > 0 degrees of freedom at the standard normal
// quantile z (z = normal_quantile(p)); clamped at 0 (the cube goes negative for small nu and
// very small p).
template <class Scalar>
Scalar chi2_quantile_wh(Scalar nu, Scalar z) noexcept {
  const Scalar h = Scalar(2) / (Scalar(9) * nu);
  const Scalar t = Scalar(1) - h + z * std::sqrt(h);
  if (!(t > Scalar(0))) return Scalar(0);
  return nu * t * t * t;
}

}  // namespace gyrodrift
