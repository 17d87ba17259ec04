// The re-identification time-shared among gyro channels
// (include/gyrodrift/filters/shared_drift_identifier.hpp): with one channel it is
// OnlineDriftIdentifier sample for sample; with three, the channels take turns of one block
// (one parameter update per step at most), each converges to its own simulating model, the
// idle channels keep their running means, reset and refused configurations; state size.
#define EIGEN_RUNTIME_NO_MALLOC
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/online_drift_identifier.hpp>
#include <gyrodrift/filters/shared_drift_identifier.hpp>
#include <limits>
#include <vector>

#include "alloc_counter.hpp"
#include "drift_test_support.hpp"

namespace {

using gyrodrift::DriftModelParams;
using gyrodrift::OnlineDriftIdentifier;
using gyrodrift::OnlineDriftSettings;
using gyrodrift::OnlineDriftStatus;
using gyrodrift::SharedDriftIdentifier;

using drift_test::record;
using drift_test::small_settings;

}  // namespace

TEST_CASE("one channel: the single-channel identifier, sample for sample") {
  const auto y = record(0.2297, 0.1638, 1.0, 1.0, 3.0, 60000, 11);
  const DriftModelParams<double> cfg{0.18, 0.1, 1.5, 0.7, 0.0};
  OnlineDriftIdentifier<double> one;
  SharedDriftIdentifier<double, 1> shared;
  REQUIRE(one.configure(cfg, small_settings()));
  REQUIRE(shared.configure(&cfg, 1, small_settings()));
  std::size_t retunes_seen = 0;
  for (double v : y) {
    one.push(v);
    shared.push(0, v);
    REQUIRE(shared.retuned() == one.retuned());
    retunes_seen += one.retuned() ? 1U : 0U;
  }
  CHECK(retunes_seen > 0);
  // bit for bit: the same operations in the same order
  CHECK(shared.estimate(0).a1 == one.estimate().a1);
  CHECK(shared.estimate(0).a2 == one.estimate().a2);
  CHECK(shared.estimate(0).q == one.estimate().q);
  CHECK(shared.estimate(0).r == one.estimate().r);
  CHECK(shared.estimate(0).mean == one.estimate().mean);
  CHECK(shared.gain0(0) == one.gain0());
  CHECK(shared.gain1(0) == one.gain1());
  CHECK(shared.status(0) == one.status());
  CHECK(shared.retunes(0) == one.retunes());
  CHECK(shared.blocks(0) == one.blocks());
}

TEST_CASE("three channels take turns of one block, and each converges to its own model") {
  // Three gyros with the papers' correlated AR(2) pair, q and r up to 9 and 4 times apart
  // (drift-to-noise ratios 1 to 2.25); 600000 samples per channel: each gets a third of the
  // blocks (1000 of 200 samples, a few more: a turn passed on to a channel later in the push
  // order starts in the same step), about the length at which the single-channel test holds
  // its 200000-sample estimate (the same bounds).
  constexpr std::size_t kN = 600000;
  const double q[3] = {1.0, 4.0, 9.0};
  const double r[3] = {1.0, 2.0, 4.0};
  std::vector<double> y[3];
  for (std::size_t c = 0; c < 3; ++c) y[c] = record(0.2297, 0.1638, q[c], r[c], 1.0 + static_cast<double>(c), kN, 21 + c);
  DriftModelParams<double> cfg[3];
  for (std::size_t c = 0; c < 3; ++c) cfg[c] = DriftModelParams<double>{0.18, 0.1, 1.5 * q[c], 0.7 * r[c], 0.0};
  static SharedDriftIdentifier<double, 3> id;
  REQUIRE(id.configure(cfg, 3, small_settings()));
  std::size_t most_updates_in_a_step = 0;
  double mean_check[3] = {0.0, 0.0, 0.0};
  gyrodrift::test::AllocationScope scope;
  for (std::size_t k = 0; k < kN; ++k) {
    std::size_t updates = 0;
    for (std::size_t c = 0; c < 3; ++c) {
      const std::uint32_t before = id.blocks(c);
      id.push(c, y[c][k]);
      updates += id.blocks(c) != before ? 1U : 0U;
      mean_check[c] += y[c][k];
    }
    if (updates > most_updates_in_a_step) most_updates_in_a_step = updates;
    if (k == 599) {  // blocks of 200: channel 0 had samples 0-199, 1 200-399, 2 400-599
      CHECK(id.blocks(0) == 1);
      CHECK(id.blocks(1) == 1);
      CHECK(id.blocks(2) == 1);
      CHECK(id.turn() == 0);
    }
  }
  CHECK(scope.allocations() == 0);
  CHECK(most_updates_in_a_step == 1);
  for (std::size_t c = 0; c < 3; ++c) {
    const auto& e = id.estimate(c);
    CAPTURE(c);
    CHECK(id.blocks(c) >= 1000);
    CHECK(id.blocks(c) <= 1010);
    CHECK(id.samples(c) == kN);  // every sample counts and moves the mean
    CHECK(std::fabs(e.a1 - 0.2297) < 0.045);
    CHECK(std::fabs(e.a2 - 0.1638) < 0.026);
    CHECK(std::fabs(e.q / q[c] - 1.0) < 0.25);
    CHECK(std::fabs(e.r / r[c] - 1.0) < 0.25);
    // the running mean of all the channel's samples (no forgetting: the plain mean), to the
    // rounding of 600000 incremental updates in double
    CHECK(e.mean == doctest::Approx(mean_check[c] / static_cast<double>(kN)).epsilon(1e-9));
    CHECK(id.status(c) == OnlineDriftStatus::tracking);
    CHECK(id.retunes(c) > 0);
  }
  // reset: every channel back to its configured model and the turn at channel 0
  id.reset();
  CHECK(id.turn() == 0);
  for (std::size_t c = 0; c < 3; ++c) {
    CHECK(id.in_use(c).q == cfg[c].q);
    CHECK(id.blocks(c) == 0);
    CHECK(id.status(c) == OnlineDriftStatus::learning);
  }
}

