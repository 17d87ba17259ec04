// IEEE 952 noise estimates (angle random walk N, bias instability B, rate random walk K) with
// intervals, read from a StreamingAllan curve while it grows: the numbers a navigation computer
// reports about its own gyros.
//
// Units are the channel's: for a gyro in rad/s, N in rad/s/sqrt(Hz) (= rad/sqrt(s)), B in rad/s,
// K in rad/s*sqrt(Hz) (= rad/s/sqrt(s)). Allocation-free, noexcept, templated on Scalar.
//
// Read-offs (IEEE Std 952-1997 Annex C, the slopes of the Allan variance sigma^2(tau)): only
// octaves with at least kNoiseMinTerms squared differences are used (the usable octaves, a
// prefix 0 .. L-1 of the curve, tau_k = tau0 2^k).
// - N: among the octaves k where white rate noise dominates, i.e. the variance falls with a
//   slope of -1 +- 0.3 to the next octave (sigma^2_{k+1} / sigma^2_k in [2^-1.3, 2^-0.7];
//   quantization, slope -2, and a sensor's output filter, which flattens the first octaves, are
//   left out), the shortest one whose slope is within -1 +- 0.1 (most terms, least
//   contamination), else the one closest to -1 (where quantization below and bias instability
//   above add least; the shortest on a tie): N = sqrt(sigma^2_k tau_k). (Always the closest
//   would select on the noise of the slopes and bias the interval's coverage.) Without such an octave, an upper limit: N <= min_k
//   sqrt(hi_k tau_k) (any white noise adds N^2 / tau to every octave).
// - B: the Allan minimum over the usable octaves, B = sqrt(min sigma^2) / 0.664 (0.664 =
//   sqrt(2 ln2 / pi), the flicker floor), at b_tau_s. While the curve still falls at its
//   longest usable octave, an upper limit (the minimum is not seen yet).
// - K: when the longest usable octave L-1 lies beyond the minimum and the curve rises into it
//   by at least half the random-walk slope (sigma^2_{L-1} / sigma^2_{L-2} >= 2^0.5):
//   K = sqrt(3 (sigma^2_{L-1} - N^2 / tau) / tau) (the white part extrapolated from N taken
//   out; the flat part is not, so K is overstated where the flicker floor is still close).
//   Otherwise an upper limit from that octave: K <= sqrt(3 hi / tau) (any random walk adds
//   K^2 tau / 3 to it).
// Intervals: sigma^2 nu / chi2_{(1 +- c)/2}(nu) at coverage c (NIST SP 1065 eq. 45), nu the
// non-overlapped edf of the noise type read at that octave (allan_chi2.hpp: white for N,
// flicker for B, random walk for K), chi-square quantiles by Wilson-Hilferty; the interval
// is carried through the same formula as the value. The reference in numpy is
// gyrodrift.reference.online_noise (same equations).
// Cost: one pass over the octaves (no logarithms; one square root per interval end and a
// few per call for the quantiles); call it at the report cadence, not per sample.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "allan_chi2.hpp"
#include "streaming_allan.hpp"

