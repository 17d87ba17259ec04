// The gyro monitor (include/gyrodrift/imu/gyro_monitor.hpp) and its place in the processor:
// its streaming curve is StreamingAllan over the good samples only, it allocates nothing, a
// processor built without it is unchanged, a processor with it (re-identification off) gives
// the same outputs bit for bit, and a steady-state stage's retune carries its state.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/imu/gyro_monitor.hpp>
#include <gyrodrift/imu/imu_processor.hpp>
#include <type_traits>
#include <vector>

#include "alloc_counter.hpp"

namespace {

// Deterministic white noise uniform(-a, a) around a bias, from an LCG.
struct Noise {
  std::uint64_t s;
  double bias;
  double a;
  double next() noexcept {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u = static_cast<double>(s >> 11) * 0x1.0p-53 * 2.0 - 1.0;
    return bias + a * u;
  }
};

template <class Scalar, std::size_t O>
gyrodrift::HealthReference<Scalar, O> white_reference(Scalar r, std::size_t octaves) {
  gyrodrift::HealthReference<Scalar, O> ref{};
  ref.octaves = octaves;
  for (std::size_t k = 0; k < octaves; ++k) ref.avar[k] = r / static_cast<Scalar>(std::uint64_t{1} << k);
  return ref;
}

template <class Scalar>
gyrodrift::GyroMonitorSettings<Scalar> settings(std::size_t octaves, bool reidentify) {
  gyrodrift::GyroMonitorSettings<Scalar> s;
  s.sample_rate_hz = Scalar(400);
  s.octaves = octaves;
  s.alarms.stuck_samples = 200;
  s.alarms.saturated_samples = 200;
  s.reidentify = reidentify;
  return s;
}

}  // namespace

TEST_CASE("the curve is the streaming Allan variance of the good samples") {
  constexpr std::size_t kOct = 12;
  gyrodrift::GyroMonitor<double, kOct> mon;
  const gyrodrift::DriftModelParams<double> model{0.0, 0.0, 0.0, 1e-8, 0.0};
  REQUIRE(mon.configure(settings<double>(kOct, false), model, white_reference<double, kOct>(1e-8, kOct)) ==
          gyrodrift::GyroMonitorStatus::ok);
  gyrodrift::StreamingAllan<double, kOct> sa;
  REQUIRE(sa.configure(400.0, kOct));
  Noise n{7, 1e-3, 1e-4};
  for (std::size_t i = 0; i < 40000; ++i) {
    double y = n.next();
    const bool stuck = i % 1000 < 3;
    const bool saturated = i % 777 == 5;
    if (i % 5000 == 17) y = std::nan("");
    mon.push(y, stuck, saturated);
    if (!stuck && !saturated && std::isfinite(y)) sa.push(y);
  }
  CHECK(mon.samples() == 40000);
  CHECK(mon.used() == sa.samples());
  for (std::size_t k = 0; k < kOct; ++k) {
    double a = 0.0, b = 0.0;
    REQUIRE(mon.allan().avar(k, a));
    REQUIRE(sa.avar(k, b));
    CHECK(a == b);  // the same object fed the same samples: bit-identical
  }
}

TEST_CASE("configure refuses bad settings, references and models") {
  constexpr std::size_t kOct = 8;
  gyrodrift::GyroMonitor<float, kOct> mon;
  const gyrodrift::DriftModelParams<float> ok{0.5F, 0.0F, 1e-10F, 1e-8F, 0.0F};
  const auto ref = white_reference<float, kOct>(1e-8F, kOct);
  CHECK(mon.configure(settings<float>(kOct + 1, false), ok, ref) == gyrodrift::GyroMonitorStatus::bad_settings);
  auto zero = ref;
  zero.avar[3] = 0.0F;
  CHECK(mon.configure(settings<float>(kOct, false), ok, zero) == gyrodrift::GyroMonitorStatus::bad_settings);
  const gyrodrift::DriftModelParams<float> unit_root{1.0F, 0.0F, 1e-10F, 1e-8F, 0.0F};
  CHECK(mon.configure(settings<float>(kOct, false), unit_root, ref) == gyrodrift::GyroMonitorStatus::bad_model);
  CHECK(mon.push(1.0F, false, false) == 0);  // unconfigured: nothing happens
  CHECK(mon.samples() == 0);
  CHECK(mon.configure(settings<float>(kOct, true), ok, ref) == gyrodrift::GyroMonitorStatus::ok);
}

