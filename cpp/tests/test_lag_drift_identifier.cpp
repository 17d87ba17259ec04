// The re-identification from lag statistics (include/gyrodrift/filters/lag_drift_identifier.hpp):
// its schedule (staggered requests, paused statistics, the retune at the apply point), the
// model in use equal to the fit of the paused statistics, the guards (too few samples, a white
// record, truncation, the bounded step, the fallback), the fit with the AR part held, deferred
// fits (equal to inline when run in time; late ones discarded), refused configurations, the
// monitor and the processor built with it, no allocation, its size.
#define EIGEN_RUNTIME_NO_MALLOC
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/lag_drift_fit.hpp>
#include <gyrodrift/filters/lag_drift_identifier.hpp>
#include <gyrodrift/imu/gyro_monitor.hpp>
#include <gyrodrift/imu/imu_processor.hpp>
#include <vector>

#include "alloc_counter.hpp"
#include "drift_test_support.hpp"

namespace {

using gyrodrift::DriftModelParams;
using gyrodrift::LagDriftFitStatus;
using gyrodrift::LagDriftIdentifier;
using gyrodrift::LagDriftSettings;
using gyrodrift::OnlineDriftSettings;
using gyrodrift::OnlineDriftStatus;

// cadence 3000 samples, fits from 2000 statistics samples on, 500 samples from a request to
// its retune, steps unbounded in practice.
template <class Scalar = double>
OnlineDriftSettings<Scalar> lag_settings() {
  OnlineDriftSettings<Scalar> s;
  s.block_samples = 100;
  s.retune_blocks = 30;
  s.min_samples = 2000;
  s.max_step = Scalar(100);
  return s;
}
// The same without the identification guards (tests of the schedule, not of the guards).
template <class Scalar = double>
OnlineDriftSettings<Scalar> unguarded() {
  OnlineDriftSettings<Scalar> s = lag_settings<Scalar>();
  s.max_rel_stderr = Scalar(1e30);
  s.min_ar_wald = Scalar(0);
  return s;
}
// A well identified record: AR(2) drift (0.9, -0.2), q = 2, r = 1, mean 0.5 (every fit of its
// first 3000 samples is accepted by the default guards for the seeds used).
std::vector<double> strong(std::size_t n, std::uint64_t seed) {
  return drift_test::record(0.9, -0.2, 2.0, 1.0, 0.5, n, seed);
}

template <class Scalar = double>
LagDriftSettings<Scalar> schedule(std::uint32_t delay = 500, bool restart = false) {
  LagDriftSettings<Scalar> l;
  l.fit_delay_samples = delay;
  l.restart_after_fit = restart;
  return l;
}

double atanh_of(double p) { return 0.5 * std::log((1.0 + p) / (1.0 - p)); }

// (u1, u2, log q, log r) of a model.
std::array<double, 4> coords(const DriftModelParams<double>& m) {
  return {atanh_of(m.a1 / (1.0 - m.a2)), atanh_of(m.a2), std::log(m.q), std::log(m.r)};
}

bool same(const DriftModelParams<double>& a, const DriftModelParams<double>& b) {
  return a.a1 == b.a1 && a.a2 == b.a2 && a.q == b.q && a.r == b.r && a.mean == b.mean;
}

}  // namespace

