// Deviation-family kernels (include/gyrodrift/stability/deviation_*.hpp) for gyrodrift.deviation.
// Part of the "allan" binding area (registered from bind_allan).
//   deviation_sigma2(data, m, name, threads)   whole array, all factors in fused passes
//                                              (DeviationFused, HdevCascade), GIL released
//   ModAllanStream / OhdevStream / HdevStream   streaming state for chunked records
//   (the total variance streams through OadevStream on the reflected record)
#include <gyrodrift/stability/deviation_blocked.hpp>
#include <gyrodrift/stability/deviation_fused.hpp>
#include <gyrodrift/stability/deviation_hadamard.hpp>
#include <gyrodrift/stability/deviation_modified.hpp>
#include <gyrodrift/stability/deviation_total.hpp>

#include <algorithm>
#include <atomic>
#include <memory>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "array_checks.hpp"
#include "bindings.hpp"
#include "workers.hpp"

namespace gyrodrift::py_bindings {

namespace {

enum class Dev { mdev, ohdev, hdev, totdev };

Dev parse_dev(const std::string& name) {
  if (name == "mdev") return Dev::mdev;
  if (name == "ohdev") return Dev::ohdev;
  if (name == "hdev") return Dev::hdev;
  if (name == "totdev") return Dev::totdev;
  throw py::value_error("name must be 'mdev', 'ohdev', 'hdev' or 'totdev', got '" + name + "'");
}

std::size_t dev_max_m(Dev d, std::size_t n) {
  switch (d) {
    case Dev::mdev: return mdev_max_m(n);
    case Dev::ohdev: return ohdev_max_m(n);
    case Dev::hdev: return hdev_max_m(n);
    case Dev::totdev: return totdev_max_m(n);
  }
  return 0;
}

template <class T>
const T* require_vec(const CArray<T>& a, const char* what) {
  if (a.ndim() != 1) {
    throw py::value_error(std::string(what) + ": expected a 1-D array, got ndim=" +
                          std::to_string(a.ndim()));
  }
  return a.data();
}

constexpr std::size_t kGroup = 64;
// Term indices per block of the fused kernels: the largest multiple of kMinBlock up to
// kMaxBlock whose workspace stays within kMaxWorkspace doubles (8 MiB: one workspace per
// thread, whatever the record length or grid), and no more than half the terms (so the
// two parts of a group can run on two threads). Larger blocks need fewer prefix sums per
// term (the union of the stretches [offset, offset + block] over the factors' offsets,
// per block): ohdev at 1e6 samples, octave taus, 4 per term at block 258048 instead of 6
// at 131072 (the previous fixed block), ~8 % less CPU (mdev, totdev: see plan_block). The
// block depends only on (n_data, m): same result for any thread count.
constexpr std::size_t kMaxBlock = 1 << 19;
constexpr std::size_t kMaxBlockOther = 1 << 17;
constexpr std::size_t kMinBlock = 1 << 12;
constexpr std::size_t kMaxWorkspace = 1 << 20;

FusedDeviation fused_kind(Dev d) {
  return d == Dev::mdev ? FusedDeviation::mdev
                        : d == Dev::ohdev ? FusedDeviation::ohdev : FusedDeviation::totdev;
}

// Plans `fused` with the block chosen as above (binary search: the workspace grows with
// the block); returns it, or 0 if the plan fails.
std::size_t plan_block(DeviationFused<kGroup>& fused, FusedDeviation kind, std::size_t n_data,
                       const std::size_t* m, std::size_t n_m) {
  if (!fused.plan(n_data, kind, m, n_m, kMinBlock)) return 0;
  std::size_t terms = 0;  // the group's largest term count (its first factor's, or N - 1)
  for (std::size_t j = 0; j < n_m; ++j) {
    const std::size_t t = kind == FusedDeviation::ohdev  ? ohdev_terms(n_data, m[j])
                          : kind == FusedDeviation::mdev ? mdev_terms(n_data, m[j])
                                                         : totdev_terms(n_data);
    terms = std::max(terms, t);
  }
  // ohdev and mdev: the largest block whose workspace fits (mdev: V integrates H in double
  // inside a block only within pieces of 1024 terms and is anchored every max(B, 16 m)
  // terms; 3.1e-13 from the long double kernels at 258048 against 2.4e-13 at 131072 on the
  // drifting bench record, well inside 1e-12). totdev: no faster at the blocks that fit,
  // keeps 131072.
  const std::size_t top = kind == FusedDeviation::totdev ? kMaxBlockOther : kMaxBlock;
  std::size_t hi = std::min(top, (terms / 2 + kMinBlock - 1) / kMinBlock * kMinBlock);
  hi = std::max(hi, kMinBlock) / kMinBlock;  // in units of kMinBlock
  std::size_t lo = 1;  // kMinBlock always (even when over the cap: the smallest there is)
  while (lo < hi) {
    const std::size_t mid = (lo + hi + 1) / 2;
    if (!fused.plan(n_data, kind, m, n_m, mid * kMinBlock)) return 0;
    if (fused.workspace_doubles() <= kMaxWorkspace) {
      lo = mid;
    } else {
      hi = mid - 1;
    }
  }
  if (!fused.plan(n_data, kind, m, n_m, lo * kMinBlock)) return 0;
  return lo * kMinBlock;
}

template <class T>
py::tuple deviation_sigma2(const CArray<T>& data, const CArray<std::int64_t>& m_in,
                           const std::string& name, std::int64_t threads) {
  const Dev d = parse_dev(name);
  const T* x = require_vec(data, "data");
  const auto n_data = static_cast<std::size_t>(data.shape(0));
  const std::int64_t* m_raw = require_vec(m_in, "m");
  const auto n_m = static_cast<std::size_t>(m_in.shape(0));
  if (threads < 1) throw py::value_error("threads must be >= 1");
  const std::size_t max_m = dev_max_m(d, n_data);
  std::vector<std::size_t> m(n_m);
  for (std::size_t j = 0; j < n_m; ++j) {
    if (m_raw[j] < 1 || static_cast<std::size_t>(m_raw[j]) > max_m) {
      throw py::value_error("averaging factor m=" + std::to_string(m_raw[j]) +
                            " does not fit a record of " + std::to_string(n_data) +
                            " rate samples for " + name + " (1 <= m <= " +
                            std::to_string(max_m) + " leaves at least 2 terms)");
    }
    m[j] = static_cast<std::size_t>(m_raw[j]);
    if (j > 0 && m[j] <= m[j - 1]) throw py::value_error("m must be strictly increasing");
  }
  // NaN/Inf: every sample enters the fused kernels' running sums (ohdev, mdev, totdev: the
  // terms' windows cover the record) and the hdev cascade's m = 1 pass, so a non-finite
  // sample makes the sums non-finite and the kernel fail; the 8-byte-per-sample scan that
  // names the culprit then runs only on failure (it cost ~0.2 ms at 1e6 samples, a tenth
  // of an hdev call). hdev without m = 1 leaves a tail unread: checked first.
  const bool covered = d != Dev::hdev || m.empty() || m[0] == 1;
  if (!covered) require_finite(x, n_data, "data");
  py::array_t<double> sigma2(static_cast<py::ssize_t>(n_m));
  py::array_t<std::int64_t> terms_out(static_cast<py::ssize_t>(n_m));
  std::vector<std::size_t> terms(n_m, 0);
  double* s2 = sigma2.mutable_data();
  bool all_ok = true;
  if (d == Dev::hdev) {  // one cascaded pass for all factors (groups of <= kGroup)
    py::gil_scoped_release release;
    auto cascade = std::make_unique<HdevCascade<kGroup>>();
    std::vector<double> work;
    for (std::size_t lo = 0; lo < n_m && all_ok; lo += kGroup) {
      const std::size_t cnt = std::min<std::size_t>(kGroup, n_m - lo);
      all_ok = cascade->plan(n_data, m.data() + lo, cnt);
      if (!all_ok) break;
      work.resize(cascade->workspace_len());
      all_ok = cascade->run(x, work.data(), work.size(), s2 + lo, terms.data() + lo);
    }
  } else {
    // Groups of at most kGroup factors, each run as kParts stretches of its term range
    // (the same split for any thread count, so the same result); workers take whole parts,
    // each with its own plan and workspace.
    constexpr std::size_t kParts = 2;
    const FusedDeviation kind = fused_kind(d);
    const std::size_t n_groups = (n_m + kGroup - 1) / kGroup;
    std::vector<std::unique_ptr<DeviationFused<kGroup>>> parts(n_groups * kParts);
    std::vector<char> part_ok(parts.size(), 0);
    for (std::size_t t = 0; t < parts.size(); ++t) {
      const std::size_t lo = (t / kParts) * kGroup;
      parts[t] = std::make_unique<DeviationFused<kGroup>>();
      if (plan_block(*parts[t], kind, n_data, m.data() + lo, std::min(kGroup, n_m - lo)) == 0) {
        throw py::value_error("deviation_sigma2: could not plan the factors");
      }
    }
    const std::size_t n_threads = std::min(parts.size(), static_cast<std::size_t>(threads));
    std::size_t largest = 0;
    for (const auto& f : parts) largest = std::max(largest, f->workspace_doubles());
    // One allocation for all workers' workspaces, on this thread and left uninitialized:
    // the heap then reuses the same pages from call to call (per-thread or repeated
    // multi-MB allocations are returned to the system and fault in again, ~1 ms per 4 MB).
    // Each worker's workspace starts on a 64-byte boundary (the kernels' segments are
    // 64-byte multiples: aligned streams read faster, see stability/fused_common.hpp).
    constexpr std::size_t kAlign = fused_detail::kAlignDoubles;
    largest = (largest + kAlign - 1) / kAlign * kAlign;
    const std::unique_ptr<double[]> work(new double[n_threads * largest + kAlign]);
    const auto base_addr = reinterpret_cast<std::uintptr_t>(work.get());
    const std::size_t skew = (kAlign - (base_addr / sizeof(double)) % kAlign) % kAlign;
    std::atomic<std::size_t> next{0};
    const auto worker = [&](std::size_t id) noexcept {
      double* w = work.get() + skew + id * largest;
      for (std::size_t t = next++; t < parts.size(); t = next++) {
        DeviationFused<kGroup>& f = *parts[t];
        const std::size_t k = t % kParts;
        part_ok[t] = f.accumulate(x, w, largest, f.part_begin(k, kParts),
                                  f.part_begin(k + 1, kParts))
                         ? 1
                         : 0;
      }
    };
    run_workers(n_threads, worker);
    all_ok = std::all_of(part_ok.begin(), part_ok.end(), [](char v) { return v != 0; });
    for (std::size_t g = 0; g < n_groups && all_ok; ++g) {
      const DeviationFused<kGroup>* group[kParts];
      for (std::size_t k = 0; k < kParts; ++k) group[k] = parts[g * kParts + k].get();
      all_ok = DeviationFused<kGroup>::finish_parts(group, kParts, s2 + g * kGroup,
                                                    terms.data() + g * kGroup);
    }
  }
  if (!all_ok) {
    if (covered) require_finite(x, n_data, "data");
    throw py::value_error("data: the " + name + " sums are not finite (values too large?)");
  }
  std::int64_t* t = terms_out.mutable_data();
  for (std::size_t j = 0; j < n_m; ++j) t[j] = static_cast<std::int64_t>(terms[j]);
  return py::make_tuple(sigma2, terms_out);
}

std::size_t same_len(std::initializer_list<const CArray<double>*> arrays, const char* what) {
  std::size_t n = 0;
  bool first = true;
  for (const auto* a : arrays) {
    require_vec(*a, what);
    const auto len = static_cast<std::size_t>(a->shape(0));
    if (!first && len != n) throw py::value_error(std::string(what) + ": chunks differ in length");
    n = len;
    first = false;
    require_finite(a->data(), len, what);
  }
  return n;
}

std::size_t check_m(std::int64_t m) {
  if (m < 1) throw py::value_error("m must be >= 1, got " + std::to_string(m));
  return static_cast<std::size_t>(m);
}

class ModAllanStream {
 public:
  explicit ModAllanStream(std::int64_t m) : m_(check_m(m)) {}
  void seed_diff(const CArray<double>& lo, const CArray<double>& hi) {
    const std::size_t n = same_len({&lo, &hi}, "seed_diff()");
    mdev_rate_seed_diff(s_, lo.data(), hi.data(), n);
  }
  void seed_inner(const CArray<double>& y0, const CArray<double>& y1, const CArray<double>& y2) {
    const std::size_t n = same_len({&y0, &y1, &y2}, "seed_inner()");
    mdev_rate_seed_inner(s_, y0.data(), y1.data(), y2.data(), n);
  }
  void advance(const CArray<double>& y0, const CArray<double>& y1, const CArray<double>& y2,
               const CArray<double>& y3) {
    const std::size_t n = same_len({&y0, &y1, &y2, &y3}, "advance()");
    py::gil_scoped_release release;
    mdev_rate_advance(s_, y0.data(), y1.data(), y2.data(), y3.data(), n);
  }
  void finish() { mdev_rate_finish(s_); }
  double sigma2() const {
    double out = 0.0;
    if (!mdev_sigma2(s_, m_, out)) throw py::value_error("no finite mdev sums (no terms, overflow)");
    return out;
  }
  std::int64_t terms() const { return static_cast<std::int64_t>(s_.terms); }

