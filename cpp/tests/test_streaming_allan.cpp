// Streaming octave Allan variance (include/gyrodrift/stability/streaming_allan.hpp) against the
// non-overlapped definition (consecutive cluster means summed sample by sample in long double),
// term counts, float against double after 10 h at 400 Hz, bad input, and no allocation.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/stability/streaming_allan.hpp>
#include <limits>
#include <vector>

#include "alloc_counter.hpp"

namespace {

// Deterministic gyro-like record: constant bias, white noise uniform(-1, 1) and a slow random
// walk, from an LCG (no <random> distribution, so the numbers are the same everywhere).
struct Gyro {
  std::uint64_t s;
  double bias;
  double walk{0.0};
  double next() noexcept {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u = static_cast<double>(s >> 11) * 0x1.0p-53 * 2.0 - 1.0;
    walk += 1e-4 * u;
    return bias + u + walk;
  }
};

// Non-overlapped Allan variance from the definition: M = floor(N / m) cluster means, each the
// plain sum of its m samples in long double, squared differences of consecutive means.
long double definition_avar(const std::vector<double>& y, std::size_t m, std::size_t& terms) {
  const std::size_t clusters = y.size() / m;
  long double prev = 0.0L;
  long double sum_sq = 0.0L;
  for (std::size_t j = 0; j < clusters; ++j) {
    long double s = 0.0L;
    for (std::size_t i = 0; i < m; ++i) s += static_cast<long double>(y[j * m + i]);
    const long double mean = s / static_cast<long double>(m);
    if (j > 0) sum_sq += (mean - prev) * (mean - prev);
    prev = mean;
  }
  terms = clusters - 1;
  return sum_sq / (2.0L * static_cast<long double>(terms));
}

}  // namespace

TEST_CASE("double equals the non-overlapped definition at every octave") {
  constexpr std::size_t kOctaves = 14;
  Gyro g{12345, 10.0};
  std::vector<double> y(100003);  // not a power of two: partial clusters are left out
  for (auto& v : y) v = g.next();
  gyrodrift::StreamingAllan<double, kOctaves> sa;
  REQUIRE(sa.configure(400.0, kOctaves));
  CHECK(sa.push(y.data(), y.size()) == y.size());
  CHECK(sa.samples() == y.size());
  for (std::size_t k = 0; k < kOctaves; ++k) {
    std::size_t terms = 0;
    const long double ref = definition_avar(y, std::size_t{1} << k, terms);
    double got = 0.0;
    REQUIRE(sa.avar(k, got));
    CHECK(sa.terms(k) == terms);
    CHECK(sa.terms(k) == y.size() / (std::size_t{1} << k) - 1);
    // double rounding of pairwise means and a compensated sum: 1e-12 relative is ~4500 ulp
    const double rel = std::fabs(got - static_cast<double>(ref)) / static_cast<double>(ref);
    CHECK(rel < 1e-12);
    CHECK(sa.tau_s(k) == doctest::Approx(std::ldexp(1.0, static_cast<int>(k)) / 400.0));
  }
}

TEST_CASE("the term callback hands over every squared difference of every octave once") {
  // 1000 samples of the gyro record: the callback's terms per octave, counted and summed in
  // long double, against terms(k) and the definition (the same 1e-12 as above)
  constexpr std::size_t kOctaves = 6;
  Gyro g{777, 3.0};
  std::vector<double> y(1000);
  for (auto& v : y) v = g.next();
  gyrodrift::StreamingAllan<double, kOctaves> sa;
  REQUIRE(sa.configure(100.0, kOctaves));
  std::size_t count[kOctaves] = {};
  long double sum[kOctaves] = {};
  bool in_order = true;  // terms(k) already counts the term when it is handed over
  for (double v : y) {
    sa.push(v, [&](std::size_t k, double d2) {
      ++count[k];
      sum[k] += static_cast<long double>(d2);
      in_order = in_order && sa.terms(k) == count[k];
    });
  }
  CHECK(in_order);
  for (std::size_t k = 0; k < kOctaves; ++k) {
    std::size_t terms = 0;
    const long double ref = definition_avar(y, std::size_t{1} << k, terms);
    CHECK(count[k] == terms);
    const double got = static_cast<double>(sum[k] / (2.0L * static_cast<long double>(terms)));
    CHECK(std::fabs(got - static_cast<double>(ref)) < 1e-12 * static_cast<double>(ref));
  }
}

