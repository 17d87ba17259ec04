// C++-only timing of the Allan kernels (no Python): octave taus on a white + offset record,
// per-tau kernel vs fused kernel. Prints a markdown table. Usage: bench_allan [N]
#include <algorithm>
#include <ctime>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <gyrodrift/allan.hpp>
#include <memory>
#include <vector>

namespace {

// Process CPU time: on a shared, loaded machine it tracks the kernel's own cost better
// than wall time (the table says which is which).
double cpu_seconds() {
  return static_cast<double>(std::clock()) / static_cast<double>(CLOCKS_PER_SEC);
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? static_cast<std::size_t>(std::atof(argv[1])) : 10000000;
  const std::size_t block = argc > 2 ? static_cast<std::size_t>(std::atol(argv[2])) : 4096;
  std::vector<double> y(n);
  std::uint64_t s = 1;
  for (std::size_t i = 0; i < n; ++i) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    y[i] = 15.0 + static_cast<double>(s >> 11) * 0x1.0p-53 - 0.5;
  }
  std::size_t m[64] = {};
  const std::size_t n_m = gyrodrift::tau_grid(
      gyrodrift::TauGrid::octave, gyrodrift::oadev_max_m(n, gyrodrift::AllanInput::rate), 0, m,
      64);
  std::vector<double> out(n_m);
  std::printf("| kernel | N | taus | CPU s (median of 3) | ns/sample/tau |\n| --- | --- | --- | --- | --- |\n");
  for (int kind = 0; kind < 2; ++kind) {
    std::vector<double> times;
    for (int rep = 0; rep < 3; ++rep) {
      const double t0 = cpu_seconds();
      bool ok = false;
      if (kind == 0) {
        ok = gyrodrift::oadev(y.data(), n, gyrodrift::AllanInput::rate, m, n_m, out.data(),
                              static_cast<std::size_t*>(nullptr));
      } else {
        auto fused = std::make_unique<gyrodrift::OadevFused<64>>();
        ok = fused->plan(n, m, n_m, block);
        std::vector<double> work(fused->workspace_doubles());
        ok = ok && fused->run(y.data(), work.data(), work.size(), out.data(),
                              static_cast<std::size_t*>(nullptr));
      }
      times.push_back(cpu_seconds() - t0);
      if (!ok) return 1;
    }
    std::sort(times.begin(), times.end());
    const double t = times[1];
    std::printf("| %s | %.0e | %zu | %.3f | %.3f |\n", kind == 0 ? "per-tau (long double)" : "fused",
                static_cast<double>(n), n_m, t,
                t / static_cast<double>(n) / static_cast<double>(n_m) * 1e9);
  }
  return 0;
}
