// Real-time sliding-window wavelet prefilter (paper 004, sec. 2.2), one per channel.
//
// Definition (the reference, per input sample once the window is full):
//   w   = the last N inputs, oldest first (N = WindowN, a power of two)
//   ext = [w, reverse(w)]                       (symmetric extension to 2N, then periodic)
//   c   = periodized J-level DWT of ext          (pywt.wavedec(ext, w, "periodization", J))
//   forced mode:    all detail coefficients set to zero
//   soft/hard mode: sigma = median(|cD_1|) / 0.6745, t = sigma * sqrt(2 ln N) (paper 000,
//                   sec. 2.3), pywt.threshold(cD_j, t, "soft"|"hard") for j = 1..J
//   output = inverse DWT(c)[N - 1]               (the filtered newest sample)
//
// Start-up: for the first N-1 accepted samples the window is not full and the paper does
// not filter ("the first N-1 samples are not processed"): step() returns the input
// unchanged and ready() is false. From the N-th accepted sample on, every output is filtered.
//
// Bad input: a NaN/Inf sample, or a finite one beyond filter_input_limit() (input_range.hpp:
// it would overflow the window sums and the detail coefficients, and NaN the output for a
// whole window length), is NOT inserted into the window; fault_count() is
// incremented and step() returns the previous output (0 before any output). The window,
// the start-up count and the filter state are untouched, so the next finite sample
// continues exactly as if the bad one had not arrived.
//
// Streaming: forced denoising of the newest sample is linear in the window, so it is an
// N-tap FIR filter y = sum_i taps[i] w[i] (taps derived once at construction from the lifting
// transform: with the orthogonal DWT F and the approximation projector P_J, taps =
// S^T F^T P_J F e_{N-1}, S the extension). Threshold modes: the level-1 coefficients of the
// extended window come from FIR streams (interior ones) plus ~2 x filter-length boundary
// coefficients, median(|d1|) is maintained incrementally (realtime_wavelet_noise.hpp),
// levels 2..J are lifted from the level-1 approximations, and the inverse transform is
// replaced by column N-1 of the DWT matrix (see threshold()).
//
// Fixed capacity, no heap, noexcept, deterministic. Invalid configurations (level outside
// 1..max for this window and wavelet, or a threshold mode on a forced-only filter) leave
// status() != ok; step() then passes inputs through.
//
// Memory per channel: RealtimeWavelet<Scalar, N> holds about 15N scalars (float, N = 256:
// 15,208 B); the forced-only RealtimeWavelet<Scalar, N, false> holds 5N (5,200 B).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "input_range.hpp"
#include "lifting_transform.hpp"
#include "realtime_wavelet_noise.hpp"

namespace gyrodrift {

enum class WaveletMode : std::uint8_t { forced = 0, soft = 1, hard = 2 };

enum class RealtimeWaveletStatus : std::uint8_t {
  ok = 0,
  level_out_of_range,  // level < 1, or (filter_length - 1) * 2^level > 2N (pywt dwt_max_level)
  bad_mode,
  window_unavailable,  // RealtimeWaveletWindows without a filter for the window asked for
};

// Largest level allowed for a 2N-sample extended window: pywt.dwt_max_level(2N, filter_len).
constexpr int realtime_wavelet_max_level(std::size_t window, WaveletKind w) noexcept {
  int level = 0;
  const auto flen = static_cast<std::size_t>(wavelet_filter_length(w) - 1);
  while (level < kMaxWaveletLevel && (flen << static_cast<unsigned>(level + 1)) <= 2 * window) ++level;
  return level;
}

namespace detail {
struct NoThresholdState {};  // forced-only filters carry no threshold-mode state
}  // namespace detail

// ThresholdModes = false gives a forced-only filter (soft/hard refused with bad_mode) that
// keeps just the taps, the window and one scratch buffer: 5N scalars instead of ~15N.
template <class Scalar, std::size_t WindowN, bool ThresholdModes = true>
class RealtimeWavelet {
  static_assert(WindowN >= 4 && (WindowN & (WindowN - 1)) == 0, "WindowN must be a power of two >= 4");

 public:
  static constexpr std::size_t kWindow = WindowN;

