// Health alarms for one gyro channel: its streaming Allan variance leaves the reference model's
// interval (angle random walk up, bias instability up, rate random walk up), or the channel is
// stuck or saturating for too long. Alarms are latched (stay raised until reset() or
// unlatch()), counted, and keep the statistic that tripped them.
//
// The reference is the expected Allan variance at each octave of the streaming curve (from the
// configured drift model, health_reference_from_drift_model, or from IEEE 952 terms,
// health_reference_from_ieee952, or learned from the first part of a record), so one alarm
// logic serves both. Allocation-free, noexcept, templated on Scalar.
//
// Octave classes (at configure(), from the reference's local slope over two octaves,
// r_k = ref_{k+1} / ref_{k-1}, one-sided and squared at the ends): the leading run of octaves
// with r_k <= 1/2 (falling at least as tau^-1/2 in variance per octave: white rate noise)
// belongs to arw_high; after it, octaves with r_k >= 2 (rising: rate random walk, or the rising
// part of an AR(2) drift's hump) to rate_random_walk_high, the others (around the minimum, the
// flat or falling correlated part) to bias_instability_high.
//
// Tests (each time an octave has a new squared difference: the alarms take every term from
// StreamingAllan::push's term callback, term(), and update() once per sample; push() does
// both):
// - block test: when octave k's term count reaches a multiple of block_terms, the Allan
//   variance of the last block_terms terms alone, sigma^2_b, from their sum, which the alarms
//   add up term by term as they arrive (one Scalar per octave; block_terms roundings of
//   Scalar at most, at any record length), so a change is seen within a block and not diluted
//   by the record so far;
// - start-up test: while octave k holds fewer than block_terms terms, the Allan variance of
//   the whole record so far at each new term (the curve's compensated sum).
// The ratio sigma^2 / ref_k is tested against max(f^2, chi2_{1-p}(nu) / nu): f the class's
// factor (N, B or K up by more than f means the variance up by more than f^2), p =
// false_alarm_probability, chi2 by Wilson-Hilferty (stability/allan_chi2.hpp), nu the edf of
// the terms tested: the reference's local slope mu at octave k (over two octaves) taken as a
// power law tau^mu, its squared differences' correlations from the phase's generalized
// autocovariance (mu = -1: white rate noise, rho(1) = -1/2; 0: flicker; 1: random walk; the
// rising side of an AR(2) drift's hump, mu up to 2, has strongly correlated differences and
// few degrees of freedom per term), computed once at configure() for block_terms terms (in
// double; where there is no hardware double, kHealthEdfFromSlope, the reference must carry it)
// and scaled to the number of terms tested. Under a reference equal to the truth (a
// stationary sensor), a test fails with probability about p or less; a test fails when the
// measured ratio exceeds f^2 and is significant at p.
// stuck / saturated: the caller's per-sample flags, raised when that many samples in a row are
// flagged (0: off).
// Trip statistics: octave tests keep sqrt(ratio) (measured / expected Allan deviation) against
// sqrt(threshold) and the octave's tau; stuck/saturated the run length against the setting.
// `sample` is the number of update() calls when it tripped.
// Cost: per update() two counter updates; per new term at an octave (two per sample on
// average, amortized) an addition, the block position (a 32-bit remainder), and at a test a
// division, the chi-square bound, a square root and a comparison.
// State (sizeof, float, Cortex-M4): 12 bytes per octave (reference variance and edf per term,
// the block's sum) plus 224 bytes (settings, class masks, counts, five trips of 24
// bytes) (docs/guides/health-alarms.md).
// Records = false (the processor's monitors, whose reports are the latched bits and the
// processor's own counters): no trips, raise or exceedance counts, and the reference and the
// settings are referred to, not copied (they must outlive the alarms: on the target the
// reference is a constant table in flash and the settings one copy that every gyro's alarms
// share; on a target without kHealthEdfFromSlope the reference must carry its edf per term,
// as there always): 4 bytes per octave plus 40, 104 bytes for 16 on the Cortex-M4F.
// The numpy reference is gyrodrift.reference.health (same equations).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "../filters/drift_likelihood.hpp"
#include "../stability/allan_chi2.hpp"
#include "../stability/model_allan.hpp"
#include "../stability/streaming_allan.hpp"

