// RealtimeWaveletWindows: the run-time window choice of the host programs gives exactly the
// filter RealtimeWavelet<Scalar, N> gives for that window (every window of the configuration
// format, both wavelets, all modes), steps without allocating, and holds no filter for a
// window outside its list (the processor then refuses the channel).
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/realtime_wavelet.hpp>
#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/imu_processor.hpp>
#include <memory>

#include "alloc_counter.hpp"

using gyrodrift::RealtimeWavelet;
using gyrodrift::RealtimeWaveletAnyWindow;
using gyrodrift::RealtimeWaveletStatus;
using gyrodrift::WaveletKind;
using gyrodrift::WaveletMode;

namespace {

double input(std::size_t i) {
  // deterministic, noisy: a slow sine plus a hashed component
  const auto h = static_cast<std::uint32_t>(i * 2654435761U);
  return std::sin(0.01 * static_cast<double>(i)) + 0.3 * (static_cast<double>(h >> 8) / 16777216.0 - 0.5);
}

template <std::size_t N>
void check_window() {
  for (const WaveletKind kind : {WaveletKind::db4, WaveletKind::db8}) {
    const int jmax = gyrodrift::realtime_wavelet_max_level(N, kind);
    for (const WaveletMode mode : {WaveletMode::forced, WaveletMode::soft, WaveletMode::hard}) {
      auto direct = std::make_unique<RealtimeWavelet<double, N>>(kind, jmax, mode);
      auto any = std::make_unique<RealtimeWaveletAnyWindow<double>>(N, kind, jmax, mode);
      REQUIRE(any->status() == RealtimeWaveletStatus::ok);
      CHECK(any->window() == N);
      bool same = true;
      for (std::size_t i = 0; i < N + 40; ++i) {
        const double x = i == N + 5 ? std::nan("") : input(i);  // one skipped sample (fault counted)
        same = same && direct->step(x) == any->step(x);
      }
      CHECK(same);
      CHECK(any->ready());
      CHECK(any->fault_count() == 1U);
      any->reset();
      CHECK(!any->ready());
      CHECK(any->fault_count() == 0U);
    }
  }
}

}  // namespace

TEST_CASE("every format window gives the filter of that window, bit for bit") {
  check_window<16>();
  check_window<32>();
  check_window<64>();
  check_window<128>();
  check_window<256>();
  check_window<512>();
  check_window<1024>();
  check_window<2048>();
  check_window<4096>();
}

TEST_CASE("a window outside the list, or none, holds no filter") {
  for (const std::size_t n : {std::size_t{0}, std::size_t{8}, std::size_t{100}, std::size_t{8192}}) {
    RealtimeWaveletAnyWindow<float> w(n, WaveletKind::db4, 1, WaveletMode::forced);
    CHECK(w.status() == RealtimeWaveletStatus::window_unavailable);
    CHECK(w.window() == 0U);
    CHECK(w.step(2.5F) == 2.5F);  // passes through
  }
  CHECK(RealtimeWaveletAnyWindow<float>{}.status() == RealtimeWaveletStatus::window_unavailable);
  CHECK(RealtimeWaveletAnyWindow<float>::supports(4096));
  CHECK(!RealtimeWaveletAnyWindow<float>::supports(8));
  CHECK(gyrodrift::config_wavelet_window_ok(16));
  CHECK(gyrodrift::config_wavelet_window_ok(4096));
  CHECK(!gyrodrift::config_wavelet_window_ok(8));
  CHECK(!gyrodrift::config_wavelet_window_ok(8192));
  CHECK(!gyrodrift::config_wavelet_window_ok(100));
  CHECK(!gyrodrift::config_wavelet_window_ok(-256));
  // A level too deep for the window is the filter's own status.
  RealtimeWaveletAnyWindow<float> deep(16, WaveletKind::db8, 2, WaveletMode::forced);
  CHECK(deep.status() == RealtimeWaveletStatus::level_out_of_range);
}

TEST_CASE("a processor with per-channel windows steps without allocating") {
  using W = RealtimeWaveletAnyWindow<float>;
  using Proc = gyrodrift::ImuProcessor<float, W>;
  gyrodrift::ImuConfig<float> cfg;
  for (auto& cc : cfg.channels) cc = gyrodrift::ImuChannelConfig<float>{};
  for (std::size_t c = 0; c < 4; ++c) cfg.channels[c].filter = gyrodrift::ChannelFilter::wavelet;
  const std::size_t windows[4] = {16, 64, 512, 4096};
  auto p = std::make_unique<Proc>(cfg, [&windows](std::size_t c) {
    return c < 4 ? W(windows[c], WaveletKind::db4, 2, c % 2 == 0 ? WaveletMode::forced : WaveletMode::soft) : W{};
  });
  REQUIRE(p->status() == gyrodrift::ImuStatus::ok);
  gyrodrift::ImuSample<float> in;
  gyrodrift::ImuOutput<float> out;
  long n_alloc = 0;
  float acc = 0.0F;
  {
    gyrodrift::test::AllocationScope scope;
    for (std::size_t k = 0; k < 600; ++k) {
      in.seq = static_cast<std::uint16_t>(k);
      in.t_us = std::uint64_t{gyrodrift::kImuDefaultPeriodUs} * k;
      for (std::size_t c = 0; c < 6; ++c) in.values[c] = static_cast<float>(input(k + 7 * c));
      p->step(in, out);
      acc += out.values[2];
    }
    n_alloc = scope.allocations();
  }
  CHECK(n_alloc == 0);
  CHECK(acc == acc);
  // Window 4096 has not filled after 600 samples: its channel passes the input through.
  CHECK(out.values[3] == in.values[3]);
  // A wavelet channel without a filter for its window is refused.
  cfg.channels[5].filter = gyrodrift::ChannelFilter::wavelet;
  auto bad = std::make_unique<Proc>(cfg, [](std::size_t c) {
    return c == 5 ? W(100, WaveletKind::db4, 2, WaveletMode::forced) : W(16, WaveletKind::db4, 2, WaveletMode::forced);
  });
  CHECK(bad->status() == gyrodrift::ImuStatus::wavelet_unavailable);
  CHECK(bad->bad_channel() == 5);
}