TEST_CASE("no allocation: monitor and monitored processor") {
  constexpr std::size_t kOct = 16;
  std::vector<float> y(50000);
  Noise n{9, 0.0, 1e-4};
  for (auto& v : y) v = static_cast<float>(n.next());
  using Proc = gyrodrift::ImuProcessor<float, gyrodrift::NoWavelet<float>, gyrodrift::kImuChannels, kOct>;
  gyrodrift::ImuConfig<float> cfg;
  for (std::size_t c = 0; c < 3; ++c) {
    cfg.channels[c].filter = gyrodrift::ChannelFilter::ar2_kalman;
    cfg.channels[c].steady_state = true;
    cfg.channels[c].model = gyrodrift::Ar2Model<float>{0.5F, 0.0F, 1e-10F, 0.0F};
    cfg.channels[c].q = 1e-10F;
    cfg.channels[c].r = 1e-8F;
  }
  static Proc proc(cfg);  // static: a firmware-sized object, off the test's stack
  static gyrodrift::GyroMonitor<float, kOct> mon;
  std::array<Proc::MonitorReference, 3> refs{};
  for (auto& r : refs) r = white_reference<float, kOct>(1e-8F, kOct);
  gyrodrift::test::AllocationScope scope;
  const bool ok1 = mon.configure(settings<float>(kOct, true), {0.5F, 0.0F, 1e-10F, 1e-8F, 0.0F}, refs[0]) ==
                   gyrodrift::GyroMonitorStatus::ok;
  for (float v : y) mon.push(v, false, false);
  gyrodrift::NoiseEstimates<float> est{};
  mon.noise(0.95F, est);
  const bool ok2 = proc.configure_monitor(settings<float>(kOct, true), refs, {true, true, true}) ==
                   gyrodrift::GyroMonitorStatus::ok;
  gyrodrift::ImuSample<float> in{};
  gyrodrift::ImuOutput<float> out{};
  for (std::size_t i = 0; i < y.size(); ++i) {
    in.seq = static_cast<std::uint16_t>(i);
    in.t_us = 2500ULL * i;
    for (std::size_t c = 0; c < 3; ++c) in.values[c] = y[(i + 1000 * c) % y.size()];
    proc.step(in, out);
  }
  const long allocations = scope.allocations();
  CHECK(ok1);
  CHECK(ok2);
  CHECK(proc.status() == gyrodrift::ImuStatus::ok);
  CHECK(allocations == 0);
}

