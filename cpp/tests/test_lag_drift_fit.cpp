// The drift-model fit from whole-record lag statistics (include/gyrodrift/filters/lag_drift_fit.hpp):
// the likelihood from the statistics against the exact Kalman likelihood on the samples
// (drift_likelihood.hpp), the fit recovering a simulated model and beating the truth's
// likelihood, the refusals (too few samples, non-finite statistics, bad parameters) as
// status codes with the statistics left usable, and no allocation during a fit; Whittle's
// likelihood without the first values (whittle_no_head) on the statistics without them
// against the full ones, the kinds those statistics refuse, and that kind's truncation guard.
// The equality with the numpy reference (likelihood and fit) is tested in
// tests/test_lag_drift_fit.py.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/drift_likelihood.hpp>
#include <gyrodrift/filters/lag_drift_fit.hpp>
#include <gyrodrift/filters/lag_statistics.hpp>
#include <string>
#include <utility>
#include <vector>

#include "alloc_counter.hpp"
#include "drift_test_support.hpp"

namespace {

constexpr std::size_t kLags = 32;
using Fit = gyrodrift::LagDriftFitStatus;

double exact_loglike(const std::vector<double>& y, const gyrodrift::DriftModelParams<double>& p) {
  gyrodrift::DriftLikelihoodSums<double> sums;
  REQUIRE(gyrodrift::drift_likelihood(y.data(), y.size(), 1, p, sums) == gyrodrift::Ar2Status::ok);
  return sums.loglike();
}

}  // namespace

TEST_CASE("likelihood from the statistics equals the exact Kalman likelihood of the samples") {
  // At L = 32 the neglected terms are of order rho^32 per sample, rho <= 0.44 for these
  // models (r/q <= 3): 4e-12 per sample, 1e-7 in all against a log-likelihood of order
  // 3e4 here; the sums themselves agree to about 1e-15 relative. So 1e-11 relative.
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 3.0, 9.7, 20000, 1);
  gyrodrift::LagStatistics<double, kLags> st;
  REQUIRE(st.push(y.data(), y.size()) == y.size());
  const gyrodrift::DriftModelParams<double> models[] = {
      {0.6868, -0.0213, 1.0, 3.0, 9.7}, {0.5, 0.1, 2.0, 1.0, 9.5}, {0.9, -0.2, 0.5, 4.0, 10.0}};
  for (const auto& p : models) {
    double ll = 0.0;
    REQUIRE(gyrodrift::lag_drift_loglike(st, p, ll) == Fit::ok);
    const double want = exact_loglike(y, p);
    CHECK(std::fabs(ll - want) <= 1e-11 * std::fabs(want));
    // The profile at the same (a1, a2, split) is the maximum over the mean and the scale:
    // at least the likelihood at these q, r and mean.
    gyrodrift::LagDriftProfile<double> prof;
    REQUIRE(gyrodrift::lag_drift_profile(st, p.a1, p.a2, p.q / (p.q + p.r), prof) == Fit::ok);
    CHECK(prof.loglike >= ll);
    double at_profile = 0.0;
    REQUIRE(gyrodrift::lag_drift_loglike(st, gyrodrift::DriftModelParams<double>{p.a1, p.a2, prof.q, prof.r, prof.mean},
                                         at_profile) == Fit::ok);
    CHECK(std::fabs(at_profile - prof.loglike) <= 1e-12 * std::fabs(prof.loglike));
  }
}

TEST_CASE("the fit recovers a simulated model") {
  // 60000 samples of the pair (0.2297, 0.1638) at r/q = 1: the offline standard errors are
  // about 0.03 for a1 and a2 and 5 % for q and r, so 0.15 and 30 % are 5 or more of them.
  // The fit is a maximum: its exact likelihood on the samples is at least the truth's.
  const auto y = drift_test::record(0.2297, 0.1638, 1.0, 1.0, 9.7, 60000, 2);
  gyrodrift::LagStatistics<float, kLags> st;
  std::vector<float> yf(y.begin(), y.end());
  REQUIRE(st.push(yf.data(), yf.size()) == yf.size());
  const auto fit = gyrodrift::lag_drift_fit<double>(st);
  REQUIRE(fit.status == Fit::ok);
  MESSAGE("a1 " << fit.model.a1 << " a2 " << fit.model.a2 << " q " << fit.model.q << " r " << fit.model.r
                << " iterations " << fit.iterations << " evaluations " << fit.evaluations);
  CHECK(std::fabs(fit.model.a1 - 0.2297) < 0.15);
  CHECK(std::fabs(fit.model.a2 - 0.1638) < 0.15);
  CHECK(std::fabs(fit.model.q - 1.0) < 0.3);
  CHECK(std::fabs(fit.model.r - 1.0) < 0.3);
  CHECK(std::fabs(fit.model.mean - 9.7) < 0.1);
  CHECK(fit.truncation < gyrodrift::kLagDriftTruncationTol);
  CHECK(fit.runs >= 4);
  CHECK(fit.evaluations > 100);
  std::vector<double> yd(yf.begin(), yf.end());
  CHECK(exact_loglike(yd, fit.model) >= exact_loglike(yd, {0.2297, 0.1638, 1.0, 1.0, 9.7}));
  double ll = 0.0;
  REQUIRE(gyrodrift::lag_drift_loglike(st, fit.model, ll) == Fit::ok);
  CHECK(std::fabs(ll - fit.loglike) <= 1e-12 * std::fabs(ll));
}

