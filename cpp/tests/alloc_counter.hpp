// Heap-allocation counter for allocation-free tests.
//
// Include this header in exactly ONE translation unit of a test executable (each
// cpp/tests/test_*.cpp is its own executable, so: include it from the test file). It defines
//   * every replaceable global operator new / delete (plain, array, nothrow, sized,
//     std::align_val_t forms; [new.delete] in C++17), and
//   * on glibc without AddressSanitizer: the C allocation functions malloc, calloc, realloc,
//     free, aligned_alloc, posix_memalign, memalign, valloc, pvalloc.
//
// Mechanism for the C functions: glibc supports replacing malloc by defining these symbols in
// the executable (glibc manual, "Replacing malloc"); the executable's definitions are exported
// and every shared library (libstdc++, libc itself, Eigen code inlined anywhere) resolves to
// them through the dynamic linker. Our replacements count the call and forward to glibc's own
// allocator entry points __libc_malloc, __libc_calloc, __libc_realloc, __libc_memalign,
// __libc_valloc, __libc_pvalloc, __libc_free (exported by glibc since 2.0 for exactly this),
// so there is one heap and no dlsym recursion. Under ASan (which owns malloc) only the C++
// operators are replaced; GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC tells which case applies.
//
// Every underlying allocation is counted once: operator new counts as a "new" and calls the
// glibc entry point directly (not the counted malloc). Counters are lock-free atomics, so the
// counter itself never allocates and is safe before static initialisation (constant-initialised).
//
// Use:
//   gyrodrift::test::AllocationScope scope;
//   ... code that must not allocate ...
//   const auto n = scope.allocations();   // read BEFORE any CHECK (doctest may allocate)
//   CHECK(n == 0);
#pragma once

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

#if defined(__SANITIZE_ADDRESS__)
#define GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC 0
#endif
#endif
#if !defined(GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC)
#if defined(__GLIBC__)
#define GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC 1
#else
#define GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC 0
#endif
#endif

namespace gyrodrift::test {

struct AllocationCounters {
  std::atomic<long> news{0};      // operator new / new[] (all forms)
  std::atomic<long> deletes{0};   // operator delete / delete[] of a non-null pointer
  std::atomic<long> mallocs{0};   // malloc, calloc, realloc, aligned_alloc, posix_memalign, ...
  std::atomic<long> frees{0};     // free of a non-null pointer (realloc counts as a malloc)
};

// Constant-initialised (std::atomic has a constexpr constructor): valid before any dynamic
// initialisation, so allocations made by the C runtime at start-up are counted safely.
inline AllocationCounters g_allocation_counters;

// Counts the heap activity between its construction and the query.
class AllocationScope {
 public:
  AllocationScope() noexcept
      : news0_(load(g_allocation_counters.news)),
        deletes0_(load(g_allocation_counters.deletes)),
        mallocs0_(load(g_allocation_counters.mallocs)),
        frees0_(load(g_allocation_counters.frees)) {}

  long news() const noexcept { return load(g_allocation_counters.news) - news0_; }
  long deletes() const noexcept { return load(g_allocation_counters.deletes) - deletes0_; }
  long mallocs() const noexcept { return load(g_allocation_counters.mallocs) - mallocs0_; }
  long frees() const noexcept { return load(g_allocation_counters.frees) - frees0_; }
  // Every allocation of any kind (operator new + the malloc family).
  long allocations() const noexcept { return news() + mallocs(); }
  // Every release of any kind.
  long releases() const noexcept { return deletes() + frees(); }

  // True when C malloc/free are counted too (glibc, no ASan); otherwise only operator new/delete.
  static constexpr bool counts_malloc() noexcept { return GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC != 0; }

 private:
  static long load(const std::atomic<long>& a) noexcept { return a.load(std::memory_order_relaxed); }
  long news0_, deletes0_, mallocs0_, frees0_;
};

namespace detail {
inline void count(std::atomic<long>& counter) noexcept { counter.fetch_add(1, std::memory_order_relaxed); }
}  // namespace detail

}  // namespace gyrodrift::test

// ---------------------------------------------------------------------------------------------
// C allocation functions (glibc, no ASan).
#if GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* ptr, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void* __libc_valloc(std::size_t size);
void* __libc_pvalloc(std::size_t size);
void __libc_free(void* ptr);

