// Decoding an IMU sample from a user's own DBC through a generated table: allocation-free
// bit extraction in Intel (little-endian) and Motorola (big-endian) order, sign extension,
// IEEE float signals, scale/offset, simple multiplexing, and sample assembly.
//
// The table comes from the vendor's DBC through cantools
// (python/gyrodrift/codecs/can_signals.py, decode_table_text): one text line per role
//   ROLE ID EXT DLC START LENGTH ORDER TYPE SCALE OFFSET FACTOR MUX
// e.g. "gx 0x18ff0123 1 8 7 16 be s 0.005 0.0 0.017453292519943295 -". parse_signal_line
// reads one line (strtod/strtoul, no allocation), so the loop can load a table at start-up
// and an MCU build can compile one in as constexpr SignalEntry values.
//
// Bit numbering is the DBC's (what cantools reads): bit b is bit b%8 of byte b/8.
//   Intel:    START is the least significant bit; the field runs upward.
//   Motorola: START is the most significant bit; the field runs downward inside a byte and
//             continues at bit 7 of the next byte (the DBC "sawtooth").
// Physical value = raw * SCALE + OFFSET (cantools' LinearConversion); channel value =
// physical * FACTOR (unit conversion to rad/s, m/s^2; to microseconds for the time role).
//
// A multiplexed message's defined pages come as one more line per message
//   pages ID EXT START:LENGTH:ORDER V1,V2,...
// (the multiplexer selector's field and every value the DBC defines for it). A frame whose
// selector has a value the DBC does not define decodes nothing, as cantools refuses to decode
// it (DecodeError): it is counted in ignored_frames and in undefined_page_frames.
//
// Assembly rules and the accounting identity are those of the Python twin
// (gyrodrift.codecs.can_signals.SignalSampleAssembler):
//   frames_in == foreign_frames + frames_used + frames_dropped + ignored_frames
//                + pending_frames()
#pragma once
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "can_frames.hpp"  // CanFrame

namespace gyrodrift::can {

enum class ByteOrder : std::uint8_t { kIntel = 0, kMotorola = 1 };
enum class ValueType : std::uint8_t { kUnsigned = 0, kSigned = 1, kFloat32 = 2, kFloat64 = 3 };
// gx gy gz ax ay az, then the optional sequence counter and timestamp.
enum class SignalRole : std::uint8_t { kGx = 0, kGy, kGz, kAx, kAy, kAz, kSeq, kTime };
inline constexpr std::size_t kSignalRoles = 8U;
inline constexpr std::size_t kChannelRoles = 6U;

struct BitField {
  std::uint16_t start = 0;  // DBC start bit (Intel: LSB, Motorola: MSB)
  std::uint8_t length = 0;  // 1..64
  ByteOrder order = ByteOrder::kIntel;
};

struct SignalEntry {
  SignalRole role = SignalRole::kGx;
  std::uint32_t id = 0;
  bool extended = false;
  std::uint8_t dlc = 8;  // the message's length: a shorter frame is a bad DLC
  BitField field{};
  ValueType type = ValueType::kUnsigned;
  double scale = 1.0;
  double offset = 0.0;
  double factor = 1.0;
  bool muxed = false;
  BitField mux{};  // the multiplexer selector (unsigned, scale 1) when muxed
  std::uint64_t mux_value = 0;
};

// Raw bits of a field; false if any of its bits lies beyond the frame's dlc bytes.
// Bit by bit: at most 64 iterations, no table, the same code for both orders.
inline bool extract_bits(const std::uint8_t* data, std::uint8_t dlc, const BitField& f,
                         std::uint64_t& raw) noexcept {
  if (f.length == 0U || f.length > 64U) return false;
  raw = 0U;
  unsigned pos = f.start;
  for (unsigned i = 0; i < f.length; ++i) {
    const unsigned byte = pos / 8U;
    const unsigned bit = pos % 8U;
    if (byte >= dlc) return false;
    const std::uint64_t b = (static_cast<unsigned>(data[byte]) >> bit) & 1U;
    if (f.order == ByteOrder::kIntel) {
      raw |= b << i;  // LSB first, upward
      ++pos;
    } else {
      raw = (raw << 1U) | b;  // MSB first; after bit 0 of a byte comes bit 7 of the next
      pos = (bit == 0U) ? pos + 15U : pos - 1U;
    }
  }
  return true;
}

// Whether every bit of the field lies within dlc bytes (the positions extract_bits reads).
inline bool field_fits(const BitField& f, std::uint8_t dlc) noexcept {
  if (f.length == 0U || f.length > 64U) return false;
  unsigned pos = f.start;
  for (unsigned i = 0; i < f.length; ++i) {
    const unsigned bit = pos % 8U;
    if (pos / 8U >= dlc) return false;
    if (f.order == ByteOrder::kIntel) ++pos;
    else pos = (bit == 0U) ? pos + 15U : pos - 1U;
  }
  return true;
}

// The pages a multiplexed message defines (the values of its selector in the DBC).
inline constexpr std::size_t kMaxPages = 64U;
struct PageSet {
  std::uint32_t id = 0;
  bool extended = false;
  std::uint8_t dlc = 8;
  BitField mux{};
  std::array<std::uint64_t, kMaxPages> values{};
  std::size_t n = 0;

