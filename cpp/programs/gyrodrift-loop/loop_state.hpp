// The loop's state: counters, latency histograms, the parsers, the output queue and the
// processor. One static instance (allocated at program start, never on the heap).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>

#include <gyrodrift/codecs/can_frames.hpp>
#include <gyrodrift/codecs/serial_frame.hpp>
#include <gyrodrift/codecs/slcan.hpp>

#include "can_signal_input.hpp"  // --can-signals FILE
#include "latency_histogram.hpp"
#include "output_queue.hpp"
#include "processing.hpp"

namespace gyrodrift::loop {

struct Counters {
  std::uint64_t cycles = 0;
  std::uint64_t overruns = 0;          // work finished after the next deadline
  std::uint64_t missed_deadlines = 0;  // deadlines skipped because of overruns
  std::uint64_t bytes_in = 0;
  std::uint64_t bytes_out = 0;
  std::uint64_t frames_in = 0;   // IMU samples decoded from the interface
  std::uint64_t frames_out = 0;  // filtered samples written back (see OutQueue for serial/SLCAN)
  std::uint64_t wrong_type = 0;  // valid serial frames that are not input samples (0x81, 0x02, 0x82)
  std::uint64_t output_overflow = 0;  // outputs that did not fit the queue (counted, not hidden)
  std::uint64_t slcan_replies = 0;
  std::uint64_t can_tx_errors = 0;
  std::uint64_t read_errors = 0;
  std::uint64_t max_frames_per_cycle = 0;
};

// CAN carries no timestamp: the sample time is the sequence number unwrapped (signed 16-bit
// steps, so duplicates/reordering move it back) times the nominal sample period.
struct SeqUnwrapper {
  bool have = false;
  std::uint16_t last = 0;
  std::int64_t unwrapped = 0;
  std::int64_t push(std::uint16_t seq) noexcept {
    if (!have) {
      have = true;
      unwrapped = seq;
    } else {
      unwrapped += static_cast<std::int16_t>(static_cast<std::uint16_t>(seq - last));
    }
    last = seq;
    return unwrapped;
  }
};

inline constexpr std::size_t kOutCapacity = 1U << 21;

struct LoopState {
  LatencyHistogram<200000> wake_latency{100};   // 0.1 us bins up to 20 ms
  LatencyHistogram<200000> period_jitter{100};  // |actual period - nominal|
  LatencyHistogram<200000> compute{100};        // wake -> end of cycle work (incl. syscalls)
  LatencyHistogram<100000> sample{10};          // one sample: filter + encode + queue, 10 ns bins
  std::array<std::uint8_t, 16384> in_buf{};     // one read chunk
  // Capacity for as many frames as the smallest output frame (42-byte serial) fills.
  OutQueue<kOutCapacity, kOutCapacity / serial::kFrameSize + 1> out;
  serial::SerialFrameParser<8192> serial_parser;
  slcan::SlcanParser<> slcan_parser;
  can::CanSampleAssembler<8> can_rx{can::kInputBaseId};
  UserCanInput user_can;  // active with --can-signals
  Processing proc;
  Counters c;
  SeqUnwrapper unwrap;
};

}  // namespace gyrodrift::loop
