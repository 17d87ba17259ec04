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
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <gyrodrift/can_frames.hpp>

#include "can_signal_input.hpp"  // --can-signals FILE (issue 13)
#include <gyrodrift/serial_frame.hpp>
#include <gyrodrift/slcan.hpp>

#include "latency_histogram.hpp"
#include "processing.hpp"
#include "transport.hpp"

namespace {

using gyrodrift::loop::LatencyHistogram;
namespace gser = gyrodrift::serial;
namespace gcan = gyrodrift::can;
namespace gslcan = gyrodrift::slcan;

volatile sig_atomic_t g_stop_signal = 0;
extern "C" void on_signal(int sig) { g_stop_signal = sig; }

enum class Mode { kSerial, kSlcan, kSocketCan };

struct Options {
  Mode mode = Mode::kSerial;
  std::string device;
  long baud = 921600;
  double rate_hz = 400.0;
  double sample_rate_hz = 400.0;  // CAN carries no timestamp: t_us = unwrapped seq / rate
  bool realtime = true;
  int rt_priority = 80;
  std::size_t max_bytes_per_cycle = 65536;
  double idle_exit_s = 0.0;  // 0: never (exit on EOF or signal)
  double duration_s = 0.0;   // 0: unlimited
  std::string stats_path;
  std::string can_signals_path;  // --can-signals: decode CAN input through a user DBC table
  gyrodrift::loop::ProcessingOptions proc;
};

void usage(std::FILE* f) {
  std::fputs(
      "usage: gyrodrift-loop (--serial DEV | --slcan DEV | --socketcan IFACE) [options]\n"
      "  DEV is a device path (/dev/ttyUSB0, /dev/pts/N) or fd:N (inherited descriptor)\n"
      "  --baud N              serial line rate (default 921600; a pty ignores it)\n"
      "  --rate-hz F           loop rate, 1..2000 Hz (default 400)\n"
      "  --sample-rate-hz F    IMU sample rate for CAN timestamps (default 400)\n"
      "  --no-rt               do not request SCHED_FIFO and mlockall\n"
      "  --rt-priority N       SCHED_FIFO priority (default 80)\n"
      "  --max-bytes-per-cycle N  input read budget per cycle (default 65536)\n"
      "  --idle-exit-s S       exit after S seconds without input (default: never)\n"
      "  --duration-s S        exit after S seconds (default: never)\n"
      "  --stats-json PATH     also write the final statistics to PATH\n"
      "  --can-signals FILE    CAN input in a user's DBC layout: the decode table generated\n"
      "                        from it (gyrodrift.codecs.can_signals.decode_table_text)\n"
      "processor (ImuProcessor<float>; the same settings go to the Python reference):\n"
      "  --gyro-filter F       ar2_kalman (default) | bias_removal | pass_through\n"
      "  --accel-filter F      pass_through (default) | bias_removal | ar2_kalman\n"
      "  --gyro-ar2 A1,A2,SIGMA2,MEAN  AR(2) model (default 1.0,-0.25,1e-10,0: a demo model)\n"
      "  --gyro-q Q --gyro-r R Kalman process/measurement variances (default 1e-10, 1e-8)\n"
      "  --gyro-bias B --accel-bias B  subtracted after the filter (default 0)\n"
      "  --gyro-saturation S --accel-saturation S  |x| >= S is saturated (default inf)\n"
      "  --stuck-samples N     N identical values in a row = stuck (default 0: off)\n"
      "  --time-tolerance-us N timestamp check tolerance (default half a period)\n",
      f);
}

bool parse_double(const char* s, double& out) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s, &end);
  if (end == s || *end != '\0' || errno != 0 || !std::isfinite(v)) return false;
  out = v;
  return true;
}

bool parse_long(const char* s, long& out) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(s, &end, 10);
  if (end == s || *end != '\0' || errno != 0) return false;
  out = v;
  return true;
}