TEST_CASE("a channel in turn without samples passes its turn on after a block's worth") {
  // Channel 0 delivers nothing from sample 1000 on (NaN pushed, or skip(): the caller refused
  // the value). While it holds the turn the others only move their means; after block_samples
  // missed samples its partial block is dropped and the turn passes on, so channels 1 and 2
  // keep taking blocks. A few missing samples within a turn are skipped as if absent.
  const auto s = small_settings();  // blocks of 200
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const DriftModelParams<double> cfg{0.18, 0.1, 1.5, 0.7, 0.0};
  const DriftModelParams<double> cfgs[3] = {cfg, cfg, cfg};
  std::vector<double> y[3];
  for (std::size_t c = 0; c < 3; ++c) y[c] = record(0.2297, 0.1638, 1.0, 1.0, 0.0, 30000, 31 + c);
  for (int mode = 0; mode < 2; ++mode) {
    CAPTURE(mode);
    SharedDriftIdentifier<double, 3> id;
    REQUIRE(id.configure(cfgs, 3, s));
    for (std::size_t k = 0; k < 30000; ++k) {
      for (std::size_t c = 0; c < 3; ++c) {
        if (c == 0 && k >= 1000) {
          if (mode == 0) id.push(c, nan);
          else id.skip(c);
        } else {
          id.push(c, y[c][k]);
        }
      }
    }
    CHECK(id.blocks(0) == 2);  // samples 0-199 and 598-797; its later turns had none
    CHECK(id.samples(0) == 1000);
    CHECK(id.rejected(0) == (mode == 0 ? 29000U : 0U));
    for (std::size_t c = 1; c < 3; ++c) {
      CAPTURE(c);
      CHECK(id.blocks(c) >= 45);  // a third of the 150 blocks' worth of samples
      CHECK(id.samples(c) == 30000);
    }
  }
  // one channel: nothing to pass the turn to, a missing sample is skipped as if absent
  SharedDriftIdentifier<double, 1> one;
  OnlineDriftIdentifier<double> single;
  REQUIRE(one.configure(&cfg, 1, s));
  REQUIRE(single.configure(cfg, s));
  for (std::size_t k = 0; k < 30000; ++k) {
    const double v = (k % 1000) < 300 ? nan : y[0][k];
    one.push(0, v);
    single.push(v);
  }
  CHECK(one.blocks(0) == single.blocks());
  CHECK(one.estimate(0).q == single.estimate().q);
}

TEST_CASE("refused configurations and channels out of range") {
  DriftModelParams<float> cfg[3] = {{0.5F, 0.0F, 1e-10F, 1e-8F, 0.0F},
                                    {0.5F, 0.0F, 1e-10F, 0.0F, 0.0F},  // r = 0: refused
                                    {0.5F, 0.0F, 1e-10F, 1e-8F, 0.0F}};
  SharedDriftIdentifier<float, 3> id;
  OnlineDriftSettings<float> s;
  std::size_t failed = 99;
  CHECK_FALSE(id.configure(cfg, 3, s, &failed));
  CHECK(failed == 1);
  CHECK(id.channels() == 0);
  CHECK_FALSE(id.push(0, 1e-4F));
  CHECK_FALSE(id.configure(cfg, 4, s, &failed));  // more than the capacity
  CHECK(failed == 4);
  REQUIRE(id.configure(cfg, 1, s));
  CHECK(id.channels() == 1);
  CHECK_FALSE(id.push(1, 1e-4F));
  CHECK(id.push(0, 1e-4F));
  CHECK_FALSE(id.push(0, NAN));
  CHECK(id.rejected(0) == 1);
}

TEST_CASE("state size: one working state, a small state per channel") {
  using Track = OnlineDriftIdentifier<float>::Track;
  static_assert(sizeof(SharedDriftIdentifier<float, 3>) <=
                    sizeof(OnlineDriftIdentifier<float>) + 2 * sizeof(Track) + 3 * sizeof(std::size_t) + 8,
                "three channels: one identifier and two parked channel states");
  CHECK(sizeof(Track) <= 184);
  CHECK(sizeof(SharedDriftIdentifier<float, 3>) < 2 * sizeof(OnlineDriftIdentifier<float>));
}
