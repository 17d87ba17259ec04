// RealtimeWavelet: streaming forced FIR == full-window recompute, start-up pass-through,
// NaN/Inf counting, threshold modes against an independent recompute built from the direct
// convolution oracle, configuration status. Tolerance 1e-12 (double, unit-variance data).
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <gyrodrift/filters/realtime_wavelet.hpp>
#include <gyrodrift/filters/realtime_wavelet_noise.hpp>

#include "wavelet_test_support.hpp"

using gyrodrift::RealtimeWavelet;
using gyrodrift::RealtimeWaveletStatus;
using gyrodrift::WaveletKind;
using gyrodrift::WaveletMode;

namespace {

// Independent recompute of one window: direct-convolution analysis (oracle), thresholding
// as pywt, synthesis as the transpose of the orthogonal analysis matrix.
double oracle_window(const std::vector<double>& w, WaveletKind kind, int level, WaveletMode mode) {
  const std::size_t n = w.size(), n2 = 2 * n;
  std::vector<double> ext(n2);
  for (std::size_t i = 0; i < n; ++i) ext[i] = ext[n2 - 1 - i] = w[i];
  const auto c = wavelet_test::direct_wavedec(kind, ext, level);
  std::vector<double> ct = c;
  const std::size_t n_approx = n2 >> static_cast<unsigned>(level);
  std::vector<double> d1(c.begin() + static_cast<std::ptrdiff_t>(n), c.end());
  for (auto& v : d1) v = std::fabs(v);
  std::sort(d1.begin(), d1.end());
  const double sigma = 0.5 * (d1[n / 2 - 1] + d1[n / 2]) / 0.6745;
  const double t = sigma * std::sqrt(2.0 * std::log(static_cast<double>(n)));
  for (std::size_t i = n_approx; i < n2; ++i) {
    const double a = std::fabs(c[i]);
    if (mode == WaveletMode::forced) ct[i] = 0.0;
    else if (mode == WaveletMode::hard) ct[i] = a < t ? 0.0 : c[i];
    else ct[i] = a > t ? std::copysign(a - t, c[i]) : 0.0;
  }
  // Synthesis value at index n-1: row n-1 of F^T, i.e. sum_k ct[k] * F[k][n-1], where
  // column n-1 of F is the analysis of the unit vector e_{n-1}.
  std::vector<double> e(n2, 0.0);
  e[n - 1] = 1.0;
  const auto col = wavelet_test::direct_wavedec(kind, e, level);
  double y = 0.0;
  for (std::size_t k = 0; k < n2; ++k) y += ct[k] * col[k];
  return y;
}

}  // namespace

TEST_CASE("forced streaming FIR equals recompute and the oracle; start-up passes through") {
  constexpr std::size_t N = 64;
  RealtimeWavelet<double, N> f(WaveletKind::db8, 2, WaveletMode::forced);
  REQUIRE(f.status() == RealtimeWaveletStatus::ok);
  double tap_sum = 0.0;
  for (std::size_t i = 0; i < N; ++i) tap_sum += f.taps()[i];
  CHECK(std::fabs(tap_sum - 1.0) < 1e-12);
  wavelet_test::Noise g;
  std::vector<double> hist;
  for (int i = 0; i < 300; ++i) {
    const double x = g.normal() + 0.01 * i;
    hist.push_back(x);
    const double y = f.step(x);
    if (hist.size() < N) {
      CHECK(y == x);
      CHECK_FALSE(f.ready());
      continue;
    }
    CHECK(f.ready());
    std::vector<double> w(hist.end() - N, hist.end());
    RealtimeWavelet<double, N> r(WaveletKind::db8, 2, WaveletMode::forced);
    CHECK(std::fabs(y - r.recompute(w.data())) < 1e-12);
    if (i % 50 == 0) CHECK(std::fabs(y - oracle_window(w, WaveletKind::db8, 2, WaveletMode::forced)) < 1e-12);
  }
}

TEST_CASE("threshold modes equal the independent oracle") {
  constexpr std::size_t N = 32;
  for (WaveletMode mode : {WaveletMode::soft, WaveletMode::hard}) {
    RealtimeWavelet<double, N> f(WaveletKind::db4, 2, mode);
    wavelet_test::Noise g;
    std::vector<double> hist;
    for (int i = 0; i < 120; ++i) {
      const double x = g.normal();
      hist.push_back(x);
      const double y = f.step(x);
      if (hist.size() >= N) {
        std::vector<double> w(hist.end() - N, hist.end());
        CHECK(std::fabs(y - oracle_window(w, WaveletKind::db4, 2, mode)) < 1e-12);
      }
    }
  }
}

TEST_CASE("NaN and Inf are counted, skipped, and repeat the previous output") {
  constexpr std::size_t N = 16;
  RealtimeWavelet<double, N> a(WaveletKind::db4, 1), b(WaveletKind::db4, 1);
  CHECK(a.step(std::numeric_limits<double>::quiet_NaN()) == 0.0);  // before any output: 0
  wavelet_test::Noise g;
  double last = 0.0;
  for (int i = 0; i < 60; ++i) {
    const double x = g.normal();
    if (i % 7 == 3) {
      CHECK(a.step(std::numeric_limits<double>::infinity()) == last);
    }
    last = a.step(x);
    CHECK(last == b.step(x));
  }
  CHECK(a.fault_count() == 1 + 9);
  CHECK(b.fault_count() == 0);
  a.reset();
  CHECK(a.fault_count() == 0);
  CHECK_FALSE(a.ready());
}

