// C++-only timing of the loop's per-sample work with no I/O: decode one input frame, step
// ImuProcessor<float> (AR(2)-Kalman gyros, pass-through accelerometers), encode the output
// frame. Per-sample times (clock_gettime around each sample) as p50/p99/p99.99/max, and the
// bulk rate (one clock read around the whole run). Prints a markdown table row.
//   bench_replay [samples=1000000] [repeats=5]
#include <time.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include <gyrodrift/codecs/serial_frame.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

namespace {
std::uint64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL + static_cast<std::uint64_t>(ts.tv_nsec);
}
}  // namespace

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? static_cast<std::size_t>(std::strtoull(argv[1], nullptr, 10)) : 1000000U;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 5;
  namespace gs = gyrodrift::serial;
  gyrodrift::ImuConfig<float> cfg;
  for (std::size_t c = 0; c < 3; ++c) {
    // The demonstration model's coefficients (config_schema.hpp), this record's noise level.
    cfg.channels[c].model = gyrodrift::Ar2Model<float>{static_cast<float>(gyrodrift::ImuDemoAr2::a1),
                                                       static_cast<float>(gyrodrift::ImuDemoAr2::a2), 5.9e-12F,
                                                       static_cast<float>(gyrodrift::ImuDemoAr2::mean)};
    cfg.channels[c].q = 5.9e-12F;
    cfg.channels[c].r = 1e-10F;
  }
  // Input frames prepared up front (the loop's parser hands out decoded frames the same way).
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(0.0F, 1e-4F);
  std::vector<std::array<std::uint8_t, gs::kFrameSize>> frames(n);
  for (std::size_t i = 0; i < n; ++i) {
    gs::ImuFrame f;
    f.seq = static_cast<std::uint16_t>(i & 0xFFFFU);
    f.t_us = std::uint64_t{gyrodrift::kImuDefaultPeriodUs} * static_cast<std::uint64_t>(i);
    for (std::size_t c = 0; c < 6; ++c) f.values[c] = noise(rng) + (c == 5 ? 9.8F : 0.0F);
    gs::encode_frame(f, frames[i].data(), frames[i].size());
  }
  std::vector<std::uint32_t> per(n);
  std::vector<double> bulk_ns;
  std::uint64_t sink = 0;
  for (int r = 0; r < repeats; ++r) {
    gyrodrift::ImuProcessor<float> proc(cfg);
    std::array<std::uint8_t, gs::kFrameSize> out_bytes{};
    const std::uint64_t b0 = now_ns();
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint64_t t0 = now_ns();
      gs::ImuFrame in;
      gs::decode_frame(frames[i].data(), frames[i].size(), in);
      gyrodrift::ImuSample<float> s;
      s.seq = in.seq;
      s.t_us = in.t_us;
      s.values = in.values;
      gyrodrift::ImuOutput<float> y;
      const std::uint16_t flags = proc.step(s, y);
      gs::ImuFrame o;
      o.type = gs::kTypeOutput;
      o.seq = y.seq;
      o.flags = flags;
      o.t_us = y.t_us;
      o.values = y.values;
      gs::encode_frame(o, out_bytes.data(), out_bytes.size());
      sink += out_bytes[40];
      per[i] = static_cast<std::uint32_t>(now_ns() - t0);
    }
    bulk_ns.push_back(static_cast<double>(now_ns() - b0) / static_cast<double>(n));
  }
  std::sort(per.begin(), per.end());
  auto q = [&](double p) { return static_cast<double>(per[std::min(n - 1, static_cast<std::size_t>(p * static_cast<double>(n)))]); };
  std::sort(bulk_ns.begin(), bulk_ns.end());
  const double med = bulk_ns[bulk_ns.size() / 2];
  std::printf("| decode + ImuProcessor<float> step + encode (6 ch), last of %d runs of %zu samples | %.0f | %.0f | %.0f | %.0f | %.0f | %.0f |\n",
              repeats, n, med, 1e9 / med, q(0.5), q(0.99), q(0.9999), static_cast<double>(per[n - 1]));
  std::fprintf(stderr, "checksum %llu\n", static_cast<unsigned long long>(sink));
  return 0;
}
