// What the portable firmware application needs from a board: a byte link (interrupt-driven
// receive into a fixed ring, transmit from another), a periodic tick at the loop rate that
// runs the application's tick work in an interrupt below the link's, a sleep for thread mode,
// a cycle counter for timing one step, and the driver's loss counters. A port to another MCU
// implements exactly these functions in its own board folder (board/<name>/) and nothing
// in app/ changes (docs/guides/firmware-porting.md).
#pragma once
#include <cstddef>
#include <cstdint>

namespace gyrodrift::firmware::board {

// Bytes the link driver lost or held back; every loss has a counter (never silent).
struct LinkCounters {
  std::uint32_t rx_bytes = 0;          // bytes taken from the receiver into the ring
  std::uint32_t tx_bytes = 0;          // bytes handed to the transmitter
  std::uint32_t rx_overrun = 0;        // receiver overruns (a byte lost in hardware)
  std::uint32_t rx_framing = 0;        // framing/noise errors reported by the receiver
  std::uint32_t rx_ring_overflow = 0;  // bytes lost because the receive ring was full
  std::uint32_t rx_stalls = 0;         // receive interrupt paused while the ring was full
                                       // (one byte held aside meanwhile)
};

// Clocks, the link at `baud`, the tick at `tick_hz` (counting, no tick work yet); interrupts
// enabled on return.
void init(std::uint32_t tick_hz, std::uint32_t baud) noexcept;

// From the next tick on, every tick runs tick_work() (below) in the tick-work interrupt: its
// priority is below the link's receive and transmit interrupt (which nests in it, so no byte
// waits for a step) and above thread mode (which it preempts). A tick that comes while the
// work of an earlier one still runs is counted, and the work runs once more after it with
// the newer count (ticks it ran past show as a jump > 1).
void start_tick_work() noexcept;

// Thread mode: sleeps (WFI) until an interrupt has been handled, unless `work_ready` (checked
// with interrupts masked, so a request made by an interrupt cannot slip in between) says
// there is work; returns at once then. nullptr: no check.
void sleep(bool (*work_ready)() noexcept = nullptr) noexcept;

// Up to `cap` received bytes, oldest first; 0 if none.
std::size_t rx_read(std::uint8_t* dst, std::size_t cap) noexcept;

// Free bytes in the transmit ring.
std::size_t tx_room() noexcept;

// Queues n bytes for transmission, all or nothing; false if they do not fit.
bool tx_write(const std::uint8_t* src, std::size_t n) noexcept;

// Starts or continues transmission of the queued bytes (safe to call any time).
void tx_kick() noexcept;

// The core clock counter for timing: stamp() now, cycles_since(stamp) the core-clock cycles
// elapsed (valid for intervals shorter than one tick period).
std::uint32_t stamp() noexcept;
std::uint32_t cycles_since(std::uint32_t stamp) noexcept;
std::uint32_t core_clock_hz() noexcept;

// Core-clock cycles spent in the link's interrupt handler since init (as timed by stamp):
// the app subtracts what lands inside a step, so a step's cost is its own.
std::uint32_t interrupt_cycles() noexcept;

// Core-clock cycles since init (the tick count and the position within the tick), for timing
// thread mode's work over many ticks; and the cycles spent in the tick work since init without
// the link interrupt's nested in it. Thread mode's own cycles over an interval: the clock's
// minus the tick work's minus the link interrupt's (the tick interrupt's few instructions a
// tick stay in).
std::uint64_t clock_cycles() noexcept;
std::uint64_t tick_work_cycles() noexcept;

const LinkCounters& link_counters() noexcept;

// Deepest stack use so far in bytes (painted-RAM high-water mark).
std::uint32_t stack_high_water_bytes() noexcept;

// Measurement builds only: runs fn with interrupts masked and returns the stack it used below
// the caller's frame in bytes (the loop stalls meanwhile; stack_high_water_bytes restarts).
std::uint32_t stack_used_by(void (*fn)()) noexcept;

}  // namespace gyrodrift::firmware::board

namespace gyrodrift::firmware {

// The loop's work of one tick, written by the application (app/firmware.cpp) and called by
// the board from the tick-work interrupt; `tick` is the number of ticks since init.
void tick_work(std::uint32_t tick) noexcept;

}  // namespace gyrodrift::firmware
