// STM32F405 board support for the reference firmware: clock tree, USART1 (interrupt-driven
// receive into a fixed ring, transmit from another), SysTick at the loop rate pending PendSV
// for the tick work, NVIC and system handler priorities.
// Register addresses and bits: RM0090 (STM32F405/415/407/417 reference manual), sections
// RCC (6.3), USART (30.6), and the ARMv7-M ARM for SysTick (B3.3), the NVIC (B3.4), the
// system handler priorities and PendSV (B3.2.4 ICSR, B3.2.12 SHPR3).
//
// Priorities (lower number = more urgent): SysTick 0 (counts the tick, pends PendSV), USART1 4
// (receive and transmit), PendSV 15, the lowest (the tick work: nested by both above), then
// thread mode (the application's background work, preempted by all of them).
//
// Under QEMU's netduinoplus2 board (STM32F405 SoC): USART1 is the first serial port
// (-serial / serial0), the RCC is not emulated (reads as 0: the PLL never reports lock, so
// every wait below is bounded and the clock tree stays on its reset source), and the core
// runs at the board's fixed 168 MHz system clock, which SysTick counts.
#include <cstddef>
#include <cstdint>

#include "board.hpp"
#include "cortex_m_start.hpp"

extern "C" {
void USART1_IRQHandler(void);
void SysTick_Handler(void);
void PendSV_Handler(void);
}

