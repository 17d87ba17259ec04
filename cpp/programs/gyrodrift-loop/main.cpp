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
// The processor and the rates come from a configuration: --config FILE, or the built-in
// default configuration; --check-config FILE only reads and checks a file.
//
// Files, one job each: options.hpp (command line), config_file.hpp (the configuration, read
// field by field through config_schema.hpp; toml_document.hpp its TOML),
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

// Every error: one line on stderr, exit code 2.
int fail(const std::string& err) {
  std::fprintf(stderr, "gyrodrift-loop: error: %s\n", err.c_str());
  return 2;
}

// --check-config FILE: the loop's reader's verdict on FILE.
int check_config(const std::string& path) {
  FileConfig fc;
  std::string err;
  if (!read_config_file(path, fc, err)) return fail(err);
  std::printf("%s: ok\n", path.c_str());
  return 0;
}

// The configuration: --config FILE, or the built-in default configuration.
bool load_config(const Options& o, FileConfig& fc, std::string& source, std::string& err) {
  if (o.config_path.empty()) {
    source = kBuiltinConfigSource;
    return read_builtin_config(fc, err);
  }
  source = o.config_path;
  return read_config_file(o.config_path, fc, err);
}

int open_device(const Options& o, std::string& err) {
  return o.mode == Mode::kSocketCan ? open_socketcan(o.device, err) : open_serial(o.device, o.baud, err);
}

// Everything that can refuse to start, before the first deadline: the configuration and the
// processor built from it, the CAN decode table, the device. Returns the device's fd, or -1.
int set_up(const Options& o, RunInfo& run, std::string& err) {
  FileConfig fc;
  if (!load_config(o, fc, run.config, err)) return -1;
  if (!g_st.proc.init(fc, err)) {
    err = run.config + ": " + err;
    return -1;
  }
  run.sample_rate_hz = fc.sample_rate_hz;
  run.loop_rate_hz = fc.loop_rate_hz;
  if (!o.can_signals_path.empty() && !g_st.user_can.load(o.can_signals_path, err)) return -1;
  return open_device(o, err);
}

void install_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);
}

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

void announce_ready(const RtStatus& rt) {
  // Touch the static buffers so mlockall'd pages are resident before the first deadline.
  std::memset(g_st.in_buf.data(), 0, g_st.in_buf.size());
  std::fprintf(stderr, "{\"event\": \"ready\", \"pid\": %d, \"sched_fifo\": %s, \"mlockall\": %s}\n",
               static_cast<int>(getpid()), rt.sched_fifo ? "true" : "false", rt.mlockall ? "true" : "false");
  std::fflush(stderr);
}

// The fixed-rate schedule: absolute deadlines period_ns apart.
struct Schedule {
  std::uint64_t period_ns = 0;
  std::uint64_t next = 0;
  std::uint64_t prev_wake = 0;
};

// Sleeps until the next deadline and records the wake-up latency and the period jitter;
// false if a signal asked to stop.
bool sleep_until_deadline(Schedule& s, std::uint64_t& wake) {
  const timespec dl = to_timespec(s.next);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &dl, nullptr) == EINTR) {
    if (g_stop_signal != 0) break;
  }
  if (g_stop_signal != 0) return false;
  wake = now_ns();
  g_st.wake_latency.record(wake > s.next ? wake - s.next : 0);
  if (s.prev_wake != 0) {
    const std::uint64_t per = wake - s.prev_wake;
    g_st.period_jitter.record(per > s.period_ns ? per - s.period_ns : s.period_ns - per);
  }
  s.prev_wake = wake;
  return true;
}

// The next deadline after a cycle that ended at `end`: work that ran past it is an overrun,
// and the deadlines it covered are skipped (counted).
void advance(Schedule& s, std::uint64_t end) {
  s.next += s.period_ns;
  if (end > s.next) {
    ++g_st.c.overruns;
    while (s.next < end) {
      s.next += s.period_ns;
      ++g_st.c.missed_deadlines;
    }
  }
}

