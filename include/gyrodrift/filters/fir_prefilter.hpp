// Forced wavelet prefilter as an exact FIR with taps in flash (paper 004 sec. 2.2, forced mode).
//
// Forced denoising of the newest sample of a sliding window is linear in the window, so it is
// an N-tap FIR y[n] = sum_i taps[i] x[n - (N-1) + i] whose taps depend only on the wavelet,
// the window N and the level J (realtime_wavelet.hpp derives them; `gyrodrift config
// emit-cpp` writes them as a constexpr table). This stage keeps only a pointer to the taps
// (a const table: flash on an MCU) and ONE copy of the window (circular, N scalars), where
// RealtimeWavelet<Scalar, N, false> holds taps + a doubled window + scratch (5N scalars).
//
// Behaviour identical to RealtimeWavelet in forced mode: the first N-1 accepted samples pass
// through unchanged (ready() false), NaN/Inf is skipped (not put in the window), counted in
// fault_count() and answered with the previous output; the sum uses the same four
// accumulators in the same order, so equal taps give bit-identical outputs.
//
// No heap, noexcept, deterministic. A null taps pointer leaves status() == no_taps.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

namespace gyrodrift {

enum class FirPrefilterStatus : std::uint8_t { ok = 0, no_taps = 1 };

template <class Scalar, std::size_t WindowN>
class FirPrefilter {
  static_assert(WindowN >= 4 && (WindowN & (WindowN - 1)) == 0, "WindowN must be a power of two >= 4");

 public:
  static constexpr std::size_t kWindow = WindowN;
  using Status = FirPrefilterStatus;

  // taps: WindowN coefficients, oldest sample first; must outlive the filter (a static table).
  explicit FirPrefilter(const Scalar* taps = nullptr) noexcept : taps_(taps) { reset(); }

  Scalar step(Scalar x) noexcept {
    if (!std::isfinite(x)) {
      ++faults_;
      return last_out_;
    }
    buf_[pos_] = x;
    pos_ = (pos_ + 1) & (WindowN - 1);  // now the oldest sample
    if (count_ < WindowN) ++count_;
    if (count_ < WindowN || taps_ == nullptr) {
      last_out_ = x;
      return x;
    }
    last_out_ = fir();
    return last_out_;
  }

  void reset() noexcept {
    for (std::size_t i = 0; i < WindowN; ++i) buf_[i] = Scalar(0);
    pos_ = 0;
    count_ = 0;
    faults_ = 0;
    last_out_ = Scalar(0);
  }

  bool ready() const noexcept { return count_ >= WindowN; }
  Status status() const noexcept { return taps_ == nullptr ? Status::no_taps : Status::ok; }
  std::uint32_t fault_count() const noexcept { return faults_; }
  const Scalar* taps() const noexcept { return taps_; }

 private:
  Scalar fir() const noexcept {
    // Window sample i (oldest first) is buf_[(pos_ + i) mod N] (N a power of two: a mask).
    // Four accumulators, tap i into accumulator i mod 4, as in RealtimeWavelet::fir (same
    // order, same result); four independent add chains keep the FPU pipeline busy.
    constexpr std::size_t m = WindowN - 1;
    Scalar s0 = Scalar(0), s1 = Scalar(0), s2 = Scalar(0), s3 = Scalar(0);
    for (std::size_t i = 0; i < WindowN; i += 4) {
      const std::size_t j = pos_ + i;
      s0 += taps_[i] * buf_[j & m];
      s1 += taps_[i + 1] * buf_[(j + 1) & m];
      s2 += taps_[i + 2] * buf_[(j + 2) & m];
      s3 += taps_[i + 3] * buf_[(j + 3) & m];
    }
    return (s0 + s1) + (s2 + s3);
  }

  const Scalar* taps_;
  Scalar buf_[WindowN];
  std::size_t pos_ = 0;
  std::size_t count_ = 0;
  std::uint32_t faults_ = 0;
  Scalar last_out_ = Scalar(0);
};

}  // namespace gyrodrift