  // False when the frame is this message and its selector holds an undefined value.
  bool defined(const CanFrame& f) const noexcept {
    if (f.remote || f.extended != extended || f.id != id) return true;
    std::uint64_t sel = 0;
    if (!extract_bits(f.data.data(), f.dlc, mux, sel)) return true;  // short frame: bad DLC
    for (std::size_t i = 0; i < n; ++i) {
      if (values[i] == sel) return true;
    }
    return false;
  }
};

// raw * scale + offset, as cantools computes it (LinearConversion.raw_to_scaled). Scalar
// double (the default, the analysis/loop build) reproduces cantools bit for bit: integers
// widened to double first, exact for |raw| < 2^53. Scalar float (an MCU without a double FPU)
// rounds scale, offset and the product to float: within a few float ulps of the double
// result, which is itself rounded to float32 for the sample.
template <class Scalar = double>
inline Scalar raw_to_physical(std::uint64_t raw, std::uint8_t length, ValueType type,
                              double scale, double offset) noexcept {
  Scalar v = Scalar(0);
  switch (type) {
    case ValueType::kUnsigned:
      v = static_cast<Scalar>(raw);
      break;
    case ValueType::kSigned: {
      std::uint64_t u = raw;
      if (length < 64U && ((u >> (length - 1U)) & 1U) != 0U) u |= ~std::uint64_t{0} << length;
      std::int64_t s = 0;
      std::memcpy(&s, &u, sizeof s);  // two's complement reinterpretation
      v = static_cast<Scalar>(s);
      break;
    }
    case ValueType::kFloat32: {
      const auto bits = static_cast<std::uint32_t>(raw);
      float f = 0.0F;
      std::memcpy(&f, &bits, sizeof f);
      v = static_cast<Scalar>(f);
      break;
    }
    case ValueType::kFloat64: {
      double d = 0.0;
      std::memcpy(&d, &raw, sizeof d);
      v = static_cast<Scalar>(d);
      break;
    }
  }
  return v * static_cast<Scalar>(scale) + static_cast<Scalar>(offset);
}

enum class EntryMatch : std::uint8_t { kOtherMessage, kBadDlc, kOtherPage, kValue };

// Does this frame carry the entry's signal? If so, its physical value times factor.
template <class Scalar = double>
inline EntryMatch decode_entry(const SignalEntry& e, const CanFrame& f, Scalar& value) noexcept {
  if (f.remote || f.extended != e.extended || f.id != e.id) return EntryMatch::kOtherMessage;
  if (f.dlc < e.dlc) return EntryMatch::kBadDlc;
  if (e.muxed) {
    std::uint64_t sel = 0;
    if (!extract_bits(f.data.data(), f.dlc, e.mux, sel)) return EntryMatch::kBadDlc;
    if (sel != e.mux_value) return EntryMatch::kOtherPage;
  }
  std::uint64_t raw = 0;
  if (!extract_bits(f.data.data(), f.dlc, e.field, raw)) return EntryMatch::kBadDlc;
  value = raw_to_physical<Scalar>(raw, e.field.length, e.type, e.scale, e.offset) *
          static_cast<Scalar>(e.factor);
  return EntryMatch::kValue;
}

// ---- the table's text form -------------------------------------------------------------

enum class LineResult : std::uint8_t { kEntry, kBlank, kError, kPages };

namespace detail {
inline const char* skip_space(const char* p) noexcept {
  while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') ++p;
  return p;
}
inline bool word_is(const char* p, const char* w, const char** end) noexcept {
  const std::size_t n = std::strlen(w);
  if (std::strncmp(p, w, n) != 0) return false;
  const char c = p[n];
  if (c != '\0' && c != ' ' && c != '\t' && c != ':' && c != '\r' && c != '\n') return false;
  *end = p + n;
  return true;
}
inline bool read_u64(const char*& p, std::uint64_t& out, std::uint64_t max) noexcept {
  p = skip_space(p);
  if (*p < '0' || *p > '9') return false;
  char* end = nullptr;
  const unsigned long long v = std::strtoull(p, &end, 0);  // decimal or 0x hex
  if (end == p || v > max) return false;
  out = static_cast<std::uint64_t>(v);
  p = end;
  return true;
}
inline bool read_double(const char*& p, double& out) noexcept {
  p = skip_space(p);
  char* end = nullptr;
  const double v = std::strtod(p, &end);
  if (end == p || !std::isfinite(v)) return false;
  out = v;
  p = end;
  return true;
}
inline bool read_order(const char*& p, ByteOrder& out) noexcept {
  p = skip_space(p);
  const char* end = nullptr;
  if (word_is(p, "le", &end)) {
    out = ByteOrder::kIntel;
  } else if (word_is(p, "be", &end)) {
    out = ByteOrder::kMotorola;
  } else {
    return false;
  }
  p = end;
  return true;
}
inline bool read_field(const char*& p, BitField& f) noexcept {
  std::uint64_t start = 0;
  std::uint64_t length = 0;
  if (!read_u64(p, start, 511U) || !read_u64(p, length, 64U) || length == 0U) return false;
  f.start = static_cast<std::uint16_t>(start);
  f.length = static_cast<std::uint8_t>(length);
  return true;
}
}  // namespace detail

// Parses one line of the table. kBlank for empty/comment lines and the header line;
// kError with *error naming the column that is wrong.
inline LineResult parse_signal_line(const char* line, SignalEntry& e,
                                    const char** error) noexcept {
  namespace d = detail;
  static constexpr std::array<const char*, kSignalRoles> kNames = {"gx", "gy", "gz", "ax",
                                                                   "ay", "az", "seq", "time"};
  const char* p = d::skip_space(line);
  if (*p == '\0' || *p == '#' || std::strncmp(p, "gyrodrift-can-signals", 21) == 0) {
    return LineResult::kBlank;
  }
  e = SignalEntry{};
  const char* end = nullptr;
  bool found = false;
  for (std::size_t r = 0; r < kSignalRoles && !found; ++r) {
    if (d::word_is(p, kNames[r], &end)) {
      e.role = static_cast<SignalRole>(r);
      found = true;
    }
  }
  auto fail = [error](const char* what) noexcept {
    if (error != nullptr) *error = what;
    return LineResult::kError;
  };
  if (!found) return fail("role (gx gy gz ax ay az seq time)");
  p = end;
  std::uint64_t v = 0;
  if (!d::read_u64(p, v, 0x1FFFFFFFU)) return fail("id");
  e.id = static_cast<std::uint32_t>(v);
  if (!d::read_u64(p, v, 1U)) return fail("ext (0 or 1)");
  e.extended = v == 1U;
  if (!e.extended && e.id > 0x7FFU) return fail("id (a standard id is 11 bits)");
  if (!d::read_u64(p, v, 8U)) return fail("dlc (0..8)");
  e.dlc = static_cast<std::uint8_t>(v);
  if (!d::read_field(p, e.field)) return fail("start/length");
  if (!d::read_order(p, e.field.order)) return fail("order (le or be)");
  if (!field_fits(e.field, e.dlc)) return fail("start/length (the signal does not fit in DLC bytes)");
  p = d::skip_space(p);
  if (d::word_is(p, "u", &end)) {
    e.type = ValueType::kUnsigned;
  } else if (d::word_is(p, "s", &end)) {
    e.type = ValueType::kSigned;
  } else if (d::word_is(p, "f32", &end)) {
    e.type = ValueType::kFloat32;
  } else if (d::word_is(p, "f64", &end)) {
    e.type = ValueType::kFloat64;
  } else {
    return fail("type (u s f32 f64)");
  }
  p = end;
  if ((e.type == ValueType::kFloat32 && e.field.length != 32U) ||
      (e.type == ValueType::kFloat64 && e.field.length != 64U)) {
    return fail("length (a float signal is 32 or 64 bits)");
  }
  if (!d::read_double(p, e.scale)) return fail("scale");
  if (!d::read_double(p, e.offset)) return fail("offset");
  if (!d::read_double(p, e.factor) || e.factor == 0.0) return fail("factor");
  p = d::skip_space(p);
  if (*p == '-') {
    ++p;
  } else {
    e.muxed = true;
    std::uint64_t mstart = 0;
    std::uint64_t mlen = 0;
    if (!d::read_u64(p, mstart, 511U) || *p != ':') return fail("mux start");
    ++p;
    if (!d::read_u64(p, mlen, 64U) || mlen == 0U || *p != ':') return fail("mux length");
    ++p;
    e.mux.start = static_cast<std::uint16_t>(mstart);
    e.mux.length = static_cast<std::uint8_t>(mlen);
    if (!d::read_order(p, e.mux.order) || *p != ':') return fail("mux order");
    if (!field_fits(e.mux, e.dlc)) return fail("mux start/length (the selector does not fit in DLC bytes)");
    ++p;
    if (!d::read_u64(p, e.mux_value, ~std::uint64_t{0})) return fail("mux value");
  }
  p = d::skip_space(p);
  if (*p != '\0' && *p != '#') return fail("trailing text");
  if (e.role == SignalRole::kSeq &&
      (e.type != ValueType::kUnsigned || e.field.length > 16U || e.scale != 1.0 ||
       e.offset != 0.0 || e.factor != 1.0)) {
    return fail("seq (an unsigned counter of at most 16 bits, scale 1, offset 0)");
  }
  return LineResult::kEntry;
}

// Parses a `pages ID EXT DLC START:LENGTH:ORDER V1,V2,...` line (kPages), else as
// parse_signal_line.
inline LineResult parse_table_line(const char* line, SignalEntry& e, PageSet& pages,
                                   const char** error) noexcept {
  namespace d = detail;
  const char* p = d::skip_space(line);
  const char* end = nullptr;
  if (!d::word_is(p, "pages", &end)) return parse_signal_line(line, e, error);
  auto fail = [error](const char* what) noexcept {
    if (error != nullptr) *error = what;
    return LineResult::kError;
  };
  p = end;
  pages = PageSet{};
  std::uint64_t v = 0;
  if (!d::read_u64(p, v, 0x1FFFFFFFU)) return fail("id");
  pages.id = static_cast<std::uint32_t>(v);
  if (!d::read_u64(p, v, 1U)) return fail("ext (0 or 1)");
  pages.extended = v == 1U;
  if (!pages.extended && pages.id > 0x7FFU) return fail("id (a standard id is 11 bits)");
  if (!d::read_u64(p, v, 8U)) return fail("dlc (0..8)");
  pages.dlc = static_cast<std::uint8_t>(v);
  std::uint64_t mstart = 0;
  std::uint64_t mlen = 0;
  if (!d::read_u64(p, mstart, 511U) || *p != ':') return fail("mux start");
  ++p;
  if (!d::read_u64(p, mlen, 64U) || mlen == 0U || *p != ':') return fail("mux length");
  ++p;
  pages.mux.start = static_cast<std::uint16_t>(mstart);
  pages.mux.length = static_cast<std::uint8_t>(mlen);
  if (!d::read_order(p, pages.mux.order) || *p != ':') return fail("mux order");
  ++p;
  if (!field_fits(pages.mux, pages.dlc)) return fail("mux start/length (the selector does not fit in DLC bytes)");
  for (;;) {
    if (pages.n >= kMaxPages) return fail("pages (at most 64 values)");
    if (!d::read_u64(p, pages.values[pages.n], ~std::uint64_t{0})) return fail("page value");
    ++pages.n;
    if (*p != ',') break;
    ++p;
  }
  p = d::skip_space(p);
  if (*p != '\0' && *p != '#') return fail("trailing text");
  return LineResult::kPages;
}

// ---- a table and the sample assembler ----------------------------------------------------

template <std::size_t MaxEntries = kSignalRoles>
class SignalTable {
 public:
  // False if the table is full or the role is already mapped.
  bool add(const SignalEntry& e) noexcept {
    const auto r = static_cast<std::size_t>(e.role);
    if (n_ >= MaxEntries || (present_ & (1U << r)) != 0U) return false;
    entries_[n_++] = e;
    present_ |= 1U << r;
    return true;
  }
  // Every channel role mapped (sequence and time are optional).
  bool complete() const noexcept { return (present_ & 0x3FU) == 0x3FU; }
  bool has(SignalRole r) const noexcept {
    return (present_ & (1U << static_cast<unsigned>(r))) != 0U;
  }
  std::uint32_t roles_mask() const noexcept { return present_; }
  std::size_t size() const noexcept { return n_; }
  const SignalEntry& operator[](std::size_t i) const noexcept { return entries_[i]; }
  const SignalEntry* find(SignalRole r) const noexcept {
    for (std::size_t i = 0; i < n_; ++i) {
      if (entries_[i].role == r) return &entries_[i];
    }
    return nullptr;
  }
  // A message's defined pages; false if the table holds as many page sets as entries or
  // the message has one already.
  bool add_pages(const PageSet& p) noexcept {
    if (n_pages_ >= MaxEntries) return false;
    for (std::size_t i = 0; i < n_pages_; ++i) {
      if (pages_[i].id == p.id && pages_[i].extended == p.extended) return false;
    }
    pages_[n_pages_++] = p;
    return true;
  }
  // False when the frame is a multiplexed message whose page the DBC does not define.
  bool page_defined(const CanFrame& f) const noexcept {
    for (std::size_t i = 0; i < n_pages_; ++i) {
      if (!pages_[i].defined(f)) return false;
    }
    return true;
  }

