// C++-only timing of the IMU processor and the frame codecs (no Python):
//   * ImuProcessor step, six channels (3 AR(2)-Kalman gyros + 3 pass-through accels; and all
//     six through RealtimeWavelet<., 256> forced): median ns per step over a record, plus the
//     per-step distribution (p50/p99/max of single steps timed with steady_clock, which
//     includes ~20 ns of clock overhead) - the target is <= 2 us worst case per cycle;
//   * serial encode and parse (ns per 42-byte frame), CRC-16 (ns per byte), CAN encode +
//     reassembly (ns per sample), SLCAN encode + parse (ns per frame).
// Prints a markdown table; benchmarks/bench_imu.py runs it and adds the Python rows.
//   bench_imu [samples=200000] [repeats=5]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <gyrodrift/codecs/can_frames.hpp>
#include <gyrodrift/codecs/crc16.hpp>
#include <gyrodrift/codecs/serial_frame.hpp>
#include <gyrodrift/codecs/slcan.hpp>
#include <gyrodrift/filters/realtime_wavelet.hpp>
#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/imu_processor.hpp>
#include <memory>
#include <vector>

#include "../cortex_m/generated/gyrodrift_budget_config.hpp"  // the Cortex-M budget chain

using namespace gyrodrift;
using Clock = std::chrono::steady_clock;

namespace {

volatile double g_sink = 0.0;

template <class Scalar>
std::vector<ImuSample<Scalar>> record(std::size_t n) {
  std::vector<ImuSample<Scalar>> out(n);
  std::uint32_t s = 2026u;
  double p1 = 0.0, p2 = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    out[k].seq = static_cast<std::uint16_t>(k);
    out[k].t_us = std::uint64_t{kImuDefaultPeriodUs} * k;  // on the default period's grid
    for (std::size_t c = 0; c < 6; ++c) {
      s = s * 1664525u + 1013904223u;
      const double w = static_cast<double>(s >> 8) / static_cast<double>(1u << 24) - 0.5;
      const double x = 1.6 * p1 - 0.65 * p2 + 1e-5 * w;
      if (c == 0) {
        p2 = p1;
        p1 = x;
      }
      out[k].values[c] = static_cast<Scalar>(c < 3 ? 1e-5 + x + 1e-5 * w : 0.01 * w);
    }
  }
  return out;
}

template <class Scalar>
ImuConfig<Scalar> kalman_config() {
  ImuConfig<Scalar> cfg;
  for (std::size_t c = 0; c < 3; ++c) {
    auto& cc = cfg.channels[c];
    cc.filter = ChannelFilter::ar2_kalman;
    cc.model = Ar2Model<Scalar>{Scalar(1.6), Scalar(-0.65), Scalar(1e-10), Scalar(1e-5)};
    cc.q = Scalar(1e-10);
    cc.r = Scalar(1e-9);
    cc.stuck_samples = 100;
    cc.saturation = Scalar(10);
  }
  return cfg;
}

struct Stats {
  double median_ns = 0, p50 = 0, p99 = 0, max = 0;
};

template <class Proc, class Scalar>
Stats time_processor(Proc& p, const std::vector<ImuSample<Scalar>>& in, int repeats) {
  Stats st;
  std::vector<double> runs;
  ImuOutput<Scalar> y;
  for (int r = 0; r < repeats; ++r) {
    p.reset();
    const auto t0 = Clock::now();
    for (const auto& s : in) {
      p.step(s, y);
      g_sink = g_sink + static_cast<double>(y.values[0]);
    }
    runs.push_back(std::chrono::duration<double, std::nano>(Clock::now() - t0).count() /
                   static_cast<double>(in.size()));
  }
  std::sort(runs.begin(), runs.end());
  st.median_ns = runs[runs.size() / 2];
  // single-step distribution
  p.reset();
  std::vector<double> one(in.size());
  for (std::size_t k = 0; k < in.size(); ++k) {
    const auto t0 = Clock::now();
    p.step(in[k], y);
    const auto t1 = Clock::now();
    g_sink = g_sink + static_cast<double>(y.values[1]);
    one[k] = std::chrono::duration<double, std::nano>(t1 - t0).count();
  }
  std::sort(one.begin(), one.end());
  st.p50 = one[one.size() / 2];
  st.p99 = one[one.size() * 99 / 100];
  st.max = one.back();
  return st;
}

