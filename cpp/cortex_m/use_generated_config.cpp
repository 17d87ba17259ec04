// Cortex-M4F gate unit: the firmware processor built from a GENERATED configuration header
// (`gyrodrift config emit-cpp cpp/cortex_m/budget_config.toml -o generated/...hpp`; the test
// checks the committed header is what the generator writes). The budget chain:
// gyros wavelet db4 N = 256 J = 5 forced (FIR taps in flash, one window per gyro) ->
// steady-state AR(2)-Kalman, accelerometers bias removal. Its sizes are the budget figures
// (flash <= 16 KiB, RAM data + bss + measured stack <= 8 KiB; tests/test_cortex_m_golden.py).
#include "generated/gyrodrift_budget_config.hpp"
#include "support.hpp"

namespace {

// Static storage: the three windows live in .bss, the taps and the configuration in flash.
budget_config::Processor processor(budget_config::kImuConfig, budget_config::make_wavelet);

}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  if (processor.status() != gyrodrift::ImuStatus::ok) return 100;
  gyrodrift::ImuSample<float> s;
  gyrodrift::ImuOutput<float> y;
  std::uint32_t outputs = 0;
  for (std::uint32_t k = 0; k < 600; ++k) {
    s.seq = static_cast<std::uint16_t>(k);
    s.t_us = std::uint64_t{budget_config::kImuConfig.period_us} * static_cast<std::uint64_t>(k);
    for (std::size_t c = 0; c < 6; ++c) s.values[c] = input(k + 7u * c);
    if ((processor.step(s, y) & gyrodrift::kFlagRejected) != 0u) continue;
    sink(y.values[0] + y.values[1] + y.values[2] + y.values[3] + y.values[4] + y.values[5]);
    ++outputs;
  }
  return outputs == 600u ? 0 : 1;
}