TEST_CASE("the octave appears after two clusters; configure limits the octaves") {
  gyrodrift::StreamingAllan<double, 8> sa;
  double v = 0.0;
  CHECK_FALSE(sa.push(1.0));  // not configured
  CHECK(sa.rejected() == 1);
  REQUIRE(sa.configure(100.0, 3));
  CHECK(sa.rejected() == 0);
  for (int i = 0; i < 7; ++i) sa.push(i % 2 == 0 ? 1.0 : -1.0);
  // 7 samples: octave 0 has 6 differences (each 2 or -2), octave 1 (pairs) has 3 clusters of
  // mean 0 -> 2 differences of 0, octave 2 has 1 cluster -> no term yet.
  REQUIRE(sa.avar(0, v));
  CHECK(v == doctest::Approx(2.0));  // (2^2) / 2
  CHECK(sa.terms(0) == 6);
  REQUIRE(sa.avar(1, v));
  CHECK(v == 0.0);
  CHECK(sa.terms(1) == 2);
  CHECK_FALSE(sa.avar(2, v));
  sa.push(1.0);
  REQUIRE(sa.avar(2, v));
  CHECK(sa.terms(2) == 1);
  CHECK_FALSE(sa.avar(3, v));  // beyond the configured octaves
  CHECK(sa.terms(3) == 0);
}

TEST_CASE("bad configuration and non-finite samples are refused and counted") {
  gyrodrift::StreamingAllan<float, 4> sa;
  CHECK_FALSE(sa.configure(0.0F, 2));
  CHECK_FALSE(sa.configure(-1.0F, 2));
  CHECK_FALSE(sa.configure(std::numeric_limits<float>::quiet_NaN(), 2));
  CHECK_FALSE(sa.configure(100.0F, 0));
  CHECK_FALSE(sa.configure(100.0F, 5));
  REQUIRE(sa.configure(100.0F, 4));
  CHECK(sa.octaves() == 4);
  const float bad[3] = {std::numeric_limits<float>::quiet_NaN(),
                        std::numeric_limits<float>::infinity(), 1.0F};
  CHECK(sa.push(bad, 3) == 1);
  CHECK(sa.rejected() == 2);
  CHECK(sa.samples() == 1);
  sa.reset();
  CHECK(sa.samples() == 0);
  CHECK(sa.rejected() == 0);
}

TEST_CASE("float after 10 h at 400 Hz stays close to double on the same samples") {
  // 14.4e6 samples of a gyro with a 10-unit bias (as deg/h), unit white noise and a slow
  // random walk. Both variants get the same float values, so the difference is arithmetic
  // only. Bound: 1e-6 relative (~16 float eps) at every octave up to tau0 * 2^19 (1311 s,
  // 26 terms): the cluster means are carried as hi + lo pairs (their differences keep float
  // precision relative to the difference, not to the drifted mean) and the renormalised
  // compensated sum keeps a few eps whatever the term count (measured: < 1e-7). A plain float
  // sum of the octave 0 squares loses ~2e-2 (checked below), and a Neumaier sum whose
  // compensation is not folded back loses ~5e-5 (its compensation term grows to a fair part of
  // the sum: most squares are below an ulp of the running sum).
  constexpr std::size_t kOctaves = 20;
  gyrodrift::StreamingAllan<float, kOctaves> f;
  gyrodrift::StreamingAllan<double, kOctaves> d;
  REQUIRE(f.configure(400.0F, kOctaves));
  REQUIRE(d.configure(400.0, kOctaves));
  Gyro g{777, 10.0};
  float naive0 = 0.0F;
  float prev = 0.0F;
  const std::size_t n = 14'400'000;
  for (std::size_t i = 0; i < n; ++i) {
    const auto y = static_cast<float>(g.next());
    f.push(y);
    d.push(static_cast<double>(y));
    if (i > 0) naive0 += (y - prev) * (y - prev);
    prev = y;
  }
  double worst = 0.0;
  for (std::size_t k = 0; k < kOctaves; ++k) {
    float vf = 0.0F;
    double vd = 0.0;
    REQUIRE(f.avar(k, vf));
    REQUIRE(d.avar(k, vd));
    CHECK(f.terms(k) == d.terms(k));
    const double rel = std::fabs(static_cast<double>(vf) - vd) / vd;
    worst = rel > worst ? rel : worst;
  }
  MESSAGE("float vs double, worst relative avar error over 20 octaves: " << worst);
  CHECK(worst < 1e-6);
  double vd0 = 0.0;
  REQUIRE(d.avar(0, vd0));
  const double naive_rel =
      std::fabs(static_cast<double>(naive0) / (2.0 * static_cast<double>(n - 1)) - vd0) / vd0;
  MESSAGE("plain float sum at octave 0, relative error: " << naive_rel);
  CHECK(naive_rel > 1e-4);  // the compensation is what keeps float usable here
}

TEST_CASE("no allocation") {
  gyrodrift::StreamingAllan<float, 16> sa;
  std::vector<float> y(50000);
  Gyro g{9, 1.0};
  for (auto& v : y) v = static_cast<float>(g.next());
  gyrodrift::test::AllocationScope scope;
  const bool ok = sa.configure(400.0F, 16);
  const std::size_t accepted = sa.push(y.data(), y.size());
  float v = 0.0F;
  const bool got = sa.avar(10, v);
  const long allocations = scope.allocations();
  CHECK(ok);
  CHECK(accepted == y.size());
  CHECK(got);
  CHECK(allocations == 0);
}
