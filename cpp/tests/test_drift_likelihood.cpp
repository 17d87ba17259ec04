// Drift-model log-likelihood (filters/drift_likelihood.hpp): checks against closed forms that do not
// use the Kalman filter (white noise: iid Gaussian; pure AR(1)/AR(2), r = 0: the exact conditional
// decomposition with the stationary start), the Lyapunov equation of the initial covariance,
// the mean/stride/innovation outputs, the status codes, and that nothing is allocated.
#define EIGEN_RUNTIME_NO_MALLOC
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/drift_likelihood.hpp>
#include <limits>
#include <vector>

#include "alloc_counter.hpp"

namespace {

using gyrodrift::Ar2Status;
using gyrodrift::DriftLikelihoodSums;
using gyrodrift::DriftModelParams;
using gyrodrift::drift_likelihood;

constexpr double kLog2Pi = 1.8378770664093454835606594728112353;

// Deterministic pseudo-Gaussian (sum of 4 LCG uniforms, variance 1).
double gauss(std::uint32_t& s) {
  double acc = 0.0;
  for (int i = 0; i < 4; ++i) {
    s = s * 1664525u + 1013904223u;
    acc += static_cast<double>(s >> 8) / static_cast<double>(1u << 24) - 0.5;
  }
  return acc * std::sqrt(3.0);
}

std::vector<double> ar2_record(double a1, double a2, double q, double r, double mean, std::size_t n,
                               std::uint32_t seed) {
  std::vector<double> y(n);
  double x1 = 0.0, x2 = 0.0;
  for (std::size_t k = 0; k < 200 + n; ++k) {
    const double x = a1 * x1 + a2 * x2 + std::sqrt(q) * gauss(seed);
    x2 = x1;
    x1 = x;
    if (k >= 200) y[k - 200] = mean + x + std::sqrt(r) * gauss(seed);
  }
  return y;
}

double normal_logpdf(double e, double var) { return -0.5 * (kLog2Pi + std::log(var) + e * e / var); }

}  // namespace

TEST_CASE("stationary covariance solves the Lyapunov equation P = A P A^T + Q") {
  for (auto [a1, a2] : {std::pair{0.6868, -0.0213}, {1.6, -0.8}, {-0.034, 0.0252}, {0.2297, 0.1638}}) {
    double g0 = 0.0, g1 = 0.0;
    gyrodrift::drift_stationary_covariance(a1, a2, 0.7, g0, g1);
    // (A P A^T + Q): element 00 = a1^2 g0 + 2 a1 a2 g1 + a2^2 g0 + q, 01 = a1 g0 + a2 g1, 11 = g0
    CHECK(a1 * a1 * g0 + 2.0 * a1 * a2 * g1 + a2 * a2 * g0 + 0.7 == doctest::Approx(g0).epsilon(1e-13));
    CHECK(a1 * g0 + a2 * g1 == doctest::Approx(g1).epsilon(1e-13));
  }
}

TEST_CASE("white noise alone: the iid Gaussian log-likelihood") {
  const auto y = ar2_record(0.0, 0.0, 0.0, 2.5, 3.0, 5000, 11u);
  DriftLikelihoodSums<double> s;
  REQUIRE(drift_likelihood(y.data(), y.size(), 1, DriftModelParams<double>{0, 0, 0, 2.5, 3.0}, s) ==
          Ar2Status::ok);
  double ref = 0.0;
  for (double v : y) ref += normal_logpdf(v - 3.0, 2.5);
  CHECK(s.loglike() == doctest::Approx(ref).epsilon(1e-13));
}

TEST_CASE("pure AR(2) and AR(1) (r = 0): exact conditional decomposition with stationary start") {
  for (auto [a1, a2] : {std::pair{0.6868, -0.0213}, {1.6, -0.8}, {0.5, 0.0}}) {
    const double q = 0.3, mean = -1.0;
    const auto y = ar2_record(a1, a2, q, 0.0, mean, 4000, 5u);
    double g0 = 0.0, g1 = 0.0;
    gyrodrift::drift_stationary_covariance(a1, a2, q, g0, g1);
    // y1 ~ N(0, g0); y2 | y1 ~ N(g1/g0 y1, g0 - g1^2/g0); then e_k = x_k - a1 x_{k-1} - a2 x_{k-2}.
    const double z0 = y[0] - mean, z1 = y[1] - mean;
    double ref = normal_logpdf(z0, g0) + normal_logpdf(z1 - g1 / g0 * z0, g0 - g1 * g1 / g0);
    for (std::size_t k = 2; k < y.size(); ++k) {
      ref += normal_logpdf((y[k] - mean) - a1 * (y[k - 1] - mean) - a2 * (y[k - 2] - mean), q);
    }
    DriftLikelihoodSums<double> s;
    REQUIRE(drift_likelihood(y.data(), y.size(), 1, DriftModelParams<double>{a1, a2, q, 0.0, mean}, s) ==
            Ar2Status::ok);
    CHECK(s.loglike() == doctest::Approx(ref).epsilon(1e-11));
  }
}