TEST_CASE("refusals are status codes and leave the statistics usable") {
  gyrodrift::LagStatistics<float, kLags> st;
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 1.0, 0.0, 4000, 3);
  // 2 L + 2 = 66 samples are the minimum.
  for (std::size_t i = 0; i < 65; ++i) st.push(static_cast<float>(y[i]));
  auto fit = gyrodrift::lag_drift_fit<double>(st);
  CHECK(fit.status == Fit::too_few_samples);
  CHECK(fit.evaluations == 0);
  double ll = 0.0;
  CHECK(gyrodrift::lag_drift_loglike(st, gyrodrift::DriftModelParams<double>{0.5, 0.0, 1.0, 1.0, 0.0}, ll) ==
        Fit::too_few_samples);
  st.push(static_cast<float>(y[65]));
  CHECK(gyrodrift::lag_drift_loglike(st, gyrodrift::DriftModelParams<double>{0.5, 0.0, 1.0, 1.0, 0.0}, ll) == Fit::ok);
  // Parameters outside the model.
  CHECK(gyrodrift::lag_drift_loglike(st, gyrodrift::DriftModelParams<double>{1.2, 0.0, 1.0, 1.0, 0.0}, ll) ==
        Fit::bad_model);
  CHECK(gyrodrift::lag_drift_loglike(st, gyrodrift::DriftModelParams<double>{0.5, 0.0, 1.0, 0.0, 0.0}, ll) ==
        Fit::bad_model);
  CHECK(gyrodrift::lag_drift_loglike(st, gyrodrift::DriftModelParams<double>{0.5, 0.0, NAN, 1.0, 0.0}, ll) ==
        Fit::non_finite);
  gyrodrift::LagDriftProfile<double> prof;
  CHECK(gyrodrift::lag_drift_profile(st, 0.5, 0.0, 1.0, prof) == Fit::bad_model);
  // The statistics are untouched: pushing on and fitting works.
  for (std::size_t i = 66; i < y.size(); ++i) st.push(static_cast<float>(y[i]));
  fit = gyrodrift::lag_drift_fit<double>(st);
  CHECK((fit.status == Fit::ok || fit.status == Fit::truncation));
  CHECK(std::isfinite(fit.model.a1));
  // Statistics whose sums overflowed in float (every sample finite, every w^2 finite, their
  // sum not): non_finite, no fit attempted.
  gyrodrift::LagStatistics<float, kLags> big;
  big.push(0.0F);
  for (int i = 0; i < 100; ++i) big.push(i % 2 == 0 ? 1.5e19F : -1.5e19F);
  REQUIRE(big.samples() == 101);
  REQUIRE(!std::isfinite(big.product(0).value()));
  fit = gyrodrift::lag_drift_fit<double>(big);
  CHECK(fit.status == Fit::non_finite);
  CHECK(fit.evaluations == 0);
  CHECK(gyrodrift::lag_drift_loglike(big, gyrodrift::DriftModelParams<double>{0.5, 0.0, 1.0, 1.0, 0.0}, ll) ==
        Fit::non_finite);
}

TEST_CASE("a model the lags are too short for is reported as truncation") {
  // AR(1) drift at 0.9 with r/q = 10: the innovation filter's pole is about 0.71, so
  // rho^32 is about 2e-5, far above 1e-10. The estimate is still returned.
  const auto y = drift_test::record(0.9, 0.0, 1.0, 10.0, 0.0, 20000, 6);
  gyrodrift::LagStatistics<double, kLags> st;
  st.push(y.data(), y.size());
  const auto fit = gyrodrift::lag_drift_fit<double>(st);
  CHECK(fit.status == Fit::truncation);
  CHECK(fit.truncation > 1e-7);
  CHECK(fit.truncation < 1.0);
  CHECK(std::fabs(fit.model.a1 + fit.model.a2 - 0.9) < 0.1);
}