  explicit RealtimeWavelet(WaveletKind wavelet = WaveletKind::db8, int level = 5,
                           WaveletMode mode = WaveletMode::forced) noexcept
      : wavelet_(wavelet), level_(level), mode_(mode) {
    if (level < 1 || level > realtime_wavelet_max_level(WindowN, wavelet)) {
      status_ = RealtimeWaveletStatus::level_out_of_range;
    } else if (mode != WaveletMode::forced &&
               (!ThresholdModes || (mode != WaveletMode::soft && mode != WaveletMode::hard))) {
      status_ = RealtimeWaveletStatus::bad_mode;
    }
    compute_taps();
    if constexpr (ThresholdModes) {
      if (status_ == RealtimeWaveletStatus::ok && mode_ != WaveletMode::forced) configure_noise();
    }
    reset();
  }

  // Filters one sample (see the file comment for start-up and NaN/Inf behaviour).
  Scalar step(Scalar x) noexcept {
    if (!accepts(x)) {
      ++faults_;
      return last_out_;
    }
    buf_[pos_] = x;  // doubled circular buffer: after the increment the window is buf_[pos_, pos_+N)
    buf_[pos_ + WindowN] = x;
    pos_ = (pos_ + 1) % WindowN;
    if (count_ < WindowN) ++count_;
    const Scalar* w = &buf_[pos_];  // oldest .. newest
    if constexpr (ThresholdModes) {
      if (noise_ok_) {  // threshold modes: level-1 streams advance on every accepted sample
        median_d1_ = noise_.update(w);
        t_ = approx_.update(w);
      }
    }
    if (count_ < WindowN || status_ != RealtimeWaveletStatus::ok) {
      last_out_ = x;
      return x;
    }
    last_out_ = mode_ == WaveletMode::forced ? fir(w) : threshold(w);
    return last_out_;
  }

  void reset() noexcept {
    std::fill(buf_, buf_ + 2 * WindowN, Scalar(0));
    pos_ = 0;
    count_ = 0;
    faults_ = 0;
    last_out_ = Scalar(0);
    median_d1_ = Scalar(0);
    if constexpr (ThresholdModes) {
      noise_.reset();
      approx_.reset();
    }
    t_ = 0;
  }

  // Whether step() takes x into the window (finite and within the input range).
  static bool accepts(Scalar x) noexcept { return filter_input_ok(x); }

  bool ready() const noexcept { return count_ >= WindowN; }
  RealtimeWaveletStatus status() const noexcept { return status_; }
  std::uint32_t fault_count() const noexcept { return faults_; }
  WaveletKind wavelet() const noexcept { return wavelet_; }
  int level() const noexcept { return level_; }
  WaveletMode mode() const noexcept { return mode_; }

  // Forced-mode equivalent FIR: y[n] = sum_i taps()[i] * x[n - (N-1) + i] (oldest first).
  const Scalar* taps() const noexcept { return taps_; }

  // Full recompute of the window (the reference algorithm: extension, J-level lifting DWT,
  // thresholding with nth_element's median, inverse DWT) on an explicit window, oldest
  // first. Used by tests and benchmarks, and by threshold modes when the window is too short
  // for the streaming noise estimate (filter length > N/2). Not for forced-only filters.
  Scalar recompute(const Scalar* window) noexcept {
    static_assert(ThresholdModes, "recompute() needs the work buffer of the full filter");
    constexpr std::size_t n2 = 2 * WindowN;
    for (std::size_t i = 0; i < WindowN; ++i) {
      work_[i] = window[i];
      work_[n2 - 1 - i] = window[i];
    }
    LiftingTransform<Scalar>::forward(wavelet_, work_, n2, level_, scratch_);
    const std::size_t n_approx = n2 >> static_cast<unsigned>(level_);
    if (mode_ == WaveletMode::forced) {
      std::fill(work_ + n_approx, work_ + n2, Scalar(0));
    } else {
      const Scalar t = threshold_value(work_ + WindowN);  // cD_1 = last N coefficients
      for (std::size_t i = n_approx; i < n2; ++i) {
        const Scalar c = work_[i];
        const Scalar a = std::fabs(c);
        if (mode_ == WaveletMode::hard) {
          work_[i] = a >= t ? c : Scalar(0);  // pywt hard: zero where |c| < t
        } else {
          work_[i] = a > t ? std::copysign(a - t, c) : Scalar(0);
        }
      }
    }
    LiftingTransform<Scalar>::inverse(wavelet_, work_, n2, level_, scratch_);
    return work_[WindowN - 1];
  }

