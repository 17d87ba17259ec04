// CAN IMU frames: hand-checked bytes and reassembly by Seq with counted incompletes.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <array>
#include <cstdint>
#include <gyrodrift/codecs/can_frames.hpp>
#include <vector>

using namespace gyrodrift::can;

namespace {
std::array<CanFrame, 4> sample_frames(std::uint16_t seq, std::uint32_t base = kInputBaseId) {
  CanSample s;
  s.seq = seq;
  s.flags = 0;
  s.values = {1.0F, -2.0F, 0.5F, 0.0F, 2.0F, static_cast<float>(seq)};
  std::array<CanFrame, 4> f{};
  encode_sample(s, base, f);
  return f;
}

template <std::size_t S>
void check_accounting(const CanSampleAssembler<S>& a) {
  const auto& s = a.stats();
  CHECK(s.frames_in == s.foreign_frames + s.frames_used + s.frames_dropped + a.pending_frames());
}
}  // namespace

TEST_CASE("hand-checked frame bytes") {
  CanSample s;
  s.seq = 0x1234;
  s.flags = 0x0081;
  s.values = {1.0F, -2.0F, 0.5F, 0.0F, 2.0F, -1.0F};
  std::array<CanFrame, 4> f{};
  encode_sample(s, kOutputBaseId, f);
  const std::array<std::array<std::uint8_t, 8>, 4> expected = {{
      {0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0xC0},
      {0x00, 0x00, 0x00, 0x3F, 0x34, 0x12, 0x81, 0x00},
      {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x40},
      {0x00, 0x00, 0x80, 0xBF, 0x34, 0x12, 0x81, 0x00},
  }};
  for (std::size_t k = 0; k < 4; ++k) {
    CHECK(f[k].id == 0x180 + k);
    CHECK(f[k].dlc == 8);
    CHECK(f[k].data == expected[k]);
  }
}

TEST_CASE("reassembly: complete, lost, duplicated, foreign frames") {
  CanSampleAssembler<4> a;
  std::vector<CanFrame> in;
  auto add = [&in](const std::array<CanFrame, 4>& f, std::initializer_list<int> which) {
    for (int k : which) in.push_back(f[static_cast<std::size_t>(k)]);
  };
  add(sample_frames(0), {0, 1, 2, 3});
  add(sample_frames(1), {0, 2, 3});  // GyroZ lost
  add(sample_frames(2), {0, 1, 1, 2, 3});  // GyroZ duplicated
  add(sample_frames(3), {1, 2, 3});  // GyroXY lost
  CanFrame foreign;
  foreign.id = 0x300;
  foreign.dlc = 8;
  in.push_back(foreign);
  CanFrame shortf = sample_frames(9)[0];
  shortf.dlc = 6;
  in.push_back(shortf);
  add(sample_frames(4), {0, 1, 2, 3});
  add(sample_frames(4, kOutputBaseId), {0, 1, 2, 3});  // not ours: foreign
  add(sample_frames(5), {0, 1});  // half at end of stream
  std::vector<std::uint16_t> got;
  CanSample s;
  for (const auto& f : in) {
    if (a.push(f, s)) {
      got.push_back(s.seq);
      CHECK(s.values[5] == static_cast<float>(s.seq));
      CHECK(s.values[0] == 1.0F);
    }
  }
  a.finish();
  CHECK(got == std::vector<std::uint16_t>{0, 2, 4});
  const auto& st = a.stats();
  CHECK(st.complete_samples == 3);
  CHECK(st.incomplete_samples == 3);  // 1, 3, 5
  CHECK(st.duplicate_frames == 1);
  CHECK(st.foreign_frames == 5);
  CHECK(st.bad_dlc == 1);
  CHECK(st.orphan_frames == 2);  // sample 1's GyroXY, sample 3's GyroZ
  CHECK(a.pending_frames() == 0);
  check_accounting(a);
}

TEST_CASE("slot table full: oldest partial sample is evicted as incomplete") {
  CanSampleAssembler<2> a;
  CanSample s;
  for (std::uint16_t seq = 0; seq < 5; ++seq) {
    const auto f = sample_frames(seq);
    CHECK_FALSE(a.push(f[0], s));
    CHECK_FALSE(a.push(f[1], s));  // gyro halves only
  }
  CHECK(a.stats().incomplete_samples == 3);
  CHECK(a.pending_frames() == 4);
  check_accounting(a);
  const auto f4 = sample_frames(4);
  CHECK_FALSE(a.push(f4[2], s));
  CHECK(a.push(f4[3], s));
  CHECK(s.seq == 4);
  check_accounting(a);
}