namespace {

// The steady state by iterating the Riccati recursion (prediction form, stationary start) in
// long double, until the innovation variance F changes by at most 1e-18 relative on two
// steps in a row (with a1 = 0 the even and odd samples are two independent chains and F can
// stay the same for one step), at most 10^6 steps: F and the gain (k0, k1) there.
struct IteratedSteady {
  long double f = 0.0L, k0 = 0.0L, k1 = 0.0L;
};
IteratedSteady iterate_riccati(long double a1, long double a2, long double q, long double r) {
  IteratedSteady out;
  long double p00 = 0.0L, p01 = 0.0L, p11 = 0.0L;
  if (q > 0.0L) {
    p00 = q * (1.0L - a2) / ((1.0L + a2) * ((1.0L - a2) * (1.0L - a2) - a1 * a1));
    p01 = a1 * p00 / (1.0L - a2);
    p11 = p00;
  }
  long double f_prev = -1.0L;
  bool small_before = false;
  for (long step = 0; step < 1000000; ++step) {
    out.f = p00 + r;
    out.k0 = p00 / out.f;
    out.k1 = p01 / out.f;
    const bool small = std::fabs(out.f - f_prev) <= 1e-18L * out.f;
    if (small && small_before) break;
    small_before = small;
    f_prev = out.f;
    const long double u00 = p00 - out.k0 * p00, u01 = p01 - out.k0 * p01, u11 = p11 - out.k1 * p01;
    p00 = a1 * a1 * u00 + 2.0L * a1 * a2 * u01 + a2 * a2 * u11 + q;
    p01 = a1 * u00 + a2 * u01;
    p11 = u00;
  }
  return out;
}

}  // namespace

TEST_CASE("the steady state in closed form equals the iterated Riccati recursion") {
  // lag_innovation_factor (Whittle's kinds' sigma^2 and B, hence the innovation filter's
  // impulse response A / B) against the recursion the exact kind iterates, run to its fixed
  // point in long double, on a grid of (a1, a2): the stationary triangle in steps (a2 = 0
  // included, a1 = 0 too), complex pole pairs of modulus 0.99 and 0.995 at four angles, a
  // real double pole at +-0.99 and real poles 0.995 and -0.3; with q/r from 0 (q = 0: B = A,
  // sigma^2 = r) through 1e-6 to 100, and r = 0 (B = 1, sigma^2 = q). sigma^2 to 1e-12
  // relative and pi_0..pi_32 (pi_0 = 1) to 1e-12 absolute. Double rounding of the closed form
  // is some eps amplified by 1 / s_i (s_i down to about 0.005 on this grid, where the poles
  // of B come within 0.01 of the unit circle): observed 5e-14 against this recursion, and the
  // same against the closed form in 50-digit arithmetic (a numpy/mpmath check of the formula,
  // not kept). 190 models, 1330 cases.
  std::vector<std::pair<double, double>> models;
  for (int i = -9; i <= 9; ++i) {
    for (int j = -9; j <= 9; ++j) {
      const double a1 = 0.22 * i, a2 = 0.105 * j;
      if (std::fabs(a1) < 1.0 - a2 - 1e-9 && a2 > -1.0 + 1e-9) models.emplace_back(a1, a2);
    }
  }
  for (const double rho : {0.99, 0.995}) {
    for (const double angle : {0.3, 1.0, 2.0, 3.0}) models.emplace_back(2.0 * rho * std::cos(angle), -rho * rho);
  }
  models.emplace_back(1.98, -0.9801);
  models.emplace_back(-1.98, -0.9801);
  models.emplace_back(0.995 - 0.3, 0.995 * 0.3);
  for (const double a1 : {-0.9, -0.3, 0.0, 0.3, 0.6868, 0.99}) models.emplace_back(a1, 0.0);
  REQUIRE(models.size() > 180);
  double worst_s2 = 0.0, worst_pi = 0.0;
  for (const auto& [a1, a2] : models) {
    REQUIRE(gyrodrift::ar2_is_stationary(a1, a2));
    for (const double ratio : {0.0, 1e-6, 1e-4, 1e-2, 1.0, 100.0, -1.0}) {
      const double q = ratio < 0.0 ? 1.0 : ratio, r = ratio < 0.0 ? 0.0 : 1.0;  // -1: r = 0
      double s2 = 0.0, b1 = 0.0, b2 = 0.0;
      REQUIRE(gyrodrift::detail::lag_innovation_factor(a1, a2, q, r, s2, b1, b2));
      const IteratedSteady it = iterate_riccati(a1, a2, q, r);
      worst_s2 = std::max(worst_s2, static_cast<double>(std::fabs(s2 - it.f) / it.f));
      // Impulse responses: A / B from (b1, b2), and the steady filter's from its gain.
      long double x0 = 0.0L, x1 = 0.0L;
      double p1 = 0.0, p2 = 0.0;
      for (int t = 0; t <= 32; ++t) {
        const long double e = (t == 0 ? 1.0L : 0.0L) - x0;
        const long double u0 = x0 + it.k0 * e, u1 = x1 + it.k1 * e;
        x0 = a1 * u0 + a2 * u1;
        x1 = u0;
        const double alpha = t == 0 ? 1.0 : (t == 1 ? -a1 : (t == 2 ? -a2 : 0.0));
        const double v = alpha - b1 * p1 - b2 * p2;
        p2 = p1;
        p1 = v;
        worst_pi = std::max(worst_pi, static_cast<double>(std::fabs(v - e)));
      }
    }
  }
  CHECK(worst_s2 <= 1e-12);
  CHECK(worst_pi <= 1e-12);
  // Not a model: q = r = 0.
  double s2 = 0.0, b1 = 0.0, b2 = 0.0;
  CHECK_FALSE(gyrodrift::detail::lag_innovation_factor(0.5, 0.1, 0.0, 0.0, s2, b1, b2));
}

