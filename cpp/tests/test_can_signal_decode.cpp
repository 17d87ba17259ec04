// User-DBC signal decoding: hand-checked bit fields in both byte orders, sign extension,
// scale/offset, the table's text form, multiplexed assembly with exact frame accounting.
// (The agreement with cantools on every frame of a log is tests/test_can_signals.py.)
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <array>
#include <cstdint>
#include <gyrodrift/codecs/can_signal_decode.hpp>
#include <string>

using namespace gyrodrift::can;

namespace {
CanFrame frame(std::uint32_t id, std::array<std::uint8_t, 8> data, bool extended = false) {
  CanFrame f;
  f.id = id;
  f.dlc = 8;
  f.extended = extended;
  f.data = data;
  return f;
}

template <std::size_t N, class S>
void check_accounting(const SignalSampleAssembler<N, S>& a) {
  const auto& s = a.stats();
  CHECK(s.frames_in == s.foreign_frames + s.frames_used + s.frames_dropped + s.ignored_frames +
                           a.pending_frames());
}
}  // namespace

TEST_CASE("bit fields by hand: Intel and Motorola") {
  const std::array<std::uint8_t, 8> d = {0x12, 0x34, 0x0A, 0xBC, 0xC0, 0xAB, 0x80, 0x01};
  std::uint64_t raw = 0;
  // Intel 16 bits from bit 0: bytes 0..1 little-endian.
  REQUIRE(extract_bits(d.data(), 8, BitField{0, 16, ByteOrder::kIntel}, raw));
  CHECK(raw == 0x3412U);
  // Motorola 16 bits with MSB at bit 7: bytes 0..1 big-endian.
  REQUIRE(extract_bits(d.data(), 8, BitField{7, 16, ByteOrder::kMotorola}, raw));
  CHECK(raw == 0x1234U);
  // Motorola 12 bits with MSB at bit 19 (byte 2, bit 3): low nibble of byte 2, then byte 3.
  REQUIRE(extract_bits(d.data(), 8, BitField{19, 12, ByteOrder::kMotorola}, raw));
  CHECK(raw == 0xABCU);
  // Intel 12 bits from bit 36 (byte 4, bit 4): high nibble of byte 4 is the low nibble.
  REQUIRE(extract_bits(d.data(), 8, BitField{36, 12, ByteOrder::kIntel}, raw));
  CHECK(raw == 0xABCU);
  // A single bit, and a field that runs past the frame's data.
  REQUIRE(extract_bits(d.data(), 8, BitField{55, 1, ByteOrder::kIntel}, raw));
  CHECK(raw == 1U);
  CHECK_FALSE(extract_bits(d.data(), 4, BitField{31, 16, ByteOrder::kMotorola}, raw));
  CHECK_FALSE(extract_bits(d.data(), 8, BitField{60, 8, ByteOrder::kIntel}, raw));
}

TEST_CASE("sign extension, scale and offset, floats") {
  CHECK(raw_to_physical(0xFFFEU, 16, ValueType::kSigned, 0.5, 1.0) == 0.0);
  CHECK(raw_to_physical(0x7FFFU, 16, ValueType::kSigned, 1.0, 0.0) == 32767.0);
  CHECK(raw_to_physical(0x800U, 12, ValueType::kSigned, 0.0625, 0.0) == -128.0);
  CHECK(raw_to_physical(0xFFFEU, 16, ValueType::kUnsigned, 1.0, -40.0) == 65494.0);
  CHECK(raw_to_physical(0x3FC00000U, 32, ValueType::kFloat32, 1.0, 0.0) == 1.5);
  CHECK(raw_to_physical<float>(0xFFFEU, 16, ValueType::kSigned, 0.5, 1.0) == 0.0F);
}

