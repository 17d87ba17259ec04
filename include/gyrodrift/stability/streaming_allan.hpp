// Streaming non-overlapped Allan variance at octave-spaced averaging times, one sample at a
// time, for the target: fixed memory chosen at compile time, no heap, no exceptions, no
// double unless Scalar is double.
//
// Estimator (IEEE Std 952-1997 Annex C, non-overlapped; NIST SP 1065 eq. 6, allantools.adev):
// rate samples y_0, y_1, ... at interval tau0; at averaging factor m = 2^k (tau = m tau0) the
// record is cut into M = floor(N / m) consecutive clusters of m samples with means ybar_j, and
//   sigma^2(tau) = 1 / (2 (M - 1)) * sum_{j=0}^{M-2} (ybar_{j+1} - ybar_j)^2.
// The number of squared differences, M - 1, is terms(k). Its equivalent degrees of freedom
// are Greenhall & Riley's for d = 2, F = m, S = 1 (gyrodrift.stability.edf.edf_greenhall with
// overlapping=False, modified=False, n_phase = N + 1), which the Python wrapper applies.
//
// Cascaded pairwise averaging: the cluster means of octave k + 1 are the averages of pairs of
// consecutive cluster means of octave k (octave 0: the samples). Every new cluster mean adds
// one squared difference to its octave and, every second one, passes a pair average up: two
// octave updates per sample on average (amortized O(1)), at most `Octaves` in one step.
// Which octaves take a new cluster mean follows from the sample count alone (octave k has
// floor(N / 2^k) cluster means), so an octave keeps no counters or flags: its last cluster
// mean (which is also the first half of the next octave's cluster while that waits for its
// partner) and its compensated sum.
// The error-free transformations need IEEE round-to-nearest without reassociation: do not
// build this with -ffast-math (-ffp-contract only fuses d * d into the sum, which is harmless).
// State: 4 Scalars per octave (16 bytes in float) and a fixed 24-byte part (float, 32-bit MCU).
//
// Precision (float on the MCU, hours at 400 Hz):
// - the cluster means are pairwise averages carried as unevaluated pairs hi + lo (TwoSum:
//   about twice the precision of Scalar), so the difference of two neighbouring means, which
//   is small against the means themselves once a slow drift or a bias has moved them, is
//   not swamped by the rounding of the means;
// - the first accepted sample is subtracted from every sample (the origin, exactly: the
//   subtraction is a TwoSum too), so a large constant rate (bias, Earth rate) does not sit in
//   the cluster means whose differences are squared;
// - the sums of squared differences are compensated and renormalised (CompensatedSum), so
//   the rounding stays at a few eps after 10^7 and more terms instead of growing with the
//   term count.
// Non-finite samples are not used: push() returns false and rejected() counts them (the record
// is then one sample shorter; the cluster boundaries move by one sample).
#pragma once
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "compensated_sum.hpp"

namespace gyrodrift {

// Octaves: capacity (tau0 * 2^0 .. tau0 * 2^(Octaves - 1)); configure() may use fewer.
template <class Scalar, std::size_t Octaves>
class StreamingAllan {
  static_assert(Octaves >= 1 && Octaves <= 48, "Octaves must be in 1..48");

 public:
  static constexpr std::size_t capacity = Octaves;

  StreamingAllan() noexcept = default;

  // rate_hz > 0 and finite, 1 <= octaves <= Octaves; returns false (state unchanged) otherwise.
  // Resets the statistics.
  bool configure(Scalar rate_hz, std::size_t octaves) noexcept {
    if (!(rate_hz > Scalar(0)) || !std::isfinite(rate_hz) || octaves < 1 || octaves > Octaves) {
      return false;
    }
    tau0_s_ = Scalar(1) / rate_hz;
    octaves_ = static_cast<std::uint32_t>(octaves);
    reset();
    return true;
  }

  // Forgets every sample (keeps the configuration).
  void reset() noexcept {
    for (std::size_t k = 0; k < Octaves; ++k) {
      octave_[k] = Octave{};
    }
    origin_ = Scalar(0);
    samples_ = 0;
    rejected_ = 0;
  }

  // One rate sample. False (and counted in rejected()) if it is not finite or the object is
  // not configured.
  bool push(Scalar y) noexcept { return push(y, [](std::size_t, Scalar) noexcept {}); }

