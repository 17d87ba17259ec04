// Cortex-M4F gate unit: the re-identification from lag statistics
// (filters/lag_drift_identifier.hpp) for three gyros as a navigation computer would run it:
// float statistics pushed sample by sample, the fits deferred (defer_fits) and run by the
// caller as thread mode would (run_pending_fit), in software double; then each gyro's model in
// use, gain and counters are read out, with the state size. This unit may link software double
// (tests/test_cortex_m_gate.py): the fit runs in double by design (lag_drift_fit.hpp).
//
// Record per gyro: AR(2) drift (0.9, -0.2) driven by q = 2, white noise r = 1, from an LCG
// (the sum of 12 uniforms), in float; cadence 4096 samples, fits from 2048 statistics samples,
// applied 1024 samples after their request: 9216 samples give four fits (gyro 0 twice).
// The deepest stack a fit takes below its caller (run_pending_fit's caller: free stack painted
// again before each fit, cortex_m_start.hpp's stack_used_by) is the last value sunk, the
// semihosting report's sink_i32.
#include <gyrodrift/filters/lag_drift_identifier.hpp>

#include <cstddef>
#include <cstdint>

#include "cortex_m_start.hpp"
#include "support.hpp"

namespace {

using gyrodrift::cortex_m::Noise;
using Identifier = gyrodrift::LagDriftIdentifier<float, 3>;
constexpr std::size_t kSamples = 9216;
// The state on the Cortex-M4 (x86-64: 920 and 408 B, cpp/tests/test_lag_drift_identifier.cpp):
// per gyro its statistics (136 B) and 120 B for its models, gains, counters and schedule; once
// the settings the fit uses and the fit's outcome.
static_assert(sizeof(Identifier) == 904, "three gyros");
static_assert(sizeof(gyrodrift::LagDriftIdentifier<float, 1>) == 392, "one gyro");

// Static storage, no heap.
Identifier& identifier() noexcept {
  static Identifier id;
  return id;
}

struct Drift {
  Noise w, v;
  float x1 = 0.0F, x2 = 0.0F;
  float next(float mean) noexcept {
    const float x = 0.9F * x1 - 0.2F * x2 + 1.41421356F * w.normal();
    x2 = x1;
    x1 = x;
    return mean + x + v.normal();
  }
};
}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  gyrodrift::OnlineDriftSettings<float> s;
  s.block_samples = 256;
  s.retune_blocks = 16;
  s.min_samples = 2048;
  s.max_step = 10.0F;
  gyrodrift::LagDriftSettings<float> lag;
  lag.fit_delay_samples = 1024;
  const gyrodrift::DriftModelParams<float> cfg{0.7F, 0.0F, 1.0F, 1.0F, 0.0F};
  const gyrodrift::DriftModelParams<float> models[3] = {cfg, cfg, cfg};
  Identifier& id = identifier();
  if (!id.configure(models, 3, s, lag)) return 1;
  id.defer_fits(true);
  Drift gyro[3] = {{{11U}, {12U}}, {{21U}, {22U}}, {{31U}, {32U}}};
  const float mean = input(0);
  std::int32_t fits = 0;
  std::uint32_t fit_stack = 0;
  for (std::size_t k = 0; k < kSamples; ++k) {
    for (std::size_t c = 0; c < 3; ++c) id.push(c, gyro[c].next(mean));
    // thread mode: the fit runs between interrupts, long before its apply point
    if (id.fit_pending()) {
      const std::uint32_t used = gyrodrift::cortex_m_start::stack_used_by([] { identifier().run_pending_fit(); });
      fit_stack = used > fit_stack ? used : fit_stack;
      ++fits;
    }
  }
  std::uint32_t applied = 0, accepted = 0;
  for (std::size_t c = 0; c < 3; ++c) {
    const auto& m = id.in_use(c);
    sink(m.a1);
    sink(m.a2);
    sink(m.q);
    sink(m.r);
    sink(m.mean);
    sink(id.gain0(c));
    sink(id.gain1(c));
    sink(static_cast<std::int32_t>(id.status(c)));
    sink(static_cast<std::int32_t>(id.fit_status(c)));
    applied += id.retunes(c) + id.refused_retunes(c);
    accepted += id.retunes(c);
  }
  sink(fits);
  sink(static_cast<std::int32_t>(sizeof(Identifier)));
  sink(static_cast<std::int32_t>(fit_stack));
  const bool near = id.in_use(0).a1 > 0.7F && id.in_use(0).a1 < 1.1F;
  return fits == 4 && applied == 4 && accepted >= 1 && id.late_fits() == 0 && near ? 0 : 2;
}