TEST_CASE("without the monitor the processor pays nothing; with it (no retune) outputs are unchanged") {
  static_assert(std::is_empty_v<gyrodrift::detail::ImuMonitorBank<float, 0, 3>>, "no monitor: no bytes");
  static_assert(sizeof(gyrodrift::ImuProcessor<float>) ==
                    sizeof(gyrodrift::ImuProcessor<float, gyrodrift::NoWavelet<float>, gyrodrift::kImuChannels, 0>),
                "the default is the build without the monitor");
  constexpr std::size_t kOct = 10;
  using Plain = gyrodrift::ImuProcessor<float>;
  using Watched = gyrodrift::ImuProcessor<float, gyrodrift::NoWavelet<float>, gyrodrift::kImuChannels, kOct>;
  gyrodrift::ImuConfig<float> cfg;
  for (std::size_t c = 0; c < 3; ++c) {
    cfg.channels[c].filter = gyrodrift::ChannelFilter::ar2_kalman;
    cfg.channels[c].steady_state = c != 1;
    cfg.channels[c].model = gyrodrift::Ar2Model<float>{1.2F, -0.3F, 1e-10F, 1e-3F};
    cfg.channels[c].q = 1e-10F;
    cfg.channels[c].r = 1e-8F;
    cfg.channels[c].stuck_samples = 5;
    cfg.channels[c].saturation = 0.5F;
  }
  Plain plain(cfg);
  static Watched watched(cfg);
  std::array<Watched::MonitorReference, 3> refs{};
  for (auto& r : refs) r = white_reference<float, kOct>(1e-8F, kOct);
  REQUIRE(watched.configure_monitor(settings<float>(kOct, false), refs, {true, false, true}) ==
          gyrodrift::GyroMonitorStatus::ok);
  Noise n{3, 1e-3, 1e-4};
  gyrodrift::ImuSample<float> in{};
  gyrodrift::ImuOutput<float> a{}, b{};
  for (std::size_t i = 0; i < 20000; ++i) {
    in.seq = static_cast<std::uint16_t>(i);
    in.t_us = 2500ULL * i;
    for (std::size_t c = 0; c < 6; ++c) in.values[c] = static_cast<float>(n.next());
    if (i >= 5000 && i < 5300) in.values[0] = 0.25F;  // gx stuck
    if (i % 3000 == 7) in.values[2] = 1.0F;          // gz saturated
    const std::uint16_t fa = plain.step(in, a);
    const std::uint16_t fb = watched.step(in, b);
    CHECK((fb & ~gyrodrift::kFlagHealthAlarm) == fa);
    for (std::size_t c = 0; c < 6; ++c) CHECK(a.values[c] == b.values[c]);
  }
  CHECK(watched.monitor_active(0));
  CHECK(!watched.monitor_active(1));
  CHECK(watched.monitor(0).samples() == 20000);
  CHECK(watched.monitor(0).used() == 20000 - 296);  // the 5th to the 300th stuck value left out
  CHECK(watched.health().monitor_retunes == 0);
  // one slot: the image pays for one monitor, and it serves the channel it was given
  using One = gyrodrift::ImuProcessor<float, gyrodrift::NoWavelet<float>, gyrodrift::kImuChannels, kOct, 1>;
  static_assert(sizeof(One) < sizeof(Watched), "fewer slots, fewer bytes");
  static One one(cfg);
  CHECK(one.configure_monitor(settings<float>(kOct, false), refs, {true, false, true}) ==
        gyrodrift::GyroMonitorStatus::bad_settings);  // two channels, one slot
  REQUIRE(one.configure_monitor(settings<float>(kOct, false), refs, {false, false, true}) ==
          gyrodrift::GyroMonitorStatus::ok);
  CHECK(!one.monitor_active(0));
  CHECK(one.monitor_active(2));
  for (std::size_t i = 0; i < 1000; ++i) {
    in.seq = static_cast<std::uint16_t>(i);
    in.t_us = 2500ULL * i;
    for (std::size_t c = 0; c < 6; ++c) in.values[c] = static_cast<float>(n.next());
    one.step(in, b);
  }
  CHECK(one.monitor(2).samples() == 1000);
}

