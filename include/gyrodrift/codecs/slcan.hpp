// SLCAN (Lawicel ASCII serial-line CAN) encoding and a line parser, for the loop's SLCAN
// path. Frames: "tIIILDD..\r" (standard), "TIIIIIIIILDD..\r" (extended), "r"/"R" remote.
// Commands (S0..S8 bitrate, O open, L listen-only, C close, V/v version, N serial,
// F status, Z timestamps, ...) are recognised and acknowledged with "\r"; errors with BEL.
// The parser holds one line in a fixed buffer; an overlong line is dropped to its
// terminator and counted, never written past the buffer.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>

#include "can_frames.hpp"

namespace gyrodrift::slcan {

inline constexpr char kCr = '\r';
inline constexpr char kBell = '\a';
// "T" + 8 id + 1 dlc + 16 data + 4 timestamp + CR
inline constexpr std::size_t kMaxFrameLine = 1 + 8 + 1 + 16 + 4 + 1;

namespace detail {
inline char hex_digit(unsigned v) noexcept {
  return static_cast<char>(v < 10U ? '0' + static_cast<int>(v) : 'A' + static_cast<int>(v - 10U));
}
inline int hex_value(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}
inline bool parse_hex(const char* s, std::size_t n, std::uint32_t& out) noexcept {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const int h = hex_value(s[i]);
    if (h < 0) return false;
    v = (v << 4) | static_cast<std::uint32_t>(h);
  }
  out = v;
  return true;
}
}  // namespace detail

// Writes the SLCAN line for one frame (uppercase hex, like python-can's slcan interface),
// terminated by '\r'. Returns its length, or 0 if the frame is invalid (id out of range,
// dlc > 8) or capacity is too small.
inline std::size_t encode_frame(const can::CanFrame& f, char* out, std::size_t capacity) noexcept {
  if (out == nullptr || f.dlc > 8) return 0;
  if (f.extended ? f.id > 0x1FFFFFFFU : f.id > 0x7FFU) return 0;
  const std::size_t id_digits = f.extended ? 8U : 3U;
  const std::size_t data_digits = f.remote ? 0U : 2U * f.dlc;
  const std::size_t len = 1 + id_digits + 1 + data_digits + 1;
  if (capacity < len) return 0;
  std::size_t k = 0;
  out[k++] = f.remote ? (f.extended ? 'R' : 'r') : (f.extended ? 'T' : 't');
  for (std::size_t i = 0; i < id_digits; ++i) {
    out[k++] = detail::hex_digit((f.id >> (4 * (id_digits - 1 - i))) & 0xFU);
  }
  out[k++] = static_cast<char>('0' + f.dlc);
  for (std::size_t i = 0; i < data_digits / 2; ++i) {
    out[k++] = detail::hex_digit(static_cast<unsigned>(f.data[i] >> 4));
    out[k++] = detail::hex_digit(static_cast<unsigned>(f.data[i] & 0xFU));
  }
  out[k++] = kCr;
  return k;
}

enum class EventKind : std::uint8_t { kNone, kFrame, kCommand, kError };

struct Event {
  EventKind kind = EventKind::kNone;
  can::CanFrame frame{};          // kFrame
  char command = 0;               // kCommand: first character ('S', 'O', 'C', 'V', ...)
  std::uint8_t arg_len = 0;       // kCommand: characters after the command letter
  std::array<char, 16> arg{};     // kCommand: those characters (not terminated)
};

struct SlcanStats {
  std::uint64_t bytes_in = 0;
  std::uint64_t lines = 0;       // non-empty lines terminated by CR (or LF) or cut short
  std::uint64_t frames = 0;      // valid t/T/r/R lines
  std::uint64_t commands = 0;    // recognised command lines
  std::uint64_t malformed = 0;   // bad hex, bad dlc, wrong length, unknown command, or a line
                                 // cut short (ended by the next frame letter, its CR lost)
  std::uint64_t overlong = 0;    // lines longer than the buffer (dropped to the terminator)
  std::uint64_t bells = 0;       // BEL bytes (error replies from the other side)
};

// Lawicel command letters this parser recognises (no frame letters).
inline bool is_command_letter(char c) noexcept {
  switch (c) {
    case 'S': case 's': case 'O': case 'L': case 'C': case 'V': case 'v': case 'N':
    case 'F': case 'Z': case 'W': case 'M': case 'm': case 'X': case 'U': case 'Q':
      return true;
    default:
      return false;
  }
}

// Letters that begin a frame line (and never appear anywhere else in a line).
inline bool is_frame_letter(char c) noexcept { return c == 't' || c == 'T' || c == 'r' || c == 'R'; }

// Reply a Lawicel device gives to an event (what the loop writes back on its SLCAN port):
// a transmitted frame is confirmed with "z\r" (standard) or "Z\r" (extended), a command
// with "\r" (or its data: V, v, N, F), an error or an unknown line with BEL.
// Returns the reply length (0 if capacity is too small).
inline std::size_t command_reply(const Event& ev, char* out, std::size_t capacity) noexcept {
  const char* reply = "\r";
  if (ev.kind == EventKind::kFrame) {
    reply = ev.frame.extended ? "Z\r" : "z\r";
  } else if (ev.kind != EventKind::kCommand) {
    reply = "\a";
  } else if (ev.command == 'V') {
    reply = "V1013\r";
  } else if (ev.command == 'v') {
    reply = "v1013\r";
  } else if (ev.command == 'N') {
    reply = "NGD01\r";
  } else if (ev.command == 'F') {
    reply = "F00\r";
  } else if (ev.command == 'S' && (ev.arg_len != 1 || ev.arg[0] < '0' || ev.arg[0] > '8')) {
    reply = "\a";
  }
  std::size_t n = 0;
  while (reply[n] != '\0') ++n;
  if (out == nullptr || capacity < n) return 0;
  for (std::size_t i = 0; i < n; ++i) out[i] = reply[i];
  return n;
}