bool parse_args(int argc, char** argv, Options& o, std::string& err) {
  int modes = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto need = [&](const char* what) -> const char* {
      if (i + 1 >= argc) {
        err = std::string(what) + " needs a value";
        return nullptr;
      }
      return argv[++i];
    };
    const char* v = nullptr;
    if (a == "-h" || a == "--help") {
      usage(stdout);
      std::exit(0);
    } else if (a == "--serial" || a == "--slcan" || a == "--socketcan") {
      if ((v = need(a.c_str())) == nullptr) return false;
      o.mode = a == "--serial" ? Mode::kSerial : (a == "--slcan" ? Mode::kSlcan : Mode::kSocketCan);
      o.device = v;
      ++modes;
    } else if (a == "--baud") {
      if ((v = need("--baud")) == nullptr || !parse_long(v, o.baud)) return err = "bad --baud", false;
    } else if (a == "--rate-hz") {
      if ((v = need("--rate-hz")) == nullptr || !parse_double(v, o.rate_hz)) return err = "bad --rate-hz", false;
    } else if (a == "--sample-rate-hz") {
      if ((v = need("--sample-rate-hz")) == nullptr || !parse_double(v, o.sample_rate_hz) ||
          o.sample_rate_hz <= 0.0) {
        return err = "bad --sample-rate-hz", false;
      }
    } else if (a == "--gyro-filter" || a == "--accel-filter") {
      if ((v = need(a.c_str())) == nullptr ||
          !gyrodrift::loop::parse_filter(v, a == "--gyro-filter" ? o.proc.gyro_filter : o.proc.accel_filter)) {
        return err = "bad " + a + " (ar2_kalman, bias_removal, pass_through)", false;
      }
    } else if (a == "--gyro-ar2") {
      double m[4] = {0, 0, 0, 0};
      if ((v = need("--gyro-ar2")) == nullptr || !gyrodrift::loop::parse_csv4(v, m)) {
        return err = "bad --gyro-ar2 (A1,A2,SIGMA2,MEAN)", false;
      }
      o.proc.a1 = m[0];
      o.proc.a2 = m[1];
      o.proc.sigma2 = m[2];
      o.proc.mean = m[3];
    } else if (a == "--gyro-q" || a == "--gyro-r" || a == "--gyro-bias" || a == "--accel-bias" ||
               a == "--gyro-saturation" || a == "--accel-saturation") {
      double x = 0.0;
      const bool sat = a == "--gyro-saturation" || a == "--accel-saturation";
      if ((v = need(a.c_str())) == nullptr) return false;
      if (sat && std::string(v) == "inf") x = INFINITY;
      else if (!parse_double(v, x)) return err = "bad " + a, false;
      if (a == "--gyro-q") o.proc.q = x;
      else if (a == "--gyro-r") o.proc.r = x;
      else if (a == "--gyro-bias") o.proc.gyro_bias = x;
      else if (a == "--accel-bias") o.proc.accel_bias = x;
      else if (a == "--gyro-saturation") o.proc.gyro_saturation = x;
      else o.proc.accel_saturation = x;
    } else if (a == "--stuck-samples") {
      long n = 0;
      if ((v = need("--stuck-samples")) == nullptr || !parse_long(v, n) || n < 0 || n > 1000000) {
        return err = "bad --stuck-samples", false;
      }
      o.proc.stuck_samples = static_cast<std::uint32_t>(n);
    } else if (a == "--time-tolerance-us") {
      if ((v = need("--time-tolerance-us")) == nullptr || !parse_long(v, o.proc.time_tolerance_us) ||
          o.proc.time_tolerance_us < 0) {
        return err = "bad --time-tolerance-us", false;
      }
    } else if (a == "--no-rt") {
      o.realtime = false;
    } else if (a == "--rt-priority") {
      long p = 0;
      if ((v = need("--rt-priority")) == nullptr || !parse_long(v, p) || p < 1 || p > 99) {
        return err = "bad --rt-priority (1..99)", false;
      }
      o.rt_priority = static_cast<int>(p);
    } else if (a == "--max-bytes-per-cycle") {
      long n = 0;
      if ((v = need("--max-bytes-per-cycle")) == nullptr || !parse_long(v, n) || n < 64 || n > (1L << 20)) {
        return err = "bad --max-bytes-per-cycle (64..1048576)", false;
      }
      o.max_bytes_per_cycle = static_cast<std::size_t>(n);
    } else if (a == "--idle-exit-s") {
      if ((v = need("--idle-exit-s")) == nullptr || !parse_double(v, o.idle_exit_s) || o.idle_exit_s < 0.0) {
        return err = "bad --idle-exit-s", false;
      }
    } else if (a == "--duration-s") {
      if ((v = need("--duration-s")) == nullptr || !parse_double(v, o.duration_s) || o.duration_s < 0.0) {
        return err = "bad --duration-s", false;
      }
    } else if (a == "--stats-json") {
      if ((v = need("--stats-json")) == nullptr) return false;
      o.stats_path = v;
    } else if (a == "--can-signals") {
      if ((v = need("--can-signals")) == nullptr) return false;
      o.can_signals_path = v;
    } else {
      err = "unknown argument '" + a + "'";
      return false;
    }
  }
  if (modes != 1) {
    err = "give exactly one of --serial, --slcan, --socketcan";
    return false;
  }
  if (!o.can_signals_path.empty() && o.mode == Mode::kSerial) {
    err = "--can-signals applies to --slcan and --socketcan input";
    return false;
  }
  if (!(o.rate_hz >= 1.0 && o.rate_hz <= 2000.0)) {
    err = "--rate-hz must be within 1..2000";
    return false;
  }
  return true;
}