TEST_CASE("schedule: staggered requests, paused statistics, the fit of those statistics applied after the delay") {
  constexpr std::size_t kN = 3;
  const std::vector<double> y[kN] = {drift_test::record(0.2297, 0.1638, 1.0, 1.0, 3.0, 12000, 1),
                                     drift_test::record(0.6868, -0.0213, 1.0, 3.0, -1.0, 12000, 2),
                                     drift_test::record(0.9, -0.2, 2.0, 1.0, 0.5, 12000, 3)};
  const DriftModelParams<double> cfg[kN] = {
      {0.18, 0.1, 1.5, 0.7, 0.0}, {0.5, 0.0, 1.0, 1.0, 0.0}, {0.7, 0.0, 1.0, 1.0, 0.0}};
  static LagDriftIdentifier<double, kN> id;
  REQUIRE(id.configure(cfg, kN, unguarded(), schedule()));
  CHECK(id.cadence() == 3000);
  for (std::size_t c = 0; c < kN; ++c) CHECK(id.next_request(c) == 3000 + 1000 * c);
  std::vector<std::uint64_t> retuned_at[kN];
  gyrodrift::LagStatisticsNoHead<double, gyrodrift::kLagIdentifierLags> at_request[kN];
  std::uint64_t requested_at[kN] = {};
  std::size_t accepted = 0;
  for (std::size_t i = 0; i < 12000; ++i) {
    std::size_t waiting = 0;
    for (std::size_t c = 0; c < kN; ++c) {
      const bool was_waiting = id.apply_at(c) != 0;
      id.push(c, y[c][i]);
      if (!was_waiting && id.apply_at(c) != 0) {  // requested at this sample
        at_request[c] = id.statistics(c);
        requested_at[c] = id.samples(c);
        CHECK(id.apply_at(c) == requested_at[c] + 500);
      }
      if (was_waiting && id.apply_at(c) == 0) {  // applied at this sample
        retuned_at[c].push_back(id.samples(c));
        // the model in use is the fit of the statistics as they were at the request (the
        // guards off: refused only for the fit's status)
        const auto fit = gyrodrift::lag_drift_fit<double>(at_request[c], gyrodrift::LagLikelihoodKind::whittle_no_head);
        CHECK(id.fit_status(c) == fit.status);
        if (fit.status != LagDriftFitStatus::ok) {
          CHECK(id.status(c) == OnlineDriftStatus::fallback);
          CHECK(same(id.in_use(c), cfg[c]));
          continue;
        }
        ++accepted;
        CHECK(id.retuned());
        CHECK(same(id.in_use(c), fit.model));
        CHECK(same(id.estimate(c), fit.model));
        CHECK(id.status(c) == OnlineDriftStatus::tracking);
        CHECK(id.fit_status(c) == LagDriftFitStatus::ok);
        const gyrodrift::Ar2SteadyStateKalman<double> kf(
            gyrodrift::Ar2Model<double>{fit.model.a1, fit.model.a2, fit.model.q, 0.0}, fit.model.q, fit.model.r);
        CHECK(id.gain0(c) == kf.gain()(0));
        CHECK(id.gain1(c) == kf.gain()(1));
      }
      waiting += id.apply_at(c) != 0 ? 1U : 0U;
    }
    REQUIRE(waiting <= 1);  // one fit at a time
  }
  // requests at 3000 + 1000 c (the first from 3000 statistics samples: min_samples 2000 met),
  // then every 3000; each applied 500 samples later
  for (std::size_t c = 0; c < kN; ++c) {
    const std::vector<std::uint64_t> expected = {3500 + 1000 * c, 6500 + 1000 * c, 9500 + 1000 * c};
    CHECK(retuned_at[c] == expected);
    CHECK(id.retunes(c) + id.refused_retunes(c) == 3);
    CHECK(id.paused(c) == 3 * 500);
    CHECK(id.statistics(c).samples() == id.samples(c) - id.paused(c));
    CHECK(id.samples(c) == 12000);
  }
  CHECK(accepted >= 6);  // of 9
  CHECK(id.late_fits() == 0);
  // reset: the configured models, the schedule from the start
  id.reset();
  for (std::size_t c = 0; c < kN; ++c) {
    CHECK(same(id.in_use(c), cfg[c]));
    CHECK(id.retunes(c) == 0);
    CHECK(id.samples(c) == 0);
    CHECK(id.statistics(c).samples() == 0);
    CHECK(id.next_request(c) == 3000 + 1000 * c);
    CHECK(id.status(c) == OnlineDriftStatus::learning);
  }
}

