// C++-only timing of the AR(2) filters' step (no Python): ns per sample per axis for the full
// Joseph-form AR(2)-Kalman (double, float), the steady-state variant, the AR filter and a
// 3-axis bank. Median of repeats over a 1e6-sample record (in cache-friendly blocks).
// Prints a markdown table; benchmarks/bench_kalman.py runs it and merges the rows.
//   bench_kalman [samples=1000000] [repeats=7]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <gyrodrift/filters/ar2_kalman.hpp>
#include <gyrodrift/filters/ar2_model.hpp>
#include <gyrodrift/filters/ar2_steady_state.hpp>
#include <gyrodrift/filters/ar_filter.hpp>
#include <gyrodrift/filters/axis_bank.hpp>
#include <string>
#include <vector>

namespace {

template <class Scalar>
std::vector<Scalar> record(std::size_t n) {
  std::vector<Scalar> y(n);
  std::uint32_t s = 2026u;
  double p1 = 0.0, p2 = 0.0;
  for (auto& v : y) {
    s = s * 1664525u + 1013904223u;
    const double w = static_cast<double>(s >> 8) / static_cast<double>(1u << 24) - 0.5;
    const double x = 0.6868 * p1 - 0.0213 * p2 + w;
    p2 = p1;
    p1 = x;
    v = static_cast<Scalar>(x + 9.7);
  }
  return y;
}

template <class F>
double median_ns_per_sample(F&& run, std::size_t samples, int repeats) {
  std::vector<double> t;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    run();
    const auto t1 = std::chrono::steady_clock::now();
    t.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count() / static_cast<double>(samples));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

volatile double g_sink;

template <class Filter, class Scalar>
double time_single(const Filter& proto, const std::vector<Scalar>& y, std::vector<Scalar>& out, int repeats) {
  return median_ns_per_sample(
      [&] {
        Filter f = proto;
        for (std::size_t k = 0; k < y.size(); ++k) out[k] = f.step(y[k]);
        g_sink = static_cast<double>(out[y.size() / 2]);
      },
      y.size(), repeats);
}

template <class Filter, class Scalar>
double time_bank(const Filter& proto, const std::vector<Scalar>& y3, std::vector<Scalar>& out3, int repeats) {
  const std::size_t rows = y3.size() / 3;
  return median_ns_per_sample(
      [&] {
        gyrodrift::AxisBank<Filter> bank(proto);
        for (std::size_t k = 0; k < rows; ++k) bank.step(&y3[3 * k], &out3[3 * k]);
        g_sink = static_cast<double>(out3[rows]);
      },
      y3.size(), repeats);  // per sample per axis
}

template <class Scalar>
void run_type(const char* type, std::size_t n, int repeats) {
  const auto y = record<Scalar>(n);
  std::vector<Scalar> out(n);
  const gyrodrift::Ar2Model<Scalar> m{Scalar(0.6868), Scalar(-0.0213), Scalar(0.0833), Scalar(9.7)};
  const gyrodrift::Ar2Kalman<Scalar> kf(m, m.sigma2, m.sigma2);
  gyrodrift::Ar2Kalman<Scalar> kf_full(m, m.sigma2, m.sigma2);
  kf_full.set_covariance_latch(false);  // worst case: covariance recursion on every step
  const gyrodrift::Ar2SteadyStateKalman<Scalar> ss(m, m.sigma2, m.sigma2);
  const gyrodrift::ArFilter<Scalar> ar(m);
  const double t_kf = time_single(kf, y, out, repeats);
  const double t_kf_full = time_single(kf_full, y, out, repeats);
  const double t_ss = time_single(ss, y, out, repeats);
  const double t_ar = time_single(ar, y, out, repeats);
  const double t_bank = time_bank(kf, y, out, repeats);
  const double t_bank_full = time_bank(kf_full, y, out, repeats);
  const double t_bank_ss = time_bank(ss, y, out, repeats);
  auto row = [&](const char* what, double ns) {
    std::printf("| C++ %s, %s | %.2f | %.1f |\n", what, type, ns, 1e3 / ns);
  };
  row("AR(2)-Kalman step (Joseph, covariance latch on)", t_kf);
  row("AR(2)-Kalman step (Joseph, every step: worst case)", t_kf_full);
  row("AR(2)-Kalman steady-state step", t_ss);
  row("AR filter step", t_ar);
  row("AxisBank<Ar2Kalman> 3 axes, per axis", t_bank);
  row("AxisBank<Ar2Kalman> 3 axes, per axis, worst case", t_bank_full);
  row("AxisBank<steady-state> 3 axes, per axis", t_bank_ss);
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? static_cast<std::size_t>(std::strtoull(argv[1], nullptr, 10)) : 1000000;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 7;
  std::printf("| case | ns/sample/axis | M samples/s |\n| --- | ---: | ---: |\n");
  run_type<double>("double", n, repeats);
  run_type<float>("float", n, repeats);
  return 0;
}