namespace gyrodrift {

inline constexpr std::uint16_t kAlarmArwHigh = 1U << 0;              // short-tau Allan variance up
inline constexpr std::uint16_t kAlarmBiasInstabilityHigh = 1U << 1;  // Allan variance near the minimum up
inline constexpr std::uint16_t kAlarmRateRandomWalkHigh = 1U << 2;   // long-tau Allan variance up
inline constexpr std::uint16_t kAlarmStuck = 1U << 3;                // stuck longer than allowed
inline constexpr std::uint16_t kAlarmSaturated = 1U << 4;            // saturated longer than allowed

struct HealthAlarmName {
  std::uint16_t bit;
  const char* name;
};
inline constexpr HealthAlarmName kHealthAlarmNames[] = {
    {kAlarmArwHigh, "arw_high"},
    {kAlarmBiasInstabilityHigh, "bias_instability_high"},
    {kAlarmRateRandomWalkHigh, "rate_random_walk_high"},
    {kAlarmStuck, "stuck"},
    {kAlarmSaturated, "saturated"},
};
inline constexpr std::size_t kHealthAlarmCount = sizeof(kHealthAlarmNames) / sizeof(kHealthAlarmNames[0]);

// Whether HealthAlarms::configure derives a missing edf per term from the reference's slope
// (power_law_edf_per_term, in double). Off on a target without a double-precision FPU (e.g.
// Cortex-M4F, __ARM_FP without bit 3), where software double would be pulled into the image:
// there every reference must carry its edf (health_reference_from_drift_model fills it; the
// generated firmware header writes the table the host computes from the channel's drift model,
// gyrodrift.stability.model_allan.ar2_white_edf_per_term), and configure() rejects a
// reference without one (health_reference_from_ieee952's, whose edf comes from the slope).
#if defined(__ARM_FP) && !(__ARM_FP & 8)
inline constexpr bool kHealthEdfFromSlope = false;
#else
inline constexpr bool kHealthEdfFromSlope = true;
#endif

template <class Scalar, std::size_t Octaves>
struct HealthReference {
  Scalar avar[Octaves] = {};  // expected Allan variance at octave k (tau = 2^k / rate), channel units^2
  std::size_t octaves = 0;    // number of valid entries
  // Optional: equivalent degrees of freedom per squared difference of a block at octave k
  // under the reference model (0 < e <= 1; 0: derived from the reference's local slope at
  // configure()). health_reference_from_drift_model fills it exactly for its model.
  Scalar edf_per_term[Octaves] = {};
};

template <class Scalar>
struct HealthAlarmSettings {
  Scalar arw_factor = Scalar(2);               // alarm when N is up by more than this factor
  Scalar bias_instability_factor = Scalar(2);  // ... B up by more than this factor
  Scalar rate_random_walk_factor = Scalar(2);  // ... K up by more than this factor
  Scalar false_alarm_probability = Scalar(1e-6);  // per check and octave, for the chi-square bound
  std::uint32_t stuck_samples = 0;      // 0: off; stuck for this many samples in a row raises stuck
  std::uint32_t saturated_samples = 0;  // 0: off; saturated this many samples in a row raises saturated
  std::uint32_t block_terms = 64;       // squared differences per block test at each octave (>= 4)
};

// What tripped an alarm (the first time it was raised).
template <class Scalar>
struct HealthTrip {
  Scalar statistic = Scalar(0);  // e.g. measured / expected Allan deviation, or samples in a row
  Scalar threshold = Scalar(0);  // the value it exceeded
  Scalar tau_s = Scalar(0);      // averaging time of the octave (0 for stuck/saturated)
  std::uint64_t sample = 0;      // sample count when it tripped
};

namespace detail {

// t mod b (b > 0) without a 64-bit division (none in the Cortex-M instruction set, a library
// call otherwise): the low word by one 32-bit division while the high word is 0 (2^32 terms:
// 124 days at 400 Hz), else the high word's remainder extended bit by bit over the low word.
inline std::uint32_t mod_u64_u32(std::uint64_t t, std::uint32_t b) noexcept {
  const auto hi = static_cast<std::uint32_t>(t >> 32);
  const auto lo = static_cast<std::uint32_t>(t);
  if (hi == 0U) return lo % b;
  std::uint64_t r = hi % b;
  for (int i = 31; i >= 0; --i) {
    r = (r << 1) | ((lo >> i) & 1U);
    if (r >= b) r -= b;
  }
  return static_cast<std::uint32_t>(r);
}

// What HealthAlarms keeps besides its tests: with Records, a copy of the reference, the raise
// and exceedance counts and a trip per alarm; without, a pointer to the caller's reference.
template <class Scalar, std::size_t Octaves, bool Records>
struct HealthAlarmStore {
  HealthReference<Scalar, Octaves> ref{};
  HealthAlarmSettings<Scalar> set{};
  std::uint32_t raised[kHealthAlarmCount] = {};
  std::uint32_t exceedances[kHealthAlarmCount] = {};
  HealthTrip<Scalar> trip[kHealthAlarmCount] = {};
  const HealthReference<Scalar, Octaves>& reference() const noexcept { return ref; }
  const HealthAlarmSettings<Scalar>& settings() const noexcept { return set; }
  std::size_t octaves() const noexcept { return ref.octaves; }
  Scalar edf(std::size_t k) const noexcept { return ref.edf_per_term[k]; }
  void set_edf(std::size_t k, Scalar v) noexcept { ref.edf_per_term[k] = v; }
};
// Without Records, where the edf may be derived (kHealthEdfFromSlope: the host), the alarms
// keep the edf per term they use (the reference's, or derived); on the target they read the
// reference's (which must carry it) and keep nothing.
template <class Scalar, std::size_t Octaves, bool Own>
struct HealthAlarmEdf {
  Scalar edf_per_term[Octaves] = {};
};
template <class Scalar, std::size_t Octaves>
struct HealthAlarmEdf<Scalar, Octaves, false> {};
template <class Scalar, std::size_t Octaves>
struct HealthAlarmStore<Scalar, Octaves, false> : HealthAlarmEdf<Scalar, Octaves, kHealthEdfFromSlope> {
  const HealthReference<Scalar, Octaves>* ref = nullptr;  // set by a successful configure()
  const HealthAlarmSettings<Scalar>* set = nullptr;        // likewise
  const HealthReference<Scalar, Octaves>& reference() const noexcept { return *ref; }
  const HealthAlarmSettings<Scalar>& settings() const noexcept { return *set; }
  std::size_t octaves() const noexcept { return ref != nullptr ? ref->octaves : 0U; }
  Scalar edf(std::size_t k) const noexcept {
    if constexpr (kHealthEdfFromSlope) {
      return this->edf_per_term[k];
    } else {
      return reference().edf_per_term[k];
    }
  }
  void set_edf(std::size_t k, Scalar v) noexcept {
    if constexpr (kHealthEdfFromSlope) {
      this->edf_per_term[k] = v;
    } else {
      (void)k;
      (void)v;
    }
  }
};

}  // namespace detail

template <class Scalar, std::size_t Octaves, bool Records = true>
class HealthAlarms {
  static_assert(Octaves >= 1 && Octaves <= 48, "Octaves must be in 1..48");
  using Reference = HealthReference<Scalar, Octaves>;

