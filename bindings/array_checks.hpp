// Shared argument checks for the bindings: numpy arrays in, clear ValueError/TypeError out.
#pragma once
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace gyrodrift::py_bindings {

namespace py = pybind11;

// C-contiguous array of exactly this dtype; with .noconvert() in the signature a dtype or
// layout mismatch is a TypeError instead of a silent copy (zero-copy input).
template <class T>
using CArray = py::array_t<T, py::array::c_style>;

// 1-D samples, or (n, 3) per-axis samples. Returns the number of rows.
template <class T>
inline std::size_t require_1d_or_n3(const CArray<T>& a, const char* what) {
  if (a.ndim() == 1) return static_cast<std::size_t>(a.shape(0));
  if (a.ndim() == 2 && a.shape(1) == 3) return static_cast<std::size_t>(a.shape(0));
  throw py::value_error(std::string(what) + ": expected a 1-D array or an (n, 3) array, got ndim=" +
                        std::to_string(a.ndim()));
}

template <class T>
inline void require_finite(const T* data, std::size_t n, const char* what) {
  // Fast pass without an early exit (it vectorizes): x - x is 0 for every finite x and NaN
  // for NaN or Inf, so the lane sums stay 0 exactly when all samples are finite.
  constexpr std::size_t kLanes = 8;
  T acc[kLanes] = {};
  std::size_t j = 0;
  for (; j + kLanes <= n; j += kLanes) {
    for (std::size_t k = 0; k < kLanes; ++k) acc[k] += data[j + k] - data[j + k];
  }
  for (; j < n; ++j) acc[0] += data[j] - data[j];
  bool all_zero = true;
  for (std::size_t k = 0; k < kLanes; ++k) all_zero = all_zero && acc[k] == T(0);
  if (all_zero) return;
  for (std::size_t i = 0; i < n; ++i) {  // find the first one for the message
    if (!std::isfinite(data[i])) {
      throw py::value_error(std::string(what) + ": non-finite value (NaN or Inf) at flat index " +
                            std::to_string(i));
    }
  }
}

}  // namespace gyrodrift::py_bindings
