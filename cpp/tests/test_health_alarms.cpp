// Health alarms (include/gyrodrift/imu/health_alarms.hpp), online noise estimates
// (include/gyrodrift/stability/online_noise.hpp) and the model Allan variance
// (include/gyrodrift/stability/model_allan.hpp) in C++ alone: float and double builds, known
// closed forms, an angle random walk step and a stuck run, no allocation, noexcept.
// (The numbers against the numpy references: tests/test_health_alarms.py,
// tests/test_online_noise.py.)
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/imu/health_alarms.hpp>
#include <gyrodrift/stability/model_allan.hpp>
#include <gyrodrift/stability/online_noise.hpp>
#include <utility>
#include <vector>

#include "alloc_counter.hpp"

namespace {

// Gaussian-ish white noise of variance 1 from an LCG (sum of 12 uniforms - 6): the same
// numbers everywhere.
struct Noise {
  std::uint64_t s;
  double next() noexcept {
    double acc = 0.0;
    for (int i = 0; i < 12; ++i) {
      s = s * 6364136223846793005ULL + 1442695040888963407ULL;
      acc += static_cast<double>(s >> 11) * 0x1.0p-53;
    }
    return acc - 6.0;
  }
};

template <class Scalar>
void run_arw_step() {
  constexpr std::size_t kOct = 10;
  gyrodrift::StreamingAllan<Scalar, kOct> allan;
  gyrodrift::HealthAlarms<Scalar, kOct> alarms;
  gyrodrift::HealthReference<Scalar, kOct> ref;
  REQUIRE(allan.configure(Scalar(100), kOct));
  // white noise of variance 1: a1 = a2 = q = 0, r = 1
  REQUIRE(gyrodrift::health_reference_from_drift_model(
      gyrodrift::DriftModelParams<Scalar>{Scalar(0), Scalar(0), Scalar(0), Scalar(1), Scalar(0)}, kOct,
      ref));
  gyrodrift::HealthAlarmSettings<Scalar> s{};
  s.stuck_samples = 5;
  REQUIRE(alarms.configure(ref, s));
  for (std::size_t k = 0; k < kOct; ++k) CHECK(alarms.octave_alarm(k) == gyrodrift::kAlarmArwHigh);
  Noise n{3};
  std::uint16_t bits = 0;
  for (int i = 0; i < 20000; ++i) {
    alarms.push(allan, static_cast<Scalar>(n.next()), false, false);
    bits = alarms.latched();
  }
  CHECK(bits == 0);
  for (int i = 0; i < 4000; ++i) {  // N up 3x
    alarms.push(allan, static_cast<Scalar>(3.0 * n.next()), i >= 100 && i < 106, false);
    bits = alarms.latched();
  }
  CHECK(bits == (gyrodrift::kAlarmArwHigh | gyrodrift::kAlarmStuck));
  CHECK(alarms.raised(0) == 1);
  CHECK(alarms.raised(3) == 1);
  CHECK(alarms.exceedances(3) == 2);  // the 5th and 6th sample of a run of 6
  const auto& t = alarms.trip(0);
  CHECK(t.sample > 20000);
  CHECK(t.sample <= 20000 + 2 * 64 + 2);
  CHECK(t.statistic > t.threshold);
  CHECK(alarms.trip(3).sample == 20000 + 105);
  alarms.unlatch();
  CHECK(alarms.latched() == 0);
  CHECK(alarms.raised(0) == 1);

  gyrodrift::NoiseEstimates<Scalar> est{};
  REQUIRE(gyrodrift::estimate_noise(allan, Scalar(0.95), est));
  CHECK(est.n.valid);
  CHECK_FALSE(est.n.upper_limit);
  CHECK(est.n.lo < est.n.value);
  CHECK(est.n.value < est.n.hi);
}

}  // namespace

TEST_CASE("an angle random walk step and a stuck run raise latched, counted alarms (float, double)") {
  run_arw_step<float>();
  run_arw_step<double>();
}

