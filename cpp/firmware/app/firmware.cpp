// The reference firmware of the IMU loop: every tick of the loop rate, in the board's
// tick-work interrupt (below the link's receive interrupt, above thread mode), it drains the
// receive ring, decodes serial frames, runs each input sample through the processor built from
// the generated configuration header, and queues the output frame for transmission. Thread
// mode runs the background work the processor asks for and sleeps otherwise: the gyro
// monitor's lag identifier defers each drift-model fit to it (3e7 to 1e8 instructions of
// software double, under a second of a 168 MHz M4F at 400 Hz) and applies its outcome a fixed
// number of samples after its request, so the image equals the host loop (which fits inline)
// sample for sample while no fit is late (monitor_late_fits stays 0). Bad input
// never stops the loop: every rejected byte and frame is counted by reason, as the host loop
// (cpp/programs/gyrodrift-loop) counts it. A health request frame (type 0x02) is answered
// with the counters as health report frames (type 0x82), one counter per frame, under the
// names of the host loop's statistics; one report is also sent at start-up.
//
// Static storage only (no heap), no exceptions, float arithmetic only. Board-specific code
// is behind board.hpp.
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include <gyrodrift/codecs/serial_frame.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

#include "board.hpp"
#include "gyrodrift_firmware_config.hpp"  // generated: gyrodrift config emit-cpp --namespace fw_config

#ifndef GYRODRIFT_FW_BAUD
#define GYRODRIFT_FW_BAUD 921600
#endif

