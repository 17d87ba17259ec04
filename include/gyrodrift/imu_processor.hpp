// Six-channel IMU processor (3 gyro + 3 accelerometer) for a fixed-rate navigation loop.
//
// Per channel c (chosen at construction):
//   pass_through:  y = x
//   bias_removal:  y = x - bias
//   ar2_kalman:    y = Ar2Kalman(x) - bias   (paper 000 sec. 2.2 / paper 002 sec. 3; model and
//                  q, r identified offline, e.g. with fit_ar2; the model mean is kept in the
//                  filter output, so bias is normally 0 here)
//   wavelet:       y = Wavelet(x) - bias     (real-time sliding-window prefilter, paper 004
//                  sec. 2.2; any type with step(Scalar), reset(), status() plugs in, see below)
// Gyros default to ar2_kalman (their model must be supplied: an unset model makes status()
// report bad_channel_config), accelerometers to pass_through.
//
// One step(sample, out) per tick: allocation-free, noexcept, deterministic (no clocks, no
// random numbers, fixed operation order), so the same input gives bit-identical output.
//
// Health (every counter is cumulative; the per-sample flags go into the output frame):
//   * sequence: seq == last accepted seq -> duplicate, rejected; seq behind the last one
//     (u16 difference >= 32768) -> out_of_order, rejected; a forward jump > 1 -> seq gap
//     (missing_samples += jump - 1), accepted. Rejected frames never reach the filters.
//     After kResyncAfter consecutive rejections the source is assumed to have restarted:
//     the next frame is accepted (counted in seq_resyncs).
//   * timestamp: |dt_us - jump * period_us| > time_tolerance_us -> time_jump (flag only).
//   * per value: NaN/Inf, saturation (|x| >= saturation), stuck channel (the same value
//     stuck_samples times in a row). Such a value is a missing measurement for its channel:
//     the Kalman filter does a predict-only step, the wavelet window skips it, pass-through
//     and bias channels hold their last output. Filter state never sees the bad value.
//   * filter_faults: a good value the channel's filter refused (a Kalman update with a
//     non-finite result, or a value beyond the filters' input range, input_range.hpp), or
//     a channel output that would not be finite (e.g. x - bias overflowing); the channel
//     then holds its last output. Every output value is finite or this counter moved.
// A processor whose configuration is invalid (status() != ok) rejects every sample with
// kFlagConfigError, rather than passing data through silently.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "ar2_kalman.hpp"
#include "ar2_model.hpp"

namespace gyrodrift {

enum class ChannelFilter : std::uint8_t { pass_through = 0, bias_removal = 1, ar2_kalman = 2, wavelet = 3 };

inline constexpr std::size_t kImuChannels = 6;  // gyro x y z (rad/s), accel x y z (m/s^2)

// Per-sample health flags (u16, the `flags` field of output frames).
inline constexpr std::uint16_t kFlagNonFinite = 1U << 0;   // a channel value was NaN/Inf
inline constexpr std::uint16_t kFlagSaturated = 1U << 1;   // a channel at its saturation limit
inline constexpr std::uint16_t kFlagStuck = 1U << 2;       // a channel stuck (repeated value)
inline constexpr std::uint16_t kFlagSeqGap = 1U << 3;      // samples missing before this one
inline constexpr std::uint16_t kFlagDuplicate = 1U << 4;   // seq repeated (rejected)
inline constexpr std::uint16_t kFlagOutOfOrder = 1U << 5;  // seq went backwards (rejected)
inline constexpr std::uint16_t kFlagTimeJump = 1U << 6;    // timestamp off the nominal grid
inline constexpr std::uint16_t kFlagFilterFault = 1U << 7; // a filter rejected its update
inline constexpr std::uint16_t kFlagResync = 1U << 8;      // accepted after kResyncAfter rejections
inline constexpr std::uint16_t kFlagConfigError = 1U << 14; // processor not configured (rejected)
inline constexpr std::uint16_t kFlagRejected = 1U << 15;   // no output for this input

template <class Scalar>
struct ImuChannelConfig {
  ChannelFilter filter = ChannelFilter::pass_through;
  Scalar bias = Scalar(0);  // units of the channel (rad/s or m/s^2), subtracted after the filter
  // ar2_kalman: model, process noise q and measurement noise r (units^2), P_0 = p0 I.
  Ar2Model<Scalar> model{std::numeric_limits<Scalar>::quiet_NaN(), std::numeric_limits<Scalar>::quiet_NaN(),
                         std::numeric_limits<Scalar>::quiet_NaN(), std::numeric_limits<Scalar>::quiet_NaN()};
  Scalar q = std::numeric_limits<Scalar>::quiet_NaN();
  Scalar r = std::numeric_limits<Scalar>::quiet_NaN();
  Scalar p0 = Scalar(1);
  Scalar saturation = std::numeric_limits<Scalar>::infinity();  // |x| >= saturation: saturated
  std::uint32_t stuck_samples = 0;  // 0: off; N: the N-th identical value in a row is stuck
};

template <class Scalar>
struct ImuConfig {
  std::array<ImuChannelConfig<Scalar>, kImuChannels> channels = default_channels();
  std::uint32_t period_us = 2500;          // nominal sample period (400 Hz)
  std::uint32_t time_tolerance_us = 1250;  // 0: timestamp check off

