// The loop's processing stage: ImuProcessor<float> (with the real-time wavelet stage, any
// window of the format) configured from a configuration (--config FILE, or the built-in
// default configuration; config_file.hpp), and its JSON counters (names from
// imu/imu_processor.hpp, the one list).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/config_schema.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

#include "config_file.hpp"

namespace gyrodrift::loop {

// The most octaves a configuration may give the monitor (the schema's bound): the loop's capacity.
inline constexpr std::size_t kLoopMonitorOctaves = static_cast<std::size_t>(config_schema::kMonitorOctaves.hi);

// The exact non-overlapped Allan variance of the drift model "AR(2) drift + white noise" at
// averaging factors m = 2^k, k < octaves (gyrodrift.imu.monitor.model_avar, the same sum):
//   sigma^2(m) = r / m + (1 / m^2) [ m g0 + 2 sum_{k=1}^{m-1} (m - k) g_k - sum_{k=1}^{2m-1} min(k, 2m - k) g_k ]
// with g_k the drift's autocovariance (g_k = a1 g_{k-1} + a2 g_{k-2}), in double on the host;
// one pass over the lags, each lag added to the octaves it belongs to.
inline void drift_model_avar(double a1, double a2, double q, double r, std::size_t octaves, double* out) {
  const double d = (1.0 + a2) * ((1.0 - a2) * (1.0 - a2) - a1 * a1);
  const double g0 = q == 0.0 ? 0.0 : q * (1.0 - a2) / d;
  const double g1 = q == 0.0 ? 0.0 : a1 * g0 / (1.0 - a2);
  std::array<double, kLoopMonitorOctaves> var_sum{}, cov_sum{};
  if (octaves > kLoopMonitorOctaves) octaves = kLoopMonitorOctaves;
  const std::uint64_t lags = std::uint64_t{1} << octaves;  // 2 m_max
  double gm2 = g0, gm1 = g1;
  for (std::uint64_t k = 1; k < lags; ++k) {
    const double gk = k == 1 ? g1 : a1 * gm1 + a2 * gm2;
    if (k > 1) {
      gm2 = gm1;
      gm1 = gk;
    }
    for (std::size_t j = 0; j < octaves; ++j) {
      const std::uint64_t m = std::uint64_t{1} << j;
      if (k >= 2 * m) continue;
      if (k < m) var_sum[j] += static_cast<double>(m - k) * gk;
      cov_sum[j] += static_cast<double>(k < m ? k : 2 * m - k) * gk;
    }
  }
  for (std::size_t j = 0; j < octaves; ++j) {
    const auto m = static_cast<double>(std::uint64_t{1} << j);
    out[j] = r / m + (m * g0 + 2.0 * var_sum[j] - cov_sum[j]) / (m * m);
  }
}

class Processing {
 public:
  // The window comes from the configuration file at run time: one stage type over every
  // window of the format (16..4096), each channel holding the instance it was given.
  using Wavelet = RealtimeWaveletAnyWindow<float>;
  static constexpr std::size_t kMonitorOctaves = kLoopMonitorOctaves;
  using Proc = ImuProcessor<float, Wavelet, kImuChannels, kMonitorOctaves>;

  // Builds the processor from a configuration's content (already checked key by key); false
  // (with a message) if the processor still refuses it, so a misconfigured loop refuses to
  // start instead of rejecting every sample. Each channel's wavelet stage is built in place
  // for the file's window.
  bool init(const FileConfig& fc, std::string& error) {
    sample_rate_hz_ = fc.sample_rate_hz;
    proc_.emplace(fc.imu, [&fc](std::size_t c) {
      const WaveletSpec& w = fc.wavelets[c];
      return Wavelet(w.window, w.kind, w.level, w.mode);
    });
    if (proc_->status() != ImuStatus::ok) {
      // The file's values passed the reader's checks in double; the float processor refuses
      // them (a value that is 0 or not finite in float).
      const int c = proc_->bad_channel();
      error = (c >= 0 ? std::string("channels.") + config_schema::kChannelNames[c] + ": " : std::string()) +
              "invalid processor configuration (a value out of float range?)";
      return false;
    }
    return fc.monitor.enabled ? init_monitor(fc, error) : true;
  }

  // The gyro monitor on the channels the file's [monitor] table selects, each compared
  // against its ar2_kalman model's Allan variance.
  bool init_monitor(const FileConfig& fc, std::string& error) {
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
    s.drift.max_step = static_cast<float>(m.max_step);
    s.drift.max_rel_stderr = static_cast<float>(m.max_rel_stderr);
    std::array<Proc::MonitorReference, kImuGyroChannels> refs{};
    std::array<bool, kImuGyroChannels> on{};
    for (std::size_t c = 0; c < kImuGyroChannels; ++c) {
      on[c] = m.channels[c];
      if (!on[c]) continue;
      const ImuChannelConfig<float>& cc = fc.imu.channels[c];
      double avar[kMonitorOctaves] = {};
      drift_model_avar(static_cast<double>(cc.model.a1), static_cast<double>(cc.model.a2), static_cast<double>(cc.q),
                       static_cast<double>(cc.r), m.octaves, avar);
      refs[c].octaves = m.octaves;
      for (std::size_t k = 0; k < m.octaves; ++k) refs[c].avar[k] = static_cast<float>(avar[k]);
    }
    if (proc_->configure_monitor(s, refs, on) != GyroMonitorStatus::ok) {
      error = "monitor: the gyro monitor refuses this configuration (a value out of float range?)";
      return false;
    }
    return true;
  }

  // One input sample through the processor; true if it produced an output.
  bool step(const ImuSample<float>& in, ImuOutput<float>& out) noexcept {
    return (proc_->step(in, out) & kFlagRejected) == 0U;
  }

  // Processor rejections (samples that produced no output).
  template <class F>
  void for_each_rejection(F&& field) const {
    for_each_rejection_field(proc_->health(), field);
  }

  template <class F>
  void for_each_health(F&& field) const {
    for_each_health_field(proc_->health(), field);
  }

  double sample_rate_hz() const noexcept { return sample_rate_hz_; }

 private:
  double sample_rate_hz_ = config_schema::kDefaultSampleRateHz;
  std::optional<Proc> proc_;
};

}  // namespace gyrodrift::loop
