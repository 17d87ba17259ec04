// Minimal Cortex-M4F start-up: vector table, reset handler that initialises .data/.bss,
// enables the FPU (CP10/CP11 full access) and runs static constructors before app_main().
#include <cstdint>

#include "support.hpp"

extern "C" {
// Symbols from stm32f4.ld.
extern std::uint32_t _sidata, _sdata, _edata, _sbss, _ebss;
// Top of the stack. Declared as a function so it can be placed in the (function-pointer)
// vector table without a cast that would make the table dynamically initialised.
void _estack(void);
extern void (*__preinit_array_start[])(void);
extern void (*__preinit_array_end[])(void);
extern void (*__init_array_start[])(void);
extern void (*__init_array_end[])(void);

// Exit status of app_main, observable with a debugger.
volatile int gyrodrift_cm_exit_code = -1;

[[noreturn]] void Reset_Handler(void);
[[noreturn]] void Default_Handler(void);
}

namespace {
constexpr std::uintptr_t kCpacr = 0xE000ED88u;  // Coprocessor Access Control Register (SCB)
}

extern "C" [[noreturn]] void Default_Handler(void) {
  for (;;) {
  }
}

extern "C" [[noreturn]] void Reset_Handler(void) {
  // Copy initialised data from flash, zero .bss (word loops: memcpy may not be usable yet).
  const std::uint32_t* src = &_sidata;
  for (std::uint32_t* dst = &_sdata; dst < &_edata;) *dst++ = *src++;
  for (std::uint32_t* dst = &_sbss; dst < &_ebss;) *dst++ = 0u;
  // FPU on before any float instruction (ARMv7-M ARM, B3.2.20): CP10 and CP11 full access.
  *reinterpret_cast<volatile std::uint32_t*>(kCpacr) |= (0xFu << 20);
  __asm volatile("dsb\n\tisb" ::: "memory");
  for (auto** f = __preinit_array_start; f < __preinit_array_end; ++f) (**f)();
  for (auto** f = __init_array_start; f < __init_array_end; ++f) (**f)();
  gyrodrift_cm_exit_code = app_main();
  for (;;) {
  }
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
