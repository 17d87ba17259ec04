// Allan-variance kernels (include/gyrodrift/stability/allan.hpp) for gyrodrift.allan.
//   OadevOptions(kind=, method=, block=, threads=)  the options of oadev_sigma2, one bound
//                                         configuration struct (keyword-only, checked)
//   oadev_sigma2(data, m, options)        whole array, all factors, GIL released
//   oadev_fused_groups(n_data, m, block)  groups of factors one fused pass can share
//   OadevStream(m, kind)                  streaming sums for chunked (memory-mapped) records
//   OadevFusedStream(n_data, m, block)    fused streaming sums for a group of factors
//   tau_grid(grid, max_m, per_decade)     averaging-factor grids
#include <gyrodrift/stability/allan.hpp>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

AllanInput parse_kind(const std::string& kind) {
  if (kind == "rate") return AllanInput::rate;
  if (kind == "phase") return AllanInput::phase;
  throw py::value_error("kind must be 'rate' or 'phase', got '" + kind + "'");
}

template <class T>
const T* require_1d(const CArray<T>& a, const char* what) {
  if (a.ndim() != 1) {
    throw py::value_error(std::string(what) + ": expected a 1-D array, got ndim=" +
                          std::to_string(a.ndim()));
  }
  return a.data();
}

constexpr std::size_t kGroup = 64;

// The options of oadev_sigma2 as one bound object (gyrodrift._core.OadevOptions): input kind
// ('rate' or 'phase'), kernel ('fused' or 'per_tau'), fused block length (>= 16 samples) and
// worker threads (>= 1). Checked when built and again when used (the fields are writable).
struct OadevOptions {
  std::string kind{"rate"};
  std::string method{"fused"};
  std::int64_t block{65536};
  std::int64_t threads{1};

  AllanInput checked_kind() const {
    const AllanInput k = parse_kind(kind);
    if (method != "fused" && method != "per_tau") {
      throw py::value_error("method must be 'fused' or 'per_tau', got '" + method + "'");
    }
    if (block < 16) throw py::value_error("block must be >= 16, got " + std::to_string(block));
    if (threads < 1) {
      throw py::value_error("threads must be >= 1, got " + std::to_string(threads));
    }
    return k;
  }
};

// Factor groups [lo, hi) of the fused kernel: runs of at most kGroup factors, each cut in
// two where the estimated costs balance (oadev_fused_cut), so two threads can take one half
// each. The cut depends only on (n_data, m, block), never on the thread count, so results
// are the same for any `threads` and on the memory-mapped path (which runs the same groups).
std::vector<std::pair<std::size_t, std::size_t>> fused_groups(std::size_t n_data,
                                                              const std::vector<std::size_t>& m,
                                                              std::size_t block) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  auto scratch = std::make_unique<OadevFused<kGroup>>();
  for (std::size_t lo = 0; lo < m.size(); lo += kGroup) {
    const std::size_t hi = std::min(m.size(), lo + kGroup);
    const std::size_t cut = lo + oadev_fused_cut(n_data, m.data() + lo, hi - lo, block, *scratch);
    out.emplace_back(lo, cut);
    if (cut < hi) out.emplace_back(cut, hi);
  }
  return out;
}

