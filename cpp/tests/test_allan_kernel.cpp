// Overlapping Allan kernel (include/gyrodrift/stability/allan.hpp) against the definition
// (overlapping cluster averages, summed in long double), streaming splits, phase input,
// precision with a large constant rate, tau grids, bad input, and no allocation.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/stability/allan.hpp>
#include <limits>
#include <memory>
#include <vector>

#include "alloc_counter.hpp"

namespace {

using gyrodrift::AllanInput;
using gyrodrift::OadevSums;

// Deterministic uniform(-1, 1) noise plus a slow random walk (gyro-like), no <random>
// distribution (implementation-defined) so the numbers are the same everywhere.
std::vector<double> record(std::size_t n, double offset, std::uint64_t seed) {
  std::vector<double> y(n);
  std::uint64_t s = seed;
  double walk = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u = static_cast<double>(s >> 11) * 0x1.0p-53 * 2.0 - 1.0;
    walk += 1e-3 * u;
    y[i] = offset + u + walk;
  }
  return y;
}

// sigma^2 from the definition (IEEE Std 952 Annex C): cluster averages of m samples at every
// start, squared differences of averages m apart, all in long double.
long double definition_sigma2(const std::vector<double>& y, std::size_t m) {
  const std::size_t n_avg = y.size() - m + 1;
  std::vector<long double> avg(n_avg);
  for (std::size_t i = 0; i < n_avg; ++i) {
    long double s = 0.0L;
    for (std::size_t k = 0; k < m; ++k) s += static_cast<long double>(y[i + k]);
    avg[i] = s / static_cast<long double>(m);
  }
  long double sum = 0.0L;
  const std::size_t terms = n_avg - m;
  for (std::size_t i = 0; i < terms; ++i) {
    const long double d = avg[i + m] - avg[i];
    sum += d * d;
  }
  return sum / (2.0L * static_cast<long double>(terms));
}

}  // namespace

TEST_CASE("rate input equals the cluster-average definition") {
  const auto y = record(4001, 0.0, 1);
  const std::size_t m[] = {1, 2, 3, 7, 64, 500, 2000};
  double sigma2[7] = {};
  std::size_t terms[7] = {};
  REQUIRE(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, m, 7, sigma2, terms));
  for (std::size_t j = 0; j < 7; ++j) {
    const auto ref = static_cast<double>(definition_sigma2(y, m[j]));
    // both in long double; the kernel's running difference vs explicit averages: 1e-13
    CHECK(sigma2[j] == doctest::Approx(ref).epsilon(1e-13));
    CHECK(terms[j] == y.size() - 2 * m[j] + 1);
  }
}

TEST_CASE("a large constant rate costs no precision (mean cancels in the differences)") {
  // 1e5 deg/h offset on unit noise: doubles near 1e5 keep ~1e-11 absolute, and D never forms
  // the 1e5 * m phase, so the kernel stays at the definition's value of the same data.
  const auto y = record(3001, 1e5, 2);
  const std::size_t m[] = {1, 10, 1000};
  double sigma2[3] = {};
  REQUIRE(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, m, 3, sigma2,
                           static_cast<std::size_t*>(nullptr)));
  for (std::size_t j = 0; j < 3; ++j) {
    CHECK(sigma2[j] == doctest::Approx(static_cast<double>(definition_sigma2(y, m[j])))
                           .epsilon(1e-12));
  }
}

TEST_CASE("streaming in arbitrary pieces equals the whole-array call") {
  const auto y = record(10007, 3.0, 3);
  for (const std::size_t m : {std::size_t{1}, std::size_t{5}, std::size_t{777}}) {
    double whole = 0.0;
    REQUIRE(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, &m, 1, &whole,
                             static_cast<std::size_t*>(nullptr)));
    OadevSums<long double> s;
    // seed in pieces of 3, advance in pieces of 101
    for (std::size_t k = 0; k < m; k += 3) {
      const std::size_t len = std::min<std::size_t>(3, m - k);
      gyrodrift::oadev_rate_seed(s, y.data() + k, y.data() + m + k, len);
    }
    const std::size_t n_adv = y.size() - 2 * m;
    for (std::size_t i = 0; i < n_adv; i += 101) {
      const std::size_t len = std::min<std::size_t>(101, n_adv - i);
      gyrodrift::oadev_rate_advance(s, y.data() + i, y.data() + i + m, y.data() + i + 2 * m,
                                    len);
    }
    gyrodrift::oadev_rate_finish(s);
    double streamed = 0.0;
    REQUIRE(gyrodrift::oadev_sigma2(s, m, streamed));
    // only the grouping of long-double additions differs: 1e-15
    CHECK(streamed == doctest::Approx(whole).epsilon(1e-15));
    CHECK(s.terms == y.size() - 2 * m + 1);
  }
}