  static std::array<ImuChannelConfig<Scalar>, kImuChannels> default_channels() noexcept {
    std::array<ImuChannelConfig<Scalar>, kImuChannels> ch{};
    for (std::size_t c = 0; c < 3; ++c) ch[c].filter = ChannelFilter::ar2_kalman;
    return ch;
  }
};

template <class Scalar>
struct ImuSample {
  std::uint16_t seq = 0;
  std::uint64_t t_us = 0;
  std::array<Scalar, kImuChannels> values{};
};

template <class Scalar>
struct ImuOutput {
  std::uint16_t seq = 0;
  std::uint16_t flags = 0;
  std::uint64_t t_us = 0;
  std::array<Scalar, kImuChannels> values{};
};

struct ImuHealth {
  std::uint64_t samples_in = 0;
  std::uint64_t samples_accepted = 0;
  std::uint64_t duplicates = 0;       // rejected
  std::uint64_t out_of_order = 0;     // rejected
  std::uint64_t config_rejected = 0;  // rejected: processor not configured
  std::uint64_t seq_gaps = 0;         // gap events
  std::uint64_t missing_samples = 0;  // sum over gaps of (jump - 1)
  std::uint64_t seq_resyncs = 0;
  std::uint64_t time_jumps = 0;
  std::uint64_t non_finite_samples = 0;  // samples with >= 1 NaN/Inf value
  std::uint64_t non_finite_values = 0;
  std::uint64_t saturated_values = 0;
  std::uint64_t stuck_values = 0;
  std::uint64_t filter_faults = 0;
};

enum class ImuStatus : std::uint8_t {
  ok = 0,
  bad_channel_config,   // Kalman model/q/r invalid, bad saturation, unknown filter
  wavelet_unavailable,  // a channel asks for the wavelet, but the Wavelet type is NoWavelet
                        // or the wavelet prototype's status() is not ok
  bad_timing,           // timestamp check on (time_tolerance_us > 0) with period_us == 0
};

// Placeholder wavelet stage: lets ImuProcessor<Scalar> compile without the wavelet header;
// selecting ChannelFilter::wavelet with it is a configuration error.
template <class Scalar>
struct NoWavelet {
  enum class Status : std::uint8_t { ok = 0, unavailable = 1 };
  Scalar step(Scalar x) noexcept { return x; }
  void reset() noexcept {}
  std::uint32_t fault_count() const noexcept { return 0; }
  Status status() const noexcept { return Status::unavailable; }
};

// Wavelet: copyable, `Scalar step(Scalar)` (NaN/Inf input = skip and hold, as
// RealtimeWavelet does), `void reset()`, `status()` whose value 0 means ok, and
// `std::uint32_t fault_count()` (inputs it refused: counted in filter_faults). Example:
//   ImuProcessor<float, RealtimeWavelet<float, 256>> p(config, RealtimeWavelet<float, 256>(WaveletKind::db8, 5));
template <class Scalar, class Wavelet = NoWavelet<Scalar>>
class ImuProcessor {
 public:
  static constexpr std::uint32_t kResyncAfter = 8;

  explicit ImuProcessor(const ImuConfig<Scalar>& config, const Wavelet& wavelet_prototype = Wavelet{}) noexcept
      : config_(config),
        kalman_{make_kalman(config, 0), make_kalman(config, 1), make_kalman(config, 2),
                make_kalman(config, 3), make_kalman(config, 4), make_kalman(config, 5)},
        wavelet_{wavelet_prototype, wavelet_prototype, wavelet_prototype,
                 wavelet_prototype, wavelet_prototype, wavelet_prototype} {
    status_ = check_config(wavelet_prototype);
    reset();
  }

