// Fuzz test for the frame parsers, built with AddressSanitizer + UBSan (GYRODRIFT_SANITIZE=ON):
// random bytes, truncated and corrupted frames through the serial parser, random and mutated
// CAN frames through the sample assembler, random and mutated lines through the SLCAN parser.
// Parsers live on the heap with their buffer as the last member, and inputs are exact-size
// heap vectors, so a read or write outside any buffer is an ASan error. Deterministic seeds,
// bounded work (a few MB in total, well under a second unsanitised).
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cstdint>
#include <gyrodrift/codecs/can_frames.hpp>
#include <gyrodrift/codecs/serial_frame.hpp>
#include <gyrodrift/codecs/slcan.hpp>
#include <memory>
#include <random>
#include <vector>

using namespace gyrodrift;

namespace {

std::vector<std::uint8_t> serial_stream(std::mt19937& gen, std::size_t frames) {
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> action(0, 9);
  std::uniform_real_distribution<float> value(-1e3F, 1e3F);
  std::vector<std::uint8_t> out;
  std::uint8_t buf[serial::kFrameSize];
  for (std::size_t k = 0; k < frames; ++k) {
    serial::ImuFrame f;
    f.type = (k % 2 == 0) ? serial::kTypeInput : serial::kTypeOutput;
    f.seq = static_cast<std::uint16_t>(k);
    f.t_us = 2500ULL * k;
    for (auto& v : f.values) v = value(gen);
    serial::encode_frame(f, buf, sizeof buf);
    std::size_t len = serial::kFrameSize;
    switch (action(gen)) {
      case 0: len = static_cast<std::size_t>(byte(gen)) % serial::kFrameSize; break;  // truncated
      case 1: buf[static_cast<std::size_t>(byte(gen)) % serial::kFrameSize] ^= static_cast<std::uint8_t>(1 + byte(gen) % 255); break;
      case 2: buf[3] = static_cast<std::uint8_t>(byte(gen)); break;  // length byte
      case 3:
        for (int i = 0, n = byte(gen); i < n; ++i) out.push_back(static_cast<std::uint8_t>(byte(gen)));
        break;
      case 4:  // sync words only
        for (int i = 0, n = byte(gen) % 8; i < n; ++i) {
          out.push_back(serial::kSync0);
          out.push_back(serial::kSync1);
        }
        break;
      default: break;
    }
    out.insert(out.end(), buf, buf + len);
  }
  return out;
}

}  // namespace

TEST_CASE("serial parser: random and damaged streams, all chunk sizes") {
  for (unsigned seed = 1; seed <= 8; ++seed) {
    std::mt19937 gen(seed);
    std::vector<std::uint8_t> data = serial_stream(gen, 4000);
    // pure random bytes too
    std::uniform_int_distribution<int> byte(0, 255);
    for (int i = 0; i < 50000; ++i) data.push_back(static_cast<std::uint8_t>(byte(gen)));
    auto parser = std::make_unique<serial::SerialFrameParser<128>>();
    std::uniform_int_distribution<std::size_t> chunk(1, 300);
    std::size_t pos = 0;
    serial::ImuFrame f;
    std::uint64_t frames = 0;
    while (pos < data.size()) {
      const std::size_t want = std::min(chunk(gen), data.size() - pos);
      // copy into an exact-size heap block: reading past `want` is an ASan error
      std::vector<std::uint8_t> block(data.begin() + static_cast<std::ptrdiff_t>(pos),
                                      data.begin() + static_cast<std::ptrdiff_t>(pos + want));
      pos += parser->feed(block.data(), block.size());
      while (parser->next(f)) {
        ++frames;
        REQUIRE((f.type == serial::kTypeInput || f.type == serial::kTypeOutput));
      }
      REQUIRE(parser->buffered() <= parser->capacity());
    }
    parser->finish();
    const auto& s = parser->stats();
    CHECK(s.frames_ok == frames);
    CHECK(frames > 2000);  // most frames were left intact
    CHECK(s.bytes_in == data.size());
    CHECK(s.bytes_in == serial::kFrameSize * s.frames_ok + s.discarded_bytes + parser->buffered());
  }
}

