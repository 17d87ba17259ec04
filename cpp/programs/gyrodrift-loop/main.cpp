// gyrodrift-loop: a firmware-style fixed-rate IMU loop for hardware-in-the-loop replay.
//
// Every period (absolute deadlines with clock_nanosleep(TIMER_ABSTIME), so the schedule does
// not drift with the work done per cycle) it drains the input interface, decodes IMU samples
// (serial frames, SLCAN lines or SocketCAN frames), runs each through the float
// ImuProcessor, and writes the filtered sample back on the same interface in the same
// format. Bad input never stops the loop: every rejected byte/frame is counted by reason.
// On end of input or SIGINT/SIGTERM it prints JSON statistics on stdout.
//
// All buffers are fixed-size and allocated before the loop starts (static storage); the
// cycle itself does not allocate.
//
// Files, one job each: options.hpp (command line), config_file.hpp (--config FILE),
// processing.hpp (the processor and its counters), transport.hpp (opening the devices),
// wire_io.hpp (wire <-> ImuSample/ImuOutput), output_queue.hpp (non-blocking output with
// frame accounting), loop_state.hpp (the static state), stats_json.hpp (the statistics),
// latency_histogram.hpp; this file: real-time set-up and the fixed-rate cycle.
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include "config_file.hpp"
#include "loop_state.hpp"
#include "options.hpp"
#include "stats_json.hpp"
#include "transport.hpp"
#include "wire_io.hpp"

namespace {

using namespace gyrodrift::loop;

volatile sig_atomic_t g_stop_signal = 0;
extern "C" void on_signal(int sig) { g_stop_signal = sig; }

timespec to_timespec(std::uint64_t ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / 1000000000ULL);
  ts.tv_nsec = static_cast<long>(ns % 1000000000ULL);
  return ts;
}

LoopState g_st;  // static storage: every buffer of the loop, allocated once