TEST_CASE("restart_after_fit: each fit reads only the samples since the channel's previous fit") {
  const auto y = strong(9000, 4);
  const DriftModelParams<double> cfg{0.7, 0.0, 1.0, 1.0, 0.0};
  LagDriftIdentifier<double, 1> id;
  REQUIRE(id.configure(&cfg, 1, lag_settings(), schedule(500, true)));
  gyrodrift::LagStatisticsNoHead<double, gyrodrift::kLagIdentifierLags> fresh;
  for (std::size_t i = 0; i < y.size(); ++i) {
    const bool collecting = id.apply_at(0) == 0;
    id.push(0, y[i]);
    if (collecting) fresh.push(y[i]);
    if (!collecting && id.apply_at(0) == 0) {
      fresh.reset();  // applied: the samples after it start the next fit's statistics
    }
    if (id.apply_at(0) != 0 && collecting) {  // requested at this sample: the same statistics
      CHECK(id.statistics(0).samples() == fresh.samples());
      CHECK(id.statistics(0).product(0).sum == fresh.product(0).sum);
    }
  }
  // requests at 3000 (3000 samples) and 6000 (2500 since the restart)
  CHECK(id.retunes(0) + id.refused_retunes(0) == 2);
}

TEST_CASE("too few samples: no fit, nothing counted, the configured model kept") {
  const auto y = drift_test::record(0.2297, 0.1638, 1.0, 1.0, 3.0, 20000, 5);
  const DriftModelParams<double> cfg{0.18, 0.1, 1.5, 0.7, 0.0};
  auto s = lag_settings();
  s.min_samples = 1000000;
  LagDriftIdentifier<double, 1> id;
  REQUIRE(id.configure(&cfg, 1, s, schedule()));
  for (double v : y) {
    id.push(0, v);
    REQUIRE(!id.retuned());
  }
  CHECK(id.retunes(0) == 0);
  CHECK(id.refused_retunes(0) == 0);
  CHECK(id.paused(0) == 0);
  CHECK(id.statistics(0).samples() == 20000);
  CHECK(id.status(0) == OnlineDriftStatus::learning);
  CHECK(id.fit_status(0) == LagDriftFitStatus::too_few_samples);
  CHECK(same(id.in_use(0), cfg));
  CHECK(same(id.estimate(0), cfg));
}

TEST_CASE("a white record: the split is not identified, the configured model stays") {
  // AR part 0: drift and noise both white, q and r not separable
  const auto y = drift_test::record(0.0, 0.0, 1.0, 1.0, 0.0, 9000, 6);
  const DriftModelParams<double> cfg{0.5, 0.0, 1.0, 1.0, 0.0};
  LagDriftIdentifier<double, 1> id;
  REQUIRE(id.configure(&cfg, 1, lag_settings(), schedule()));
  bool retuned = false;
  for (double v : y) {
    id.push(0, v);
    retuned = retuned || id.retuned();
  }
  CHECK(!retuned);  // refused from the configured gain: nothing to reload
  CHECK(id.retunes(0) == 0);
  CHECK(id.refused_retunes(0) == 2);  // applied at 3500 and 6500 (the request at 9000 is not)
  CHECK(id.status(0) == OnlineDriftStatus::not_identified);
  CHECK(same(id.in_use(0), cfg));
  const gyrodrift::Ar2SteadyStateKalman<double> kf(gyrodrift::Ar2Model<double>{cfg.a1, cfg.a2, cfg.q, 0.0}, cfg.q,
                                                   cfg.r);
  CHECK(id.gain0(0) == kf.gain()(0));
  CHECK(id.gain1(0) == kf.gain()(1));
}