std::uint64_t now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL + static_cast<std::uint64_t>(ts.tv_nsec);
}

timespec to_timespec(std::uint64_t ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / 1000000000ULL);
  ts.tv_nsec = static_cast<long>(ns % 1000000000ULL);
  return ts;
}

// Linear output buffer (fixed capacity): bytes are appended by the cycle and written out
// non-blocking; what the device does not take now stays queued for the next cycle.
template <std::size_t Capacity>
struct OutQueue {
  std::array<std::uint8_t, Capacity> buf{};
  std::size_t head = 0;
  std::size_t tail = 0;
  std::size_t pending() const noexcept { return tail - head; }
  std::size_t room() const noexcept { return Capacity - pending(); }
  bool append(const void* p, std::size_t n) noexcept {
    if (n > Capacity - tail) {
      if (n > room()) return false;
      std::memmove(buf.data(), buf.data() + head, pending());
      tail -= head;
      head = 0;
    }
    std::memcpy(buf.data() + tail, p, n);
    tail += n;
    return true;
  }
  // Returns false on a hard write error (errno set).
  bool flush(int fd, std::uint64_t& bytes_out) noexcept {
    while (pending() > 0) {
      const ssize_t w = write(fd, buf.data() + head, pending());
      if (w > 0) {
        head += static_cast<std::size_t>(w);
        bytes_out += static_cast<std::uint64_t>(w);
        continue;
      }
      if (w < 0 && errno == EINTR) continue;
      if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
      return false;
    }
    if (head == tail) head = tail = 0;
    return true;
  }
};

struct Counters {
  std::uint64_t cycles = 0;
  std::uint64_t overruns = 0;          // work finished after the next deadline
  std::uint64_t missed_deadlines = 0;  // deadlines skipped because of overruns
  std::uint64_t bytes_in = 0;
  std::uint64_t bytes_out = 0;
  std::uint64_t frames_in = 0;   // IMU samples decoded from the interface
  std::uint64_t frames_out = 0;  // filtered samples written back
  std::uint64_t wrong_type = 0;  // serial frames of type 0x81 (an output frame on the input)
  std::uint64_t output_overflow = 0;  // outputs that did not fit the queue (counted, not hidden)
  std::uint64_t slcan_replies = 0;
  std::uint64_t can_tx_errors = 0;
  std::uint64_t read_errors = 0;
  std::uint64_t max_frames_per_cycle = 0;
};

// Static storage: allocated once at program start, never on the heap.
LatencyHistogram<200000> g_wake_latency(100);   // 0.1 us bins up to 20 ms
LatencyHistogram<200000> g_period_jitter(100);  // |actual period - nominal|
LatencyHistogram<200000> g_compute(100);        // wake -> end of cycle work (incl. syscalls)
LatencyHistogram<100000> g_sample(10);          // one sample: filter + encode + queue, 10 ns bins
std::array<std::uint8_t, 16384> g_in_buf{};  // one read chunk
OutQueue<(1U << 21)> g_out;
gser::SerialFrameParser<8192> g_serial_parser;
gslcan::SlcanParser<> g_slcan_parser;
gcan::CanSampleAssembler<8> g_can_rx(gcan::kInputBaseId);
gyrodrift::loop::UserCanInput g_user_can;  // active with --can-signals
gyrodrift::loop::Processing g_proc;
Counters g_c;

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
SeqUnwrapper g_unwrap;