 public:
  static constexpr bool kRecords = Records;

  // False (state unchanged) for a reference with more than Octaves or no octaves, a
  // non-finite or non-positive entry, a factor below 1 or not finite, false_alarm_probability
  // outside (0, 0.5], or block_terms below 4; without kHealthEdfFromSlope also for a reference
  // entry whose edf per term is 0. Resets the alarms. Without Records the
  // alarms keep a pointer to `ref`: it must outlive them (a temporary is refused at compile time).
  template <bool R = Records, class = std::enable_if_t<!R>>
  bool configure(Reference&& ref, const HealthAlarmSettings<Scalar>& s) = delete;
  template <bool R = Records, class = std::enable_if_t<!R>>
  bool configure(const Reference& ref, HealthAlarmSettings<Scalar>&& s) = delete;
  template <bool R = Records, class = std::enable_if_t<!R>>
  bool configure(Reference&& ref, HealthAlarmSettings<Scalar>&& s) = delete;
  bool configure(const Reference& ref, const HealthAlarmSettings<Scalar>& s) noexcept {
    constexpr bool derive_edf = kHealthEdfFromSlope;
    if (ref.octaves < 1 || ref.octaves > Octaves) return false;
    for (std::size_t k = 0; k < ref.octaves; ++k) {
      if (!(ref.avar[k] > Scalar(0)) || !std::isfinite(ref.avar[k])) return false;
      if (!(ref.edf_per_term[k] >= Scalar(0)) || ref.edf_per_term[k] > Scalar(1)) return false;
      if (!derive_edf && !(ref.edf_per_term[k] > Scalar(0))) return false;
    }
    const Scalar factors[3] = {s.arw_factor, s.bias_instability_factor, s.rate_random_walk_factor};
    for (const Scalar f : factors) {
      if (!(f >= Scalar(1)) || !std::isfinite(f)) return false;
    }
    if (!(s.false_alarm_probability > Scalar(0)) || !(s.false_alarm_probability <= Scalar(0.5)) ||
        s.block_terms < 4) {
      return false;
    }
    if constexpr (Records) {
      store_.ref = ref;
      store_.set = s;
    } else {
      store_.ref = &ref;
      store_.set = &s;
    }
    z_ = -normal_quantile(s.false_alarm_probability);  // 1 - p would round in float
    arw_mask_ = 0;
    rrw_mask_ = 0;
    const std::size_t n = ref.octaves;
    bool leading = true;
    for (std::size_t k = 0; k < n; ++k) {
      Scalar r = Scalar(1);
      if (n >= 3 && k > 0 && k + 1 < n) {
        r = ref.avar[k + 1] / ref.avar[k - 1];
      } else if (n >= 2) {
        const Scalar one = k == 0 ? ref.avar[1] / ref.avar[0] : ref.avar[k] / ref.avar[k - 1];
        r = one * one;
      }
      const Mask bit = Mask{1} << k;
      if (leading && (n == 1 || r <= Scalar(0.5))) {
        arw_mask_ |= bit;
        continue;
      }
      leading = false;
      if (r >= Scalar(2)) rrw_mask_ |= bit;
    }
    for (std::size_t k = 0; k < n; ++k) {
      if (ref.edf_per_term[k] > Scalar(0) && ref.edf_per_term[k] <= Scalar(1)) {
        store_.set_edf(k, ref.edf_per_term[k]);
        continue;
      }
      if constexpr (derive_edf) {
        const double lo = static_cast<double>(ref.avar[k > 0 ? k - 1 : k]);
        const double hi = static_cast<double>(ref.avar[k + 1 < n ? k + 1 : k]);
        const double span = (k > 0 && k + 1 < n) ? 2.0 : 1.0;
        const double mu = n >= 2 ? std::log2(hi / lo) / span : -1.0;
        store_.set_edf(k, static_cast<Scalar>(power_law_edf_per_term(mu, s.block_terms)));
      }
    }
    reset();
    return true;
  }

