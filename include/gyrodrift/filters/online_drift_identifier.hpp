// Online re-identification of the drift model "AR(2) drift + white noise" (the model of
// drift_likelihood.hpp and of the offline fit gyrodrift.filters.fit_drift_model), for a
// navigation computer that retunes its steady-state AR(2)-Kalman gain while it runs.
//
// INTERFACE SKELETON: the estimator below is not implemented yet (it keeps the configured
// model). The public names and meanings are fixed; the implementation replaces the bodies.
//
// Allocation-free, noexcept, deterministic, templated on Scalar.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "drift_likelihood.hpp"

namespace gyrodrift {

enum class OnlineDriftStatus : std::uint8_t {
  unconfigured = 0,    // configure() not called or refused
  learning = 1,        // fewer than min_samples: the configured model is in use
  tracking = 2,        // an identified estimate is in use by the gain
  not_identified = 3,  // the estimate's drift/noise split is not identified: configured model in use
  fallback = 4,        // a guard rejected the estimate (diverged, non-stationary): configured model in use
};

template <class Scalar>
struct OnlineDriftSettings {
  std::uint32_t block_samples = 400;   // samples per parameter update
  std::uint32_t retune_blocks = 60;    // parameter updates between gain retunes
  std::uint64_t min_samples = 240000;  // no retune before this many accepted samples
  Scalar memory_blocks = Scalar(0);    // forgetting horizon in blocks; 0: none (converges to the ML fit)
  Scalar max_step = Scalar(0.1);       // largest change of one parameter per update (log q, log r; AR part)
  Scalar max_rel_stderr = Scalar(0.5); // split identified when the relative stderr of q and r is <= this
};

template <class Scalar>
class OnlineDriftIdentifier {
 public:
  OnlineDriftIdentifier() noexcept = default;

  // The configured model is the start and the fallback. Returns false (status unconfigured)
  // for an invalid model or settings.
  bool configure(const DriftModelParams<Scalar>& configured, const OnlineDriftSettings<Scalar>& s) noexcept {
    configured_ = configured;
    estimate_ = configured;
    in_use_ = configured;
    settings_ = s;
    status_ = drift_params_status(configured) == Ar2Status::ok ? OnlineDriftStatus::learning
                                                                : OnlineDriftStatus::unconfigured;
    samples_ = 0;
    rejected_ = 0;
    return status_ != OnlineDriftStatus::unconfigured;
  }

  // Back to the configured model, counters cleared.
  void reset() noexcept { configure(configured_, settings_); }

  // One rate sample (units of the model, e.g. rad/s). NaN/Inf: skipped and counted, false.
  bool push(Scalar y) noexcept {
    if (status_ == OnlineDriftStatus::unconfigured || !std::isfinite(y)) {
      ++rejected_;
      return false;
    }
    ++samples_;
    return true;
  }

  OnlineDriftStatus status() const noexcept { return status_; }
  const DriftModelParams<Scalar>& configured() const noexcept { return configured_; }
  const DriftModelParams<Scalar>& estimate() const noexcept { return estimate_; }  // running estimate
  const DriftModelParams<Scalar>& in_use() const noexcept { return in_use_; }      // the gain's model
  // Approximate standard errors of the running estimate; false while they do not exist.
  bool stderrs(DriftModelParams<Scalar>& se) const noexcept {
    (void)se;
    return false;
  }
  // Steady-state Kalman gain (k0, k1) of in_use(); changes only at a retune.
  Scalar gain0() const noexcept { return gain_[0]; }
  Scalar gain1() const noexcept { return gain_[1]; }
  // True after the push() that retuned the gain (until the next push()).
  bool retuned() const noexcept { return retuned_; }
  std::uint32_t retunes() const noexcept { return retunes_; }
  std::uint32_t refused_retunes() const noexcept { return refused_retunes_; }
  std::uint64_t samples() const noexcept { return samples_; }
  std::uint64_t rejected() const noexcept { return rejected_; }

 private:
  DriftModelParams<Scalar> configured_{};
  DriftModelParams<Scalar> estimate_{};
  DriftModelParams<Scalar> in_use_{};
  OnlineDriftSettings<Scalar> settings_{};
  OnlineDriftStatus status_ = OnlineDriftStatus::unconfigured;
  Scalar gain_[2] = {Scalar(0), Scalar(0)};
  bool retuned_ = false;
  std::uint32_t retunes_ = 0;
  std::uint32_t refused_retunes_ = 0;
  std::uint64_t samples_ = 0;
  std::uint64_t rejected_ = 0;
};

}  // namespace gyrodrift