namespace gyrodrift::firmware::board {
namespace {

inline volatile std::uint32_t& reg(std::uintptr_t addr) noexcept {
  return *reinterpret_cast<volatile std::uint32_t*>(addr);
}

// RCC (RM0090 6.3)
constexpr std::uintptr_t kRcc = 0x40023800U;
constexpr std::uintptr_t kRccCr = kRcc + 0x00U;
constexpr std::uintptr_t kRccPllCfgr = kRcc + 0x04U;
constexpr std::uintptr_t kRccCfgr = kRcc + 0x08U;
constexpr std::uintptr_t kRccAhb1Enr = kRcc + 0x30U;
constexpr std::uintptr_t kRccApb2Enr = kRcc + 0x44U;
constexpr std::uintptr_t kFlashAcr = 0x40023C00U;
// GPIOA: PA9 = USART1_TX, PA10 = USART1_RX, alternate function 7
constexpr std::uintptr_t kGpioA = 0x40020000U;
// USART1 (RM0090 30.6)
constexpr std::uintptr_t kUsart1 = 0x40011000U;
constexpr std::uintptr_t kSr = kUsart1 + 0x00U;
constexpr std::uintptr_t kDr = kUsart1 + 0x04U;
constexpr std::uintptr_t kBrr = kUsart1 + 0x08U;
constexpr std::uintptr_t kCr1 = kUsart1 + 0x0CU;
constexpr std::uint32_t kSrFe = 1U << 1, kSrNf = 1U << 2, kSrOre = 1U << 3, kSrRxne = 1U << 5,
                        kSrTxe = 1U << 7;
constexpr std::uint32_t kCr1Re = 1U << 2, kCr1Te = 1U << 3, kCr1Rxneie = 1U << 5,
                        kCr1Txeie = 1U << 7, kCr1Ue = 1U << 13;
constexpr unsigned kUsart1Irq = 37U;
// SysTick and NVIC (ARMv7-M ARM B3.3, B3.4)
constexpr std::uintptr_t kSystCsr = 0xE000E010U;
constexpr std::uintptr_t kSystRvr = 0xE000E014U;
constexpr std::uintptr_t kSystCvr = 0xE000E018U;
constexpr std::uintptr_t kNvicIser = 0xE000E100U;
constexpr std::uintptr_t kNvicIpr = 0xE000E400U;
constexpr std::uintptr_t kScbIcsr = 0xE000ED04U;
constexpr std::uint32_t kIcsrPendSvSet = 1U << 28;
constexpr std::uint32_t kIcsrPendStSet = 1U << 26;  // SysTick pending
constexpr std::uintptr_t kScbShpr3 = 0xE000ED20U;  // bits 23:16 PendSV, 31:24 SysTick

// Core clock: HSE 25 MHz (the Netduino Plus 2 crystal) -> PLL M=25 N=336 P=2 = 168 MHz,
// APB2 = 84 MHz (USART1), APB1 = 42 MHz.
#ifndef GYRODRIFT_FW_CORE_HZ
#define GYRODRIFT_FW_CORE_HZ 168000000
#endif
constexpr std::uint32_t kCoreHz = GYRODRIFT_FW_CORE_HZ;
constexpr std::uint32_t kApb2Hz = 84000000U;
constexpr std::uint32_t kReadyPolls = 100000U;  // bounded waits for the oscillator/PLL

#ifndef GYRODRIFT_FW_RX_RING
#define GYRODRIFT_FW_RX_RING 512
#endif
#ifndef GYRODRIFT_FW_TX_RING
#define GYRODRIFT_FW_TX_RING 256
#endif
constexpr std::uint32_t kRxRing = GYRODRIFT_FW_RX_RING;
constexpr std::uint32_t kTxRing = GYRODRIFT_FW_TX_RING;
static_assert((kRxRing & (kRxRing - 1U)) == 0U && (kTxRing & (kTxRing - 1U)) == 0U,
              "ring sizes must be powers of two");

// Single-producer single-consumer rings: indices run free (wrap at 2^32), the producer
// writes only head, the consumer only tail; 32-bit aligned accesses are atomic on the M4.
struct Ring {
  volatile std::uint32_t head = 0;
  volatile std::uint32_t tail = 0;
};
std::uint8_t g_rx[kRxRing];
std::uint8_t g_tx[kTxRing];
Ring g_rx_ring;
Ring g_tx_ring;
LinkCounters g_link;
// The byte the receive interrupt took aside when the ring was full (rx_read puts it in).
std::uint8_t g_rx_held = 0;
volatile bool g_rx_held_valid = false;
volatile std::uint32_t g_ticks = 0;
volatile bool g_tick_work = false;  // SysTick pends the tick work (start_tick_work)
volatile std::uint32_t g_isr_cycles = 0;
std::uint64_t g_tick_work_cycles = 0;  // written by the tick work only
std::uint32_t g_reload = 0;

inline void irq_off() noexcept { __asm volatile("cpsid i" ::: "memory"); }
inline void irq_on() noexcept { __asm volatile("cpsie i" ::: "memory"); }

bool wait_bit(std::uintptr_t addr, std::uint32_t bit) noexcept {
  for (std::uint32_t i = 0; i < kReadyPolls; ++i) {
    if ((reg(addr) & bit) != 0U) return true;
  }
  return false;
}

// HSE -> PLL -> SYSCLK 168 MHz, flash 5 wait states with caches and prefetch. Every wait is
// bounded: if the oscillator or the PLL does not report ready (no crystal, or an emulator
// without an RCC model) the clock stays on its reset source.
void clock_init() noexcept {
  reg(kFlashAcr) = 5U | (1U << 8) | (1U << 9) | (1U << 10);  // LATENCY=5, PRFTEN, ICEN, DCEN
  reg(kRccCr) |= 1U << 16;                                   // HSEON
  if (!wait_bit(kRccCr, 1U << 17)) return;                   // HSERDY
  reg(kRccPllCfgr) = 25U | (336U << 6) | (0U << 16) | (1U << 22) | (7U << 24);
  reg(kRccCr) |= 1U << 24;                    // PLLON
  if (!wait_bit(kRccCr, 1U << 25)) return;    // PLLRDY
  reg(kRccCfgr) = (5U << 10) | (4U << 13) | 2U;  // APB1 /4, APB2 /2, SW = PLL
  (void)wait_bit(kRccCfgr, 2U << 2);             // SWS = PLL
}

void usart_init(std::uint32_t baud) noexcept {
  reg(kRccAhb1Enr) |= 1U << 0;  // GPIOAEN
  reg(kRccApb2Enr) |= 1U << 4;  // USART1EN
  // PA9/PA10 alternate function mode (MODER = 10b), AF7 (AFRH nibbles 1 and 2)
  reg(kGpioA + 0x00U) = (reg(kGpioA + 0x00U) & ~(0xFU << 18)) | (0xAU << 18);
  reg(kGpioA + 0x24U) = (reg(kGpioA + 0x24U) & ~(0xFFU << 4)) | (0x77U << 4);
  // 16x oversampling: BRR = f_APB2 / baud in 1/16 steps (rounded)
  reg(kBrr) = (kApb2Hz + baud / 2U) / baud;
  reg(kCr1) = kCr1Ue | kCr1Te | kCr1Re | kCr1Rxneie;
  *reinterpret_cast<volatile std::uint8_t*>(kNvicIpr + kUsart1Irq) = 0x40U;  // priority 4 (SysTick keeps its reset priority 0)
  reg(kNvicIser + 4U * (kUsart1Irq / 32U)) = 1U << (kUsart1Irq % 32U);
}

void systick_init(std::uint32_t tick_hz) noexcept {
  // SysTick 0 (its reset priority), PendSV 0xF0: the lowest of the 16 levels the part has
  reg(kScbShpr3) = (reg(kScbShpr3) & ~(0xFFU << 16)) | (0xF0U << 16);
  g_reload = kCoreHz / tick_hz - 1U;
  reg(kSystRvr) = g_reload;
  reg(kSystCvr) = 0U;
  reg(kSystCsr) = 0x7U;  // CLKSOURCE = core, TICKINT, ENABLE
}

// Moves queued bytes into the transmitter while it takes them; interrupts must be off.
void tx_pump_locked() noexcept {
  while (g_tx_ring.tail != g_tx_ring.head && (reg(kSr) & kSrTxe) != 0U) {
    reg(kDr) = g_tx[g_tx_ring.tail & (kTxRing - 1U)];
    g_tx_ring.tail = g_tx_ring.tail + 1U;
    ++g_link.tx_bytes;
  }
  if (g_tx_ring.tail != g_tx_ring.head) reg(kCr1) |= kCr1Txeie;
  else reg(kCr1) &= ~kCr1Txeie;
}

}  // namespace

void init(std::uint32_t tick_hz, std::uint32_t baud) noexcept {
  irq_off();
  clock_init();
  usart_init(baud);
  systick_init(tick_hz);
  irq_on();
}

void start_tick_work() noexcept { g_tick_work = true; }

void sleep(bool (*work_ready)() noexcept) noexcept {
  irq_off();  // check and sleep with interrupts masked: a request cannot slip in between
  if (work_ready == nullptr || !work_ready()) {
    __asm volatile("wfi" ::: "memory");  // wakes on a pending interrupt even with PRIMASK set
  }
  irq_on();  // the pending interrupt is taken here
}

std::size_t rx_read(std::uint8_t* dst, std::size_t cap) noexcept {
  std::size_t n = 0;
  std::uint32_t tail = g_rx_ring.tail;
  const std::uint32_t head = g_rx_ring.head;
  while (n < cap && tail != head) {
    dst[n++] = g_rx[tail & (kRxRing - 1U)];
    ++tail;
  }
  g_rx_ring.tail = tail;
  if (n > 0U && (reg(kCr1) & kCr1Rxneie) == 0U) {
    irq_off();  // room again: the byte taken aside first, then resume the receive interrupt
    if (g_rx_held_valid) {  // (paused, so the ring's head is ours meanwhile)
      g_rx[g_rx_ring.head & (kRxRing - 1U)] = g_rx_held;
      g_rx_ring.head = g_rx_ring.head + 1U;
      g_rx_held_valid = false;
    }
    reg(kCr1) |= kCr1Rxneie;  // a byte waiting in the data register is taken at once
    irq_on();
  }
  return n;
}

std::size_t tx_room() noexcept { return kTxRing - (g_tx_ring.head - g_tx_ring.tail); }

bool tx_write(const std::uint8_t* src, std::size_t n) noexcept {
  if (n > tx_room()) return false;
  std::uint32_t head = g_tx_ring.head;
  for (std::size_t i = 0; i < n; ++i) g_tx[(head++) & (kTxRing - 1U)] = src[i];
  g_tx_ring.head = head;
  tx_kick();
  return true;
}

void tx_kick() noexcept {
  irq_off();
  tx_pump_locked();
  irq_on();
}

std::uint32_t stamp() noexcept { return reg(kSystCvr); }

std::uint32_t cycles_since(std::uint32_t start) noexcept {
  const std::uint32_t now = reg(kSystCvr);  // counts down from g_reload to 0
  return start >= now ? start - now : start + (g_reload + 1U) - now;
}

std::uint32_t core_clock_hz() noexcept { return kCoreHz; }

std::uint32_t interrupt_cycles() noexcept { return g_isr_cycles; }

std::uint64_t clock_cycles() noexcept {
  for (;;) {
    const std::uint32_t ticks = g_ticks;
    const std::uint32_t before = reg(kSystCvr);
    // the counter reloaded but its tick not counted yet (the interrupt masked, or a few
    // cycles before it is taken): that tick is due
    const bool due = (reg(kScbIcsr) & kIcsrPendStSet) != 0U;
    const std::uint32_t now = reg(kSystCvr);
    // a tick counted, or a reload (the counter counts down) between the reads: again
    if (ticks != g_ticks || now > before) continue;
    const std::uint64_t whole = static_cast<std::uint64_t>(ticks) + (due ? 1U : 0U);
    return whole * (static_cast<std::uint64_t>(g_reload) + 1U) + (g_reload - now);
  }
}

std::uint64_t tick_work_cycles() noexcept {
  irq_off();  // 64 bits written by the tick work: read them whole
  const std::uint64_t c = g_tick_work_cycles;
  irq_on();
  return c;
}

const LinkCounters& link_counters() noexcept { return g_link; }

std::uint32_t stack_high_water_bytes() noexcept {
  return gyrodrift::cortex_m_start::stack_high_water_bytes();  // painted by startup.cpp
}

std::uint32_t stack_used_by(void (*fn)()) noexcept {
  irq_off();
  const std::uint32_t used = gyrodrift::cortex_m_start::stack_used_by(fn);
  irq_on();
  return used;
}

}  // namespace gyrodrift::firmware::board

