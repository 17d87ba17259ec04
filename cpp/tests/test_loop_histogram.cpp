// The loop's fixed-size latency histogram: percentiles against an exact sort of the same
// values (to one bin width), exact max, the overflow bin, empty and degenerate inputs.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "../programs/gyrodrift-loop/latency_histogram.hpp"

using gyrodrift::loop::LatencyHistogram;

namespace {
// Nearest-rank quantile (the definition the histogram implements): the ceil(q n)-th value.
std::uint64_t exact_quantile(std::vector<std::uint64_t> v, double q) {
  std::sort(v.begin(), v.end());
  auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  if (rank == 0) rank = 1;
  return v[rank - 1];
}
}  // namespace

TEST_CASE("percentiles agree with an exact sort to one bin width") {
  std::mt19937_64 rng(42);
  std::lognormal_distribution<double> dist(9.0, 1.0);  // ~8 us median, long tail (ns)
  LatencyHistogram<20000> h(100);                       // 0.1 us bins up to 2 ms
  std::vector<std::uint64_t> values;
  for (int i = 0; i < 100000; ++i) {
    const auto ns = static_cast<std::uint64_t>(dist(rng));
    values.push_back(ns);
    h.record(ns);
  }
  CHECK(h.count() == values.size());
  CHECK(h.max_ns() == *std::max_element(values.begin(), values.end()));
  for (const double q : {0.01, 0.5, 0.9, 0.99, 0.999}) {
    const std::uint64_t exact = exact_quantile(values, q);
    const std::uint64_t got = h.quantile_ns(q);
    // The histogram reports the upper edge of the bin holding the exact value.
    CHECK(got >= exact);
    CHECK(got - exact <= 100);
  }
}

TEST_CASE("overflow bin keeps the exact max and empty histograms report 0") {
  LatencyHistogram<10> h(1000);  // 1 us bins up to 10 us
  CHECK(h.quantile_ns(0.5) == 0);
  for (int i = 0; i < 98; ++i) h.record(500);
  h.record(1'000'000);
  h.record(2'500'000);
  CHECK(h.quantile_ns(0.5) == 1000);
  CHECK(h.quantile_ns(0.99) == 2'500'000);  // falls in the overflow bin: the exact max
  CHECK(h.quantile_ns(1.0) == 2'500'000);
  CHECK(h.max_ns() == 2'500'000);
}

TEST_CASE("a single value and a zero bin width") {
  LatencyHistogram<4> h(0);  // a zero width is treated as 1 ns, never a division by zero
  h.record(2);
  CHECK(h.quantile_ns(0.0) == 2);
  CHECK(h.quantile_ns(1.0) == 2);
}
