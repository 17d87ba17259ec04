#include "bindings.hpp"

namespace gyrodrift::py_bindings {
void bind_align(pybind11::module_& /*m*/) {}
}  // namespace gyrodrift::py_bindings
