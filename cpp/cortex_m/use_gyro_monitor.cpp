// Cortex-M4F gate unit: the gyro monitor on one gyro (16 octaves, tau up to 131 s at 250 Hz,
// health alarms, online re-identification), fed sample by sample with the processor's
// stuck/saturated flags, then its curve, noise estimates, alarms and model in use read out.
#include <gyrodrift/imu/gyro_monitor.hpp>

#include "support.hpp"

namespace {
constexpr std::size_t kOctaves = 16;
using Monitor = gyrodrift::GyroMonitor<float, kOctaves>;
// Static storage, no heap.
Monitor& monitor() noexcept {
  static Monitor m;
  return m;
}
}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  gyrodrift::GyroMonitorSettings<float> s;
  s.sample_rate_hz = 250.0F;
  s.octaves = kOctaves;
  s.alarms.stuck_samples = 400U;
  s.alarms.saturated_samples = 400U;
  s.reidentify = true;
  gyrodrift::HealthReference<float, kOctaves> ref{};
  ref.octaves = kOctaves;
  float avar = 1e-8F;
  // White rate noise (variance halving per octave). Without a double-precision FPU the alarms
  // derive no edf: a reference without one is refused, ...
  for (std::size_t k = 0; k < kOctaves; ++k, avar *= 0.5F) ref.avar[k] = avar;
  const gyrodrift::DriftModelParams<float> model{0.5F, 0.0F, 1e-10F, 1e-8F, 0.0F};
  if (monitor().configure(s, model, ref) != gyrodrift::GyroMonitorStatus::bad_settings) return 2;
  // ... so it comes with the reference as on the target, computed on the host: for blocks of
  // 64 terms of white rate noise n / (1.5 n - 0.5).
  for (std::size_t k = 0; k < kOctaves; ++k) ref.edf_per_term[k] = 64.0F / 95.5F;
  if (monitor().configure(s, model, ref) != gyrodrift::GyroMonitorStatus::ok) return 1;
  for (std::size_t k = 0; k < 8192; ++k) {
    monitor().push(input(k), false, k % 1000U == 7U);
  }
  for (std::size_t j = 0; j < kOctaves; ++j) {
    float v = 0.0F;
    if (monitor().allan().avar(j, v)) sink(v);
  }
  gyrodrift::NoiseEstimates<float> e{};
  monitor().noise(0.6827F, e);
  sink(e.n.value);
  sink(e.b.value);
  sink(e.k.hi);
  sink(static_cast<std::int32_t>(monitor().latched()));
  sink(monitor().identifier().gain0());
  sink(monitor().identifier().in_use().q);
  sink(static_cast<std::int32_t>(sizeof(Monitor)));
  return 0;
}
