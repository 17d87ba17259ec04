// Cortex-M4F gate unit: three float online drift identifiers (one per gyro axis), fed sample
// by sample as the navigation computer would, with a short block and retune cadence so the
// run crosses parameter updates and gain retunes; then each axis's estimate, gain, status and
// counters are read out, with the state size.
#include <gyrodrift/filters/online_drift_identifier.hpp>

#include "support.hpp"

namespace {
using Identifier = gyrodrift::OnlineDriftIdentifier<float>;
// Static storage, no heap.
Identifier& axis(int i) noexcept {
  static Identifier ids[3];
  return ids[i];
}
}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  gyrodrift::OnlineDriftSettings<float> s;
  s.block_samples = 64;
  s.retune_blocks = 4;
  s.min_samples = 1024;
  const gyrodrift::DriftModelParams<float> cfg{0.5F, 0.0F, 0.5F, 1.0F, 0.0F};
  for (int a = 0; a < 3; ++a) {
    if (!axis(a).configure(cfg, s)) return 1;
  }
  for (std::size_t k = 0; k < 4096; ++k) {
    for (int a = 0; a < 3; ++a) axis(a).push(input(3 * k + static_cast<std::size_t>(a)));
  }
  for (int a = 0; a < 3; ++a) {
    const auto& e = axis(a).estimate();
    sink(e.a1);
    sink(e.a2);
    sink(e.q);
    sink(e.r);
    sink(e.mean);
    sink(axis(a).gain0());
    sink(axis(a).gain1());
    sink(static_cast<std::int32_t>(axis(a).status()));
    sink(static_cast<std::int32_t>(axis(a).retunes()));
    sink(static_cast<std::int32_t>(axis(a).refused_retunes()));
    gyrodrift::DriftModelParams<float> se{};
    if (axis(a).stderrs(se)) sink(se.q);
  }
  sink(static_cast<std::int32_t>(axis(0).rejected()));
  sink(static_cast<std::int32_t>(sizeof(Identifier)));
  return 0;
}
