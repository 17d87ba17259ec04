// C++-only timing of the real-time wavelet filter and the lifting DWT (no Python): ns per
// sample per axis, median of repeats, measured in thread CPU time (CLOCK_THREAD_CPUTIME_ID)
// because the machine is shared: time spent preempted does not count. Prints a markdown table.
//   bench_wavelet [samples=200000] [repeats=5]
#include <gyrodrift/filters/lifting_transform.hpp>
#include <gyrodrift/filters/realtime_wavelet.hpp>

#include <algorithm>
#include <ctime>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <vector>

namespace {

using gyrodrift::WaveletKind;
using gyrodrift::WaveletMode;

template <class Scalar>
std::vector<Scalar> record(std::size_t n) {
  std::vector<Scalar> y(n);
  std::uint32_t s = 2026u;
  for (auto& v : y) {
    s = s * 1664525u + 1013904223u;
    v = static_cast<Scalar>(static_cast<double>(s >> 8) / static_cast<double>(1u << 24) - 0.5);
  }
  return y;
}

template <class F>
double median_ns(F&& run, std::size_t samples, int repeats) {
  std::vector<double> t;
  for (int r = 0; r < repeats; ++r) {
    timespec t0{}, t1{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t0);
    run();
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t1);
    const double ns = static_cast<double>(t1.tv_sec - t0.tv_sec) * 1e9 + static_cast<double>(t1.tv_nsec - t0.tv_nsec);
    t.push_back(ns / static_cast<double>(samples));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

volatile double g_sink = 0.0;

template <class Scalar, bool Full = true>
double bench_filter(WaveletKind w, WaveletMode m, bool recompute, std::size_t n, int repeats) {
  auto f = std::make_unique<gyrodrift::RealtimeWavelet<Scalar, 256, Full>>(w, 5, m);
  const auto x = record<Scalar>(n);
  for (std::size_t i = 0; i < 256; ++i) f->step(x[i]);
  return median_ns(
      [&] {
        Scalar acc = Scalar(0);
        if constexpr (Full) {
          if (recompute) {
            for (std::size_t i = 0; i + 256 <= n; ++i) acc += f->recompute(&x[i]);
            g_sink = static_cast<double>(acc);
            return;
          }
        }
        for (std::size_t i = 0; i < n; ++i) acc += f->step(x[i]);
        g_sink = static_cast<double>(acc);
      },
      recompute ? n - 255 : n, repeats);
}

const char* name(WaveletKind w) { return w == WaveletKind::db8 ? "db8" : "db4"; }

}  // namespace

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? std::strtoul(argv[1], nullptr, 10) : 200000;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 5;
  std::printf("| wavelet | scalar | path (N=256, J=5) | ns/sample/axis |\n| --- | --- | --- | ---: |\n");
  for (WaveletKind w : {WaveletKind::db8, WaveletKind::db4}) {
    const std::size_t n_slow = std::max<std::size_t>(n / 20, 1000);
    std::printf("| %s | double | streaming forced | %.1f |\n", name(w),
                bench_filter<double>(w, WaveletMode::forced, false, n, repeats));
    std::printf("| %s | double | streaming soft | %.1f |\n", name(w),
                bench_filter<double>(w, WaveletMode::soft, false, n_slow, repeats));
    std::printf("| %s | double | streaming hard | %.1f |\n", name(w),
                bench_filter<double>(w, WaveletMode::hard, false, n_slow, repeats));
    std::printf("| %s | double | full-window recompute (soft) | %.1f |\n", name(w),
                bench_filter<double>(w, WaveletMode::soft, true, n_slow, repeats));
    std::printf("| %s | float | streaming forced | %.1f |\n", name(w),
                bench_filter<float>(w, WaveletMode::forced, false, n, repeats));
    std::printf("| %s | float | streaming forced, forced-only variant | %.1f |\n", name(w),
                bench_filter<float, false>(w, WaveletMode::forced, false, n, repeats));
    std::printf("| %s | float | streaming soft | %.1f |\n", name(w),
                bench_filter<float>(w, WaveletMode::soft, false, n_slow, repeats));
    // Lifting DWT of the 512-sample extended window alone (the threshold path's main cost).
    std::vector<double> data = record<double>(512), scratch(512);
    const double t_dwt = median_ns(
        [&] {
          for (int r = 0; r < 1000; ++r) {
            gyrodrift::LiftingTransform<double>::forward(w, data.data(), 512, 5, scratch.data());
          }
          g_sink = data[0];
        },
        1000, repeats);
    std::printf("| %s | double | lifting DWT of the 512-sample extension, J=5 (per call) | %.1f |\n",
                name(w), t_dwt);
  }
  return 0;
}
