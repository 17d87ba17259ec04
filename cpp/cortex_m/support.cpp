// Shared definitions for the Cortex-M4F gate programs: the volatile input/output buffers and
// the few C++ runtime hooks a freestanding, exception-free program needs.
#include "support.hpp"

extern "C" {
// A deterministic gyro-like pattern (deg/h): bias plus a small alternating component.
volatile float gyrodrift_cm_input[64] = {
    0.51f, 0.47f, 0.55f, 0.43f, 0.52f, 0.49f, 0.58f, 0.41f, 0.50f, 0.53f, 0.46f, 0.57f, 0.44f,
    0.50f, 0.48f, 0.56f, 0.42f, 0.54f, 0.51f, 0.45f, 0.59f, 0.40f, 0.52f, 0.47f, 0.55f, 0.44f,
    0.53f, 0.49f, 0.57f, 0.43f, 0.50f, 0.48f, 0.51f, 0.47f, 0.55f, 0.43f, 0.52f, 0.49f, 0.58f,
    0.41f, 0.50f, 0.53f, 0.46f, 0.57f, 0.44f, 0.50f, 0.48f, 0.56f, 0.42f, 0.54f, 0.51f, 0.45f,
    0.59f, 0.40f, 0.52f, 0.47f, 0.55f, 0.44f, 0.53f, 0.49f, 0.57f, 0.43f, 0.50f, 0.48f};
const std::size_t gyrodrift_cm_input_len = 64;
volatile float gyrodrift_cm_sink = 0.0f;
volatile std::int32_t gyrodrift_cm_sink_i32 = 0;

// Pure virtual call: trap instead of pulling in libsupc++'s handler (which prints/aborts).
void __cxa_pure_virtual() { __builtin_trap(); }

// Bare metal has no process exit: static destructors are never registered or run.
void* __dso_handle = nullptr;
int __cxa_atexit(void (*)(void*), void*, void*) { return 0; }
}
