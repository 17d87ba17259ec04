// Re-identification of the drift model "AR(2) drift + white noise" (drift_likelihood.hpp, the
// offline fit gyrodrift.filters.fit_drift_model) from whole-record lag statistics, for up to
// `Channels` gyro channels: each channel keeps LagStatisticsNoHead<Scalar, Lags>
// (lag_statistics.hpp) of its samples, and at a slow cadence its drift model is fitted from
// them in double (lag_drift_fit.hpp, the kind whittle_no_head) and its steady-state
// AR(2)-Kalman gain retuned. Unlike the recursive estimator (online_drift_identifier.hpp,
// shared_drift_identifier.hpp), no estimate is carried from block to block: every fit
// maximises the likelihood of the statistics it reads, with the multi-start across the fold at
// a2 = 0, so it converges to the offline maximum-likelihood fit of the same samples
// (docs/validation/online-identification.md, "Whole-record statistics" and "The fit from lag
// statistics as the monitor's identifier"). The same calls as SharedDriftIdentifier where a
// processor uses them, and a few more (status, statistics, paused samples, the schedule).
//
// Settings. OnlineDriftSettings supplies the shared ones:
//   - cadence = retune_blocks * block_samples samples of a channel (push() and skip() both
//     count): the interval between two fits of one channel;
//   - min_samples: no fit from fewer statistics samples (nor below lag_drift_min_samples(L));
//     the request is then dropped (not a refusal, not counted) and the channel keeps its model;
//   - max_step: the bounded step. A retune moves the model in use toward the fit by at most
//     max_step in log q, in log r and in the AR part's coordinates u1 = atanh(a1 / (1 - a2)),
//     u2 = atanh(a2) (the fit's), the step scaled as a whole (its direction kept: the
//     parameters are correlated along the likelihood's ridge, as in the recursive
//     identifier); the mean is the fit's;
//   - max_rel_stderr and min_ar_wald: identification guards from the Hessian of the profile
//     f(u) = -(profile log-likelihood) / n at the fit's u = (u1, u2, u3), u3 = logit(lam),
//     lam = q / (q + r), by central differences (step kLagIdentifierHessianStep in every u;
//     19 evaluations): Cov(u) ~ (n Hess f)^-1. The relative standard errors of q and r are
//     taken as (1 - lam) SE(u3) and lam SE(u3) (d log q / d u3 = 1 - lam, d log r / d u3 =
//     -lam; this neglects the uncertainty of the profiled common scale of q and r, whose
//     relative standard error is of order sqrt(2 / n), and its correlation with u3); the split is
//     identified when both are at most max_rel_stderr and (with adapt_ar) the Wald statistic of
//     (u1, u2) against white drift, u12^T Cov(u12)^-1 u12, is at least min_ar_wald. A Hessian
//     that is not positive definite means "not identified" too;
//   - adapt_ar: true fits a1, a2, q, r (lag_drift_fit); false holds a1, a2 at the configured
//     model and fits the split only (u3; the mean and the scale in closed form as always): a
//     one-dimensional BFGS (the fit's maximiser over u3 alone) from the best of 11 splits
//     (0.02, 0.1, 0.2, ..., 0.9, 0.98). ar_order 1 needs adapt_ar false (a configured a2 of 0,
//     held); with adapt_ar, configure() refuses ar_order 1 (the fit is AR(2)).
//   block_samples, retune_blocks enter only through the cadence; memory_blocks, warmup_blocks,
//   lambda_start, info_blocks and max_innovation_ratio are the recursive estimator's and are
//   not used here.
// LagDriftSettings adds the schedule: fit_delay_samples, restart_after_fit, max_iterations.
//
// Schedule. Channel i's fits are requested when its sample count reaches
// cadence + i * cadence / n, then every cadence (staggered, so one fit at a time: configure()
// refuses n * fit_delay_samples > cadence). One fit's working state exists once; a channel
// whose request comes while another channel's fit holds it requests again at each of its next
// samples until it is free. While the counts of the channels stay equal (the processor pushes
// or skips every watched channel on every sample) that happens only at n * fit_delay_samples
// = cadence, where a request can fall on the sample at which the previous channel's fit
// applies, and a channel pushed before that one then waits one sample.
//   - At the request (if the statistics have enough samples) the channel's statistics pause:
//     its samples from then on are counted (paused(c)) but not pushed. The fit reads the
//     paused statistics in place, so no copy is needed.
//   - At the apply point, the request's sample count + fit_delay_samples: the fit's outcome
//     applies. Accepted (the fit's status ok, the guards pass, the gain converges): the model
//     in use moves toward the fit (bounded step), its steady-state gain (Ar2SteadyStateKalman,
//     as the configured model's) is recomputed, retunes(c)++, status tracking. Refused: the
//     configured model and its gain are put back (the fallback, as the recursive identifier's),
//     refused_retunes(c)++, status not_identified (guards) or fallback (the fit's status not
//     ok, a non-finite estimate or a gain that does not converge). retuned() is true after the
//     push()/skip() that applied an accepted fit, or a refused one that changed the gain back.
//     Then the statistics resume (emptied first with restart_after_fit: each fit then reads
//     only the samples since the channel's previous fit; a request dropped for too few samples
//     does not restart them).
//   - Inline (the default, host): the fit runs at the request, inside push()/skip().
//     Deferred (defer_fits(true), a target): push()/skip() only mark it; thread mode calls
//     run_pending_fit() (while the loop's interrupt keeps pushing). At the apply point the
//     push()/skip() uses the outcome if the fit is done; if not, late_fits()++, the channel's
//     statistics stay paused until it is done, and its outcome is then discarded (nothing
//     applied or counted but the late fit; the statistics resume, restarted with
//     restart_after_fit). The hand-over is one std::atomic<bool> each way (lock-free on the
//     Cortex-M4). The fit's outcome (guards, bounded step, gain) is computed by the fit, so the
//     apply point only copies it. Host and target agree sample for sample whenever
//     late_fits() == 0.
//   configure() and reset() must not run while a deferred fit runs (the fit reads the
//   channel's statistics and settings): stop calling run_pending_fit() first.
//
// Precision: the statistics in Scalar (float on the MCU: compensated sums, lag_statistics.hpp);
// the fit, the guards and the bounded step in double (software double on the Cortex-M4F; the
// likelihood must resolve 1e-7 of its value); the model in use and the gain in Scalar.
// Memory: per channel the statistics (136 B for <float, 8>) and 120 B for its models, gains,
// counters (paused and rejected 32-bit, saturating) and schedule; once: the settings the fit,
// its guards and the bounded step use (not OnlineDriftSettings whole) and the fit's outcome
// (its model in double, the stepped model and its gain; no LagDriftFitResult is kept).
// sizeof(LagDriftIdentifier<float, 3>) is 904 B on the Cortex-M4 (920 on x86-64), <float, 1>
// 392 B (408): checked in cpp/tests/test_lag_drift_identifier.cpp and
// cpp/cortex_m/use_lag_drift_identifier.cpp. The fit's stack is the caller's of push()
// (inline) or of run_pending_fit() (deferred): the fit runs first and returns, then the guards
// (the Hessian's evaluations), then the bounded step and the gain, each out of line
// (GYRODRIFT_NOINLINE), so that their states never sit on one another's. On the M4 at L = 8,
// below the caller of run_pending_fit(): 1124 B (adapt_ar; the gate unit's fit_stack), and the
// gate unit's whole high-water mark, three gyros with their fits and guards, 1412 B.
// Cost: per sample per channel the statistics' L + 1 products and compensated sums; a fit is
// about 3.3e7 instructions of software double on a Cortex-M4F at L = 8 (lag_drift_fit.hpp).
// No heap, no exceptions, deterministic.
#pragma once

