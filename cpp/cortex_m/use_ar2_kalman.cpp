// Cortex-M4F gate unit: the FLOAT AR(2) chain as firmware would run it on a 3-axis gyro:
// on-target re-identification (streaming Yule-Walker + Burg over a static block), then a
// 3-axis bank of full AR(2)-Kalman filters, a steady-state bank and the AR filter, stepped on
// volatile input. No heap, no exceptions, no double arithmetic.
#include <gyrodrift/filters/ar2_kalman.hpp>
#include <gyrodrift/filters/ar2_model.hpp>
#include <gyrodrift/filters/ar2_steady_state.hpp>
#include <gyrodrift/filters/ar_filter.hpp>
#include <gyrodrift/filters/axis_bank.hpp>

#include "support.hpp"

namespace {
float block[256];  // identification block in static RAM (caller-owned buffer)
}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  using gyrodrift::cortex_m::sink;
  gyrodrift::Ar2YuleWalkerAccumulator<float> acc;
  for (std::size_t i = 0; i < 256; ++i) {
    block[i] = input(i) + 0.5f * input(i + 7);
    acc.push(block[i]);
  }
  gyrodrift::Ar2Model<float> model{0.6868f, -0.0213f, 0.01f, 0.5f};  // paper 002 fallback
  gyrodrift::Ar2Model<float> fitted{};
  if (acc.fit(fitted) == gyrodrift::Ar2Status::ok) model = fitted;
  gyrodrift::Ar2Model<float> burg{};
  const bool burg_ok = gyrodrift::fit_ar2(block, 256, gyrodrift::Ar2Method::burg, burg) ==
                       gyrodrift::Ar2Status::ok;
  const float r = gyrodrift::ar2_residual_variance(block, 256, model);

  gyrodrift::AxisBank<gyrodrift::Ar2Kalman<float>> kalman{gyrodrift::Ar2Kalman<float>(model, model.sigma2, r)};
  gyrodrift::AxisBank<gyrodrift::Ar2SteadyStateKalman<float>> steady{
      gyrodrift::Ar2SteadyStateKalman<float>(model, model.sigma2, r)};
  gyrodrift::ArFilter<float> ar(model);
  float in[3], out[3], out_ss[3];
  for (std::size_t i = 0; i < 1000; ++i) {
    in[0] = input(i);
    in[1] = input(i + 1);
    in[2] = input(i + 2);
    kalman.step(in, out);
    steady.step(in, out_ss);
    sink(out[0] + out[1] + out[2] + out_ss[0] + ar.step(in[0]));
  }
  sink(static_cast<std::int32_t>(burg_ok));
  return static_cast<int>(kalman.fault_count() + steady.fault_count() + ar.fault_count());
}
