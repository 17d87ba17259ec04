// The on-target monitor of one gyro channel: streaming Allan statistics of its raw input, the
// IEEE 952 noise estimates read from them (N, B, K with intervals), latched health alarms
// against a reference Allan curve, and the online re-identification of the channel's drift
// model "AR(2) drift + white noise", whose steady-state Kalman gain the processor may take.
//
//   StreamingAllan<Scalar, Octaves>   stability/streaming_allan.hpp
//   estimate_noise                    stability/online_noise.hpp (at report time, not per sample)
//   HealthAlarms<Scalar, Octaves>     imu/health_alarms.hpp (per sample)
//   OnlineDriftIdentifier<Scalar>     filters/online_drift_identifier.hpp (per sample, optional;
//                                     Kind recursive)
//   LagDriftIdentifier<Scalar, 1>     filters/lag_drift_identifier.hpp (Kind lag: the statistics per
//                                     sample, a fit at its cadence)
//
// push(y, stuck, saturated) once per sample of the channel, after the processor's bad-value
// checks: a stuck or saturated value (or a non-finite one) is not a statistic's input, but the
// stuck and saturated flags go to the alarms, which count how long they last.
//
// Fixed memory chosen at compile time (Octaves: the largest number of octaves a configuration
// may use; Reidentify false: no re-identification state, and configure() refuses
// settings.reidentify; Records false: the alarms keep no trips or counts and refer to the
// reference and their settings instead of copying them, HealthAlarms' Records), no heap, no exceptions,
// deterministic (the same input gives the same state). Kind: which re-identification the
// build holds (one of the two, for its RAM); configure() refuses a settings.identifier that is
// not it when settings.reidentify is on. The processor's monitors are built
// with neither (it reports the latched bits and counts alarms itself, and shares one
// re-identification among its gyros: filters/shared_drift_identifier.hpp).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "../filters/drift_likelihood.hpp"
#include "../filters/lag_drift_identifier.hpp"
#include "../filters/online_drift_identifier.hpp"
#include "../stability/online_noise.hpp"
#include "../stability/streaming_allan.hpp"
#include "health_alarms.hpp"

namespace gyrodrift {

template <class Scalar>
struct GyroMonitorSettings {
  Scalar sample_rate_hz = Scalar(0);         // sample rate of the channel, Hz
  std::size_t octaves = 0;                   // octaves of the streaming Allan curve (<= Octaves)
  HealthAlarmSettings<Scalar> alarms{};      // alarm factors, false-alarm probability, durations
  bool reidentify = false;                   // run the online re-identification
  OnlineDriftSettings<Scalar> drift{};       // its block, retune cadence, guards
  // Which re-identification: the recursive estimator or the fit from lag statistics (the
  // build must hold it: GyroMonitor's Kind, ImuProcessor's MonitorIdentifier).
  DriftIdentifierKind identifier = DriftIdentifierKind::recursive;
  LagDriftSettings<Scalar> lag{};            // the lag identifier's schedule (fit delay, restart)
};

enum class GyroMonitorStatus : std::uint8_t {
  unconfigured = 0,  // configure() not called
  ok = 1,
  bad_settings = 2,   // rate, octaves or the reference out of range
  bad_model = 3,      // the drift model is not a valid stationary model
};

namespace detail {
struct NoDriftIdentifier {};  // the re-identification compiled out

// The kind of a re-identification type (the recursive ones unless specialised).
template <class T>
struct DriftIdentifierKindOf {
  static constexpr DriftIdentifierKind value = DriftIdentifierKind::recursive;
};
template <class S, std::size_t C, std::size_t L>
struct DriftIdentifierKindOf<LagDriftIdentifier<S, C, L>> {
  static constexpr DriftIdentifierKind value = DriftIdentifierKind::lag;
};
}  // namespace detail

template <class T>
inline constexpr DriftIdentifierKind drift_identifier_kind_v = detail::DriftIdentifierKindOf<T>::value;

template <class Scalar, std::size_t Octaves, bool Reidentify = true, bool Records = true,
          DriftIdentifierKind Kind = DriftIdentifierKind::recursive>
class GyroMonitor {
 public:
  static constexpr std::size_t capacity = Octaves;
  static constexpr bool kReidentify = Reidentify;
  static constexpr bool kRecords = Records;
  static constexpr DriftIdentifierKind kIdentifierKind = Kind;
  using Identifier = std::conditional_t<Kind == DriftIdentifierKind::lag, LagDriftIdentifier<Scalar, 1>,
                                        OnlineDriftIdentifier<Scalar>>;
  using Reference = HealthReference<Scalar, Octaves>;
  using Alarms = HealthAlarms<Scalar, Octaves, Records>;

  GyroMonitor() noexcept = default;

  // Without Records the alarms refer to `reference` and settings.alarms: they must outlive
  // the monitor.
  template <bool R = Records, class = std::enable_if_t<!R>>
  GyroMonitorStatus configure(const GyroMonitorSettings<Scalar>& settings, const DriftModelParams<Scalar>& model,
                              Reference&& reference) = delete;