RtStatus request_realtime(const Options& o) {
  RtStatus s;
  if (!o.realtime) {
    s.sched_error = s.mlock_error = "not requested (--no-rt)";
    return s;
  }
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) s.mlockall = true;
  else s.mlock_error = std::strerror(errno);
  sched_param sp{};
  sp.sched_priority = o.rt_priority;
  if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) s.sched_fifo = true;
  else s.sched_error = std::strerror(errno);
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  std::string err;
  if (!parse_args(argc, argv, o, err)) {
    std::fprintf(stderr, "gyrodrift-loop: error: %s\n", err.c_str());
    usage(stderr);
    return 2;
  }
  if (!o.can_signals_path.empty() && !g_st.user_can.load(o.can_signals_path, err)) {
    std::fprintf(stderr, "gyrodrift-loop: error: %s\n", err.c_str());
    return 2;
  }
  int fd = -1;
  if (o.mode == Mode::kSocketCan) fd = open_socketcan(o.device, err);
  else fd = open_serial(o.device, o.baud, err);
  if (fd < 0) {
    std::fprintf(stderr, "gyrodrift-loop: error: %s\n", err.c_str());
    return 2;
  }
  bool proc_ok = false;
  if (!o.config_path.empty()) {
    FileConfig fc;
    if (!read_config_file(o.config_path, fc, err)) {
      std::fprintf(stderr, "gyrodrift-loop: error: %s\n", err.c_str());
      return 2;
    }
    // The command line overrides the file's timing.
    if (o.sample_rate_given && o.sample_rate_hz != fc.sample_rate_hz) {
      std::fprintf(stderr, "gyrodrift-loop: error: --sample-rate-hz %g contradicts timing.sample_rate_hz %g of %s\n",
                   o.sample_rate_hz, fc.sample_rate_hz, o.config_path.c_str());
      return 2;
    }
    if (!o.rate_given) o.rate_hz = fc.loop_rate_hz > 0.0 ? fc.loop_rate_hz : fc.sample_rate_hz;
    if (!(o.rate_hz >= 1.0 && o.rate_hz <= 2000.0)) {
      std::fprintf(stderr, "gyrodrift-loop: error: loop rate %g Hz outside 1..2000 (give --rate-hz)\n", o.rate_hz);
      return 2;
    }
    o.sample_rate_hz = fc.sample_rate_hz;
    proc_ok = g_st.proc.init(fc, err);
  } else {
    o.proc.sample_rate_hz = o.sample_rate_hz;
    proc_ok = g_st.proc.init(o.proc, err);
  }
  if (!proc_ok) {
    std::fprintf(stderr, "gyrodrift-loop: error: %s\n", err.c_str());
    return 2;
  }

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);

  const RtStatus rt = request_realtime(o);
  // Touch the static buffers so mlockall'd pages are resident before the first deadline.
  std::memset(g_st.in_buf.data(), 0, g_st.in_buf.size());
  std::fprintf(stderr, "{\"event\": \"ready\", \"pid\": %d, \"sched_fifo\": %s, \"mlockall\": %s}\n",
               static_cast<int>(getpid()), rt.sched_fifo ? "true" : "false", rt.mlockall ? "true" : "false");
  std::fflush(stderr);

  const auto period_ns = static_cast<std::uint64_t>(std::llround(1e9 / o.rate_hz));
  const std::uint64_t start = now_ns();
  std::uint64_t next = start + period_ns;
  std::uint64_t prev_wake = 0;
  std::uint64_t last_input = start;
  const char* end_reason = "signal";
  bool running = true;
  while (running) {
    const timespec dl = to_timespec(next);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &dl, nullptr) == EINTR) {
      if (g_stop_signal != 0) break;
    }
    if (g_stop_signal != 0) break;
    const std::uint64_t wake = now_ns();
    g_st.wake_latency.record(wake > next ? wake - next : 0);
    if (prev_wake != 0) {
      const std::uint64_t per = wake - prev_wake;
      g_st.period_jitter.record(per > period_ns ? per - period_ns : period_ns - per);
    }
    prev_wake = wake;
    ++g_st.c.cycles;
    const std::uint64_t frames_before = g_st.c.frames_in;

    bool open = true;
    if (o.mode == Mode::kSocketCan) {
      open = process_socketcan(g_st, fd);
    } else {
      // Drain the input chunk by chunk, processing and flushing each before the next read: a
      // tty hands over at most its line-discipline buffer (4 KiB) per read and the kernel
      // refills it meanwhile. Back-pressure: read only while the output queue can absorb a
      // chunk's worst-case reply (serial: 1 output byte per input byte; SLCAN: a 2-byte "V\r"
      // gets a 6-byte reply), so nothing is lost for lack of room; unread input waits in
      // the kernel (and the sender blocks).
      std::size_t total = 0;
      while (open && total < o.max_bytes_per_cycle && g_st.out.room() >= 3 * g_st.in_buf.size()) {
        const std::size_t cap = std::min(g_st.in_buf.size(), o.max_bytes_per_cycle - total);
        const std::size_t got = read_chunk(g_st, fd, g_st.in_buf.data(), cap, open);
        if (got == 0) break;
        total += got;
        g_st.c.bytes_in += got;
        last_input = wake;
        if (o.mode == Mode::kSerial) process_serial_bytes(g_st, g_st.in_buf.data(), got);
        else process_slcan_bytes(g_st, g_st.in_buf.data(), got);
        if (!g_st.out.flush(fd, g_st.c.bytes_out) && errno != EIO) ++g_st.c.read_errors;
      }
      if (!g_st.out.flush(fd, g_st.c.bytes_out)) {
        if (errno == EIO) open = false;
        else ++g_st.c.read_errors;
      }
    }
    const std::uint64_t per_cycle = g_st.c.frames_in - frames_before;
    if (per_cycle > g_st.c.max_frames_per_cycle) g_st.c.max_frames_per_cycle = per_cycle;
    const std::uint64_t end = now_ns();
    g_st.compute.record(end - wake);

    if (!open) {
      end_reason = "end_of_input";
      running = false;
    }
    if (o.idle_exit_s > 0.0 && static_cast<double>(end - last_input) * 1e-9 > o.idle_exit_s) {
      end_reason = "idle";
      running = false;
    }
    if (o.duration_s > 0.0 && static_cast<double>(end - start) * 1e-9 >= o.duration_s) {
      end_reason = "duration";
      running = false;
    }
    next += period_ns;
    if (end > next) {  // the work ran past the next deadline: count it, skip to the future
      ++g_st.c.overruns;
      while (next < end) {
        next += period_ns;
        ++g_st.c.missed_deadlines;
      }
    }
  }
  // Shutdown: give the output queue a bounded chance to drain, then count what is left.
  if (o.mode != Mode::kSocketCan) {
    const std::uint64_t give_up = now_ns() + 500000000ULL;
    while (g_st.out.pending() > 0 && now_ns() < give_up) {
      if (!g_st.out.flush(fd, g_st.c.bytes_out)) break;
      if (g_st.out.pending() > 0) usleep(1000);
    }
    g_st.out.drop_pending();  // what the peer did not take: counted in frames_dropped
  }
  if (o.mode == Mode::kSerial) g_st.serial_parser.finish();
  else if (g_st.user_can.active()) g_st.user_can.finish();
  else g_st.can_rx.finish();
  const double elapsed_s = static_cast<double>(now_ns() - start) * 1e-9;
  write_stats(stdout, o, rt, g_st, end_reason, elapsed_s);
  std::fflush(stdout);
  if (!o.stats_path.empty()) {
    if (std::FILE* f = std::fopen(o.stats_path.c_str(), "w")) {
      write_stats(f, o, rt, g_st, end_reason, elapsed_s);
      std::fclose(f);
    } else {
      std::fprintf(stderr, "gyrodrift-loop: cannot write %s: %s\n", o.stats_path.c_str(), std::strerror(errno));
    }
  }
  return 0;
}