TEST_CASE("a float fit compiles and refuses like the double one") {
  // The fit's scalar is meant to be double; a float instantiation builds and keeps its
  // contract (status codes, no crash), whatever its accuracy.
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 1.0, 0.0, 5000, 7);
  std::vector<float> yf(y.begin(), y.end());
  gyrodrift::LagStatistics<float, kLags> st;
  st.push(yf.data(), 40);
  CHECK(gyrodrift::lag_drift_fit<float>(st).status == Fit::too_few_samples);
  st.push(yf.data() + 40, yf.size() - 40);
  const auto fit = gyrodrift::lag_drift_fit<float>(st);
  CHECK(fit.status != Fit::too_few_samples);
  CHECK(fit.evaluations > 0);
}

TEST_CASE("no allocation during a fit") {
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 1.0, 0.0, 20000, 4);
  std::vector<float> yf(y.begin(), y.end());
  gyrodrift::LagStatistics<float, kLags> st;
  st.push(yf.data(), yf.size());
  gyrodrift::test::AllocationScope scope;
  const auto fit = gyrodrift::lag_drift_fit<double>(st);
  double ll = 0.0;
  const Fit ls = gyrodrift::lag_drift_loglike(st, fit.model, ll, gyrodrift::LagLikelihoodKind::whittle);
  const long allocations = scope.allocations();
  CHECK(fit.status != Fit::non_finite);
  CHECK(ls == Fit::ok);
  CHECK(allocations == 0);
}

TEST_CASE("without the first values: the same likelihood and fit as the full statistics") {
  // whittle_no_head reads no first values, and the two forms hold the same sums and last
  // values bit for bit (test_lag_statistics.cpp): the same numbers, exactly.
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 3.0, 9.7, 30000, 8);
  std::vector<float> yf(y.begin(), y.end());
  gyrodrift::LagStatistics<float, 12> full;
  gyrodrift::LagStatisticsNoHead<float, 12> compact;
  full.push(yf.data(), yf.size());
  compact.push(yf.data(), yf.size());
  const auto kind = gyrodrift::LagLikelihoodKind::whittle_no_head;
  const gyrodrift::DriftModelParams<double> p{0.6, 0.05, 1.2, 2.5, 9.6};
  double ll_full = 0.0, ll_compact = 0.0;
  REQUIRE(gyrodrift::lag_drift_loglike(full, p, ll_full, kind) == Fit::ok);
  REQUIRE(gyrodrift::lag_drift_loglike(compact, p, ll_compact) == Fit::ok);  // the default kind there
  CHECK(ll_full == ll_compact);
  // Not Whittle's with the first values: the mean's correction differs.
  double ll_whittle = 0.0;
  REQUIRE(gyrodrift::lag_drift_loglike(full, p, ll_whittle, gyrodrift::LagLikelihoodKind::whittle) == Fit::ok);
  CHECK(ll_whittle != ll_full);
  const auto a = gyrodrift::lag_drift_fit<double>(full, kind);
  const auto b = gyrodrift::lag_drift_fit<double>(compact);
  CHECK(a.status == Fit::ok);
  CHECK(b.status == a.status);
  CHECK(b.model.a1 == a.model.a1);
  CHECK(b.model.a2 == a.model.a2);
  CHECK(b.model.q == a.model.q);
  CHECK(b.model.r == a.model.r);
  CHECK(b.model.mean == a.model.mean);
  CHECK(b.loglike == a.loglike);
  CHECK(b.evaluations == a.evaluations);
  // 30000 samples at r/q = 3: standard errors of about 0.07 for a1 and a2, 10 % for q and r.
  CHECK(std::fabs(b.model.a1 - 0.6868) < 0.25);
  CHECK(std::fabs(b.model.r - 3.0) < 0.9);
}

