// The start of a Cortex-M4F image before its main function, and the stack high-water mark
// it makes possible: one copy for every startup.cpp (the reference firmware's board/<name>/
// and the Cortex-M build gate's cpp/cortex_m/). What differs between them stays in their own
// startup.cpp: the vector table, the fault handler and what runs after the start.
//
// The linker script defines _sidata, _sdata, _edata, _sbss, _ebss and _estack (the top of the
// stack) and keeps the .preinit_array and .init_array sections between their _start/_end
// symbols.
#pragma once

#include <cstdint>

extern "C" {
extern std::uint32_t _sidata, _sdata, _edata, _sbss, _ebss;
// Top of the stack. Declared as a function so it can be placed in the (function-pointer)
// vector table without a cast that would make the table dynamically initialised.
void _estack(void);
extern void (*__preinit_array_start[])(void);
extern void (*__preinit_array_end[])(void);
extern void (*__init_array_start[])(void);
extern void (*__init_array_end[])(void);
}

namespace gyrodrift::cortex_m_start {

// Free RAM between .bss and the stack is painted with this word at reset; the lowest word
// that no longer holds it marks the deepest stack use.
constexpr std::uint32_t kStackPaint = 0x5AC3A55CU;

// Copy .data from flash and zero .bss (word loops: memcpy may not be usable yet), paint the
// free RAM below the current stack frame (64-byte margin), switch the FPU on before any float
// instruction (ARMv7-M ARM B3.2.20: CPACR CP10 and CP11 full access), run the static
// constructors. Inlined into the reset handler, so the frame left unpainted is the handler's.
__attribute__((always_inline)) inline void run_c_runtime_start() {
  constexpr std::uintptr_t kCpacr = 0xE000ED88U;  // Coprocessor Access Control Register (SCB)
  const std::uint32_t* src = &_sidata;
  for (std::uint32_t* dst = &_sdata; dst < &_edata;) *dst++ = *src++;
  for (std::uint32_t* dst = &_sbss; dst < &_ebss;) *dst++ = 0U;
  std::uint32_t* sp = nullptr;
  __asm volatile("mov %0, sp" : "=r"(sp));
  for (volatile std::uint32_t* w = &_ebss; w < sp - 16;) *w++ = kStackPaint;
  *reinterpret_cast<volatile std::uint32_t*>(kCpacr) |= (0xFU << 20);
  __asm volatile("dsb\n\tisb" ::: "memory");
  for (auto** f = __preinit_array_start; f < __preinit_array_end; ++f) (**f)();
  for (auto** f = __init_array_start; f < __init_array_end; ++f) (**f)();
}

// Deepest stack use since reset in bytes: from the top of the stack down to the lowest
// painted word that was overwritten.
inline std::uint32_t stack_high_water_bytes() noexcept {
  const std::uint32_t* word = &_ebss;
  const auto* top = reinterpret_cast<const std::uint32_t*>(&_estack);
  while (word < top && *word == kStackPaint) ++word;
  return static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(top) -
                                    reinterpret_cast<std::uintptr_t>(word));
}

// Measurement only: the stack `fn` uses below the caller's frame, in bytes. The free RAM below
// the current stack pointer is painted again (the 64-byte margin), `fn` runs, and the lowest
// word it overwrote gives its depth. The caller masks interrupts, so that only fn's frames land
// there; the image's high-water mark (stack_high_water_bytes) from before is lost.
__attribute__((always_inline)) inline std::uint32_t stack_used_by(void (*fn)()) {
  std::uint32_t* sp = nullptr;
  __asm volatile("mov %0, sp" : "=r"(sp));
  for (volatile std::uint32_t* w = &_ebss; w < sp - 16;) *w++ = kStackPaint;
  fn();
  const volatile std::uint32_t* word = &_ebss;
  while (word < sp - 16 && *word == kStackPaint) ++word;
  return static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(sp) -
                                    reinterpret_cast<std::uintptr_t>(word));
}

}  // namespace gyrodrift::cortex_m_start