void* malloc(std::size_t size) noexcept {
  gyrodrift::test::detail::count(gyrodrift::test::g_allocation_counters.mallocs);
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) noexcept {
  gyrodrift::test::detail::count(gyrodrift::test::g_allocation_counters.mallocs);
  return __libc_calloc(count, size);
}
void* realloc(void* ptr, std::size_t size) noexcept {
  gyrodrift::test::detail::count(gyrodrift::test::g_allocation_counters.mallocs);
  return __libc_realloc(ptr, size);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  gyrodrift::test::detail::count(gyrodrift::test::g_allocation_counters.mallocs);
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  gyrodrift::test::detail::count(gyrodrift::test::g_allocation_counters.mallocs);
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  // POSIX: alignment must be a power of two multiple of sizeof(void*).
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  gyrodrift::test::detail::count(gyrodrift::test::g_allocation_counters.mallocs);
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t size) noexcept {
  gyrodrift::test::detail::count(gyrodrift::test::g_allocation_counters.mallocs);
  return __libc_valloc(size);
}
void* pvalloc(std::size_t size) noexcept {
  gyrodrift::test::detail::count(gyrodrift::test::g_allocation_counters.mallocs);
  return __libc_pvalloc(size);
}
void free(void* ptr) noexcept {
  if (ptr != nullptr) gyrodrift::test::detail::count(gyrodrift::test::g_allocation_counters.frees);
  __libc_free(ptr);
}
}  // extern "C"
#endif

// ---------------------------------------------------------------------------------------------
// Replaceable global operator new / delete ([new.delete.single], [new.delete.array]).
namespace gyrodrift::test::detail {

inline void* raw_alloc(std::size_t size) noexcept {
  count(g_allocation_counters.news);
  if (size == 0) size = 1;  // new(0) must return a unique non-null pointer
#if GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC
  return __libc_malloc(size);
#else
  return std::malloc(size);
#endif
}

inline void* raw_alloc_aligned(std::size_t size, std::size_t alignment) noexcept {
  count(g_allocation_counters.news);
  if (size == 0) size = 1;
#if GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC
  return __libc_memalign(alignment, size);
#else
  // aligned_alloc needs size to be a multiple of the alignment.
  return std::aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
#endif
}

inline void raw_free(void* ptr) noexcept {
  if (ptr == nullptr) return;
  count(g_allocation_counters.deletes);
#if GYRODRIFT_ALLOC_COUNTER_COUNTS_MALLOC
  __libc_free(ptr);
#else
  std::free(ptr);
#endif
}

[[noreturn]] inline void out_of_memory() {
#if defined(__cpp_exceptions)
  throw std::bad_alloc();
#else
  std::abort();
#endif
}

}  // namespace gyrodrift::test::detail

void* operator new(std::size_t size) {
  void* p = gyrodrift::test::detail::raw_alloc(size);
  if (p == nullptr) gyrodrift::test::detail::out_of_memory();
  return p;
}
void* operator new[](std::size_t size) {
  void* p = gyrodrift::test::detail::raw_alloc(size);
  if (p == nullptr) gyrodrift::test::detail::out_of_memory();
  return p;
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  return gyrodrift::test::detail::raw_alloc(size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  return gyrodrift::test::detail::raw_alloc(size);
}
void* operator new(std::size_t size, std::align_val_t al) {
  void* p = gyrodrift::test::detail::raw_alloc_aligned(size, static_cast<std::size_t>(al));
  if (p == nullptr) gyrodrift::test::detail::out_of_memory();
  return p;
}
void* operator new[](std::size_t size, std::align_val_t al) {
  void* p = gyrodrift::test::detail::raw_alloc_aligned(size, static_cast<std::size_t>(al));
  if (p == nullptr) gyrodrift::test::detail::out_of_memory();
  return p;
}
void* operator new(std::size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  return gyrodrift::test::detail::raw_alloc_aligned(size, static_cast<std::size_t>(al));
}
void* operator new[](std::size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  return gyrodrift::test::detail::raw_alloc_aligned(size, static_cast<std::size_t>(al));
}

void operator delete(void* p) noexcept { gyrodrift::test::detail::raw_free(p); }
void operator delete[](void* p) noexcept { gyrodrift::test::detail::raw_free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { gyrodrift::test::detail::raw_free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { gyrodrift::test::detail::raw_free(p); }
void operator delete(void* p, std::size_t) noexcept { gyrodrift::test::detail::raw_free(p); }
void operator delete[](void* p, std::size_t) noexcept { gyrodrift::test::detail::raw_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { gyrodrift::test::detail::raw_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { gyrodrift::test::detail::raw_free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  gyrodrift::test::detail::raw_free(p);
}
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  gyrodrift::test::detail::raw_free(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  gyrodrift::test::detail::raw_free(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  gyrodrift::test::detail::raw_free(p);
}