#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "ar2_model.hpp"
#include "ar2_steady_state.hpp"
#include "drift_likelihood.hpp"
#include "lag_drift_fit.hpp"
#include "lag_statistics.hpp"
#include "online_drift_identifier.hpp"

namespace gyrodrift {

// Which re-identification a monitor runs: the recursive estimator (online_drift_identifier.hpp,
// shared_drift_identifier.hpp) or the fit from lag statistics (this header).
enum class DriftIdentifierKind : std::uint8_t { recursive = 0, lag = 1 };

inline const char* to_string(DriftIdentifierKind k) noexcept {
  return k == DriftIdentifierKind::lag ? "lag" : "recursive";
}

// L of the statistics: Whittle's likelihood without the first samples is within 0.07 offline
// standard errors of the exact fit at L = 8 on the convergence records
// (docs/validation/online-identification.md, "Whittle without the first samples, by L").
inline constexpr std::size_t kLagIdentifierLags = 8;
// Central-difference step of the guards' Hessian in u (f is a per-sample value of order 1
// evaluated to about 1e-15 relative: the second difference's rounding is about 1e-8 of f, its
// truncation about 1e-6 relative).
inline constexpr double kLagIdentifierHessianStep = 1e-3;

template <class Scalar>
struct LagDriftSettings {
  std::uint32_t fit_delay_samples = 12000;  // samples from a fit's request to the retune that applies it
  bool restart_after_fit = false;           // each fit uses only the samples since the gyro's previous fit
  std::uint32_t max_iterations = kLagDriftMaxIterations;  // BFGS iterations per run
};

template <class Scalar, std::size_t Channels, std::size_t Lags = kLagIdentifierLags>
class LagDriftIdentifier {
  static_assert(Channels >= 1 && Channels <= 8, "Channels in 1..8");

