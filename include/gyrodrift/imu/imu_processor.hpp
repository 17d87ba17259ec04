// Six-channel IMU processor (3 gyro + 3 accelerometer) for a fixed-rate navigation loop.
//
// Per channel c (chosen at construction) a chain of up to two stages, `filter` then
// `filter2` (pass_through as filter2 means "no second stage"); each stage is one of
//   pass_through:  y = x
//   bias_removal:  y = x - bias
//   ar2_kalman:    y = Ar2Kalman(x)   (paper 000 sec. 2.2 / paper 002 sec. 3; model and q, r
//                  identified offline, e.g. with fit_ar2; the model mean is kept in the output;
//                  steady_state selects the constant-gain filter of filters/ar2_steady_state.hpp)
//   wavelet:       y = Wavelet(x)     (real-time sliding-window prefilter, paper 004 sec. 2.2;
//                  any type with step(Scalar), reset(), status() plugs in, see below)
// e.g. the 2014 paper's chain: filter = wavelet, filter2 = ar2_kalman. A chain without a
// bias_removal stage subtracts `bias` after its last stage (so a single ar2_kalman or wavelet
// stage gives y = stage(x) - bias, as before chains existed).
// The wavelet stage exists only on channels c < WaveletChannels (a template parameter), so a
// firmware build whose wavelet runs on the three gyros pays for three windows, not six.
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
//     and bias stages hold their last output. A missing value stays missing through the
//     chain: the second stage is told "missing", not given the first stage's held output.
//     Filter state never sees the bad value.
//   * filter_faults: a good value a stage refused (a Kalman update with a non-finite result,
//     or a value beyond the filters' input range, filters/input_range.hpp), or a stage output that
//     would not be finite (e.g. x - bias overflowing); the stage then holds its last output.
//     Every output value is finite or this counter moved.
// A processor whose configuration is invalid (status() != ok) rejects every sample with
// kFlagConfigError, rather than passing data through silently.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>

#include "../filters/ar2_kalman.hpp"
#include "../filters/ar2_model.hpp"
#include "../filters/ar2_steady_state.hpp"
#include "config_schema.hpp"
#include "../filters/lag_drift_identifier.hpp"
#include "../filters/shared_drift_identifier.hpp"
#include "gyro_monitor.hpp"

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
inline constexpr std::uint16_t kFlagHealthAlarm = 1U << 9; // a gyro monitor's alarm is latched
inline constexpr std::uint16_t kFlagConfigError = 1U << 14; // processor not configured (rejected)
inline constexpr std::uint16_t kFlagRejected = 1U << 15;   // no output for this input

// The processor's contract in one place: flag names, health counter names, defaults. The
// binding exports these (gyrodrift._core.IMU_FLAGS, IMU_HEALTH_KEYS, ...), the loop's JSON
// uses them, and tests/test_imu_contract.py fails if any other copy differs.
struct ImuFlagName {
  std::uint16_t bit;
  const char* name;
};
inline constexpr ImuFlagName kImuFlagNames[] = {
    {kFlagNonFinite, "non_finite"},     {kFlagSaturated, "saturated"},
    {kFlagStuck, "stuck"},              {kFlagSeqGap, "seq_gap"},
    {kFlagDuplicate, "duplicate"},      {kFlagOutOfOrder, "out_of_order"},
    {kFlagTimeJump, "time_jump"},       {kFlagFilterFault, "filter_fault"},
    {kFlagResync, "resync"},            {kFlagHealthAlarm, "health_alarm"},
    {kFlagConfigError, "config_error"},
    {kFlagRejected, "rejected"},
};
// Every default below comes from the configuration schema (config_schema.hpp, generated from
// gyrodrift/imu/schema.py): the shipped default configuration's timing (its sample period, and
// half of it as the timestamp tolerance) and the fields' own defaults.
inline constexpr std::uint32_t kImuDefaultPeriodUs = config_schema::kDefaultPeriodUs;
inline constexpr std::uint32_t kImuDefaultTimeToleranceUs = config_schema::kDefaultTimeToleranceUs;
inline constexpr std::uint32_t kImuResyncAfter = 8;  // consecutive rejections -> source restart

