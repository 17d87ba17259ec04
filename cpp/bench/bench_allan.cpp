// C++-only timing of the Allan kernels (no Python): octave taus on a white + offset record:
// per-tau kernel, fused kernel (one group), and the two cost-balanced fused groups
// (oadev_fused_cut) on one and on two std::threads, as the binding runs them.
// Prints a markdown table. Usage: bench_allan [N] [block]
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <gyrodrift/stability/allan.hpp>
#include <memory>
#include <thread>
#include <vector>

namespace {

// Process CPU time (all threads): on a shared, loaded machine it tracks the kernel's own
// cost better than wall time (the table gives both).
double cpu_seconds() {
  return static_cast<double>(std::clock()) / static_cast<double>(CLOCKS_PER_SEC);
}

double wall_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

bool run_group(const std::vector<double>& y, const std::size_t* m, std::size_t n_m,
               std::size_t block, double* out) {
  auto fused = std::make_unique<gyrodrift::OadevFused<64>>();
  if (!fused->plan(y.size(), m, n_m, block)) return false;
  std::vector<double> work(fused->workspace_doubles());
  return fused->run(y.data(), work.data(), work.size(), out,
                    static_cast<std::size_t*>(nullptr));
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? static_cast<std::size_t>(std::atof(argv[1])) : 10000000;
  const std::size_t block = argc > 2 ? static_cast<std::size_t>(std::atol(argv[2])) : 65536;
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
  auto scratch = std::make_unique<gyrodrift::OadevFused<64>>();
  const std::size_t cut = gyrodrift::oadev_fused_cut(n, m, n_m, block, *scratch);
  std::vector<double> out(n_m);
  std::printf("N = %.0e, %zu octave taus, block %zu, groups [0, %zu) [%zu, %zu)\n\n",
              static_cast<double>(n), n_m, block, cut, cut, n_m);
  std::printf("| kernel | wall s | CPU s (all threads) | CPU ns/sample/tau |\n"
              "| --- | --- | --- | --- |\n");
  const char* names[4] = {"per-tau (long double)", "fused, one group",
                          "fused, two groups, 1 thread", "fused, two groups, 2 threads"};
  for (int kind = 0; kind < 4; ++kind) {
    std::vector<double> walls;
    std::vector<double> cpus;
    for (int rep = 0; rep < 3; ++rep) {
      const double c0 = cpu_seconds();
      const double w0 = wall_seconds();
      bool ok = false;
      if (kind == 0) {
        ok = gyrodrift::oadev(y.data(), n, gyrodrift::AllanInput::rate, m, n_m, out.data(),
                              static_cast<std::size_t*>(nullptr));
      } else if (kind == 1) {
        ok = run_group(y, m, n_m, block, out.data());
      } else if (kind == 2) {
        ok = run_group(y, m, cut, block, out.data());
        ok = ok && (cut == n_m || run_group(y, m + cut, n_m - cut, block, out.data() + cut));
      } else {
        bool ok_b = true;
        std::thread second([&] {
          ok_b = cut == n_m || run_group(y, m + cut, n_m - cut, block, out.data() + cut);
        });
        ok = run_group(y, m, cut, block, out.data());
        second.join();
        ok = ok && ok_b;
      }
      walls.push_back(wall_seconds() - w0);
      cpus.push_back(cpu_seconds() - c0);
      if (!ok) return 1;
    }
    std::sort(walls.begin(), walls.end());
    std::sort(cpus.begin(), cpus.end());
    std::printf("| %s | %.3f | %.3f | %.3f |\n", names[kind], walls[1], cpus[1],
                cpus[1] / static_cast<double>(n) / static_cast<double>(n_m) * 1e9);
  }
  return 0;
}
