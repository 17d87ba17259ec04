// CAN encoding of one IMU sample (classic CAN, 11-bit IDs, 8-byte frames; the DBC file
// python/gyrodrift/data/gyrodrift_imu.dbc describes the same layout for cantools):
//   base+0 GyroXY : GyroX f32 @0, GyroY f32 @4            (rad/s)
//   base+1 GyroZ  : GyroZ f32 @0, Seq u16 @4, Flags u16 @6
//   base+2 AccelXY: AccelX f32 @0, AccelY f32 @4          (m/s^2)
//   base+3 AccelZ : AccelZ f32 @0, Seq u16 @4, Flags u16 @6
// base = 0x100 for input samples, 0x180 for filtered output. All little-endian (Intel).
//
// Reassembly: an XY frame carries no Seq, so it binds to the next Z frame of the same
// half (the transmitter sends base+0..base+3 in order and CAN keeps one sender's order).
// Halves are joined by Seq in a small fixed slot table. Every frame is accounted for:
//   frames_in == foreign_frames + frames_used + frames_dropped + pending_frames()
// and each sample that lost a frame is counted once in incomplete_samples ("can_incomplete").
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>

#include "serial_frame.hpp"  // little-endian helpers

namespace gyrodrift::can {

inline constexpr std::uint32_t kInputBaseId = 0x100U;
inline constexpr std::uint32_t kOutputBaseId = 0x180U;
inline constexpr std::size_t kFramesPerSample = 4U;
inline constexpr std::uint8_t kImuDlc = 8U;

struct CanFrame {
  std::uint32_t id = 0;  // 11-bit (standard) or 29-bit (extended)
  std::uint8_t dlc = 0;  // 0..8
  bool extended = false;
  bool remote = false;
  std::array<std::uint8_t, 8> data{};
};

// values = gyro x y z (rad/s), accel x y z (m/s^2)
struct CanSample {
  std::uint16_t seq = 0;
  std::uint16_t flags = 0;
  std::array<float, 6> values{};
};

enum class Role : std::uint8_t { kGyroXY = 0, kGyroZ = 1, kAccelXY = 2, kAccelZ = 3 };

// The four frames of one sample, in transmit order.
inline void encode_sample(const CanSample& s, std::uint32_t base_id,
                          std::array<CanFrame, kFramesPerSample>& out) noexcept {
  namespace d = serial::detail;
  for (std::size_t k = 0; k < kFramesPerSample; ++k) {
    out[k] = CanFrame{};
    out[k].id = base_id + static_cast<std::uint32_t>(k);
    out[k].dlc = kImuDlc;
  }
  d::put_u32(out[0].data.data(), d::float_bits(s.values[0]));
  d::put_u32(out[0].data.data() + 4, d::float_bits(s.values[1]));
  d::put_u32(out[1].data.data(), d::float_bits(s.values[2]));
  d::put_u16(out[1].data.data() + 4, s.seq);
  d::put_u16(out[1].data.data() + 6, s.flags);
  d::put_u32(out[2].data.data(), d::float_bits(s.values[3]));
  d::put_u32(out[2].data.data() + 4, d::float_bits(s.values[4]));
  d::put_u32(out[3].data.data(), d::float_bits(s.values[5]));
  d::put_u16(out[3].data.data() + 4, s.seq);
  d::put_u16(out[3].data.data() + 6, s.flags);
}

struct CanRxStats {
  std::uint64_t frames_in = 0;
  std::uint64_t frames_used = 0;         // 4 per complete sample
  std::uint64_t frames_dropped = 0;      // all reasons below + frames of incomplete samples
  std::uint64_t foreign_frames = 0;      // other IDs, extended or remote frames (not ours)
  std::uint64_t bad_dlc = 0;             // our ID with dlc != 8
  std::uint64_t orphan_frames = 0;       // XY replaced before its Z arrived, or Z without its XY
  std::uint64_t duplicate_frames = 0;    // a half that was already present for this Seq
  std::uint64_t complete_samples = 0;
  std::uint64_t incomplete_samples = 0;  // reason "can_incomplete"
};

// Slots: samples (Seqs) that can be in flight at once; a sample pushed out of the table
// before both halves arrived counts as incomplete.
template <std::size_t Slots = 4>
class CanSampleAssembler {
  static_assert(Slots >= 1, "need at least one slot");

 public:
  explicit CanSampleAssembler(std::uint32_t base_id = kInputBaseId) noexcept : base_id_(base_id) {}

