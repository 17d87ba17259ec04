// Serial IMU frame: CRC check value, a hand-written frame, parser resynchronisation and the
// byte accounting invariant, including a buffer that fills up.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <array>
#include <cstdint>
#include <gyrodrift/codecs/crc16.hpp>
#include <gyrodrift/codecs/serial_frame.hpp>
#include <vector>

using namespace gyrodrift;
using serial::ImuFrame;

namespace {

std::vector<std::uint8_t> encode(const ImuFrame& f) {
  std::vector<std::uint8_t> b(serial::kFrameSize);
  REQUIRE(serial::encode_frame(f, b.data(), b.size()) == serial::kFrameSize);
  return b;
}

ImuFrame frame(std::uint16_t seq) {
  ImuFrame f;
  f.seq = seq;
  f.t_us = 1000000ULL + 2500ULL * seq;
  for (std::size_t c = 0; c < 6; ++c) f.values[c] = 0.25F * static_cast<float>(c) - static_cast<float>(seq);
  return f;
}

template <std::size_t Cap>
std::vector<ImuFrame> parse_all(serial::SerialFrameParser<Cap>& p, const std::vector<std::uint8_t>& bytes,
                                std::size_t chunk) {
  std::vector<ImuFrame> out;
  ImuFrame f;
  std::size_t pos = 0;
  while (pos < bytes.size()) {
    const std::size_t want = std::min(chunk, bytes.size() - pos);
    pos += p.feed(bytes.data() + pos, want);
    while (p.next(f)) out.push_back(f);
  }
  p.finish();
  return out;
}

template <std::size_t Cap>
void check_accounting(const serial::SerialFrameParser<Cap>& p) {
  const auto& s = p.stats();
  CHECK(s.bytes_in == serial::kFrameSize * s.frames_ok + s.discarded_bytes + p.buffered());
}

}  // namespace