 private:
  Scalar fir(const Scalar* w) const noexcept {
    // Four accumulators: breaks the add dependency chain, fixed order (deterministic).
    Scalar s0 = Scalar(0), s1 = Scalar(0), s2 = Scalar(0), s3 = Scalar(0);
    for (std::size_t i = 0; i < WindowN; i += 4) {
      s0 += taps_[i] * w[i];
      s1 += taps_[i + 1] * w[i + 1];
      s2 += taps_[i + 2] * w[i + 2];
      s3 += taps_[i + 3] * w[i + 3];
    }
    return (s0 + s1) + (s2 + s3);
  }

  // Threshold modes without the inverse transform. With the orthogonal DWT F and c = F ext,
  // the full reconstruction gives ext[N-1] = x_newest = sum_k c_k F[k][N-1]; thresholding
  // changes only details, so  y = x_newest - sum_{detail k} (c_k - T(c_k)) F[k][N-1].
  // c - T(c) is clamp(c, -t, t) for soft and c [|c| < t] for hard thresholding; column N-1
  // of F has only a few dozen non-zero detail entries (62 for db8, N=256, J=5).
  Scalar threshold(const Scalar* w) noexcept {
    if constexpr (!ThresholdModes) {
      return w[WindowN - 1];  // unreachable: the constructor refuses threshold modes
    } else {
      return threshold_impl(w);
    }
  }

  Scalar threshold_impl(const Scalar* w) noexcept {
    if (n_col_ == 0) return recompute(w);  // capacity fallback (not reached for db4/db8)
    constexpr std::size_t n2 = 2 * WindowN;
    Scalar t = Scalar(0);
    if (noise_ok_) {
      // Level 1 from the streams (interior values) plus the boundary coefficients; levels
      // 2..J by lifting on the assembled approximation band.
      approx_.assemble(w, t_, work_);
      noise_.assemble(work_ + WindowN);
      if (level_ > 1) LiftingTransform<Scalar>::forward(wavelet_, work_, WindowN, level_ - 1, scratch_);
      t = threshold_from_median(median_d1_);
    } else {
      for (std::size_t i = 0; i < WindowN; ++i) {
        work_[i] = w[i];
        work_[n2 - 1 - i] = w[i];
      }
      LiftingTransform<Scalar>::forward(wavelet_, work_, n2, level_, scratch_);
      t = threshold_value(work_ + WindowN);
    }
    Scalar removed = Scalar(0);
    if (mode_ == WaveletMode::soft) {
      for (std::size_t i = 0; i < n_col_; ++i) {
        const Scalar c = work_[col_index_[i]];
        removed += (c > t ? t : (c < -t ? -t : c)) * col_value_[i];
      }
    } else {
      for (std::size_t i = 0; i < n_col_; ++i) {
        const Scalar c = work_[col_index_[i]];
        removed += (std::fabs(c) < t ? c : Scalar(0)) * col_value_[i];
      }
    }
    return w[WindowN - 1] - removed;
  }

  // t = sigma * sqrt(2 ln N), sigma = median(|cD_1|) / 0.6745 (paper 000, sec. 2.3).
  // Uses scratch_ (free between the forward and the inverse transform) for the selection.
  Scalar threshold_value(const Scalar* d1) noexcept {
    Scalar* med = scratch_;
    for (std::size_t i = 0; i < WindowN; ++i) {  // NaN (overflow) -> +Inf keeps a strict order
      const Scalar a = std::fabs(d1[i]);
      med[i] = a == a ? a : std::numeric_limits<Scalar>::infinity();
    }
    constexpr std::size_t mid = WindowN / 2;  // N even: median = mean of the two middle values
    std::nth_element(med, med + mid, med + WindowN);
    const Scalar upper = med[mid];
    const Scalar lower = *std::max_element(med, med + mid);
    return threshold_from_median((lower + upper) * Scalar(0.5));
  }

  static Scalar threshold_from_median(Scalar median) noexcept {
    const Scalar sigma = median / Scalar(0.6745);
    return sigma * std::sqrt(Scalar(2) * std::log(static_cast<Scalar>(WindowN)));
  }