namespace {

namespace board = gyrodrift::firmware::board;
namespace serial = gyrodrift::serial;

// Loop counters, named as in the host loop's statistics (written by the tick work only).
struct Counters {
  std::uint32_t cycles = 0;
  std::uint32_t overruns = 0;          // the work of a cycle ran past the next tick
  std::uint32_t missed_deadlines = 0;  // ticks skipped because of overruns
  std::uint32_t frames_in = 0;         // input samples decoded
  std::uint32_t frames_out = 0;        // output frames queued for transmission
  std::uint32_t wrong_type = 0;        // valid frames that are not input samples
  std::uint32_t output_overflow = 0;   // outputs that did not fit the transmit ring
  std::uint32_t max_frames_per_cycle = 0;
  std::uint32_t health_requests = 0;
  std::uint32_t ticks = 0;  // loop-rate ticks since start
};

// Cost of one step (processor + encode + queue) in core-clock cycles as the board's counter
// measures them, without the time spent in the link's interrupt meanwhile: exact maximum and
// minimum, median from a histogram.
constexpr std::uint32_t kCostBinCycles = 16;
constexpr std::size_t kCostBins = 128;
struct StepCost {
  std::uint32_t n = 0;
  std::uint32_t max = 0;
  std::uint32_t min = 0;  // valid when n > 0 (zero-initialised: .bss, not .data)
  std::array<std::uint16_t, kCostBins> hist{};
  void record(std::uint32_t c) noexcept {
    ++n;
    if (c > max) max = c;
    if (n == 1U || c < min) min = c;
    std::size_t b = c / kCostBinCycles;
    if (b >= kCostBins) b = kCostBins - 1U;
    if (hist[b] != 0xFFFFU) ++hist[b];
  }
  std::uint32_t median() const noexcept {  // centre of the bin holding the median
    std::uint32_t acc = 0;
    for (std::size_t b = 0; b < kCostBins; ++b) {
      acc += hist[b];
      if (2U * acc >= n && n > 0U) return static_cast<std::uint32_t>(b) * kCostBinCycles + kCostBinCycles / 2U;
    }
    return 0;
  }
};

// Calibration of the step timer: a loop of known length (2 instructions per turn) timed at
// start-up, the shortest of three tries (an interrupt may land in one). Under QEMU -icount
// it turns timer counts into instructions; on silicon into cycles per instruction of a
// tight loop.
constexpr std::uint32_t kCalibrationTurns = 2000;
std::uint32_t g_calibration_cycles = 0;

void calibrate_timer() noexcept {
  for (int k = 0; k < 3; ++k) {
    std::uint32_t n = kCalibrationTurns;
    const std::uint32_t t0 = board::stamp();
    __asm volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
    const std::uint32_t c = board::cycles_since(t0);
    if (k == 0 || c < g_calibration_cycles) g_calibration_cycles = c;
  }
}

fw_config::Processor g_proc(fw_config::kImuConfig, fw_config::make_wavelet);
serial::SerialFrameParser<256> g_parser;
Counters g_c;
StepCost g_cost;
// The monitor's fits run by thread mode (written there only; one aligned word, read whole).
volatile std::uint32_t g_fits_run = 0;
// The fits' own core-clock cycles (thread mode's time without the interrupts'), saturated at
// 2^32 - 1 (25 s at 168 MHz); aligned words, read whole by the health report.
volatile std::uint32_t g_fit_cycles_max = 0;
volatile std::uint32_t g_fit_cycles_min = 0;
#if defined(GYRODRIFT_FW_MEASURE_FIT_STACK)
std::uint32_t g_fit_stack = 0;  // the deepest stack a fit used below thread mode's frame
#endif

void send_blocking(const std::uint8_t* p, std::size_t n) noexcept {
  while (!board::tx_write(p, n)) board::tx_kick();
}

// One counter as a health report frame: seq = index, flags = group, t_us = value, the value
// bytes = the name.
enum Group : std::uint16_t { kTop = 0, kRejected = 1, kHealth = 2, kFirmware = 3, kEnd = 0xFF };
struct Reporter {
  std::uint16_t index = 0;
  void put(Group g, const char* name, std::uint64_t value) noexcept {
    serial::ImuFrame f;
    f.type = serial::kTypeHealthReport;
    f.seq = index++;
    f.flags = g;
    f.t_us = value;
    std::array<std::uint8_t, serial::kFrameSize> b{};
    serial::encode_frame(f, b.data(), b.size());
    std::size_t k = 0;
    for (; name[k] != '\0' && k < 24U; ++k) b[16U + k] = static_cast<std::uint8_t>(name[k]);
    for (; k < 24U; ++k) b[16U + k] = 0U;
    const std::uint16_t crc = gyrodrift::crc16_ccitt_false(b.data() + 2, serial::kCrcOffset - 2);
    b[serial::kCrcOffset] = static_cast<std::uint8_t>(crc & 0xFFU);
    b[serial::kCrcOffset + 1U] = static_cast<std::uint8_t>(crc >> 8);
    send_blocking(b.data(), b.size());
  }
};

void send_health() noexcept {
  Reporter r;
  const board::LinkCounters& l = board::link_counters();
  const serial::SerialParserStats& s = g_parser.stats();
  r.put(kTop, "cycles", g_c.cycles);
  r.put(kTop, "overruns", g_c.overruns);
  r.put(kTop, "missed_deadlines", g_c.missed_deadlines);
  r.put(kTop, "frames_in", g_c.frames_in);
  r.put(kTop, "frames_out", g_c.frames_out);
  r.put(kTop, "frames_queued", g_c.frames_out);
  r.put(kTop, "max_frames_per_cycle", g_c.max_frames_per_cycle);
  r.put(kTop, "bytes_in", l.rx_bytes);
  r.put(kTop, "bytes_out", l.tx_bytes);
  r.put(kRejected, "crc", s.crc_errors);
  r.put(kRejected, "bad_header", s.bad_header);
  r.put(kRejected, "truncated", s.truncated);
  r.put(kRejected, "garbage_bytes", s.garbage_bytes);
  r.put(kRejected, "overflow_bytes", s.overflow_bytes);
  r.put(kRejected, "wrong_type", g_c.wrong_type);
  gyrodrift::for_each_rejection_field(g_proc.health(),
                                      [&r](const char* k, std::uint64_t v) { r.put(kRejected, k, v); });
  r.put(kRejected, "output_overflow", g_c.output_overflow);
  r.put(kRejected, "rx_overrun", l.rx_overrun);
  r.put(kRejected, "rx_framing", l.rx_framing);
  r.put(kRejected, "rx_ring_overflow", l.rx_ring_overflow);
  gyrodrift::for_each_health_field(g_proc.health(),
                                   [&r](const char* k, std::uint64_t v) { r.put(kHealth, k, v); });
  r.put(kFirmware, "health_requests", g_c.health_requests);
  r.put(kFirmware, "ticks", g_c.ticks);
  r.put(kFirmware, "rx_stalls", l.rx_stalls);
  r.put(kFirmware, "stack_bytes", board::stack_high_water_bytes());
  r.put(kFirmware, "monitor_fits_run", g_fits_run);
  r.put(kFirmware, "monitor_late_fits", g_proc.monitor_late_fits());
  r.put(kFirmware, "fit_cycles_max", g_fit_cycles_max);
  r.put(kFirmware, "fit_cycles_min", g_fit_cycles_min);
#if defined(GYRODRIFT_FW_MEASURE_FIT_STACK)
  r.put(kFirmware, "fit_stack_bytes", g_fit_stack);
#endif
  r.put(kFirmware, "core_clock_hz", board::core_clock_hz());
  r.put(kFirmware, "steps_timed", g_cost.n);
  r.put(kFirmware, "step_cycles_max", g_cost.max);
  r.put(kFirmware, "step_cycles_min", g_cost.min);
  r.put(kFirmware, "step_cycles_median", g_cost.median());
  r.put(kFirmware, "step_cycles_bin", kCostBinCycles);
  r.put(kFirmware, "interrupt_cycles", board::interrupt_cycles());
  r.put(kFirmware, "calibration_instructions", 2U * kCalibrationTurns);
  r.put(kFirmware, "calibration_cycles", g_calibration_cycles);
  const std::uint16_t n = r.index;
  r.put(kEnd, "end", n);
}

// One decoded input sample: processor, output frame, queue; timed.
void handle_sample(const serial::ImuFrame& f) noexcept {
  ++g_c.frames_in;
#if defined(GYRODRIFT_FW_INJECT_SKIPPED_STEP)
  // Deliberate defect for the test of the test: one sample is never stepped.
  if (g_c.frames_in == 1500U) return;
#endif
  const std::uint32_t t0 = board::stamp();
  const std::uint32_t isr0 = board::interrupt_cycles();
  gyrodrift::ImuSample<float> in;
  in.seq = f.seq;
  in.t_us = f.t_us;
  in.values = f.values;
  gyrodrift::ImuOutput<float> y;
  if ((g_proc.step(in, y) & gyrodrift::kFlagRejected) == 0U) {
    serial::ImuFrame out;
    out.type = serial::kTypeOutput;
    out.seq = y.seq;
    out.flags = y.flags;
    out.t_us = y.t_us;
    out.values = y.values;
    std::array<std::uint8_t, serial::kFrameSize> b{};
    serial::encode_frame(out, b.data(), b.size());
    if (board::tx_write(b.data(), b.size())) ++g_c.frames_out;
    else ++g_c.output_overflow;
  }
  const std::uint32_t elapsed = board::cycles_since(t0);
  const std::uint32_t in_isr = board::interrupt_cycles() - isr0;  // receive bytes meanwhile
  g_cost.record(elapsed > in_isr ? elapsed - in_isr : 0U);
}

// Everything received since the last cycle; returns the input samples handled.
std::uint32_t serve_link() noexcept {
  std::uint32_t samples = 0;
  std::array<std::uint8_t, 64> chunk{};
  for (;;) {
    std::size_t room = g_parser.capacity() - g_parser.buffered();
    if (room > chunk.size()) room = chunk.size();
    const std::size_t n = board::rx_read(chunk.data(), room);
    if (n == 0U) break;
    g_parser.feed(chunk.data(), n);
    serial::ImuFrame f;
    while (g_parser.next(f)) {
      if (f.type == serial::kTypeInput) {
        handle_sample(f);
        ++samples;
      } else if (f.type == serial::kTypeHealthRequest) {
        ++g_c.health_requests;
        send_health();
      } else {
        ++g_c.wrong_type;
      }
    }
  }
  return samples;
}

std::uint32_t g_last_tick = 0;  // the tick of the previous tick work
bool g_started = false;         // the first tick work only sets g_last_tick

// Thread mode's work, run whenever the tick work leaves time: the monitor's pending fit (none
// in an image without the lag identifier); returns whether it did any.
bool background_ready() noexcept { return g_proc.monitor_fit_pending(); }
bool run_background() noexcept {
  if (!g_proc.monitor_fit_pending()) return false;
  const std::uint64_t c0 = board::clock_cycles();
  const std::uint64_t w0 = board::tick_work_cycles();
  const std::uint32_t i0 = board::interrupt_cycles();
#if defined(GYRODRIFT_FW_MEASURE_FIT_STACK)
  // Measurement build: each fit with interrupts masked on freshly painted stack, so the stack
  // below thread mode's frame is the fit's own (the loop stalls for the fit meanwhile, and the
  // ticks it masks make the fit's cycles below wrong in this build).
  const std::uint32_t used = board::stack_used_by([] { g_proc.run_pending_monitor_fit(); });
  if (used > g_fit_stack) g_fit_stack = used;
#else
  g_proc.run_pending_monitor_fit();
#endif
  const std::uint64_t all = board::clock_cycles() - c0;
  const std::uint64_t others = (board::tick_work_cycles() - w0) + (board::interrupt_cycles() - i0);
  const std::uint64_t own64 = all > others ? all - others : 0U;
  const std::uint32_t own = own64 > 0xFFFFFFFFU ? 0xFFFFFFFFU : static_cast<std::uint32_t>(own64);
  if (own > g_fit_cycles_max) g_fit_cycles_max = own;
  if (g_fits_run == 0U || own < g_fit_cycles_min) g_fit_cycles_min = own;
  g_fits_run = g_fits_run + 1U;
  return true;
}

}  // namespace