  // Clears the alarms, counts and trips and restarts the tests (keeps the configuration).
  void reset() noexcept {
    latched_ = 0;
    if constexpr (Records) {
      for (std::size_t i = 0; i < kHealthAlarmCount; ++i) {
        store_.raised[i] = 0;
        store_.exceedances[i] = 0;
        store_.trip[i] = HealthTrip<Scalar>{};
      }
    }
    for (std::size_t k = 0; k < Octaves; ++k) block_[k] = Scalar(0);
    updates_ = 0;
    stuck_run_ = 0;
    saturated_run_ = 0;
  }

  // Lowers the latched bits (counts and trips stay; the next raise records a new trip).
  void unlatch() noexcept { latched_ = 0; }

  // Every squared difference d2 of octave k, as `allan` produces it (StreamingAllan::push's
  // term callback, the same curve every time, not reset in between unless these alarms are
  // reset too), then update() once for the sample.
  void term(const StreamingAllan<Scalar, Octaves>& allan, std::size_t k, Scalar d2) noexcept {
    const std::size_t ref_octaves = store_.octaves();
    if (k >= ref_octaves || k >= allan.octaves()) return;
    block_[k] += d2;
    check_octave(allan, k);
  }

  // Once per sample, after the sample's terms (term()). Returns the latched bits.
  std::uint16_t update(bool stuck, bool saturated) noexcept {
    ++updates_;
    stuck_run_ = stuck ? sat_inc(stuck_run_) : 0U;
    saturated_run_ = saturated ? sat_inc(saturated_run_) : 0U;
    const HealthAlarmSettings<Scalar>& set = settings();
    if (set.stuck_samples > 0 && stuck_run_ >= set.stuck_samples) {
      raise(3, static_cast<Scalar>(stuck_run_), static_cast<Scalar>(set.stuck_samples), Scalar(0), updates_);
    }
    if (set.saturated_samples > 0 && saturated_run_ >= set.saturated_samples) {
      raise(4, static_cast<Scalar>(saturated_run_), static_cast<Scalar>(set.saturated_samples), Scalar(0),
            updates_);
    }
    return latched_;
  }

