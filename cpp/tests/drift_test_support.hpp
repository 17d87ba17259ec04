// Test support for the online drift identifiers: a deterministic noise source and a simulated
// AR(2)-drift-plus-white-noise record, the same on every platform (no <random> distribution).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/online_drift_identifier.hpp>
#include <vector>

namespace drift_test {

// Gaussian-like noise: the sum of 12 uniforms from an LCG minus 6 (variance 1).
struct Noise {
  std::uint64_t s;
  double uniform() noexcept {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(s >> 11) * 0x1.0p-53;
  }
  double normal() noexcept {
    double v = -6.0;
    for (int i = 0; i < 12; ++i) v += uniform();
    return v;
  }
};

// AR(2) drift (a1, a2, driving variance q) + white noise (variance r) on a mean, after 2000
// samples of burn-in.
inline std::vector<double> record(double a1, double a2, double q, double r, double mean,
                                  std::size_t n, std::uint64_t seed) {
  Noise w{seed}, v{seed * 7919 + 1};
  std::vector<double> y(n);
  double x1 = 0.0, x2 = 0.0;
  for (std::size_t k = 0; k < n + 2000; ++k) {
    const double x = a1 * x1 + a2 * x2 + std::sqrt(q) * w.normal();
    x2 = x1;
    x1 = x;
    if (k >= 2000) y[k - 2000] = mean + x + std::sqrt(r) * v.normal();
  }
  return y;
}

// Short blocks and learning time, so that a test converges within 1e5 samples.
template <class Scalar = double>
gyrodrift::OnlineDriftSettings<Scalar> small_settings() {
  gyrodrift::OnlineDriftSettings<Scalar> s;
  s.block_samples = 200;
  s.retune_blocks = 20;
  s.min_samples = 20000;
  return s;
}

}  // namespace drift_test
