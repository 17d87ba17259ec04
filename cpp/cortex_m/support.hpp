// Support for the Cortex-M4F gate programs (cpp/cortex_m/use_*.cpp).
//
// Each use_<name>.cpp defines `extern "C" int app_main(void)`, which the reset handler
// (startup.cpp) calls after initialising RAM and enabling the FPU. It should instantiate the
// FLOAT version of one filter and run it on samples read through `input()` (a volatile
// buffer, so the compiler cannot constant-fold the filter away) and pass results to `sink()`
// (a volatile store, so they cannot be discarded). tests/test_cortex_m_gate.py builds one
// bare-metal ELF per use_*.cpp and rejects heap, software-double and exception symbols.
#pragma once

#include <cstddef>
#include <cstdint>

extern "C" {
// Input samples, initialised data in RAM: the optimiser must assume a debugger or DMA may
// have changed them. gyrodrift_cm_input_len is their count.
extern volatile float gyrodrift_cm_input[64];
extern const std::size_t gyrodrift_cm_input_len;
// Output sink: every value written here is observable.
extern volatile float gyrodrift_cm_sink;
extern volatile std::int32_t gyrodrift_cm_sink_i32;
// Entry point of each gate program (defined in use_<name>.cpp).
int app_main(void);
}

namespace gyrodrift::cortex_m {

// Sample i of the volatile input (wraps around the 64-entry buffer).
inline float input(std::size_t i) noexcept { return gyrodrift_cm_input[i % 64u]; }

// Publishes a result so the computation producing it cannot be removed.
inline void sink(float value) noexcept { gyrodrift_cm_sink = value; }
inline void sink(std::int32_t value) noexcept { gyrodrift_cm_sink_i32 = value; }

// Gaussian-like noise: the sum of 12 uniforms from an LCG minus 6 (variance 1), in float (the
// gate units that simulate a record: deterministic, no library call).
struct Noise {
  std::uint32_t s;
  float uniform() noexcept {
    s = s * 1664525U + 1013904223U;
    return static_cast<float>(s >> 8U) * 0x1.0p-24F;
  }
  float normal() noexcept {
    float v = -6.0F;
    for (int i = 0; i < 12; ++i) v += uniform();
    return v;
  }
};

// Host files through semihosting (support.cpp): a handle >= 0, or -1. For the golden-I/O unit.
int host_open(const char* path, bool write);
bool host_read(int fd, void* buf, std::size_t n);   // true when all n bytes were read
bool host_write(int fd, const void* buf, std::size_t n);
void host_close(int fd);

}  // namespace gyrodrift::cortex_m
