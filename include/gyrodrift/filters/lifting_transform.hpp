// Periodic lifting wavelet transform (db4, db8), one level and multi-level, in place.
//
// Reproduces pywt.wavedec / pywt.waverec with mode="periodization" coefficient for
// coefficient with NO index shift: the output rotation of each band is part of the
// factorization (lifting_coefficients_db*.hpp, derived by scripts/derive_lifting.py).
// Layout after forward(x, n, J): x = [cA_J | cD_J | cD_{J-1} | ... | cD_1], which is
// numpy.concatenate(pywt.wavedec(x, w, mode="periodization", level=J)).
//
// Storage is caller-owned: x (n values) and scratch (n values). No heap, no exceptions;
// functions return false on bad arguments (null pointers, n not divisible by 2^J, J out of
// 1..kMaxLevel) and then leave x untouched.
#pragma once

#include <cstddef>
#include <cstdint>

#include "lifting_coefficients_db4.hpp"
#include "lifting_coefficients_db8.hpp"

namespace gyrodrift {

enum class WaveletKind : std::uint8_t { db4 = 4, db8 = 8 };

inline constexpr int kMaxWaveletLevel = 8;

// Filter length of the equivalent FIR filter bank (2 x vanishing moments).
constexpr int wavelet_filter_length(WaveletKind w) noexcept { return 2 * static_cast<int>(w); }

namespace detail {

// (i mod h) for any int i and h >= 1.
// Lifting offsets are a few samples, so one conditional add/sub almost always suffices;
// the division is only for bands shorter than the offsets (deep levels of short signals).
inline std::ptrdiff_t wrap_index(std::ptrdiff_t i, std::ptrdiff_t h) noexcept {
  if (i >= 0) {
    if (i < h) return i;
    if (i < 2 * h) return i - h;
  } else if (i >= -h) {
    return i + h;
  }
  const std::ptrdiff_t r = i % h;
  return r < 0 ? r + h : r;
}

// target[k] += sign * sum_j c[j] * other[(k + first + j) mod h], k = 0..h-1.
template <class Scalar, std::size_t MaxTaps>
inline void lift(const LiftingStep<Scalar, MaxTaps>& st, Scalar* target, const Scalar* other,
                 std::ptrdiff_t h, bool undo) noexcept {
  const std::ptrdiff_t lo = st.first < 0 ? -st.first : 0;                       // first k without wrap
  const std::ptrdiff_t hi = h - (st.first + st.ntaps - 1 > 0 ? st.first + st.ntaps - 1 : 0);  // end
  auto term = [&](std::ptrdiff_t k, bool wrap) noexcept {
    Scalar acc = Scalar(0);
    for (int j = 0; j < st.ntaps; ++j) {
      const std::ptrdiff_t i = k + st.first + j;
      acc += st.c[static_cast<std::size_t>(j)] * other[wrap ? wrap_index(i, h) : i];
    }
    return acc;
  };
  if (lo >= hi) {  // short band: every index may wrap (possibly several times)
    for (std::ptrdiff_t k = 0; k < h; ++k) target[k] = undo ? target[k] - term(k, true) : target[k] + term(k, true);
    return;
  }
  for (std::ptrdiff_t k = 0; k < lo; ++k) target[k] = undo ? target[k] - term(k, true) : target[k] + term(k, true);
  // Interior: no wrap; the 1- and 2-tap steps (all of db4/db8) get straight-line loops the
  // compiler vectorises. The sign is folded into the coefficients (exact: negation).
  const Scalar sign = undo ? Scalar(-1) : Scalar(1);
  const std::ptrdiff_t f = st.first;
  if (st.ntaps == 2) {
    const Scalar c0 = sign * st.c[0], c1 = sign * st.c[1];
    for (std::ptrdiff_t k = lo; k < hi; ++k) target[k] += c0 * other[k + f] + c1 * other[k + f + 1];
  } else if (st.ntaps == 1) {
    const Scalar c0 = sign * st.c[0];
    for (std::ptrdiff_t k = lo; k < hi; ++k) target[k] += c0 * other[k + f];
  } else if (undo) {
    for (std::ptrdiff_t k = lo; k < hi; ++k) target[k] -= term(k, false);
  } else {
    for (std::ptrdiff_t k = lo; k < hi; ++k) target[k] += term(k, false);
  }
  for (std::ptrdiff_t k = hi; k < h; ++k) target[k] = undo ? target[k] - term(k, true) : target[k] + term(k, true);
}

}  // namespace detail

// Lifting kernels of one wavelet (Coefs = LiftingCoefficientsDb4/Db8<Scalar>).
template <class Scalar, class Coefs>
struct LiftingKernel {
  // One analysis level on x[0..n) (n even): x = [cA | cD]. scratch: n values.
  static void forward_level(Scalar* x, std::size_t n, Scalar* scratch) noexcept {
    const auto h = static_cast<std::ptrdiff_t>(n / 2);
    Scalar* band[2] = {scratch, scratch + h};
    for (std::ptrdiff_t k = 0; k < h; ++k) {  // polyphase split e[k] = x[2k], o[k] = x[2k+1]
      band[0][k] = x[2 * k];
      band[1][k] = x[2 * k + 1];
    }
    for (int s = 0; s < Coefs::kSteps; ++s) {
      const auto& st = Coefs::kStep[s];
      detail::lift(st, band[st.target], band[1 - st.target], h, false);
    }
    const Scalar* a = band[Coefs::kBandA];
    const Scalar* d = band[1 - Coefs::kBandA];
    for (std::ptrdiff_t k = 0; k < h; ++k) {  // scaling and the band rotation z^shift
      x[k] = Coefs::kA * a[detail::wrap_index(k + Coefs::kShiftA, h)];
      x[h + k] = Coefs::kD * d[detail::wrap_index(k + Coefs::kShiftD, h)];
    }
  }

