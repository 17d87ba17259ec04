// Online re-identification of the drift model "AR(2) drift + white noise" (the model of
// drift_likelihood.hpp and of the offline fit gyrodrift.filters.fit_drift_model), for a
// navigation computer that retunes its steady-state AR(2)-Kalman gain while it runs.
//
// Model: x_k = a1 x_{k-1} + a2 x_{k-2} + w_k (w ~ N(0, q)), y_k = mean + x_k + v_k (v ~ N(0, r)).
//
// Estimator: recursive prediction error (Ljung & Soderstrom 1983, Theory and Practice of
// Recursive Identification: the recursive Gauss-Newton algorithm) on the exact Kalman innovations of the model, with the parameters
// updated once per block of `block_samples` samples:
//   theta = (u1, u2, log q, log r),  a2 = tanh(u2), a1 = tanh(u1) (1 - a2)
// (partial autocorrelations through tanh, as the offline fit: every theta is stationary; with
// ar_order = 1, u2 = a2 = 0 is held; with adapt_ar = false, u1 and u2 are held at the
// configured model). The mean is the running mean of the samples (the
// innovations are those of y - mean); it is not part of theta.
// Per sample (cheap part, about 200 flops, 4 divisions, 1 square root):
//   - four Kalman filters (time-varying covariance, prediction form of drift_likelihood.hpp)
//     run on d_k = y_k - mean: the main one at theta and three at theta + delta e_j for
//     j = u1, u2, log q (delta = 2^-10). Their innovation e and variance F give the
//     sensitivities psi_j = de/dtheta_j ~ (e_j - e) / delta and phi_j = dF/dtheta_j ~
//     (F_j - F) / delta. The log r direction needs no filter: scaling q and r together by s
//     leaves every gain unchanged and scales every F by s, so psi_logr = -psi_logq and
//     phi_logr = F - phi_logq (exact up to the differencing of psi_logq, phi_logq).
//   - the per-sample negative log-likelihood l = (log F + e^2 / F) / 2 has the gradient
//     g_j = e psi_j / F + (phi_j / 2F) (1 - e^2 / F) and the Gauss-Newton (Fisher) information
//     h_jk = psi_j psi_k / F + phi_j phi_k / (2 F^2); both are summed over the block.
// Per block (heavier part, once per block_samples samples):
//   gamma_k: Ljung & Soderstrom's start-up forgetting-factor schedule, lambda_1 = lambda_start,
//   lambda_k = rho lambda_{k-1} + (1 - rho), rho = 1 - 1/warmup_blocks, gamma_1 = 1,
//   gamma_k = gamma_{k-1} / (gamma_{k-1} + lambda_k) (-> 1/k: the early blocks' information,
//   gathered far from the optimum, is discounted); warmup_blocks = 0: gamma_k = 1/k. With
//   forgetting, gamma_k >= 1/memory_blocks.
//   R_k = R_{k-1} + max(gamma_k, 1/info_blocks) (H_block / B - R_{k-1})   (information per sample)
//   step = -gamma_k (R_k + mu diag R_k)^-1 G_block / B           (mu = 2^-16, Marquardt)
// scaled as a whole so that no component exceeds max_step (the direction is kept: the
// parameters are strongly correlated along the likelihood's ridge, and clipping components
// one by one leaves the ridge), then u1, u2 clipped to +-kOnlineDriftMaxU and log q, log r to
// log(q0 + r0) +- kOnlineDriftLogVarRange (q0, r0 configured). Without forgetting this is the
// recursive form of the Gauss-Newton maximum-likelihood estimate and converges to the offline
// ML fit (a local method: from a start in the basin of the ML optimum; the likelihood of this
// model can have several modes, which the offline fit's multi-start handles). With the floor
// 1/memory_blocks it tracks a change with a memory of about memory_blocks blocks (the running
// mean has the same memory); adapt_ar = false then holds a1, a2 at the configured values and
// tracks q and r only, which is much better conditioned (docs/validation/online-identification.md).
//
// Standard errors: Cov(theta) ~ (n_eff R)^-1, n_eff = B k (no forgetting) or
// B min(k, 2 memory_blocks - 1) (the variance of an exponential average of gain 1/M is that of
// 2M - 1 terms), carried to (a1, a2, q, r) by the chain rule; the mean's from the long-run
// variance, (q / (1 - a1 - a2)^2 + r) / n_mean.
//
// Retune, every retune_blocks blocks (the gain of in_use() changes only here):
//   - fewer than min_samples accepted samples: status learning, configured model in use;
//   - the estimate is not finite/stationary, sits on a bound of theta, R is not positive
//     definite, or the mean normalised innovation power e^2/F of the main filter over the last
//     retune interval is outside [1/max_innovation_ratio, max_innovation_ratio] (the model does
//     not describe the data: a divergence): status fallback;
//   - the relative standard error of q or of r (= the stderr of log q, log r) exceeds
//     max_rel_stderr, or (AR part estimated) its Wald statistic against white drift is below
//     min_ar_wald (the drift/white split is not identified; the online analogue of the
//     offline fit's split check): status not_identified;
//   - the steady-state gain of the estimate (Riccati recursion warm-started from the main
//     filter's covariance, at most kOnlineDriftRetuneIterations steps, stopped as in
//     Ar2SteadyStateKalman) does not converge: status fallback;
//   - otherwise in_use() = estimate(), the gain is its steady-state gain, status tracking.
// A refused retune counts in refused_retunes() and puts the configured model (and its gain,
// Ar2SteadyStateKalman's, computed once at configure()) back in use. The estimate keeps running
// in every case, so a later retune can accept it again.
//
// State: sizeof(OnlineDriftIdentifier<float>) is 408 bytes, <double> 744 on x86-64 (checked in
// cpp/tests/test_online_drift_identifier.cpp; the float size is the same on Cortex-M4), of which
// 184 (float) are the channel's own (Track); the rest, the filters, block sums and settings, is
// working state that SharedDriftIdentifier (shared_drift_identifier.hpp) keeps once for several
// channels.
// Per-sample work: 4 filter steps (about 200 flops, 4 divisions, 1 square root).
// Allocation-free, noexcept, deterministic, templated on Scalar; float-safe (no double
// arithmetic in a float instantiation).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "ar2_model.hpp"
#include "ar2_steady_state.hpp"
#include "drift_likelihood.hpp"

