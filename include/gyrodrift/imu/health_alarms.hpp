// Health alarms for one gyro channel: its streaming Allan variance leaves the reference model's
// interval (angle random walk up, bias instability up, rate random walk up), or the channel is
// stuck or saturating for too long. Alarms are latched (stay raised until reset()), counted, and
// keep the statistic that tripped them.
//
// INTERFACE SKELETON: update() is not implemented yet (no alarm is ever raised). The public
// names and meanings are fixed; the implementation replaces the bodies.
//
// The reference is the expected Allan variance at each octave of the streaming curve (from the
// configured drift model, or learned from the first part of a record), so one alarm logic
// serves both. Allocation-free, noexcept, templated on Scalar.
#pragma once

#include <cstddef>
#include <cstdint>

#include "../stability/streaming_allan.hpp"

namespace gyrodrift {

inline constexpr std::uint16_t kAlarmArwHigh = 1U << 0;              // short-tau Allan variance up
inline constexpr std::uint16_t kAlarmBiasInstabilityHigh = 1U << 1;  // Allan variance near the minimum up
inline constexpr std::uint16_t kAlarmRateRandomWalkHigh = 1U << 2;   // long-tau Allan variance up
inline constexpr std::uint16_t kAlarmStuck = 1U << 3;                // stuck longer than allowed
inline constexpr std::uint16_t kAlarmSaturated = 1U << 4;            // saturated longer than allowed

struct HealthAlarmName {
  std::uint16_t bit;
  const char* name;
};
inline constexpr HealthAlarmName kHealthAlarmNames[] = {
    {kAlarmArwHigh, "arw_high"},
    {kAlarmBiasInstabilityHigh, "bias_instability_high"},
    {kAlarmRateRandomWalkHigh, "rate_random_walk_high"},
    {kAlarmStuck, "stuck"},
    {kAlarmSaturated, "saturated"},
};
inline constexpr std::size_t kHealthAlarmCount = sizeof(kHealthAlarmNames) / sizeof(kHealthAlarmNames[0]);

template <class Scalar, std::size_t Octaves>
struct HealthReference {
  Scalar avar[Octaves] = {};  // expected Allan variance at octave k (tau = 2^k / rate), channel units^2
  std::size_t octaves = 0;    // number of valid entries
};

template <class Scalar>
struct HealthAlarmSettings {
  Scalar arw_factor = Scalar(2);               // alarm when N is up by more than this factor
  Scalar bias_instability_factor = Scalar(2);  // ... B up by more than this factor
  Scalar rate_random_walk_factor = Scalar(2);  // ... K up by more than this factor
  Scalar false_alarm_probability = Scalar(1e-6);  // per check and octave, for the chi-square bound
  std::uint32_t stuck_samples = 0;      // 0: off; stuck for this many samples in a row raises stuck
  std::uint32_t saturated_samples = 0;  // 0: off; saturated this many samples in a row raises saturated
};

// What tripped an alarm (the first time it was raised).
template <class Scalar>
struct HealthTrip {
  Scalar statistic = Scalar(0);  // e.g. measured / expected Allan deviation, or samples in a row
  Scalar threshold = Scalar(0);  // the value it exceeded
  Scalar tau_s = Scalar(0);      // averaging time of the octave (0 for stuck/saturated)
  std::uint64_t sample = 0;      // sample count when it tripped
};

template <class Scalar, std::size_t Octaves>
class HealthAlarms {
 public:
  bool configure(const HealthReference<Scalar, Octaves>& ref, const HealthAlarmSettings<Scalar>& s) noexcept {
    ref_ = ref;
    settings_ = s;
    reset();
    return true;
  }
  void reset() noexcept {
    latched_ = 0;
    for (std::size_t i = 0; i < kHealthAlarmCount; ++i) {
      raised_[i] = 0;
      trip_[i] = HealthTrip<Scalar>{};
    }
  }
  // Once per sample, after the sample went into `allan`. Returns the latched alarm bits.
  std::uint16_t update(const StreamingAllan<Scalar, Octaves>& allan, bool stuck, bool saturated) noexcept {
    (void)allan;
    (void)stuck;
    (void)saturated;
    return latched_;
  }
  std::uint16_t latched() const noexcept { return latched_; }
  // Times alarm i (index into kHealthAlarmNames) was raised since reset (0 or 1 while latched).
  std::uint32_t raised(std::size_t i) const noexcept { return i < kHealthAlarmCount ? raised_[i] : 0; }
  const HealthTrip<Scalar>& trip(std::size_t i) const noexcept { return trip_[i < kHealthAlarmCount ? i : 0]; }

 private:
  HealthReference<Scalar, Octaves> ref_{};
  HealthAlarmSettings<Scalar> settings_{};
  std::uint16_t latched_ = 0;
  std::uint32_t raised_[kHealthAlarmCount] = {};
  HealthTrip<Scalar> trip_[kHealthAlarmCount] = {};
};

}  // namespace gyrodrift
