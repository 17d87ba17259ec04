// C++-only timing of the fused deviation kernels (no Python): octave taus on a drifting
// record with an offset, DeviationFused (ohdev, mdev, totdev) and HdevCascade, one thread,
// best of the repeats in process CPU time, and the largest relative difference from the
// long double per-tau kernels. Prints a markdown table.
// Usage: bench_deviations [N] [block] [repeats]
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <gyrodrift/stability/deviation_blocked.hpp>
#include <gyrodrift/stability/deviation_fused.hpp>
#include <memory>
#include <vector>

namespace {

double cpu_seconds() {
  return static_cast<double>(std::clock()) / static_cast<double>(CLOCKS_PER_SEC);
}

template <class Run>
double best_of(int repeats, Run run) {
  double best = 1e300;
  for (int r = 0; r < repeats; ++r) {
    const double t0 = cpu_seconds();
    if (!run()) std::printf("kernel failed\n");
    const double t = cpu_seconds() - t0;
    best = t < best ? t : best;
  }
  return best;
}

double max_rel(const std::vector<double>& a, const std::vector<double>& b) {
  double worst = 0.0;
  for (std::size_t j = 0; j < a.size(); ++j) {
    const double r = std::fabs(a[j] - b[j]) / b[j];
    worst = r > worst ? r : worst;
  }
  return worst;
}

}  // namespace

int main(int argc, char** argv) {
  using gyrodrift::FusedDeviation;
  const std::size_t n = argc > 1 ? static_cast<std::size_t>(std::atof(argv[1])) : 1000000;
  const std::size_t block = argc > 2 ? static_cast<std::size_t>(std::atol(argv[2])) : 131072;
  const int repeats = argc > 3 ? std::atoi(argv[3]) : 7;
  std::vector<double> y(n);
  std::uint64_t s = 1;
  double walk = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u = static_cast<double>(s >> 11) * 0x1.0p-53 - 0.5;
    walk += 1e-3 * u;
    y[i] = 15.0 + u + walk;
  }
  std::printf("N = %.0e, block %zu, best of %d (CPU)\n\n", static_cast<double>(n), block,
              repeats);
  std::printf("| kernel | taus | workspace doubles | CPU s | CPU ns/sample/tau | max rel. diff. "
              "from long double per tau |\n| --- | --- | --- | --- | --- | --- |\n");
  const char* names[] = {"ohdev", "ohdev, taus alone", "mdev", "totdev"};
  for (std::size_t r = 0; r < 4; ++r) {
    const std::size_t d = r == 0 ? 0 : r - 1;
    const std::size_t max_m = d == 0 ? gyrodrift::ohdev_max_m(n)
                              : d == 1 ? gyrodrift::mdev_max_m(n)
                                       : gyrodrift::totdev_max_m(n);
    std::size_t m[64] = {};
    const std::size_t n_m = gyrodrift::tau_grid(gyrodrift::TauGrid::octave, max_m, 0, m, 64);
    auto fused = std::make_unique<gyrodrift::DeviationFused<64>>();
    const FusedDeviation kind = d == 0   ? FusedDeviation::ohdev
                                : d == 1 ? FusedDeviation::mdev
                                         : FusedDeviation::totdev;
    if (!fused->plan(n, kind, m, n_m, block)) return 1;
    fused->use_pairs(r != 1);
    // a 64-byte aligned workspace, as the bindings allocate it
    std::vector<double> work_store(fused->workspace_doubles() + 8);
    double* work = work_store.data();
    while (reinterpret_cast<std::uintptr_t>(work) % 64 != 0) ++work;
    const std::size_t work_len = fused->workspace_doubles();
    std::vector<double> out(n_m);
    std::vector<double> ref(n_m);
    std::vector<std::size_t> terms(n_m);
    const double t = best_of(repeats, [&] {
      return fused->run(y.data(), work, work_len, out.data(), terms.data());
    });
    std::vector<double> tot_work(3 * 512);
    bool ok = false;
    if (d == 0) ok = gyrodrift::ohdev<double, double>(y.data(), n, m, n_m, ref.data(), nullptr);
    if (d == 1) ok = gyrodrift::mdev<double, double>(y.data(), n, m, n_m, ref.data(), nullptr);
    if (d == 2) {
      ok = gyrodrift::totdev<double, double>(y.data(), n, m, n_m, tot_work.data(), 512,
                                             ref.data(), nullptr);
    }
    if (!ok) return 1;
    std::printf("| %s (DeviationFused) | %zu | %zu | %.4f | %.3f | %.1e |\n", names[r], n_m,
                work_len, t, t / static_cast<double>(n) / static_cast<double>(n_m) * 1e9,
                max_rel(out, ref));
  }
  std::size_t m[64] = {};
  const std::size_t n_m =
      gyrodrift::tau_grid(gyrodrift::TauGrid::octave, gyrodrift::hdev_max_m(n), 0, m, 64);
  auto cascade = std::make_unique<gyrodrift::HdevCascade<64>>();
  if (!cascade->plan(n, m, n_m)) return 1;
  std::vector<double> work(cascade->workspace_len());
  std::vector<double> out(n_m);
  std::vector<double> ref(n_m);
  std::vector<std::size_t> terms(n_m);
  const double t = best_of(repeats, [&] {
    return cascade->run(y.data(), work.data(), work.size(), out.data(), terms.data());
  });
  if (!gyrodrift::hdev<double, double>(y.data(), n, m, n_m, ref.data(), nullptr)) return 1;
  std::printf("| hdev (HdevCascade) | %zu | %zu | %.4f | %.3f | %.1e |\n", n_m, work.size(), t,
              t / static_cast<double>(n) / static_cast<double>(n_m) * 1e9, max_rel(out, ref));
  return 0;
}
