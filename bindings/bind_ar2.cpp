#include "bindings.hpp"

namespace gyrodrift::py_bindings {
void bind_ar2(pybind11::module_& /*m*/) {}
}  // namespace gyrodrift::py_bindings
