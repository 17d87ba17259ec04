// Lifting transform vs a direct periodized convolution with PyWavelets' filter taps
// (independent oracle), perfect reconstruction, Parseval, float accuracy, bad arguments.
// Tolerances: double 1e-12 absolute on unit-variance data (observed ~1e-15); float 4x the
// direct float convolution's error against the double oracle.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <gyrodrift/filters/lifting_transform.hpp>

#include "wavelet_test_support.hpp"

using gyrodrift::LiftingTransform;
using gyrodrift::WaveletKind;

namespace {

std::vector<double> noise(std::size_t n, std::uint64_t seed) {
  wavelet_test::Noise g;
  g.s += seed;
  std::vector<double> x(n);
  for (auto& v : x) v = g.normal();
  return x;
}

double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::fabs(a[i] - b[i]));
  return m;
}

}  // namespace

TEST_CASE("forward equals the direct periodized convolution, inverse reconstructs") {
  for (WaveletKind w : {WaveletKind::db4, WaveletKind::db8}) {
    for (auto [n, levels] : {std::pair<std::size_t, int>{2, 1}, {16, 4}, {64, 1}, {96, 5}, {512, 5}, {1024, 8}}) {
      CAPTURE(n);
      CAPTURE(levels);
      const auto x = noise(n, n);
      auto c = x;
      std::vector<double> scratch(n);
      REQUIRE(LiftingTransform<double>::forward(w, c.data(), n, levels, scratch.data()));
      CHECK(max_abs_diff(c, wavelet_test::direct_wavedec(w, x, levels)) < 1e-12);
      double ex = 0.0, ec = 0.0;  // orthogonal transform: energy preserved (Parseval)
      for (std::size_t i = 0; i < n; ++i) {
        ex += x[i] * x[i];
        ec += c[i] * c[i];
      }
      CHECK(std::fabs(ex - ec) < 1e-12 * ex);
      REQUIRE(LiftingTransform<double>::inverse(w, c.data(), n, levels, scratch.data()));
      CHECK(max_abs_diff(c, x) < 1e-12);
    }
  }
}

TEST_CASE("float lifting error is within 4x the direct float convolution") {
  for (WaveletKind w : {WaveletKind::db4, WaveletKind::db8}) {
    const std::size_t n = 4096;
    const auto x = noise(n, 7);
    const auto exact = wavelet_test::direct_wavedec(w, x, 5);
    std::vector<float> xf(x.begin(), x.end()), scratch(n);
    const auto direct = wavelet_test::direct_wavedec(w, xf, 5);
    REQUIRE(LiftingTransform<float>::forward(w, xf.data(), n, 5, scratch.data()));
    double err_lift = 0.0, err_direct = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      err_lift = std::max(err_lift, std::fabs(static_cast<double>(xf[i]) - exact[i]));
      err_direct = std::max(err_direct, std::fabs(static_cast<double>(direct[i]) - exact[i]));
    }
    CAPTURE(err_lift);
    CAPTURE(err_direct);
    CHECK(err_lift <= 4.0 * err_direct);
    CHECK(err_lift < 2e-5);
  }
}

TEST_CASE("bad arguments are refused and leave the data untouched") {
  std::vector<double> x(100, 1.0), scratch(100);
  CHECK_FALSE(LiftingTransform<double>::forward(WaveletKind::db8, x.data(), 100, 3, scratch.data()));
  CHECK_FALSE(LiftingTransform<double>::forward(WaveletKind::db8, x.data(), 64, 0, scratch.data()));
  CHECK_FALSE(LiftingTransform<double>::forward(WaveletKind::db8, x.data(), 64, 9, scratch.data()));
  CHECK_FALSE(LiftingTransform<double>::forward(WaveletKind::db8, nullptr, 64, 1, scratch.data()));
  CHECK_FALSE(LiftingTransform<double>::inverse(WaveletKind::db8, x.data(), 64, 1, nullptr));
  CHECK_FALSE(LiftingTransform<double>::forward_level(WaveletKind::db4, x.data(), 7, scratch.data()));
  CHECK(std::all_of(x.begin(), x.end(), [](double v) { return v == 1.0; }));
}