 private:
  std::array<PageSet, MaxEntries> pages_{};
  std::size_t n_pages_ = 0;
  std::array<SignalEntry, MaxEntries> entries_{};
  std::size_t n_ = 0;
  std::uint32_t present_ = 0;
};

struct SignalRxStats {
  std::uint64_t frames_in = 0;
  std::uint64_t frames_used = 0;
  std::uint64_t frames_dropped = 0;  // frames of incomplete samples, and bad DLC
  std::uint64_t foreign_frames = 0;  // not a mapped message (or a remote frame)
  std::uint64_t ignored_frames = 0;  // a mapped message carrying no mapped signal (mux page)
  std::uint64_t undefined_page_frames = 0;  // of those: a page the DBC does not define
  std::uint64_t bad_dlc = 0;
  std::uint64_t complete_samples = 0;
  std::uint64_t incomplete_samples = 0;
};

struct SignalSample {
  std::uint16_t seq = 0;   // unwrapped 16-bit sequence, or a running count
  bool has_time = false;
  std::uint64_t t_us = 0;  // the IMU's own time (has_time)
  std::array<float, kChannelRoles> values{};
};

// Scalar: arithmetic of the six channel values (double reproduces cantools exactly; float
// for an MCU). The sequence counter and the timestamp are always decoded in double: a
// microsecond clock needs more than float's 24-bit mantissa.
template <std::size_t MaxEntries = kSignalRoles, class Scalar = double>
class SignalSampleAssembler {
 public:
  // Keeps a reference to the table (which may be filled after construction).
  explicit SignalSampleAssembler(const SignalTable<MaxEntries>& table) noexcept
      : table_(table) {}