TEST_CASE("phase input of the cumulative sum equals rate input") {
  const auto y = record(5000, 0.5, 4);
  std::vector<double> x(y.size() + 1, 0.0);
  long double acc = 0.0L;
  for (std::size_t i = 0; i < y.size(); ++i) {
    acc += static_cast<long double>(y[i]);
    x[i + 1] = static_cast<double>(acc);
  }
  const std::size_t m[] = {1, 4, 100, 2499};
  double s_rate[4] = {};
  double s_phase[4] = {};
  std::size_t t_rate[4] = {};
  std::size_t t_phase[4] = {};
  REQUIRE(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, m, 4, s_rate, t_rate));
  REQUIRE(gyrodrift::oadev(x.data(), x.size(), AllanInput::phase, m, 4, s_phase, t_phase));
  for (std::size_t j = 0; j < 4; ++j) {
    // x rounded to double (|x| <= 2.6e3, ulp 4.5e-13) against differences of ~sqrt(2m):
    // relative error well under 1e-11
    CHECK(s_phase[j] == doctest::Approx(s_rate[j]).epsilon(1e-11));
    CHECK(t_phase[j] == t_rate[j]);
  }
}

TEST_CASE("float input, long double sums") {
  std::vector<float> yf(2000);
  const auto y = record(2000, 0.0, 5);
  for (std::size_t i = 0; i < y.size(); ++i) yf[i] = static_cast<float>(y[i]);
  std::vector<double> yd(yf.begin(), yf.end());
  const std::size_t m[] = {1, 33};
  float sf[2] = {};
  double sd[2] = {};
  REQUIRE(gyrodrift::oadev(yf.data(), yf.size(), AllanInput::rate, m, 2, sf,
                           static_cast<std::size_t*>(nullptr)));
  REQUIRE(gyrodrift::oadev(yd.data(), yd.size(), AllanInput::rate, m, 2, sd,
                           static_cast<std::size_t*>(nullptr)));
  for (std::size_t j = 0; j < 2; ++j) {
    CHECK(static_cast<double>(sf[j]) == doctest::Approx(sd[j]).epsilon(1e-7));  // float out
  }
}

TEST_CASE("bad input returns false") {
  auto y = record(100, 0.0, 6);
  double s = -1.0;
  const std::size_t too_big = 50;  // rate: m <= (N - 1) / 2 = 49
  CHECK_FALSE(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, &too_big, 1, &s,
                               static_cast<std::size_t*>(nullptr)));
  const std::size_t zero = 0;
  CHECK_FALSE(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, &zero, 1, &s,
                               static_cast<std::size_t*>(nullptr)));
  CHECK(s == -1.0);  // untouched
  const std::size_t ok = 49;
  CHECK(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, &ok, 1, &s,
                         static_cast<std::size_t*>(nullptr)));
  y[37] = std::numeric_limits<double>::quiet_NaN();
  const std::size_t m1 = 1;
  double s2 = -1.0;
  CHECK_FALSE(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, &m1, 1, &s2,
                               static_cast<std::size_t*>(nullptr)));
  CHECK(s2 == -1.0);
  CHECK(gyrodrift::oadev_max_m(2, AllanInput::rate) == 0);
  CHECK(gyrodrift::oadev_max_m(3, AllanInput::rate) == 1);
  CHECK(gyrodrift::oadev_max_m(4, AllanInput::phase) == 1);
}

TEST_CASE("tau grids") {
  std::size_t out[64] = {};
  REQUIRE(gyrodrift::tau_grid(gyrodrift::TauGrid::octave, 100, 0, out, 64) == 7);
  CHECK(out[0] == 1);
  CHECK(out[6] == 64);
  REQUIRE(gyrodrift::tau_grid(gyrodrift::TauGrid::all, 5, 0, out, 64) == 5);
  CHECK(out[4] == 5);
  // decade, 4 per decade: round(10^(k/4)) = 1, 2, 3, 6, 10, 18, 32, 56, 100
  const std::size_t expect[] = {1, 2, 3, 6, 10, 18, 32, 56, 100};
  REQUIRE(gyrodrift::tau_grid(gyrodrift::TauGrid::decade, 100, 4, out, 64) == 9);
  for (std::size_t j = 0; j < 9; ++j) CHECK(out[j] == expect[j]);
  // duplicates removed at 10 per decade: 1, 2 (1.26 -> 1 dropped), ...
  const std::size_t n10 = gyrodrift::tau_grid(gyrodrift::TauGrid::decade, 1000, 10, out, 64);
  for (std::size_t j = 1; j < n10; ++j) CHECK(out[j] > out[j - 1]);
  CHECK(out[n10 - 1] == 1000);
  // capacity respected; huge max_m does not overflow the octave loop
  CHECK(gyrodrift::tau_grid(gyrodrift::TauGrid::octave, std::numeric_limits<std::size_t>::max(),
                            0, out, 64) == 64);
  CHECK(gyrodrift::tau_grid(gyrodrift::TauGrid::all, 1000, 0, out, 3) == 3);
}