  // One sample into `allan` and the alarms: allan.push(y) feeding term(), then update().
  // False (the alarms still updated) if the curve refused y.
  bool push(StreamingAllan<Scalar, Octaves>& allan, Scalar y, bool stuck, bool saturated) noexcept {
    const bool used = allan.push(y, [this, &allan](std::size_t k, Scalar d2) noexcept { term(allan, k, d2); });
    update(stuck, saturated);
    return used;
  }

  std::uint16_t latched() const noexcept { return latched_; }
  // Times alarm i (index into kHealthAlarmNames) was raised since reset (0 or 1 while latched).
  template <bool R = Records, class = std::enable_if_t<R>>
  std::uint32_t raised(std::size_t i) const noexcept {
    return i < kHealthAlarmCount ? store_.raised[i] : 0;
  }
  // Failed tests of alarm i since reset (octave tests over the threshold, or samples of a
  // stuck/saturated run at or beyond its limit), counted also while the alarm is latched.
  template <bool R = Records, class = std::enable_if_t<R>>
  std::uint32_t exceedances(std::size_t i) const noexcept {
    return i < kHealthAlarmCount ? store_.exceedances[i] : 0;
  }
  template <bool R = Records, class = std::enable_if_t<R>>
  const HealthTrip<Scalar>& trip(std::size_t i) const noexcept {
    return store_.trip[i < kHealthAlarmCount ? i : 0];
  }
  // The alarm bit octave k's tests raise (0 beyond the reference).
  std::uint16_t octave_alarm(std::size_t k) const noexcept {
    if (k >= store_.octaves()) return 0;
    const Mask bit = Mask{1} << k;
    if ((arw_mask_ & bit) != 0U) return kAlarmArwHigh;
    if ((rrw_mask_ & bit) != 0U) return kAlarmRateRandomWalkHigh;
    return kAlarmBiasInstabilityHigh;
  }
  // The reference in use (without Records: only after a successful configure()).
  const Reference& reference() const noexcept { return store_.reference(); }
  // The settings in use (without Records: only after a successful configure(), and they are
  // the caller's, which must outlive the alarms, as the reference).
  const HealthAlarmSettings<Scalar>& settings() const noexcept { return store_.settings(); }
  std::uint64_t updates() const noexcept { return updates_; }

 private:
  static std::uint32_t sat_inc(std::uint32_t v) noexcept { return v == 0xFFFFFFFFU ? v : v + 1U; }

