// Host build of the golden kernels (golden_kernels.hpp): reads golden_in.bin, writes
// golden_out.bin in the working directory. Built by tests/test_cortex_m_golden.py with the host
// compiler (-std=c++17 -O2 -ffp-contract=off); compared bit for bit with the Cortex-M run.
#include <cstdio>
#include <memory>

#include "golden_kernels.hpp"

int main() {
  auto kernels = std::make_unique<gyrodrift::golden::Kernels>();
  if (!kernels->ok()) return 100;
  std::FILE* in = std::fopen("golden_in.bin", "rb");
  std::FILE* out = std::fopen("golden_out.bin", "wb");
  if (in == nullptr || out == nullptr) return 101;
  std::uint8_t rec[gyrodrift::golden::kInRecord];
  std::uint8_t res[gyrodrift::golden::kOutRecord];
  while (std::fread(rec, 1, sizeof rec, in) == sizeof rec) {
    kernels->step(rec, res);
    if (std::fwrite(res, 1, sizeof res, out) != sizeof res) return 102;
  }
  std::fclose(in);
  return std::fclose(out) == 0 ? 0 : 103;
}