TEST_CASE("truncation: the fit refused as L too short, the fallback") {
  // (0.6868, -0.0213) at r/q = 3: rho^4 about 0.03, over the kind's 3e-3
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 3.0, 0.0, 4000, 10);
  const DriftModelParams<double> cfg{0.6, 0.0, 1.0, 3.0, 0.0};
  LagDriftIdentifier<double, 1, 4> id;
  REQUIRE(id.configure(&cfg, 1, lag_settings(), schedule()));
  for (double v : y) id.push(0, v);
  CHECK(id.refused_retunes(0) == 1);
  CHECK(id.retunes(0) == 0);
  CHECK(id.fit_status(0) == LagDriftFitStatus::truncation);
  CHECK(id.status(0) == OnlineDriftStatus::fallback);
  CHECK(id.estimate(0).a1 != cfg.a1);  // the fit's estimate is reported, not used
  CHECK(same(id.in_use(0), cfg));
}

TEST_CASE("fallback after an accepted retune: the configured model and gain back, retuned()") {
  // the drift stops half way (white from there); each fit reads only its own samples
  auto y = strong(9000, 4);
  const auto white = drift_test::record(0.0, 0.0, 1.0, 1.0, 0.5, 9000, 8);
  for (std::size_t i = 3500; i < y.size(); ++i) y[i] = white[i];
  const DriftModelParams<double> cfg{0.7, 0.0, 1.0, 1.0, 0.0};
  LagDriftIdentifier<double, 1> id;
  REQUIRE(id.configure(&cfg, 1, lag_settings(), schedule(500, true)));
  const double g0 = id.gain0(0), g1 = id.gain1(0);
  std::vector<std::uint64_t> at;
  for (double v : y) {
    id.push(0, v);
    if (id.retuned()) at.push_back(id.samples(0));
    if (id.samples(0) == 3500) {
      CHECK(id.retunes(0) == 1);
      CHECK(id.gain0(0) != g0);
    }
  }
  // accepted at 3500, refused at 6500 (the gain put back: retuned), refused at 9500 is past the end
  CHECK(at == std::vector<std::uint64_t>{3500, 6500});
  CHECK(id.refused_retunes(0) == 1);
  CHECK(id.status(0) == OnlineDriftStatus::not_identified);
  CHECK(id.gain0(0) == g0);
  CHECK(id.gain1(0) == g1);
  CHECK(same(id.in_use(0), cfg));
}

TEST_CASE("bounded step: the model in use moves at most max_step, along the direction to the fit") {
  const auto y = strong(3600, 3);
  const DriftModelParams<double> cfg{0.5, -0.1, 2.0, 0.5, 0.0};
  auto s = lag_settings();
  s.max_step = 0.05;
  LagDriftIdentifier<double, 1> id;
  REQUIRE(id.configure(&cfg, 1, s, schedule()));
  for (double v : y) id.push(0, v);
  REQUIRE(id.retunes(0) == 1);
  const auto from = coords(cfg), to = coords(id.estimate(0)), now = coords(id.in_use(0));
  double big = 0.0, moved = 0.0;
  for (std::size_t j = 0; j < 4; ++j) big = std::fmax(big, std::fabs(to[j] - from[j]));
  REQUIRE(big > 0.05);
  for (std::size_t j = 0; j < 4; ++j) {
    moved = std::fmax(moved, std::fabs(now[j] - from[j]));
    // the same fraction of the way in every coordinate (round trips through tanh, exp: 1e-12)
    CHECK(std::fabs((now[j] - from[j]) - 0.05 / big * (to[j] - from[j])) < 1e-12);
  }
  CHECK(std::fabs(moved - 0.05) < 1e-12);
  CHECK(id.in_use(0).mean == id.estimate(0).mean);  // the mean is the fit's
}