TEST_CASE("table lines parse; bad columns are named") {
  SignalEntry e;
  const char* err = nullptr;
  CHECK(parse_signal_line("# comment", e, &err) == LineResult::kBlank);
  CHECK(parse_signal_line("gyrodrift-can-signals 1", e, &err) == LineResult::kBlank);
  REQUIRE(parse_signal_line("az 0x124 0 8 47 16 be s 0.0005 9.80665 1.0 0:8:le:0  # x", e,
                            &err) == LineResult::kEntry);
  CHECK(e.role == SignalRole::kAz);
  CHECK(e.id == 0x124U);
  CHECK(e.field.start == 47U);
  CHECK(e.field.order == ByteOrder::kMotorola);
  CHECK(e.offset == 9.80665);
  CHECK(e.muxed);
  CHECK(e.mux.length == 8U);
  CHECK(e.mux_value == 0U);
  CHECK(parse_signal_line("gx 0x800 0 8 0 16 le s 1 0 1 -", e, &err) == LineResult::kError);
  CHECK(std::string(err).find("standard id") != std::string::npos);
  CHECK(parse_signal_line("gx 0x100 0 8 0 16 xx s 1 0 1 -", e, &err) == LineResult::kError);
  CHECK(std::string(err).find("order") != std::string::npos);
  CHECK(parse_signal_line("gx 0x100 0 8 0 16 le f32 1 0 1 -", e, &err) == LineResult::kError);
  CHECK(parse_signal_line("seq 0x100 0 8 0 16 le s 1 0 1 -", e, &err) == LineResult::kError);
  CHECK(parse_signal_line("gx 0x100 0 8 0 16 le s 1 0 1 - extra", e, &err) ==
        LineResult::kError);
}

TEST_CASE("multiplexed assembly, counter unwrap, accounting") {
  // Rates on 0x10 (Intel int16 x3 + 4-bit counter in byte 6), accelerations on page 0 of
  // 0x20 (selector byte 0), page 1 of 0x20 unused.
  const char* lines[] = {
      "gx 0x10 0 8 0 16 le s 0.5 0 1 -",  "gy 0x10 0 8 16 16 le s 0.5 0 1 -",
      "gz 0x10 0 8 32 16 le s 0.5 0 1 -", "ax 0x20 0 8 8 16 le s 1 0 1 0:8:le:0",
      "ay 0x20 0 8 24 16 le s 1 0 1 0:8:le:0", "az 0x20 0 8 40 16 le s 1 0 1 0:8:le:0",
      "seq 0x10 0 8 48 4 le u 1 0 1 -"};
  SignalTable<> table;
  for (const char* l : lines) {
    SignalEntry e;
    const char* err = nullptr;
    REQUIRE(parse_signal_line(l, e, &err) == LineResult::kEntry);
    REQUIRE(table.add(e));
  }
  REQUIRE(table.complete());
  SignalSampleAssembler<> a(table);
  SignalSample s;
  int done = 0;
  for (std::uint8_t k = 0; k < 20; ++k) {
    const auto c = static_cast<std::uint8_t>(k % 16U);
    CHECK_FALSE(a.push(frame(0x10, {2, 0, 0xFE, 0xFF, k, 0, c, 0}), s));
    CHECK_FALSE(a.push(frame(0x20, {1, 9, 9, 9, 9, 9, 9, 9}), s));  // page 1: ignored
    CHECK_FALSE(a.push(frame(0x30, {}), s));                        // foreign
    REQUIRE(a.push(frame(0x20, {0, 3, 0, 4, 0, 5, 0, 0}), s));
    CHECK(s.seq == k);  // the 4-bit counter unwrapped past 15
    CHECK(s.values[0] == 1.0F);
    CHECK(s.values[1] == -1.0F);
    CHECK(s.values[2] == 0.5F * static_cast<float>(k));
    CHECK(s.values[5] == 5.0F);
    ++done;
  }
  CHECK(done == 20);
  // A lost rates frame: the accel frame completes nothing, and the next accel frame would
  // fill its roles again, so the partial sample is dropped and counted.
  CHECK_FALSE(a.push(frame(0x20, {0, 3, 0, 4, 0, 5, 0, 0}), s));
  CHECK_FALSE(a.push(frame(0x20, {0, 3, 0, 4, 0, 5, 0, 0}), s));
  CHECK(a.stats().incomplete_samples == 1U);
  CHECK(a.stats().frames_dropped == 1U);
  // A short frame of a mapped message is a bad DLC.
  CanFrame shortf = frame(0x10, {});
  shortf.dlc = 4;
  CHECK_FALSE(a.push(shortf, s));
  CHECK(a.stats().bad_dlc == 1U);
  a.finish();
  CHECK(a.stats().incomplete_samples == 2U);
  CHECK(a.stats().complete_samples == 20U);
  CHECK(a.stats().ignored_frames == 20U);
  CHECK(a.stats().foreign_frames == 20U);
  check_accounting(a);
}

