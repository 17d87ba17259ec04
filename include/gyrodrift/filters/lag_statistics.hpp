// Whole-record lag statistics of a rate record, kept while streaming, from which the exact
// likelihood of the drift model "AR(2) drift + white noise" (drift_likelihood.hpp, the offline
// fit gyrodrift.filters.fit_drift_model) follows for any parameters, up to terms of order
// rho^Lags (rho the pole modulus of the model's steady-state innovation filter). The
// equations, the likelihood and the fit from these statistics are those of the numpy reference
// gyrodrift.reference.lag_drift (docs/validation/online-identification.md, "Whole-record
// statistics"); this header keeps the statistics on the target, the fit from them is
// lag_drift_fit.hpp.
//
// State of the accepted samples y_0 .. y_{n-1}, with w_t = y_t - c and c = y_0 (the centre):
//   n; sum_t w_t; the lag products P_k = sum_{t>=k} w_t w_{t-k} for k = 0..Lags;
//   the first min(n, Lags) values of w (head) and the last min(n, Lags) (tail, a ring: the
//   lag products need it anyway), both read out oldest first.
// Per sample: Lags + 1 products, each added to its compensated sum, and one compensated add
// for sum w. No heap, no exceptions, no double unless Scalar is double.
//
// Precision (float on the MCU, hours at 400 Hz): every sum is carried as a renormalised pair
// sum + comp ("double-Scalar": TwoSum of sum and the term, the error added to comp, then comp
// folded back into sum by Fast2Sum; stability/compensated_sum.hpp). After 10^7 terms
// of about one ulp of the sum each, a plain float sum has lost a fair part of them, and
// Kahan/Neumaier's correction term, itself summed plainly, grows to a fair part of the sum;
// the pair's own rounding is at most of order n u^2 of the sum (u the unit roundoff, 2^-24 in
// float; observed about 1e-13 of P_0 after 10^6 float samples). What is left is the rounding
// of each w_t (Scalar subtraction) and of each product:
//   |error of P_k| <= (3u + O(n u^2)) sum_t |w_t w_{t-k}| <= (3u + O(n u^2)) P_0,
// observed 3e-11 to 3e-8 of P_0 on the records measured (6e4 to 1.44e7 samples), nearly all
// from the rounding of w_t: at most u |w_t| <= u (|y_t| + |c|), the order of the rounding of
// the float samples themselves, and larger the farther c lies from the record's mean.
// A float pair added in double (double(sum) + double(comp)) is its value to double precision, so
// a double fit on the target's float statistics reads them at that accuracy.
// The error-free transformations need IEEE round-to-nearest without reassociation: do not
// build this with -ffast-math.
//
// State: 2 (Lags + 1) + 2 + 2 Lags + 1 Scalars and 16 bytes of counters, padded: sizeof is 552 bytes
// for LagStatistics<float, 32> and 1080 for <double, 32> on x86-64 (checked in
// cpp/tests/test_lag_statistics.cpp); 552 on Cortex-M4 (cpp/cortex_m/use_lag_statistics.cpp).
// Without the first values (KeepHead = false, LagStatisticsNoHead: for Whittle's likelihood
// with the first samples replaced by the record's mean, lag_drift_fit.hpp) the state is
// 2 (Lags + 1) + 2 + Lags + 1 Scalars and the counters: 136 bytes for <float, 8> and 184 for
// <float, 12>, on x86-64 and on the Cortex-M4 alike; the sums and the tail are those of the
// full form on the same samples, bit for bit.
// Non-finite samples (and a sample whose w_t^2 overflows) are not used: push() returns false,
// the statistics are untouched and rejected() counts them.
#pragma once
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "../stability/compensated_sum.hpp"

namespace gyrodrift {

namespace detail {
// The first min(n, Lags) values of w, kept or not (an empty base when not: no bytes).
template <class Scalar, std::size_t Lags, bool Keep>
struct LagHeadStore {
  void keep(std::size_t i, Scalar w) noexcept { values_[i] = w; }
  Scalar values_[Lags]{};
};
template <class Scalar, std::size_t Lags>
struct LagHeadStore<Scalar, Lags, false> {
  void keep(std::size_t, Scalar) noexcept {}
};
}  // namespace detail

// KeepHead: whether the first min(n, Lags) values of w are kept (the exact likelihood needs
// them; Whittle's with the first samples replaced by the mean does not).
template <class Scalar, std::size_t Lags, bool KeepHead = true>
class LagStatistics : private detail::LagHeadStore<Scalar, Lags, KeepHead> {
  static_assert(Lags >= 1 && Lags <= 1024, "Lags must be in 1..1024");
  using HeadStore = detail::LagHeadStore<Scalar, Lags, KeepHead>;