TEST_CASE("CAN assembler: random, mutated, reordered frames") {
  for (unsigned seed = 1; seed <= 8; ++seed) {
    std::mt19937 gen(seed);
    std::uniform_int_distribution<int> byte(0, 255);
    std::uniform_int_distribution<int> action(0, 9);
    auto asm_in = std::make_unique<can::CanSampleAssembler<4>>(can::kInputBaseId);
    can::CanSample out;
    std::uint64_t complete = 0;
    for (std::uint32_t k = 0; k < 20000; ++k) {
      can::CanSample s;
      s.seq = static_cast<std::uint16_t>(k);
      std::array<can::CanFrame, 4> frames{};
      can::encode_sample(s, can::kInputBaseId, frames);
      for (auto& fr : frames) {
        switch (action(gen)) {
          case 0: continue;  // lost
          case 1: fr.dlc = static_cast<std::uint8_t>(byte(gen)); break;  // any dlc, even > 8
          case 2: fr.id = static_cast<std::uint32_t>(0xFC + byte(gen) % 12); break;
          case 3: fr.data[static_cast<std::size_t>(byte(gen) % 8)] = static_cast<std::uint8_t>(byte(gen)); break;
          case 4: fr.extended = true; break;
          default: break;
        }
        if (asm_in->push(fr, out)) ++complete;
        if (action(gen) == 0 && asm_in->push(fr, out)) ++complete;  // duplicate
      }
    }
    asm_in->finish();
    const auto& st = asm_in->stats();
    CHECK(st.complete_samples == complete);
    CHECK(st.frames_in == st.foreign_frames + st.frames_used + st.frames_dropped + asm_in->pending_frames());
    CHECK(asm_in->pending_frames() == 0);
  }
}

TEST_CASE("SLCAN parser: random bytes and mutated lines") {
  for (unsigned seed = 1; seed <= 8; ++seed) {
    std::mt19937 gen(seed);
    std::uniform_int_distribution<int> byte(0, 255);
    std::uniform_int_distribution<int> action(0, 9);
    std::vector<std::uint8_t> data;
    char line[slcan::kMaxFrameLine];
    for (std::uint32_t k = 0; k < 20000; ++k) {
      can::CanFrame fr;
      fr.id = static_cast<std::uint32_t>(byte(gen) * 8) & 0x7FFU;
      fr.dlc = static_cast<std::uint8_t>(byte(gen) % 9);
      fr.extended = action(gen) == 0;
      for (auto& d : fr.data) d = static_cast<std::uint8_t>(byte(gen));
      const std::size_t n = slcan::encode_frame(fr, line, sizeof line);
      REQUIRE(n > 0);
      std::vector<std::uint8_t> l(line, line + n);
      switch (action(gen)) {
        case 0: l.resize(static_cast<std::size_t>(byte(gen)) % n); break;
        case 1: l[static_cast<std::size_t>(byte(gen)) % n] = static_cast<std::uint8_t>(byte(gen)); break;
        case 2: l.insert(l.begin(), 40, 'f'); break;  // overlong
        case 3:
          for (int i = 0; i < 30; ++i) l.push_back(static_cast<std::uint8_t>(byte(gen)));
          break;
        default: break;
      }
      data.insert(data.end(), l.begin(), l.end());
    }
    auto parser = std::make_unique<slcan::SlcanParser<>>();
    slcan::Event ev;
    char reply[16];
    std::uint64_t events = 0;
    for (std::uint8_t b : data) {
      if (parser->push(b, ev)) {
        ++events;
        REQUIRE(slcan::command_reply(ev, reply, sizeof reply) > 0);
        if (ev.kind == slcan::EventKind::kFrame) REQUIRE(ev.frame.dlc <= 8);
      }
      REQUIRE(parser->buffered() <= slcan::kMaxFrameLine);
    }
    const auto& st = parser->stats();
    CHECK(st.bytes_in == data.size());
    CHECK(st.lines == events);
    CHECK(st.lines == st.frames + st.commands + st.malformed + st.overlong);
    CHECK(st.frames > 10000);
  }
}