  // edf / n of n squared differences of power-law noise whose Allan variance goes as tau^mu
  // (mu clamped to [-1, 1.9]): the phase's generalized autocovariance G(t) = t^2 (|t|^mu - 1) / mu
  // (t^2 ln|t| at mu = 0; the t^2 term is annihilated by the differences), the correlations
  // rho(h) of consecutive second differences from its fourth differences, edf = n^2 / (n + 2
  // sum_{h<n} (n - h) rho(h)^2). In double: the fourth differences cancel to h^-4 of G.
  static double power_law_edf_per_term(double mu, std::uint32_t n) noexcept {
    if (!std::isfinite(mu) || mu < -1.0) mu = -1.0;
    if (mu > 1.9) mu = 1.9;
    const auto g = [mu](double t) noexcept {
      t = std::fabs(t);
      if (t == 0.0) return 0.0;
      const double l = std::log(t);
      const double x = mu * l;
      const double f = x == 0.0 ? 1.0 : std::expm1(x) / x;
      return t * t * l * f;
    };
    const auto c = [&g](double h) noexcept {
      return g(h - 2.0) - 4.0 * g(h - 1.0) + 6.0 * g(h) - 4.0 * g(h + 1.0) + g(h + 2.0);
    };
    const double c0 = c(0.0);
    const double nn = static_cast<double>(n);
    double sum = 0.0;
    for (std::uint32_t h = 1; h < n; ++h) {
      const double r = c(static_cast<double>(h)) / c0;
      sum += (nn - static_cast<double>(h)) * r * r;
    }
    return nn / (nn + 2.0 * sum);
  }

  void raise(std::size_t i, Scalar statistic, Scalar threshold, Scalar tau_s, std::uint64_t sample) noexcept {
    if constexpr (Records) store_.exceedances[i] = sat_inc(store_.exceedances[i]);
    const std::uint16_t bit = kHealthAlarmNames[i].bit;
    if ((latched_ & bit) != 0U) return;
    latched_ = static_cast<std::uint16_t>(latched_ | bit);
    if constexpr (Records) {
      store_.raised[i] = sat_inc(store_.raised[i]);
      store_.trip[i] = HealthTrip<Scalar>{statistic, threshold, tau_s, sample};
    } else {
      (void)sample;
      (void)statistic;
      (void)threshold;
      (void)tau_s;
    }
  }

  // After block_[k] took octave k's newest term: the block test when the term count is a
  // multiple of block_terms, else the start-up test while it is below.
  void check_octave(const StreamingAllan<Scalar, Octaves>& allan, std::size_t k) noexcept {
    const std::uint64_t terms = allan.terms(k);
    const std::uint32_t block_terms = settings().block_terms;
    Scalar var = Scalar(0);
    std::uint32_t tested = 0;  // 32-bit: a hardware conversion to float on the MCU
    if (detail::mod_u64_u32(terms, block_terms) == 0U) {
      var = block_[k] / (Scalar(2) * static_cast<Scalar>(block_terms));
      tested = block_terms;
      block_[k] = Scalar(0);
    } else if (terms < block_terms) {
      if (!allan.avar(k, var)) return;
      tested = static_cast<std::uint32_t>(terms);  // < block_terms
    } else {
      return;
    }
    const std::uint16_t bit = octave_alarm(k);
    const std::size_t c = bit == kAlarmArwHigh ? 0U : (bit == kAlarmBiasInstabilityHigh ? 1U : 2U);
    const HealthAlarmSettings<Scalar>& set = settings();
    const Scalar f = c == 0U ? set.arw_factor : (c == 1U ? set.bias_instability_factor : set.rate_random_walk_factor);
    const Scalar f2 = f * f;
    const Reference& ref = reference();
    Scalar nu = store_.edf(k) * static_cast<Scalar>(tested);
    if (nu < Scalar(1)) nu = Scalar(1);
    const Scalar chi = chi2_quantile_wh(nu, z_) / nu;
    const Scalar thr = chi > f2 ? chi : f2;
    const Scalar ratio = var / ref.avar[k];
    if (ratio > thr) raise(c, std::sqrt(ratio), std::sqrt(thr), allan.tau_s(k), updates_ + 1U);
  }

