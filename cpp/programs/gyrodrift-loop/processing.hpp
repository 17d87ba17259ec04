// The loop's processing stage: ImuProcessor<float> (with the real-time wavelet stage, any
// window of the format) configured from a configuration (--config FILE, or the built-in
// default configuration; config_file.hpp), and its JSON counters (names from
// imu/imu_processor.hpp, the one list).
#pragma once
#include <cstddef>
#include <optional>
#include <string>

#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/config_schema.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

#include "config_file.hpp"

namespace gyrodrift::loop {

class Processing {
 public:
  // The window comes from the configuration file at run time: one stage type over every
  // window of the format (16..4096), each channel holding the instance it was given.
  using Wavelet = RealtimeWaveletAnyWindow<float>;
  using Proc = ImuProcessor<float, Wavelet>;

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