namespace gyrodrift {

enum class OnlineDriftStatus : std::uint8_t {
  unconfigured = 0,    // configure() not called or refused
  learning = 1,        // fewer than min_samples: the configured model is in use
  tracking = 2,        // an identified estimate is in use by the gain
  not_identified = 3,  // the estimate's drift/noise split is not identified: configured model in use
  fallback = 4,        // a guard rejected the estimate (diverged, non-stationary): configured model in use
};

inline const char* to_string(OnlineDriftStatus s) noexcept {
  switch (s) {
    case OnlineDriftStatus::unconfigured: return "unconfigured";
    case OnlineDriftStatus::learning: return "learning";
    case OnlineDriftStatus::tracking: return "tracking";
    case OnlineDriftStatus::not_identified: return "not_identified";
    case OnlineDriftStatus::fallback: return "fallback";
  }
  return "unknown";
}

// Bounds of the unconstrained parameters: |u1|, |u2| <= 5.5 keeps each partial autocorrelation
// within 1 - 3.4e-5 of 1 (representable with ~2e-3 relative accuracy of 1 - rho in float);
// log q and log r stay within +-23 (a factor 1e10) of log(q0 + r0).
inline constexpr double kOnlineDriftMaxU = 5.5;
inline constexpr double kOnlineDriftLogVarRange = 23.0;
// Largest number of Riccati steps of one gain retune (warm start: usually a few dozen).
inline constexpr std::uint32_t kOnlineDriftRetuneIterations = 2048;

template <class Scalar>
struct OnlineDriftSettings {
  std::uint32_t block_samples = 400;   // samples per parameter update (>= 8)
  std::uint32_t retune_blocks = 60;    // parameter updates between gain retunes (>= 1)
  std::uint64_t min_samples = 240000;  // no retune before this many accepted samples
  Scalar memory_blocks = Scalar(0);    // forgetting horizon in blocks; 0: none (converges to the ML fit), else >= 1
  Scalar max_step = Scalar(0.1);       // largest change of one parameter per update (log q, log r; AR part)
  Scalar max_rel_stderr = Scalar(0.5); // split identified when the relative stderr of q and r is <= this
  // Added: the divergence guard (mean e^2/F of the estimate's filter over a retune interval
  // must lie in [1/ratio, ratio]; > 1) and the AR order of the drift (2, or 1: a2 held at 0).
  Scalar max_innovation_ratio = Scalar(3);
  std::uint8_t ar_order = 2;
  // Added: the start-up schedule of the gain (Ljung & Soderstrom 1983: a forgetting
  // factor that tends to 1): lambda_1 = lambda_start, lambda_k = rho lambda_{k-1} + (1 - rho),
  // rho = 1 - 1/warmup_blocks, gamma_k = gamma_{k-1} / (gamma_{k-1} + lambda_k). It discounts
  // the first blocks' information, gathered far from the optimum; gamma_k -> 1/k afterwards.
  // warmup_blocks = 0: gamma_k = 1/k from the start.
  Scalar warmup_blocks = Scalar(50);
  Scalar lambda_start = Scalar(0.7);
  // Added: false holds a1, a2 at the configured values and identifies q and r only (better
  // conditioned when tracking a change of the noise levels with forgetting).
  bool adapt_ar = true;
  // Added: memory of the information matrix R in blocks (its gain is at least
  // 1/info_blocks; 0: R averages every block as theta does). R is the Gauss-Newton metric
  // of the steps and gives the standard errors and the identification guard, so it must
  // describe the information at the current estimate, not an average over the path there
  // (at a white-noise record the information about the split vanishes only at the optimum).
  Scalar info_blocks = Scalar(50);
  // Added: with adapt_ar, the split is identified only if the drift is told from white noise:
  // the Wald statistic of the AR part against zero, u^T Cov(u)^-1 u (u = (u1, u2), chi-square
  // with 2 degrees of freedom, 1 with ar_order 1) is at least this. At a1 = a2 = 0 the drift
  // is white and q, r are not separable, although the linearised stderrs near there are finite.
  Scalar min_ar_wald = Scalar(25);
};

template <class Scalar, std::size_t Channels>
class SharedDriftIdentifier;

template <class Scalar>
class OnlineDriftIdentifier {
 public:
  // The state that belongs to one channel: the configured model and its gain, theta, the
  // information R, the running mean (in the estimate), the start-up schedule, the gain in use,
  // the counters. The filters, the block sums and the settings are the estimator's working
  // state (SharedDriftIdentifier keeps one of those for all its channels).
  struct Track {
    DriftModelParams<Scalar> configured_{};
    DriftModelParams<Scalar> estimate_{};
    DriftModelParams<Scalar> in_use_{};
    Scalar u_[2] = {Scalar(0), Scalar(0)};
    Scalar logq_ = Scalar(0), logr_ = Scalar(0), log_var0_ = Scalar(0);
    Scalar r_info_[10] = {};  // running average information per sample (packed)
    Scalar nis_sum_ = Scalar(0);
    Scalar lambda_ = Scalar(1), gamma_ = Scalar(1);
    Scalar gain_[2] = {Scalar(0), Scalar(0)};
    Scalar cgain_[2] = {Scalar(0), Scalar(0)};  // the configured model's gain
    std::uint64_t samples_ = 0;
    std::uint64_t rejected_ = 0;
    std::uint32_t blocks_ = 0;
    std::uint32_t retunes_ = 0;
    std::uint32_t refused_retunes_ = 0;
    OnlineDriftStatus status_ = OnlineDriftStatus::unconfigured;
  };