TEST_CASE("a steady-state retune carries the filtered rate and refuses bad models") {
  const gyrodrift::Ar2Model<double> m{1.2, -0.3, 1e-10, 1e-3};
  gyrodrift::Ar2SteadyStateKalman<double> f(m, 1e-10, 1e-8), g(m, 1e-10, 1e-8);
  Noise n{5, 1e-3, 1e-4};
  for (int i = 0; i < 1000; ++i) {
    const double y = n.next();
    f.step(y);
    g.step(y);
  }
  // the same model and gain: nothing changes, bit for bit
  REQUIRE(g.retune(1.2, -0.3, 1e-3, f.gain()(0), f.gain()(1)));
  for (int i = 0; i < 100; ++i) {
    const double y = n.next();
    CHECK(f.step(y) == g.step(y));
  }
  // a new mean: the filtered rate (state + mean) stays where it was
  const double before0 = g.state()(0) + 1e-3, before1 = g.state()(1) + 1e-3;
  REQUIRE(g.retune(1.2, -0.3, 2e-3, 0.1, 0.05));
  CHECK(g.state()(0) + 2e-3 == doctest::Approx(before0).epsilon(1e-12));
  CHECK(g.state()(1) + 2e-3 == doctest::Approx(before1).epsilon(1e-12));
  CHECK(g.gain()(0) == 0.1);
  CHECK(!g.retune(1.0, 0.0, 0.0, 0.1, 0.05));           // unit root
  CHECK(!g.retune(1.2, -0.3, std::nan(""), 0.1, 0.05));  // mean not finite
  CHECK(!g.retune(1.2, -0.3, 0.0, INFINITY, 0.05));      // gain not finite
  CHECK(g.gain()(0) == 0.1);                             // refused: unchanged
}

TEST_CASE("a retune of the re-identification reaches the steady-state stage") {
  // gz: AR(1) drift a1 = 0.99, q four times the configured one; re-identification from 60 s on,
  // retunes every 10 s: the processor counts each retune its stage took
  constexpr std::size_t kOct = 12;
  using Watched = gyrodrift::ImuProcessor<float, gyrodrift::NoWavelet<float>, gyrodrift::kImuChannels, kOct, 1>;
  gyrodrift::ImuConfig<float> cfg;
  cfg.channels[0].filter = cfg.channels[1].filter = gyrodrift::ChannelFilter::pass_through;
  cfg.channels[2].filter = gyrodrift::ChannelFilter::ar2_kalman;
  cfg.channels[2].steady_state = true;
  cfg.channels[2].model = gyrodrift::Ar2Model<float>{0.99F, 0.0F, 1e-10F, 0.0F};
  cfg.channels[2].q = 1e-10F;
  cfg.channels[2].r = 1e-8F;
  static Watched proc(cfg);
  std::array<Watched::MonitorReference, 3> refs{};
  refs[2] = white_reference<float, kOct>(1e-8F, kOct);
  auto s = settings<float>(kOct, true);
  s.drift.block_samples = 400;
  s.drift.retune_blocks = 10;
  s.drift.min_samples = 24000;
  REQUIRE(proc.configure_monitor(s, refs, {false, false, true}) == gyrodrift::GyroMonitorStatus::ok);
  Noise w{11, 0.0, 1.0};
  double x = 0.0;
  gyrodrift::ImuSample<float> in{};
  gyrodrift::ImuOutput<float> out{};
  for (std::size_t i = 0; i < 160000; ++i) {  // 400 s
    x = 0.99 * x + 2e-5 * std::sqrt(3.0) * w.next();  // q = 4e-10 (uniform: variance a^2 / 3)
    in.seq = static_cast<std::uint16_t>(i);
    in.t_us = 2500ULL * i;
    in.values[2] = static_cast<float>(x + 1e-4 * std::sqrt(3.0) * w.next());  // r = 1e-8
    proc.step(in, out);
  }
  const auto& id = proc.monitor_identifier();
  const std::size_t slot = proc.monitor_slot(2);
  CHECK(id.channels() == 1);
  CHECK(id.retunes(slot) >= 1);
  CHECK(proc.health().monitor_retunes == id.retunes(slot));
  CHECK(proc.health().monitor_refused_retunes == id.refused_retunes(slot));
}