template <std::size_t LineCapacity = kMaxFrameLine>
class SlcanParser {
  static_assert(LineCapacity >= kMaxFrameLine, "line buffer must hold an extended frame line");

 public:
  // Feeds one byte; returns true (and fills ev) when it completed a line that is a frame,
  // a command or an error (a malformed line gives kError, so the caller can reply BEL).
  bool push(std::uint8_t byte, Event& ev) noexcept {
    ++stats_.bytes_in;
    const char c = static_cast<char>(byte);
    if (c == kBell) {
      ++stats_.bells;
      return false;
    }
    if (is_frame_letter(c) && (len_ > 0 || overlong_)) {
      // t/T/r/R never occur inside a line (ids, data and timestamps are hex, command
      // arguments digits or hex): the line before lost its terminator on the wire. Settle
      // it as an error now and start the new line with this letter, so one lost CR costs
      // one line, not that line and the next.
      ++stats_.lines;
      ++(overlong_ ? stats_.overlong : stats_.malformed);
      overlong_ = false;
      line_[0] = c;
      len_ = 1;
      ev = Event{};
      ev.kind = EventKind::kError;
      return true;
    }
    if (c != kCr && c != '\n') {
      if (overlong_) return false;
      if (len_ == LineCapacity) {
        overlong_ = true;
        return false;
      }
      line_[len_++] = c;
      return false;
    }
    if (overlong_) {
      ++stats_.lines;
      ++stats_.overlong;
      overlong_ = false;
      len_ = 0;
      ev = Event{};
      ev.kind = EventKind::kError;
      return true;
    }
    if (len_ == 0) return false;  // empty line (e.g. the LF of CR LF)
    ++stats_.lines;
    const bool ok = parse_line(ev);
    len_ = 0;
    if (!ok) {
      ++stats_.malformed;
      ev = Event{};
      ev.kind = EventKind::kError;
    }
    return true;
  }

  void reset() noexcept {
    len_ = 0;
    overlong_ = false;
    stats_ = SlcanStats{};
  }

  std::size_t buffered() const noexcept { return len_; }
  const SlcanStats& stats() const noexcept { return stats_; }

 private:
  bool parse_line(Event& ev) noexcept {
    ev = Event{};
    const char c0 = line_[0];
    if (c0 == 't' || c0 == 'T' || c0 == 'r' || c0 == 'R') {
      const bool extended = (c0 == 'T' || c0 == 'R');
      const bool remote = (c0 == 'r' || c0 == 'R');
      const std::size_t id_digits = extended ? 8U : 3U;
      if (len_ < 1 + id_digits + 1) return false;
      std::uint32_t id = 0;
      if (!detail::parse_hex(line_.data() + 1, id_digits, id)) return false;
      if (extended ? id > 0x1FFFFFFFU : id > 0x7FFU) return false;
      const int dlc = line_[1 + id_digits] - '0';
      if (dlc < 0 || dlc > 8) return false;
      const std::size_t data_digits = remote ? 0U : 2U * static_cast<std::size_t>(dlc);
      const std::size_t base_len = 1 + id_digits + 1 + data_digits;
      // Adapters with timestamps on ("Z1") append 4 hex digits; accept and ignore them.
      if (len_ != base_len && len_ != base_len + 4) return false;
      ev.frame.id = id;
      ev.frame.dlc = static_cast<std::uint8_t>(dlc);
      ev.frame.extended = extended;
      ev.frame.remote = remote;
      for (std::size_t i = 0; i < data_digits / 2; ++i) {
        std::uint32_t b = 0;
        if (!detail::parse_hex(line_.data() + base_len - data_digits + 2 * i, 2, b)) return false;
        ev.frame.data[i] = static_cast<std::uint8_t>(b);
      }
      if (len_ == base_len + 4) {
        std::uint32_t ts = 0;
        if (!detail::parse_hex(line_.data() + base_len, 4, ts)) return false;
      }
      ev.kind = EventKind::kFrame;
      ++stats_.frames;
      return true;
    }
    if (!is_command_letter(c0)) return false;
    const std::size_t arg_len = len_ - 1;
    if (arg_len > ev.arg.size()) return false;
    ev.kind = EventKind::kCommand;
    ev.command = c0;
    ev.arg_len = static_cast<std::uint8_t>(arg_len);
    for (std::size_t i = 0; i < arg_len; ++i) ev.arg[i] = line_[1 + i];
    ++stats_.commands;
    return true;
  }

  // The line buffer is the last member (see SerialFrameParser): overruns leave the object.
  std::size_t len_ = 0;
  bool overlong_ = false;
  SlcanStats stats_{};
  std::array<char, LineCapacity> line_{};
};

}  // namespace gyrodrift::slcan
