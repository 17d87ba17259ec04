// The loop's processing stage: ImuProcessor<float> (with the real-time wavelet stage, any
// window of the format) configured from a configuration (--config FILE, or the built-in
// default configuration; config_file.hpp), and its JSON counters (names from
// imu/imu_processor.hpp, the one list). The monitor's re-identification is the processor's
// build choice (imu_processor.hpp, MonitorIdentifierType): the loop holds the processor with
// the recursive identifier or the one with the lag identifier, chosen by the settings'
// identifier at start (fits inline: the host runs each at its request).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>

#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/config_schema.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

#include "config_file.hpp"

namespace gyrodrift::loop {

// The most octaves a configuration may give the monitor (the schema's bound): the loop's capacity.
inline constexpr std::size_t kLoopMonitorOctaves = static_cast<std::size_t>(config_schema::kMonitorOctaves.hi);

class Processing {
 public:
  // The window comes from the configuration file at run time: one stage type over every
  // window of the format (16..4096), each channel holding the instance it was given.
  using Wavelet = RealtimeWaveletAnyWindow<float>;
  static constexpr std::size_t kMonitorOctaves = kLoopMonitorOctaves;
  using Proc = ImuProcessor<float, Wavelet, kImuChannels, kMonitorOctaves>;
  using ProcLag = ImuProcessor<float, Wavelet, kImuChannels, kMonitorOctaves, kImuGyroChannels, true,
                               LagDriftIdentifier<float, kImuGyroChannels>>;
  static_assert(std::is_same_v<Proc::MonitorReference, ProcLag::MonitorReference>, "one reference type");

  // Builds the processor from a configuration's content (already checked key by key); false
  // (with a message) if the processor still refuses it, so a misconfigured loop refuses to
  // start instead of rejecting every sample. Each channel's wavelet stage is built in place
  // for the file's window.
  bool init(const FileConfig& fc, std::string& error) {
    sample_rate_hz_ = fc.sample_rate_hz;
    const GyroMonitorSettings<float> s = monitor_settings(fc);
    proc_.reset();
    proc_lag_.reset();
    const auto make_wavelet = [&fc](std::size_t c) {
      const WaveletSpec& w = fc.wavelets[c];
      return Wavelet(w.window, w.kind, w.level, w.mode);
    };
    if (fc.monitor.enabled && s.reidentify && s.identifier == DriftIdentifierKind::lag) {
      proc_lag_.emplace(fc.imu, make_wavelet);
    } else {
      proc_.emplace(fc.imu, make_wavelet);
    }
    const bool ok = with([&](auto& p) {
      if (p.status() == ImuStatus::ok) return true;
      // The file's values passed the reader's checks in double; the float processor refuses
      // them (a value that is 0 or not finite in float).
      const int c = p.bad_channel();
      error = (c >= 0 ? std::string("channels.") + config_schema::kChannelNames[c] + ": " : std::string()) +
              "invalid processor configuration (a value out of float range?)";
      return false;
    });
    if (!ok) return false;
    return fc.monitor.enabled ? init_monitor(fc, s, error) : true;
  }

  // The monitor's settings from the file's [monitor] table.
  static GyroMonitorSettings<float> monitor_settings(const FileConfig& fc) {
    const MonitorSpec& m = fc.monitor;
    GyroMonitorSettings<float> s;
    s.sample_rate_hz = static_cast<float>(fc.sample_rate_hz);
    s.octaves = m.octaves;
    s.alarms.arw_factor = static_cast<float>(m.arw_factor);
    s.alarms.bias_instability_factor = static_cast<float>(m.bias_instability_factor);
    s.alarms.rate_random_walk_factor = static_cast<float>(m.rate_random_walk_factor);
    s.alarms.false_alarm_probability = static_cast<float>(m.false_alarm_probability);
    s.alarms.stuck_samples = m.stuck_samples;
    s.alarms.saturated_samples = m.saturated_samples;
    s.reidentify = m.reidentify;
    s.drift.block_samples = m.block_samples;
    s.drift.retune_blocks = m.retune_blocks;
    s.drift.min_samples = m.min_samples;
    s.drift.memory_blocks = static_cast<float>(m.memory_blocks);
    s.drift.adapt_ar = m.reidentify_ar;
    s.drift.max_step = static_cast<float>(m.max_step);
    s.drift.max_rel_stderr = static_cast<float>(m.max_rel_stderr);
    s.identifier = m.lag_identifier ? DriftIdentifierKind::lag : DriftIdentifierKind::recursive;
    s.lag.fit_delay_samples = m.fit_delay_samples;
    s.lag.restart_after_fit = m.restart_after_fit;
    return s;
  }

  // The gyro monitor on the channels the file's [monitor] table selects, each compared
  // against its ar2_kalman model's Allan variance.
  bool init_monitor(const FileConfig& fc, GyroMonitorSettings<float> s, std::string& error) {
    const MonitorSpec& m = fc.monitor;
    std::array<Proc::MonitorReference, kImuGyroChannels>& refs = monitor_references_;  // the monitors read it
    refs = {};
    std::array<bool, kImuGyroChannels> on{};
    for (std::size_t c = 0; c < kImuGyroChannels; ++c) {
      on[c] = m.channels[c];
      if (!on[c]) continue;
      const ImuChannelConfig<float>& cc = fc.imu.channels[c];
      // the model's exact Allan variance and block edf per octave (computed in double)
      const DriftModelParams<float> model{cc.model.a1, cc.model.a2, cc.q, cc.r, cc.model.mean};
      if (!health_reference_from_drift_model(model, m.octaves, refs[c], s.alarms.block_terms)) {
        error = std::string("channels.") + config_schema::kChannelNames[c] +
                ": the monitor cannot compute this model's Allan variance";
        return false;
      }
    }
    if (with([&](auto& p) { return p.configure_monitor(s, refs, on); }) != GyroMonitorStatus::ok) {
      error = "monitor: the gyro monitor refuses this configuration (a value out of float range?)";
      return false;
    }
    return true;
  }

  // One input sample through the processor; true if it produced an output.
  bool step(const ImuSample<float>& in, ImuOutput<float>& out) noexcept {
    return (with([&](auto& p) noexcept { return p.step(in, out); }) & kFlagRejected) == 0U;
  }

  // Processor rejections (samples that produced no output).
  template <class F>
  void for_each_rejection(F&& field) const {
    for_each_rejection_field(health(), field);
  }

  template <class F>
  void for_each_health(F&& field) const {
    for_each_health_field(health(), field);
  }

  double sample_rate_hz() const noexcept { return sample_rate_hz_; }

 private:
  const ImuHealth& health() const noexcept {
    return proc_lag_ ? proc_lag_->health() : proc_->health();
  }

  // f on the processor in use.
  template <class F>
  auto with(F&& f) -> decltype(f(std::declval<Proc&>())) {
    if (proc_lag_) return f(*proc_lag_);
    return f(*proc_);
  }

  double sample_rate_hz_ = config_schema::kDefaultSampleRateHz;
  std::optional<Proc> proc_;
  std::optional<ProcLag> proc_lag_;
  // The monitors' reference curves (they refer to these for the processor's lifetime).
  std::array<Proc::MonitorReference, kImuGyroChannels> monitor_references_{};
};

}  // namespace gyrodrift::loop