TEST_CASE("no allocation") {
  const auto y = record(20000, 1.0, 7);
  std::size_t m[16] = {};
  double sigma2[16] = {};
  std::size_t terms[16] = {};
  gyrodrift::test::AllocationScope scope;
  const std::size_t n_m =
      gyrodrift::tau_grid(gyrodrift::TauGrid::octave, gyrodrift::oadev_max_m(y.size(),
                                                                             AllanInput::rate),
                          0, m, 16);
  const bool ok = gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, m, n_m, sigma2, terms);
  const long allocations = scope.allocations();
  CHECK(ok);
  CHECK(n_m == 14);
  CHECK(allocations == 0);
}

TEST_CASE("fused multi-tau kernel equals the per-tau kernel, drift included") {
  // Unit noise + random walk + offset 15; octave and dense factor sets, block sizes that do
  // and do not divide the record.
  auto y = record(200003, 15.0, 8);
  for (std::size_t i = 0; i < y.size(); ++i) y[i] += 1e-4 * static_cast<double>(i % 1000);
  for (const std::size_t block : {std::size_t{16}, std::size_t{1000}, std::size_t{4096}}) {
    std::size_t m[64] = {};
    const std::size_t n_m = gyrodrift::tau_grid(
        gyrodrift::TauGrid::octave, gyrodrift::oadev_max_m(y.size(), AllanInput::rate), 0, m,
        64);
    double per_tau[64] = {};
    double fused_out[64] = {};
    std::size_t t_per[64] = {};
    std::size_t t_fused[64] = {};
    REQUIRE(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, m, n_m, per_tau, t_per));
    auto fused = std::make_unique<gyrodrift::OadevFused<64>>();
    REQUIRE(fused->plan(y.size(), m, n_m, block));
    std::vector<double> work(fused->workspace_doubles());
    REQUIRE(fused->run(y.data(), work.data(), work.size(), fused_out, t_fused));
    for (std::size_t j = 0; j < n_m; ++j) {
      // fused: block-local double prefix sums (~B eps sigma each), long double carries;
      // measured agreement ~1e-14, bound 1e-12
      CHECK(fused_out[j] == doctest::Approx(per_tau[j]).epsilon(1e-12));
      CHECK(t_fused[j] == t_per[j]);
    }
  }
  // dense consecutive factors (one merged segment) against the definition
  const auto z = record(3000, -2.0, 9);
  std::size_t dense[40] = {};
  for (std::size_t j = 0; j < 40; ++j) dense[j] = 30 + j;
  gyrodrift::OadevFused<40> f40;
  REQUIRE(f40.plan(z.size(), dense, 40, 64));
  std::vector<double> work(f40.workspace_doubles());
  double out[40] = {};
  REQUIRE(f40.run(z.data(), work.data(), work.size(), out, static_cast<std::size_t*>(nullptr)));
  for (std::size_t j = 0; j < 40; ++j) {
    CHECK(out[j] == doctest::Approx(static_cast<double>(definition_sigma2(z, dense[j])))
                        .epsilon(1e-12));
  }
}

TEST_CASE("two cost-balanced fused groups equal the per-tau kernel") {
  auto y = record(300001, 15.0, 11);
  std::size_t m[64] = {};
  const std::size_t n_m = gyrodrift::tau_grid(
      gyrodrift::TauGrid::octave, gyrodrift::oadev_max_m(y.size(), AllanInput::rate), 0, m, 64);
  auto scratch = std::make_unique<gyrodrift::OadevFused<64>>();
  const std::size_t block = 4096;
  const std::size_t cut = gyrodrift::oadev_fused_cut(y.size(), m, n_m, block, *scratch);
  // the first group holds the short factors (one near segment), the second the long ones
  REQUIRE(cut > 0);
  REQUIRE(cut < n_m);
  CHECK(gyrodrift::oadev_fused_cut(y.size(), m, n_m, block, *scratch) == cut);  // deterministic
  double per_tau[64] = {};
  REQUIRE(gyrodrift::oadev(y.data(), y.size(), AllanInput::rate, m, n_m, per_tau,
                           static_cast<std::size_t*>(nullptr)));
  double out[64] = {};
  const std::size_t lo[2] = {0, cut};
  const std::size_t hi[2] = {cut, n_m};
  for (std::size_t g = 0; g < 2; ++g) {
    REQUIRE(scratch->plan(y.size(), m + lo[g], hi[g] - lo[g], block));
    std::vector<double> work(scratch->workspace_doubles());
    REQUIRE(scratch->run(y.data(), work.data(), work.size(), out + lo[g],
                         static_cast<std::size_t*>(nullptr)));
  }
  for (std::size_t j = 0; j < n_m; ++j) {
    // same bound as the one-group fused kernel above (measured ~1e-14)
    CHECK(out[j] == doctest::Approx(per_tau[j]).epsilon(1e-12));
  }
  // one factor: nothing to cut
  CHECK(gyrodrift::oadev_fused_cut(y.size(), m, 1, block, *scratch) == 1);
}

