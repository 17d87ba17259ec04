// One online re-identification (filters/online_drift_identifier.hpp) time-shared among up to
// `Channels` gyro channels, for a target that watches several gyros within a small RAM and
// per-step budget: the channels take turns of one block each (round robin, in channel order).
//
// During channel c's turn its samples run through the estimator's four Kalman filters and
// block sums exactly as in OnlineDriftIdentifier; at the end of the block come its parameter
// update and, on its cadence, its gain retune; then the turn passes to the next channel. The
// other channels' samples only update their running mean and sample count (a division each).
// Each channel keeps its own state (OnlineDriftIdentifier::Track: the configured model and
// gain, theta, the information R, the start-up schedule, the gain in use, the counters); the
// filters, block sums and settings exist once. A turn starts the filters from the stationary
// covariance of the channel's estimate (the exact likelihood of the block's samples, as at the
// start of a record), so a block is the same statistic as in the single-channel estimator,
// whose filters run on from the previous block.
//
// A channel in turn that delivers no usable sample (a NaN/Inf pushed, or skip(): the caller's
// checks refused the value, e.g. a stuck or saturated gyro) keeps the turn only until it has
// missed block_samples samples during it; then its partial block is dropped (no parameter
// update) and the turn passes on, so a failed gyro cannot stop the others' re-identification.
// A few missing samples within a turn are skipped as if absent, as in OnlineDriftIdentifier.
//
// Effect: with n channels each one's estimate advances by one block every n blocks of samples,
// so every time constant counted in blocks (the start-up schedule warmup_blocks, the memory
// memory_blocks and info_blocks, the retune cadence retune_blocks) is n times longer in time,
// and so are the convergence and tracking times (docs/validation/online-identification.md);
// min_samples counts the channel's samples (all of them, as the mean does), of which the
// estimate has seen 1/n. With one channel this is OnlineDriftIdentifier, sample for sample.
// Cost per step: one channel's filter steps and (n - 1) mean updates; at most one parameter
// update (and retune) per step, plus the next turn's start (four tanh, an exp, four
// stationary covariances).
//
// Allocation-free, noexcept, deterministic, templated on Scalar; float-safe.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "drift_likelihood.hpp"
#include "online_drift_identifier.hpp"

namespace gyrodrift {

template <class Scalar, std::size_t Channels>
class SharedDriftIdentifier {
  static_assert(Channels >= 1 && Channels <= 8, "Channels in 1..8");

 public:
  using Identifier = OnlineDriftIdentifier<Scalar>;
  using Track = typename Identifier::Track;
  static constexpr std::size_t capacity = Channels;

  SharedDriftIdentifier() noexcept = default;

  // Channels 0 .. n - 1 with their configured models (the start and fallback of each), one
  // setting for all. False (no channel configured) for n outside 1..Channels or a model or
  // settings OnlineDriftIdentifier::configure refuses; `failed` is then the first channel
  // refused (n for a bad n). The turn starts at channel 0.
  bool configure(const DriftModelParams<Scalar>* models, std::size_t n, const OnlineDriftSettings<Scalar>& s,
                 std::size_t* failed = nullptr) noexcept {
    n_ = 0;
    turn_ = 0;
    missed_ = 0;
    retuned_ = false;
    if (n < 1 || n > Channels) {
      if (failed != nullptr) *failed = n;
      return false;
    }
    for (std::size_t c = n; c-- > 0;) {  // channel c > 0 parked at c - 1, channel 0 in turn
      if (!id_.configure(models[c], s)) {
        if (failed != nullptr) *failed = c;
        id_ = Identifier{};
        return false;
      }
      if (c > 0) parked_[c - 1] = id_.t_;
    }
    n_ = n;
    return true;
  }

  // Every channel back to its configured model, counters cleared, the turn at channel 0.
  void reset() noexcept {
    retuned_ = false;
    missed_ = 0;
    if (n_ == 0) return;
    for (std::size_t k = 0; k < n_; ++k) {
      id_.reset();
      rotate(false);
    }
    while (turn_ != 0) rotate(false);
    id_.resume();
  }