  // settings: see GyroMonitorSettings; model: the channel's configured drift model (the
  // identifier's start and fallback); reference: the expected Allan variance per octave that
  // the alarms compare against (reference.octaves >= 1, at most settings.octaves).
  GyroMonitorStatus configure(const GyroMonitorSettings<Scalar>& settings, const DriftModelParams<Scalar>& model,
                              const Reference& reference) noexcept {
    return configure(settings, settings.alarms, model, reference);
  }
  // The same with the alarms' settings `alarms` instead of settings.alarms (without Records the
  // alarms refer to them: several monitors may share one copy, which must outlive them).
  template <bool R = Records, class = std::enable_if_t<!R>>
  GyroMonitorStatus configure(const GyroMonitorSettings<Scalar>& settings, HealthAlarmSettings<Scalar>&& alarms,
                              const DriftModelParams<Scalar>& model, const Reference& reference) = delete;
  GyroMonitorStatus configure(const GyroMonitorSettings<Scalar>& settings, const HealthAlarmSettings<Scalar>& alarms,
                              const DriftModelParams<Scalar>& model, const Reference& reference) noexcept {
    reidentify_ = Reidentify && settings.reidentify;
    status_ = GyroMonitorStatus::bad_settings;
    if (settings.reidentify && (!Reidentify || settings.identifier != Kind)) return status_;
    if (settings.octaves < 1 || settings.octaves > Octaves || reference.octaves < 1 ||
        reference.octaves > settings.octaves) {
      return status_;
    }
    if (!allan_.configure(settings.sample_rate_hz, settings.octaves)) return status_;
    for (std::size_t k = 0; k < reference.octaves; ++k) {
      if (!(reference.avar[k] > Scalar(0)) || !std::isfinite(reference.avar[k])) return status_;
    }
    if (drift_params_status(model) != Ar2Status::ok) {
      status_ = GyroMonitorStatus::bad_model;
      return status_;
    }
    if (!alarms_.configure(reference, alarms)) return status_;
    if constexpr (Reidentify) {
      bool configured = true;
      if constexpr (Kind == DriftIdentifierKind::lag) {
        if (settings.reidentify) configured = identifier_.configure(&model, 1, settings.drift, settings.lag);
      } else {
        if (settings.reidentify) configured = identifier_.configure(model, settings.drift);
      }
      if (!configured) {
        // the identifier's own rules: a model with white noise (r > 0), its block and memory
        status_ = model.r > Scalar(0) ? GyroMonitorStatus::bad_settings : GyroMonitorStatus::bad_model;
        return status_;
      }
    }
    status_ = GyroMonitorStatus::ok;
    reset();
    return status_;
  }

  // Forgets every sample and clears the alarms; keeps the configuration.
  void reset() noexcept {
    allan_.reset();
    alarms_.reset();
    if constexpr (Reidentify) {
      if (reidentify_) identifier_.reset();
    }
    retuned_ = false;
  }

  // One sample of the channel. stuck/saturated: the processor's checks flagged this value (it
  // is then not used by the statistics). Returns the latched alarm bits (0: healthy).
  std::uint16_t push(Scalar y, bool stuck, bool saturated) noexcept {
    retuned_ = false;
    if (status_ != GyroMonitorStatus::ok) return 0;
    // Every sample updates the alarms (their sample count, and the time of a trip, are the
    // monitor's); a non-finite value feeds no statistic and ends a stuck or saturated run.
    const bool bad = stuck || saturated;
    const bool used = !bad && std::isfinite(y) &&
                      allan_.push(y, [this](std::size_t k, Scalar d2) noexcept { alarms_.term(allan_, k, d2); });
    if constexpr (Reidentify) {
      if (reidentify_) {
        if constexpr (Kind == DriftIdentifierKind::lag) {
          // every sample counts for the fits' schedule; the statistics take the used ones
          if (used) {
            identifier_.push(0, y);
          } else {
            identifier_.skip(0);
          }
          retuned_ = identifier_.retuned();
        } else if (used) {
          identifier_.push(y);
          retuned_ = identifier_.retuned();
        }
      }
    }
    return alarms_.update(stuck, saturated);
  }

  // Noise estimates from the curve so far (report time: a few octave fits, not per sample).
  bool noise(Scalar coverage, NoiseEstimates<Scalar>& out) const noexcept {
    if (status_ != GyroMonitorStatus::ok) {
      out = NoiseEstimates<Scalar>{};
      return false;
    }
    return estimate_noise(allan_, coverage, out);
  }

  GyroMonitorStatus status() const noexcept { return status_; }
  const StreamingAllan<Scalar, Octaves>& allan() const noexcept { return allan_; }
  const Alarms& alarms() const noexcept { return alarms_; }
  template <bool R = Reidentify, class = std::enable_if_t<R>>
  const Identifier& identifier() const noexcept {
    return identifier_;
  }
  std::uint16_t latched() const noexcept { return alarms_.latched(); }
  // True after the push() whose sample made the identifier retune the gain.
  bool retuned() const noexcept { return retuned_; }
  bool reidentifying() const noexcept { return reidentify_ && status_ == GyroMonitorStatus::ok; }
  std::uint64_t samples() const noexcept { return alarms_.updates(); }  // pushed (all)
  std::uint64_t used() const noexcept { return allan_.samples(); }      // used by the statistics

 private:
  StreamingAllan<Scalar, Octaves> allan_{};
  Alarms alarms_{};
  std::conditional_t<Reidentify, Identifier, detail::NoDriftIdentifier> identifier_{};
  GyroMonitorStatus status_ = GyroMonitorStatus::unconfigured;
  bool retuned_ = false;
  bool reidentify_ = false;  // the settings are kept by the parts that use them
};

}  // namespace gyrodrift
