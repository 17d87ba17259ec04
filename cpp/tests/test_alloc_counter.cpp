// Proves the allocation counter can fail: it must see std::vector, Eigen dynamic matrices,
// operator new (plain, array, aligned, nothrow) and the C malloc family. An allocation-free
// assertion built on a counter that saw nothing would pass vacuously.
#define DOCTEST_CONFIG_IMPLEMENT_WITH_MAIN
#include <doctest/doctest.h>

#include <Eigen/Dense>
#include <cstdlib>
#include <memory>
#include <vector>

#include "alloc_counter.hpp"

namespace {

// Makes the pointer observable so the optimiser cannot elide the allocation
// (GCC/Clang may remove matching new/delete and malloc/free pairs otherwise).
void escape(const void* p) { asm volatile("" : : "g"(p) : "memory"); }

struct alignas(64) OverAligned {
  double values[8];
};

}  // namespace

using gyrodrift::test::AllocationScope;

TEST_CASE("malloc is counted on glibc without sanitizers") {
#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__)
  CHECK(AllocationScope::counts_malloc());
#endif
  if (!AllocationScope::counts_malloc()) return;  // ASan build: only operator new is counted
  AllocationScope scope;
  void* p = std::malloc(48);
  escape(p);
  std::free(p);
  const long mallocs = scope.mallocs();
  const long frees = scope.frees();
  const long news = scope.news();
  CHECK(mallocs == 1);
  CHECK(frees == 1);
  CHECK(news == 0);
}

TEST_CASE("calloc, realloc, aligned_alloc and posix_memalign are counted") {
  if (!AllocationScope::counts_malloc()) return;
  AllocationScope scope;
  void* a = std::calloc(4, 16);
  escape(a);
  a = std::realloc(a, 4096);
  escape(a);
  void* b = std::aligned_alloc(64, 256);
  escape(b);
  void* c = nullptr;
  const int rc = posix_memalign(&c, 64, 128);
  escape(c);
  std::free(a);
  std::free(b);
  std::free(c);
  std::free(nullptr);  // a no-op: not a release
  const long mallocs = scope.mallocs();
  const long frees = scope.frees();
  CHECK(rc == 0);
  CHECK(mallocs == 4);
  CHECK(frees == 3);
}

TEST_CASE("a std::vector allocation is counted") {
  AllocationScope scope;
  {
    std::vector<int> v(100, 7);
    escape(v.data());
  }
  const long news = scope.news();
  const long deletes = scope.deletes();
  const long all = scope.allocations();
  CHECK(news == 1);
  CHECK(deletes == 1);
  CHECK(all == 1);  // operator new does not also count as a malloc
}

TEST_CASE("array, nothrow and over-aligned operator new are counted") {
  AllocationScope scope;
  int* arr = new int[10];
  escape(arr);
  delete[] arr;
  int* nt = new (std::nothrow) int(3);
  escape(nt);
  delete nt;
  auto aligned = std::make_unique<OverAligned>();
  escape(aligned.get());
  const bool is_aligned = reinterpret_cast<std::uintptr_t>(aligned.get()) % 64 == 0;
  aligned.reset();
  const long news = scope.news();
  const long deletes = scope.deletes();
  CHECK(news == 3);
  CHECK(deletes == 3);
  CHECK(is_aligned);
}

TEST_CASE("Eigen: dynamic matrices allocate, fixed-size ones do not") {
  long dynamic_allocs = 0;
  {
    AllocationScope scope;
    Eigen::VectorXd v = Eigen::VectorXd::Constant(100, 1.5);
    escape(v.data());
    dynamic_allocs = scope.allocations();
  }
  // Eigen's heap goes through std::malloc, which only the non-ASan build counts.
  if (AllocationScope::counts_malloc()) CHECK(dynamic_allocs >= 1);

  AllocationScope scope;
  Eigen::Matrix2d p = Eigen::Matrix2d::Identity();
  for (int i = 0; i < 1000; ++i) {
    p = (p * 0.5 + Eigen::Matrix2d::Identity()).eval();
    escape(p.data());
  }
  const long fixed_allocs = scope.allocations();
  CHECK(fixed_allocs == 0);
  CHECK(p(0, 0) == doctest::Approx(2.0));  // converges to 2 I
}

TEST_CASE("scopes measure deltas independently") {
  AllocationScope outer;
  {
    AllocationScope inner;
    std::vector<double> v(8);
    escape(v.data());
    const long inner_news = inner.news();
    CHECK(inner_news == 1);
  }
  AllocationScope fresh;
  const long fresh_news = fresh.news();
  const long outer_news = outer.news();
  CHECK(fresh_news == 0);
  CHECK(outer_news >= 1);
}
