// Serial IMU frame (42 bytes, little-endian) and a resynchronising byte-stream parser.
//
//   off size field
//   0   1    sync0 = 0xA5
//   1   1    sync1 = 0x5A
//   2   1    type  = 0x01 input IMU sample | 0x81 filtered output sample |
//                    0x02 health request | 0x82 health report (one counter per frame:
//                    seq = index, flags = group, t_us = value, the 24 value bytes = the
//                    counter's name, NUL-padded ASCII; group 0xFF ends the report,
//                    its t_us = the number of counter frames before it)
//   3   1    len   = 36 (payload bytes that follow, before the CRC)
//   4   2    seq   u16 sample counter, wraps at 65536
//   6   2    flags u16 (input: 0; output: ImuProcessor health bits of that sample)
//   8   8    t_us  u64 timestamp, microseconds
//   16  24   6 x float32: gyro x y z (rad/s), accel x y z (m/s^2)
//   40  2    crc   CRC-16/CCITT-FALSE over bytes 2..39
//
// The parser owns a fixed-capacity byte buffer (no heap), never reads outside it, and
// accounts for every byte it is fed:
//   bytes_in == kFrameSize * frames_ok + discarded_bytes + buffered()
// Reasons for discarded bytes are counted separately (garbage while hunting for the sync
// word, bad header, CRC failure, frame cut short by the next frame, truncated at end).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "crc16.hpp"