TEST_CASE("bad configurations report a status and pass samples through") {
  RealtimeWavelet<double, 32> too_deep(WaveletKind::db8, 3);  // 15 * 2^3 > 64
  CHECK(too_deep.status() == RealtimeWaveletStatus::level_out_of_range);
  RealtimeWavelet<double, 32> zero(WaveletKind::db8, 0);
  CHECK(zero.status() == RealtimeWaveletStatus::level_out_of_range);
  for (int i = 0; i < 100; ++i) CHECK(too_deep.step(double(i)) == double(i));
  CHECK(gyrodrift::realtime_wavelet_max_level(256, WaveletKind::db8) == 5);
  CHECK(gyrodrift::realtime_wavelet_max_level(256, WaveletKind::db4) == 6);
  RealtimeWavelet<double, 256> ok(WaveletKind::db4, 5);
  CHECK(ok.status() == RealtimeWaveletStatus::ok);
}

TEST_CASE("copies are independent (value semantics for per-channel embedding)") {
  RealtimeWavelet<float, 32> a(WaveletKind::db4, 2, WaveletMode::soft);
  for (int i = 0; i < 40; ++i) a.step(static_cast<float>(i % 5));
  RealtimeWavelet<float, 32> b = a;
  for (int i = 0; i < 40; ++i) {
    const float x = static_cast<float>((i * 7) % 11);
    CHECK(a.step(x) == b.step(x));
  }
}

TEST_CASE("incremental median(|d1|) equals the sorted median of the oracle's d1, every step") {
  constexpr std::size_t N = 64;
  for (WaveletKind kind : {WaveletKind::db4, WaveletKind::db8}) {
    const auto& h = wavelet_test::rec_lo(kind);
    const std::size_t taps = h.size();
    std::vector<double> g(taps);
    for (std::size_t i = 0; i < taps; ++i) g[i] = (i % 2 == 0 ? 1.0 : -1.0) * h[taps - 1 - i];
    gyrodrift::SlidingDetailMedian<double, N> med;
    REQUIRE(med.configure(g.data(), taps));
    std::vector<double> buf(2 * N, 0.0), hist;
    std::size_t pos = 0;
    wavelet_test::Noise noise;
    for (int i = 0; i < 400; ++i) {
      const double x = noise.normal() * (1.0 + 0.5 * std::sin(0.05 * i));  // non-stationary
      hist.push_back(x);
      buf[pos] = buf[pos + N] = x;
      pos = (pos + 1) % N;
      const double got = med.update(&buf[pos]);
      if (hist.size() < N) continue;
      std::vector<double> ext(2 * N);
      for (std::size_t k = 0; k < N; ++k) ext[k] = ext[2 * N - 1 - k] = hist[hist.size() - N + k];
      const auto c = wavelet_test::direct_wavedec(kind, ext, 1);
      std::vector<double> d1(c.begin() + N, c.end());
      for (auto& v : d1) v = std::fabs(v);
      std::sort(d1.begin(), d1.end());
      CHECK(std::fabs(got - 0.5 * (d1[N / 2 - 1] + d1[N / 2])) < 1e-13);
    }
    med.reset();
    CHECK(med.update(buf.data()) == 0.0);  // not full after a reset
  }
}

TEST_CASE("median estimator refuses filters it cannot stream") {
  gyrodrift::SlidingDetailMedian<double, 16> med;
  const double g[16] = {};
  CHECK_FALSE(med.configure(g, 16));  // taps > N/2
  CHECK_FALSE(med.configure(g, 3));   // odd
  CHECK(med.update(g) == 0.0);        // unconfigured: inert
}

TEST_CASE("forced-only variant: same output as the full filter, 5N scalars of state") {
  using Lean = gyrodrift::RealtimeWavelet<float, 256, false>;
  using Full = gyrodrift::RealtimeWavelet<float, 256>;
  static Lean lean(WaveletKind::db4, 5);
  static Full full(WaveletKind::db4, 5);
  REQUIRE(lean.status() == RealtimeWaveletStatus::ok);
  for (std::size_t i = 0; i < 256; ++i) CHECK(lean.taps()[i] == full.taps()[i]);
  wavelet_test::Noise g;
  for (int i = 0; i < 700; ++i) {
    const float x = static_cast<float>(g.normal());
    CHECK(lean.step(x) == full.step(x));
  }
  // taps N + window 2N + scratch 2N, plus a few words of bookkeeping.
  CHECK(sizeof(Lean) <= 5 * 256 * sizeof(float) + 128);
  MESSAGE("per-channel state, float N=256: forced-only " << sizeof(Lean) << " B, full " << sizeof(Full) << " B");
  Lean soft(WaveletKind::db4, 5, WaveletMode::soft);
  CHECK(soft.status() == RealtimeWaveletStatus::bad_mode);
  CHECK(soft.step(3.0F) == 3.0F);
}