template <class F>
double median_ns(F&& run, std::size_t items, int repeats) {
  std::vector<double> t;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = Clock::now();
    run();
    t.push_back(std::chrono::duration<double, std::nano>(Clock::now() - t0).count() / static_cast<double>(items));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

void row(const char* what, double ns, const char* unit, const Stats* st = nullptr) {
  if (st != nullptr) {
    std::printf("| %s | %.1f | %.3g | %.0f / %.0f / %.0f |\n", what, ns, 1e9 / ns, st->p50, st->p99, st->max);
  } else {
    std::printf("| %s | %.1f | %.3g %s | - |\n", what, ns, 1e9 / ns, unit);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? static_cast<std::size_t>(std::atol(argv[1])) : 200000;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 5;
  std::printf("| C++ (%zu samples, median of %d) | ns per item | items/s | single step p50 / p99 / max ns |\n", n, repeats);
  std::printf("| --- | ---: | ---: | ---: |\n");

  {
    const auto in = record<float>(n);
    ImuProcessor<float> p(kalman_config<float>());
    const Stats st = time_processor(p, in, repeats);
    row("ImuProcessor<float> step, 3 AR(2)-Kalman + 3 pass", st.median_ns, "", &st);
  }
  {
    const auto in = record<double>(n);
    ImuProcessor<double> p(kalman_config<double>());
    const Stats st = time_processor(p, in, repeats);
    row("ImuProcessor<double> step, 3 AR(2)-Kalman + 3 pass", st.median_ns, "", &st);
  }
  {
    using W = RealtimeWavelet<float, 256>;
    auto cfg = kalman_config<float>();
    for (auto& cc : cfg.channels) cc.filter = ChannelFilter::wavelet;
    const auto in = record<float>(n / 4);
    auto p = std::make_unique<ImuProcessor<float, W>>(cfg, W(WaveletKind::db8, 5));
    const Stats st = time_processor(*p, in, repeats);
    row("ImuProcessor<float> step, 6 x wavelet db8 N=256 forced", st.median_ns, "", &st);
  }

  {
    // The Cortex-M budget chain from the generated configuration header: 3 gyros wavelet db4
    // N=256 J=5 forced (flash-FIR stage) -> steady-state AR(2)-Kalman, 3 accels bias removal.
    const auto in = record<float>(n / 4);
    auto p = std::make_unique<budget_config::Processor>(budget_config::kImuConfig, budget_config::make_wavelet);
    const Stats st = time_processor(*p, in, repeats);
    row("budget chain (generated header): 3 x FIR db4 N=256 -> steady AR(2)-Kalman + 3 bias", st.median_ns, "", &st);
  }
  {
    // The same chain as gyrodrift-loop runs it from a configuration file (RealtimeWavelet stage).
    using W = RealtimeWavelet<float, 256>;
    ImuConfig<float> cfg = budget_config::kImuConfig;
    const auto in = record<float>(n / 4);
    auto p = std::make_unique<ImuProcessor<float, W>>(cfg, W(WaveletKind::db4, 5));
    const Stats st = time_processor(*p, in, repeats);
    row("same chain, RealtimeWavelet<float, 256> stage", st.median_ns, "", &st);
  }
  {
    // The loop's stage: the window chosen at run time from the configuration (256 here).
    using W = RealtimeWaveletAnyWindow<float>;
    ImuConfig<float> cfg = budget_config::kImuConfig;
    const auto in = record<float>(n / 4);
    auto p = std::make_unique<ImuProcessor<float, W>>(
        cfg, [](std::size_t) { return W(256, WaveletKind::db4, 5, WaveletMode::forced); });
    const Stats st = time_processor(*p, in, repeats);
    row("same chain, RealtimeWaveletAnyWindow stage, N=256 (the loop's)", st.median_ns, "", &st);
  }
  {
    // The largest window of the format: the forced FIR has 4096 taps per gyro.
    using W = RealtimeWaveletAnyWindow<float>;
    ImuConfig<float> cfg = budget_config::kImuConfig;
    const auto in = record<float>(n / 4);
    auto p = std::make_unique<ImuProcessor<float, W>>(
        cfg, [](std::size_t) { return W(4096, WaveletKind::db4, 8, WaveletMode::forced); });
    const Stats st = time_processor(*p, in, repeats);
    row("same chain, RealtimeWaveletAnyWindow stage, db4 N=4096 J=8", st.median_ns, "", &st);
  }

  // Codecs.
  std::vector<std::uint8_t> stream(n * serial::kFrameSize);
  {
    const auto in = record<float>(n);
    const double ns = median_ns(
        [&] {
          for (std::size_t k = 0; k < n; ++k) {
            serial::ImuFrame f;
            f.seq = in[k].seq;
            f.t_us = in[k].t_us;
            f.values = in[k].values;
            serial::encode_frame(f, stream.data() + k * serial::kFrameSize, serial::kFrameSize);
          }
        },
        n, repeats);
    row("serial encode_frame (42 B)", ns, "frames/s");
  }
  {
    const double ns = median_ns(
        [&] {
          auto p = std::make_unique<serial::SerialFrameParser<4096>>();
          serial::ImuFrame f;
          std::size_t pos = 0;
          while (pos < stream.size()) {
            pos += p->feed(stream.data() + pos, std::min<std::size_t>(1024, stream.size() - pos));
            while (p->next(f)) g_sink = g_sink + static_cast<double>(f.values[2]);
          }
        },
        n, repeats);
    row("serial parse (1 KiB chunks)", ns, "frames/s");
  }
  {
    const double ns = median_ns(
        [&] { g_sink = g_sink + crc16_ccitt_false(stream.data(), stream.size()); }, stream.size(), repeats);
    row("CRC-16/CCITT-FALSE", ns, "bytes/s");
  }
  {
    const double ns = median_ns(
        [&] {
          can::CanSampleAssembler<4> a;
          std::array<can::CanFrame, 4> fr{};
          can::CanSample s, out;
          for (std::size_t k = 0; k < n; ++k) {
            s.seq = static_cast<std::uint16_t>(k);
            can::encode_sample(s, can::kInputBaseId, fr);
            for (const auto& f : fr) {
              if (a.push(f, out)) g_sink = g_sink + out.seq;
            }
          }
        },
        n, repeats);
    row("CAN encode 4 frames + reassemble", ns, "samples/s");
  }
  {
    const double ns = median_ns(
        [&] {
          slcan::SlcanParser<> p;
          can::CanFrame f;
          f.id = 0x101;
          f.dlc = 8;
          char line[slcan::kMaxFrameLine];
          slcan::Event ev;
          for (std::size_t k = 0; k < n; ++k) {
            f.data[0] = static_cast<std::uint8_t>(k);
            const std::size_t len = slcan::encode_frame(f, line, sizeof line);
            for (std::size_t i = 0; i < len; ++i) {
              if (p.push(static_cast<std::uint8_t>(line[i]), ev)) g_sink = g_sink + ev.frame.data[0];
            }
          }
        },
        n, repeats);
    row("SLCAN encode + parse (22-char line)", ns, "frames/s");
  }
  return 0;
}
