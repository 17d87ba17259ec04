#include "bindings.hpp"

PYBIND11_MODULE(_core, m) {
  m.doc() = "gyrodrift C++ core (header-only library include/gyrodrift bound with pybind11)";
  m.attr("__version__") = GYRODRIFT_VERSION;
  namespace b = gyrodrift::py_bindings;
  b::bind_ar2(m);
  b::bind_wavelet(m);
  b::bind_allan(m);
  b::bind_imu(m);
  b::bind_align(m);
}