using namespace gyrodrift::firmware::board;

extern "C" void SysTick_Handler(void) {
  g_ticks = g_ticks + 1U;
  if (g_tick_work) reg(kScbIcsr) = kIcsrPendSvSet;  // runs once more if already running
}

extern "C" void PendSV_Handler(void) {
  const std::uint64_t t0 = clock_cycles();
  const std::uint32_t isr0 = g_isr_cycles;
  gyrodrift::firmware::tick_work(g_ticks);
  const std::uint64_t spent = clock_cycles() - t0;
  const std::uint32_t nested = g_isr_cycles - isr0;  // the link interrupt's, nested in it
  g_tick_work_cycles += spent > nested ? spent - nested : 0U;
}

extern "C" void USART1_IRQHandler(void) {
  const std::uint32_t t0 = stamp();
  const std::uint32_t sr = reg(kSr);
  if ((sr & kSrOre) != 0U) ++g_link.rx_overrun;  // cleared by the SR read then the DR read
  if ((sr & (kSrFe | kSrNf)) != 0U) ++g_link.rx_framing;
  if ((sr & (kSrRxne | kSrOre)) != 0U && (reg(kCr1) & kCr1Rxneie) != 0U) {
    if (g_rx_ring.head - g_rx_ring.tail >= kRxRing) {
#if defined(GYRODRIFT_FW_RX_FULL_DROPS)
      // Ring full, drop policy: the byte is read and discarded, and counted.
      (void)reg(kDr);
      ++g_link.rx_ring_overflow;
#else
      // Ring full, default policy: take this byte aside (one byte, put into the ring by
      // rx_read before anything newer) and pause this interrupt until the application has
      // read from the ring (rx_read resumes it); the next byte waits in the data register.
      // A sender that keeps going meanwhile overruns the receiver, which the next SR read
      // counts (rx_overrun); a sender that waits (QEMU's serial back-end) loses nothing.
      // Reading the data register is what clears the request: QEMU's USART model keeps its
      // interrupt line raised while a byte waits, whatever RXNEIE says, and the interrupt
      // would then re-enter forever and starve the ring's reader. RXNEIE goes off first, so
      // that a byte the emulator delivers right after the read raises no request either.
      reg(kCr1) &= ~kCr1Rxneie;
      g_rx_held = static_cast<std::uint8_t>(reg(kDr) & 0xFFU);
      g_rx_held_valid = true;
      ++g_link.rx_bytes;
      ++g_link.rx_stalls;
#endif
    } else {
      const auto byte = static_cast<std::uint8_t>(reg(kDr) & 0xFFU);
      ++g_link.rx_bytes;
      bool keep = true;
#if defined(GYRODRIFT_FW_INJECT_DROPPED_BYTE)
      // Deliberate defect for the test of the test: one byte vanishes without a count.
      keep = g_link.rx_bytes != 4000U;
#endif
      if (keep) {
        g_rx[g_rx_ring.head & (kRxRing - 1U)] = byte;
        g_rx_ring.head = g_rx_ring.head + 1U;
      }
    }
  }
  if ((reg(kCr1) & kCr1Txeie) != 0U && (sr & kSrTxe) != 0U) tx_pump_locked();
  g_isr_cycles = g_isr_cycles + cycles_since(t0);
}

// errno of the C library's float math routines (logf, expf, ... set it on a domain or range
// error; the image never reads it): one int of .bss, instead of newlib's reentrancy structure
// (about 100 bytes of .data) that its own __errno returns a member of. The tick work and
// thread mode (a background fit's double routines) may both set it; nothing reads it, so one
// errno shared by them is harmless.
extern "C" int* __errno(void) {
  static int error_number = 0;
  return &error_number;
}