// The demonstration gyro model of the shipped default configuration (used when no identified
// model is given): AR(2) with a double root at 0.5 (stationary); sigma2, q, r in (rad/s)^2,
// mean in rad/s. The one copy is config_schema::DemoAr2; gyrodrift._core.IMU_DEMO_AR2 exports it.
using ImuDemoAr2 = config_schema::DemoAr2;

// A field's default in the processor's scalar type, as a constant (converted at compile time:
// a float build does no double arithmetic for it).
template <class Scalar>
inline constexpr Scalar kImuDefaultP0 = static_cast<Scalar>(config_schema::kAr2KalmanP0.default_value);
template <class Scalar>
inline constexpr Scalar kImuDefaultSaturation = static_cast<Scalar>(config_schema::kChannelSaturation.default_value);
inline constexpr std::uint32_t kImuDefaultStuckSamples =
    static_cast<std::uint32_t>(config_schema::kChannelStuckSamples.default_value);
inline constexpr bool kImuDefaultSteadyState = config_schema::kAr2KalmanSteadyState.default_value != 0.0;

template <class Scalar>
struct ImuChannelConfig {
  ChannelFilter filter = ChannelFilter::pass_through;   // first stage
  ChannelFilter filter2 = ChannelFilter::pass_through;  // second stage (pass_through: none)
  bool steady_state = kImuDefaultSteadyState;  // ar2_kalman stage: constant DARE gain (Ar2SteadyStateKalman)
  // Units of the channel (rad/s or m/s^2): subtracted by the bias_removal stage, or after the
  // last stage when the chain has no bias_removal stage.
  Scalar bias = Scalar(0);
  // ar2_kalman: model, process noise q and measurement noise r (units^2), P_0 = p0 I.
  Ar2Model<Scalar> model{std::numeric_limits<Scalar>::quiet_NaN(), std::numeric_limits<Scalar>::quiet_NaN(),
                         std::numeric_limits<Scalar>::quiet_NaN(), std::numeric_limits<Scalar>::quiet_NaN()};
  Scalar q = std::numeric_limits<Scalar>::quiet_NaN();
  Scalar r = std::numeric_limits<Scalar>::quiet_NaN();
  Scalar p0 = kImuDefaultP0<Scalar>;
  Scalar saturation = kImuDefaultSaturation<Scalar>;  // |x| >= saturation: saturated (inf: off)
  std::uint32_t stuck_samples = kImuDefaultStuckSamples;  // 0: off; N: the N-th identical value in a row is stuck
};

template <class Scalar>
struct ImuConfig {
  std::array<ImuChannelConfig<Scalar>, kImuChannels> channels = default_channels();
  std::uint32_t period_us = kImuDefaultPeriodUs;                // nominal sample period
  std::uint32_t time_tolerance_us = kImuDefaultTimeToleranceUs;  // 0: timestamp check off

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
  // The gyro monitor (zero while it is off): alarms raised per kind (health_alarms.hpp), gain
  // retunes taken by a steady-state AR(2)-Kalman stage, and retunes the re-identification
  // refused (its guards).
  std::uint64_t arw_high_alarms = 0;
  std::uint64_t bias_instability_alarms = 0;
  std::uint64_t rate_random_walk_alarms = 0;
  std::uint64_t stuck_alarms = 0;
  std::uint64_t saturated_alarms = 0;
  std::uint64_t monitor_retunes = 0;
  std::uint64_t monitor_refused_retunes = 0;
};

// The monitor's alarm counters in the order of kHealthAlarmNames.
inline std::uint64_t* monitor_alarm_counter(ImuHealth& h, std::size_t i) noexcept {
  std::uint64_t* counters[kHealthAlarmCount] = {&h.arw_high_alarms, &h.bias_instability_alarms,
                                                &h.rate_random_walk_alarms, &h.stuck_alarms,
                                                &h.saturated_alarms};
  return counters[i < kHealthAlarmCount ? i : 0];
}