 public:
  using Statistics = LagStatisticsNoHead<Scalar, Lags>;
  static constexpr std::size_t capacity = Channels;
  static constexpr std::size_t lags = Lags;

  LagDriftIdentifier() noexcept = default;
  // A copy takes the state as it is (not while a deferred fit runs).
  LagDriftIdentifier(const LagDriftIdentifier& o) noexcept { *this = o; }
  LagDriftIdentifier& operator=(const LagDriftIdentifier& o) noexcept {
    if (this == &o) return *this;
    for (std::size_t c = 0; c < Channels; ++c) tracks_[c] = o.tracks_[c];
    guards_ = o.guards_;
    lag_ = o.lag_;
    outcome_ = o.outcome_;
    cadence_ = o.cadence_;
    n_ = o.n_;
    owner_ = o.owner_;
    pending_.store(o.pending_.load(std::memory_order_acquire), std::memory_order_relaxed);
    done_.store(o.done_.load(std::memory_order_acquire), std::memory_order_relaxed);
    late_fits_.store(o.late_fits_.load(std::memory_order_relaxed), std::memory_order_relaxed);
    deferred_ = o.deferred_;
    retuned_ = o.retuned_;
    return *this;
  }

  // Channels 0 .. n - 1 with their configured models (each one's start and fallback), one
  // setting for all. False (no channel configured) for n outside 1..Channels, settings out of
  // range (header comment: block_samples, retune_blocks >= 1, max_step, max_rel_stderr > 0,
  // min_ar_wald >= 0, ar_order 1 only with adapt_ar false, n * fit_delay_samples <= cadence,
  // max_iterations >= 1) or a model refused (drift_params_status not ok, r <= 0, a2 != 0 with
  // ar_order 1, its steady-state gain not converging); `failed` is then the first channel
  // refused (n for a bad n or bad settings). Inline fits after configure().
  bool configure(const DriftModelParams<Scalar>* models, std::size_t n, const OnlineDriftSettings<Scalar>& s,
                 const LagDriftSettings<Scalar>& lag, std::size_t* failed = nullptr) noexcept {
    n_ = 0;
    deferred_ = false;
    guards_ = Guards{s.min_samples, s.max_step, s.max_rel_stderr, s.min_ar_wald, s.adapt_ar};
    lag_ = lag;
    const std::uint64_t cadence = static_cast<std::uint64_t>(s.block_samples) * s.retune_blocks;
    const bool settings_ok = models != nullptr && n >= 1 && n <= Channels && s.block_samples >= 1 &&
                             s.retune_blocks >= 1 && std::isfinite(s.max_step) && s.max_step > Scalar(0) &&
                             std::isfinite(s.max_rel_stderr) && s.max_rel_stderr > Scalar(0) &&
                             std::isfinite(s.min_ar_wald) && s.min_ar_wald >= Scalar(0) &&
                             (s.ar_order == 2 || (s.ar_order == 1 && !s.adapt_ar)) && lag.max_iterations >= 1 &&
                             static_cast<std::uint64_t>(n) * lag.fit_delay_samples <= cadence;
    if (!settings_ok) {
      if (failed != nullptr) *failed = n;
      return false;
    }
    for (std::size_t c = 0; c < n; ++c) {
      const DriftModelParams<Scalar>& m = models[c];
      bool ok = drift_params_status(m) == Ar2Status::ok && m.r > Scalar(0) && (s.ar_order == 2 || m.a2 == Scalar(0));
      if (ok) {
        const Ar2SteadyStateKalman<Scalar> kf(Ar2Model<Scalar>{m.a1, m.a2, m.q, Scalar(0)}, m.q, m.r);
        ok = kf.status() == Ar2Status::ok;
        if (ok) {
          tracks_[c].configured = m;
          tracks_[c].cgain[0] = kf.gain()(0);
          tracks_[c].cgain[1] = kf.gain()(1);
        }
      }
      if (!ok) {
        if (failed != nullptr) *failed = c;
        return false;
      }
    }
    cadence_ = cadence;
    n_ = n;
    reset();
    return true;
  }

