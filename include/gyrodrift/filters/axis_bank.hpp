// A bank of identical-type per-axis filters (3 gyro axes by default): any filter type with
// `Scalar step(Scalar) noexcept`, `void reset() noexcept` and `std::uint32_t fault_count()`.
// Each axis has its own model/state; the bank adds no heap and no virtual calls.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>

namespace gyrodrift {

template <class Filter, std::size_t N = 3>
class AxisBank {
 public:
  static constexpr std::size_t kAxes = N;

  // One filter per axis (e.g. AxisBank<Ar2Kalman<float>>({fx, fy, fz})).
  explicit AxisBank(const std::array<Filter, N>& filters) noexcept : f_(filters) {}
  // The same configuration on every axis.
  explicit AxisBank(const Filter& prototype) noexcept
      : f_(fill(prototype, std::make_index_sequence<N>{})) {}

  // in[0..N) -> out[0..N); in and out may alias.
  template <class Scalar>
  void step(const Scalar* in, Scalar* out) noexcept {
    for (std::size_t i = 0; i < N; ++i) out[i] = f_[i].step(in[i]);
  }

  void reset() noexcept {
    for (auto& f : f_) f.reset();
  }

  std::uint32_t fault_count() const noexcept {
    std::uint32_t total = 0;
    for (const auto& f : f_) total += f.fault_count();
    return total;
  }

  Filter& axis(std::size_t i) noexcept { return f_[i]; }
  const Filter& axis(std::size_t i) const noexcept { return f_[i]; }

 private:
  template <std::size_t... I>
  static std::array<Filter, N> fill(const Filter& p, std::index_sequence<I...>) noexcept {
    return {{(static_cast<void>(I), p)...}};
  }

  std::array<Filter, N> f_;
};

}  // namespace gyrodrift
