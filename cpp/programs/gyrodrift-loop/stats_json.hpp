// gyrodrift-loop's final statistics as JSON (stdout and --stats-json).
#pragma once
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <string>

#include "latency_histogram.hpp"
#include "loop_state.hpp"
#include "options.hpp"

namespace gyrodrift::loop {

struct RtStatus {
  bool sched_fifo = false;
  bool mlockall = false;
  std::string sched_error;
  std::string mlock_error;
};

// What the run was set up with (the statistics repeat it).
struct RunInfo {
  std::string config;           // the configuration's source: --config FILE, or the built-in default
  double sample_rate_hz = 0.0;  // timing.sample_rate_hz
  double loop_rate_hz = 0.0;    // timing.loop_rate_hz (absent: the sample rate)
  RtStatus rt;
};

inline void json_string(std::FILE* f, const std::string& s) {
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

inline void write_stats(std::FILE* f, const Options& o, const RunInfo& run, const LoopState& st,
                        const char* end_reason, double elapsed_s) {
  const RtStatus& rt = run.rt;
  const char* mode = o.mode == Mode::kSerial ? "serial" : (o.mode == Mode::kSlcan ? "slcan" : "socketcan");
  std::fprintf(f, "{\n  \"program\": \"gyrodrift-loop\",\n  \"interface\": \"%s\",\n  \"device\": ", mode);
  json_string(f, o.device);
  std::fputs(",\n  \"config\": ", f);
  json_string(f, run.config);
  std::fprintf(f, ",\n  \"sample_rate_hz\": %.3f,\n  \"loop_rate_hz\": %.3f,\n  \"baud\": %ld,\n", run.sample_rate_hz,
               run.loop_rate_hz, o.baud);
  std::fprintf(f, "  \"realtime\": {\"sched_fifo\": %s, \"priority\": %d, \"mlockall\": %s, \"sched_error\": ",
               rt.sched_fifo ? "true" : "false", rt.sched_fifo ? o.rt_priority : 0, rt.mlockall ? "true" : "false");
  json_string(f, rt.sched_error);
  std::fputs(", \"mlock_error\": ", f);
  json_string(f, rt.mlock_error);
  std::fprintf(f, "},\n  \"end_reason\": \"%s\",\n  \"elapsed_s\": %.6f,\n", end_reason, elapsed_s);
  std::fprintf(f, "  \"cycles\": %" PRIu64 ",\n  \"overruns\": %" PRIu64 ",\n  \"missed_deadlines\": %" PRIu64 ",\n",
               st.c.cycles, st.c.overruns, st.c.missed_deadlines);
  // Output accounting: frames_queued = frames_out (fully written) + frames_dropped (still
  // queued at exit, the peer did not read them); output_overflow: did not fit the queue.
  std::fprintf(f, "  \"frames_in\": %" PRIu64 ",\n  \"frames_out\": %" PRIu64 ",\n  \"frames_queued\": %" PRIu64
                  ",\n  \"frames_dropped\": %" PRIu64 ",\n  \"max_frames_per_cycle\": %" PRIu64 ",\n",
               st.c.frames_in, st.out.frames_written, st.out.frames_queued, st.out.frames_dropped,
               st.c.max_frames_per_cycle);
  std::fprintf(f, "  \"bytes_in\": %" PRIu64 ",\n  \"bytes_out\": %" PRIu64 ",\n", st.c.bytes_in, st.c.bytes_out);
  // Rejections by reason: the transport level (bytes/frames that never became a sample),
  // then the processor's own (samples it did not turn into an output).
  std::fputs("  \"rejected\": {", f);
  bool first = true;
  auto field = [&](const char* k, std::uint64_t v) {  // one JSON member
    std::fprintf(f, "%s\"%s\": %" PRIu64, first ? "" : ", ", k, v);
    first = false;
  };
  if (o.mode == Mode::kSerial) {
    const auto& s = st.serial_parser.stats();
    field("crc", s.crc_errors);
    field("bad_header", s.bad_header);
    field("truncated", s.truncated);
    field("garbage_bytes", s.garbage_bytes);
    field("overflow_bytes", s.overflow_bytes);
    field("wrong_type", st.c.wrong_type);
  } else if (st.user_can.active()) {
    const auto& s = st.user_can.stats();
    field("can_incomplete", s.incomplete_samples);
    field("can_bad_dlc", s.bad_dlc);
    field("can_foreign_frames", s.foreign_frames);
    field("can_ignored_frames", s.ignored_frames);
    field("can_undefined_page_frames", s.undefined_page_frames);
    field("can_frames_dropped", s.frames_dropped);
    if (o.mode == Mode::kSlcan) {
      field("slcan_malformed", st.slcan_parser.stats().malformed);
      field("slcan_overlong", st.slcan_parser.stats().overlong);
    }
  } else {
    const auto& s = st.can_rx.stats();
    field("can_incomplete", s.incomplete_samples);
    field("can_orphan_frames", s.orphan_frames);
    field("can_duplicate_frames", s.duplicate_frames);
    field("can_bad_dlc", s.bad_dlc);
    field("can_foreign_frames", s.foreign_frames);
    field("can_frames_dropped", s.frames_dropped);
    if (o.mode == Mode::kSlcan) {
      field("slcan_malformed", st.slcan_parser.stats().malformed);
      field("slcan_overlong", st.slcan_parser.stats().overlong);
    }
  }
  st.proc.for_each_rejection(field);
  field("output_overflow", st.c.output_overflow);
  field("read_errors", st.c.read_errors);
  field("can_tx_errors", st.c.can_tx_errors);
  std::fputs("},\n", f);
  if (o.mode != Mode::kSerial) {
    const auto& s = st.can_rx.stats();
    const auto& u = st.user_can.stats();
    const bool user = st.user_can.active();
    std::fprintf(f, "  \"can\": {\"frames_in\": %" PRIu64 ", \"frames_used\": %" PRIu64
                    ", \"complete_samples\": %" PRIu64 ", \"slcan_lines\": %" PRIu64
                    ", \"slcan_commands\": %" PRIu64 ", \"slcan_replies\": %" PRIu64
                    ", \"user_dbc\": %s},\n",
                 user ? u.frames_in : s.frames_in, user ? u.frames_used : s.frames_used,
                 user ? u.complete_samples : s.complete_samples, st.slcan_parser.stats().lines,
                 st.slcan_parser.stats().commands, st.c.slcan_replies, user ? "true" : "false");
  }
  std::fputs("  \"health\": {", f);
  first = true;
  st.proc.for_each_health(field);
  std::fputs("},\n", f);
  json_hist(f, "period_jitter_us", st.period_jitter, 1e-3);
  std::fputs(",\n", f);
  json_hist(f, "wake_latency_us", st.wake_latency, 1e-3);
  std::fputs(",\n", f);
  json_hist(f, "compute_us", st.compute, 1e-3);
  std::fputs(",\n", f);
  json_hist(f, "sample_us", st.sample, 1e-3);
  std::fputs("\n}\n", f);
}

}  // namespace gyrodrift::loop