  // Every channel back to its configured model, statistics emptied, counters (late_fits too)
  // cleared, the schedule restarted, no fit pending. Not while a deferred fit runs.
  void reset() noexcept {
    retuned_ = false;
    owner_ = kNone;
    pending_.store(false, std::memory_order_relaxed);
    done_.store(false, std::memory_order_relaxed);
    late_fits_.store(0, std::memory_order_relaxed);
    for (std::size_t c = 0; c < n_; ++c) {
      Track& t = tracks_[c];
      t.stats.reset();
      t.in_use = t.configured;
      t.estimate = t.configured;
      t.gain[0] = t.cgain[0];
      t.gain[1] = t.cgain[1];
      t.samples = 0;
      t.paused = t.rejected = 0;
      t.next_request = cadence_ + c * cadence_ / n_;
      t.apply_at = 0;
      t.retunes = t.refused = 0;
      t.fit_status = LagDriftFitStatus::too_few_samples;
      t.status = OnlineDriftStatus::learning;
      t.phase = Phase::collecting;
    }
  }

  // One sample of channel c (after the caller's bad-value checks). False for a channel out of
  // range or unconfigured, or a sample the statistics refuse (NaN/Inf: counted in rejected(c)
  // and the schedule's count, as skip()). While the channel's statistics pause for a fit the
  // sample is counted in paused(c), not pushed (true).
  bool push(std::size_t c, Scalar y) noexcept {
    retuned_ = false;
    if (c >= n_) return false;
    Track& t = tracks_[c];
    ++t.samples;
    bool ok = true;
    if (!std::isfinite(y)) {
      ok = false;
    } else if (t.phase == Phase::collecting) {
      ok = t.stats.push(y);
    } else {
      count(t.paused);
    }
    if (!ok) count(t.rejected);
    advance(c);
    return ok;
  }

  // Channel c has no usable sample at this step (stuck, saturated, non-finite): it counts for
  // the schedule (a fit's request and apply point), not for the statistics.
  void skip(std::size_t c) noexcept {
    retuned_ = false;
    if (c >= n_) return;
    Track& t = tracks_[c];
    ++t.samples;
    if (t.phase != Phase::collecting) count(t.paused);
    advance(c);
  }

  // True after the push()/skip() that applied an accepted retune of its channel, or a refused
  // one that put the configured gain back: reload that channel's gain0(c), gain1(c) then.
  bool retuned() const noexcept { return retuned_; }

  // Scheduling. Inline (off, the default): the fit runs inside the push()/skip() of its
  // request. Deferred (on): that push()/skip() only marks it pending and run_pending_fit()
  // runs it (thread mode on a target). Switch it before the first sample.
  void defer_fits(bool on) noexcept { deferred_ = on; }
  bool deferred() const noexcept { return deferred_; }
  // A deferred fit waits to be run.
  bool fit_pending() const noexcept { return pending_.load(std::memory_order_acquire); }
  // Runs the pending fit, if any, to its end (heavy: about 3.3e7 instructions of software
  // double on a Cortex-M4F at L = 8); its outcome is used at its apply point if done by then.
  void run_pending_fit() noexcept {
    if (!pending_.load(std::memory_order_acquire)) return;
    run_fit(owner_);
    pending_.store(false, std::memory_order_relaxed);
    done_.store(true, std::memory_order_release);
  }
  // Deferred fits not done by their apply point (their outcomes discarded).
  std::uint32_t late_fits() const noexcept { return late_fits_.load(std::memory_order_relaxed); }

  std::size_t channels() const noexcept { return n_; }
  const LagDriftSettings<Scalar>& lag_settings() const noexcept { return lag_; }
  // Samples of a channel between two fits (retune_blocks * block_samples).
  std::uint64_t cadence() const noexcept { return cadence_; }

  // Channel c's state (c < channels()).
  const DriftModelParams<Scalar>& configured(std::size_t c) const noexcept { return track(c).configured; }
  // The last fit's estimate (the configured model before the first fit).
  const DriftModelParams<Scalar>& estimate(std::size_t c) const noexcept { return track(c).estimate; }
  // The gain's model.
  const DriftModelParams<Scalar>& in_use(std::size_t c) const noexcept { return track(c).in_use; }
  Scalar gain0(std::size_t c) const noexcept { return track(c).gain[0]; }
  Scalar gain1(std::size_t c) const noexcept { return track(c).gain[1]; }
  std::uint32_t retunes(std::size_t c) const noexcept { return track(c).retunes; }  // accepted
  std::uint32_t refused_retunes(std::size_t c) const noexcept { return track(c).refused; }
  // push() and skip() calls of the channel (the schedule's count).
  std::uint64_t samples(std::size_t c) const noexcept { return track(c).samples; }
  // Of those, the samples not pushed while the statistics paused for a fit (saturating at
  // 2^32 - 1, as rejected()).
  std::uint64_t paused(std::size_t c) const noexcept { return track(c).paused; }
  // Pushed samples the statistics refused (NaN/Inf; saturating at 2^32 - 1).
  std::uint64_t rejected(std::size_t c) const noexcept { return track(c).rejected; }
  // The status of the last applied fit (too_few_samples before the first).
  LagDriftFitStatus fit_status(std::size_t c) const noexcept { return track(c).fit_status; }
  // learning (no fit applied yet), tracking (an accepted fit in use), not_identified (the
  // guards refused the last fit), fallback (the last fit failed): the recursive identifier's
  // codes.
  OnlineDriftStatus status(std::size_t c) const noexcept { return track(c).status; }
  const Statistics& statistics(std::size_t c) const noexcept { return track(c).stats; }
  // The channel's sample count at its next request, and at its pending apply point (0: none).
  std::uint64_t next_request(std::size_t c) const noexcept { return track(c).next_request; }
  std::uint64_t apply_at(std::size_t c) const noexcept {
    return track(c).phase == Phase::collecting ? 0U : track(c).apply_at;
  }