void emit_serial(const gser::ImuFrame& out) noexcept {
  std::array<std::uint8_t, gser::kFrameSize> bytes{};
  gser::encode_frame(out, bytes.data(), bytes.size());
  if (g_out.append(bytes.data(), bytes.size())) {
    ++g_c.frames_out;
  } else {
    ++g_c.output_overflow;
  }
}

void emit_slcan(const gser::ImuFrame& out) noexcept {
  gcan::CanSample s;
  s.seq = out.seq;
  s.flags = out.flags;
  s.values = out.values;
  std::array<gcan::CanFrame, gcan::kFramesPerSample> frames{};
  gcan::encode_sample(s, gcan::kOutputBaseId, frames);
  std::array<char, 4 * gslcan::kMaxFrameLine> line{};
  std::size_t n = 0;
  for (const auto& f : frames) n += gslcan::encode_frame(f, line.data() + n, line.size() - n);
  if (g_out.append(line.data(), n)) {
    ++g_c.frames_out;
  } else {
    ++g_c.output_overflow;
  }
}

void emit_socketcan(int fd, const gser::ImuFrame& out) noexcept {
#if GYRODRIFT_HAVE_SOCKETCAN
  gcan::CanSample s;
  s.seq = out.seq;
  s.flags = out.flags;
  s.values = out.values;
  std::array<gcan::CanFrame, gcan::kFramesPerSample> frames{};
  gcan::encode_sample(s, gcan::kOutputBaseId, frames);
  bool ok = true;
  for (const auto& f : frames) {
    can_frame cf{};
    cf.can_id = f.id;
    cf.can_dlc = f.dlc;
    std::memcpy(cf.data, f.data.data(), 8);
    const ssize_t w = write(fd, &cf, sizeof cf);
    if (w != static_cast<ssize_t>(sizeof cf)) ok = false;
    else g_c.bytes_out += sizeof cf;
  }
  if (ok) ++g_c.frames_out;
  else ++g_c.can_tx_errors;
#else
  (void)fd;
  (void)out;
#endif
}

// One decoded input sample through the processor; the filtered sample (if any) is queued.
template <class Emit>
void handle_sample(const gser::ImuFrame& in, Emit&& emit) noexcept {
  ++g_c.frames_in;
  const std::uint64_t t0 = now_ns();
  gser::ImuFrame out;
  if (g_proc.step(in, out)) emit(out);
  g_sample.record(now_ns() - t0);  // the per-sample compute of this cycle (six channels)
}

void handle_can_frame(const gcan::CanFrame& f, Mode mode, int fd) noexcept {
  gser::ImuFrame in;
  in.type = gser::kTypeInput;
  bool has_time = false;
  if (g_user_can.active()) {  // a user's DBC layout (--can-signals)
    gcan::SignalSample s;
    if (!g_user_can.push(f, s)) return;
    in.seq = s.seq;
    in.flags = 0;
    in.values = s.values;
    in.t_us = s.t_us;
    has_time = s.has_time;
  } else {
    gcan::CanSample s;
    if (!g_can_rx.push(f, s)) return;
    in.seq = s.seq;
    in.flags = s.flags;
    in.values = s.values;
  }
  const std::int64_t k = g_unwrap.push(in.seq);
  if (!has_time) {
    in.t_us = k <= 0 ? 0U : static_cast<std::uint64_t>(std::llround(static_cast<double>(k) * 1e6 / g_proc.options().sample_rate_hz));
  }
  if (mode == Mode::kSlcan) handle_sample(in, emit_slcan);
  else handle_sample(in, [fd](const gser::ImuFrame& o) { emit_socketcan(fd, o); });
}

// Reads one chunk (at most cap bytes). Returns the bytes read, 0 when nothing is available
// now; `open` becomes false at end of input (EOF, or EIO from a pty master whose other side
// was closed).
std::size_t read_chunk(int fd, std::uint8_t* buf, std::size_t cap, bool& open) noexcept {
  for (;;) {
    const ssize_t r = read(fd, buf, cap);
    if (r > 0) return static_cast<std::size_t>(r);
    if (r == 0) {
      open = false;
      return 0;
    }
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
    if (errno == EIO) {
      open = false;
      return 0;
    }
    ++g_c.read_errors;
    return 0;
  }
}