TEST_CASE("a stuck gyro does not stop the other gyros' re-identification") {
  // Three watched gyros sharing one re-identification in turns of one block; gx sticks at
  // 20 s (its values are then not used by its monitor, so they never reach the
  // re-identification). Its turn passes on after a block's worth of missed samples, and gy and
  // gz keep being re-identified and retuned: each of them takes about a third of the 400 s in
  // blocks (133 by the turns' schedule), where they stopped at the 7 they had when gx's turn
  // came while it was stuck.
  constexpr std::size_t kOct = 12;
  using Watched = gyrodrift::ImuProcessor<float, gyrodrift::NoWavelet<float>, gyrodrift::kImuChannels, kOct, 3>;
  gyrodrift::ImuConfig<float> cfg;
  for (std::size_t c = 0; c < 3; ++c) {
    cfg.channels[c].filter = gyrodrift::ChannelFilter::ar2_kalman;
    cfg.channels[c].steady_state = true;
    cfg.channels[c].model = gyrodrift::Ar2Model<float>{0.99F, 0.0F, 1e-10F, 0.0F};
    cfg.channels[c].q = 1e-10F;
    cfg.channels[c].r = 1e-8F;
    cfg.channels[c].stuck_samples = 50;
  }
  static Watched proc(cfg);
  std::array<Watched::MonitorReference, 3> refs{};
  for (auto& r : refs) r = white_reference<float, kOct>(1e-8F, kOct);
  auto s = settings<float>(kOct, true);
  s.drift.block_samples = 400;
  s.drift.retune_blocks = 10;
  s.drift.min_samples = 24000;
  REQUIRE(proc.configure_monitor(s, refs, {true, true, true}) == gyrodrift::GyroMonitorStatus::ok);
  Noise w{13, 0.0, 1.0};
  double x[3] = {0.0, 0.0, 0.0};
  gyrodrift::ImuSample<float> in{};
  gyrodrift::ImuOutput<float> out{};
  const auto& id = proc.monitor_identifier();
  std::uint32_t gx_blocks_when_stuck = 0;
  for (std::size_t i = 0; i < 160000; ++i) {  // 400 s at 400 Hz
    for (std::size_t c = 0; c < 3; ++c) {
      x[c] = 0.99 * x[c] + 2e-5 * std::sqrt(3.0) * w.next();  // q = 4e-10
      in.values[c] = static_cast<float>(x[c] + 1e-4 * std::sqrt(3.0) * w.next());  // r = 1e-8
    }
    if (i >= 8000) in.values[0] = 1e-3F;  // gx stuck from 20 s on
    if (i == 8000) gx_blocks_when_stuck = id.blocks(proc.monitor_slot(0));
    in.seq = static_cast<std::uint16_t>(i);
    in.t_us = 2500ULL * i;
    proc.step(in, out);
  }
  CHECK(proc.health().stuck_values > 0);
  CHECK(id.blocks(proc.monitor_slot(0)) == gx_blocks_when_stuck);  // no block from stuck values
  for (std::size_t c = 1; c < 3; ++c) {
    CAPTURE(c);
    const std::size_t slot = proc.monitor_slot(c);
    CHECK(id.blocks(slot) >= 130);
    CHECK(id.retunes(slot) >= 1);
  }
  CHECK(proc.health().monitor_retunes == id.retunes(1) + id.retunes(2));
}

