// Allocation-free evidence for the AR(2) filters: 1e6 steps on 3 axes, float and double, with
// every operator new / malloc counted (alloc_counter.hpp) and Eigen's runtime malloc guard
// armed (EIGEN_RUNTIME_NO_MALLOC: any Eigen heap allocation asserts; asserts are on in tests).
#define EIGEN_RUNTIME_NO_MALLOC
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/ar2_kalman.hpp>
#include <gyrodrift/filters/ar2_model.hpp>
#include <gyrodrift/filters/ar2_steady_state.hpp>
#include <gyrodrift/filters/ar_filter.hpp>
#include <gyrodrift/filters/axis_bank.hpp>
#include <limits>

#include "alloc_counter.hpp"

namespace {

using gyrodrift::test::AllocationScope;

// Deterministic pseudo-noise (LCG) so the loop has data-dependent work and occasional NaN.
template <class Scalar>
Scalar noise(std::uint32_t& s) noexcept {
  s = s * 1664525u + 1013904223u;
  return static_cast<Scalar>(static_cast<std::int32_t>(s >> 8) - (1 << 23)) / static_cast<Scalar>(1 << 23);
}

template <class Filter, class Scalar>
long run_bank(gyrodrift::AxisBank<Filter>& bank, Scalar& checksum) {
  std::uint32_t seed = 12345u;
  Scalar in[3], out[3];
  AllocationScope scope;
  Eigen::internal::set_is_malloc_allowed(false);
  for (std::size_t k = 0; k < 1000000; ++k) {
    for (std::size_t i = 0; i < 3; ++i) in[i] = noise<Scalar>(seed) + Scalar(10);
    if (k % 100000 == 7) in[1] = std::numeric_limits<Scalar>::quiet_NaN();
    bank.step(in, out);
    checksum += out[0] + out[1] + out[2];
  }
  Eigen::internal::set_is_malloc_allowed(true);
  return scope.allocations();  // read before any CHECK (doctest may allocate)
}

template <class Scalar>
void check_all_filters() {
  const gyrodrift::Ar2Model<Scalar> m{Scalar(0.6868), Scalar(-0.0213), Scalar(0.04), Scalar(10)};
  Scalar sum = Scalar(0);
  {
    gyrodrift::AxisBank<gyrodrift::Ar2Kalman<Scalar>> bank(gyrodrift::Ar2Kalman<Scalar>(m, m.sigma2, Scalar(0.3)));
    const long allocs = run_bank(bank, sum);
    CHECK(allocs == 0);
    CHECK(bank.fault_count() == 10u);
  }
  {
    gyrodrift::AxisBank<gyrodrift::Ar2SteadyStateKalman<Scalar>> bank(
        gyrodrift::Ar2SteadyStateKalman<Scalar>(m, m.sigma2, Scalar(0.3)));
    const long allocs = run_bank(bank, sum);
    CHECK(allocs == 0);
    CHECK(bank.fault_count() == 10u);
  }
  {
    gyrodrift::AxisBank<gyrodrift::ArFilter<Scalar>> bank{gyrodrift::ArFilter<Scalar>{m}};
    const long allocs = run_bank(bank, sum);
    CHECK(allocs == 0);
  }
  CHECK(std::isfinite(sum));
}

}  // namespace

TEST_CASE("the counter is live in this executable (so a zero below can fail)") {
  AllocationScope scope;
  int* p = new int(7);
  asm volatile("" : : "g"(p) : "memory");  // keep the allocation observable
  delete p;
  const long allocs = scope.allocations();
  CHECK(allocs == 1);
}

TEST_CASE("AR(2) filters: 1e6 steps x 3 axes allocate nothing (double)") { check_all_filters<double>(); }
TEST_CASE("AR(2) filters: 1e6 steps x 3 axes allocate nothing (float)") { check_all_filters<float>(); }

TEST_CASE("identification allocates nothing") {
  static double buf[4096];
  std::uint32_t seed = 7u;
  double prev1 = 0.0, prev2 = 0.0;
  for (double& v : buf) {
    v = 0.5 * prev1 - 0.2 * prev2 + noise<double>(seed);
    prev2 = prev1;
    prev1 = v;
  }
  AllocationScope scope;
  Eigen::internal::set_is_malloc_allowed(false);
  gyrodrift::Ar2Model<double> m{};
  int ok = 0;
  for (auto method : {gyrodrift::Ar2Method::yule_walker, gyrodrift::Ar2Method::burg,
                      gyrodrift::Ar2Method::least_squares}) {
    ok += gyrodrift::fit_ar2(buf, 4096, method, m) == gyrodrift::Ar2Status::ok;
  }
  gyrodrift::Ar2YuleWalkerAccumulator<double> acc;
  for (double v : buf) acc.push(v);
  ok += acc.fit(m) == gyrodrift::Ar2Status::ok;
  gyrodrift::Ar2SteadyStateKalman<double> ss(m, m.sigma2, m.sigma2);  // Riccati solve at construction
  Eigen::internal::set_is_malloc_allowed(true);
  const long allocs = scope.allocations();
  CHECK(allocs == 0);
  CHECK(ok == 4);
  CHECK(ss.status() == gyrodrift::Ar2Status::ok);
}