  // High-pass taps G (pywt rec_hi) read off the lifting transform's impulse responses
  // (cD[k] = sum_i G[i] x[2k + m0 + i], m0 = 1 - taps/2), then the incremental median.
  void configure_noise() noexcept {
    const auto taps = static_cast<std::size_t>(wavelet_filter_length(wavelet_));
    const std::size_t n = 4 * taps;
    if (n > 2 * WindowN) return;  // window too short for the streaming estimate: recompute
    Scalar g[16] = {};
    Scalar h[16] = {};
    const auto m0 = 1 - static_cast<std::ptrdiff_t>(taps / 2);
    for (std::size_t p = 2 * taps; p < 2 * taps + 2; ++p) {
      std::fill(work_, work_ + n, Scalar(0));
      work_[p] = Scalar(1);
      LiftingTransform<Scalar>::forward_level(wavelet_, work_, n, scratch_);
      for (std::size_t k = 0; k < n / 2; ++k) {
        const std::ptrdiff_t i = static_cast<std::ptrdiff_t>(p) - 2 * static_cast<std::ptrdiff_t>(k) - m0;
        if (i >= 0 && i < static_cast<std::ptrdiff_t>(taps)) {
          h[static_cast<std::size_t>(i)] = work_[k];
          g[static_cast<std::size_t>(i)] = work_[n / 2 + k];
        }
      }
    }
    noise_ok_ = noise_.configure(g, taps) && approx_.configure(h, taps);
  }

  void compute_taps() noexcept {
    constexpr std::size_t n2 = 2 * WindowN;
    // Forced-only filters borrow the (not yet started) window buffer as work space.
    Scalar* work = ThresholdModes ? work_ : buf_;
    std::fill(taps_, taps_ + WindowN, Scalar(0));
    if (status_ != RealtimeWaveletStatus::ok) return;
    // Projector Q = F^T P_J F is symmetric, so row N-1 of Q is Q e_{N-1}; folding the
    // extension (ext[i] and ext[2N-1-i] both equal w[i]) gives taps[i] = q[i] + q[2N-1-i].
    std::fill(work, work + n2, Scalar(0));
    work[WindowN - 1] = Scalar(1);
    LiftingTransform<Scalar>::forward(wavelet_, work, n2, level_, scratch_);
    std::fill(work + (n2 >> static_cast<unsigned>(level_)), work + n2, Scalar(0));
    LiftingTransform<Scalar>::inverse(wavelet_, work, n2, level_, scratch_);
    for (std::size_t i = 0; i < WindowN; ++i) taps_[i] = work[i] + work[n2 - 1 - i];
    if constexpr (ThresholdModes) compute_column();
  }

  void compute_column() noexcept {
    constexpr std::size_t n2 = 2 * WindowN;
    Scalar* work = work_;
    // Column N-1 of F restricted to details: F e_{N-1} (lifting keeps exact zeros outside
    // the support, so the non-zero test is exact).
    std::fill(work, work + n2, Scalar(0));
    work[WindowN - 1] = Scalar(1);
    LiftingTransform<Scalar>::forward(wavelet_, work, n2, level_, scratch_);
    n_col_ = 0;
    for (std::size_t k = n2 >> static_cast<unsigned>(level_); k < n2; ++k) {
      if (work[k] == Scalar(0)) continue;
      if (n_col_ == kColCapacity) {
        n_col_ = 0;  // cannot happen for db4/db8 (<= filter length per level); recompute then
        break;
      }
      col_index_[n_col_] = static_cast<std::uint32_t>(k);
      col_value_[n_col_] = work[k];
      ++n_col_;
    }
  }

  WaveletKind wavelet_;
  int level_;
  WaveletMode mode_;
  RealtimeWaveletStatus status_ = RealtimeWaveletStatus::ok;
  std::size_t pos_ = 0;
  std::size_t count_ = 0;
  std::uint32_t faults_ = 0;
  Scalar last_out_ = Scalar(0);
  Scalar taps_[WindowN];
  Scalar buf_[2 * WindowN];
  Scalar work_[ThresholdModes ? 2 * WindowN : 1];
  Scalar scratch_[2 * WindowN];
  // <= filter length (16) non-zeros per level touch one sample; 8 levels.
  static constexpr std::size_t kColCapacity = ThresholdModes ? 16 * kMaxWaveletLevel : 1;
  template <class T>
  using IfThreshold = std::conditional_t<ThresholdModes, T, detail::NoThresholdState>;
  IfThreshold<SlidingDetailMedian<Scalar, WindowN>> noise_;  // level-1 details + median(|d1|)
  IfThreshold<Level1Stream<Scalar, WindowN>> approx_;         // level-1 approximations
  std::size_t t_ = 0;                            // stream index of the newest sample
  bool noise_ok_ = false;
  Scalar median_d1_ = Scalar(0);
  std::size_t n_col_ = 0;
  std::uint32_t col_index_[kColCapacity] = {};
  Scalar col_value_[kColCapacity] = {};
};

}  // namespace gyrodrift