TEST_CASE("a monitor built without the re-identification equals one with it off, and refuses it") {
  constexpr std::size_t kOct = 12;
  using Lean = gyrodrift::GyroMonitor<float, kOct, false>;
  using Full = gyrodrift::GyroMonitor<float, kOct, true>;
  static_assert(sizeof(Lean) + sizeof(gyrodrift::OnlineDriftIdentifier<float>) <= sizeof(Full) + 8,
                "the lean monitor holds no identifier state");
  const gyrodrift::DriftModelParams<float> model{0.5F, 0.0F, 1e-10F, 1e-8F, 0.0F};
  auto ref = white_reference<float, kOct>(1e-8F, kOct);
  ref.avar[6] *= 0.1F;  // a reference the noise exceeds tenfold at one octave: alarms to compare
  static Lean lean;
  static Full full;
  CHECK(lean.configure(settings<float>(kOct, true), model, ref) == gyrodrift::GyroMonitorStatus::bad_settings);
  REQUIRE(lean.configure(settings<float>(kOct, false), model, ref) == gyrodrift::GyroMonitorStatus::ok);
  REQUIRE(full.configure(settings<float>(kOct, false), model, ref) == gyrodrift::GyroMonitorStatus::ok);
  CHECK_FALSE(lean.reidentifying());
  Noise n{11, 0.0, 3e-4};  // variance 3e-8: 3x the reference, 30x at octave 6
  for (std::size_t i = 0; i < 30000; ++i) {
    const float y = static_cast<float>(n.next());
    const bool stuck = i % 4000 < 2;
    CHECK(lean.push(y, stuck, false) == full.push(y, stuck, false));
  }
  CHECK(lean.latched() != 0);  // the comparison saw a raised alarm
  for (std::size_t k = 0; k < kOct; ++k) {
    float a = 0.0F, b = 0.0F;
    REQUIRE(lean.allan().avar(k, a));
    REQUIRE(full.allan().avar(k, b));
    CHECK(a == b);  // the same code on the same samples: bit-identical
  }
  for (std::size_t i = 0; i < gyrodrift::kHealthAlarmCount; ++i) {
    CHECK(lean.alarms().raised(i) == full.alarms().raised(i));
    CHECK(lean.alarms().exceedances(i) == full.alarms().exceedances(i));
  }
}

TEST_CASE("a monitor without records (the processor's) raises the same alarms at the same samples") {
  // Records false: no trips or counts, the reference read in place; the alarm bits after every
  // sample equal the full monitor's, whose trips say when each was raised.
  constexpr std::size_t kOct = 12;
  using Bare = gyrodrift::GyroMonitor<float, kOct, false, false>;
  using Full = gyrodrift::GyroMonitor<float, kOct, false, true>;
  static_assert(sizeof(Bare) + sizeof(gyrodrift::HealthReference<float, kOct>) <= sizeof(Full),
                "no copy of the reference, no trips");
  const gyrodrift::DriftModelParams<float> model{0.5F, 0.0F, 1e-10F, 1e-8F, 0.0F};
  auto ref = white_reference<float, kOct>(1e-8F, kOct);
  ref.avar[6] *= 0.1F;  // the noise exceeds it tenfold at octave 6
  ref.avar[9] *= 0.3F;  // and threefold at octave 9: a second alarm kind later
  static Bare bare;
  static Full full;
  auto s = settings<float>(kOct, false);
  s.alarms.saturated_samples = 3;
  REQUIRE(bare.configure(s, model, ref) == gyrodrift::GyroMonitorStatus::ok);
  REQUIRE(full.configure(s, model, ref) == gyrodrift::GyroMonitorStatus::ok);
  Noise n{17, 0.0, 3e-4};
  std::uint16_t seen = 0;
  for (std::size_t i = 0; i < 60000; ++i) {
    const float y = static_cast<float>(n.next());
    const bool sat = i % 7000 < 4;
    const std::uint16_t b = bare.push(y, false, sat);
    REQUIRE(b == full.push(y, false, sat));
    if ((b & ~seen) != 0) {  // a newly raised alarm: the full monitor's trip is this sample
      for (std::size_t a = 0; a < gyrodrift::kHealthAlarmCount; ++a) {
        if ((b & ~seen & gyrodrift::kHealthAlarmNames[a].bit) != 0) CHECK(full.alarms().trip(a).sample == i + 1);
      }
      seen = b;
    }
  }
  CHECK((seen & gyrodrift::kAlarmSaturated) != 0);
  CHECK((seen & ~gyrodrift::kAlarmSaturated) != 0);  // an octave alarm too
  CHECK(bare.samples() == full.samples());
  CHECK(bare.used() == full.used());
  CHECK(&bare.alarms().reference() == &ref);  // read in place
  CHECK(&bare.alarms().settings() == &s.alarms);  // so are the alarms' settings
  CHECK(&full.alarms().settings() != &s.alarms);  // the full monitor's are a copy
}