TEST_CASE("adapt_ar off: a1, a2 held at the configured model, the split at the profile's maximum") {
  const auto y = strong(3600, 5);
  const DriftModelParams<double> cfg{0.88, -0.18, 3.0, 0.3, 0.0};
  auto s = lag_settings();
  s.adapt_ar = false;
  LagDriftIdentifier<double, 1> id;
  REQUIRE(id.configure(&cfg, 1, s, schedule()));
  gyrodrift::LagStatisticsNoHead<double, gyrodrift::kLagIdentifierLags> st;
  for (double v : y) {
    const bool before_request = id.apply_at(0) == 0 && id.retunes(0) + id.refused_retunes(0) == 0;
    id.push(0, v);
    if (before_request) st.push(v);
  }
  REQUIRE(st.samples() == 3000);
  REQUIRE(id.retunes(0) == 1);
  const DriftModelParams<double>& m = id.in_use(0);
  CHECK(m.a1 == cfg.a1);
  CHECK(m.a2 == cfg.a2);
  // the profile at the configured AR part is highest at the fitted split
  const double lam = m.q / (m.q + m.r);
  gyrodrift::LagDriftProfile<double> at, lo, hi;
  REQUIRE(gyrodrift::lag_drift_profile(st, cfg.a1, cfg.a2, lam, at) == LagDriftFitStatus::ok);
  REQUIRE(gyrodrift::lag_drift_profile(st, cfg.a1, cfg.a2, lam * 0.98, lo) == LagDriftFitStatus::ok);
  REQUIRE(gyrodrift::lag_drift_profile(st, cfg.a1, cfg.a2, lam * 1.02, hi) == LagDriftFitStatus::ok);
  CHECK(at.loglike > lo.loglike);
  CHECK(at.loglike > hi.loglike);
  CHECK(std::fabs(at.q - m.q) <= 1e-12 * m.q);
  CHECK(std::fabs(at.r - m.r) <= 1e-12 * m.r);
  // with ar_order 1 the configured a2 must be 0, and adapt_ar must be off
  auto s1 = s;
  s1.ar_order = 1;
  const DriftModelParams<double> ar1{0.5, 0.0, 1.0, 1.0, 0.0};
  CHECK(id.configure(&ar1, 1, s1, schedule()));
  CHECK(!id.configure(&cfg, 1, s1, schedule()));
  s1.adapt_ar = true;
  CHECK(!id.configure(&ar1, 1, s1, schedule()));
}

TEST_CASE("deferred fits: the same as inline when run in time; a late one is discarded") {
  const auto y = strong(10000, 6);
  const DriftModelParams<double> cfg{0.7, 0.0, 1.0, 1.0, 0.0};
  LagDriftIdentifier<double, 1> inline_id, deferred;
  REQUIRE(inline_id.configure(&cfg, 1, lag_settings(), schedule()));
  REQUIRE(deferred.configure(&cfg, 1, lag_settings(), schedule()));
  deferred.defer_fits(true);
  std::size_t runs = 0;
  for (std::size_t i = 0; i < y.size(); ++i) {
    inline_id.push(0, y[i]);
    deferred.push(0, y[i]);
    if (deferred.fit_pending() && i % 400 == 0) {  // thread mode gets to it some samples later
      deferred.run_pending_fit();
      ++runs;
      CHECK(!deferred.fit_pending());
    }
    REQUIRE(deferred.retuned() == inline_id.retuned());
    REQUIRE(same(deferred.in_use(0), inline_id.in_use(0)));
    REQUIRE(deferred.gain0(0) == inline_id.gain0(0));
  }
  CHECK(runs == 3);
  CHECK(deferred.retunes(0) == 3);
  CHECK(deferred.late_fits() == 0);
  CHECK(deferred.paused(0) == inline_id.paused(0));

  // never run by the apply point: late, the statistics paused until the fit is done, its
  // outcome discarded, the next request on schedule
  LagDriftIdentifier<double, 1> late;
  REQUIRE(late.configure(&cfg, 1, lag_settings(), schedule()));
  late.defer_fits(true);
  for (std::size_t i = 0; i < 4000; ++i) late.push(0, y[i]);
  CHECK(late.fit_pending());
  CHECK(late.late_fits() == 1);
  CHECK(late.paused(0) == 1000);  // from 3001 to 4000
  CHECK(late.statistics(0).samples() == 3000);
  late.run_pending_fit();
  CHECK(!late.fit_pending());
  late.push(0, y[4000]);  // discarded here: nothing applied, the statistics resume after it
  CHECK(!late.retuned());
  CHECK(late.retunes(0) == 0);
  CHECK(late.refused_retunes(0) == 0);
  CHECK(same(late.in_use(0), cfg));
  CHECK(late.apply_at(0) == 0);
  late.push(0, y[4001]);
  CHECK(late.statistics(0).samples() == 3001);
  for (std::size_t i = 4002; i < 6001; ++i) late.push(0, y[i]);
  CHECK(late.fit_pending());  // the next request at 6000
  late.run_pending_fit();
  for (std::size_t i = 6001; i < 6500; ++i) late.push(0, y[i]);
  CHECK(late.retuned());
  CHECK(late.retunes(0) == 1);
  CHECK(late.late_fits() == 1);
}

