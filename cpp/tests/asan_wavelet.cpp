// Address/UB sanitizer run of the lifting transform (all wrap-around paths, tiny bands) and
// the real-time filter in every mode, including NaN input and invalid configurations.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <vector>

#include <gyrodrift/lifting_transform.hpp>
#include <gyrodrift/realtime_wavelet.hpp>

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
