// STM32F405 start-up for the reference firmware: vector table (the 16 system exceptions and
// the part's 82 interrupts), Reset_Handler (copy .data, zero .bss, paint the free RAM for the
// stack high-water mark, FPU on, static constructors, firmware_main()).
#include <array>
#include <cstdint>

extern "C" {
extern std::uint32_t _sidata, _sdata, _edata, _sbss, _ebss;
void _estack(void);  // top of the stack (a function type so it fits the vector table)
extern void (*__preinit_array_start[])(void);
extern void (*__preinit_array_end[])(void);
extern void (*__init_array_start[])(void);
extern void (*__init_array_end[])(void);
[[noreturn]] void firmware_main(void);
[[noreturn]] void Reset_Handler(void);
[[noreturn]] void Default_Handler(void);
void SysTick_Handler(void);
void USART1_IRQHandler(void);
// Two words the host can read with a debugger: which exception stopped the firmware.
volatile std::uint32_t gyrodrift_fw_fault_ipsr = 0;
}

namespace {
constexpr std::uintptr_t kCpacr = 0xE000ED88U;
constexpr std::uint32_t kStackPaint = 0x5AC3A55CU;  // board.cpp reads the high-water mark
constexpr unsigned kIrqCount = 82U;                 // STM32F405 (RM0090 table 61)
constexpr unsigned kUsart1Irq = 37U;

using Vector = void (*)(void);
constexpr std::array<Vector, 16U + kIrqCount> make_vectors() {
  std::array<Vector, 16U + kIrqCount> v{};
  v[0] = _estack;
  v[1] = Reset_Handler;
  for (unsigned i = 2; i < v.size(); ++i) v[i] = Default_Handler;
  v[7] = v[8] = v[9] = v[10] = v[13] = nullptr;  // reserved
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
  const std::uint32_t* src = &_sidata;
  for (std::uint32_t* dst = &_sdata; dst < &_edata;) *dst++ = *src++;
  for (std::uint32_t* dst = &_sbss; dst < &_ebss;) *dst++ = 0U;
  std::uint32_t* sp = nullptr;
  __asm volatile("mov %0, sp" : "=r"(sp));
  for (volatile std::uint32_t* w = &_ebss; w < sp - 16;) *w++ = kStackPaint;
  // FPU on before any float instruction (ARMv7-M ARM B3.2.20): CP10 and CP11 full access.
  *reinterpret_cast<volatile std::uint32_t*>(kCpacr) |= (0xFU << 20);
  __asm volatile("dsb\n\tisb" ::: "memory");
  for (auto** f = __preinit_array_start; f < __preinit_array_end; ++f) (**f)();
  for (auto** f = __init_array_start; f < __init_array_end; ++f) (**f)();
  firmware_main();
}