namespace gyrodrift::serial {

inline constexpr std::uint8_t kSync0 = 0xA5U;
inline constexpr std::uint8_t kSync1 = 0x5AU;
inline constexpr std::uint8_t kTypeInput = 0x01U;
inline constexpr std::uint8_t kTypeOutput = 0x81U;
inline constexpr std::uint8_t kTypeHealthRequest = 0x02U;
inline constexpr std::uint8_t kTypeHealthReport = 0x82U;
inline constexpr std::uint8_t kPayloadLen = 36U;
inline constexpr std::size_t kFrameSize = 42U;
inline constexpr std::size_t kCrcOffset = 40U;

// One decoded frame; values = gyro x y z (rad/s), accel x y z (m/s^2).
struct ImuFrame {
  std::uint8_t type = kTypeInput;
  std::uint16_t seq = 0;
  std::uint16_t flags = 0;
  std::uint64_t t_us = 0;
  std::array<float, 6> values{};
};

namespace detail {
inline void put_u16(std::uint8_t* p, std::uint16_t v) noexcept {
  p[0] = static_cast<std::uint8_t>(v & 0xFFU);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
inline void put_u32(std::uint8_t* p, std::uint32_t v) noexcept {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>((v >> (8 * i)) & 0xFFU);
}
inline void put_u64(std::uint8_t* p, std::uint64_t v) noexcept {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>((v >> (8 * i)) & 0xFFU);
}
inline std::uint16_t get_u16(const std::uint8_t* p) noexcept {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}
inline std::uint32_t get_u32(const std::uint8_t* p) noexcept {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
inline std::uint64_t get_u64(const std::uint8_t* p) noexcept {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
// IEEE-754 binary32 <-> its bit pattern (memcpy is the defined way; no byte-order assumption
// beyond float and uint32 sharing one, true on every target we build for).
inline std::uint32_t float_bits(float f) noexcept {
  std::uint32_t u = 0;
  std::memcpy(&u, &f, sizeof u);
  return u;
}
inline float bits_float(std::uint32_t u) noexcept {
  float f = 0.0F;
  std::memcpy(&f, &u, sizeof f);
  return f;
}
inline bool valid_header(std::uint8_t type, std::uint8_t len) noexcept {
  return (type == kTypeInput || type == kTypeOutput || type == kTypeHealthRequest ||
          type == kTypeHealthReport) &&
         len == kPayloadLen;
}
}  // namespace detail

// Writes one frame into out[0..41]. Returns kFrameSize, or 0 if capacity < kFrameSize.
inline std::size_t encode_frame(const ImuFrame& f, std::uint8_t* out, std::size_t capacity) noexcept {
  if (out == nullptr || capacity < kFrameSize) return 0;
  out[0] = kSync0;
  out[1] = kSync1;
  out[2] = f.type;
  out[3] = kPayloadLen;
  detail::put_u16(out + 4, f.seq);
  detail::put_u16(out + 6, f.flags);
  detail::put_u64(out + 8, f.t_us);
  for (std::size_t i = 0; i < 6; ++i) detail::put_u32(out + 16 + 4 * i, detail::float_bits(f.values[i]));
  detail::put_u16(out + kCrcOffset, crc16_ccitt_false(out + 2, kCrcOffset - 2));
  return kFrameSize;
}

enum class DecodeStatus : std::uint8_t { kOk, kTooShort, kBadSync, kBadHeader, kBadCrc };

// Decodes exactly one frame starting at p (n bytes available).
inline DecodeStatus decode_frame(const std::uint8_t* p, std::size_t n, ImuFrame& out) noexcept {
  if (p == nullptr || n < kFrameSize) return DecodeStatus::kTooShort;
  if (p[0] != kSync0 || p[1] != kSync1) return DecodeStatus::kBadSync;
  if (!detail::valid_header(p[2], p[3])) return DecodeStatus::kBadHeader;
  if (crc16_ccitt_false(p + 2, kCrcOffset - 2) != detail::get_u16(p + kCrcOffset)) {
    return DecodeStatus::kBadCrc;
  }
  out.type = p[2];
  out.seq = detail::get_u16(p + 4);
  out.flags = detail::get_u16(p + 6);
  out.t_us = detail::get_u64(p + 8);
  for (std::size_t i = 0; i < 6; ++i) out.values[i] = detail::bits_float(detail::get_u32(p + 16 + 4 * i));
  return DecodeStatus::kOk;
}

struct SerialParserStats {
  std::uint64_t bytes_in = 0;         // bytes accepted by feed()
  std::uint64_t frames_ok = 0;        // frames with valid header and CRC
  std::uint64_t discarded_bytes = 0;  // every byte not part of a good frame (all reasons)
  std::uint64_t garbage_bytes = 0;    // discarded while hunting for the sync word
  std::uint64_t bad_header = 0;       // sync found, but type/len invalid
  std::uint64_t crc_errors = 0;       // complete frame whose CRC failed (42 bytes discarded)
  std::uint64_t truncated = 0;        // frame cut short: next header starts inside it, or end of stream
  std::uint64_t overflow_bytes = 0;   // bytes refused by feed() because the buffer was full
};

// Capacity: bytes buffered between feed() and next(); at least two frames.
template <std::size_t Capacity = 256>
class SerialFrameParser {
  static_assert(Capacity >= 2 * kFrameSize, "parser buffer must hold at least two frames");

 public:
  // Copies as many of the n bytes as fit; returns how many were taken. Bytes not taken are
  // counted in overflow_bytes (the caller still holds them; drain with next() and re-feed).
  std::size_t feed(const std::uint8_t* data, std::size_t n) noexcept {
    if (data == nullptr || n == 0) return 0;
    if (head_ > 0 && tail_ + n > Capacity) {  // compact: move the unread bytes to the front
      const std::size_t unread = tail_ - head_;
      std::memmove(buf_.data(), buf_.data() + head_, unread);
      head_ = 0;
      tail_ = unread;
    }
    const std::size_t room = Capacity - tail_;
    const std::size_t take = n < room ? n : room;
    std::memcpy(buf_.data() + tail_, data, take);
    tail_ += take;
    stats_.bytes_in += take;
    stats_.overflow_bytes += n - take;
    return take;
  }

  // Extracts the next good frame; false when more bytes are needed.
  bool next(ImuFrame& out) noexcept {
    for (;;) {
      const std::size_t avail = tail_ - head_;
      if (avail == 0) return false;
      const std::uint8_t* p = buf_.data() + head_;
      if (avail < 2 || p[0] != kSync0 || p[1] != kSync1) {
        if (!hunt_sync()) return false;
        continue;
      }
      if (avail < 4) return false;
      if (!detail::valid_header(p[2], p[3])) {
        ++stats_.bad_header;
        discard(2);
        continue;
      }
      if (avail < kFrameSize) return false;
      if (decode_frame(p, avail, out) == DecodeStatus::kOk) {
        head_ += kFrameSize;
        ++stats_.frames_ok;
        if (head_ == tail_) head_ = tail_ = 0;
        return true;
      }
      // CRC failed. If another valid header starts anywhere inside (offsets 2..41: a frame
      // cut short by even 1 byte has the next one's header at 41), this frame was cut short;
      // resume exactly there. Otherwise it was corrupted: drop all of it. A header at 39..41
      // ends up to 3 bytes past this frame, so wait for them: deciding on fewer would make
      // the counters depend on how the stream was chunked.
      if (avail < kFrameSize + 3) return false;
      const std::size_t k = header_inside(p);
      if (k < kFrameSize) {
        ++stats_.truncated;
        discard(k);
      } else {
        ++stats_.crc_errors;
        discard(kFrameSize);
      }
    }
  }

  // End of stream: whatever is still buffered can never complete a frame. A complete frame
  // left here failed its CRC while next() waited for the 3 bytes after it: settle it as
  // next() would (a header inside it whose bytes are all here means cut short).
  void finish() noexcept {
    std::size_t avail = tail_ - head_;
    if (avail >= kFrameSize) {
      const std::uint8_t* p = buf_.data() + head_;
      const std::size_t k = header_inside(p, avail);
      if (k < kFrameSize) {
        ++stats_.truncated;
        discard(k);
      } else {
        ++stats_.crc_errors;
        discard(kFrameSize);
      }
      avail = tail_ - head_;
    }
    if (avail == 0) return;
    if (buf_[head_] == kSync0) {
      ++stats_.truncated;
    } else {
      stats_.garbage_bytes += avail;
    }
    discard(avail);
  }

  void reset() noexcept {
    head_ = tail_ = 0;
    stats_ = SerialParserStats{};
  }

  std::size_t buffered() const noexcept { return tail_ - head_; }
  static constexpr std::size_t capacity() noexcept { return Capacity; }
  const SerialParserStats& stats() const noexcept { return stats_; }

 private:
  void discard(std::size_t n) noexcept {
    head_ += n;
    stats_.discarded_bytes += n;
    if (head_ == tail_) head_ = tail_ = 0;
  }

  // Offset (2..41) of the first valid header (sync word, type, len) inside the frame at p,
  // looking at no byte at or past avail; kFrameSize if none. Offset 1 cannot hold one
  // (p[1] is sync1, not sync0).
  static std::size_t header_inside(const std::uint8_t* p, std::size_t avail = kFrameSize + 3) noexcept {
    for (std::size_t k = 2; k < kFrameSize && k + 3 < avail; ++k) {
      if (p[k] == kSync0 && p[k + 1] == kSync1 && detail::valid_header(p[k + 2], p[k + 3])) return k;
    }
    return kFrameSize;
  }

  // Drops bytes up to the next possible sync word; a trailing lone sync0 is kept because
  // its sync1 may still arrive. Returns true if a full sync pair is now at the front.
  bool hunt_sync() noexcept {
    const std::size_t avail = tail_ - head_;
    const std::uint8_t* p = buf_.data() + head_;
    std::size_t k = (avail >= 2 && p[0] == kSync0 && p[1] == kSync1) ? 0 : 1;
    if (avail == 1) {
      if (p[0] == kSync0) return false;
      k = 1;
    } else {
      if (p[0] == kSync0 && p[1] == kSync1) return true;
      for (; k < avail; ++k) {
        if (p[k] == kSync0 && (k + 1 == avail || p[k + 1] == kSync1)) break;
      }
    }
    stats_.garbage_bytes += k;
    discard(k);
    return buffered() >= 2;
  }

  // The buffer is the last member, so any access past its end would leave the object
  // (caught by AddressSanitizer when the parser lives on the heap, as in the fuzz test).
  std::size_t head_ = 0;
  std::size_t tail_ = 0;
  SerialParserStats stats_{};
  std::array<std::uint8_t, Capacity> buf_{};
};

}  // namespace gyrodrift::serial