TEST_CASE("mean shift from the sums, strided column, innovations, float") {
  const double a1 = 0.6868, a2 = -0.0213, q = 0.25, r = 0.09, mean = 40.0;
  const auto y = ar2_record(a1, a2, q, r, mean, 3000, 9u);
  DriftLikelihoodSums<double> s, s2;
  std::vector<double> innov(y.size());
  REQUIRE(drift_likelihood(y.data(), y.size(), 1, DriftModelParams<double>{a1, a2, q, r, mean}, s,
                           innov.data(), 1) == Ar2Status::ok);
  // log L(mean + d) from one pass at `mean` equals a second pass at mean + d.
  const double d = 0.37;
  REQUIRE(drift_likelihood(y.data(), y.size(), 1, DriftModelParams<double>{a1, a2, q, r, mean + d}, s2) ==
          Ar2Status::ok);
  const double shifted = -0.5 * (static_cast<double>(y.size()) * kLog2Pi + s.sum_log_f + s.sum_ee -
                                 2.0 * d * s.sum_eg + d * d * s.sum_gg);
  CHECK(shifted == doctest::Approx(s2.loglike()).epsilon(1e-12));
  double ss = 0.0;
  for (double e : innov) ss += e * e;
  CHECK(ss == doctest::Approx(s.sum_ee).epsilon(1e-12));
  CHECK(ss / static_cast<double>(y.size()) == doctest::Approx(1.0).epsilon(0.1));  // true model

  // Column 1 of an (n, 3) row-major array read in place equals the contiguous pass.
  std::vector<double> rows(3 * y.size(), std::numeric_limits<double>::quiet_NaN());
  for (std::size_t k = 0; k < y.size(); ++k) rows[3 * k + 1] = y[k];
  DriftLikelihoodSums<double> sc;
  REQUIRE(drift_likelihood(rows.data() + 1, y.size(), 3, DriftModelParams<double>{a1, a2, q, r, mean}, sc) ==
          Ar2Status::ok);
  CHECK(sc.loglike() == s.loglike());

  std::vector<float> yf(y.begin(), y.end());
  DriftLikelihoodSums<float> sf;
  REQUIRE(drift_likelihood(yf.data(), yf.size(), 1,
                           DriftModelParams<float>{0.6868f, -0.0213f, 0.25f, 0.09f, 40.0f}, sf) ==
          Ar2Status::ok);
  CHECK(static_cast<double>(sf.loglike()) == doctest::Approx(s.loglike()).epsilon(1e-4));
}

TEST_CASE("bad arguments are statuses, out untouched") {
  const auto y = ar2_record(0.5, 0.1, 1.0, 1.0, 0.0, 100, 3u);
  DriftLikelihoodSums<double> s;
  s.n = 12345;
  CHECK(drift_likelihood<double>(nullptr, 10, 1, {0.5, 0, 1, 1, 0}, s) == Ar2Status::bad_argument);
  CHECK(drift_likelihood(y.data(), 0, 1, DriftModelParams<double>{0.5, 0, 1, 1, 0}, s) == Ar2Status::bad_argument);
  CHECK(drift_likelihood(y.data(), 100, 0, DriftModelParams<double>{0.5, 0, 1, 1, 0}, s) == Ar2Status::bad_argument);
  CHECK(drift_likelihood(y.data(), 100, 1, DriftModelParams<double>{0.5, 0, -1, 1, 0}, s) == Ar2Status::bad_argument);
  CHECK(drift_likelihood(y.data(), 100, 1, DriftModelParams<double>{0.5, 0, 0, 0, 0}, s) == Ar2Status::bad_argument);
  CHECK(drift_likelihood(y.data(), 100, 1, DriftModelParams<double>{0.7, 0.3, 1, 1, 0}, s) ==
        Ar2Status::non_stationary);
  CHECK(drift_likelihood(y.data(), 100, 1, DriftModelParams<double>{0.5, 0, 1, std::nan(""), 0}, s) ==
        Ar2Status::non_finite);
  std::vector<double> bad(y);
  bad[50] = std::numeric_limits<double>::infinity();
  CHECK(drift_likelihood(bad.data(), 100, 1, DriftModelParams<double>{0.5, 0, 1, 1, 0}, s) == Ar2Status::non_finite);
  CHECK(s.n == 12345u);
}

