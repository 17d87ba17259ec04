// Cortex-M4F golden-I/O unit (MCU equals host): reads golden_in.bin through
// semihosting, runs the float kernels of golden_kernels.hpp, writes golden_out.bin. Built and
// run by tests/test_cortex_m_golden.py with the gate's flags (not a use_*.cpp: it needs its
// input file next to it).
#include "golden_kernels.hpp"
#include "support.hpp"

namespace {
gyrodrift::golden::Kernels kernels;  // static storage (windows in .bss)
}

extern "C" int app_main(void) {
  namespace cm = gyrodrift::cortex_m;
  if (!kernels.ok()) return 100;
  const int in = cm::host_open("golden_in.bin", false);
  const int out = cm::host_open("golden_out.bin", true);
  if (in < 0 || out < 0) return 101;
  std::uint8_t rec[gyrodrift::golden::kInRecord];
  std::uint8_t res[gyrodrift::golden::kOutRecord];
  std::int32_t n = 0;
  while (cm::host_read(in, rec, sizeof rec)) {
    kernels.step(rec, res);
    if (!cm::host_write(out, res, sizeof res)) return 102;
    ++n;
  }
  cm::host_close(in);
  cm::host_close(out);
  cm::sink(n);
  return n > 0 ? 0 : 103;
}
