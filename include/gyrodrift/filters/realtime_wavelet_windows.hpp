// RealtimeWavelet with the window chosen at run time, for host programs (the loop reading a
// configuration file, the Python binding).
//
// The filter itself stays templated on its window (RealtimeWavelet<Scalar, N>: memory sized
// at compile time; a firmware build instantiates only the windows it uses and never includes
// this header). RealtimeWaveletWindows<Scalar, N1, N2, ...> holds one of those instances, or
// none, in a std::variant: constructed in place for the window given, no heap, and step()
// dispatches on the held window with a fixed chain of index comparisons (no virtual call, no
// allocation, noexcept). Its size is that of the largest window's filter: over every format
// window (RealtimeWaveletAnyWindow, 16..4096) about 13 x 4096 scalars per channel (210 KiB
// float), of which only the chosen window's part is ever touched.
//
// A window not in the list, like a default-constructed stage, holds no filter: status()
// reports RealtimeWaveletStatus::window_unavailable (ImuProcessor then refuses a channel
// that uses it) and step() passes inputs through.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <utility>
#include <variant>

#include "realtime_wavelet.hpp"

namespace gyrodrift {

template <class Scalar, std::size_t... Windows>
class RealtimeWaveletWindows {
  static_assert(sizeof...(Windows) >= 1, "at least one window");

 public:
  // No filter (status() == window_unavailable).
  RealtimeWaveletWindows() noexcept = default;

  // The filter RealtimeWavelet<Scalar, window>(wavelet, level, mode), built in place; a
  // window not in the list leaves no filter.
  RealtimeWaveletWindows(std::size_t window, WaveletKind wavelet, int level, WaveletMode mode) noexcept {
    emplace(window, wavelet, level, mode, std::make_index_sequence<sizeof...(Windows)>{});
  }

  // Whether `window` is one of the instantiated windows.
  static constexpr bool supports(std::size_t window) noexcept { return ((window == Windows) || ...); }

  Scalar step(Scalar x) noexcept {
    Scalar y = x;
    visit([&y, x](auto& f) noexcept { y = f.step(x); });
    return y;
  }

  void reset() noexcept {
    visit([](auto& f) noexcept { f.reset(); });
  }

  RealtimeWaveletStatus status() const noexcept {
    RealtimeWaveletStatus s = RealtimeWaveletStatus::window_unavailable;
    visit([&s](const auto& f) noexcept { s = f.status(); });
    return s;
  }

  std::uint32_t fault_count() const noexcept {
    std::uint32_t n = 0;
    visit([&n](const auto& f) noexcept { n = f.fault_count(); });
    return n;
  }

  bool ready() const noexcept {
    bool r = false;
    visit([&r](const auto& f) noexcept { r = f.ready(); });
    return r;
  }

  // The held filter's window (0: none).
  std::size_t window() const noexcept {
    std::size_t n = 0;
    visit([&n](const auto& f) noexcept { n = std::decay_t<decltype(f)>::kWindow; });
    return n;
  }

 private:
  template <std::size_t... I>
  void emplace(std::size_t window, WaveletKind wavelet, int level, WaveletMode mode,
               std::index_sequence<I...>) noexcept {
    (void)((window == kList[I] ? (filter_.template emplace<I + 1>(wavelet, level, mode), true) : false) || ...);
  }

  // Calls f on the held filter (nothing if none): index tests, no std::visit (which may throw).
  template <class F>
  void visit(F&& f) noexcept {
    visit_impl(f, filter_, std::make_index_sequence<sizeof...(Windows)>{});
  }
  template <class F>
  void visit(F&& f) const noexcept {
    visit_impl(f, filter_, std::make_index_sequence<sizeof...(Windows)>{});
  }
  template <class F, class V, std::size_t... I>
  static void visit_impl(F& f, V& v, std::index_sequence<I...>) noexcept {
    const std::size_t k = v.index();
    (void)((k == I + 1 ? (f(*std::get_if<I + 1>(&v)), true) : false) || ...);
  }

  static constexpr std::size_t kList[sizeof...(Windows)] = {Windows...};
  std::variant<std::monostate, RealtimeWavelet<Scalar, Windows>...> filter_;
};

// Every window of the configuration format: a power of two in 16..4096.
template <class Scalar>
using RealtimeWaveletAnyWindow = RealtimeWaveletWindows<Scalar, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096>;

inline constexpr std::size_t kConfigMinWaveletWindow = 16;
inline constexpr std::size_t kConfigMaxWaveletWindow = 4096;

// Whether `window` is a window of the configuration format (a power of two in 16..4096).
constexpr bool config_wavelet_window_ok(long long window) noexcept {
  return window >= static_cast<long long>(kConfigMinWaveletWindow) &&
         window <= static_cast<long long>(kConfigMaxWaveletWindow) && (window & (window - 1)) == 0;
}

}  // namespace gyrodrift