  // The same, calling on_term(k, d2) with each new squared difference d2 of octave k right
  // after it went into the octave's sum (lowest octave first; terms(k) already counts it):
  // the health alarms' block statistics take their terms from here.
  template <class OnTerm>
  bool push(Scalar y, OnTerm&& on_term) noexcept {
    if (octaves_ == 0 || !std::isfinite(y)) {
      if (rejected_ != 0xFFFFFFFFU) ++rejected_;
      return false;
    }
    if (samples_ == 0) origin_ = y;
    ++samples_;
    Pair mean = two_sum(y, -origin_);
    for (std::size_t k = 0; k < octaves_; ++k) {
      // this is cluster mean number c = N / 2^k of octave k (N a multiple of 2^k here)
      const std::uint64_t c = samples_ >> k;
      Octave& o = octave_[k];
      if (c >= 2) {
        // hi parts of neighbouring means are close, so their difference is (nearly) exact
        const Scalar d = (mean.hi - o.prev.hi) + (mean.lo - o.prev.lo);
        const Scalar d2 = d * d;
        o.sum_sq.add(d2);
        on_term(k, d2);
      }
      if ((c & 1U) != 0U) {  // first half of the next octave's cluster: wait for its partner
        o.prev = mean;
        return true;
      }
      const Pair up = average(o.prev, mean);
      o.prev = mean;
      mean = up;
    }
    return true;
  }

  // Samples of an array (the count accepted).
  std::size_t push(const Scalar* y, std::size_t n) noexcept {
    std::size_t accepted = 0;
    for (std::size_t i = 0; i < n; ++i) accepted += push(y[i]) ? 1U : 0U;
    return accepted;
  }

  std::size_t octaves() const noexcept { return octaves_; }
  Scalar tau0_s() const noexcept { return tau0_s_; }
  // tau of octave k: tau0 * 2^k seconds.
  Scalar tau_s(std::size_t k) const noexcept {
    return tau0_s_ * std::ldexp(Scalar(1), static_cast<int>(k));
  }
  // Averaging factor of octave k (samples per cluster).
  std::uint64_t factor(std::size_t k) const noexcept { return std::uint64_t{1} << k; }
  // Squared differences summed at octave k: floor(N / 2^k) - 1 (0 before two clusters).
  std::uint64_t terms(std::size_t k) const noexcept {
    if (k >= octaves_) return 0;
    const std::uint64_t c = samples_ >> k;
    return c >= 2 ? c - 1 : 0;
  }
  std::uint64_t samples() const noexcept { return samples_; }
  // Samples refused (not finite, or not configured); stops at 2^32 - 1.
  std::uint64_t rejected() const noexcept { return rejected_; }

  // Allan variance at octave k in (rate units)^2; false if k is out of range or it has no term.
  bool avar(std::size_t k, Scalar& out) const noexcept {
    const std::uint64_t n = terms(k);
    if (n == 0) return false;
    out = octave_[k].sum_sq.value() / (Scalar(2) * static_cast<Scalar>(n));
    return std::isfinite(out);
  }

  // The compensated sum of the squared differences at octave k (sum + comp, about twice the
  // precision of Scalar); {0, 0} out of range. The difference of two of these taken terms
  // apart is the sum over those terms to a few eps.
  CompensatedSum<Scalar> sum_sq(std::size_t k) const noexcept {
    return k < octaves_ ? octave_[k].sum_sq : CompensatedSum<Scalar>{};
  }

 private:
  // A cluster mean as an unevaluated sum hi + lo (lo: the rounding error of hi).
  struct Pair {
    Scalar hi{0};
    Scalar lo{0};
  };
  // Knuth's TwoSum: a + b = hi + lo exactly (round to nearest, no reassociation).
  static Pair two_sum(Scalar a, Scalar b) noexcept {
    const Scalar hi = a + b;
    const Scalar bb = hi - a;
    const Scalar lo = (a - (hi - bb)) + (b - bb);
    return {hi, lo};
  }
  // (a + b) / 2 as a renormalised pair (the halving is exact).
  static Pair average(const Pair& a, const Pair& b) noexcept {
    const Pair s = two_sum(a.hi, b.hi);
    const Pair r = two_sum(s.hi, s.lo + (a.lo + b.lo));
    return {r.hi * Scalar(0.5), r.lo * Scalar(0.5)};
  }

  struct Octave {
    CompensatedSum<Scalar> sum_sq{};
    Pair prev{};  // last cluster mean: the next difference's partner and, when the octave
                  // has an odd number of means, the first half of the next octave's cluster
  };

  Octave octave_[Octaves]{};
  std::uint64_t samples_{0};
  Scalar tau0_s_{0};
  Scalar origin_{0};
  std::uint32_t octaves_{0};
  std::uint32_t rejected_{0};  // saturating
};

}  // namespace gyrodrift