TEST_CASE("fused kernel rejects bad plans and data, allocates nothing") {
  auto y = record(10000, 0.0, 10);
  gyrodrift::OadevFused<8> f;
  const std::size_t unsorted[] = {4, 2};
  CHECK_FALSE(f.plan(y.size(), unsorted, 2, 64));
  const std::size_t too_many[9] = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  CHECK_FALSE(f.plan(y.size(), too_many, 9, 64));
  const std::size_t too_big[] = {5000};
  CHECK_FALSE(f.plan(y.size(), too_big, 1, 64));
  const std::size_t ok[] = {1, 16, 256};
  CHECK_FALSE(f.plan(y.size(), ok, 3, 8));  // block < 16
  REQUIRE(f.plan(y.size(), ok, 3, 256));
  std::vector<double> work(f.workspace_doubles());
  double out[3] = {-1.0, -1.0, -1.0};
  CHECK_FALSE(f.run(y.data(), work.data(), work.size() - 1, out,
                    static_cast<std::size_t*>(nullptr)));  // workspace too small
  {
    gyrodrift::test::AllocationScope scope;
    const bool ran = f.run(y.data(), work.data(), work.size(), out,
                           static_cast<std::size_t*>(nullptr));
    const long allocations = scope.allocations();
    CHECK(ran);
    CHECK(allocations == 0);
  }
  y[5000] = std::numeric_limits<double>::infinity();
  double out2[3] = {-1.0, -1.0, -1.0};
  CHECK_FALSE(f.run(y.data(), work.data(), work.size(), out2,
                    static_cast<std::size_t*>(nullptr)));
  CHECK(out2[0] == -1.0);
}

TEST_CASE("fused streaming API in term ranges equals run(), bit for bit") {
  const auto y = record(50000, 7.0, 11);
  std::size_t m[64] = {};
  const std::size_t n_m = gyrodrift::tau_grid(
      gyrodrift::TauGrid::octave, gyrodrift::oadev_max_m(y.size(), AllanInput::rate), 0, m, 64);
  auto whole = std::make_unique<gyrodrift::OadevFused<64>>();
  REQUIRE(whole->plan(y.size(), m, n_m, 256));
  std::vector<double> work(whole->workspace_doubles());
  double ref[64] = {};
  REQUIRE(whole->run(y.data(), work.data(), work.size(), ref,
                     static_cast<std::size_t*>(nullptr)));

  auto parts = std::make_unique<gyrodrift::OadevFused<64>>();
  REQUIRE(parts->plan(y.size(), m, n_m, 256));
  parts->reset_sums();
  parts->set_ramp(y.data(), y.data() + (y.size() - gyrodrift::fused_detail::kRampEnd),
                  y.size());
  for (std::size_t j = 0; j < n_m; ++j) {  // seeds in pieces of 100
    for (std::size_t k = 0; k < m[j]; k += 100) {
      parts->seed_add(j, y.data() + k, y.data() + m[j] + k, std::min<std::size_t>(100, m[j] - k));
    }
  }
  // Each range gets its own copies of the windows (as a file reader would), then they die.
  const std::size_t n_terms0 = parts->n_terms(0);
  CHECK_FALSE(parts->process_blocks(static_cast<const double* const*>(nullptr), 100, 200,
                                    work.data(), work.size()));  // not a block multiple
  for (std::size_t b0 = 0; b0 < n_terms0; b0 += 768) {
    const std::size_t b1 = std::min(b0 + 768, n_terms0);
    std::vector<std::vector<double>> windows(parts->segments());
    std::vector<const double*> bases(parts->segments());
    for (std::size_t k = 0; k < parts->segments(); ++k) {
      const std::size_t lo = b0 + parts->segment_start(k);
      const std::size_t hi = std::min(y.size(), b1 + parts->segment_start(k) +
                                                    parts->segment_span(k));
      if (hi > lo) windows[k].assign(y.begin() + static_cast<std::ptrdiff_t>(lo),
                                     y.begin() + static_cast<std::ptrdiff_t>(hi));
      bases[k] = windows[k].data();
    }
    REQUIRE(parts->process_blocks(bases.data(), b0, b1, work.data(), work.size()));
  }
  double got[64] = {};
  REQUIRE(parts->finish(got, static_cast<std::size_t*>(nullptr)));
  for (std::size_t j = 0; j < n_m; ++j) CHECK(got[j] == ref[j]);
}