  // Processes one input sample. Returns the sample's flags; if kFlagRejected is set, `out`
  // is not written (duplicate/out-of-order frame or unconfigured processor).
  std::uint16_t step(const ImuSample<Scalar>& in, ImuOutput<Scalar>& out) noexcept {
    ++health_.samples_in;
    if (status_ != ImuStatus::ok) {
      ++health_.config_rejected;
      return static_cast<std::uint16_t>(kFlagConfigError | kFlagRejected);
    }
    std::uint16_t flags = 0;
    std::uint32_t jump = 1;
    if (have_last_) {
      const auto d = static_cast<std::uint16_t>(in.seq - last_seq_);
      if (d == 0 || d >= 0x8000U) {
        if (++consecutive_rejects_ < kResyncAfter) {
          if (d == 0) {
            ++health_.duplicates;
            return static_cast<std::uint16_t>(kFlagDuplicate | kFlagRejected);
          }
          ++health_.out_of_order;
          return static_cast<std::uint16_t>(kFlagOutOfOrder | kFlagRejected);
        }
        ++health_.seq_resyncs;  // the source restarted: accept and carry on from here
        flags = static_cast<std::uint16_t>(flags | kFlagResync);
      } else {
        jump = d;
        if (d > 1) {
          ++health_.seq_gaps;
          health_.missing_samples += static_cast<std::uint64_t>(d - 1U);
          flags = static_cast<std::uint16_t>(flags | kFlagSeqGap);
        }
        if (config_.time_tolerance_us != 0) {
          const std::uint64_t expected = static_cast<std::uint64_t>(jump) * config_.period_us;
          const std::uint64_t dt = in.t_us - last_t_us_;  // wraps huge if time went backwards
          const std::uint64_t err = dt > expected ? dt - expected : expected - dt;
          if (in.t_us < last_t_us_ || err > config_.time_tolerance_us) {
            ++health_.time_jumps;
            flags = static_cast<std::uint16_t>(flags | kFlagTimeJump);
          }
        }
      }
    }
    consecutive_rejects_ = 0;
    have_last_ = true;
    last_seq_ = in.seq;
    last_t_us_ = in.t_us;
    ++health_.samples_accepted;

    bool any_non_finite = false;
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      const ImuChannelConfig<Scalar>& cc = config_.channels[c];
      const Scalar x = in.values[c];
      bool good = true;
      if (!std::isfinite(x)) {
        any_non_finite = true;
        ++health_.non_finite_values;
        good = false;
      } else {
        // Stuck: count identical consecutive finite values (bit-exact comparison on purpose).
        run_[c] = (has_raw_[c] && x == last_raw_[c]) ? run_[c] + 1U : 1U;
        last_raw_[c] = x;
        has_raw_[c] = true;
        if (std::fabs(x) >= cc.saturation) {
          ++health_.saturated_values;
          flags = static_cast<std::uint16_t>(flags | kFlagSaturated);
          good = false;
        }
        if (cc.stuck_samples != 0 && run_[c] >= cc.stuck_samples) {
          ++health_.stuck_values;
          flags = static_cast<std::uint16_t>(flags | kFlagStuck);
          good = false;
        }
      }
      const Scalar missing = std::numeric_limits<Scalar>::quiet_NaN();
      Scalar y = Scalar(0);
      switch (cc.filter) {
        case ChannelFilter::ar2_kalman: {
          const std::uint32_t faults_before = kalman_[c].fault_count();
          y = kalman_[c].step(good ? x : missing) - cc.bias;
          if (good && kalman_[c].fault_count() != faults_before) {
            ++health_.filter_faults;
            flags = static_cast<std::uint16_t>(flags | kFlagFilterFault);
            good = false;  // counted once
          }
          break;
        }
        case ChannelFilter::wavelet: {
          const std::uint32_t faults_before = wavelet_[c].fault_count();
          y = wavelet_[c].step(good ? x : missing) - cc.bias;
          if (good && wavelet_[c].fault_count() != faults_before) {
            ++health_.filter_faults;
            flags = static_cast<std::uint16_t>(flags | kFlagFilterFault);
            good = false;  // counted once
          }
          break;
        }
        case ChannelFilter::bias_removal:
          y = good ? x - cc.bias : last_out_[c];
          break;
        case ChannelFilter::pass_through:
        default:
          y = good ? x : last_out_[c];
          break;
      }
      if (!std::isfinite(y)) {  // e.g. x - bias overflowed: hold, and say so
        if (good) {
          ++health_.filter_faults;
          flags = static_cast<std::uint16_t>(flags | kFlagFilterFault);
        }
        y = last_out_[c];
      }
      last_out_[c] = y;
      out.values[c] = y;
    }
    if (any_non_finite) {
      ++health_.non_finite_samples;
      flags = static_cast<std::uint16_t>(flags | kFlagNonFinite);
    }
    out.seq = in.seq;
    out.t_us = in.t_us;
    out.flags = flags;
    return flags;
  }

