// Cortex-M4F gate unit: three float real-time wavelet prefilters (one per gyro axis), db4,
// level 5, window 256, forced, as the alignment prefilter of paper 004 sec. 2.2 runs them
// (the forced-only variant: 5 KiB of state per axis), plus one full filter in soft-threshold
// mode so the threshold path (streams, incremental median, log, sqrt in float) is linked too.
#include <gyrodrift/filters/realtime_wavelet.hpp>

#include "support.hpp"

namespace {
using Filter = gyrodrift::RealtimeWavelet<float, 256, false>;
using FullFilter = gyrodrift::RealtimeWavelet<float, 256>;
// Static storage, constructed on first use, no heap.
Filter& axis(int i) noexcept {
  static Filter filters[3] = {Filter(gyrodrift::WaveletKind::db4, 5, gyrodrift::WaveletMode::forced),
                              Filter(gyrodrift::WaveletKind::db4, 5, gyrodrift::WaveletMode::forced),
                              Filter(gyrodrift::WaveletKind::db4, 5, gyrodrift::WaveletMode::forced)};
  return filters[i];
}
FullFilter& threshold_channel() noexcept {
  static FullFilter f(gyrodrift::WaveletKind::db8, 5, gyrodrift::WaveletMode::soft);
  return f;
}
}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  for (std::size_t k = 0; k < 1024; ++k) {
    for (int a = 0; a < 3; ++a) sink(axis(a).step(input(3 * k + static_cast<std::size_t>(a))));
    sink(threshold_channel().step(input(k)));
  }
  sink(static_cast<std::int32_t>(axis(0).fault_count() + threshold_channel().fault_count()));
  sink(static_cast<std::int32_t>(sizeof(Filter)));
  sink(static_cast<std::int32_t>(sizeof(FullFilter)));
  return 0;
}