 public:
  static constexpr std::size_t lags = Lags;
  static constexpr bool keeps_head = KeepHead;

  // A sum carried as the renormalised pair sum + comp (|comp| at most half an ulp of sum).
  using Sum = CompensatedSum<Scalar>;

  LagStatistics() noexcept = default;

  // Forgets every sample and the rejected count.
  void reset() noexcept { *this = LagStatistics{}; }

  // One rate sample. False (statistics untouched, counted in rejected()) if it is not finite
  // or its w_t^2 is not.
  bool push(Scalar y) noexcept {
    const Scalar w = n_ == 0 ? Scalar(0) : y - centre_;
    const Scalar w2 = w * w;
    if (!std::isfinite(y) || !std::isfinite(w2)) {
      if (rejected_ != 0xFFFFFFFFU) ++rejected_;
      return false;
    }
    if (n_ == 0) centre_ = y;
    products_[0].add(w2);
    // P_k += w_t w_{t-k}, k = 1..min(n, Lags): the ring holds w_{t-1} at next_ - 1, then
    // backwards (wrapping) to the oldest kept value.
    const std::size_t back = kept();
    std::size_t k = 1;
    for (std::size_t j = next_; j > 0 && k <= back; ++k) products_[k].add(w * ring_[--j]);
    for (std::size_t j = Lags; k <= back; ++k) products_[k].add(w * ring_[--j]);
    total_.add(w);
    if (n_ < Lags) HeadStore::keep(static_cast<std::size_t>(n_), w);
    ring_[next_] = w;
    next_ = next_ + 1 == Lags ? 0U : next_ + 1;
    ++n_;
    return true;
  }

  // Samples of an array in time order (the count accepted); the same state as pushing them
  // one at a time.
  std::size_t push(const Scalar* y, std::size_t count) noexcept {
    std::size_t accepted = 0;
    for (std::size_t i = 0; i < count; ++i) accepted += push(y[i]) ? 1U : 0U;
    return accepted;
  }

  // Accepted samples n.
  std::uint64_t samples() const noexcept { return n_; }
  // Samples refused (not finite); stops at 2^32 - 1.
  std::uint64_t rejected() const noexcept { return rejected_; }
  // c: the first accepted sample (0 before it).
  Scalar centre() const noexcept { return centre_; }
  // sum_t w_t.
  Sum total() const noexcept { return total_; }
  // P_k = sum_{t>=k} w_t w_{t-k} for k <= Lags ({0, 0} beyond).
  Sum product(std::size_t k) const noexcept { return k <= Lags ? products_[k] : Sum{}; }
  // min(n, Lags): the number of head and of tail values.
  std::size_t kept() const noexcept { return n_ < Lags ? static_cast<std::size_t>(n_) : Lags; }
  // w_i, i < kept() (0 beyond): the first values of w (only when they are kept).
  template <bool Kept = KeepHead, typename std::enable_if<Kept, int>::type = 0>
  Scalar head(std::size_t i) const noexcept {
    return i < kept() ? HeadStore::values_[i] : Scalar(0);
  }
  // w_{n - kept() + i}, i < kept() (0 beyond): the last values of w, oldest first.
  Scalar tail(std::size_t i) const noexcept {
    const std::size_t m = kept();
    if (i >= m) return Scalar(0);
    std::size_t j = next_ + Lags - m + i;
    if (j >= Lags) j -= Lags;
    if (j >= Lags) j -= Lags;
    return ring_[j];
  }

 private:
  Sum products_[Lags + 1]{};
  Sum total_{};
  Scalar ring_[Lags]{};  // ring_[next_ - 1] (wrapping) is the newest w
  std::uint64_t n_{0};
  Scalar centre_{0};
  std::uint32_t next_{0};      // ring slot of the next sample
  std::uint32_t rejected_{0};  // saturating
};

// The statistics without the first values: n, c, sum w, P_0..P_L and the last L values.
template <class Scalar, std::size_t Lags>
using LagStatisticsNoHead = LagStatistics<Scalar, Lags, false>;

}  // namespace gyrodrift
