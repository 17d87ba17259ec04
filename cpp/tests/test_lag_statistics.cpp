// Whole-record lag statistics (include/gyrodrift/filters/lag_statistics.hpp) against their
// definition (sums over the whole record in long double), a hand-checked short record, chunked
// pushes against single pushes, refusal of non-finite samples, float against double on a long
// record (and against a plain float sum), state size, and no allocation; the form without the
// first values against the full one. The equality with the
// numpy reference and the fit on these statistics are tested in tests/test_lag_statistics.py.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/lag_statistics.hpp>
#include <limits>
#include <vector>

#include "alloc_counter.hpp"
#include "drift_test_support.hpp"

namespace {

constexpr std::size_t kLags = 32;

template <class Scalar, std::size_t L>
bool same_state(const gyrodrift::LagStatistics<Scalar, L>& a, const gyrodrift::LagStatistics<Scalar, L>& b) {
  // Bitwise-equal values (no tolerance): the same operations in the same order.
  bool same = a.samples() == b.samples() && a.rejected() == b.rejected() && a.kept() == b.kept() &&
              a.centre() == b.centre() && a.total().sum == b.total().sum && a.total().comp == b.total().comp;
  for (std::size_t k = 0; k <= L; ++k) {
    same = same && a.product(k).sum == b.product(k).sum && a.product(k).comp == b.product(k).comp;
  }
  for (std::size_t i = 0; i < a.kept(); ++i) same = same && a.head(i) == b.head(i) && a.tail(i) == b.tail(i);
  return same;
}

}  // namespace

TEST_CASE("state size") {
  CHECK(sizeof(gyrodrift::LagStatistics<float, kLags>) <= 552);
  CHECK(sizeof(gyrodrift::LagStatistics<double, kLags>) <= 1080);
}

TEST_CASE("state size without the first values") {
  // 2 (L + 1) + 2 + L + 1 floats and 16 bytes of counters, padded to 8: at L = 8,
  // 18 + 2 + 8 + 1 = 29 floats (116 B) + 16 = 132 -> 136; at L = 12, 41 floats (164 B) + 16 =
  // 180 -> 184. The Cortex-M4 gate's cost unit prints the same sizes there
  // (scripts/lag_drift_fit_cost.py).
  CHECK(sizeof(gyrodrift::LagStatisticsNoHead<float, 8>) == 136);
  CHECK(sizeof(gyrodrift::LagStatisticsNoHead<float, 12>) == 184);
  CHECK(sizeof(gyrodrift::LagStatistics<float, 8>) == 168);  // the full form: 8 more floats
  CHECK(!gyrodrift::LagStatisticsNoHead<float, 8>::keeps_head);
  CHECK(gyrodrift::LagStatistics<float, 8>::keeps_head);
}

TEST_CASE("without the first values: the same sums and last values as the full form") {
  // The same operations in the same order, so bitwise equal, in float and double, also with
  // fewer samples than lags and with a refused sample.
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 3.0, 9.7, 3000, 5);
  std::vector<float> yf(y.begin(), y.end());
  gyrodrift::LagStatistics<float, 8> full;
  gyrodrift::LagStatisticsNoHead<float, 8> compact;
  gyrodrift::LagStatistics<double, 12> full_d;
  gyrodrift::LagStatisticsNoHead<double, 12> compact_d;
  auto same = [](const auto& a, const auto& b) {
    bool eq = a.samples() == b.samples() && a.rejected() == b.rejected() && a.kept() == b.kept() &&
              a.centre() == b.centre() && a.total().sum == b.total().sum && a.total().comp == b.total().comp;
    for (std::size_t k = 0; k <= a.lags; ++k) {
      eq = eq && a.product(k).sum == b.product(k).sum && a.product(k).comp == b.product(k).comp;
    }
    for (std::size_t i = 0; i < a.kept(); ++i) eq = eq && a.tail(i) == b.tail(i);
    return eq;
  };
  for (std::size_t i = 0; i < 5; ++i) {
    full.push(yf[i]);
    compact.push(yf[i]);
    full_d.push(y[i]);
    compact_d.push(y[i]);
  }
  CHECK(compact.kept() == 5);
  CHECK(same(full, compact));
  CHECK(same(full_d, compact_d));
  CHECK(!compact.push(std::numeric_limits<float>::quiet_NaN()));
  full.push(std::numeric_limits<float>::quiet_NaN());
  CHECK(full.push(yf.data() + 5, yf.size() - 5) == compact.push(yf.data() + 5, yf.size() - 5));
  CHECK(full_d.push(y.data() + 5, y.size() - 5) == compact_d.push(y.data() + 5, y.size() - 5));
  CHECK(compact.rejected() == 1);
  CHECK(same(full, compact));
  CHECK(same(full_d, compact_d));
  compact.reset();
  CHECK(compact.samples() == 0);
  CHECK(compact.rejected() == 0);
  CHECK(compact.product(0).value() == 0.0F);
}

