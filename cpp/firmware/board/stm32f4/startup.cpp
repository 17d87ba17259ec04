// STM32F405 start-up for the reference firmware: vector table (the 16 system exceptions and
// the part's 82 interrupts), Reset_Handler (the C runtime start of ../cortex_m_start.hpp:
// .data, .bss, the stack paint, FPU on, static constructors; then firmware_main()).
#include <array>
#include <cstdint>

#include "cortex_m_start.hpp"

extern "C" {
[[noreturn]] void firmware_main(void);
[[noreturn]] void Reset_Handler(void);
[[noreturn]] void Default_Handler(void);
void SysTick_Handler(void);
void PendSV_Handler(void);
void USART1_IRQHandler(void);
// Two words the host can read with a debugger: which exception stopped the firmware.
volatile std::uint32_t gyrodrift_fw_fault_ipsr = 0;
}

namespace {
constexpr unsigned kIrqCount = 82U;  // STM32F405 (RM0090 table 61)
constexpr unsigned kUsart1Irq = 37U;

using Vector = void (*)(void);
constexpr std::array<Vector, 16U + kIrqCount> make_vectors() {
  std::array<Vector, 16U + kIrqCount> v{};
  v[0] = _estack;
  v[1] = Reset_Handler;
  for (unsigned i = 2; i < v.size(); ++i) v[i] = Default_Handler;
  v[7] = v[8] = v[9] = v[10] = v[13] = nullptr;  // reserved
  v[14] = PendSV_Handler;
  v[15] = SysTick_Handler;
  v[16U + kUsart1Irq] = USART1_IRQHandler;
  return v;
}
}  // namespace

extern "C" __attribute__((section(".isr_vector"), used)) const std::array<Vector, 16U + kIrqCount>
    gyrodrift_fw_vectors = make_vectors();

extern "C" [[noreturn]] void Default_Handler(void) {
  std::uint32_t ipsr = 0;
  __asm volatile("mrs %0, ipsr" : "=r"(ipsr));
  gyrodrift_fw_fault_ipsr = ipsr;
  for (;;) {
    __asm volatile("bkpt 0");
  }
}

extern "C" [[noreturn]] void Reset_Handler(void) {
  gyrodrift::cortex_m_start::run_c_runtime_start();
  firmware_main();
}
