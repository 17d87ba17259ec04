// Input range of the filters (AR filter, AR(2)-Kalman, real-time wavelet).
//
// A finite sample far beyond any sensor's range (say 3e38 in float32, 1.7e308 in float64)
// would overflow the filters' sums: the wavelet adds 2N window samples through J lifting
// levels, the AR recursions add a1 x1 + a2 x2 with |a1| + |a2| < 3. Such a sample is treated
// like NaN/Inf (skipped and counted as a fault), so every filter either returns a finite
// output or counts a fault, and its state stays finite. The limit leaves 2^24 of headroom
// below the type's maximum (float: 2.0e31, double: 1.1e301), far more than the gains
// involved; for real data (rad/s, m/s^2, deg/h) it is never reached.
#pragma once

#include <cmath>
#include <limits>

namespace gyrodrift {

template <class Scalar>
constexpr Scalar filter_input_limit() noexcept {
  return std::numeric_limits<Scalar>::max() / Scalar(16777216);  // max / 2^24
}

// True for a finite value within the limit; false for NaN, +-Inf and |x| > limit
// (one compare: NaN fails every comparison).
template <class Scalar>
inline bool filter_input_ok(Scalar x) noexcept {
  return std::fabs(x) <= filter_input_limit<Scalar>();
}

}  // namespace gyrodrift