TEST_CASE("a short record by hand: w = 0, 1, 3, 2") {
  gyrodrift::LagStatistics<double, 2> st;
  const double y[] = {1.0, 2.0, 4.0, 3.0};
  CHECK(st.push(y, 4) == 4);
  CHECK(st.samples() == 4);
  CHECK(st.centre() == 1.0);
  CHECK(st.total().value() == 6.0);
  CHECK(st.product(0).value() == 14.0);  // 0 + 1 + 9 + 4
  CHECK(st.product(1).value() == 9.0);   // 1*0 + 3*1 + 2*3
  CHECK(st.product(2).value() == 2.0);   // 3*0 + 2*1
  CHECK(st.product(3).value() == 0.0);   // beyond Lags
  REQUIRE(st.kept() == 2);
  CHECK(st.head(0) == 0.0);
  CHECK(st.head(1) == 1.0);
  CHECK(st.tail(0) == 3.0);
  CHECK(st.tail(1) == 2.0);
  CHECK(st.tail(2) == 0.0);  // beyond kept()
}

TEST_CASE("fewer samples than lags: head and tail hold all of them") {
  gyrodrift::LagStatistics<double, 4> st;
  const double y[] = {5.0, 7.0, 4.0};  // w = 0, 2, -1
  CHECK(st.push(y, 3) == 3);
  REQUIRE(st.kept() == 3);
  for (std::size_t i = 0; i < 3; ++i) {
    CHECK(st.head(i) == y[i] - 5.0);
    CHECK(st.tail(i) == y[i] - 5.0);
  }
  CHECK(st.product(0).value() == 5.0);
  CHECK(st.product(1).value() == -2.0);
  CHECK(st.product(2).value() == 0.0);
  CHECK(st.product(3).value() == 0.0);
}

TEST_CASE("double equals the definition on a drift record") {
  // AR(2) drift (0.6868, -0.0213) + white noise on a mean of 9.7, 100003 samples (the ring
  // wraps at a sample count that is not a multiple of Lags). Reference: the definition
  // summed in long double (64-bit mantissa on x86-64: rounding of a sum of 1e5 terms well
  // below 1e-13 of it); the compensated double sums are within a few eps: 1e-13 relative to
  // P_0 (the lag products can be small against P_0; their error scales with P_0).
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 3.0, 9.7, 100003, 5);
  gyrodrift::LagStatistics<double, kLags> st;
  CHECK(st.push(y.data(), y.size()) == y.size());
  const std::size_t n = y.size();
  const double c = y[0];
  std::vector<double> w(n);
  for (std::size_t t = 0; t < n; ++t) w[t] = y[t] - c;
  CHECK(st.samples() == n);
  CHECK(st.centre() == c);
  long double total = 0.0L;
  for (double v : w) total += static_cast<long double>(v);
  long double p0 = 0.0L;
  for (double v : w) p0 += static_cast<long double>(v) * static_cast<long double>(v);
  const double scale = static_cast<double>(p0);
  CHECK(std::fabs(st.total().value() - static_cast<double>(total)) <= 1e-13 * std::sqrt(scale * static_cast<double>(n)));
  for (std::size_t k = 0; k <= kLags; ++k) {
    long double pk = 0.0L;
    for (std::size_t t = k; t < n; ++t) pk += static_cast<long double>(w[t]) * static_cast<long double>(w[t - k]);
    CHECK(std::fabs(st.product(k).value() - static_cast<double>(pk)) <= 1e-13 * scale);
  }
  REQUIRE(st.kept() == kLags);
  for (std::size_t i = 0; i < kLags; ++i) {
    CHECK(st.head(i) == w[i]);  // the same subtraction: exact equality
    CHECK(st.tail(i) == w[n - kLags + i]);
  }
}

TEST_CASE("chunked pushes equal single pushes, float and double") {
  const auto y = drift_test::record(0.2297, 0.1638, 1.0, 1.0, -3.0, 5000, 2);
  std::vector<float> yf(y.begin(), y.end());
  gyrodrift::LagStatistics<double, kLags> one, chunked;
  gyrodrift::LagStatistics<float, kLags> one_f, chunked_f;
  for (double v : y) one.push(v);
  for (float v : yf) one_f.push(v);
  // uneven chunks: empty, shorter than Lags, exactly Lags, one more, the rest
  const std::size_t edges[] = {0, 0, 1, 8, 40, 72, 105, 2000, y.size()};
  for (std::size_t i = 0; i + 1 < sizeof(edges) / sizeof(edges[0]); ++i) {
    const std::size_t len = edges[i + 1] - edges[i];
    CHECK(chunked.push(y.data() + edges[i], len) == len);
    CHECK(chunked_f.push(yf.data() + edges[i], len) == len);
  }
  CHECK(same_state(one, chunked));
  CHECK(same_state(one_f, chunked_f));
}

