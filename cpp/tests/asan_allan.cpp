// The Allan kernel tests again under AddressSanitizer + UBSan (built when GYRODRIFT_SANITIZE
// is ON): the fused kernel's segment/window index arithmetic must never read outside y or
// the workspace.
#include "test_allan_kernel.cpp"