  // Octave class masks: 32 bits where they hold every octave.
  using Mask = std::conditional_t<(Octaves <= 32), std::uint32_t, std::uint64_t>;

  detail::HealthAlarmStore<Scalar, Octaves, Records> store_{};
  Scalar block_[Octaves] = {};  // sum of the squared differences of the current block per octave
  std::uint64_t updates_ = 0;
  Mask arw_mask_ = 0;
  Mask rrw_mask_ = 0;
  Scalar z_ = Scalar(0);
  std::uint32_t stuck_run_ = 0;
  std::uint32_t saturated_run_ = 0;
  std::uint16_t latched_ = 0;
};

// Reference from the drift model "AR(2) drift + white noise" (exact expected Allan variance at
// tau = 2^k / rate, k < octaves; stability/model_allan.hpp). Computes in double and rounds to
// Scalar (the difference of two near-equal sums loses digits for a smooth drift). False
// (ref untouched) for an invalid model or octaves outside 1..Octaves.
// The edf per term is that of block_terms terms under the model (ar2_white_edf_per_term; pass
// the alarms' block_terms).
template <class Scalar, std::size_t Octaves>
bool health_reference_from_drift_model(const DriftModelParams<Scalar>& p, std::size_t octaves,
                                       HealthReference<Scalar, Octaves>& ref,
                                       std::uint32_t block_terms = 64) noexcept {
  if (octaves < 1 || octaves > Octaves || block_terms < 1) return false;
  double av[Octaves] = {};
  double e[Octaves] = {};
  const double a1 = static_cast<double>(p.a1);
  const double a2 = static_cast<double>(p.a2);
  const double q = static_cast<double>(p.q);
  const double r = static_cast<double>(p.r);
  if (!ar2_white_avar<double>(a1, a2, q, r, octaves, av) ||
      !ar2_white_edf_per_term<double>(a1, a2, q, r, octaves, block_terms, e)) {
    return false;
  }
  for (std::size_t k = 0; k < Octaves; ++k) {
    ref.avar[k] = k < octaves ? static_cast<Scalar>(av[k]) : Scalar(0);
    ref.edf_per_term[k] = k < octaves ? static_cast<Scalar>(e[k]) : Scalar(0);
  }
  ref.octaves = octaves;
  return true;
}

// Reference from IEEE 952 terms in the channel's units at rate_hz (stability/model_allan.hpp:
// q_angle quantization, n angle random walk, b bias instability, k rate random walk; tau = 2^k /
// rate_hz). False for octaves outside 1..Octaves, a negative or non-finite term, all terms 0,
// or a rate not positive.
template <class Scalar, std::size_t Octaves>
bool health_reference_from_ieee952(Scalar q_angle, Scalar n, Scalar b, Scalar k, Scalar rate_hz,
                                   std::size_t octaves, HealthReference<Scalar, Octaves>& ref) noexcept {
  const Scalar t[4] = {q_angle, n, b, k};
  for (const Scalar v : t) {
    if (!(v >= Scalar(0)) || !std::isfinite(v)) return false;
  }
  if (octaves < 1 || octaves > Octaves || !(rate_hz > Scalar(0)) || !std::isfinite(rate_hz) ||
      !(q_angle + n + b + k > Scalar(0))) {
    return false;
  }
  for (std::size_t j = 0; j < octaves; ++j) {
    const Scalar tau = std::ldexp(Scalar(1), static_cast<int>(j)) / rate_hz;
    ref.avar[j] = ieee952_avar(q_angle, n, b, k, tau);
  }
  for (std::size_t j = octaves; j < Octaves; ++j) ref.avar[j] = Scalar(0);
  for (std::size_t j = 0; j < Octaves; ++j) ref.edf_per_term[j] = Scalar(0);  // from the slope
  ref.octaves = octaves;
  return true;
}

}  // namespace gyrodrift