TEST_CASE("non-finite samples are refused and leave the statistics unchanged") {
  const float bad[] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                       -std::numeric_limits<float>::infinity()};
  gyrodrift::LagStatistics<float, 4> st, ref;
  // before the first sample: no centre is taken from a refused one
  for (float b : bad) CHECK_FALSE(st.push(b));
  CHECK(st.samples() == 0);
  CHECK(st.rejected() == 3);
  const float good[] = {2.0F, 3.5F, 1.0F, 2.5F, 4.0F, 0.5F};
  for (float g : good) {
    CHECK(st.push(g));
    ref.push(g);
    for (float b : bad) CHECK_FALSE(st.push(b));
  }
  CHECK_FALSE(st.push(3e19F));  // finite, but (y - c)^2 overflows float
  CHECK(st.rejected() == 3 + 3 * 6 + 1);
  CHECK(ref.rejected() == 0);
  // the refused samples changed nothing but the count
  CHECK(st.samples() == ref.samples());
  CHECK(st.centre() == ref.centre());
  CHECK(st.total().value() == ref.total().value());
  for (std::size_t k = 0; k <= 4; ++k) CHECK(st.product(k).value() == ref.product(k).value());
  for (std::size_t i = 0; i < 4; ++i) {
    CHECK(st.head(i) == ref.head(i));
    CHECK(st.tail(i) == ref.tail(i));
  }
  st.reset();
  CHECK(st.samples() == 0);
  CHECK(st.rejected() == 0);
  CHECK(st.product(0).value() == 0.0F);
}

TEST_CASE("float against double after 1e6 samples, and against a plain float sum") {
  // The same float samples into both. Bound (header): |P_k(float) - P_k(double)| <=
  // (3u + O(n u^2)) P_0 with u = 2^-24 (rounding of w_t and of each product, the pair sums'
  // own rounding of order n u^2 = 6e-9 here): 4u = 2.4e-7 relative to P_0. sum w: each w_t
  // is rounded once (u |w_t|). Head and tail: |dw| <= u |w|.
  constexpr std::size_t n = 1000000;
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 3.0, 9.7, n, 7);
  std::vector<float> yf(y.begin(), y.end());
  gyrodrift::LagStatistics<float, kLags> f;
  gyrodrift::LagStatistics<double, kLags> d;
  CHECK(f.push(yf.data(), n) == n);
  for (float v : yf) d.push(static_cast<double>(v));
  const double u = 0x1.0p-24;
  const double p0 = d.product(0).value();
  double worst = 0.0;
  for (std::size_t k = 0; k <= kLags; ++k) {
    const double fk = static_cast<double>(f.product(k).sum) + static_cast<double>(f.product(k).comp);
    const double e = std::fabs(fk - d.product(k).value()) / p0;
    worst = e > worst ? e : worst;
  }
  MESSAGE("float vs double, largest |dP_k| / P_0 over k = 0..32: " << worst);
  CHECK(worst <= 4.0 * u);
  double abs_w = 0.0;
  for (std::size_t i = 0; i < n; ++i) abs_w += std::fabs(static_cast<double>(yf[i]) - static_cast<double>(yf[0]));
  const double ft = static_cast<double>(f.total().sum) + static_cast<double>(f.total().comp);
  CHECK(std::fabs(ft - d.total().value()) <= 2.0 * u * abs_w);
  for (std::size_t i = 0; i < kLags; ++i) {
    CHECK(std::fabs(static_cast<double>(f.head(i)) - d.head(i)) <= u * std::fabs(d.head(i)));
    CHECK(std::fabs(static_cast<double>(f.tail(i)) - d.tail(i)) <= u * std::fabs(d.tail(i)));
  }
  // A plain float sum of the same products: the compensation is what keeps float usable.
  float naive = 0.0F;
  for (std::size_t t = 0; t < n; ++t) {
    const float w = yf[t] - yf[0];
    naive += w * w;
  }
  const double naive_rel = std::fabs(static_cast<double>(naive) - p0) / p0;
  MESSAGE("plain float sum of P_0, relative error: " << naive_rel);
  CHECK(naive_rel > 100.0 * worst);
}

TEST_CASE("no allocation") {
  const auto y = drift_test::record(0.6868, -0.0213, 1.0, 1.0, 0.0, 50000, 3);
  std::vector<float> yf(y.begin(), y.end());
  gyrodrift::LagStatistics<float, kLags> st;
  gyrodrift::test::AllocationScope scope;
  const std::size_t accepted = st.push(yf.data(), yf.size());
  const bool refused = !st.push(std::numeric_limits<float>::quiet_NaN());
  const float p5 = st.product(5).value() + st.tail(3);
  st.reset();
  const long allocations = scope.allocations();
  CHECK(accepted == yf.size());
  CHECK(refused);
  CHECK(std::isfinite(p5));
  CHECK(allocations == 0);
}
