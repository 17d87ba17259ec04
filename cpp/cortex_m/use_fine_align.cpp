// Cortex-M4F gate unit: the FLOAT alignment pipeline (coarse alignment, strapdown with
// coning/sculling, 15-state fine-alignment KF with Joseph update and feedback, 256-tap gyro
// prefilter with the matching 8-sample accelerometer delay) stepped on volatile input.
#include <gyrodrift/nav/align_pipeline.hpp>

#include "support.hpp"

namespace {
using Pipe = gyrodrift::AlignPipeline<float, 15, 256, 16>;
Pipe pipe;  // static storage: ~9 KiB of filter state, no heap
float taps[256];
}  // namespace

extern "C" int app_main(void) {
  using gyrodrift::cortex_m::input;
  for (int j = 0; j < 256; ++j) taps[j] = input(static_cast<std::size_t>(j)) * 1e-3f + 1.0f / 256.0f;
  gyrodrift::AlignSettings<float> s;
  s.dt_s = 0.0025f;
  s.lat_rad = 0.6806784f;  // 39 deg
  s.lon_rad = 2.0245819f;
  s.h_m = 50.0f;
  s.coarse_samples = 400;
  s.kf_every = 40;
  s.accel_delay_samples = 8;
  s.heading_stage_cycles = 10;  // heading acquisition stage for the first second (float path)
  s.heading_stage_q = 3e-8f;
  Pipe::VecN p0, q, floor;
  p0 << 3e-4f, 3e-4f, 3e-2f, 0.25f, 0.25f, 0.25f, 1.0f, 1.0f, 1.0f, 1e-14f, 1e-14f, 1e-14f, 1e-6f,
      1e-6f, 1e-6f;
  q << 8e-14f, 8e-14f, 8e-14f, 1e-8f, 1e-8f, 1e-8f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f,
      0.0f;
  floor.setConstant(1e-20f);
  const Pipe::Vec3 r(1e-4f, 1e-4f, 1e-4f);
  if (!pipe.reset(s, p0, q, r, floor, taps, 256)) return -1;
  int updates = 0;
  for (std::size_t i = 0; i < 2000; ++i) {
    const Pipe::Vec3 dth(input(i) * 1e-7f, input(i + 1) * 1e-7f, 1.6e-7f + input(i + 2) * 1e-7f);
    const Pipe::Vec3 dv(input(i + 3) * 1e-4f, input(i + 4) * 1e-4f, 0.0245f + input(i + 5) * 1e-4f);
    if (pipe.step(dth, dv) == gyrodrift::AlignStatus::kKfUpdated) ++updates;
  }
  const Pipe::Vec3 att = pipe.attitude();
  gyrodrift::cortex_m::sink(att(2));
  gyrodrift::cortex_m::sink(static_cast<std::int32_t>(updates));
  return static_cast<int>(pipe.bad_samples());
}