  // Exact inverse of forward_level: x = [cA | cD] -> signal.
  static void inverse_level(Scalar* x, std::size_t n, Scalar* scratch) noexcept {
    const auto h = static_cast<std::ptrdiff_t>(n / 2);
    Scalar* band[2] = {scratch, scratch + h};
    Scalar* a = band[Coefs::kBandA];
    Scalar* d = band[1 - Coefs::kBandA];
    for (std::ptrdiff_t k = 0; k < h; ++k) {
      a[detail::wrap_index(k + Coefs::kShiftA, h)] = Coefs::kInvA * x[k];
      d[detail::wrap_index(k + Coefs::kShiftD, h)] = Coefs::kInvD * x[h + k];
    }
    for (int s = Coefs::kSteps - 1; s >= 0; --s) {
      const auto& st = Coefs::kStep[s];
      detail::lift(st, band[st.target], band[1 - st.target], h, true);
    }
    for (std::ptrdiff_t k = 0; k < h; ++k) {
      x[2 * k] = band[0][k];
      x[2 * k + 1] = band[1][k];
    }
  }
};

// Runtime-selected wavelet; all functions are noexcept and status-returning.
template <class Scalar>
struct LiftingTransform {
  static bool valid(std::size_t n, int levels) noexcept {
    if (levels < 1 || levels > kMaxWaveletLevel || n == 0) return false;
    return (n % (std::size_t{1} << static_cast<unsigned>(levels))) == 0;
  }

  static bool forward_level(WaveletKind w, Scalar* x, std::size_t n, Scalar* scratch) noexcept {
    if (x == nullptr || scratch == nullptr || n < 2 || n % 2 != 0) return false;
    if (w == WaveletKind::db8) {
      LiftingKernel<Scalar, LiftingCoefficientsDb8<Scalar>>::forward_level(x, n, scratch);
    } else {
      LiftingKernel<Scalar, LiftingCoefficientsDb4<Scalar>>::forward_level(x, n, scratch);
    }
    return true;
  }

  static bool inverse_level(WaveletKind w, Scalar* x, std::size_t n, Scalar* scratch) noexcept {
    if (x == nullptr || scratch == nullptr || n < 2 || n % 2 != 0) return false;
    if (w == WaveletKind::db8) {
      LiftingKernel<Scalar, LiftingCoefficientsDb8<Scalar>>::inverse_level(x, n, scratch);
    } else {
      LiftingKernel<Scalar, LiftingCoefficientsDb4<Scalar>>::inverse_level(x, n, scratch);
    }
    return true;
  }

  // J-level decomposition in place (Mallat layout, see top of file).
  static bool forward(WaveletKind w, Scalar* x, std::size_t n, int levels, Scalar* scratch) noexcept {
    if (x == nullptr || scratch == nullptr || !valid(n, levels)) return false;
    for (int j = 0; j < levels; ++j) forward_level(w, x, n >> static_cast<unsigned>(j), scratch);
    return true;
  }

  // J-level reconstruction in place.
  static bool inverse(WaveletKind w, Scalar* x, std::size_t n, int levels, Scalar* scratch) noexcept {
    if (x == nullptr || scratch == nullptr || !valid(n, levels)) return false;
    for (int j = levels - 1; j >= 0; --j) inverse_level(w, x, n >> static_cast<unsigned>(j), scratch);
    return true;
  }
};

}  // namespace gyrodrift
