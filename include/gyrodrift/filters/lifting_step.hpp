// One lifting step of a factored wavelet filter bank (Daubechies & Sweldens 1998):
// band[target][k] += sum_{j < ntaps} c[j] * band[1 - target][(k + first + j) mod h].
// target 1 is a predict (odd band updated from even), 0 an update (even from odd).
#pragma once

#include <cstddef>

namespace gyrodrift {

template <class Scalar, std::size_t MaxTaps>
struct LiftingStep {
  int target;
  int first;
  int ntaps;
  Scalar c[MaxTaps];
};

}  // namespace gyrodrift
