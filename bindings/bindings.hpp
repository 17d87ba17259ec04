// Registration functions of the gyrodrift._core module, one per feature area, each
// defined in its own bindings/bind_*.cpp so the areas build and change independently.
#pragma once
#include <pybind11/pybind11.h>

namespace gyrodrift::py_bindings {
void bind_ar2(pybind11::module_& m);      // AR(2) identification and AR(2)-Kalman filters
void bind_wavelet(pybind11::module_& m);  // lifting wavelets and denoisers
void bind_allan(pybind11::module_& m);    // Allan variance kernels
void bind_deviation(pybind11::module_& m);  // deviation family (part of the allan area)
void bind_imu(pybind11::module_& m);      // IMU processor and frame codecs
void bind_align(pybind11::module_& m);    // strapdown navigation and alignment
void bind_drift(pybind11::module_& m);    // drift-model likelihood (ML identification)
}  // namespace gyrodrift::py_bindings