TEST_CASE("the likelihood pass allocates nothing (double and float, 1e5 samples, with innovations)") {
  static double yd[100000];
  static float yf[100000];
  static double id[100000];
  static float ifl[100000];
  std::uint32_t seed = 1u;
  double x1 = 0.0;
  for (std::size_t k = 0; k < 100000; ++k) {
    x1 = 0.6868 * x1 + gauss(seed);
    yd[k] = x1 + gauss(seed);
    yf[k] = static_cast<float>(yd[k]);
  }
  DriftLikelihoodSums<double> sd;
  DriftLikelihoodSums<float> sf;
  gyrodrift::test::AllocationScope scope;
  Eigen::internal::set_is_malloc_allowed(false);
  const Ar2Status s1 = drift_likelihood(yd, 100000, 1, DriftModelParams<double>{0.6868, -0.0213, 1, 1, 0}, sd, id, 1);
  const Ar2Status s2 =
      drift_likelihood(yf, 100000, 1, DriftModelParams<float>{0.6868f, -0.0213f, 1.0f, 1.0f, 0.0f}, sf, ifl, 1);
  Eigen::internal::set_is_malloc_allowed(true);
  const long allocs = scope.allocations();
  CHECK(allocs == 0);
  CHECK(s1 == Ar2Status::ok);
  CHECK(s2 == Ar2Status::ok);
  CHECK(static_cast<double>(sf.loglike()) == doctest::Approx(sd.loglike()).epsilon(1e-5));
}

TEST_CASE("the pass over a record in pieces equals the one pass, bit for bit, however it is cut") {
  const double a1 = 0.6868, a2 = -0.0213, q = 0.25, r = 0.09, mean = 40.0;
  const auto y = ar2_record(a1, a2, q, r, mean, 5000, 21u);
  const DriftModelParams<double> p{a1, a2, q, r, mean};
  DriftLikelihoodSums<double> whole;
  std::vector<double> innov(y.size()), innov_pieces(y.size(), 0.0);
  REQUIRE(drift_likelihood(y.data(), y.size(), 1, p, whole, innov.data(), 1) == Ar2Status::ok);
  // Pieces shorter and longer than the 64-sample summation block, cut inside the covariance
  // recursion's first steps (before the latch) and after it.
  for (std::size_t piece : {std::size_t{1}, std::size_t{7}, std::size_t{64}, std::size_t{1000},
                            std::size_t{4999}}) {
    gyrodrift::DriftLikelihoodStream<double> stream;
    REQUIRE(stream.begin(p) == Ar2Status::ok);
    for (std::size_t lo = 0; lo < y.size(); lo += piece) {
      const std::size_t n = std::min(piece, y.size() - lo);
      REQUIRE(stream.update(y.data() + lo, n, 1, innov_pieces.data() + lo, 1) == Ar2Status::ok);
    }
    DriftLikelihoodSums<double> s;
    REQUIRE(stream.finish(s) == Ar2Status::ok);
    CHECK(s.n == whole.n);
    CHECK(s.sum_log_f == whole.sum_log_f);
    CHECK(s.sum_ee == whole.sum_ee);
    CHECK(s.sum_eg == whole.sum_eg);
    CHECK(s.sum_gg == whole.sum_gg);
    CHECK(innov_pieces == innov);
  }
  // A NaN in a later piece, and a piece before begin(), are statuses.
  gyrodrift::DriftLikelihoodStream<double> stream;
  CHECK(stream.update(y.data(), 10, 1) == Ar2Status::bad_argument);
  REQUIRE(stream.begin(p) == Ar2Status::ok);
  std::vector<double> bad(y.begin(), y.begin() + 100);
  bad[70] = std::numeric_limits<double>::quiet_NaN();
  REQUIRE(stream.update(bad.data(), 50, 1) == Ar2Status::ok);
  REQUIRE(stream.update(bad.data() + 50, 50, 1) == Ar2Status::ok);
  DriftLikelihoodSums<double> s;
  CHECK(stream.finish(s) == Ar2Status::non_finite);
}