void process_serial_bytes(const std::uint8_t* p, std::size_t n) noexcept {
  while (n > 0) {
    // Feed only what fits, so overflow_bytes stays a true count of refused bytes.
    const std::size_t room = g_serial_parser.capacity() - g_serial_parser.buffered();
    const std::size_t take = g_serial_parser.feed(p, std::min(n, room));
    p += take;
    n -= take;
    gser::ImuFrame f;
    while (g_serial_parser.next(f)) {
      if (f.type != gser::kTypeInput) {
        ++g_c.wrong_type;
        continue;
      }
      handle_sample(f, emit_serial);
    }
    if (take == 0) break;  // cannot happen after draining; guards against a stuck loop
  }
}

void process_slcan_bytes(const std::uint8_t* p, std::size_t n) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    gslcan::Event ev;
    if (!g_slcan_parser.push(p[i], ev)) continue;
    // Lawicel replies: "z\r" confirms a frame, "\r" (or data) a command, BEL an error.
    std::array<char, 16> reply{};
    const std::size_t r = gslcan::command_reply(ev, reply.data(), reply.size());
    if (r > 0 && g_out.append(reply.data(), r)) ++g_c.slcan_replies;
    if (ev.kind == gslcan::EventKind::kFrame) handle_can_frame(ev.frame, Mode::kSlcan, -1);
  }
}

bool process_socketcan(int fd) noexcept {
#if GYRODRIFT_HAVE_SOCKETCAN
  for (int i = 0; i < 4096; ++i) {
    can_frame cf{};
    const ssize_t r = read(fd, &cf, sizeof cf);
    if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return true;
    if (r < 0 && errno == EINTR) continue;
    if (r != static_cast<ssize_t>(sizeof cf)) {
      ++g_c.read_errors;
      return r >= 0;
    }
    g_c.bytes_in += sizeof cf;
    gcan::CanFrame f;
    f.extended = (cf.can_id & CAN_EFF_FLAG) != 0U;
    f.remote = (cf.can_id & CAN_RTR_FLAG) != 0U;
    f.id = cf.can_id & (f.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    f.dlc = cf.can_dlc > 8 ? 8 : cf.can_dlc;
    std::memcpy(f.data.data(), cf.data, 8);
    if ((cf.can_id & CAN_ERR_FLAG) != 0U) continue;
    handle_can_frame(f, Mode::kSocketCan, fd);
  }
  return true;
#else
  (void)fd;
  return false;
#endif
}

struct RtStatus {
  bool sched_fifo = false;
  bool mlockall = false;
  std::string sched_error;
  std::string mlock_error;
};

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

void json_string(std::FILE* f, const std::string& s) {
  std::fputc('"', f);
  for (const char c : s) {
    if (c == '"' || c == '\\') std::fputc('\\', f);
    if (static_cast<unsigned char>(c) < 0x20) {
      std::fprintf(f, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(c)));
      continue;
    }
    std::fputc(c, f);
  }
  std::fputc('"', f);
}

template <std::size_t B>
void json_hist(std::FILE* f, const char* name, const LatencyHistogram<B>& h, double scale) {
  std::fprintf(f, "  \"%s\": {\"n\": %" PRIu64 ", \"p50\": %.3f, \"p99\": %.3f, \"max\": %.3f}", name,
               h.count(), static_cast<double>(h.quantile_ns(0.50)) * scale,
               static_cast<double>(h.quantile_ns(0.99)) * scale, static_cast<double>(h.max_ns()) * scale);
}