// One tick of the loop (the board's tick-work interrupt).
void gyrodrift::firmware::tick_work(std::uint32_t tick) noexcept {
  if (!g_started) {  // the reference that overruns are counted from
    g_started = true;
    g_last_tick = tick;
    return;
  }
  if (tick - g_last_tick > 1U) {
    ++g_c.overruns;
    g_c.missed_deadlines += tick - g_last_tick - 1U;
  }
  g_last_tick = tick;
  g_c.ticks = tick;
  ++g_c.cycles;
  const std::uint32_t n = serve_link();
  if (n > g_c.max_frames_per_cycle) g_c.max_frames_per_cycle = n;
  board::tx_kick();
}

extern "C" [[noreturn]] void firmware_main(void) {
  static_assert(fw_config::kLoopRateHz >= 1.0F, "loop rate below 1 Hz");
  board::init(static_cast<std::uint32_t>(fw_config::kLoopRateHz + 0.5F), GYRODRIFT_FW_BAUD);
  calibrate_timer();
  // The gyro monitor, when the configuration has one ([monitor] enabled; else a no-op).
  const bool monitor_ok = fw_config::start_monitor(g_proc);
  g_proc.defer_monitor_fits(true);  // the lag identifier's fits in thread mode (else a no-op)
  send_health();  // start-up announcement
  // A configuration the processor refuses is refused by the build already; should one get
  // here, the loop stops after the announcement (its health shows every sample rejected).
  while (g_proc.status() != gyrodrift::ImuStatus::ok || !monitor_ok) board::sleep();
  // The loop: the tick work from the next tick on, thread mode in the background.
  board::start_tick_work();
  for (;;) {
    if (!run_background()) board::sleep(background_ready);
  }
}
