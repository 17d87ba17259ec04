// Worker threads for the whole-array kernels of the bindings: run(n_threads, worker) starts
// n_threads - 1 threads running `worker` and runs it on the calling thread too, with the
// GIL released, then joins them. When no more threads can be started the ones running
// share the work (workers take items from a shared counter), so this never fails.
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
    for (std::size_t k = 1; k < n_threads; ++k) pool.emplace_back(worker);
  } catch (...) {
    // no more threads available: the workers already started and this one share the rest
  }
  worker();
  for (auto& th : pool) th.join();
}

}  // namespace gyrodrift::py_bindings
