#include "bindings.hpp"

PYBIND11_MODULE(_core, m) {
  m.doc() = "gyrodrift C++ core (header-only library include/gyrodrift bound with pybind11)";
  m.attr("__version__") = GYRODRIFT_VERSION;
  namespace b = gyrodrift::py_bindings;
#if GYRODRIFT_BIND_AR2
  b::bind_ar2(m);
#endif
#if GYRODRIFT_BIND_WAVELET
  b::bind_wavelet(m);
#endif
#if GYRODRIFT_BIND_ALLAN
  b::bind_allan(m);
#endif
#if GYRODRIFT_BIND_IMU
  b::bind_imu(m);
#endif
#if GYRODRIFT_BIND_ALIGN
  b::bind_align(m);
#endif
#if GYRODRIFT_BIND_DRIFT
  b::bind_drift(m);
#endif
}
