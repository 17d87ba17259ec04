// Worker threads for the whole-array kernels of the bindings: run_workers(n_threads, worker)
// starts n_threads - 1 threads running worker(1), worker(2), ... and runs worker(0) on the
// calling thread, with the GIL released, then joins them. When no more threads can be
// started the ones running share the work (workers take items from a shared counter), so
// this never fails. The id lets a worker use storage the caller prepared (one allocation on
// the calling thread, whose heap reuses the pages from call to call: a worker thread's own
// multi-MB allocation is fresh memory each time, ~1 ms of page faults per 4 MB).
#pragma once
#include <cstddef>
#include <thread>
#include <vector>

#include "bindings.hpp"

namespace gyrodrift::py_bindings {

template <class Worker>
void run_workers(std::size_t n_threads, Worker& worker) {
  py::gil_scoped_release release;
  std::vector<std::thread> pool;
  try {
    for (std::size_t k = 1; k < n_threads; ++k) pool.emplace_back(worker, k);
  } catch (...) {
    // no more threads available: the workers already started and this one share the rest
  }
  worker(std::size_t{0});
  for (auto& th : pool) th.join();
}

}  // namespace gyrodrift::py_bindings
