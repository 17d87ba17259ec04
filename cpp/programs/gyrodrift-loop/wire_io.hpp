// The transports' data path: bytes/frames from the interface -> ImuSample<float> (the
// processor's own sample type) -> processor -> ImuOutput<float> -> the same wire format back.
// Serial: 42-byte frames (t_us on the wire). SLCAN / SocketCAN: four CAN frames per sample
// (no timestamp: t_us from the unwrapped sequence number and the sample rate).
#pragma once
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <ctime>

#include <gyrodrift/codecs/can_frames.hpp>
#include <gyrodrift/codecs/serial_frame.hpp>
#include <gyrodrift/codecs/slcan.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

#include "loop_state.hpp"
#include "options.hpp"
#include "transport.hpp"

namespace gyrodrift::loop {

inline std::uint64_t now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000000ULL + static_cast<std::uint64_t>(ts.tv_nsec);
}

inline void emit_serial(LoopState& st, const ImuOutput<float>& y) noexcept {
  serial::ImuFrame out;
  out.type = serial::kTypeOutput;
  out.seq = y.seq;
  out.flags = y.flags;
  out.t_us = y.t_us;
  out.values = y.values;
  std::array<std::uint8_t, serial::kFrameSize> bytes{};
  serial::encode_frame(out, bytes.data(), bytes.size());
  if (!st.out.append(bytes.data(), bytes.size(), true)) ++st.c.output_overflow;
}

inline std::array<can::CanFrame, can::kFramesPerSample> can_frames_of(const ImuOutput<float>& y) noexcept {
  can::CanSample s;
  s.seq = y.seq;
  s.flags = y.flags;
  s.values = y.values;
  std::array<can::CanFrame, can::kFramesPerSample> frames{};
  can::encode_sample(s, can::kOutputBaseId, frames);
  return frames;
}

inline void emit_slcan(LoopState& st, const ImuOutput<float>& y) noexcept {
  std::array<char, 4 * slcan::kMaxFrameLine> line{};
  std::size_t n = 0;
  for (const auto& f : can_frames_of(y)) n += slcan::encode_frame(f, line.data() + n, line.size() - n);
  if (!st.out.append(line.data(), n, true)) ++st.c.output_overflow;
}

// SocketCAN writes each frame directly (a sample is written or counted as a tx error).
inline void emit_socketcan(LoopState& st, int fd, const ImuOutput<float>& y) noexcept {
#if GYRODRIFT_HAVE_SOCKETCAN
  bool ok = true;
  ++st.out.frames_queued;
  for (const auto& f : can_frames_of(y)) {
    can_frame cf{};
    cf.can_id = f.id;
    cf.can_dlc = f.dlc;
    std::memcpy(cf.data, f.data.data(), 8);
    const ssize_t w = write(fd, &cf, sizeof cf);
    if (w != static_cast<ssize_t>(sizeof cf)) ok = false;
    else st.c.bytes_out += sizeof cf;
  }
  if (ok) ++st.out.frames_written;
  else {
    ++st.c.can_tx_errors;
    ++st.out.frames_dropped;
  }
#else
  (void)st;
  (void)fd;
  (void)y;
#endif
}

// One decoded input sample through the processor; the output (if any) goes to `emit`.
template <class Emit>
void handle_sample(LoopState& st, const ImuSample<float>& in, Emit&& emit) noexcept {
  ++st.c.frames_in;
  const std::uint64_t t0 = now_ns();
  ImuOutput<float> y;
  if (st.proc.step(in, y)) emit(y);
  st.sample.record(now_ns() - t0);  // the per-sample compute (six channels + encode + queue)
}