template <class T>
py::tuple oadev_sigma2(const CArray<T>& data, const CArray<std::int64_t>& m_in,
                       const OadevOptions& options) {
  const AllanInput kind = options.checked_kind();
  const std::string& kind_name = options.kind;
  const std::string& method = options.method;
  const std::int64_t block = options.block;
  const std::int64_t threads = options.threads;
  const T* x = require_1d(data, "data");
  const auto n_data = static_cast<std::size_t>(data.shape(0));
  const std::int64_t* m_raw = require_1d(m_in, "m");
  const auto n_m = static_cast<std::size_t>(m_in.shape(0));
  const std::size_t max_m = oadev_max_m(n_data, kind);
  std::vector<std::size_t> m(n_m);
  for (std::size_t j = 0; j < n_m; ++j) {
    if (m_raw[j] < 1 || static_cast<std::size_t>(m_raw[j]) > max_m) {
      throw py::value_error("averaging factor m=" + std::to_string(m_raw[j]) +
                            " does not fit a record of " + std::to_string(n_data) + " " +
                            kind_name + " samples (1 <= m <= " + std::to_string(max_m) +
                            " leaves at least 2 differences)");
    }
    m[j] = static_cast<std::size_t>(m_raw[j]);
    if (j > 0 && m[j] <= m[j - 1]) throw py::value_error("m must be strictly increasing");
  }
  require_finite(x, n_data, "data");  // one pass; names the first bad sample
  py::array_t<double> sigma2(static_cast<py::ssize_t>(n_m));
  py::array_t<std::int64_t> terms_out(static_cast<py::ssize_t>(n_m));
  std::vector<std::size_t> terms(n_m, 0);
  double* s2 = sigma2.mutable_data();
  bool ok = true;
  if (kind == AllanInput::rate && method == "fused") {
    const auto bsz = static_cast<std::size_t>(block);
    const auto groups = fused_groups(n_data, m, bsz);
    std::vector<char> group_ok(groups.size(), 0);
    std::atomic<std::size_t> next{0};
    std::size_t* t_out = terms.data();
    // Each worker takes whole groups (own plan, own workspace); outputs do not overlap.
    std::atomic<bool> out_of_memory{false};
    const auto worker = [&]() noexcept {
      try {  // workspace allocation is the only thing that can throw here
        auto fused = std::make_unique<OadevFused<kGroup>>();
        std::vector<double> work;
        for (std::size_t g = next++; g < groups.size(); g = next++) {
          const std::size_t lo = groups[g].first;
          const std::size_t cnt = groups[g].second - lo;
          if (!fused->plan(n_data, m.data() + lo, cnt, bsz)) continue;
          work.resize(fused->workspace_doubles());
          group_ok[g] = fused->run(x, work.data(), work.size(), s2 + lo, t_out + lo) ? 1 : 0;
        }
      } catch (...) {
        out_of_memory = true;
      }
    };
    const std::size_t n_threads =
        std::min(groups.size(), static_cast<std::size_t>(threads));
    {
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
    if (out_of_memory) throw std::bad_alloc();  // pybind11 turns it into MemoryError
    ok = std::all_of(group_ok.begin(), group_ok.end(), [](char v) { return v != 0; });
  } else {
    py::gil_scoped_release release;
    ok = gyrodrift::oadev<T, double>(x, n_data, kind, m.data(), n_m, s2, terms.data());
  }
  if (!ok) throw py::value_error("data: the Allan sums are not finite (values too large?)");
  std::int64_t* t = terms_out.mutable_data();
  for (std::size_t j = 0; j < n_m; ++j) t[j] = static_cast<std::int64_t>(terms[j]);
  return py::make_tuple(sigma2, terms_out);
}

// Streaming state for one averaging factor, long double inside (exposed as double only
// at the end through sigma2()).
class OadevStream {
 public:
  OadevStream(std::int64_t m, const std::string& kind) : kind_(parse_kind(kind)) {
    if (m < 1) throw py::value_error("m must be >= 1, got " + std::to_string(m));
    m_ = static_cast<std::size_t>(m);
  }

  void seed(const CArray<double>& lo, const CArray<double>& hi) {
    if (kind_ != AllanInput::rate) throw py::value_error("seed() is for rate input only");
    require_1d(lo, "lo");
    require_1d(hi, "hi");
    if (lo.shape(0) != hi.shape(0)) throw py::value_error("seed(): lo and hi differ in length");
    const auto n = static_cast<std::size_t>(lo.shape(0));
    require_finite(lo.data(), n, "lo");
    require_finite(hi.data(), n, "hi");
    ReleasedAndLocked guard(this);  // GIL released, then this stream's lock
    oadev_rate_seed(sums_, lo.data(), hi.data(), n);
  }

  void advance(const CArray<double>& y0, const CArray<double>& y1, const CArray<double>& y2) {
    const std::size_t n = same_length(y0, y1, y2);
    const double* a = y0.data();
    const double* b = y1.data();
    const double* c = y2.data();
    require_finite(a, n, "y0");
    require_finite(b, n, "y1");
    require_finite(c, n, "y2");
    ReleasedAndLocked guard(this);
    if (kind_ == AllanInput::rate) {
      oadev_rate_advance(sums_, a, b, c, n);
    } else {
      oadev_phase_accumulate(sums_, a, b, c, n);
    }
  }

  void finish() {
    if (kind_ != AllanInput::rate) throw py::value_error("finish() is for rate input only");
    ReleasedAndLocked guard(this);
    oadev_rate_finish(sums_);
  }

  double sigma2() const {
    double out = 0.0;
    bool ok = false;
    {
      ReleasedAndLocked guard(this);
      ok = oadev_sigma2(sums_, m_, out);
    }
    if (!ok) {
      throw py::value_error("no finite Allan sums yet (no terms, or overflow)");
    }
    return out;
  }

  std::int64_t terms() const {
    ReleasedAndLocked guard(this);
    return static_cast<std::int64_t>(sums_.terms);
  }

 private:
  std::size_t same_length(const CArray<double>& a, const CArray<double>& b,
                          const CArray<double>& c) const {
    require_1d(a, "y0");
    require_1d(b, "y1");
    require_1d(c, "y2");
    if (a.shape(0) != b.shape(0) || a.shape(0) != c.shape(0)) {
      throw py::value_error("advance(): the three chunks must have the same length");
    }
    return static_cast<std::size_t>(a.shape(0));
  }

  AllanInput kind_;
  std::size_t m_{1};
  OadevSums<long double> sums_{};
};

// Fused multi-tau sums for a record read in pieces (memory-mapped files): plan, seeds,
// consecutive term ranges with one window of y per segment, finish. Like OadevStream, every
// method touching the sums runs under the stream's lock (shared by threads).
class OadevFusedStream {
 public:
  OadevFusedStream(std::int64_t n_data, const CArray<std::int64_t>& m_in, std::int64_t block)
      : fused_(std::make_unique<OadevFused<64>>()) {
    const std::int64_t* m_raw = require_1d(m_in, "m");
    const auto n_m = static_cast<std::size_t>(m_in.shape(0));
    if (n_data < 3 || block < 16 || n_m == 0 || n_m > 64) {
      throw py::value_error("OadevFusedStream: need n_data >= 3, block >= 16, 1..64 factors");
    }
    std::vector<std::size_t> m(n_m);
    for (std::size_t j = 0; j < n_m; ++j) {
      if (m_raw[j] < 1) throw py::value_error("m must be >= 1");
      m[j] = static_cast<std::size_t>(m_raw[j]);
    }
    n_data_ = static_cast<std::size_t>(n_data);
    if (!fused_->plan(n_data_, m.data(), n_m, static_cast<std::size_t>(block))) {
      throw py::value_error("OadevFusedStream: m must be strictly increasing and fit the record");
    }
    work_.resize(fused_->workspace_doubles());
    fused_->reset_sums();
  }

  py::list segments() const {
    py::list out;
    for (std::size_t k = 0; k < fused_->segments(); ++k) {
      out.append(py::make_tuple(fused_->segment_start(k), fused_->segment_span(k)));
    }
    return out;
  }

  // The record's rate line, as the in-memory run() removes it (then the sums are
  // bit-identical): head = its first kRampEnd (64) samples, tail its last ones.
  void set_ramp(const CArray<double>& head, const CArray<double>& tail) {
    require_1d(head, "head");
    require_1d(tail, "tail");
    constexpr auto k = static_cast<py::ssize_t>(gyrodrift::fused_detail::kRampEnd);
    if (head.shape(0) != k || tail.shape(0) != k) {
      throw py::value_error("set_ramp(): head and tail need 64 samples each");
    }
    // non-finite ends give no line (ramp_line); the samples are checked where they are read
    fused_->set_ramp(head.data(), tail.data(), n_data_);
  }

  void seed(std::size_t j, const CArray<double>& lo, const CArray<double>& hi) {
    require_1d(lo, "lo");
    require_1d(hi, "hi");
    if (j >= fused_->factors()) throw py::value_error("seed(): factor index out of range");
    if (lo.shape(0) != hi.shape(0)) throw py::value_error("seed(): lo and hi differ in length");
    const auto n = static_cast<std::size_t>(lo.shape(0));
    require_finite(lo.data(), n, "lo");
    require_finite(hi.data(), n, "hi");
    ReleasedAndLocked guard(this);  // GIL released, then this stream's lock
    fused_->seed_add(j, lo.data(), hi.data(), n);
  }

  void process(std::size_t b_begin, std::size_t b_end, const py::list& windows) {
    const std::size_t n_seg = fused_->segments();
    if (static_cast<std::size_t>(py::len(windows)) != n_seg) {
      throw py::value_error("process(): need one window per segment");
    }
    std::vector<CArray<double>> keep;
    std::vector<const double*> bases(n_seg, nullptr);
    keep.reserve(n_seg);
    for (std::size_t k = 0; k < n_seg; ++k) {
      keep.push_back(windows[k].cast<CArray<double>>());
      const CArray<double>& w = keep.back();
      require_1d(w, "window");
      const std::size_t start = b_begin + fused_->segment_start(k);
      const std::size_t end_needed =
          std::min(n_data_, b_end + fused_->segment_start(k) + fused_->segment_span(k));
      const std::size_t need = end_needed > start ? end_needed - start : 0;
      const auto have = static_cast<std::size_t>(w.shape(0));
      if (have < need) {
        throw py::value_error("process(): window " + std::to_string(k) + " has " +
                              std::to_string(have) + " samples, needs " + std::to_string(need));
      }
      require_finite(w.data(), have, "window");
      bases[k] = w.data();
    }
    // The order check, the work and the move of next_ are one step under the stream's lock:
    // checked before the lock, a second call on the same range passed while the first one
    // was still running (GIL released) and the sums counted the range twice.
    bool in_order = false;
    bool ok = false;
    {
      ReleasedAndLocked guard(this);
      in_order = b_begin == next_;
      if (in_order) {
        ok = fused_->process_blocks(bases.data(), b_begin, b_end, work_.data(), work_.size());
        if (ok) next_ = b_end;
      }
    }
    if (!in_order) throw py::value_error("process(): term ranges must be consecutive");
    if (!ok) throw py::value_error("process(): b_begin/b_end must be multiples of the block");
  }

  py::tuple finish() const {
    const std::size_t n_m = fused_->factors();
    py::array_t<double> sigma2(static_cast<py::ssize_t>(n_m));
    py::array_t<std::int64_t> terms_out(static_cast<py::ssize_t>(n_m));
    std::vector<std::size_t> terms(n_m);
    std::vector<double> s2(n_m);
    bool done = false;
    bool ok = false;
    {
      ReleasedAndLocked guard(this);
      done = next_ >= fused_->n_terms(0);
      ok = done && fused_->finish(s2.data(), terms.data());
    }
    if (!done) throw py::value_error("finish(): not all terms processed");
    if (!ok) throw py::value_error("the Allan sums are not finite (values too large?)");
    std::copy(s2.begin(), s2.end(), sigma2.mutable_data());
    std::int64_t* t = terms_out.mutable_data();
    for (std::size_t j = 0; j < n_m; ++j) t[j] = static_cast<std::int64_t>(terms[j]);
    return py::make_tuple(sigma2, terms_out);
  }

  std::size_t block() const { return fused_->block(); }
  std::size_t n_terms0() const { return fused_->n_terms(0); }

 private:
  std::unique_ptr<OadevFused<64>> fused_;
  std::vector<double> work_;
  std::size_t n_data_{0};
  std::size_t next_{0};
};

// [(lo, hi)] factor-index groups the fused kernel runs (see fused_groups).
py::list fused_groups_py(std::int64_t n_data, const CArray<std::int64_t>& m_in,
                         std::int64_t block) {
  const std::int64_t* m_raw = require_1d(m_in, "m");
  if (n_data < 3 || block < 16) throw py::value_error("need n_data >= 3 and block >= 16");
  std::vector<std::size_t> m(static_cast<std::size_t>(m_in.shape(0)));
  for (std::size_t j = 0; j < m.size(); ++j) {
    if (m_raw[j] < 1) throw py::value_error("m must be >= 1");
    m[j] = static_cast<std::size_t>(m_raw[j]);
  }
  py::list out;
  for (const auto& g : fused_groups(static_cast<std::size_t>(n_data), m,
                                    static_cast<std::size_t>(block))) {
    out.append(py::make_tuple(g.first, g.second));
  }
  return out;
}

py::array_t<std::int64_t> tau_grid_py(const std::string& grid_name, std::int64_t max_m,
                                       std::int64_t per_decade) {
  TauGrid grid = TauGrid::octave;
  if (grid_name == "octave") {
    grid = TauGrid::octave;
  } else if (grid_name == "decade") {
    grid = TauGrid::decade;
  } else if (grid_name == "all") {
    grid = TauGrid::all;
  } else {
    throw py::value_error("grid must be 'octave', 'decade' or 'all', got '" + grid_name + "'");
  }
  if (max_m < 0) throw py::value_error("max_m must be >= 0");
  if (per_decade < 1) throw py::value_error("per_decade must be >= 1");
  const auto mx = static_cast<std::size_t>(max_m);
  // Capacity: every m for "all", else at most 64 octaves / per_decade * 20 decades.
  const std::size_t capacity =
      grid == TauGrid::all ? mx : 64 + static_cast<std::size_t>(per_decade) * 20;
  std::vector<std::size_t> buf(capacity);
  const std::size_t n =
      tau_grid(grid, mx, static_cast<std::size_t>(per_decade), buf.data(), capacity);
  py::array_t<std::int64_t> out(static_cast<py::ssize_t>(n));
  std::int64_t* o = out.mutable_data();
  for (std::size_t j = 0; j < n; ++j) o[j] = static_cast<std::int64_t>(buf[j]);
  return out;
}

}  // namespace