TEST_CASE("refused configurations") {
  const DriftModelParams<double> good[2] = {{0.5, 0.0, 1.0, 1.0, 0.0}, {0.5, 0.0, 1.0, 1.0, 0.0}};
  LagDriftIdentifier<double, 2> id;
  std::size_t failed = 99;
  CHECK(id.configure(good, 2, lag_settings(), schedule(1500)));  // 2 x 1500 = the cadence
  CHECK(!id.configure(good, 2, lag_settings(), schedule(1501), &failed));
  CHECK(failed == 2);
  CHECK(id.channels() == 0);
  CHECK(!id.configure(good, 3, lag_settings(), schedule(), &failed));
  CHECK(failed == 3);
  CHECK(!id.configure(good, 0, lag_settings(), schedule(), &failed));
  auto s = lag_settings();
  s.max_step = 0.0;
  CHECK(!id.configure(good, 1, s, schedule()));
  s = lag_settings();
  s.max_rel_stderr = std::nan("");
  CHECK(!id.configure(good, 1, s, schedule()));
  auto l = schedule();
  l.max_iterations = 0;
  CHECK(!id.configure(good, 1, lag_settings(), l));
  const DriftModelParams<double> bad[2] = {{0.5, 0.0, 1.0, 1.0, 0.0}, {0.5, 0.0, 1.0, 0.0, 0.0}};  // r = 0
  CHECK(!id.configure(bad, 2, lag_settings(), schedule(), &failed));
  CHECK(failed == 1);
  const DriftModelParams<double> unstable{1.5, 0.0, 1.0, 1.0, 0.0};
  CHECK(!id.configure(&unstable, 1, lag_settings(), schedule(), &failed));
  CHECK(failed == 0);
  // unconfigured: every call refused or a no-op
  CHECK(!id.push(0, 1.0));
  id.skip(0);
  CHECK(!id.retuned());
}