 private:
  static constexpr std::size_t kNone = Channels;
  enum class Phase : std::uint8_t { collecting = 0, waiting = 1, late = 2 };

  struct Track {
    Statistics stats{};
    DriftModelParams<Scalar> configured{};
    DriftModelParams<Scalar> estimate{};
    DriftModelParams<Scalar> in_use{};
    Scalar gain[2] = {Scalar(0), Scalar(0)};
    Scalar cgain[2] = {Scalar(0), Scalar(0)};  // the configured model's gain
    LagDriftFitStatus fit_status = LagDriftFitStatus::too_few_samples;
    OnlineDriftStatus status = OnlineDriftStatus::unconfigured;
    Phase phase = Phase::collecting;
    std::uint64_t samples = 0;
    std::uint64_t next_request = 0;
    std::uint64_t apply_at = 0;
    std::uint32_t paused = 0;    // saturating
    std::uint32_t rejected = 0;  // saturating
    std::uint32_t retunes = 0;
    std::uint32_t refused = 0;
  };

  // One more in a saturating 32-bit count.
  static void count(std::uint32_t& n) noexcept {
    if (n != std::numeric_limits<std::uint32_t>::max()) ++n;
  }

  // The settings the fit, its guards and the bounded step use (OnlineDriftSettings's).
  struct Guards {
    std::uint64_t min_samples = 0;
    Scalar max_step = Scalar(0);
    Scalar max_rel_stderr = Scalar(0);
    Scalar min_ar_wald = Scalar(0);
    bool adapt_ar = true;
  };

  // What a fit decided, applied at its apply point. Written by the fit only (one at a time,
  // and the previous outcome applied before the next request).
  struct Outcome {
    DriftModelParams<double> fit{};    // the fit's model (set when its status has one)
    DriftModelParams<Scalar> model{};  // the model in use after the bounded step
    Scalar gain[2] = {Scalar(0), Scalar(0)};
    LagDriftFitStatus fit_status = LagDriftFitStatus::non_finite;
    OnlineDriftStatus status = OnlineDriftStatus::fallback;  // tracking: accepted
  };

  const Track& track(std::size_t c) const noexcept { return tracks_[c < Channels ? c : 0]; }

  // The schedule after channel c's sample.
  void advance(std::size_t c) noexcept {
    Track& t = tracks_[c];
    switch (t.phase) {
      case Phase::collecting:
        if (t.samples >= t.next_request) request(c);
        break;
      case Phase::waiting:
        if (t.samples >= t.apply_at) arrive(c);
        break;
      case Phase::late:
        if (done_.load(std::memory_order_acquire)) resume(c);  // the late outcome discarded
        break;
    }
  }

  void request(std::size_t c) noexcept {
    Track& t = tracks_[c];
    if (owner_ != kNone) return;  // another channel's fit holds the working state: next sample
    while (t.next_request <= t.samples) t.next_request += cadence_;
    const std::uint64_t floor = lag_drift_min_samples(Lags);
    const std::uint64_t need = guards_.min_samples > floor ? guards_.min_samples : floor;
    if (t.stats.samples() < need) return;  // not a refusal: the channel keeps its model
    owner_ = c;
    t.phase = Phase::waiting;
    t.apply_at = t.samples + lag_.fit_delay_samples;
    done_.store(false, std::memory_order_relaxed);
    if (deferred_) {
      pending_.store(true, std::memory_order_release);
    } else {
      run_fit(c);
      done_.store(true, std::memory_order_relaxed);
    }
    if (t.samples >= t.apply_at) arrive(c);  // fit_delay_samples 0
  }