// One cycle of serial or SLCAN input. The input is drained chunk by chunk, processing and
// flushing each before the next read: a tty hands over at most its line-discipline buffer
// (4 KiB) per read and the kernel refills it meanwhile. Back-pressure: read only while the
// output queue can absorb a chunk's worst-case reply (serial: 1 output byte per input byte;
// SLCAN: a 2-byte "V\r" gets a 6-byte reply), so nothing is lost for lack of room; unread
// input waits in the kernel (and the sender blocks). False at end of input.
bool serve_stream(const Options& o, int fd, bool& got_input) {
  bool open = true;
  std::size_t total = 0;
  while (open && total < o.max_bytes_per_cycle && g_st.out.room() >= 3 * g_st.in_buf.size()) {
    const std::size_t cap = std::min(g_st.in_buf.size(), o.max_bytes_per_cycle - total);
    const std::size_t got = read_chunk(g_st, fd, g_st.in_buf.data(), cap, open);
    if (got == 0) break;
    total += got;
    g_st.c.bytes_in += got;
    got_input = true;
    if (o.mode == Mode::kSerial) process_serial_bytes(g_st, g_st.in_buf.data(), got);
    else process_slcan_bytes(g_st, g_st.in_buf.data(), got);
    if (!g_st.out.flush(fd, g_st.c.bytes_out) && errno != EIO) ++g_st.c.read_errors;
  }
  if (!g_st.out.flush(fd, g_st.c.bytes_out)) {
    if (errno == EIO) open = false;
    else ++g_st.c.read_errors;
  }
  return open;
}

// The cycles at `loop_rate_hz` from `start` until end of input, idle, the duration or a
// signal; returns the reason.
const char* run_cycles(const Options& o, double loop_rate_hz, int fd, std::uint64_t start) {
  Schedule s;
  s.period_ns = static_cast<std::uint64_t>(std::llround(1e9 / loop_rate_hz));
  s.next = start + s.period_ns;
  std::uint64_t last_input = start;
  for (;;) {
    std::uint64_t wake = 0;
    if (!sleep_until_deadline(s, wake)) return "signal";
    ++g_st.c.cycles;
    const std::uint64_t frames_before = g_st.c.frames_in;
    bool got_input = false;
    const bool open = o.mode == Mode::kSocketCan ? process_socketcan(g_st, fd) : serve_stream(o, fd, got_input);
    if (got_input) last_input = wake;
    const std::uint64_t per_cycle = g_st.c.frames_in - frames_before;
    if (per_cycle > g_st.c.max_frames_per_cycle) g_st.c.max_frames_per_cycle = per_cycle;
    const std::uint64_t end = now_ns();
    g_st.compute.record(end - wake);

    const char* reason = nullptr;  // the last that applies wins
    if (!open) reason = "end_of_input";
    if (o.idle_exit_s > 0.0 && static_cast<double>(end - last_input) * 1e-9 > o.idle_exit_s) reason = "idle";
    if (o.duration_s > 0.0 && static_cast<double>(end - start) * 1e-9 >= o.duration_s) reason = "duration";
    advance(s, end);
    if (reason != nullptr) return reason;
  }
}

// Shutdown: give the output queue a bounded chance to drain, count what is left, and close
// the input parsers (a partial frame at the end is counted).
void wind_down(const Options& o, int fd) {
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
}

// The statistics on stdout, and in --stats-json PATH.
void report(const Options& o, const RunInfo& run, const char* end_reason, double elapsed_s) {
  write_stats(stdout, o, run, g_st, end_reason, elapsed_s);
  std::fflush(stdout);
  if (o.stats_path.empty()) return;
  if (std::FILE* f = std::fopen(o.stats_path.c_str(), "w")) {
    write_stats(f, o, run, g_st, end_reason, elapsed_s);
    std::fclose(f);
  } else {
    std::fprintf(stderr, "gyrodrift-loop: cannot write %s: %s\n", o.stats_path.c_str(), std::strerror(errno));
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  std::string err;
  if (!parse_args(argc, argv, o, err)) return fail(err);
  if (!o.check_config_path.empty()) return check_config(o.check_config_path);
  RunInfo run;
  const int fd = set_up(o, run, err);
  if (fd < 0) return fail(err);
  install_signal_handlers();
  run.rt = request_realtime(o);
  announce_ready(run.rt);
  const std::uint64_t start = now_ns();
  const char* end_reason = run_cycles(o, run.loop_rate_hz, fd, start);
  wind_down(o, fd);
  report(o, run, end_reason, static_cast<double>(now_ns() - start) * 1e-9);
  return 0;
}
