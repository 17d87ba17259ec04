// IEEE 952 noise estimates (angle random walk N, bias instability B, rate random walk K) with
// intervals, read from a StreamingAllan curve while it grows: the numbers a navigation computer
// reports about its own gyros.
//
// INTERFACE SKELETON: estimate_noise() is not implemented yet (it reports nothing valid). The
// public names and meanings are fixed; the implementation replaces the body.
//
// Units are the channel's: for a gyro in rad/s, N in rad/s/sqrt(Hz) (= rad/sqrt(s)), B in rad/s,
// K in rad/s*sqrt(Hz) (= rad/s/sqrt(s)). Allocation-free, noexcept, templated on Scalar.
#pragma once

#include <cstddef>

#include "streaming_allan.hpp"

namespace gyrodrift {

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
  NoiseTermEstimate<Scalar> b{};  // bias instability (fitted flat term)
  NoiseTermEstimate<Scalar> k{};  // rate random walk
  Scalar b_tau_s = Scalar(0);     // averaging time of the Allan minimum
};

// Estimates from the curve so far at `coverage` (e.g. 0.95). False when nothing is estimable.
template <class Scalar, std::size_t Octaves>
bool estimate_noise(const StreamingAllan<Scalar, Octaves>& allan, Scalar coverage,
                    NoiseEstimates<Scalar>& out) noexcept {
  (void)allan;
  (void)coverage;
  out = NoiseEstimates<Scalar>{};
  return false;
}

}  // namespace gyrodrift