  // Channel c at its apply point.
  void arrive(std::size_t c) noexcept {
    Track& t = tracks_[c];
    if (!done_.load(std::memory_order_acquire)) {
      late_fits_.store(late_fits_.load(std::memory_order_relaxed) + 1U, std::memory_order_relaxed);
      t.phase = Phase::late;
      return;
    }
    const Outcome& o = outcome_;
    t.fit_status = o.fit_status;
    if (has_model(o.fit_status)) t.estimate = to_scalar(o.fit);
    if (o.status == OnlineDriftStatus::tracking) {
      t.in_use = o.model;
      t.gain[0] = o.gain[0];
      t.gain[1] = o.gain[1];
      ++t.retunes;
      retuned_ = true;
    } else {
      ++t.refused;
      t.in_use = t.configured;
      if (t.gain[0] != t.cgain[0] || t.gain[1] != t.cgain[1]) retuned_ = true;
      t.gain[0] = t.cgain[0];
      t.gain[1] = t.cgain[1];
    }
    t.status = o.status;
    resume(c);
  }

  void resume(std::size_t c) noexcept {
    Track& t = tracks_[c];
    t.phase = Phase::collecting;
    if (lag_.restart_after_fit) t.stats.reset();
    owner_ = kNone;
  }

  using Objective = detail::LagFitObjective<double, Scalar, Lags, false>;

  static double atanh_of(double p) noexcept { return 0.5 * std::log((1.0 + p) / (1.0 - p)); }

  // The fit's statuses that come with an estimate.
  static bool has_model(LagDriftFitStatus st) noexcept {
    return st == LagDriftFitStatus::ok || st == LagDriftFitStatus::truncation || st == LagDriftFitStatus::not_converged;
  }

  static DriftModelParams<Scalar> to_scalar(const DriftModelParams<double>& m) noexcept {
    return DriftModelParams<Scalar>{static_cast<Scalar>(m.a1), static_cast<Scalar>(m.a2), static_cast<Scalar>(m.q),
                                    static_cast<Scalar>(m.r), static_cast<Scalar>(m.mean)};
  }

  // The fit with a1, a2 held at (a1, a2): u3 only, a one-dimensional BFGS from the best of the
  // 11 splits, into `run`.
  static GYRODRIFT_NOINLINE void split_run(Objective& obj, double a1, double a2, std::uint32_t max_iterations,
                                           detail::BfgsRun<double>& run) noexcept {
    static constexpr double kSplits[11] = {0.02, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.98};
    double* const u = run.u;
    u[0] = atanh_of(a1 / (1.0 - a2));
    u[1] = atanh_of(a2);
    u[2] = 0.0;
    double best_f = std::numeric_limits<double>::infinity(), best_u3 = 0.0;
    for (const double lam : kSplits) {
      u[2] = std::log(lam / (1.0 - lam));
      const double f = obj(u);
      if (f < best_f) {
        best_f = f;
        best_u3 = u[2];
      }
    }
    u[2] = best_u3;
    const std::size_t free3[1] = {2};
    detail::bfgs<1>(obj, run, free3, max_iterations);
  }

  // The fit of channel c's statistics (whittle_no_head; with adapt_ar lag_drift_fit's, else the
  // split alone with the AR part held at the configured model's); its model into outcome_.fit
  // when the status has one. Out of line: its objective and runs are off the stack before the
  // guards run.
  GYRODRIFT_NOINLINE LagDriftFitStatus fit_statistics(std::size_t c) noexcept {
    const Statistics& st = tracks_[c].stats;
    const LagLikelihoodKind kind = LagLikelihoodKind::whittle_no_head;
    if (st.samples() < lag_drift_min_samples(Lags)) return LagDriftFitStatus::too_few_samples;
    Objective obj(st, kind);
    if (!obj.form().finite()) return LagDriftFitStatus::non_finite;
    detail::BfgsRun<double> chosen;
    if (guards_.adapt_ar) {
      detail::lag_fit_runs<double>(obj, lag_.max_iterations, chosen, nullptr, nullptr);
    } else {
      const DriftModelParams<Scalar>& cfg = tracks_[c].configured;
      split_run(obj, static_cast<double>(cfg.a1), static_cast<double>(cfg.a2), lag_.max_iterations, chosen);
    }
    return detail::lag_fit_estimate<Lags, double>(obj, kind, chosen, guards_.adapt_ar, outcome_.fit, nullptr,
                                                  nullptr);
  }