TEST_CASE("closed forms: white noise Allan variance r / m, its edf n^2 / (1.5 n - 0.5)") {
  double av[4] = {};
  REQUIRE(gyrodrift::ar2_white_avar(0.0, 0.0, 0.0, 2.0, 4, av));
  for (int k = 0; k < 4; ++k) CHECK(av[k] == doctest::Approx(2.0 / std::ldexp(1.0, k)).epsilon(1e-15));
  double e[3] = {};
  REQUIRE(gyrodrift::ar2_white_edf_per_term(0.0, 0.0, 0.0, 1.0, 3, 20, e));
  for (double v : e) CHECK(v == doctest::Approx(20.0 / 29.5).epsilon(1e-12));
  CHECK(gyrodrift::nonoverlapped_edf<double>(gyrodrift::AllanNoise::white, 20, 1) ==
        doctest::Approx(400.0 / 29.5).epsilon(1e-14));
  CHECK(gyrodrift::normal_quantile(0.975) == doctest::Approx(1.959963985).epsilon(1e-8));
  CHECK_FALSE(gyrodrift::ar2_white_avar(1.0, 0.5, 1.0, 1.0, 4, av));  // not stationary
}

TEST_CASE("the block position: a 64-bit term count modulo block_terms without a 64-bit division") {
  const std::uint64_t counts[] = {0U, 1U, 63U, 64U, 65U, 0xFFFFFFFFULL, 0x100000000ULL, 0x100000040ULL,
                                  0x123456789ABCDEFULL, 0xFFFFFFFFFFFFFFFFULL};
  const std::uint32_t blocks[] = {4U, 7U, 64U, 1000U, 0x80000001U, 0xFFFFFFFFU};
  for (const std::uint64_t t : counts) {
    for (const std::uint32_t b : blocks) {
      CHECK(gyrodrift::detail::mod_u64_u32(t, b) == t % b);
    }
  }
}

TEST_CASE("bad configuration is refused and leaves the alarms as they were") {
  gyrodrift::HealthAlarms<float, 4> alarms;
  gyrodrift::HealthReference<float, 4> ref;
  ref.octaves = 2;
  ref.avar[0] = 1.0F;
  ref.avar[1] = 0.0F;  // not positive
  CHECK_FALSE(alarms.configure(ref, {}));
  ref.avar[1] = 0.5F;
  gyrodrift::HealthAlarmSettings<float> s{};
  s.arw_factor = 0.5F;
  CHECK_FALSE(alarms.configure(ref, s));
  s.arw_factor = 2.0F;
  s.block_terms = 2;
  CHECK_FALSE(alarms.configure(ref, s));
  CHECK(alarms.reference().octaves == 0);
  CHECK_FALSE(gyrodrift::health_reference_from_ieee952(0.0F, 0.0F, 0.0F, 0.0F, 100.0F, 4, ref));
}

TEST_CASE("no allocation, noexcept, state sizes") {
  using Allan = gyrodrift::StreamingAllan<float, 16>;
  using Alarms = gyrodrift::HealthAlarms<float, 16>;
  static_assert(noexcept(std::declval<Alarms&>().push(std::declval<Allan&>(), 0.0F, false, false)));
  static_assert(noexcept(std::declval<Alarms&>().update(false, false)));
  static_assert(noexcept(gyrodrift::estimate_noise(std::declval<const Allan&>(), 0.95F,
                                                   std::declval<gyrodrift::NoiseEstimates<float>&>())));
  // per octave: 16 bytes of streaming state, 12 of alarm state (docs/guides/health-alarms.md;
  // 64-bit host: the reference's size_t and the padding a little more than on the MCU)
  static_assert(sizeof(Allan) <= 16 * 16 + 24);
  static_assert(sizeof(Alarms) <= 12 * 16 + 240);
  Allan allan;
  Alarms alarms;
  gyrodrift::HealthReference<float, 16> ref;
  gyrodrift::NoiseEstimates<float> est{};
  std::vector<float> y(50000);
  Noise n{5};
  for (auto& v : y) v = static_cast<float>(n.next());
  gyrodrift::test::AllocationScope scope;
  bool ok = allan.configure(400.0F, 16);
  ok = ok && gyrodrift::health_reference_from_ieee952(0.0F, 0.05F, 0.0F, 0.0F, 400.0F, 16, ref);
  ok = ok && alarms.configure(ref, {});
  std::uint16_t bits = 0;
  for (float v : y) {
    alarms.push(allan, v, false, false);
    bits = static_cast<std::uint16_t>(bits | alarms.latched());
  }
  const bool est_ok = gyrodrift::estimate_noise(allan, 0.95F, est);
  const long allocations = scope.allocations();
  CHECK(ok);
  CHECK(est_ok);
  CHECK(allocations == 0);
  (void)bits;
}