 private:
  std::size_t m_;
  ModAllanSums<long double> s_{};
};

class OhdevStream {
 public:
  explicit OhdevStream(std::int64_t m) : m_(check_m(m)) {}
  void seed(const CArray<double>& y0, const CArray<double>& y1, const CArray<double>& y2) {
    const std::size_t n = same_len({&y0, &y1, &y2}, "seed()");
    ohdev_rate_seed(s_, y0.data(), y1.data(), y2.data(), n);
  }
  void advance(const CArray<double>& y0, const CArray<double>& y1, const CArray<double>& y2,
               const CArray<double>& y3) {
    const std::size_t n = same_len({&y0, &y1, &y2, &y3}, "advance()");
    py::gil_scoped_release release;
    ohdev_rate_advance(s_, y0.data(), y1.data(), y2.data(), y3.data(), n);
  }
  void finish() { ohdev_rate_finish(s_); }
  double sigma2() const {
    double out = 0.0;
    if (!hadamard_sigma2(s_.sum_sq, s_.terms, m_, out)) {
      throw py::value_error("no finite ohdev sums (no terms, overflow)");
    }
    return out;
  }
  std::int64_t terms() const { return static_cast<std::int64_t>(s_.terms); }

 private:
  std::size_t m_;
  HadamardSums<long double> s_{};
};

class HdevStream {
 public:
  explicit HdevStream(std::int64_t m) : m_(check_m(m)) {}
  void push(const CArray<double>& y) {
    const std::size_t n = same_len({&y}, "push()");
    py::gil_scoped_release release;
    hdev_rate_push(s_, m_, y.data(), n);
  }
  double sigma2() const {
    double out = 0.0;
    if (!hadamard_sigma2(s_.sum_sq, s_.terms, m_, out)) {
      throw py::value_error("no finite hdev sums (fewer than 3 blocks, or overflow)");
    }
    return out;
  }
  std::int64_t terms() const { return static_cast<std::int64_t>(s_.terms); }