  // The guards: Cov(u) of the free coordinates from the central-difference Hessian of f at u;
  // false when it is not positive definite or not finite (the split not identified).
  GYRODRIFT_NOINLINE bool identified(const Statistics& st, const double* u_fit, double lam) const noexcept {
    Objective obj(st, LagLikelihoodKind::whittle_no_head);
    const bool ar = guards_.adapt_ar;
    const std::size_t d = ar ? 3U : 1U;
    const std::size_t idx[3] = {ar ? 0U : 2U, 1U, 2U};
    const double h = kLagIdentifierHessianStep;
    double u[3] = {u_fit[0], u_fit[1], u_fit[2]};
    const double f0 = obj(u);
    double hess[3][3] = {};
    for (std::size_t i = 0; i < d; ++i) {
      const std::size_t a = idx[i];
      u[a] = u_fit[a] + h;
      const double fp = obj(u);
      u[a] = u_fit[a] - h;
      const double fm = obj(u);
      u[a] = u_fit[a];
      hess[i][i] = (fp - 2.0 * f0 + fm) / (h * h);
      for (std::size_t j = 0; j < i; ++j) {
        const std::size_t b = idx[j];
        double s = 0.0;
        for (int sa = -1; sa <= 1; sa += 2) {
          for (int sb = -1; sb <= 1; sb += 2) {
            u[a] = u_fit[a] + sa * h;
            u[b] = u_fit[b] + sb * h;
            s += sa * sb * obj(u);
          }
        }
        u[a] = u_fit[a];
        u[b] = u_fit[b];
        hess[i][j] = hess[j][i] = s / (4.0 * h * h);
      }
    }
    const double n = static_cast<double>(st.samples());
    for (std::size_t i = 0; i < d; ++i)
      for (std::size_t j = 0; j < d; ++j) hess[i][j] *= n;
    return identified_from(hess, d, u_fit, lam);
  }

  // The guards from n times the Hessian of f (d x d) at u_fit. Out of line: the covariance is
  // not on the stack while the Hessian's evaluations run.
  GYRODRIFT_NOINLINE bool identified_from(const double (&hess)[3][3], std::size_t d, const double* u_fit,
                                          double lam) const noexcept {
    const bool ar = guards_.adapt_ar;
    double cov[3][3] = {};
    if (!invert_spd(hess, d, cov)) return false;
    const double se_u3 = std::sqrt(cov[d - 1][d - 1]);
    const double lim = static_cast<double>(guards_.max_rel_stderr);
    if (!((1.0 - lam) * se_u3 <= lim) || !(lam * se_u3 <= lim)) return false;
    if (!ar) return true;
    const double c00 = cov[0][0], c01 = cov[0][1], c11 = cov[1][1];
    const double det = c00 * c11 - c01 * c01;
    if (!(det > 0.0)) return false;
    const double wald = (c11 * u_fit[0] * u_fit[0] - 2.0 * c01 * u_fit[0] * u_fit[1] + c00 * u_fit[1] * u_fit[1]) / det;
    return wald >= static_cast<double>(guards_.min_ar_wald);
  }

  // The inverse of the d x d symmetric matrix a (d <= 3) by Cholesky; false unless positive
  // definite and finite.
  static bool invert_spd(const double (&a)[3][3], std::size_t d, double (&inv)[3][3]) noexcept {
    double l[3][3] = {};
    for (std::size_t i = 0; i < d; ++i) {
      for (std::size_t j = 0; j <= i; ++j) {
        double v = a[i][j];
        for (std::size_t k = 0; k < j; ++k) v -= l[i][k] * l[j][k];
        if (i == j) {
          if (!(v > 0.0) || !std::isfinite(v)) return false;
          l[i][i] = std::sqrt(v);
        } else {
          l[i][j] = v / l[j][j];
        }
      }
    }
    for (std::size_t col = 0; col < d; ++col) {
      double z[3] = {};
      for (std::size_t i = 0; i < d; ++i) {
        double v = i == col ? 1.0 : 0.0;
        for (std::size_t k = 0; k < i; ++k) v -= l[i][k] * z[k];
        z[i] = v / l[i][i];
      }
      for (std::size_t i = d; i-- > 0;) {
        double v = z[i];
        for (std::size_t k = i + 1; k < d; ++k) v -= l[k][i] * inv[k][col];
        inv[i][col] = v / l[i][i];
      }
    }
    for (std::size_t i = 0; i < d; ++i)
      for (std::size_t j = 0; j < d; ++j)
        if (!std::isfinite(inv[i][j])) return false;
    return true;
  }

  // The fit of channel c and its outcome (guards, bounded step, gain), into outcome_: the fit,
  // then the rest once its frames are gone.
  void run_fit(std::size_t c) noexcept { decide(c, fit_statistics(c)); }