  // Returns true (and fills out) when this frame completed a sample.
  bool push(const CanFrame& f, CanSample& out) noexcept {
    ++stats_.frames_in;
    if (f.extended || f.remote || f.id < base_id_ || f.id >= base_id_ + kFramesPerSample) {
      ++stats_.foreign_frames;
      return false;
    }
    if (f.dlc != kImuDlc) {
      ++stats_.bad_dlc;
      ++stats_.frames_dropped;
      return false;
    }
    namespace d = serial::detail;
    const auto role = static_cast<std::size_t>(f.id - base_id_);
    const std::size_t half = role / 2;  // 0 gyro, 1 accel
    if (role % 2 == 0) {                // XY frame: hold until its Z arrives
      Pending& pend = pending_[half];
      if (pend.valid) {
        ++stats_.orphan_frames;
        ++stats_.frames_dropped;
      }
      pend.valid = true;
      pend.x = d::bits_float(d::get_u32(f.data.data()));
      pend.y = d::bits_float(d::get_u32(f.data.data() + 4));
      return false;
    }
    // Z frame: carries Seq and Flags.
    Pending& pend = pending_[half];
    const std::uint16_t seq = d::get_u16(f.data.data() + 4);
    const std::uint16_t flags = d::get_u16(f.data.data() + 6);
    Slot* slot = find(seq);
    if (slot != nullptr && slot->state[half] != kEmpty) {
      const std::uint64_t n = pend.valid ? 2U : 1U;
      stats_.duplicate_frames += n;
      stats_.frames_dropped += n;
      pend.valid = false;
      return false;
    }
    if (slot == nullptr) slot = allocate(seq);
    if (pend.valid) {
      slot->state[half] = kOk;
      slot->held += 2;
      slot->values[3 * half + 0] = pend.x;
      slot->values[3 * half + 1] = pend.y;
      slot->values[3 * half + 2] = d::bits_float(d::get_u32(f.data.data()));
      slot->flags = static_cast<std::uint16_t>(slot->flags | flags);
    } else {
      slot->state[half] = kBroken;
      slot->held += 1;
      ++stats_.orphan_frames;
    }
    pend.valid = false;
    if (slot->state[0] == kEmpty || slot->state[1] == kEmpty) return false;
    if (slot->state[0] == kOk && slot->state[1] == kOk) {
      out.seq = slot->seq;
      out.flags = slot->flags;
      out.values = slot->values;
      stats_.frames_used += kFramesPerSample;
      ++stats_.complete_samples;
      slot->used = false;
      return true;
    }
    drop(*slot);
    return false;
  }

  // End of stream: every partial sample and held XY frame is counted as dropped.
  void finish() noexcept {
    for (Slot& s : slots_) {
      if (s.used) drop(s);
    }
    for (Pending& p : pending_) {
      if (p.valid) {
        ++stats_.orphan_frames;
        ++stats_.frames_dropped;
        p.valid = false;
      }
    }
  }

  std::uint64_t pending_frames() const noexcept {
    std::uint64_t n = 0;
    for (const Slot& s : slots_) n += s.used ? s.held : 0U;
    for (const Pending& p : pending_) n += p.valid ? 1U : 0U;
    return n;
  }

  void reset() noexcept {
    slots_ = {};
    pending_ = {};
    stats_ = CanRxStats{};
    order_ = 0;
  }

  const CanRxStats& stats() const noexcept { return stats_; }
  std::uint32_t base_id() const noexcept { return base_id_; }

 private:
  enum : std::uint8_t { kEmpty = 0, kOk = 1, kBroken = 2 };
  struct Slot {
    bool used = false;
    std::uint16_t seq = 0;
    std::uint16_t flags = 0;
    std::array<std::uint8_t, 2> state{};
    std::uint8_t held = 0;  // frames of this sample held here
    std::uint64_t order = 0;
    std::array<float, 6> values{};
  };
  struct Pending {
    bool valid = false;
    float x = 0.0F;
    float y = 0.0F;
  };

  Slot* find(std::uint16_t seq) noexcept {
    for (Slot& s : slots_) {
      if (s.used && s.seq == seq) return &s;
    }
    return nullptr;
  }

  Slot* allocate(std::uint16_t seq) noexcept {
    Slot* victim = &slots_[0];
    for (Slot& s : slots_) {
      if (!s.used) {
        victim = &s;
        break;
      }
      if (s.order < victim->order) victim = &s;
    }
    if (victim->used) drop(*victim);
    *victim = Slot{};
    victim->used = true;
    victim->seq = seq;
    victim->order = order_++;
    return victim;
  }

  void drop(Slot& s) noexcept {
    ++stats_.incomplete_samples;
    stats_.frames_dropped += s.held;
    s.used = false;
  }

  std::uint32_t base_id_;
  std::array<Slot, Slots> slots_{};
  std::array<Pending, 2> pending_{};
  CanRxStats stats_{};
  std::uint64_t order_ = 0;
};

}  // namespace gyrodrift::can