  OnlineDriftIdentifier() noexcept = default;

  // The configured model is the start and the fallback. Returns false (status unconfigured)
  // for an invalid model (drift_params_status not ok, r <= 0, a2 != 0 with ar_order 1, or
  // its steady-state gain not converging) or invalid settings. A configured q = 0 (white
  // noise) starts the estimate at q = 1e-6 r (log q must be finite).
  bool configure(const DriftModelParams<Scalar>& configured, const OnlineDriftSettings<Scalar>& s) noexcept {
    t_.configured_ = configured;
    settings_ = s;
    t_.status_ = OnlineDriftStatus::unconfigured;
    const bool settings_ok =
        s.block_samples >= 8 && s.retune_blocks >= 1 && std::isfinite(s.memory_blocks) &&
        (s.memory_blocks == Scalar(0) || s.memory_blocks >= Scalar(1)) && std::isfinite(s.max_step) &&
        s.max_step > Scalar(0) && std::isfinite(s.max_rel_stderr) && s.max_rel_stderr > Scalar(0) &&
        std::isfinite(s.max_innovation_ratio) && s.max_innovation_ratio > Scalar(1) &&
        (s.ar_order == 1 || s.ar_order == 2) && std::isfinite(s.warmup_blocks) &&
        (s.warmup_blocks == Scalar(0) || s.warmup_blocks >= Scalar(1)) && s.lambda_start > Scalar(0) &&
        s.lambda_start <= Scalar(1) && std::isfinite(s.info_blocks) &&
        (s.info_blocks == Scalar(0) || s.info_blocks >= Scalar(1)) && std::isfinite(s.min_ar_wald) &&
        s.min_ar_wald >= Scalar(0);
    const bool model_ok = drift_params_status(configured) == Ar2Status::ok && configured.r > Scalar(0) &&
                          (s.ar_order == 2 || configured.a2 == Scalar(0));
    if (!settings_ok || !model_ok) {
      clear_state();
      return false;
    }
    const Ar2SteadyStateKalman<Scalar> kf(Ar2Model<Scalar>{configured.a1, configured.a2, configured.q, Scalar(0)},
                                          configured.q, configured.r);
    if (kf.status() != Ar2Status::ok) {
      clear_state();
      return false;
    }
    t_.cgain_[0] = kf.gain()(0);
    t_.cgain_[1] = kf.gain()(1);
    t_.log_var0_ = std::log(configured.q + configured.r);
    clear_state();
    t_.status_ = OnlineDriftStatus::learning;
    return true;
  }

  // Back to the configured model, counters cleared.
  void reset() noexcept {
    if (t_.status_ != OnlineDriftStatus::unconfigured) {
      clear_state();
      t_.status_ = OnlineDriftStatus::learning;
    }
  }

  // One rate sample (units of the model, e.g. rad/s). NaN/Inf (or unconfigured): skipped and
  // counted in rejected(), false.
  bool push(Scalar y) noexcept {
    retuned_ = false;
    block_updated_ = false;
    Scalar d;
    if (!observe(t_, settings_, y, d)) return false;
    sample(d);
    if (++in_block_ == settings_.block_samples) end_block();
    return true;
  }

