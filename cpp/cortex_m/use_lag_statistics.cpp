// Cortex-M4F gate unit: three float whole-record lag statistics (one per gyro axis, 32 lags),
// fed sample by sample as the navigation computer would, with one refused (NaN) sample; then
// each axis's count, centre, sum, lag products and first and last values read out, with the
// state size. The form without the first values is checked for its size on this target too.
#include <gyrodrift/filters/lag_statistics.hpp>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "support.hpp"

namespace {
using Stats = gyrodrift::LagStatistics<float, 32>;
// The statistics without the first values (lag_statistics.hpp): the same sizes as on x86-64.
static_assert(sizeof(gyrodrift::LagStatisticsNoHead<float, 8>) == 136, "no-head statistics, L = 8");
static_assert(sizeof(gyrodrift::LagStatisticsNoHead<float, 12>) == 184, "no-head statistics, L = 12");
// Static storage, no heap.
Stats& axis(int i) noexcept {
  static Stats stats[3];
  return stats[i];
}
}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  for (std::size_t k = 0; k < 4096; ++k) {
    for (int a = 0; a < 3; ++a) axis(a).push(input(3 * k + static_cast<std::size_t>(a)));
  }
  if (axis(0).push(std::numeric_limits<float>::quiet_NaN())) return 1;
  for (int a = 0; a < 3; ++a) {
    const Stats& s = axis(a);
    if (s.samples() != 4096 || s.kept() != Stats::lags) return 2;
    sink(s.centre());
    sink(s.total().sum);
    sink(s.total().comp);
    for (std::size_t k = 0; k <= Stats::lags; ++k) {
      sink(s.product(k).sum);
      sink(s.product(k).comp);
    }
    for (std::size_t i = 0; i < s.kept(); ++i) {
      sink(s.head(i));
      sink(s.tail(i));
    }
  }
  sink(static_cast<std::int32_t>(axis(0).rejected()));
  sink(static_cast<std::int32_t>(sizeof(Stats)));
  return axis(0).rejected() == 1 ? 0 : 3;
}