  // Back to the constructed state (filters, sequence tracking, counters).
  void reset() noexcept {
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      kalman_[c].reset();
      wavelet_[c].reset();
    }
    last_out_.fill(Scalar(0));
    last_raw_.fill(Scalar(0));
    has_raw_.fill(false);
    run_.fill(0U);
    have_last_ = false;
    last_seq_ = 0;
    last_t_us_ = 0;
    consecutive_rejects_ = 0;
    health_ = ImuHealth{};
  }

  ImuStatus status() const noexcept { return status_; }
  // Index of the first bad channel when status() == bad_channel_config (else -1).
  int bad_channel() const noexcept { return bad_channel_; }
  const ImuHealth& health() const noexcept { return health_; }
  const ImuConfig<Scalar>& config() const noexcept { return config_; }
  const Ar2Kalman<Scalar>& kalman(std::size_t c) const noexcept { return kalman_[c < kImuChannels ? c : 0]; }

 private:
  static Ar2Kalman<Scalar> make_kalman(const ImuConfig<Scalar>& config, std::size_t c) noexcept {
    const ImuChannelConfig<Scalar>& cc = config.channels[c];
    if (cc.filter == ChannelFilter::ar2_kalman) return Ar2Kalman<Scalar>(cc.model, cc.q, cc.r, cc.p0);
    // Unused stage: a valid, inert filter (never stepped).
    return Ar2Kalman<Scalar>(Ar2Model<Scalar>{Scalar(0), Scalar(0), Scalar(1), Scalar(0)}, Scalar(1), Scalar(1));
  }

  ImuStatus check_config(const Wavelet& wavelet_prototype) noexcept {
    bool wants_wavelet = false;
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      const ImuChannelConfig<Scalar>& cc = config_.channels[c];
      bool ok = std::isfinite(cc.bias) && !(cc.saturation <= Scalar(0)) && !std::isnan(cc.saturation);
      switch (cc.filter) {
        case ChannelFilter::ar2_kalman: ok = ok && kalman_[c].status() == Ar2Status::ok; break;
        case ChannelFilter::wavelet: wants_wavelet = true; break;
        case ChannelFilter::pass_through: ok = ok && cc.bias == Scalar(0); break;
        case ChannelFilter::bias_removal: break;
        default: ok = false; break;
      }
      if (!ok) {
        bad_channel_ = static_cast<int>(c);
        return ImuStatus::bad_channel_config;
      }
    }
    if (wants_wavelet && static_cast<int>(wavelet_prototype.status()) != 0) return ImuStatus::wavelet_unavailable;
    if (config_.time_tolerance_us != 0 && config_.period_us == 0) return ImuStatus::bad_timing;
    return ImuStatus::ok;
  }

  ImuConfig<Scalar> config_;
  std::array<Ar2Kalman<Scalar>, kImuChannels> kalman_;
  std::array<Wavelet, kImuChannels> wavelet_;
  std::array<Scalar, kImuChannels> last_out_{};
  std::array<Scalar, kImuChannels> last_raw_{};
  std::array<bool, kImuChannels> has_raw_{};
  std::array<std::uint32_t, kImuChannels> run_{};
  ImuStatus status_ = ImuStatus::ok;
  int bad_channel_ = -1;
  bool have_last_ = false;
  std::uint16_t last_seq_ = 0;
  std::uint64_t last_t_us_ = 0;
  std::uint32_t consecutive_rejects_ = 0;
  ImuHealth health_{};
};

}  // namespace gyrodrift