// Every health counter with its name, in the order of ImuHealth (the one list of names).
template <class H, class F>
void for_each_health_field(H& h, F&& field) {
  field("samples_in", h.samples_in);
  field("samples_accepted", h.samples_accepted);
  field("duplicates", h.duplicates);
  field("out_of_order", h.out_of_order);
  field("config_rejected", h.config_rejected);
  field("seq_gaps", h.seq_gaps);
  field("missing_samples", h.missing_samples);
  field("seq_resyncs", h.seq_resyncs);
  field("time_jumps", h.time_jumps);
  field("non_finite_samples", h.non_finite_samples);
  field("non_finite_values", h.non_finite_values);
  field("saturated_values", h.saturated_values);
  field("stuck_values", h.stuck_values);
  field("filter_faults", h.filter_faults);
  field("arw_high_alarms", h.arw_high_alarms);
  field("bias_instability_alarms", h.bias_instability_alarms);
  field("rate_random_walk_alarms", h.rate_random_walk_alarms);
  field("stuck_alarms", h.stuck_alarms);
  field("saturated_alarms", h.saturated_alarms);
  field("monitor_retunes", h.monitor_retunes);
  field("monitor_refused_retunes", h.monitor_refused_retunes);
}

// The rejection reasons (samples that produced no output) under the names the loop's JSON
// "rejected" object and the replay report use.
template <class H, class F>
void for_each_rejection_field(H& h, F&& field) {
  field("duplicate", h.duplicates);
  field("out_of_order", h.out_of_order);
  field("config", h.config_rejected);
}

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

inline constexpr std::size_t kImuGyroChannels = 3;  // gx gy gz: the channels a monitor can watch

namespace detail {

// The gyro monitors of a processor built with MonitorOctaves > 0: MonitorSlots monitors, each
// serving the gyro channel configure_monitor() gave it (slot[c], -1: none), and (with
// MonitorReidentify) one re-identification time-shared among them, slot i its channel i; an
// empty base otherwise, so a build without the monitor pays no RAM for it (empty base
// optimisation). The monitors keep no trip records and refer to the caller's references: the
// processor reports the latched bits (kFlagHealthAlarm) and counts raises and retunes itself.
template <class Scalar, std::size_t MonitorOctaves, std::size_t MonitorSlots, bool MonitorReidentify = true,
          class Identifier = SharedDriftIdentifier<Scalar, MonitorSlots>>
struct ImuMonitorBank {
  std::array<GyroMonitor<Scalar, MonitorOctaves, false, false>, MonitorSlots> monitors{};
  std::conditional_t<MonitorReidentify, Identifier, NoDriftIdentifier> identifier{};
  std::array<std::int8_t, kImuGyroChannels> slot{{-1, -1, -1}};
  std::array<bool, MonitorSlots> retune_stage{};  // the channel's steady-state stage takes retunes
  std::array<std::uint16_t, MonitorSlots> latched{};
  std::array<std::uint32_t, MonitorSlots> refused{};
  HealthAlarmSettings<Scalar> alarm_settings{};  // one copy, which every monitor's alarms refer to
  bool reidentify = false;
};
template <class Scalar, std::size_t MonitorSlots, bool MonitorReidentify, class Identifier>
struct ImuMonitorBank<Scalar, 0, MonitorSlots, MonitorReidentify, Identifier> {};

}  // namespace detail

// Wavelet: copyable, `Scalar step(Scalar)` (NaN/Inf input = skip and hold, as
// RealtimeWavelet does), `void reset()`, `status()` whose value 0 means ok, and
// `std::uint32_t fault_count()` (inputs it refused: counted in filter_faults). Example:
//   ImuProcessor<float, RealtimeWavelet<float, 256>> p(config, RealtimeWavelet<float, 256>(WaveletKind::db8, 5));
//   ImuProcessor<float, FirPrefilter<float, 256>, 3> p(config, {FirPrefilter<float, 256>(kTaps), ...});
//
// MonitorOctaves > 0 builds MonitorSlots GyroMonitors (imu/gyro_monitor.hpp, that many octaves
// at most) for the gyro channels configure_monitor() names (a firmware build watching one gyro
// pays for one); 0 (the default) builds none and the processor is the same as without the
// monitor, bit for bit. MonitorReidentify false builds the monitors without the online
// re-identification (less RAM; configure_monitor() then refuses settings.reidentify); with it,
// one re-identification serves every watched gyro: MonitorIdentifierType, by default the
// recursive estimator in turns of one block (filters/shared_drift_identifier.hpp: with n
// watched gyros its time constants are n times longer), or LagDriftIdentifier<Scalar,
// MonitorSlots> (filters/lag_drift_identifier.hpp: per gyro lag statistics, one fit at a time).
// A build holds one of them (RAM); configure_monitor() refuses a settings.identifier that is not
// its kind. With the lag identifier a target defers its fits to thread mode
// (defer_monitor_fits, run_pending_monitor_fit).
template <class Scalar, class Wavelet = NoWavelet<Scalar>, std::size_t WaveletChannels = kImuChannels,
          std::size_t MonitorOctaves = 0, std::size_t MonitorSlots = kImuGyroChannels,
          bool MonitorReidentify = true, class MonitorIdentifierType = SharedDriftIdentifier<Scalar, MonitorSlots>>
