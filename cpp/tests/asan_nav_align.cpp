// AddressSanitizer + UBSan run of the alignment pipeline (float and double, 12 and 15 states,
// prefilter on/off) through coarse and fine alignment with NaN/Inf samples and odd settings:
// any out-of-bounds access in the ring buffers / FIR window or UB in the numerics aborts.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <gyrodrift/nav/align_pipeline.hpp>
#include <limits>
#include <memory>

namespace {

template <class S, int N>
void run(int n_taps, int delay, int kf_every) {
  using Pipe = gyrodrift::AlignPipeline<S, N, 256, 32>;
  auto pipe = std::make_unique<Pipe>();
  gyrodrift::AlignSettings<S> s;
  s.dt_s = S(0.01);
  s.lat_rad = S(0.68);
  s.lon_rad = S(2.0);
  s.h_m = S(50);
  s.coarse_samples = 300;
  s.kf_every = kf_every;
  s.accel_delay_samples = delay;
  typename Pipe::VecN p0, q, fl;
  p0.setConstant(S(1e-2));
  q.setConstant(S(1e-12));
  fl.setConstant(S(1e-20));
  std::array<S, 256> taps;
  taps.fill(S(1) / static_cast<S>(n_taps > 0 ? n_taps : 1));
  REQUIRE(pipe->reset(s, p0, q, typename Pipe::Vec3(S(1e-4), S(1e-4), S(1e-4)), fl, taps.data(), n_taps));
  std::uint32_t seed = 1u;
  long bad = 0;
  for (int k = 0; k < 3000; ++k) {
    seed = seed * 1664525u + 1013904223u;
    const S u = static_cast<S>(static_cast<double>(seed >> 8) / 16777216.0 - 0.5);
    typename Pipe::Vec3 dth(S(3e-7) + S(1e-7) * u, S(5e-7), S(4.6e-7) - S(1e-7) * u);
    typename Pipe::Vec3 dv(S(1e-4) * u, S(-1e-4) * u, S(0.098));
    if (k % 401 == 17) {
      dth(1) = std::numeric_limits<S>::quiet_NaN();
      ++bad;
    }
    if (k % 613 == 5) {
      dv(2) = std::numeric_limits<S>::infinity();
      ++bad;
    }
    pipe->step(dth, dv);
  }
  CHECK(pipe->bad_samples() == bad);
  CHECK_FALSE(pipe->failed());
  CHECK(pipe->attitude().allFinite());
}

}  // namespace

TEST_CASE("alignment pipeline under sanitizers") {
  run<double, 15>(256, 8, 10);
  run<double, 12>(0, 0, 1);
  run<float, 15>(64, 32, 7);
  run<float, 12>(1, 3, 40);
}

TEST_CASE("invalid settings are rejected, not run") {
  using Pipe = gyrodrift::AlignPipeline<double, 15, 256, 32>;
  auto pipe = std::make_unique<Pipe>();
  gyrodrift::AlignSettings<double> s;
  Pipe::VecN p0 = Pipe::VecN::Constant(1e-2), q = Pipe::VecN::Zero(), fl = Pipe::VecN::Zero();
  const Pipe::Vec3 r(1e-4, 1e-4, 1e-4);
  std::array<double, 256> taps{};
  s.accel_delay_samples = 33;
  CHECK_FALSE(pipe->reset(s, p0, q, r, fl, taps.data(), 8));
  s.accel_delay_samples = 0;
  CHECK_FALSE(pipe->reset(s, p0, q, r, fl, taps.data(), 257));
  CHECK_FALSE(pipe->reset(s, p0, q, r, fl, nullptr, 8));
  s.kf_every = 0;
  CHECK_FALSE(pipe->reset(s, p0, q, r, fl, taps.data(), 8));
  CHECK(pipe->step(Pipe::Vec3::Zero(), Pipe::Vec3::Zero()) == gyrodrift::AlignStatus::kFailed);
}
