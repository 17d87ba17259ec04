// Fixed-size latency histogram for the loop's statistics: constant memory (no heap after
// construction), O(1) record, percentiles to one bin width; the exact maximum is kept aside
// so a value past the last bin is never lost (it lands in the overflow bin).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>

namespace gyrodrift::loop {

template <std::size_t Bins>
class LatencyHistogram {
 public:
  explicit LatencyHistogram(std::uint64_t bin_ns) noexcept : bin_ns_(bin_ns == 0 ? 1 : bin_ns) {}

  void record(std::uint64_t ns) noexcept {
    std::uint64_t bin = ns / bin_ns_;
    if (bin >= Bins) bin = Bins - 1;  // overflow bin: counted, max still exact
    ++counts_[static_cast<std::size_t>(bin)];
    ++n_;
    if (ns > max_ns_) max_ns_ = ns;
  }

  std::uint64_t count() const noexcept { return n_; }
  std::uint64_t max_ns() const noexcept { return max_ns_; }

  // Upper edge of the bin holding the q-quantile (q in [0, 1]); the exact max for the top
  // bin or when the quantile falls in the overflow bin. 0 when empty.
  std::uint64_t quantile_ns(double q) const noexcept {
    if (n_ == 0) return 0;
    const double target = q * static_cast<double>(n_);
    std::uint64_t rank = static_cast<std::uint64_t>(target);
    if (static_cast<double>(rank) < target) ++rank;
    if (rank == 0) rank = 1;
    std::uint64_t seen = 0;
    for (std::size_t b = 0; b < Bins; ++b) {
      seen += counts_[b];
      if (seen >= rank) {
        if (b == Bins - 1) return max_ns_;
        const std::uint64_t edge = (static_cast<std::uint64_t>(b) + 1) * bin_ns_;
        return edge < max_ns_ ? edge : max_ns_;
      }
    }
    return max_ns_;
  }

 private:
  std::uint64_t bin_ns_;
  std::array<std::uint32_t, Bins> counts_{};
  std::uint64_t n_ = 0;
  std::uint64_t max_ns_ = 0;
};

}  // namespace gyrodrift::loop
