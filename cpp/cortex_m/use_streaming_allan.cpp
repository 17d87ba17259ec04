// Cortex-M4F gate unit: three float streaming octave Allan variances (one per gyro axis),
// 16 octaves (tau up to 2^15 samples, 82 s at 400 Hz), fed sample by sample as the
// navigation computer would, then every octave's variance and term count read out.
#include <gyrodrift/stability/streaming_allan.hpp>

#include "support.hpp"

namespace {
using Stats = gyrodrift::StreamingAllan<float, 16>;
// Static storage, no heap.
Stats& axis(int i) noexcept {
  static Stats stats[3];
  return stats[i];
}
}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  for (int a = 0; a < 3; ++a) {
    if (!axis(a).configure(400.0F, 16)) return 1;
  }
  for (std::size_t k = 0; k < 4096; ++k) {
    for (int a = 0; a < 3; ++a) axis(a).push(input(3 * k + static_cast<std::size_t>(a)));
  }
  for (int a = 0; a < 3; ++a) {
    for (std::size_t j = 0; j < axis(a).octaves(); ++j) {
      float v = 0.0F;
      if (axis(a).avar(j, v)) sink(v);
      sink(static_cast<std::int32_t>(axis(a).terms(j)));
      sink(axis(a).tau_s(j));
    }
  }
  sink(static_cast<std::int32_t>(axis(0).rejected()));
  sink(static_cast<std::int32_t>(sizeof(Stats)));
  return 0;
}
