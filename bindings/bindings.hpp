// Registration functions of the gyrodrift._core module, one per feature area, each
// defined in its own bindings/bind_*.cpp so the areas build and change independently.
#pragma once
#include <pybind11/pybind11.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <mutex>

namespace gyrodrift::py_bindings {
void bind_ar2(pybind11::module_& m);      // AR(2) identification and AR(2)-Kalman filters
void bind_wavelet(pybind11::module_& m);  // lifting wavelets and denoisers
void bind_allan(pybind11::module_& m);    // Allan variance kernels
void bind_deviation(pybind11::module_& m);  // deviation family (part of the allan area)
void bind_streaming_allan(pybind11::module_& m);  // streaming octave Allan (allan area)
void bind_health(pybind11::module_& m);  // online noise estimates, health alarms (allan area)
void bind_imu(pybind11::module_& m);      // IMU processor and frame codecs
void bind_monitor(pybind11::module_& m);  // gyro monitor over records (imu area)
void bind_align(pybind11::module_& m);    // strapdown navigation and alignment
void bind_drift(pybind11::module_& m);    // drift-model likelihood (ML identification)
void bind_online_drift(pybind11::module_& m);  // online drift-model identifier (drift area)
void bind_lag_statistics(pybind11::module_& m);  // whole-record lag statistics (drift area)

// Per-object serialisation for bound objects whose methods release the GIL while they step
// their own state (ImuProcessor, RealtimeWaveletBank, OadevStream): without it, one object
// shared by several Python threads loses updates. Every method touching such
// state runs under the object's lock: `ReleasedAndLocked guard(&obj);` in place of
// `py::gil_scoped_release release;` (methods that need the GIL afterwards, e.g. to build a
// dict, copy what they need inside a scope holding the guard).
//
// Order matters: the GIL is released first, then the lock taken (and on exit the lock is
// released before the GIL is taken back). Taking the lock while holding the GIL would
// deadlock against a thread that holds the lock and waits for the GIL.
//
// The locks are a fixed table striped by object address (no per-object storage, so the
// core classes stay as they are): two objects may share a stripe, which only serialises
// them; each call takes exactly one lock, so no lock-order deadlock is possible.
inline std::mutex& object_mutex(const void* obj) noexcept {
  static std::array<std::mutex, 64> stripes;
  auto h = static_cast<std::uint64_t>(reinterpret_cast<std::uintptr_t>(obj));
  h = (h >> 4) * 0x9E3779B97F4A7C15ULL;  // Fibonacci hashing: spread nearby addresses
  return stripes[static_cast<std::size_t>(h >> 58)];
}

class ReleasedAndLocked {
 public:
  explicit ReleasedAndLocked(const void* obj) : lock_(object_mutex(obj)) {}
  ReleasedAndLocked(const ReleasedAndLocked&) = delete;
  ReleasedAndLocked& operator=(const ReleasedAndLocked&) = delete;

 private:
  pybind11::gil_scoped_release release_;  // constructed first, destroyed last
  std::unique_lock<std::mutex> lock_;
};

}  // namespace gyrodrift::py_bindings