class ImuProcessor
    : private detail::ImuMonitorBank<Scalar, MonitorOctaves, MonitorSlots, MonitorReidentify, MonitorIdentifierType> {
  static_assert(WaveletChannels >= 1 && WaveletChannels <= kImuChannels, "WaveletChannels in 1..6");
  static_assert(MonitorSlots >= 1 && MonitorSlots <= kImuGyroChannels, "MonitorSlots in 1..3");

 public:
  static constexpr std::size_t kMonitorOctaves = MonitorOctaves;
  static constexpr std::size_t kMonitorSlots = MonitorOctaves > 0 ? MonitorSlots : 0;
  using Monitor = GyroMonitor<Scalar, (MonitorOctaves > 0 ? MonitorOctaves : 1), false, false>;
  using MonitorIdentifier = MonitorIdentifierType;
  static constexpr DriftIdentifierKind kMonitorIdentifierKind = drift_identifier_kind_v<MonitorIdentifierType>;
  static_assert(MonitorIdentifierType::capacity == MonitorSlots, "the identifier serves MonitorSlots channels");
  using MonitorReference = HealthReference<Scalar, (MonitorOctaves > 0 ? MonitorOctaves : 1)>;

  static constexpr std::uint32_t kResyncAfter = kImuResyncAfter;
  using WaveletArray = std::array<Wavelet, WaveletChannels>;

  // One wavelet setting copied to every wavelet channel.
  explicit ImuProcessor(const ImuConfig<Scalar>& config, const Wavelet& wavelet_prototype = Wavelet{}) noexcept
      : ImuProcessor(config, [&wavelet_prototype](std::size_t) { return wavelet_prototype; },
                     std::make_index_sequence<WaveletChannels>{}) {}

  // Per-channel wavelet stages (wavelets[c] serves channel c).
  ImuProcessor(const ImuConfig<Scalar>& config, const WaveletArray& wavelets) noexcept
      : ImuProcessor(config, [&wavelets](std::size_t c) { return wavelets[c]; },
                     std::make_index_sequence<WaveletChannels>{}) {}

  // Per-channel wavelet stages built in place by make_wavelet(c) (no temporary array: a
  // firmware build constructs its windows directly in the processor, not on the stack).
  template <class MakeWavelet,
            class = std::enable_if_t<std::is_invocable_r_v<Wavelet, MakeWavelet&, std::size_t>>>
  ImuProcessor(const ImuConfig<Scalar>& config, MakeWavelet&& make_wavelet) noexcept
      : ImuProcessor(config, make_wavelet, std::make_index_sequence<WaveletChannels>{}) {}

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
      [[maybe_unused]] bool stuck_now = false;
      [[maybe_unused]] bool saturated_now = false;
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
          saturated_now = true;
        }
        if (cc.stuck_samples != 0 && run_[c] >= cc.stuck_samples) {
          ++health_.stuck_values;
          flags = static_cast<std::uint16_t>(flags | kFlagStuck);
          good = false;
          stuck_now = true;
        }
      }
      if constexpr (MonitorOctaves > 0) {
        if (c < kImuGyroChannels && this->slot[c] >= 0) {
          monitor_step(static_cast<std::size_t>(this->slot[c]), x, stuck_now, saturated_now);
        }
      }
      // A stage that refuses a good value makes it missing for the rest of the chain.
      Scalar y = run_stage(c, 0, cc.filter, x, good, flags);
      if (cc.filter2 != ChannelFilter::pass_through) y = run_stage(c, 1, cc.filter2, y, good, flags);
      if (!has_bias_stage(cc)) y -= cc.bias;
      if (!std::isfinite(y)) {  // the final bias overflowed: hold the last output, and say so
        if (good) count_filter_fault(flags);
        y = out_hold_[c];
      }
      out_hold_[c] = y;
      out.values[c] = y;
    }
    if (any_non_finite) {
      ++health_.non_finite_samples;
      flags = static_cast<std::uint16_t>(flags | kFlagNonFinite);
    }
    if constexpr (MonitorOctaves > 0) {
      for (std::size_t i = 0; i < MonitorSlots; ++i) {
        if (this->latched[i] != 0) flags = static_cast<std::uint16_t>(flags | kFlagHealthAlarm);
      }
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
      steady_[c].reset();
    }
    for (std::size_t c = 0; c < WaveletChannels; ++c) wavelet_[c].reset();
    for (auto& h : hold_) h.fill(Scalar(0));
    out_hold_.fill(Scalar(0));
    last_raw_.fill(Scalar(0));
    has_raw_.fill(false);
    run_.fill(0U);
    have_last_ = false;
    last_seq_ = 0;
    last_t_us_ = 0;
    consecutive_rejects_ = 0;
    health_ = ImuHealth{};
    if constexpr (MonitorOctaves > 0) {
      for (std::size_t i = 0; i < MonitorSlots; ++i) {
        this->monitors[i].reset();
        this->latched[i] = 0;
        this->refused[i] = 0;
      }
      if constexpr (MonitorReidentify) {
        if (this->reidentify) this->identifier.reset();
      }
    }
  }

  // Starts the gyro monitor on the gyro channels c with channels[c] true (only in a build
  // with MonitorOctaves > 0; at most MonitorSlots of them, given slots in channel order): each
  // channel's drift model is its first stage's ar2_kalman model (a1, a2, q, r, mean), which
  // must exist; references[c] is the expected Allan variance the alarms compare against. When
  // settings.reidentify is on and the channel's first stage is a steady-state ar2_kalman, a
  // retune of the re-identification replaces that stage's model and gain. Returns ok, or the
  // first channel's failure (no monitor is started then). Call it after construction, before
  // the first step() (it resets the monitors, not the filters). The monitors refer to
  // `references` (they keep no copy): it must outlive the processor's use of them, e.g. a
  // constant table (a temporary is refused at compile time).
  template <std::size_t O = MonitorOctaves, class = std::enable_if_t<(O > 0)>>
  GyroMonitorStatus configure_monitor(const GyroMonitorSettings<Scalar>& settings,
                                      std::array<MonitorReference, kImuGyroChannels>&& references,
                                      const std::array<bool, kImuGyroChannels>& channels) = delete;
  template <std::size_t O = MonitorOctaves, class = std::enable_if_t<(O > 0)>>
  GyroMonitorStatus configure_monitor(const GyroMonitorSettings<Scalar>& settings,
                                      const std::array<MonitorReference, kImuGyroChannels>& references,
                                      const std::array<bool, kImuGyroChannels>& channels) noexcept {
    for (std::size_t c = 0; c < kImuGyroChannels; ++c) this->slot[c] = -1;
    this->reidentify = false;
    if (status_ != ImuStatus::ok) return GyroMonitorStatus::bad_settings;
    if (settings.reidentify && (!MonitorReidentify || settings.identifier != kMonitorIdentifierKind)) {
      return GyroMonitorStatus::bad_settings;
    }
    this->alarm_settings = settings.alarms;
    GyroMonitorSettings<Scalar> per_gyro = settings;
    per_gyro.reidentify = false;  // the monitors' statistics and alarms; the processor re-identifies
    std::array<std::int8_t, kImuGyroChannels> slots{{-1, -1, -1}};
    std::array<DriftModelParams<Scalar>, MonitorSlots> models{};
    std::size_t used = 0;
    for (std::size_t c = 0; c < kImuGyroChannels; ++c) {
      if (!channels[c]) continue;
      if (used == MonitorSlots) return GyroMonitorStatus::bad_settings;
      const ImuChannelConfig<Scalar>& cc = config_.channels[c];
      if (cc.filter != ChannelFilter::ar2_kalman) return GyroMonitorStatus::bad_model;
      models[used] = DriftModelParams<Scalar>{cc.model.a1, cc.model.a2, cc.q, cc.r, cc.model.mean};
      const GyroMonitorStatus st = this->monitors[used].configure(per_gyro, this->alarm_settings, models[used],
                                                                   references[c]);
      if (st != GyroMonitorStatus::ok) return st;
      this->retune_stage[used] = settings.reidentify && cc.steady_state;
      this->latched[used] = 0;
      this->refused[used] = 0;
      slots[c] = static_cast<std::int8_t>(used++);
    }
    if constexpr (MonitorReidentify) {
      if (settings.reidentify && used > 0) {
        std::size_t failed = 0;
        bool configured = false;
        if constexpr (kMonitorIdentifierKind == DriftIdentifierKind::lag) {
          configured = this->identifier.configure(models.data(), used, settings.drift, settings.lag, &failed);
        } else {
          configured = this->identifier.configure(models.data(), used, settings.drift, &failed);
        }
        if (!configured) {
          if (failed >= used) return GyroMonitorStatus::bad_settings;
          // the identifier's own rules: a model with white noise (r > 0), its block and memory
          const bool white = failed < used && models[failed].r > Scalar(0);
          return white ? GyroMonitorStatus::bad_settings : GyroMonitorStatus::bad_model;
        }
        this->reidentify = true;
      }
    }
    this->slot = slots;
    return GyroMonitorStatus::ok;
  }

  // The monitor of gyro channel c (monitor_active(c) must be true).
  template <std::size_t O = MonitorOctaves, class = std::enable_if_t<(O > 0)>>
  const Monitor& monitor(std::size_t c) const noexcept {
    return this->monitors[monitor_active(c) ? static_cast<std::size_t>(this->slot[c]) : 0];
  }
  template <std::size_t O = MonitorOctaves, class = std::enable_if_t<(O > 0)>>
  bool monitor_active(std::size_t c) const noexcept {
    return c < kImuGyroChannels && this->slot[c] >= 0;
  }
  // The re-identification shared by the watched gyros; gyro channel c is its channel
  // monitor_slot(c) (monitor_active(c) must be true).
  template <std::size_t O = MonitorOctaves, bool R = MonitorReidentify, class = std::enable_if_t<(O > 0) && R>>
  const MonitorIdentifier& monitor_identifier() const noexcept {
    return this->identifier;
  }
  template <std::size_t O = MonitorOctaves, class = std::enable_if_t<(O > 0)>>
  std::size_t monitor_slot(std::size_t c) const noexcept {
    return monitor_active(c) ? static_cast<std::size_t>(this->slot[c]) : 0;
  }
  // The lag identifier's fits (filters/lag_drift_identifier.hpp; no-ops, false and 0 in a build
  // without it). Deferred (on): step() only marks a fit pending at its request and the caller
  // runs it with run_pending_monitor_fit() (thread mode on a target, while the interrupt keeps
  // stepping); its outcome applies a fixed number of samples after the request if done by
  // then (monitor_late_fits() counts those not done). Switch it after configure_monitor(),
  // before the first step().
  void defer_monitor_fits(bool on) noexcept {
    if constexpr (lag_identifier()) this->identifier.defer_fits(on);
    (void)on;
  }
  bool monitor_fit_pending() const noexcept {
    if constexpr (lag_identifier()) return this->identifier.fit_pending();
    return false;
  }
  void run_pending_monitor_fit() noexcept {
    if constexpr (lag_identifier()) this->identifier.run_pending_fit();
  }
  std::uint32_t monitor_late_fits() const noexcept {
    if constexpr (lag_identifier()) return this->identifier.late_fits();
    return 0;
  }
  ImuStatus status() const noexcept { return status_; }
  // Index of the first bad channel when status() != ok (else -1).
  int bad_channel() const noexcept { return bad_channel_; }
  const ImuHealth& health() const noexcept { return health_; }
  const ImuConfig<Scalar>& config() const noexcept { return config_; }
  const Ar2Kalman<Scalar>& kalman(std::size_t c) const noexcept { return kalman_[c < kImuChannels ? c : 0]; }

 private:
  template <class MakeWavelet, std::size_t... I>
  ImuProcessor(const ImuConfig<Scalar>& config, MakeWavelet&& make_wavelet, std::index_sequence<I...>) noexcept
      : config_(config),
        kalman_{make_kalman(config, 0), make_kalman(config, 1), make_kalman(config, 2),
                make_kalman(config, 3), make_kalman(config, 4), make_kalman(config, 5)},
        steady_{make_steady(config, 0), make_steady(config, 1), make_steady(config, 2),
                make_steady(config, 3), make_steady(config, 4), make_steady(config, 5)},
        wavelet_{{make_wavelet(I)...}} {
    status_ = check_config();
    reset();
  }

  static bool has_bias_stage(const ImuChannelConfig<Scalar>& cc) noexcept {
    return cc.filter == ChannelFilter::bias_removal || cc.filter2 == ChannelFilter::bias_removal;
  }

  // One stage of channel c's chain (index k = 0 or 1). `good` false: the input is missing.
  Scalar run_stage(std::size_t c, std::size_t k, ChannelFilter f, Scalar x, bool& good,
                   std::uint16_t& flags) noexcept {
    const ImuChannelConfig<Scalar>& cc = config_.channels[c];
    const Scalar missing = std::numeric_limits<Scalar>::quiet_NaN();
    Scalar y = Scalar(0);
    switch (f) {
      case ChannelFilter::ar2_kalman: {
        if (cc.steady_state) {
          const std::uint32_t before = steady_[c].fault_count();
          y = steady_[c].step(good ? x : missing);
          if (good && steady_[c].fault_count() != before) {
            count_filter_fault(flags);
            good = false;  // counted once
          }
        } else {
          const std::uint32_t before = kalman_[c].fault_count();
          y = kalman_[c].step(good ? x : missing);
          if (good && kalman_[c].fault_count() != before) {
            count_filter_fault(flags);
            good = false;  // counted once
          }
        }
        break;
      }
      case ChannelFilter::wavelet: {
        Wavelet& w = wavelet_[c < WaveletChannels ? c : 0];
        const std::uint32_t before = w.fault_count();
        y = w.step(good ? x : missing);
        if (good && w.fault_count() != before) {
          count_filter_fault(flags);
          good = false;  // counted once
        }
        break;
      }
      case ChannelFilter::bias_removal:
        y = good ? x - cc.bias : hold_[k][c];
        break;
      case ChannelFilter::pass_through:
      default:
        y = good ? x : hold_[k][c];
        break;
    }
    if (!std::isfinite(y)) {  // e.g. x - bias overflowed: hold, and say so
      if (good) count_filter_fault(flags);
      good = false;
      y = hold_[k][c];
    }
    hold_[k][c] = y;
    return y;
  }

  // One value of a gyro channel into its monitor (slot i); new alarms and retunes counted, a
  // retune taken by the channel's steady-state stage.
  void monitor_step(std::size_t slot_index, Scalar x, bool stuck, bool saturated) noexcept {
    if constexpr (MonitorOctaves > 0) {
      const std::size_t i = slot_index;
      Monitor& m = this->monitors[i];
      [[maybe_unused]] const std::uint64_t used_before = m.used();
      const std::uint16_t now = m.push(x, stuck, saturated);
      const auto raised = static_cast<std::uint16_t>(now & ~this->latched[i]);
      if (raised != 0) {
        for (std::size_t a = 0; a < kHealthAlarmCount; ++a) {
          if ((raised & kHealthAlarmNames[a].bit) != 0) ++*monitor_alarm_counter(health_, a);
        }
      }
      this->latched[i] = now;
      if constexpr (!MonitorReidentify) {
        // no re-identification compiled in: no retunes
      } else if (this->reidentify) {
        MonitorIdentifier& id = this->identifier;
        if (m.used() == used_before) {
          // a value the statistics did not take (stuck, saturated, non-finite): it counts towards
          // passing slot i's turn of the shared re-identification on, so that a failed gyro does
          // not stop the others' (the lag identifier: towards its fits' schedule)
          id.skip(i);
        } else {  // a value the statistics took
          id.push(i, x);
        }
        if (id.refused_retunes(i) != this->refused[i]) {
          health_.monitor_refused_retunes += id.refused_retunes(i) - this->refused[i];
          this->refused[i] = id.refused_retunes(i);
        }
        if (id.retuned() && this->retune_stage[i]) {
          std::size_t c = 0;  // the channel of slot i
          while (c + 1 < kImuGyroChannels && this->slot[c] != static_cast<std::int8_t>(i)) ++c;
          const DriftModelParams<Scalar>& p = id.in_use(i);
          if (steady_[c].retune(p.a1, p.a2, p.mean, id.gain0(i), id.gain1(i))) ++health_.monitor_retunes;
        }
      }
    } else {
      (void)slot_index;
      (void)x;
      (void)stuck;
      (void)saturated;
    }
  }

  static constexpr bool lag_identifier() noexcept {
    return MonitorOctaves > 0 && MonitorReidentify && kMonitorIdentifierKind == DriftIdentifierKind::lag;
  }

  void count_filter_fault(std::uint16_t& flags) noexcept {
    ++health_.filter_faults;
    flags = static_cast<std::uint16_t>(flags | kFlagFilterFault);
  }

  static Ar2Kalman<Scalar> make_kalman(const ImuConfig<Scalar>& config, std::size_t c) noexcept {
    const ImuChannelConfig<Scalar>& cc = config.channels[c];
    if (uses(cc, ChannelFilter::ar2_kalman) && !cc.steady_state) return Ar2Kalman<Scalar>(cc.model, cc.q, cc.r, cc.p0);
    // Unused stage: a valid, inert filter (never stepped).
    return Ar2Kalman<Scalar>(Ar2Model<Scalar>{Scalar(0), Scalar(0), Scalar(1), Scalar(0)}, Scalar(1), Scalar(1));
  }

  static Ar2SteadyStateKalman<Scalar> make_steady(const ImuConfig<Scalar>& config, std::size_t c) noexcept {
    const ImuChannelConfig<Scalar>& cc = config.channels[c];
    if (uses(cc, ChannelFilter::ar2_kalman) && cc.steady_state) {
      return Ar2SteadyStateKalman<Scalar>(cc.model, cc.q, cc.r);
    }
    return Ar2SteadyStateKalman<Scalar>(Ar2Model<Scalar>{Scalar(0), Scalar(0), Scalar(1), Scalar(0)}, Scalar(1),
                                        Scalar(1));
  }

  static bool uses(const ImuChannelConfig<Scalar>& cc, ChannelFilter f) noexcept {
    return cc.filter == f || cc.filter2 == f;
  }

  static bool known(ChannelFilter f) noexcept {
    return f == ChannelFilter::pass_through || f == ChannelFilter::bias_removal ||
           f == ChannelFilter::ar2_kalman || f == ChannelFilter::wavelet;
  }

  ImuStatus check_config() noexcept {
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      const ImuChannelConfig<Scalar>& cc = config_.channels[c];
      bool ok = std::isfinite(cc.bias) && !(cc.saturation <= Scalar(0)) && !std::isnan(cc.saturation) &&
                known(cc.filter) && known(cc.filter2);
      // Chains: pass_through only alone (as filter2 it means "none"), no stage twice, and a
      // bias only where something uses it.
      if (cc.filter == ChannelFilter::pass_through) ok = ok && cc.filter2 == ChannelFilter::pass_through && cc.bias == Scalar(0);
      if (cc.filter2 != ChannelFilter::pass_through) ok = ok && cc.filter2 != cc.filter;
      if (uses(cc, ChannelFilter::ar2_kalman)) {
        ok = ok && (cc.steady_state ? steady_[c].status() == Ar2Status::ok : kalman_[c].status() == Ar2Status::ok);
      }
      if (!ok) {
        bad_channel_ = static_cast<int>(c);
        return ImuStatus::bad_channel_config;
      }
    }
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      if (!uses(config_.channels[c], ChannelFilter::wavelet)) continue;
      if (c >= WaveletChannels || static_cast<int>(wavelet_[c].status()) != 0) {
        bad_channel_ = static_cast<int>(c);
        return ImuStatus::wavelet_unavailable;
      }
    }
    if (config_.time_tolerance_us != 0 && config_.period_us == 0) return ImuStatus::bad_timing;
    return ImuStatus::ok;
  }

  ImuConfig<Scalar> config_;
  std::array<Ar2Kalman<Scalar>, kImuChannels> kalman_;
  std::array<Ar2SteadyStateKalman<Scalar>, kImuChannels> steady_;
  WaveletArray wavelet_;
  std::array<std::array<Scalar, kImuChannels>, 2> hold_{};  // last output of each stage
  std::array<Scalar, kImuChannels> out_hold_{};  // last output of each channel
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