namespace gyrodrift {

// Octaves with fewer squared differences are not read (edf below about 5).
inline constexpr std::uint64_t kNoiseMinTerms = 8;

template <class Scalar>
struct NoiseTermEstimate {
  Scalar value = Scalar(0);
  Scalar lo = Scalar(0);    // interval at the requested coverage
  Scalar hi = Scalar(0);
  bool valid = false;       // false: not estimable from the curve so far
  bool upper_limit = false; // true: only `hi` is meaningful (the term is not seen yet)
};

template <class Scalar>
struct NoiseEstimates {
  NoiseTermEstimate<Scalar> n{};  // angle random walk
  NoiseTermEstimate<Scalar> b{};  // bias instability (Allan minimum / 0.664)
  NoiseTermEstimate<Scalar> k{};  // rate random walk
  Scalar b_tau_s = Scalar(0);     // averaging time of the Allan minimum
};

namespace online_noise_detail {

// Interval of an Allan variance with edf nu at normal quantile z of (1 + c) / 2.
template <class Scalar>
void avar_interval(Scalar avar, Scalar nu, Scalar z, Scalar& lo, Scalar& hi) noexcept {
  const Scalar q_hi = chi2_quantile_wh(nu, z);
  const Scalar q_lo = chi2_quantile_wh(nu, -z);
  lo = q_hi > Scalar(0) ? avar * nu / q_hi : Scalar(0);
  hi = q_lo > Scalar(0) ? avar * nu / q_lo : std::numeric_limits<Scalar>::infinity();
}

}  // namespace online_noise_detail

// Estimates from the curve so far at `coverage` (e.g. 0.95). False when nothing is estimable
// (no octave with kNoiseMinTerms terms, or coverage outside (0, 1)); then `out` is cleared.
template <class Scalar, std::size_t Octaves>
bool estimate_noise(const StreamingAllan<Scalar, Octaves>& allan, Scalar coverage,
                    NoiseEstimates<Scalar>& out) noexcept {
  using online_noise_detail::avar_interval;
  out = NoiseEstimates<Scalar>{};
  if (!(coverage > Scalar(0)) || !(coverage < Scalar(1))) return false;
  Scalar av[Octaves] = {};
  std::size_t usable = 0;
  for (std::size_t k = 0; k < allan.octaves(); ++k) {
    if (allan.terms(k) < kNoiseMinTerms || !allan.avar(k, av[k])) break;
    usable = k + 1;
  }
  if (usable == 0) return false;
  // the lower tail (1 - c) / 2 is exact in Scalar; 0.5 + c / 2 would round near 1 in float
  const Scalar z = -normal_quantile(Scalar(0.5) * (Scalar(1) - coverage));
  const Scalar kFlickerFloor = Scalar(0.66428);  // sqrt(2 ln2 / pi)
  const Scalar white_lo = Scalar(0.40612619);    // 2^-1.3
  const Scalar white_hi = Scalar(0.61557221);    // 2^-0.7
  const Scalar rw_rise = Scalar(1.41421356);     // 2^0.5
  Scalar lo = Scalar(0);
  Scalar hi = Scalar(0);

  // N: the shortest octave with a slope within -1 +- 0.1, else the one closest to -1 within
  // -1 +- 0.3 (the shortest on a tie).
  std::size_t kn = usable;
  Scalar best_dev = Scalar(0);
  const Scalar near = Scalar(1.07177346);  // 2^0.1
  for (std::size_t k = 0; k + 1 < usable; ++k) {
    if (!(av[k] > Scalar(0)) || av[k + 1] < white_lo * av[k] || av[k + 1] > white_hi * av[k]) {
      continue;
    }
    const Scalar r = Scalar(2) * av[k + 1] / av[k];  // 1 on the white slope
    const Scalar dev = r > Scalar(1) ? r : Scalar(1) / r;
    if (dev <= near) {
      kn = k;
      break;
    }
    if (kn == usable || dev < best_dev) {
      kn = k;
      best_dev = dev;
    }
  }
  if (kn < usable) {
    const Scalar tau = allan.tau_s(kn);
    const Scalar nu = nonoverlapped_edf<Scalar>(AllanNoise::white, allan.terms(kn), allan.factor(kn));
    avar_interval(av[kn], nu, z, lo, hi);
    out.n = {std::sqrt(av[kn] * tau), std::sqrt(lo * tau), std::sqrt(hi * tau), true, false};
  } else {
    Scalar best = std::numeric_limits<Scalar>::infinity();
    for (std::size_t k = 0; k < usable; ++k) {
      const Scalar nu = nonoverlapped_edf<Scalar>(AllanNoise::white, allan.terms(k), allan.factor(k));
      avar_interval(av[k], nu, z, lo, hi);
      const Scalar v = std::sqrt(hi * allan.tau_s(k));
      if (v < best) best = v;
    }
    out.n = {best, Scalar(0), best, true, true};
  }

  // B: the Allan minimum.
  std::size_t kmin = 0;
  for (std::size_t k = 1; k < usable; ++k) {
    if (av[k] < av[kmin]) kmin = k;
  }
  {
    const Scalar nu =
        nonoverlapped_edf<Scalar>(AllanNoise::flicker, allan.terms(kmin), allan.factor(kmin));
    avar_interval(av[kmin], nu, z, lo, hi);
    out.b_tau_s = allan.tau_s(kmin);
    const Scalar b_hi = std::sqrt(hi) / kFlickerFloor;
    if (kmin + 1 < usable) {
      out.b = {std::sqrt(av[kmin]) / kFlickerFloor, std::sqrt(lo) / kFlickerFloor, b_hi, true, false};
    } else {
      out.b = {b_hi, Scalar(0), b_hi, true, true};
    }
  }

  // K: read at the longest usable octave once the curve rises into it, else an upper limit.
  const std::size_t kl = usable - 1;
  if (kl > kmin && av[kl] >= rw_rise * av[kl - 1]) {
    const Scalar tau = allan.tau_s(kl);
    const Scalar white = (out.n.valid && !out.n.upper_limit) ? out.n.value * out.n.value / tau : Scalar(0);
    const Scalar nu =
        nonoverlapped_edf<Scalar>(AllanNoise::random_walk, allan.terms(kl), allan.factor(kl));
    avar_interval(av[kl], nu, z, lo, hi);
    const auto k_of = [tau, white](Scalar v) noexcept {
      const Scalar rw = v - white;
      return rw > Scalar(0) ? std::sqrt(Scalar(3) * rw / tau) : Scalar(0);
    };
    out.k = {k_of(av[kl]), k_of(lo), k_of(hi), true, false};
  } else {
    const Scalar nu =
        nonoverlapped_edf<Scalar>(AllanNoise::random_walk, allan.terms(kl), allan.factor(kl));
    avar_interval(av[kl], nu, z, lo, hi);
    const Scalar v = std::sqrt(Scalar(3) * hi / allan.tau_s(kl));
    out.k = {v, Scalar(0), v, true, true};
  }
  return true;
}

}  // namespace gyrodrift
