// Minimal Cortex-M4F start-up for the build gate: vector table, reset handler that runs the
// C runtime start (cpp/firmware/board/cortex_m_start.hpp: .data/.bss, the stack paint, FPU
// on, static constructors) before app_main(), then reports its exit code.
#include <cstdint>

#include "cortex_m_start.hpp"
#include "support.hpp"

extern "C" {
// Exit status of app_main, observable with a debugger.
volatile int gyrodrift_cm_exit_code = -1;
// Deepest stack use in bytes (painted-RAM high-water mark), valid after app_main returns.
volatile std::uint32_t gyrodrift_cm_stack_bytes = 0;

[[noreturn]] void Reset_Handler(void);
[[noreturn]] void Default_Handler(void);
}

namespace {
using gyrodrift::cortex_m_start::stack_high_water_bytes;

#if defined(GYRODRIFT_CM_SEMIHOSTING)
// ARM semihosting call (Semihosting for AArch32 and AArch64, v2: BKPT 0xAB on M-profile):
// only for runs under an emulator or debugger; the gate defines GYRODRIFT_CM_SEMIHOSTING.
int semihost(int op, const void* arg) {
  register int r0 __asm("r0") = op;
  register const void* r1 __asm("r1") = arg;
  __asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
  return r0;
}

char* put_text(char* out, const char* text) {
  while (*text != '\0') *out++ = *text++;
  return out;
}

char* put_hex(char* out, std::uint32_t value) {
  for (int shift = 28; shift >= 0; shift -= 4) {
    *out++ = "0123456789abcdef"[(value >> static_cast<unsigned>(shift)) & 0xFu];
  }
  return out;
}

// Prints "gyrodrift-cm <what> code=0x.. sink=0x.. sink_i32=0x..\n" and exits the emulator with
// `code` (SYS_EXIT_EXTENDED, reason ADP_Stopped_ApplicationExit).
[[noreturn]] void report_and_exit(const char* what, int code) {
  char line[96];
  char* p = put_text(line, "gyrodrift-cm ");
  p = put_text(p, what);
  p = put_text(p, " code=0x");
  p = put_hex(p, static_cast<std::uint32_t>(code));
  p = put_text(p, " sink=0x");
  const float sink = gyrodrift_cm_sink;
  std::uint32_t bits = 0;
  __builtin_memcpy(&bits, &sink, sizeof bits);
  p = put_hex(p, bits);
  p = put_text(p, " sink_i32=0x");
  p = put_hex(p, static_cast<std::uint32_t>(gyrodrift_cm_sink_i32));
  p = put_text(p, " stack=0x");
  p = put_hex(p, stack_high_water_bytes());
  *p++ = '\n';
  *p = '\0';
  semihost(0x04, line);  // SYS_WRITE0
  const std::uint32_t block[2] = {0x20026u, static_cast<std::uint32_t>(code)};
  semihost(0x20, block);  // SYS_EXIT_EXTENDED
  for (;;) {
  }
}
#endif
}  // namespace

extern "C" [[noreturn]] void Default_Handler(void) {
#if defined(GYRODRIFT_CM_SEMIHOSTING)
  report_and_exit("fault", 0xFA);  // an exception (HardFault, UsageFault, ...) was taken
#else
  for (;;) {
  }
#endif
}

extern "C" [[noreturn]] void Reset_Handler(void) {
  gyrodrift::cortex_m_start::run_c_runtime_start();
  gyrodrift_cm_exit_code = app_main();
  gyrodrift_cm_stack_bytes = stack_high_water_bytes();
#if defined(GYRODRIFT_CM_SEMIHOSTING)
  report_and_exit("exit", gyrodrift_cm_exit_code);
#else
  for (;;) {
  }
#endif
}

// Vector table: initial stack pointer, then the 15 system exceptions (IRQs unused here).
using Vector = void (*)(void);
extern "C" __attribute__((section(".isr_vector"), used)) const Vector gyrodrift_cm_vectors[16] = {
    _estack,
    Reset_Handler,
    Default_Handler,  // NMI
    Default_Handler,  // HardFault
    Default_Handler,  // MemManage
    Default_Handler,  // BusFault
    Default_Handler,  // UsageFault
    nullptr, nullptr, nullptr, nullptr,
    Default_Handler,  // SVCall
    Default_Handler,  // DebugMonitor
    nullptr,
    Default_Handler,  // PendSV
    Default_Handler,  // SysTick
};