  OnlineDriftStatus status() const noexcept { return t_.status_; }
  const DriftModelParams<Scalar>& configured() const noexcept { return t_.configured_; }
  const DriftModelParams<Scalar>& estimate() const noexcept { return t_.estimate_; }  // running estimate
  const DriftModelParams<Scalar>& in_use() const noexcept { return t_.in_use_; }      // the gain's model
  // Approximate standard errors of the running estimate; false while they do not exist
  // (before the first block, or an information matrix that is not positive definite).
  bool stderrs(DriftModelParams<Scalar>& se) const noexcept {
    Scalar cov[16];
    if (!theta_covariance(cov)) return false;
    const Scalar one = Scalar(1);
    const Scalar a2 = t_.estimate_.a2;
    const Scalar p1 = std::tanh(t_.u_[0]);
    // Jacobian of (a1, a2) with respect to (u1, u2).
    const Scalar j00 = (one - p1 * p1) * (one - a2), j01 = -p1 * (one - a2 * a2);
    const Scalar j11 = one - a2 * a2;
    const Scalar v_a1 = j00 * j00 * cov[0] + Scalar(2) * j00 * j01 * cov[1] + j01 * j01 * cov[5];
    const Scalar v_a2 = j11 * j11 * cov[5];
    se.a1 = std::sqrt(v_a1 > Scalar(0) ? v_a1 : Scalar(0));
    se.a2 = std::sqrt(v_a2 > Scalar(0) ? v_a2 : Scalar(0));
    se.q = t_.estimate_.q * std::sqrt(cov[10]);
    se.r = t_.estimate_.r * std::sqrt(cov[15]);
    const Scalar s = one - t_.estimate_.a1 - t_.estimate_.a2;
    se.mean = std::sqrt((t_.estimate_.q / (s * s) + t_.estimate_.r) / mean_count());
    return std::isfinite(se.a1 + se.a2 + se.q + se.r + se.mean);
  }
  // Steady-state Kalman gain (k0, k1) of in_use(); changes only at a retune.
  Scalar gain0() const noexcept { return t_.gain_[0]; }
  Scalar gain1() const noexcept { return t_.gain_[1]; }
  // True after the push() that retuned the gain (until the next push()): an accepted retune,
  // or a refused one that put the configured gain back. Reload gain0(), gain1() then.
  bool retuned() const noexcept { return retuned_; }
  std::uint32_t retunes() const noexcept { return t_.retunes_; }  // accepted retunes
  std::uint32_t refused_retunes() const noexcept { return t_.refused_retunes_; }
  std::uint64_t samples() const noexcept { return t_.samples_; }
  std::uint64_t rejected() const noexcept { return t_.rejected_; }
  // Added: true after the push() that ended a block (a parameter update); blocks so far.
  bool block_updated() const noexcept { return block_updated_; }
  std::uint32_t blocks() const noexcept { return t_.blocks_; }

 private:
  template <class S, std::size_t N>
  friend class SharedDriftIdentifier;

  // Filter state in prediction form: X_k|k-1 = (x0, x1), P_k|k-1 = [[p00, p01], [p01, p11]].
  struct Filter {
    Scalar x0, x1, p00, p01, p11;
  };

  // Is theta_j estimated (u1, u2 may be held; log q, log r always are)?
  bool is_free(int j) const noexcept {
    if (j == 0) return settings_.adapt_ar;
    if (j == 1) return settings_.adapt_ar && settings_.ar_order == 2;
    return true;
  }

  static Scalar delta() noexcept { return Scalar(1) / Scalar(1024); }

  Scalar mean_count() const noexcept { return mean_count(t_, settings_); }
  static Scalar mean_count(const Track& t, const OnlineDriftSettings<Scalar>& s) noexcept {
    const Scalar n = static_cast<Scalar>(t.samples_);
    const Scalar cap = s.memory_blocks * static_cast<Scalar>(s.block_samples);
    return (cap > Scalar(0) && n > cap) ? cap : n;
  }

  // A sample's share of the channel's state: counted, and the running mean (exponential with
  // the forgetting horizon) updated; d = y minus the mean before this sample (the first
  // sample starts the mean). NaN/Inf, or an unconfigured channel: counted in rejected, false.
  static bool observe(Track& t, const OnlineDriftSettings<Scalar>& s, Scalar y, Scalar& d) noexcept {
    if (t.status_ == OnlineDriftStatus::unconfigured || !std::isfinite(y)) {
      ++t.rejected_;
      return false;
    }
    ++t.samples_;
    if (t.samples_ == 1) t.estimate_.mean = y;
    d = y - t.estimate_.mean;
    t.estimate_.mean += d / mean_count(t, s);
    return true;
  }

  // The working state restarted for the channel now in t_ (SharedDriftIdentifier, at its
  // turn): the perturbed parameters from its theta, the four filters from the stationary
  // covariance of its estimate (the exact likelihood of the samples from here on, as at the
  // start of a record), empty block sums.
  void resume() noexcept {
    retuned_ = block_updated_ = false;
    in_block_ = 0;
    nis_block_ = Scalar(0);
    for (Scalar& v : g_) v = Scalar(0);
    for (Scalar& v : h_) v = Scalar(0);
    if (t_.status_ == OnlineDriftStatus::unconfigured) return;
    set_perturbed(settings_.ar_order == 2 ? std::tanh(t_.u_[1]) : Scalar(0));
    start_filters();
  }

