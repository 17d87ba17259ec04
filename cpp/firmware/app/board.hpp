// What the portable firmware application needs from a board: a byte link (interrupt-driven
// receive into a fixed ring, transmit from another), a periodic tick at the loop rate, a
// cycle counter for timing one step, and the driver's loss counters. A port to another MCU
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
};

// Clocks, the link at `baud`, the tick at `tick_hz`; interrupts enabled on return.
void init(std::uint32_t tick_hz, std::uint32_t baud) noexcept;

// Sleeps until the next tick; returns the number of ticks since init (ticks the caller
// slept through or missed show as a jump > 1).
std::uint32_t wait_for_tick() noexcept;

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

const LinkCounters& link_counters() noexcept;

// Deepest stack use so far in bytes (painted-RAM high-water mark).
std::uint32_t stack_high_water_bytes() noexcept;

}  // namespace gyrodrift::firmware::board