void bind_allan(pybind11::module_& m) {
  py::class_<OadevOptions>(m, "OadevOptions",
                           "Options of oadev_sigma2: kind ('rate' or 'phase'), method ('fused' "
                           "or 'per_tau'), block (fused block length, >= 16 samples), threads "
                           "(>= 1). Keyword-only; checked when built and when used.")
      .def(py::init([](const std::string& kind, const std::string& method, std::int64_t block,
                       std::int64_t threads) {
             OadevOptions o{kind, method, block, threads};
             o.checked_kind();
             return o;
           }),
           py::kw_only(), py::arg("kind") = "rate", py::arg("method") = "fused",
           py::arg("block") = 65536, py::arg("threads") = 1)
      .def_readwrite("kind", &OadevOptions::kind)
      .def_readwrite("method", &OadevOptions::method)
      .def_readwrite("block", &OadevOptions::block)
      .def_readwrite("threads", &OadevOptions::threads)
      .def("__repr__", [](const OadevOptions& o) {
        return "OadevOptions(kind='" + o.kind + "', method='" + o.method +
               "', block=" + std::to_string(o.block) + ", threads=" + std::to_string(o.threads) +
               ")";
      });
  m.def("oadev_sigma2", &oadev_sigma2<double>, py::arg("data").noconvert(),
        py::arg("m").noconvert(), py::arg("options") = OadevOptions{},
        "Overlapping Allan variance for strictly increasing averaging factors m (int64) of a\n"
        "1-D float64/float32 record, with an OadevOptions. kind='rate': (rate units)^2;\n"
        "kind='phase': (phase units)^2 per sample^2 (divide by tau0^2). method='fused' (rate\n"
        "input: the factor groups of fused_groups(), one pass each, OadevFused; `threads`\n"
        "workers take whole groups, same result for any count) or 'per_tau'. Returns\n"
        "(sigma2, terms). GIL released.");
  m.def("oadev_sigma2", &oadev_sigma2<float>, py::arg("data").noconvert(),
        py::arg("m").noconvert(), py::arg("options") = OadevOptions{});
  m.def("oadev_fused_groups", &fused_groups_py, py::arg("n_data"), py::arg("m").noconvert(),
        py::arg("block"),
        "[(lo, hi)]: factor-index groups of the fused kernel (cost-balanced halves of runs\n"
        "of <= 64 factors); the memory-mapped path runs the same groups.");
  py::class_<OadevStream>(m, "OadevStream",
                          "Streaming overlapping-Allan sums for one averaging factor m "
                          "(chunked records; long double state).")
      .def(py::init<std::int64_t, const std::string&>(), py::arg("m"), py::arg("kind") = "rate")
      .def("seed", &OadevStream::seed, py::arg("lo").noconvert(), py::arg("hi").noconvert())
      .def("advance", &OadevStream::advance, py::arg("y0").noconvert(),
           py::arg("y1").noconvert(), py::arg("y2").noconvert())
      .def("finish", &OadevStream::finish)
      .def("sigma2", &OadevStream::sigma2)
      .def_property_readonly("terms", &OadevStream::terms);
  py::class_<OadevFusedStream>(m, "OadevFusedStream",
                               "Fused multi-tau Allan sums over a record read in pieces.")
      .def(py::init<std::int64_t, const CArray<std::int64_t>&, std::int64_t>(),
           py::arg("n_data"), py::arg("m").noconvert(), py::arg("block") = 4096)
      .def("segments", &OadevFusedStream::segments,
           "[(start, span)]: segment k of block b reads y[b + start : b + start + span]")
      .def("set_ramp", &OadevFusedStream::set_ramp, py::arg("head").noconvert(),
           py::arg("tail").noconvert(),
           "the record's first and last 64 samples: remove its rate line as in memory")
      .def("seed", &OadevFusedStream::seed, py::arg("j"), py::arg("lo").noconvert(),
           py::arg("hi").noconvert())
      .def("process", &OadevFusedStream::process, py::arg("b_begin"), py::arg("b_end"),
           py::arg("windows"))
      .def("finish", &OadevFusedStream::finish)
      .def_property_readonly("block", &OadevFusedStream::block)
      .def_property_readonly("n_terms0", &OadevFusedStream::n_terms0);
  m.def("tau_grid", &tau_grid_py, py::arg("grid"), py::arg("max_m"), py::arg("per_decade") = 10,
        "Averaging factors 1 <= m <= max_m: 'octave', 'decade' (per_decade points), 'all'.");
  bind_deviation(m);  // bind_deviation.cpp: mdev, ohdev, hdev, totdev kernels
  bind_streaming_allan(m);  // bind_streaming_allan.cpp: StreamingAllan, StreamingAllanF32
  bind_health(m);  // bind_health.cpp: HealthAlarms, the model Allan variance, edf and quantiles
}

}  // namespace gyrodrift::py_bindings
