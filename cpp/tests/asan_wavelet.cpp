// Address/UB sanitizer run of the lifting transform (all wrap-around paths, tiny bands) and
// the real-time filter in every mode, including NaN input and invalid configurations.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <vector>

#include <gyrodrift/filters/lifting_transform.hpp>
#include <gyrodrift/filters/realtime_wavelet.hpp>

using namespace gyrodrift;

TEST_CASE("transform on every small size and level stays in bounds and reconstructs") {
  for (WaveletKind w : {WaveletKind::db4, WaveletKind::db8}) {
    for (std::size_t n = 2; n <= 256; n *= 2) {
      for (int level = 1; level <= kMaxWaveletLevel && (std::size_t{1} << level) <= n; ++level) {
        std::vector<double> x(n), s(n);
        for (std::size_t i = 0; i < n; ++i) x[i] = std::sin(double(i) * 0.7);
        const auto x0 = x;
        REQUIRE(LiftingTransform<double>::forward(w, x.data(), n, level, s.data()));
        REQUIRE(LiftingTransform<double>::inverse(w, x.data(), n, level, s.data()));
        for (std::size_t i = 0; i < n; ++i) CHECK(std::fabs(x[i] - x0[i]) < 1e-12);
      }
    }
  }
}

TEST_CASE("real-time filter in all modes with bad samples") {
  for (WaveletMode m : {WaveletMode::forced, WaveletMode::soft, WaveletMode::hard}) {
    RealtimeWavelet<float, 64> f(WaveletKind::db8, 2, m);
    RealtimeWavelet<float, 64> bad(WaveletKind::db8, 7, m);
    for (int i = 0; i < 300; ++i) {
      const float x = i % 17 == 0 ? std::numeric_limits<float>::quiet_NaN() : std::sin(float(i) * 0.3F);
      CHECK(std::isfinite(f.step(x)));
      bad.step(x);
    }
    CHECK(f.fault_count() == 18);
  }
}

TEST_CASE("absurd finite input (overflowing sums) neither crashes nor poisons the filter") {
  for (WaveletMode m : {WaveletMode::forced, WaveletMode::soft, WaveletMode::hard}) {
    RealtimeWavelet<float, 64> f(WaveletKind::db8, 2, m);
    RealtimeWavelet<float, 64> ref(WaveletKind::db8, 2, m);
    RealtimeWavelet<float, 16> small(WaveletKind::db8, 1, m);  // recompute-median fallback path
    for (int i = 0; i < 200; ++i) {
      small.step(i >= 80 && i < 90 ? 3.0e38F : std::sin(float(i)));
      const float big = (i % 2 == 0 ? 3.0e38F : -3.0e38F);
      f.step(i >= 80 && i < 90 ? big : std::sin(float(i)));
      ref.step(std::sin(float(i)));
    }
    // 64+ samples after the burst left the window, the output is finite again, and once the
    // burst is out of every stream the result equals an undisturbed filter's.
    float a = 0.0F, b = 0.0F;
    for (int i = 200; i < 400; ++i) {
      a = f.step(std::sin(float(i)));
      b = ref.step(std::sin(float(i)));
    }
    CHECK(std::isfinite(a));
    CHECK(std::fabs(a - b) < 1e-5F);
  }
}