TEST_CASE("the monitor with the lag identifier: every sample counts for the schedule") {
  constexpr std::size_t kOct = 8;
  using Mon = gyrodrift::GyroMonitor<double, kOct, true, true, gyrodrift::DriftIdentifierKind::lag>;
  static Mon mon;
  gyrodrift::GyroMonitorSettings<double> s;
  s.sample_rate_hz = 400.0;
  s.octaves = kOct;
  s.reidentify = true;
  s.drift = lag_settings();
  s.lag = schedule();
  gyrodrift::HealthReference<double, kOct> ref{};
  ref.octaves = kOct;
  for (std::size_t k = 0; k < kOct; ++k) ref.avar[k] = 1.0 / static_cast<double>(std::uint64_t{1} << k);
  const DriftModelParams<double> cfg{0.7, 0.0, 1.0, 1.0, 0.0};
  CHECK(mon.configure(s, cfg, ref) == gyrodrift::GyroMonitorStatus::bad_settings);  // identifier recursive
  s.identifier = gyrodrift::DriftIdentifierKind::lag;
  REQUIRE(mon.configure(s, cfg, ref) == gyrodrift::GyroMonitorStatus::ok);
  const auto y = strong(3600, 3);
  std::size_t retuned = 0, stuck_pushed = 0;
  for (std::size_t i = 0; i < y.size(); ++i) {
    const bool stuck = i % 100 == 5;  // one stuck value in 100: skipped, counted
    mon.push(y[i], stuck, false);
    retuned += mon.retuned() ? 1U : 0U;
    // the statistics take the good samples up to the request (3000) and after the apply point (3500)
    if (!stuck && (i < 3000 || i >= 3500)) ++stuck_pushed;
  }
  const auto& id = mon.identifier();
  CHECK(retuned == 1);
  CHECK(id.samples(0) == 3600);
  CHECK(id.statistics(0).samples() == stuck_pushed);
  CHECK(id.paused(0) == 500);
  CHECK(id.retunes(0) == 1);
  // the recursive monitor refuses the lag identifier
  static gyrodrift::GyroMonitor<double, kOct> rec;
  CHECK(rec.configure(s, cfg, ref) == gyrodrift::GyroMonitorStatus::bad_settings);
}

namespace {
constexpr std::size_t kProcOct = 10;
using ProcLag = gyrodrift::ImuProcessor<float, gyrodrift::NoWavelet<float>, gyrodrift::kImuChannels, kProcOct,
                                        gyrodrift::kImuGyroChannels, true,
                                        LagDriftIdentifier<float, gyrodrift::kImuGyroChannels>>;

gyrodrift::ImuConfig<float> proc_config() {
  gyrodrift::ImuConfig<float> cfg;
  for (std::size_t c = 0; c < 3; ++c) {
    cfg.channels[c].filter = gyrodrift::ChannelFilter::ar2_kalman;
    cfg.channels[c].steady_state = true;
    cfg.channels[c].model = gyrodrift::Ar2Model<float>{0.7F, 0.0F, 1.0F, 0.5F};
    cfg.channels[c].q = 1.0F;
    cfg.channels[c].r = 1.0F;
    cfg.channels[c].saturation = 1e6F;
  }
  return cfg;
}

gyrodrift::GyroMonitorSettings<float> proc_settings() {
  gyrodrift::GyroMonitorSettings<float> s;
  s.sample_rate_hz = 400.0F;
  s.octaves = kProcOct;
  s.reidentify = true;
  s.identifier = gyrodrift::DriftIdentifierKind::lag;
  s.drift = unguarded<float>();
  s.lag = schedule<float>();
  return s;
}
}  // namespace