void write_stats(std::FILE* f, const Options& o, const RtStatus& rt, const char* end_reason, double elapsed_s) {
  const char* mode = o.mode == Mode::kSerial ? "serial" : (o.mode == Mode::kSlcan ? "slcan" : "socketcan");
  std::fprintf(f, "{\n  \"program\": \"gyrodrift-loop\",\n  \"interface\": \"%s\",\n  \"device\": ", mode);
  json_string(f, o.device);
  std::fprintf(f, ",\n  \"rate_hz\": %.3f,\n  \"baud\": %ld,\n", o.rate_hz, o.baud);
  std::fprintf(f, "  \"realtime\": {\"sched_fifo\": %s, \"priority\": %d, \"mlockall\": %s, \"sched_error\": ",
               rt.sched_fifo ? "true" : "false", rt.sched_fifo ? o.rt_priority : 0, rt.mlockall ? "true" : "false");
  json_string(f, rt.sched_error);
  std::fputs(", \"mlock_error\": ", f);
  json_string(f, rt.mlock_error);
  std::fprintf(f, "},\n  \"end_reason\": \"%s\",\n  \"elapsed_s\": %.6f,\n", end_reason, elapsed_s);
  std::fprintf(f, "  \"cycles\": %" PRIu64 ",\n  \"overruns\": %" PRIu64 ",\n  \"missed_deadlines\": %" PRIu64 ",\n",
               g_c.cycles, g_c.overruns, g_c.missed_deadlines);
  std::fprintf(f, "  \"frames_in\": %" PRIu64 ",\n  \"frames_out\": %" PRIu64 ",\n  \"max_frames_per_cycle\": %" PRIu64 ",\n",
               g_c.frames_in, g_c.frames_out, g_c.max_frames_per_cycle);
  std::fprintf(f, "  \"bytes_in\": %" PRIu64 ",\n  \"bytes_out\": %" PRIu64 ",\n", g_c.bytes_in, g_c.bytes_out);
  // Rejections by reason: the transport level (bytes/frames that never became a sample),
  // then the processor's own (samples it did not turn into an output).
  std::fputs("  \"rejected\": {", f);
  bool first = true;
  auto field = [&](const char* k, std::uint64_t v) {
    std::fprintf(f, "%s\"%s\": %" PRIu64, first ? "" : ", ", k, v);
    first = false;
  };
  if (o.mode == Mode::kSerial) {
    const auto& s = g_serial_parser.stats();
    field("crc", s.crc_errors);
    field("bad_header", s.bad_header);
    field("truncated", s.truncated);
    field("garbage_bytes", s.garbage_bytes);
    field("overflow_bytes", s.overflow_bytes);
    field("wrong_type", g_c.wrong_type);
  } else if (g_user_can.active()) {
    const auto& s = g_user_can.stats();
    field("can_incomplete", s.incomplete_samples);
    field("can_bad_dlc", s.bad_dlc);
    field("can_foreign_frames", s.foreign_frames);
    field("can_ignored_frames", s.ignored_frames);
    field("can_frames_dropped", s.frames_dropped);
    if (o.mode == Mode::kSlcan) {
      field("slcan_malformed", g_slcan_parser.stats().malformed);
      field("slcan_overlong", g_slcan_parser.stats().overlong);
    }
  } else {
    const auto& s = g_can_rx.stats();
    field("can_incomplete", s.incomplete_samples);
    field("can_orphan_frames", s.orphan_frames);
    field("can_duplicate_frames", s.duplicate_frames);
    field("can_bad_dlc", s.bad_dlc);
    field("can_foreign_frames", s.foreign_frames);
    field("can_frames_dropped", s.frames_dropped);
    if (o.mode == Mode::kSlcan) {
      field("slcan_malformed", g_slcan_parser.stats().malformed);
      field("slcan_overlong", g_slcan_parser.stats().overlong);
    }
  }
  g_proc.for_each_rejection(field);
  field("output_overflow", g_c.output_overflow);
  field("read_errors", g_c.read_errors);
  field("can_tx_errors", g_c.can_tx_errors);
  std::fputs("},\n", f);
  if (o.mode != Mode::kSerial) {
    const auto& s = g_can_rx.stats();
    const auto& u = g_user_can.stats();
    const bool user = g_user_can.active();
    std::fprintf(f, "  \"can\": {\"frames_in\": %" PRIu64 ", \"frames_used\": %" PRIu64
                    ", \"complete_samples\": %" PRIu64 ", \"slcan_lines\": %" PRIu64
                    ", \"slcan_commands\": %" PRIu64 ", \"slcan_replies\": %" PRIu64
                    ", \"user_dbc\": %s},\n",
                 user ? u.frames_in : s.frames_in, user ? u.frames_used : s.frames_used,
                 user ? u.complete_samples : s.complete_samples, g_slcan_parser.stats().lines,
                 g_slcan_parser.stats().commands, g_c.slcan_replies, user ? "true" : "false");
  }
  std::fputs("  \"health\": {", f);
  first = true;
  g_proc.for_each_health(field);
  std::fputs("},\n", f);
  json_hist(f, "period_jitter_us", g_period_jitter, 1e-3);
  std::fputs(",\n", f);
  json_hist(f, "wake_latency_us", g_wake_latency, 1e-3);
  std::fputs(",\n", f);
  json_hist(f, "compute_us", g_compute, 1e-3);
  std::fputs(",\n", f);
  json_hist(f, "sample_us", g_sample, 1e-3);
  std::fputs("\n}\n", f);
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
  if (!o.can_signals_path.empty() && !g_user_can.load(o.can_signals_path, err)) {
    std::fprintf(stderr, "gyrodrift-loop: error: %s\n", err.c_str());
    return 2;
  }
  int fd = -1;
  if (o.mode == Mode::kSocketCan) fd = gyrodrift::loop::open_socketcan(o.device, err);
  else fd = gyrodrift::loop::open_serial(o.device, o.baud, err);
  if (fd < 0) {
    std::fprintf(stderr, "gyrodrift-loop: error: %s\n", err.c_str());
    return 2;
  }
  o.proc.sample_rate_hz = o.sample_rate_hz;
  if (!g_proc.init(o.proc, err)) {
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
  std::memset(g_in_buf.data(), 0, g_in_buf.size());
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
    g_wake_latency.record(wake > next ? wake - next : 0);
    if (prev_wake != 0) {
      const std::uint64_t per = wake - prev_wake;
      g_period_jitter.record(per > period_ns ? per - period_ns : period_ns - per);
    }
    prev_wake = wake;
    ++g_c.cycles;
    const std::uint64_t frames_before = g_c.frames_in;

    bool open = true;
    if (o.mode == Mode::kSocketCan) {
      open = process_socketcan(fd);
    } else {
      // Drain the input chunk by chunk, processing and flushing each before the next read: a
      // tty hands over at most its line-discipline buffer (4 KiB) per read and the kernel
      // refills it meanwhile. Back-pressure: read only while the output queue can absorb a
      // chunk's worst-case reply (serial: 1 output byte per input byte; SLCAN: a 2-byte "V\r"
      // gets a 6-byte reply), so nothing is lost for lack of room; unread input waits in
      // the kernel (and the sender blocks).
      std::size_t total = 0;
      while (open && total < o.max_bytes_per_cycle && g_out.room() >= 3 * g_in_buf.size()) {
        const std::size_t cap = std::min(g_in_buf.size(), o.max_bytes_per_cycle - total);
        const std::size_t got = read_chunk(fd, g_in_buf.data(), cap, open);
        if (got == 0) break;
        total += got;
        g_c.bytes_in += got;
        last_input = wake;
        if (o.mode == Mode::kSerial) process_serial_bytes(g_in_buf.data(), got);
        else process_slcan_bytes(g_in_buf.data(), got);
        if (!g_out.flush(fd, g_c.bytes_out) && errno != EIO) ++g_c.read_errors;
      }
      if (!g_out.flush(fd, g_c.bytes_out)) {
        if (errno == EIO) open = false;
        else ++g_c.read_errors;
      }
    }
    const std::uint64_t per_cycle = g_c.frames_in - frames_before;
    if (per_cycle > g_c.max_frames_per_cycle) g_c.max_frames_per_cycle = per_cycle;
    const std::uint64_t end = now_ns();
    g_compute.record(end - wake);

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
      ++g_c.overruns;
      while (next < end) {
        next += period_ns;
        ++g_c.missed_deadlines;
      }
    }
  }
  // Shutdown: give the output queue a bounded chance to drain, then count what is left.
  if (o.mode != Mode::kSocketCan) {
    const std::uint64_t give_up = now_ns() + 500000000ULL;
    while (g_out.pending() > 0 && now_ns() < give_up) {
      if (!g_out.flush(fd, g_c.bytes_out)) break;
      if (g_out.pending() > 0) usleep(1000);
    }
  }
  if (o.mode == Mode::kSerial) g_serial_parser.finish();
  else if (g_user_can.active()) g_user_can.finish();
  else g_can_rx.finish();
  const double elapsed_s = static_cast<double>(now_ns() - start) * 1e-9;
  write_stats(stdout, o, rt, end_reason, elapsed_s);
  std::fflush(stdout);
  if (!o.stats_path.empty()) {
    if (std::FILE* f = std::fopen(o.stats_path.c_str(), "w")) {
      write_stats(f, o, rt, end_reason, elapsed_s);
      std::fclose(f);
    } else {
      std::fprintf(stderr, "gyrodrift-loop: cannot write %s: %s\n", o.stats_path.c_str(), std::strerror(errno));
    }
  }
  return 0;
}