TEST_CASE("a page the DBC does not define decodes nothing, counted (cantools' rule)") {
  // Message 0x40: gx..az outside the multiplexer (bytes 1..6), selector byte 0 with pages
  // 0 and 2 defined; a frame with selector 1 or 7 decodes nothing, even the plain signals.
  SignalTable<> table;
  const char* lines[] = {"pages 0x40 0 8 0:8:le:0,2", "gx 0x40 0 8 8 8 le u 1 0 1 -",
                         "gy 0x40 0 8 16 8 le u 1 0 1 -", "gz 0x40 0 8 24 8 le u 1 0 1 -",
                         "ax 0x40 0 8 32 8 le u 1 0 1 -", "ay 0x40 0 8 40 8 le u 1 0 1 -",
                         "az 0x40 0 8 48 8 le u 1 0 1 -"};
  for (const char* l : lines) {
    SignalEntry e;
    PageSet p;
    const char* err = "";
    const LineResult r = parse_table_line(l, e, p, &err);
    REQUIRE(r != LineResult::kError);
    if (r == LineResult::kPages) REQUIRE(table.add_pages(p));
    else REQUIRE(table.add(e));
  }
  SignalSampleAssembler<> a(table);
  SignalSample s;
  int samples = 0;
  for (std::uint8_t k = 0; k < 110; ++k) {
    const std::uint8_t page = k < 100 ? static_cast<std::uint8_t>(2U * (k % 2U)) : (k % 2U ? 1U : 7U);
    if (a.push(frame(0x40, {page, k, 2, 3, 4, 5, 6, 0}), s)) {
      ++samples;
      CHECK(s.values[0] == static_cast<float>(k));
    }
  }
  a.finish();
  CHECK(samples == 100);
  CHECK(a.stats().undefined_page_frames == 10U);
  CHECK(a.stats().ignored_frames == 10U);
  check_accounting(a);
}

TEST_CASE("table lines whose signal cannot fit the frame are refused") {
  SignalEntry e;
  PageSet p;
  const char* err = "";
  // 32 bits from bit 0 in a 2-byte message; Motorola 16 bits ending past byte 3 of 4.
  CHECK(parse_signal_line("gx 0x10 0 2 0 32 le f32 1 0 1 -", e, &err) == LineResult::kError);
  CHECK(std::string(err).find("does not fit") != std::string::npos);
  CHECK(parse_signal_line("gx 0x10 0 4 31 16 be s 1 0 1 -", e, &err) == LineResult::kError);
  CHECK(parse_signal_line("gx 0x10 0 4 23 16 be s 1 0 1 -", e, &err) == LineResult::kEntry);
  CHECK(parse_signal_line("gx 0x10 0 2 0 8 le u 1 0 1 20:8:le:0", e, &err) == LineResult::kError);
  CHECK(parse_table_line("pages 0x10 0 2 16:8:le:0,1", e, p, &err) == LineResult::kError);
  CHECK(parse_table_line("pages 0x10 0 8 0:8:le:0,1 x", e, p, &err) == LineResult::kError);
  REQUIRE(parse_table_line("pages 0x10 0 8 0:4:be:3,5,9", e, p, &err) == LineResult::kPages);
  CHECK(p.n == 3U);
  CHECK(p.values[2] == 9U);
  // CAN FD lengths are not classic CAN: refused as a DLC.
  CHECK(parse_signal_line("gx 0x10 0 64 0 8 le u 1 0 1 -", e, &err) == LineResult::kError);
}