  // The outcome of channel c's fit of status `status` (its model in outcome_.fit): the guards,
  // the bounded step and the gain.
  GYRODRIFT_NOINLINE void decide(std::size_t c, LagDriftFitStatus status) noexcept {
    const Track& t = tracks_[c];
    Outcome& o = outcome_;
    const DriftModelParams<Scalar>& cfg = t.configured;
    o.fit_status = status;
    o.model = cfg;
    o.gain[0] = t.cgain[0];
    o.gain[1] = t.cgain[1];
    o.status = OnlineDriftStatus::fallback;
    const DriftModelParams<double>& m = o.fit;
    if (status != LagDriftFitStatus::ok || !(m.q > 0.0) || !(m.r > 0.0)) return;
    const double lam = m.q / (m.q + m.r);
    const double u_fit[3] = {atanh_of(m.a1 / (1.0 - m.a2)), atanh_of(m.a2), std::log(lam / (1.0 - lam))};
    if (!identified(t.stats, u_fit, lam)) {
      o.status = OnlineDriftStatus::not_identified;
      return;
    }
    step_toward(c, u_fit);
  }

  // An identified fit of channel c (its model in outcome_.fit, u_fit its u): the bounded step
  // from the model in use and its gain into outcome_ (status tracking), or nothing when the
  // stepped model or its gain is refused. Out of line: its state is not on the stack while the
  // guards' evaluations run.
  GYRODRIFT_NOINLINE void step_toward(std::size_t c, const double* u_fit) noexcept {
    const Track& t = tracks_[c];
    Outcome& o = outcome_;
    const DriftModelParams<Scalar>& cfg = t.configured;
    const DriftModelParams<double>& m = o.fit;
    // Bounded step from the model in use: (u1, u2, log q, log r), scaled as a whole.
    const DriftModelParams<Scalar>& use = t.in_use;
    const double ua2 = static_cast<double>(use.a2), ua1 = static_cast<double>(use.a1);
    const double ur = static_cast<double>(use.r);
    double uq = static_cast<double>(use.q);
    if (!(uq > 1e-6 * ur)) uq = 1e-6 * ur;  // a configured white-noise model (q = 0): log q finite
    const double from[4] = {atanh_of(ua1 / (1.0 - ua2)), atanh_of(ua2), std::log(uq), std::log(ur)};
    const double to[4] = {guards_.adapt_ar ? u_fit[0] : from[0], guards_.adapt_ar ? u_fit[1] : from[1],
                          std::log(m.q), std::log(m.r)};
    double step[4], big = 0.0;
    for (int j = 0; j < 4; ++j) {
      step[j] = to[j] - from[j];
      big = std::fabs(step[j]) > big ? std::fabs(step[j]) : big;
    }
    const double ms = static_cast<double>(guards_.max_step);
    const double scale = big > ms ? ms / big : 1.0;  // the step scaled as a whole
    DriftModelParams<Scalar> next = to_scalar(m);  // within max_step: the fit itself
    if (big > ms) {
      double v[4];
      for (int j = 0; j < 4; ++j) v[j] = from[j] + scale * step[j];
      const double na2 = std::tanh(v[1]);
      const double na1 = std::tanh(v[0]) * (1.0 - na2);
      next = DriftModelParams<Scalar>{static_cast<Scalar>(na1), static_cast<Scalar>(na2),
                                      static_cast<Scalar>(std::exp(v[2])), static_cast<Scalar>(std::exp(v[3])),
                                      static_cast<Scalar>(m.mean)};
    }
    if (!guards_.adapt_ar) {  // exactly the configured AR part
      next.a1 = cfg.a1;
      next.a2 = cfg.a2;
    }
    if (drift_params_status(next) != Ar2Status::ok || !(next.r > Scalar(0))) return;
    const Ar2SteadyStateKalman<Scalar> kf(Ar2Model<Scalar>{next.a1, next.a2, next.q, Scalar(0)}, next.q, next.r);
    if (kf.status() != Ar2Status::ok || !std::isfinite(kf.gain()(0)) || !std::isfinite(kf.gain()(1))) return;
    o.model = next;
    o.gain[0] = kf.gain()(0);
    o.gain[1] = kf.gain()(1);
    o.status = OnlineDriftStatus::tracking;
  }

  Track tracks_[Channels]{};
  Guards guards_{};
  Outcome outcome_{};
  std::uint64_t cadence_ = 0;
  LagDriftSettings<Scalar> lag_{};
  std::size_t n_ = 0;
  std::size_t owner_ = kNone;  // the channel whose fit holds the working state
  std::atomic<bool> pending_{false};  // a deferred fit waits for run_pending_fit()
  std::atomic<bool> done_{false};     // the owner's fit and outcome are ready
  std::atomic<std::uint32_t> late_fits_{0};
  bool deferred_ = false;
  bool retuned_ = false;
};

}  // namespace gyrodrift