  // True (and out filled) when this frame completed a sample.
  bool push(const CanFrame& f, SignalSample& out) noexcept {
    ++stats_.frames_in;
    bool mapped = false;
    bool bad = false;
    std::uint32_t got = 0;
    std::array<Scalar, kChannelRoles> vals{};
    std::array<double, 2> ints{};  // seq, time
    for (std::size_t i = 0; i < table_.size(); ++i) {
      const SignalEntry& e = table_[i];
      const auto r = static_cast<std::size_t>(e.role);
      Scalar v = Scalar(0);
      double vd = 0.0;
      const EntryMatch match =
          r < kChannelRoles ? decode_entry<Scalar>(e, f, v) : decode_entry<double>(e, f, vd);
      switch (match) {
        case EntryMatch::kOtherMessage:
          break;
        case EntryMatch::kBadDlc:
          mapped = true;
          bad = true;
          break;
        case EntryMatch::kOtherPage:
          mapped = true;
          break;
        case EntryMatch::kValue:
          mapped = true;
          got |= 1U << r;
          if (r < kChannelRoles) {
            vals[r] = v;
          } else {
            ints[r - kChannelRoles] = vd;
          }
          break;
      }
    }
    if (!mapped) {
      ++stats_.foreign_frames;
      return false;
    }
    if (bad) {
      ++stats_.bad_dlc;
      ++stats_.frames_dropped;
      return false;
    }
    if (!table_.page_defined(f)) {  // cantools decodes nothing of such a frame
      ++stats_.ignored_frames;
      ++stats_.undefined_page_frames;
      return false;
    }
    if (got == 0U) {
      ++stats_.ignored_frames;
      return false;
    }
    if ((filled_ & got) != 0U) drop();
    for (std::size_t r = 0; r < kSignalRoles; ++r) {
      if ((got & (1U << r)) == 0U) continue;
      if (r < kChannelRoles) {
        pending_[r] = vals[r];
      } else {
        pending_ints_[r - kChannelRoles] = ints[r - kChannelRoles];
      }
    }
    filled_ |= got;
    ++held_;
    if (filled_ != table_.roles_mask()) return false;
    emit(out);
    stats_.frames_used += held_;
    ++stats_.complete_samples;
    filled_ = 0;
    held_ = 0;
    return true;
  }