TEST_CASE("the processor with the lag identifier: retunes reach the steady-state stage; deferred = inline") {
  static ProcLag a(proc_config()), b(proc_config());
  std::array<ProcLag::MonitorReference, 3> refs{};
  for (auto& r : refs) {
    r.octaves = kProcOct;
    for (std::size_t k = 0; k < kProcOct; ++k) r.avar[k] = 1.0F / static_cast<float>(std::uint64_t{1} << k);
  }
  auto wrong = proc_settings();
  wrong.identifier = gyrodrift::DriftIdentifierKind::recursive;
  CHECK(a.configure_monitor(wrong, refs, {true, true, true}) == gyrodrift::GyroMonitorStatus::bad_settings);
  REQUIRE(a.configure_monitor(proc_settings(), refs, {true, true, true}) == gyrodrift::GyroMonitorStatus::ok);
  REQUIRE(b.configure_monitor(proc_settings(), refs, {true, true, true}) == gyrodrift::GyroMonitorStatus::ok);
  b.defer_monitor_fits(true);
  std::vector<double> y[3] = {strong(8000, 3), strong(8000, 4), strong(8000, 5)};
  gyrodrift::ImuSample<float> in{};
  gyrodrift::ImuOutput<float> oa{}, ob{};
  std::size_t runs = 0;
  for (std::size_t i = 0; i < 8000; ++i) {
    in.seq = static_cast<std::uint16_t>(i);
    in.t_us = 2500ULL * i;
    for (std::size_t c = 0; c < 3; ++c) in.values[c] = static_cast<float>(y[c][i]);
    const std::uint16_t fa = a.step(in, oa);
    const std::uint16_t fb = b.step(in, ob);
    REQUIRE(fa == fb);
    for (std::size_t c = 0; c < 6; ++c) REQUIRE(oa.values[c] == ob.values[c]);
    if (b.monitor_fit_pending()) {
      b.run_pending_monitor_fit();
      ++runs;
    }
  }
  // requests at 3000, 4000, 5000, 6000, 7000 and 8000 (the last step: applied after it)
  CHECK(runs == 6);
  const auto& id = a.monitor_identifier();
  std::uint64_t accepted = 0, applied = 0;
  for (std::size_t c = 0; c < 3; ++c) {
    accepted += id.retunes(c);
    applied += id.retunes(c) + id.refused_retunes(c);
  }
  CHECK(applied == 5);
  CHECK(accepted >= 3);
  CHECK(a.health().monitor_retunes == accepted);  // each taken by the channel's steady-state stage
  CHECK(b.health().monitor_retunes == accepted);
  CHECK(a.health().monitor_refused_retunes == applied - accepted);
  CHECK(b.monitor_late_fits() == 0);
  // a build with the recursive identifier has no deferred fits
  using Rec = gyrodrift::ImuProcessor<float, gyrodrift::NoWavelet<float>, gyrodrift::kImuChannels, kProcOct>;
  static Rec r(proc_config());
  CHECK(r.configure_monitor(proc_settings(), refs, {true, true, true}) == gyrodrift::GyroMonitorStatus::bad_settings);
  CHECK(!r.monitor_fit_pending());
  CHECK(r.monitor_late_fits() == 0);
}

TEST_CASE("float state, no allocation, size") {
  const auto y = strong(10000, 3);
  const DriftModelParams<float> cfg{0.7F, 0.0F, 1.0F, 1.0F, 0.0F};
  static LagDriftIdentifier<float, 3> id;
  const DriftModelParams<float> cfgs[3] = {cfg, cfg, cfg};
  gyrodrift::test::AllocationScope scope;
  const bool ok = id.configure(cfgs, 3, lag_settings<float>(), schedule<float>(1000));
  for (double v : y) {
    for (std::size_t c = 0; c < 3; ++c) id.push(c, static_cast<float>(v));
  }
  const long allocations = scope.allocations();
  CHECK(ok);
  CHECK(allocations == 0);
  // 3 x 1000 = the cadence: a request can fall on the sample where the previous channel's fit
  // applies; pushed before it, the channel waits a sample (channel 0 at 6000 and 9000, channel 1
  // at 7000, channel 2 at 8000: each a sample after the one before), so channel 0's third fit
  // applies after the record's end
  CHECK(id.retunes(0) + id.refused_retunes(0) == 2);
  CHECK(id.apply_at(0) == 10002);
  CHECK(id.retunes(1) + id.refused_retunes(1) == 2);
  CHECK(id.retunes(2) + id.refused_retunes(2) == 2);
  CHECK(id.retunes(0) >= 1);
  CHECK(std::fabs(id.in_use(0).a1 - 0.9F) < 0.1F);
  // the statistics are most of a channel's state; the settings the fit uses and its outcome
  // exist once
  CHECK(sizeof(gyrodrift::LagStatisticsNoHead<float, 8>) == 136);
  CHECK(sizeof(LagDriftIdentifier<float, 1>) == 408);
  CHECK(sizeof(LagDriftIdentifier<float, 3>) == 920);
}