TEST_CASE("without the first values: the kinds that need them are refused") {
  const auto y = drift_test::record(0.2297, 0.1638, 1.0, 1.0, 0.0, 2000, 9);
  gyrodrift::LagStatisticsNoHead<double, 8> st;
  st.push(y.data(), y.size());
  const gyrodrift::DriftModelParams<double> p{0.2, 0.1, 1.0, 1.0, 0.0};
  double ll = 0.0;
  gyrodrift::LagDriftProfile<double> prof;
  for (const auto kind : {gyrodrift::LagLikelihoodKind::exact, gyrodrift::LagLikelihoodKind::whittle}) {
    CHECK(gyrodrift::lag_drift_loglike(st, p, ll, kind) == Fit::needs_head);
    CHECK(gyrodrift::lag_drift_profile(st, 0.2, 0.1, 0.5, prof, kind) == Fit::needs_head);
    const auto fit = gyrodrift::lag_drift_fit<double>(st, kind);
    CHECK(fit.status == Fit::needs_head);
    CHECK(fit.evaluations == 0);
  }
  // Refused before the sample count is looked at.
  gyrodrift::LagStatisticsNoHead<double, 8> empty;
  CHECK(gyrodrift::lag_drift_fit<double>(empty, gyrodrift::LagLikelihoodKind::exact).status == Fit::needs_head);
  CHECK(gyrodrift::lag_drift_fit<double>(empty).status == Fit::too_few_samples);
  CHECK(gyrodrift::lag_drift_profile(st, 0.2, 0.1, 0.5, prof) == Fit::ok);
  CHECK(std::string(gyrodrift::to_string(Fit::needs_head)) == "needs the first samples");
}

TEST_CASE("whittle_no_head: its truncation tolerance") {
  // The pair (0.6868, -0.0213) at r/q = 3: rho about 0.43, so rho^4 is about 0.03 (over the
  // kind's 3e-3: refused, the estimate still returned) and rho^8 about 1.2e-3 (under it).
  // The exact kind's 1e-10 would refuse both.
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 3.0, 0.0, 60000, 10);
  gyrodrift::LagStatisticsNoHead<double, 4> short_lags;
  gyrodrift::LagStatisticsNoHead<double, 8> enough;
  short_lags.push(y.data(), y.size());
  enough.push(y.data(), y.size());
  const auto a = gyrodrift::lag_drift_fit<double>(short_lags);
  const auto b = gyrodrift::lag_drift_fit<double>(enough);
  CHECK(a.status == Fit::truncation);
  CHECK(a.truncation > gyrodrift::kLagDriftWhittleNoHeadTruncationTol);
  CHECK(std::isfinite(a.model.a1));
  CHECK(b.status == Fit::ok);
  CHECK(b.truncation <= gyrodrift::kLagDriftWhittleNoHeadTruncationTol);
  CHECK(b.truncation > gyrodrift::kLagDriftTruncationTol);
  CHECK(gyrodrift::lag_drift_truncation_tol(gyrodrift::LagLikelihoodKind::whittle) ==
        gyrodrift::kLagDriftTruncationTol);
}

TEST_CASE("no allocation during a fit without the first values") {
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 1.0, 0.0, 20000, 4);
  std::vector<float> yf(y.begin(), y.end());
  gyrodrift::LagStatisticsNoHead<float, 8> st;
  st.push(yf.data(), yf.size());
  gyrodrift::test::AllocationScope scope;
  const auto fit = gyrodrift::lag_drift_fit<double>(st);
  const long allocations = scope.allocations();
  CHECK(fit.status == Fit::ok);
  CHECK(allocations == 0);
}