  // One sample of channel c (after the caller's bad-value checks). Returns false for a
  // channel out of range, an unconfigured one, or NaN/Inf (counted in its rejected count and,
  // for the channel in turn, towards passing its turn on).
  bool push(std::size_t c, Scalar y) noexcept {
    retuned_ = false;
    if (c >= n_) return false;
    if (c != turn_) {
      Scalar d;
      return Identifier::observe(parked_[park_index(c)], id_.settings_, y, d);
    }
    const bool ok = id_.push(y);
    retuned_ = id_.retuned();
    if (id_.block_updated()) {
      if (n_ > 1) rotate(true);
    } else if (!ok) {
      miss();
    }
    return ok;
  }

  // Channel c has no usable sample at this step (the caller's checks refused its value: stuck,
  // saturated, non-finite). Nothing of the channel's state changes; for the channel in turn it
  // counts towards passing the turn on, as a rejected push() does.
  void skip(std::size_t c) noexcept {
    retuned_ = false;
    if (c < n_ && c == turn_) miss();
  }

  std::size_t channels() const noexcept { return n_; }
  std::size_t turn() const noexcept { return turn_; }  // the channel whose block runs now
  // True after the push() that retuned its channel's gain (an accepted retune, or a refused one
  // that put the configured gain back): reload that channel's gain0(c), gain1(c) then.
  bool retuned() const noexcept { return retuned_; }
  const OnlineDriftSettings<Scalar>& settings() const noexcept { return id_.settings_; }

  // Channel c's state (c < channels()).
  OnlineDriftStatus status(std::size_t c) const noexcept { return track(c).status_; }
  const DriftModelParams<Scalar>& configured(std::size_t c) const noexcept { return track(c).configured_; }
  const DriftModelParams<Scalar>& estimate(std::size_t c) const noexcept { return track(c).estimate_; }
  const DriftModelParams<Scalar>& in_use(std::size_t c) const noexcept { return track(c).in_use_; }
  Scalar gain0(std::size_t c) const noexcept { return track(c).gain_[0]; }
  Scalar gain1(std::size_t c) const noexcept { return track(c).gain_[1]; }
  std::uint32_t retunes(std::size_t c) const noexcept { return track(c).retunes_; }
  std::uint32_t refused_retunes(std::size_t c) const noexcept { return track(c).refused_retunes_; }
  std::uint32_t blocks(std::size_t c) const noexcept { return track(c).blocks_; }
  std::uint64_t samples(std::size_t c) const noexcept { return track(c).samples_; }
  std::uint64_t rejected(std::size_t c) const noexcept { return track(c).rejected_; }

 private:
  // parked_[i] holds channel (turn_ + 1 + i) mod n_.
  std::size_t park_index(std::size_t c) const noexcept { return (c + n_ - turn_ - 1) % n_; }

  const Track& track(std::size_t c) const noexcept {
    if (c >= n_ || c == turn_) return id_.t_;
    return parked_[park_index(c)];
  }

  // A sample of the channel in turn missing: after block_samples of them in one turn (and
  // with another channel to take it) its partial block is dropped and the turn passes on.
  void miss() noexcept {
    if (n_ > 1 && ++missed_ >= id_.settings_.block_samples) rotate(true);
  }

  // The turn passes to the next channel: the one in turn is parked last, the first parked
  // one comes in (and, with `start`, its working state is started: a partial block of the
  // channel parked is dropped).
  void rotate(bool start) noexcept {
    missed_ = 0;
    if (n_ > 1) {
      const Track out = id_.t_;
      id_.t_ = parked_[0];
      for (std::size_t i = 0; i + 2 < n_; ++i) parked_[i] = parked_[i + 1];
      parked_[n_ - 2] = out;
      turn_ = (turn_ + 1) % n_;
    }
    if (start) id_.resume();
  }

  Identifier id_{};                                   // the channel in turn, and the working state
  std::array<Track, Channels - 1> parked_{};        // the others
  std::size_t n_ = 0;
  std::size_t turn_ = 0;
  std::uint32_t missed_ = 0;  // samples the channel in turn missed during this turn
  bool retuned_ = false;
};

}  // namespace gyrodrift