 private:
  std::size_t m_;
  HdevBlocks<long double> s_{};
};

}  // namespace

void bind_deviation(pybind11::module_& m) {
  m.def("deviation_sigma2", &deviation_sigma2<double>, py::arg("data").noconvert(),
        py::arg("m").noconvert(), py::arg("name"), py::arg("threads") = 1,
        "Variance of the deviation `name` ('mdev', 'ohdev', 'hdev', 'totdev') of 1-D rate\n"
        "data (float64/float32) for strictly increasing averaging factors m (int64), in\n"
        "(rate units)^2. `threads` workers take whole factor groups (same result for any\n"
        "count). Returns (sigma2, terms). GIL released.");
  m.def("deviation_sigma2", &deviation_sigma2<float>, py::arg("data").noconvert(),
        py::arg("m").noconvert(), py::arg("name"), py::arg("threads") = 1);
  m.def("deviation_max_m", [](const std::string& name, std::int64_t n) {
    if (n < 0) throw py::value_error("n must be >= 0");
    return dev_max_m(parse_dev(name), static_cast<std::size_t>(n));
  }, py::arg("name"), py::arg("n_data"), "Largest averaging factor with at least 2 terms.");
  py::class_<ModAllanStream>(m, "ModAllanStream", "Streaming modified-Allan sums for one m.")
      .def(py::init<std::int64_t>(), py::arg("m"))
      .def("seed_diff", &ModAllanStream::seed_diff, py::arg("lo").noconvert(),
           py::arg("hi").noconvert())
      .def("seed_inner", &ModAllanStream::seed_inner, py::arg("y0").noconvert(),
           py::arg("y1").noconvert(), py::arg("y2").noconvert())
      .def("advance", &ModAllanStream::advance, py::arg("y0").noconvert(),
           py::arg("y1").noconvert(), py::arg("y2").noconvert(), py::arg("y3").noconvert())
      .def("finish", &ModAllanStream::finish)
      .def("sigma2", &ModAllanStream::sigma2)
      .def_property_readonly("terms", &ModAllanStream::terms);
  py::class_<OhdevStream>(m, "OhdevStream", "Streaming overlapping-Hadamard sums for one m.")
      .def(py::init<std::int64_t>(), py::arg("m"))
      .def("seed", &OhdevStream::seed, py::arg("y0").noconvert(), py::arg("y1").noconvert(),
           py::arg("y2").noconvert())
      .def("advance", &OhdevStream::advance, py::arg("y0").noconvert(),
           py::arg("y1").noconvert(), py::arg("y2").noconvert(), py::arg("y3").noconvert())
      .def("finish", &OhdevStream::finish)
      .def("sigma2", &OhdevStream::sigma2)
      .def_property_readonly("terms", &OhdevStream::terms);
  py::class_<HdevStream>(m, "HdevStream", "Streaming (non-overlapping) Hadamard sums for one m.")
      .def(py::init<std::int64_t>(), py::arg("m"))
      .def("push", &HdevStream::push, py::arg("y").noconvert())
      .def("sigma2", &HdevStream::sigma2)
      .def_property_readonly("terms", &HdevStream::terms);
}

}  // namespace gyrodrift::py_bindings