inline void handle_can_frame(LoopState& st, const can::CanFrame& f, Mode mode, int fd) noexcept {
  ImuSample<float> in;
  bool has_time = false;
  if (st.user_can.active()) {  // a user's DBC layout (--can-signals)
    can::SignalSample s;
    if (!st.user_can.push(f, s)) return;
    in.seq = s.seq;
    in.values = s.values;
    in.t_us = s.t_us;
    has_time = s.has_time;
  } else {
    can::CanSample s;
    if (!st.can_rx.push(f, s)) return;
    in.seq = s.seq;
    in.values = s.values;
  }
  const std::int64_t k = st.unwrap.push(in.seq);
  if (!has_time) {
    in.t_us = k <= 0 ? 0U
                     : static_cast<std::uint64_t>(std::llround(static_cast<double>(k) * 1e6 / st.proc.sample_rate_hz()));
  }
  if (mode == Mode::kSlcan) handle_sample(st, in, [&st](const ImuOutput<float>& y) { emit_slcan(st, y); });
  else handle_sample(st, in, [&st, fd](const ImuOutput<float>& y) { emit_socketcan(st, fd, y); });
}

// Reads one chunk (at most cap bytes). Returns the bytes read, 0 when nothing is available
// now; `open` becomes false at end of input (EOF, or EIO from a pty master whose other side
// was closed).
inline std::size_t read_chunk(LoopState& st, int fd, std::uint8_t* buf, std::size_t cap, bool& open) noexcept {
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
    ++st.c.read_errors;
    return 0;
  }
}

inline void process_serial_bytes(LoopState& st, const std::uint8_t* p, std::size_t n) noexcept {
  while (n > 0) {
    // Feed only what fits, so overflow_bytes stays a true count of refused bytes.
    const std::size_t room = st.serial_parser.capacity() - st.serial_parser.buffered();
    const std::size_t take = st.serial_parser.feed(p, std::min(n, room));
    p += take;
    n -= take;
    serial::ImuFrame f;
    while (st.serial_parser.next(f)) {
      if (f.type != serial::kTypeInput) {
        ++st.c.wrong_type;
        continue;
      }
      ImuSample<float> in;
      in.seq = f.seq;
      in.t_us = f.t_us;
      in.values = f.values;
      handle_sample(st, in, [&st](const ImuOutput<float>& y) { emit_serial(st, y); });
    }
    if (take == 0) break;  // cannot happen after draining; guards against a stuck loop
  }
}

inline void process_slcan_bytes(LoopState& st, const std::uint8_t* p, std::size_t n) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    slcan::Event ev;
    if (!st.slcan_parser.push(p[i], ev)) continue;
    // Lawicel replies: "z\r" confirms a frame, "\r" (or data) a command, BEL an error.
    std::array<char, 16> reply{};
    const std::size_t r = slcan::command_reply(ev, reply.data(), reply.size());
    if (r > 0 && st.out.append(reply.data(), r, false)) ++st.c.slcan_replies;
    if (ev.kind == slcan::EventKind::kFrame) handle_can_frame(st, ev.frame, Mode::kSlcan, -1);
  }
}

inline bool process_socketcan(LoopState& st, int fd) noexcept {
#if GYRODRIFT_HAVE_SOCKETCAN
  for (int i = 0; i < 4096; ++i) {
    can_frame cf{};
    const ssize_t r = read(fd, &cf, sizeof cf);
    if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return true;
    if (r < 0 && errno == EINTR) continue;
    if (r != static_cast<ssize_t>(sizeof cf)) {
      ++st.c.read_errors;
      return r >= 0;
    }
    st.c.bytes_in += sizeof cf;
    can::CanFrame f;
    f.extended = (cf.can_id & CAN_EFF_FLAG) != 0U;
    f.remote = (cf.can_id & CAN_RTR_FLAG) != 0U;
    f.id = cf.can_id & (f.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    f.dlc = cf.can_dlc > 8 ? 8 : cf.can_dlc;
    std::memcpy(f.data.data(), cf.data, 8);
    if ((cf.can_id & CAN_ERR_FLAG) != 0U) continue;
    handle_can_frame(st, f, Mode::kSocketCan, fd);
  }
  return true;
#else
  (void)st;
  (void)fd;
  return false;
#endif
}

}  // namespace gyrodrift::loop