  void start_filters() noexcept {
    start_filter(main_, t_.estimate_.a1, t_.estimate_.a2, t_.estimate_.q);
    start_filter(f_u1_, a1_u1_, t_.estimate_.a2, t_.estimate_.q);
    start_filter(f_u2_, a1_u2_, a2_u2_, t_.estimate_.q);
    start_filter(f_lq_, t_.estimate_.a1, t_.estimate_.a2, q_lq_);
  }

  // One filter step on d: innovation e and its variance f; then update and predict. The
  // filtered covariance is formed as r P / F (entries 00, 01) and (det P + p11 r) / F (11),
  // which keeps it positive semi-definite in float (no P - K H P cancellation).
  static void filter_step(Filter& s, Scalar a1, Scalar a2, Scalar q, Scalar r, Scalar d, Scalar& e,
                          Scalar& f) noexcept {
    f = s.p00 + r;
    e = d - s.x0;
    const Scalar inv_f = Scalar(1) / f;
    const Scalar k0 = s.p00 * inv_f, k1 = s.p01 * inv_f;
    const Scalar u0 = s.x0 + k0 * e, u1 = s.x1 + k1 * e;
    s.x0 = a1 * u0 + a2 * u1;
    s.x1 = u0;
    Scalar det = s.p00 * s.p11 - s.p01 * s.p01;
    if (det < Scalar(0)) det = Scalar(0);
    const Scalar f00 = s.p00 * r * inv_f, f01 = s.p01 * r * inv_f;
    const Scalar f11 = (det + s.p11 * r) * inv_f;
    s.p00 = a1 * a1 * f00 + Scalar(2) * a1 * a2 * f01 + a2 * a2 * f11 + q;
    s.p01 = a1 * f00 + a2 * f01;
    s.p11 = f00;
  }

  static void start_filter(Filter& s, Scalar a1, Scalar a2, Scalar q) noexcept {
    s.x0 = s.x1 = Scalar(0);
    drift_stationary_covariance(a1, a2, q, s.p00, s.p01);
    s.p11 = s.p00;
  }

  // Natural parameters of theta (and of the perturbed filters).
  void set_params() noexcept {
    const Scalar one = Scalar(1);
    const Scalar a2 = settings_.ar_order == 2 ? std::tanh(t_.u_[1]) : Scalar(0);
    t_.estimate_.a2 = a2;
    t_.estimate_.a1 = std::tanh(t_.u_[0]) * (one - a2);
    t_.estimate_.q = std::exp(t_.logq_);
    t_.estimate_.r = std::exp(t_.logr_);
    set_perturbed(a2);
  }

  // The perturbed filters' parameters (theta + delta e_j); a2 = tanh(u2), or 0 with ar_order 1.
  void set_perturbed(Scalar a2) noexcept {
    const Scalar one = Scalar(1);
    a1_u1_ = std::tanh(t_.u_[0] + delta()) * (one - a2);
    a2_u2_ = std::tanh(t_.u_[1] + delta());
    a1_u2_ = std::tanh(t_.u_[0]) * (one - a2_u2_);
    q_lq_ = std::exp(t_.logq_ + delta());
  }

  void clear_state() noexcept {
    t_.estimate_ = t_.configured_;
    t_.in_use_ = t_.configured_;
    t_.gain_[0] = t_.cgain_[0];
    t_.gain_[1] = t_.cgain_[1];
    const Scalar one = Scalar(1);
    Scalar q0 = t_.configured_.q;
    if (!(q0 > Scalar(0))) q0 = Scalar(1e-6) * t_.configured_.r;
    if (!(q0 > Scalar(0)) || !std::isfinite(q0)) q0 = one;  // unconfigured: any finite start
    const Scalar r0 = t_.configured_.r > Scalar(0) && std::isfinite(t_.configured_.r) ? t_.configured_.r : one;
    const Scalar a2 = std::isfinite(t_.configured_.a2) ? t_.configured_.a2 : Scalar(0);
    const Scalar a1 = std::isfinite(t_.configured_.a1) ? t_.configured_.a1 : Scalar(0);
    const Scalar p1 = (one - a2) != Scalar(0) ? a1 / (one - a2) : Scalar(0);
    const Scalar umax = Scalar(kOnlineDriftMaxU);
    t_.u_[0] = clamp(std::atanh(clamp(p1, -one, one)), -umax, umax);
    t_.u_[1] = settings_.ar_order == 2 ? clamp(std::atanh(clamp(a2, -one, one)), -umax, umax) : Scalar(0);
    t_.logq_ = std::log(q0);
    t_.logr_ = std::log(r0);
    set_params();
    if (t_.configured_.q > Scalar(0)) {  // exactly the configured model until the first update
      t_.estimate_.a1 = t_.configured_.a1;
      t_.estimate_.a2 = t_.configured_.a2;
      t_.estimate_.q = t_.configured_.q;
      t_.estimate_.r = t_.configured_.r;
    }
    // The estimate starts at the configured model where it is representable.
    const Scalar mean0 = t_.configured_.mean;
    t_.estimate_.mean = mean0;
    start_filters();
    for (Scalar& v : g_) v = Scalar(0);
    for (Scalar& v : h_) v = Scalar(0);
    for (Scalar& v : t_.r_info_) v = Scalar(0);
    nis_block_ = t_.nis_sum_ = Scalar(0);
    retuned_ = block_updated_ = false;
    in_block_ = 0;
    t_.blocks_ = 0;
    t_.retunes_ = t_.refused_retunes_ = 0;
    t_.samples_ = t_.rejected_ = 0;
  }

