// The loop's processing stage: ImuProcessor<float> (with the real-time wavelet stage, any
// window of the format) configured from a configuration file (--config, config_file.hpp) or
// from the command line, and its JSON counters (names from imu/imu_processor.hpp, the one list).
#pragma once
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>

#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

#include "config_file.hpp"

namespace gyrodrift::loop {

// Command-line processor settings (one setting for the three gyros, one for the three
// accelerometers). The AR(2) default is only a demonstration model: identify your gyro's
// with gyrodrift.fit_ar2 and pass --gyro-ar2 / --gyro-q / --gyro-r.
struct ProcessingOptions {
  ChannelFilter gyro_filter = ChannelFilter::ar2_kalman;
  ChannelFilter accel_filter = ChannelFilter::pass_through;
  // a1, a2 (roots 0.5, 0.5: stationary), sigma2 and mean (rad/s), q and r ((rad/s)^2).
  double a1 = ImuDemoAr2::a1, a2 = ImuDemoAr2::a2, sigma2 = ImuDemoAr2::sigma2,
         mean = ImuDemoAr2::mean, q = ImuDemoAr2::q, r = ImuDemoAr2::r;
  double gyro_bias = 0.0, accel_bias = 0.0;
  double gyro_saturation = INFINITY, accel_saturation = INFINITY;
  std::uint32_t stuck_samples = 0;
  double sample_rate_hz = 400.0;
  long time_tolerance_us = -1;  // -1: half a sample period
};

inline bool parse_filter(const std::string& s, ChannelFilter& f) noexcept {
  if (s == "ar2_kalman") f = ChannelFilter::ar2_kalman;
  else if (s == "bias_removal") f = ChannelFilter::bias_removal;
  else if (s == "pass_through") f = ChannelFilter::pass_through;
  else return false;
  return true;
}

inline bool parse_csv4(const char* s, double (&v)[4]) noexcept {
  char* end = nullptr;
  for (int i = 0; i < 4; ++i) {
    v[i] = std::strtod(s, &end);
    if (end == s || !std::isfinite(v[i])) return false;
    if (i < 3) {
      if (*end != ',') return false;
      s = end + 1;
    }
  }
  return *end == '\0';
}

class Processing {
 public:
  // The window comes from the configuration file at run time: one stage type over every
  // window of the format (16..4096), each channel holding the instance it was given.
  using Wavelet = RealtimeWaveletAnyWindow<float>;
  using Proc = ImuProcessor<float, Wavelet>;

  // Builds the processor from command-line settings; false (with a message) if the
  // configuration is invalid, so a misconfigured loop refuses to start instead of rejecting
  // every sample.
  bool init(const ProcessingOptions& o, std::string& error) {
    ImuConfig<float> cfg;
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      ImuChannelConfig<float>& cc = cfg.channels[c];
      const bool gyro = c < 3;
      cc.filter = gyro ? o.gyro_filter : o.accel_filter;
      cc.bias = static_cast<float>(gyro ? o.gyro_bias : o.accel_bias);
      cc.saturation = static_cast<float>(gyro ? o.gyro_saturation : o.accel_saturation);
      cc.stuck_samples = o.stuck_samples;
      cc.model = Ar2Model<float>{static_cast<float>(o.a1), static_cast<float>(o.a2),
                                 static_cast<float>(o.sigma2), static_cast<float>(o.mean)};
      cc.q = static_cast<float>(o.q);
      cc.r = static_cast<float>(o.r);
    }
    const double period_us = 1e6 / o.sample_rate_hz;
    cfg.period_us = static_cast<std::uint32_t>(std::lround(period_us));
    cfg.time_tolerance_us = static_cast<std::uint32_t>(
        o.time_tolerance_us < 0 ? std::lround(period_us / 2.0) : o.time_tolerance_us);
    sample_rate_hz_ = o.sample_rate_hz;
    proc_.emplace(cfg, [](std::size_t) { return Wavelet{}; });  // no wavelet stage from the command line
    if (proc_->status() != ImuStatus::ok) {
      error = "invalid processor configuration (channel " + std::to_string(proc_->bad_channel()) +
              "): check --gyro-ar2/--gyro-q/--gyro-r, biases (pass_through needs bias 0) and saturation";
      return false;
    }
    return true;
  }

  // Builds the processor from a configuration file's content (already checked key by key).
  // Each channel's wavelet stage is built in place for the file's window.
  bool init(const FileConfig& fc, std::string& error) {
    sample_rate_hz_ = fc.sample_rate_hz;
    proc_.emplace(fc.imu, [&fc](std::size_t c) {
      const WaveletSpec& w = fc.wavelets[c];
      return Wavelet(w.window, w.kind, w.level, w.mode);
    });
    if (proc_->status() != ImuStatus::ok) {
      error = "invalid processor configuration (channel " + std::to_string(proc_->bad_channel()) + ")";
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
  double sample_rate_hz_ = 400.0;
  std::optional<Proc> proc_;
};

}  // namespace gyrodrift::loop
