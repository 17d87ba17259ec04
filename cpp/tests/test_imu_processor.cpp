// ImuProcessor: allocation-free and noexcept step, determinism (bit-identical runs), health
// counters, rejected frames leave no trace, wavelet stage equals a standalone RealtimeWavelet,
// configuration errors reject everything. Numerical agreement with the numpy reference is
// tested from Python (tests/test_imu_processor.py).
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include "alloc_counter.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <gyrodrift/filters/ar2_steady_state.hpp>
#include <gyrodrift/filters/fir_prefilter.hpp>
#include <gyrodrift/filters/realtime_wavelet.hpp>
#include <gyrodrift/imu/imu_processor.hpp>
#include <limits>
#include <random>
#include <vector>

using namespace gyrodrift;

namespace {

template <class Scalar>
ImuConfig<Scalar> test_config() {
  ImuConfig<Scalar> cfg;
  for (std::size_t c = 0; c < 3; ++c) {
    auto& cc = cfg.channels[c];
    cc.filter = ChannelFilter::ar2_kalman;
    cc.model = Ar2Model<Scalar>{Scalar(1.6), Scalar(-0.65), Scalar(1e-10), Scalar(1e-5)};
    cc.q = Scalar(1e-10);
    cc.r = Scalar(1e-9);
  }
  cfg.channels[3].filter = ChannelFilter::bias_removal;
  cfg.channels[3].bias = Scalar(0.02);
  cfg.channels[4].saturation = Scalar(50);
  cfg.channels[4].stuck_samples = 4;
  return cfg;
}

// AR(2) gyro drift plus white noise, static accelerometers; seeded, so reproducible.
template <class Scalar>
std::vector<ImuSample<Scalar>> record(std::size_t n, unsigned seed) {
  std::mt19937_64 gen(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<ImuSample<Scalar>> out(n);
  std::array<double, 3> x1{}, x2{};
  for (std::size_t k = 0; k < n; ++k) {
    out[k].seq = static_cast<std::uint16_t>(k);
    out[k].t_us = std::uint64_t{kImuDefaultPeriodUs} * k;  // on the default period's grid
    for (std::size_t c = 0; c < 3; ++c) {
      const double x = 1.6 * x1[c] - 0.65 * x2[c] + 1e-5 * noise(gen);
      x2[c] = x1[c];
      x1[c] = x;
      out[k].values[c] = static_cast<Scalar>(1e-5 + x + 3e-5 * noise(gen));
    }
    for (std::size_t c = 3; c < 6; ++c) {
      out[k].values[c] = static_cast<Scalar>((c == 5 ? 9.81 : 0.0) + 0.01 * noise(gen));
    }
  }
  return out;
}

template <class Scalar>
std::vector<ImuOutput<Scalar>> run(ImuProcessor<Scalar>& p, const std::vector<ImuSample<Scalar>>& in,
                                   std::vector<std::uint16_t>* flags = nullptr) {
  std::vector<ImuOutput<Scalar>> out;
  out.reserve(in.size());
  ImuOutput<Scalar> y;
  for (const auto& s : in) {
    const std::uint16_t f = p.step(s, y);
    if (flags != nullptr) flags->push_back(f);
    if ((f & kFlagRejected) == 0) out.push_back(y);
  }
  return out;
}

}  // namespace

static_assert(noexcept(std::declval<ImuProcessor<float>&>().step(std::declval<const ImuSample<float>&>(),
                                                                  std::declval<ImuOutput<float>&>())),
              "step must be noexcept");

TEST_CASE_TEMPLATE("step is allocation-free", Scalar, float, double) {
  const auto in = record<Scalar>(2000, 1);
  ImuProcessor<Scalar> p(test_config<Scalar>());
  REQUIRE(p.status() == ImuStatus::ok);
  ImuOutput<Scalar> y;
  Scalar sink = Scalar(0);
  long allocations = 0;
  {
    gyrodrift::test::AllocationScope scope;
    for (const auto& s : in) {
      p.step(s, y);
      sink += y.values[0];
    }
    p.reset();
    allocations = scope.allocations();
  }
  CHECK(allocations == 0);
  CHECK(std::isfinite(sink));
}

TEST_CASE_TEMPLATE("deterministic: two processors and a reset give bit-identical output", Scalar, float, double) {
  auto in = record<Scalar>(3000, 2);
  in[100].values[1] = std::numeric_limits<Scalar>::quiet_NaN();
  in[200].seq = in[199].seq;  // duplicate
  ImuProcessor<Scalar> a(test_config<Scalar>());
  ImuProcessor<Scalar> b(test_config<Scalar>());
  const auto ya = run(a, in);
  const auto yb = run(b, in);
  a.reset();
  const auto yc = run(a, in);
  REQUIRE(ya.size() == yb.size());
  REQUIRE(ya.size() == yc.size());
  for (std::size_t k = 0; k < ya.size(); ++k) {
    CHECK(std::memcmp(ya[k].values.data(), yb[k].values.data(), sizeof(Scalar) * 6) == 0);
    CHECK(std::memcmp(ya[k].values.data(), yc[k].values.data(), sizeof(Scalar) * 6) == 0);
    CHECK(ya[k].flags == yc[k].flags);
  }
}

TEST_CASE("health counters") {
  auto in = record<double>(200, 3);
  in[10].values[0] = std::numeric_limits<double>::infinity();
  in[20].values[4] = 60.0;  // saturation 50
  for (std::size_t k = 30; k < 36; ++k) in[k].values[4] = 0.125;  // 6 equal: 3 stuck (4th..6th)
  in[40].t_us += 5000;                                              // time jump at 40 and 41
  in[50].seq = in[49].seq;  // duplicate (rejected), so seq 50 is missing: gap at 51
  in[60].seq = static_cast<std::uint16_t>(in[60].seq + 2);  // gap 59 -> 62 at 60, and its
                                                            // time is 2 periods early: jump
  in[61].seq = in[59].seq;  // late frames (rejected)
  in[62].seq = in[59].seq;  // index 63 (seq 63) follows seq 62 but 3 periods later: jump
  ImuProcessor<double> p(test_config<double>());
  std::vector<std::uint16_t> flags;
  const auto out = run(p, in, &flags);
  const ImuHealth& h = p.health();
  CHECK(h.samples_in == 200);
  CHECK(h.non_finite_samples == 1);
  CHECK(h.non_finite_values == 1);
  CHECK(h.saturated_values == 1);
  CHECK(h.stuck_values == 3);
  CHECK(h.time_jumps == 4);  // 40, 41, 60, 63
  CHECK(h.duplicates == 1);
  CHECK(h.seq_gaps == 2);  // at 51 and at 60
  CHECK(h.missing_samples == 1 + 2);
  CHECK(h.out_of_order == 2);
  CHECK(h.samples_accepted == 200 - 3);
  CHECK(flags[10] == kFlagNonFinite);
  CHECK(flags[20] == kFlagSaturated);
  CHECK((flags[33] & kFlagStuck) != 0);
  CHECK((flags[32] & kFlagStuck) == 0);
  CHECK(flags[50] == (kFlagDuplicate | kFlagRejected));
  CHECK(flags[51] == kFlagSeqGap);
  CHECK(flags[60] == (kFlagSeqGap | kFlagTimeJump));
  CHECK(flags[63] == kFlagTimeJump);
  CHECK(flags[61] == (kFlagOutOfOrder | kFlagRejected));
  for (const auto& y : out) {
    for (double v : y.values) CHECK(std::isfinite(v));
  }
}

TEST_CASE("resync after a source restart") {
  auto in = record<double>(120, 4);
  for (std::size_t k = 100; k < 120; ++k) in[k].seq = static_cast<std::uint16_t>(k - 100);
  ImuProcessor<double> p(test_config<double>());
  std::vector<std::uint16_t> flags;
  run(p, in, &flags);
  CHECK(p.health().out_of_order == ImuProcessor<double>::kResyncAfter - 1);
  CHECK(p.health().seq_resyncs == 1);
  CHECK(flags[100 + ImuProcessor<double>::kResyncAfter - 1] == kFlagResync);
  CHECK(flags[119] == 0);
}

TEST_CASE("rejected frames leave no trace in the filters") {
  const auto clean = record<double>(300, 5);
  auto dirty = clean;
  ImuSample<double> garbage = clean[99];
  for (auto& v : garbage.values) v = 1e30;
  dirty.insert(dirty.begin() + 100, garbage);  // duplicate seq with garbage values
  ImuProcessor<double> a(test_config<double>());
  ImuProcessor<double> b(test_config<double>());
  const auto ya = run(a, clean);
  const auto yb = run(b, dirty);
  REQUIRE(ya.size() == yb.size());
  for (std::size_t k = 0; k < ya.size(); ++k) CHECK(ya[k].values == yb[k].values);
}

TEST_CASE("wavelet stage equals a standalone RealtimeWavelet; NaN is skipped") {
  using W = RealtimeWavelet<double, 64>;
  ImuConfig<double> cfg;
  for (auto& cc : cfg.channels) cc.filter = ChannelFilter::wavelet;
  cfg.channels[2].bias = 0.5;
  auto in = record<double>(300, 6);
  in[150].values[2] = std::numeric_limits<double>::quiet_NaN();
  ImuProcessor<double, W> p(cfg, W(WaveletKind::db8, 2, WaveletMode::forced));
  REQUIRE(p.status() == ImuStatus::ok);
  std::array<W, 6> ref = {W(WaveletKind::db8, 2), W(WaveletKind::db8, 2), W(WaveletKind::db8, 2),
                          W(WaveletKind::db8, 2), W(WaveletKind::db8, 2), W(WaveletKind::db8, 2)};
  ImuOutput<double> y;
  for (const auto& s : in) {
    p.step(s, y);
    for (std::size_t c = 0; c < 6; ++c) {
      const double expected = ref[c].step(s.values[c]) - cfg.channels[c].bias;
      CHECK(y.values[c] == expected);
    }
  }
  // The default NoWavelet cannot serve a wavelet channel: configuration error.
  ImuProcessor<double> no(cfg);
  CHECK(no.status() == ImuStatus::wavelet_unavailable);
  ImuProcessor<double, W> bad_level(cfg, W(WaveletKind::db8, 9));
  CHECK(bad_level.status() == ImuStatus::wavelet_unavailable);
}

TEST_CASE("invalid configuration rejects every sample") {
  ImuConfig<float> cfg;  // gyro models not set
  ImuProcessor<float> p(cfg);
  CHECK(p.status() == ImuStatus::bad_channel_config);
  CHECK(p.bad_channel() == 0);
  ImuSample<float> s;
  ImuOutput<float> y;
  y.seq = 77;
  CHECK(p.step(s, y) == (kFlagConfigError | kFlagRejected));
  CHECK(y.seq == 77);  // not written
  CHECK(p.health().config_rejected == 1);
  auto cfg2 = test_config<float>();
  cfg2.channels[5].saturation = -1.0F;
  CHECK(ImuProcessor<float>(cfg2).status() == ImuStatus::bad_channel_config);
  auto cfg4 = test_config<float>();
  cfg4.period_us = 0;
  CHECK(ImuProcessor<float>(cfg4).status() == ImuStatus::bad_timing);
  cfg4.time_tolerance_us = 0;  // check off: a zero period is fine
  CHECK(ImuProcessor<float>(cfg4).status() == ImuStatus::ok);
  auto cfg3 = test_config<float>();
  cfg3.channels[1].model.a1 = 2.5F;  // non-stationary
  ImuProcessor<float> p3(cfg3);
  CHECK(p3.status() == ImuStatus::bad_channel_config);
  CHECK(p3.bad_channel() == 1);
}

// FirPrefilter (flash taps, one circular window) is RealtimeWavelet's forced mode
// bit for bit when given its taps; NaN skipped the same way.
TEST_CASE("FirPrefilter equals RealtimeWavelet forced bit for bit") {
  using W = RealtimeWavelet<float, 64>;
  W rt(WaveletKind::db4, 3);
  FirPrefilter<float, 64> fir(rt.taps());
  REQUIRE(fir.status() == FirPrefilterStatus::ok);
  std::mt19937 gen(7);
  std::normal_distribution<float> d(0.5f, 0.1f);
  for (int k = 0; k < 500; ++k) {
    const float x = (k % 97 == 50) ? std::numeric_limits<float>::quiet_NaN() : d(gen);
    const float a = rt.step(x), b = fir.step(x);
    REQUIRE(std::memcmp(&a, &b, sizeof a) == 0);
  }
  CHECK(fir.fault_count() == rt.fault_count());
  CHECK(FirPrefilter<float, 64>().status() == FirPrefilterStatus::no_taps);
}

// The chain wavelet -> steady-state AR(2)-Kalman equals the two filters run by hand,
// a missing value is "missing" for the second stage, and the wavelet exists only on the first
// WaveletChannels channels (asking for it on channel 3 of a 3-channel build is refused).
TEST_CASE("chain wavelet -> steady-state Kalman; WaveletChannels") {
  using W = RealtimeWavelet<float, 64, false>;
  ImuConfig<float> cfg;
  for (auto& cc : cfg.channels) cc.filter = ChannelFilter::pass_through;
  auto& g = cfg.channels[0];
  g.filter = ChannelFilter::wavelet;
  g.filter2 = ChannelFilter::ar2_kalman;
  g.steady_state = true;
  g.model = Ar2Model<float>{0.6868f, -0.0213f, 0.01f, 0.5f};
  g.q = 0.01f;
  g.r = 0.02f;
  ImuProcessor<float, W, 3> p(cfg, W(WaveletKind::db4, 3));
  REQUIRE(p.status() == ImuStatus::ok);
  W w(WaveletKind::db4, 3);
  Ar2SteadyStateKalman<float> kf(g.model, g.q, g.r);
  ImuSample<float> s;
  ImuOutput<float> y;
  std::mt19937 gen(3);
  std::normal_distribution<float> d(0.5f, 0.1f);
  for (std::uint16_t k = 0; k < 300; ++k) {
    s.seq = k;
    s.t_us = std::uint64_t{kImuDefaultPeriodUs} * static_cast<std::uint64_t>(k);
    s.values.fill(1.0f);
    s.values[0] = (k == 150) ? std::numeric_limits<float>::quiet_NaN() : d(gen);
    p.step(s, y);
    const float pre = w.step(s.values[0]);
    const float want = kf.step(std::isfinite(s.values[0]) ? pre : std::numeric_limits<float>::quiet_NaN());
    REQUIRE(std::memcmp(&want, &y.values[0], sizeof want) == 0);
  }
  cfg.channels[3].filter = ChannelFilter::wavelet;
  ImuProcessor<float, W, 3> q(cfg, W(WaveletKind::db4, 3));
  CHECK(q.status() == ImuStatus::wavelet_unavailable);
  CHECK(q.bad_channel() == 3);
  cfg.channels[3].filter = ChannelFilter::pass_through;
  cfg.channels[0].filter2 = ChannelFilter::wavelet;  // a stage twice
  ImuProcessor<float, W, 3> r(cfg, W(WaveletKind::db4, 3));
  CHECK(r.status() == ImuStatus::bad_channel_config);
}