  static Scalar clamp(Scalar v, Scalar lo, Scalar hi) noexcept { return v < lo ? lo : (v > hi ? hi : v); }

  // Packed lower triangle of a symmetric 4x4: (i, j), i >= j.
  static constexpr int idx(int i, int j) noexcept { return i * (i + 1) / 2 + j; }

  void sample(Scalar d) noexcept {
    const Scalar r = t_.estimate_.r;
    Scalar e, f, e1, f1, e2, f2, e3, f3;
    filter_step(main_, t_.estimate_.a1, t_.estimate_.a2, t_.estimate_.q, r, d, e, f);
    if (is_free(0)) {
      filter_step(f_u1_, a1_u1_, t_.estimate_.a2, t_.estimate_.q, r, d, e1, f1);
    } else {
      e1 = e;
      f1 = f;
    }
    if (is_free(1)) {
      filter_step(f_u2_, a1_u2_, a2_u2_, t_.estimate_.q, r, d, e2, f2);
    } else {
      e2 = e;
      f2 = f;
    }
    filter_step(f_lq_, t_.estimate_.a1, t_.estimate_.a2, q_lq_, r, d, e3, f3);
    // Normalised sensitivities s_j = psi_j / sqrt(F), t_j = phi_j / (sqrt(2) F).
    const Scalar inv_delta = Scalar(1024);
    const Scalar rs = Scalar(1) / std::sqrt(f);
    const Scalar en = e * rs;
    const Scalar rt = Scalar(0.70710678118654752440084436210484903L) / f;
    Scalar sv[4], tv[4];
    sv[0] = (e1 - e) * inv_delta * rs;
    tv[0] = (f1 - f) * inv_delta * rt;
    sv[1] = (e2 - e) * inv_delta * rs;
    tv[1] = (f2 - f) * inv_delta * rt;
    sv[2] = (e3 - e) * inv_delta * rs;
    tv[2] = (f3 - f) * inv_delta * rt;
    sv[3] = -sv[2];
    tv[3] = Scalar(0.70710678118654752440084436210484903L) - tv[2];
    const Scalar w = (Scalar(1) - en * en) * Scalar(0.70710678118654752440084436210484903L);
    for (int j = 0; j < 4; ++j) {
      g_[j] += en * sv[j] + w * tv[j];
      for (int i = j; i < 4; ++i) h_[idx(i, j)] += sv[i] * sv[j] + tv[i] * tv[j];
    }
    nis_block_ += en * en;
  }

