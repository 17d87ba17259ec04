// SLCAN: hand-written Lawicel lines both ways, commands and their replies, malformed lines.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <cstring>
#include <gyrodrift/codecs/slcan.hpp>
#include <string>
#include <vector>

using namespace gyrodrift;

namespace {
std::vector<slcan::Event> parse(const std::string& s, slcan::SlcanParser<>& p) {
  std::vector<slcan::Event> out;
  slcan::Event ev;
  for (char c : s) {
    if (p.push(static_cast<std::uint8_t>(c), ev)) out.push_back(ev);
  }
  return out;
}
std::string reply(const slcan::Event& ev) {
  char buf[16];
  const std::size_t n = slcan::command_reply(ev, buf, sizeof buf);
  return std::string(buf, n);
}
}  // namespace

TEST_CASE("encode standard, extended and remote frames") {
  can::CanFrame f;
  f.id = 0x101;
  f.dlc = 8;
  const std::uint8_t d[8] = {0x00, 0x00, 0x00, 0x3F, 0x34, 0x12, 0x81, 0x00};
  std::memcpy(f.data.data(), d, 8);
  char line[slcan::kMaxFrameLine];
  std::size_t n = slcan::encode_frame(f, line, sizeof line);
  CHECK(std::string(line, n) == "t10180000003F34128100\r");
  f.extended = true;
  f.id = 0x1ABCDEF0;
  f.dlc = 1;
  n = slcan::encode_frame(f, line, sizeof line);
  CHECK(std::string(line, n) == "T1ABCDEF0100\r");
  f.extended = false;
  f.remote = true;
  f.id = 0x7FF;
  f.dlc = 2;
  n = slcan::encode_frame(f, line, sizeof line);
  CHECK(std::string(line, n) == "r7FF2\r");
  f.remote = false;
  f.id = 0x800;  // not an 11-bit id
  CHECK(slcan::encode_frame(f, line, sizeof line) == 0);
  f.id = 0x100;
  f.dlc = 9;
  CHECK(slcan::encode_frame(f, line, sizeof line) == 0);
  f.dlc = 8;
  CHECK(slcan::encode_frame(f, line, 21) == 0);  // needs 22
}

TEST_CASE("parse frames and commands, reply like an adapter") {
  slcan::SlcanParser<> p;
  const auto ev = parse("C\rS6\rO\rt10180000003F34128100\rV\rT1ABCDEF0201A2\r\n", p);
  REQUIRE(ev.size() == 6);
  CHECK(ev[0].kind == slcan::EventKind::kCommand);
  CHECK(ev[0].command == 'C');
  CHECK(ev[1].command == 'S');
  CHECK(ev[1].arg_len == 1);
  CHECK(ev[1].arg[0] == '6');
  CHECK(reply(ev[1]) == "\r");
  CHECK(ev[3].kind == slcan::EventKind::kFrame);
  CHECK(ev[3].frame.id == 0x101);
  CHECK(ev[3].frame.dlc == 8);
  CHECK(ev[3].frame.data[3] == 0x3F);
  CHECK(ev[3].frame.data[6] == 0x81);
  CHECK(reply(ev[3]) == "z\r");
  CHECK(reply(ev[4]) == "V1013\r");
  CHECK(ev[5].frame.extended);
  CHECK(ev[5].frame.id == 0x1ABCDEF0);
  CHECK(reply(ev[5]) == "Z\r");
  CHECK(p.stats().frames == 2);
  CHECK(p.stats().commands == 4);
}

TEST_CASE("malformed and overlong lines give errors, parser recovers") {
  slcan::SlcanParser<> p;
  const std::string overlong = "t" + std::string(100, '1') + "\r";
  const auto ev = parse("t1013AABB\rt1G00\rS9\rQQQ\r" + overlong + "\at1000\r", p);
  REQUIRE(ev.size() == 6);
  CHECK(ev[0].kind == slcan::EventKind::kError);
  CHECK(ev[1].kind == slcan::EventKind::kError);
  CHECK(ev[2].kind == slcan::EventKind::kCommand);
  CHECK(reply(ev[2]) == "\a");  // S9: no such bitrate
  CHECK(ev[3].kind == slcan::EventKind::kCommand);  // Q with argument "QQ"
  CHECK(ev[4].kind == slcan::EventKind::kError);
  CHECK(reply(ev[4]) == "\a");
  CHECK(ev[5].kind == slcan::EventKind::kFrame);
  CHECK(ev[5].frame.id == 0x100);
  CHECK(p.stats().malformed == 2);
  CHECK(p.stats().overlong == 1);
  CHECK(p.stats().bells == 1);
}
