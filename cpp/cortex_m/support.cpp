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

// Host file access through ARM semihosting (SYS_OPEN 0x01, SYS_CLOSE 0x02, SYS_WRITE 0x05,
// SYS_READ 0x06): the golden-I/O unit reads its input and writes its outputs on the host
// (paths relative to the emulator's working directory). Without GYRODRIFT_CM_SEMIHOSTING
// every call fails.
namespace gyrodrift::cortex_m {
#if defined(GYRODRIFT_CM_SEMIHOSTING)
namespace {
int semihost_call(int op, const void* arg) {
  register int r0 __asm("r0") = op;
  register const void* r1 __asm("r1") = arg;
  __asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
  return r0;
}
}  // namespace

int host_open(const char* path, bool write) {
  std::size_t len = 0;
  while (path[len] != '\0') ++len;
  const std::uintptr_t block[3] = {reinterpret_cast<std::uintptr_t>(path),
                                   write ? 5u : 1u,  // "wb" / "rb"
                                   static_cast<std::uintptr_t>(len)};
  return semihost_call(0x01, block);
}

bool host_read(int fd, void* buf, std::size_t n) {
  const std::uintptr_t block[3] = {static_cast<std::uintptr_t>(fd), reinterpret_cast<std::uintptr_t>(buf),
                                   static_cast<std::uintptr_t>(n)};
  return semihost_call(0x06, block) == 0;  // returns the count NOT read
}

bool host_write(int fd, const void* buf, std::size_t n) {
  const std::uintptr_t block[3] = {static_cast<std::uintptr_t>(fd), reinterpret_cast<std::uintptr_t>(buf),
                                   static_cast<std::uintptr_t>(n)};
  return semihost_call(0x05, block) == 0;
}

void host_close(int fd) {
  const std::uintptr_t block[1] = {static_cast<std::uintptr_t>(fd)};
  semihost_call(0x02, block);
}
#else
int host_open(const char*, bool) { return -1; }
bool host_read(int, void*, std::size_t) { return false; }
bool host_write(int, const void*, std::size_t) { return false; }
void host_close(int) {}
#endif
}  // namespace gyrodrift::cortex_m