  // Cholesky factor of the packed matrix a (lower, packed in l); with ar_order 1 the u2 row
  // and column are replaced by the identity. False unless positive definite (each pivot above
  // 2^-20 of its diagonal entry) and finite.
  bool cholesky(const Scalar* a, Scalar ridge, Scalar* l) const noexcept {
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j <= i; ++j) {
        Scalar v = a[idx(i, j)];
        if (!is_free(i) || !is_free(j)) v = (i == j) ? Scalar(1) : Scalar(0);
        if (i == j) v += ridge * v;
        for (int k = 0; k < j; ++k) v -= l[idx(i, k)] * l[idx(j, k)];
        if (i == j) {
          const Scalar diag = is_free(i) ? a[idx(i, i)] : Scalar(1);
          if (!(v > diag * Scalar(1.0 / 1048576.0)) || !std::isfinite(v)) return false;
          l[idx(i, i)] = std::sqrt(v);
        } else {
          l[idx(i, j)] = v / l[idx(j, j)];
        }
      }
    }
    return true;
  }

  static void cholesky_solve(const Scalar* l, const Scalar* b, Scalar* x) noexcept {
    Scalar z[4];
    for (int i = 0; i < 4; ++i) {
      Scalar v = b[i];
      for (int k = 0; k < i; ++k) v -= l[idx(i, k)] * z[k];
      z[i] = v / l[idx(i, i)];
    }
    for (int i = 3; i >= 0; --i) {
      Scalar v = z[i];
      for (int k = i + 1; k < 4; ++k) v -= l[idx(k, i)] * x[k];
      x[i] = v / l[idx(i, i)];
    }
  }

  // Covariance of theta (full 4x4, row-major) from the information; false if unavailable.
  bool theta_covariance(Scalar* cov) const noexcept {
    if (t_.blocks_ == 0 || t_.status_ == OnlineDriftStatus::unconfigured) return false;
    Scalar l[10];
    if (!cholesky(t_.r_info_, Scalar(0), l)) return false;
    Scalar nb = static_cast<Scalar>(t_.blocks_);
    const Scalar m = settings_.memory_blocks;
    if (m > Scalar(0) && nb > Scalar(2) * m - Scalar(1)) nb = Scalar(2) * m - Scalar(1);
    const Scalar n_eff = nb * static_cast<Scalar>(settings_.block_samples);
    for (int j = 0; j < 4; ++j) {
      Scalar b[4] = {Scalar(0), Scalar(0), Scalar(0), Scalar(0)};
      b[j] = Scalar(1);
      Scalar x[4];
      cholesky_solve(l, b, x);
      for (int i = 0; i < 4; ++i) cov[4 * i + j] = x[i] / n_eff;
    }
    for (int k = 0; k < 2; ++k) {
      if (is_free(k)) continue;
      for (int i = 0; i < 4; ++i) cov[4 * i + k] = cov[4 * k + i] = Scalar(0);
    }
    return true;
  }

  void end_block() noexcept {
    in_block_ = 0;
    ++t_.blocks_;
    block_updated_ = true;
    const Scalar inv_b = Scalar(1) / static_cast<Scalar>(settings_.block_samples);
    Scalar gamma = Scalar(1);
    if (t_.blocks_ == 1) {
      t_.lambda_ = settings_.lambda_start;
    } else if (settings_.warmup_blocks > Scalar(0)) {
      const Scalar rho = Scalar(1) - Scalar(1) / settings_.warmup_blocks;
      t_.lambda_ = rho * t_.lambda_ + (Scalar(1) - rho);
      gamma = t_.gamma_ / (t_.gamma_ + t_.lambda_);
    } else {
      gamma = Scalar(1) / static_cast<Scalar>(t_.blocks_);
    }
    t_.gamma_ = gamma;
    const Scalar m = settings_.memory_blocks;
    if (m > Scalar(0) && gamma < Scalar(1) / m) gamma = Scalar(1) / m;
    Scalar gamma_r = gamma;
    if (settings_.info_blocks > Scalar(0) && gamma_r < Scalar(1) / settings_.info_blocks) {
      gamma_r = Scalar(1) / settings_.info_blocks;
    }
    for (int i = 0; i < 10; ++i) t_.r_info_[i] += gamma_r * (h_[i] * inv_b - t_.r_info_[i]);
    Scalar gb[4];
    for (int j = 0; j < 4; ++j) gb[j] = g_[j] * inv_b;
    for (int j = 0; j < 2; ++j) {
      if (!is_free(j)) gb[j] = Scalar(0);
    }
    Scalar l[10];
    if (cholesky(t_.r_info_, Scalar(1) / Scalar(65536), l)) {
      Scalar step[4];
      cholesky_solve(l, gb, step);
      const Scalar ms = settings_.max_step;
      // Scaled as a whole (the direction kept: the parameters are strongly correlated along
      // the likelihood's ridge) so that no component exceeds max_step.
      Scalar big = Scalar(0);
      for (int j = 0; j < 4; ++j) {
        step[j] = -gamma * step[j];
        if (std::fabs(step[j]) > big) big = std::fabs(step[j]);
      }
      if (big > ms) {
        const Scalar sc = ms / big;
        for (int j = 0; j < 4; ++j) step[j] *= sc;
      }
      if (std::isfinite(step[0] + step[1] + step[2] + step[3])) {
        const Scalar umax = Scalar(kOnlineDriftMaxU);
        const Scalar vlo = t_.log_var0_ - Scalar(kOnlineDriftLogVarRange);
        const Scalar vhi = t_.log_var0_ + Scalar(kOnlineDriftLogVarRange);
        if (is_free(0)) t_.u_[0] = clamp(t_.u_[0] + step[0], -umax, umax);
        if (is_free(1)) t_.u_[1] = clamp(t_.u_[1] + step[1], -umax, umax);
        t_.logq_ = clamp(t_.logq_ + step[2], vlo, vhi);
        t_.logr_ = clamp(t_.logr_ + step[3], vlo, vhi);
        set_params();
      }
    }
    for (Scalar& v : g_) v = Scalar(0);
    for (Scalar& v : h_) v = Scalar(0);
    t_.nis_sum_ += nis_block_;
    nis_block_ = Scalar(0);
    if (t_.blocks_ % settings_.retune_blocks == 0) retune();
  }

  // Wald statistic of the free AR parameters against zero (0 when none is free).
  Scalar ar_wald(const Scalar* cov) const noexcept {
    if (is_free(0) && is_free(1)) {
      const Scalar c00 = cov[0], c01 = cov[1], c11 = cov[5];
      const Scalar det = c00 * c11 - c01 * c01;
      if (!(det > Scalar(0))) return Scalar(0);
      return (c11 * t_.u_[0] * t_.u_[0] - Scalar(2) * c01 * t_.u_[0] * t_.u_[1] + c00 * t_.u_[1] * t_.u_[1]) / det;
    }
    if (is_free(0)) return cov[0] > Scalar(0) ? t_.u_[0] * t_.u_[0] / cov[0] : Scalar(0);
    return std::numeric_limits<Scalar>::infinity();  // AR part held: nothing to test
  }

  bool at_bound() const noexcept {
    const Scalar umax = Scalar(kOnlineDriftMaxU);
    const Scalar vlo = t_.log_var0_ - Scalar(kOnlineDriftLogVarRange);
    const Scalar vhi = t_.log_var0_ + Scalar(kOnlineDriftLogVarRange);
    return std::fabs(t_.u_[0]) >= umax || std::fabs(t_.u_[1]) >= umax || t_.logq_ <= vlo || t_.logq_ >= vhi ||
           t_.logr_ <= vlo || t_.logr_ >= vhi;
  }

  // Steady-state gain of the estimate: the Riccati recursion of filter_step from the main
  // filter's covariance, stopped as Ar2SteadyStateKalman stops (extrapolated remaining change
  // <= 64 eps relative, or the rounding floor). False if it does not get there.
  bool solve_gain(Scalar& k0, Scalar& k1) const noexcept {
    const Scalar eps = std::numeric_limits<Scalar>::epsilon();
    const Scalar tol = Scalar(64) * eps;
    const Scalar inf = std::numeric_limits<Scalar>::infinity();
    Filter s = main_;
    Scalar d1 = inf, d2 = inf;
    for (std::uint32_t it = 0; it < kOnlineDriftRetuneIterations; ++it) {
      const Scalar o00 = s.p00, o01 = s.p01, o11 = s.p11;
      Scalar e, f;
      filter_step(s, t_.estimate_.a1, t_.estimate_.a2, t_.estimate_.q, t_.estimate_.r, Scalar(0), e, f);
      if (!std::isfinite(s.p00 + s.p01 + s.p11)) return false;
      const Scalar d = std::fabs(s.p00 - o00) + std::fabs(s.p01 - o01) + std::fabs(s.p11 - o11);
      const Scalar scale = std::fabs(s.p00) + std::fabs(s.p01) + std::fabs(s.p11) + std::numeric_limits<Scalar>::min();
      const Scalar r1 = d / d1, r2 = d1 / d2;
      const Scalar rho = r1 > r2 ? r1 : r2;
      d2 = d1;
      d1 = d;
      if (d <= Scalar(4) * eps * scale || (rho < Scalar(1) && d * rho <= tol * scale * (Scalar(1) - rho))) {
        const Scalar fs = s.p00 + t_.estimate_.r;
        k0 = s.p00 / fs;
        k1 = s.p01 / fs;
        return std::isfinite(k0 + k1);
      }
    }
    return false;
  }

  void refuse(OnlineDriftStatus why) noexcept {
    ++t_.refused_retunes_;
    t_.status_ = why;
    t_.in_use_ = t_.configured_;
    if (t_.gain_[0] != t_.cgain_[0] || t_.gain_[1] != t_.cgain_[1]) retuned_ = true;
    t_.gain_[0] = t_.cgain_[0];
    t_.gain_[1] = t_.cgain_[1];
  }

  void retune() noexcept {
    const Scalar n_int = static_cast<Scalar>(settings_.retune_blocks) * static_cast<Scalar>(settings_.block_samples);
    const Scalar nis = t_.nis_sum_ / n_int;
    t_.nis_sum_ = Scalar(0);
    if (t_.samples_ < settings_.min_samples) {
      t_.status_ = OnlineDriftStatus::learning;
      return;
    }
    Scalar cov[16];
    const Scalar ratio = settings_.max_innovation_ratio;
    const bool sane = drift_params_status(t_.estimate_) == Ar2Status::ok && t_.estimate_.r > Scalar(0) && !at_bound() &&
                      std::isfinite(nis) && nis <= ratio && nis * ratio >= Scalar(1) && theta_covariance(cov);
    if (!sane) {
      refuse(OnlineDriftStatus::fallback);
      return;
    }
    const Scalar lim = settings_.max_rel_stderr;
    if (!(std::sqrt(cov[10]) <= lim) || !(std::sqrt(cov[15]) <= lim) || !(ar_wald(cov) >= settings_.min_ar_wald)) {
      refuse(OnlineDriftStatus::not_identified);
      return;
    }
    Scalar k0, k1;
    if (!solve_gain(k0, k1)) {
      refuse(OnlineDriftStatus::fallback);
      return;
    }
    t_.in_use_ = t_.estimate_;
    t_.gain_[0] = k0;
    t_.gain_[1] = k1;
    ++t_.retunes_;
    retuned_ = true;
    t_.status_ = OnlineDriftStatus::tracking;
  }

  Track t_{};  // the channel's state (the part SharedDriftIdentifier keeps per channel)
  OnlineDriftSettings<Scalar> settings_{};
  Filter main_{}, f_u1_{}, f_u2_{}, f_lq_{};
  Scalar a1_u1_ = Scalar(0), a1_u2_ = Scalar(0), a2_u2_ = Scalar(0), q_lq_ = Scalar(0);
  Scalar g_[4] = {};        // block sums of the gradient
  Scalar h_[10] = {};       // block sums of the information (packed)
  Scalar nis_block_ = Scalar(0);
  std::uint32_t in_block_ = 0;
  bool retuned_ = false;
  bool block_updated_ = false;
};

}  // namespace gyrodrift