  // End of stream: a partial sample is counted as incomplete.
  void finish() noexcept { drop(); }

  std::uint64_t pending_frames() const noexcept { return held_; }
  const SignalRxStats& stats() const noexcept { return stats_; }

 private:
  void drop() noexcept {
    if (held_ != 0U) {
      ++stats_.incomplete_samples;
      stats_.frames_dropped += held_;
    }
    filled_ = 0;
    held_ = 0;
  }

  void emit(SignalSample& out) noexcept {
    const SignalEntry* seq_entry = table_.find(SignalRole::kSeq);
    if (seq_entry != nullptr) {
      const unsigned seq_bits = seq_entry->field.length;
      const auto counter = static_cast<std::uint64_t>(pending_ints_[0]);
      if (!have_counter_) {
        seq16_ = static_cast<std::uint16_t>(counter & 0xFFFFU);
        have_counter_ = true;
      } else {
        const std::uint64_t mask = (std::uint64_t{1} << seq_bits) - 1U;
        const std::uint64_t step = (counter - last_counter_) & mask;  // modulo 2^width
        seq16_ = static_cast<std::uint16_t>((seq16_ + step) & 0xFFFFU);
      }
      last_counter_ = counter;
      out.seq = seq16_;
    } else {
      out.seq = static_cast<std::uint16_t>(count_ & 0xFFFFU);
    }
    ++count_;
    out.has_time = table_.has(SignalRole::kTime);
    if (out.has_time) {
      const double t = pending_ints_[1];
      out.t_us = (std::isfinite(t) && t >= 0.0 && t < 1.8e19)
                     ? static_cast<std::uint64_t>(std::floor(t + 0.5))
                     : 0U;
    }
    for (std::size_t c = 0; c < kChannelRoles; ++c) {
      out.values[c] = static_cast<float>(pending_[c]);
    }
  }

  const SignalTable<MaxEntries>& table_;
  std::array<Scalar, kChannelRoles> pending_{};
  std::array<double, 2> pending_ints_{};  // seq, time
  std::uint32_t filled_ = 0;
  std::uint64_t held_ = 0;
  bool have_counter_ = false;
  std::uint64_t last_counter_ = 0;
  std::uint16_t seq16_ = 0;
  std::uint64_t count_ = 0;
  SignalRxStats stats_{};
};

}  // namespace gyrodrift::can