TEST_CASE("CRC-16/CCITT-FALSE check value") {
  const std::uint8_t msg[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  CHECK(crc16_ccitt_false(msg, sizeof msg) == 0x29B1);
  // chaining two blocks equals one pass
  CHECK(crc16_ccitt_false(msg + 4, 5, crc16_ccitt_false(msg, 4)) == 0x29B1);
  CHECK(crc16_ccitt_false(msg, 0) == 0xFFFF);
}

TEST_CASE("hand-written frame") {
  // seq 0x0102, flags 0, t_us 0x0000000102030405, values 1, -2, 0.5, 0, 2, -1 (float32 LE)
  const std::array<std::uint8_t, 40> body = {
      0xA5, 0x5A, 0x01, 0x24, 0x02, 0x01, 0x00, 0x00, 0x05, 0x04, 0x03, 0x02, 0x01, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0xC0, 0x00, 0x00, 0x00, 0x3F,
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x80, 0xBF};
  ImuFrame f;
  f.seq = 0x0102;
  f.t_us = 0x0000000102030405ULL;
  f.values = {1.0F, -2.0F, 0.5F, 0.0F, 2.0F, -1.0F};
  const auto b = encode(f);
  for (std::size_t i = 0; i < body.size(); ++i) CHECK(b[i] == body[i]);
  const std::uint16_t crc = crc16_ccitt_false(body.data() + 2, 38);  // checked above
  CHECK(b[40] == (crc & 0xFF));
  CHECK(b[41] == (crc >> 8));
  ImuFrame g;
  REQUIRE(serial::decode_frame(b.data(), b.size(), g) == serial::DecodeStatus::kOk);
  CHECK(g.seq == 0x0102);
  CHECK(g.t_us == 0x0000000102030405ULL);
  CHECK(g.values == f.values);
  CHECK(serial::encode_frame(f, nullptr, 42) == 0);
  std::array<std::uint8_t, 41> small{};
  CHECK(serial::encode_frame(f, small.data(), small.size()) == 0);
  CHECK(serial::decode_frame(b.data(), 41, g) == serial::DecodeStatus::kTooShort);
}

TEST_CASE("parser: garbage, corrupted, truncated and bad-header frames are counted and skipped") {
  std::vector<std::uint8_t> s = {0x00, 0xA5, 0x13, 0x5A};  // garbage
  auto append = [&s](const std::vector<std::uint8_t>& b) { s.insert(s.end(), b.begin(), b.end()); };
  append(encode(frame(1)));
  auto cut = encode(frame(2));
  cut.resize(20);
  append(cut);  // truncated: next frame starts inside
  append(encode(frame(2)));
  auto bad = encode(frame(3));
  bad[25] ^= 0x10;
  append(bad);  // corrupted
  append(encode(frame(4)));
  auto hdr = encode(frame(5));
  hdr[3] = 35;
  append(hdr);  // bad len
  append(encode(frame(6)));
  for (std::size_t chunk : {std::size_t{1}, std::size_t{5}, std::size_t{42}, std::size_t{1000}}) {
    serial::SerialFrameParser<96> p;  // small buffer: feed() takes partial chunks
    const auto frames = parse_all(p, s, chunk);
    REQUIRE(frames.size() == 4);
    CHECK(frames[0].seq == 1);
    CHECK(frames[1].seq == 2);
    CHECK(frames[2].seq == 4);
    CHECK(frames[3].seq == 6);
    CHECK(frames[3].values == frame(6).values);
    CHECK(p.stats().crc_errors == 1);
    CHECK(p.stats().truncated == 1);
    CHECK(p.stats().bad_header == 1);
    CHECK(p.stats().garbage_bytes >= 4);
    check_accounting(p);
    CHECK(p.buffered() == 0);
  }
}

TEST_CASE("parser: feed refuses bytes beyond capacity and counts them") {
  serial::SerialFrameParser<84> p;
  std::vector<std::uint8_t> s;
  for (std::uint16_t k = 0; k < 3; ++k) {
    const auto b = encode(frame(k));
    s.insert(s.end(), b.begin(), b.end());
  }
  CHECK(p.feed(s.data(), s.size()) == 84);
  CHECK(p.stats().overflow_bytes == 42);
  ImuFrame f;
  CHECK(p.next(f));
  CHECK(p.next(f));
  CHECK_FALSE(p.next(f));
  CHECK(p.feed(s.data() + 84, 42) == 42);
  CHECK(p.next(f));
  CHECK(f.seq == 2);
  check_accounting(p);
  CHECK(p.feed(nullptr, 10) == 0);
}

TEST_CASE("parser: a frame cut short by any number of bytes loses only itself") {
  for (std::size_t kept = 1; kept < serial::kFrameSize; ++kept) {
    std::vector<std::uint8_t> s;
    auto append = [&s](const std::vector<std::uint8_t>& b) { s.insert(s.end(), b.begin(), b.end()); };
    append(encode(frame(0)));
    auto cut = encode(frame(1));
    cut.resize(kept);
    append(cut);
    append(encode(frame(2)));
    append(encode(frame(3)));
    for (std::size_t chunk : {std::size_t{1}, std::size_t{7}, std::size_t{42}, std::size_t{1000}}) {
      serial::SerialFrameParser<96> p;
      const auto frames = parse_all(p, s, chunk);
      CAPTURE(kept);
      CAPTURE(chunk);
      REQUIRE(frames.size() == 3);
      CHECK(frames[0].seq == 0);
      CHECK(frames[1].seq == 2);
      CHECK(frames[2].seq == 3);
      // 1..3 bytes cannot hold a header: hunted over / a bad header, not a cut frame
      CHECK(p.stats().truncated == (kept >= 4 ? 1U : 0U));
      CHECK(p.stats().crc_errors == 0);
      check_accounting(p);
    }
  }
}

TEST_CASE("health request and report frames are valid frames; other types are bad headers") {
  std::vector<std::uint8_t> s;
  for (const std::uint8_t type : {serial::kTypeHealthRequest, serial::kTypeHealthReport, std::uint8_t{0x03}}) {
    ImuFrame f = frame(7);
    f.type = type;
    const auto b = encode(f);  // any type, with a matching CRC: only 0x03 is refused
    s.insert(s.end(), b.begin(), b.end());
  }
  serial::SerialFrameParser<256> p;
  const auto frames = parse_all(p, s, 42);
  REQUIRE(frames.size() == 2);
  CHECK(frames[0].type == serial::kTypeHealthRequest);
  CHECK(frames[1].type == serial::kTypeHealthReport);
  CHECK(frames[1].t_us == frame(7).t_us);
  CHECK(p.stats().bad_header == 1);
  check_accounting(p);
}
