// Online drift-model identifier (include/gyrodrift/filters/online_drift_identifier.hpp) for
// gyrodrift.filters.online (part of the drift area):
//   OnlineDriftSettings(*, block_samples, retune_blocks, min_samples, memory_blocks, max_step,
//                       max_rel_stderr, max_innovation_ratio, ar_order)   defaults from C++
//   OnlineDriftIdentifier(*, a1, a2, q, r, mean, settings)      double state, push(float64 array)
//   OnlineDriftIdentifierF32(*, a1, a2, q, r, mean, settings)   float state (as on the target),
//                                                                push(float32 array)
// push(y) runs every sample through the identifier (GIL released, the object's lock held) and
// returns one row per parameter update (block) completed during the call:
//   (accepted, samples[nb] int64, estimate[nb, 5], in_use[nb, 5], gain[nb, 2], status[nb] uint8,
//    stderr[nb, 5] (NaN while unavailable), retuned[nb] bool)
// with the model columns (a1, a2, q, r, mean).
//   SharedDriftIdentifier(*, models[n, 5], settings)   (shared_drift_identifier.hpp: one
//   SharedDriftIdentifierF32(*, models[n, 5], settings)  identifier in turns of one block among
//                                                       n = 1..3 gyro channels, as the processor)
// push(y[samples, n]) runs each row's samples in channel order (as the processor's monitor
// steps its watched gyros) and returns one row per block completed during the call:
//   (channel[nb] int64, samples[nb] int64, estimate[nb, 5], in_use[nb, 5], gain[nb, 2],
//    status[nb] uint8, retuned[nb] bool)
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/online_drift_identifier.hpp>
#include <gyrodrift/filters/shared_drift_identifier.hpp>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

using Settings = OnlineDriftSettings<double>;

std::string settings_problem(const Settings& s) {
  if (s.block_samples < 8) return "block_samples must be >= 8";
  if (s.retune_blocks < 1) return "retune_blocks must be >= 1";
  if (!std::isfinite(s.memory_blocks) || !(s.memory_blocks == 0.0 || s.memory_blocks >= 1.0)) {
    return "memory_blocks must be 0 (no forgetting) or a finite number >= 1";
  }
  if (!std::isfinite(s.max_step) || !(s.max_step > 0.0)) return "max_step must be a positive finite number";
  if (!std::isfinite(s.max_rel_stderr) || !(s.max_rel_stderr > 0.0)) {
    return "max_rel_stderr must be a positive finite number";
  }
  if (!std::isfinite(s.max_innovation_ratio) || !(s.max_innovation_ratio > 1.0)) {
    return "max_innovation_ratio must be a finite number > 1";
  }
  if (s.ar_order != 1 && s.ar_order != 2) return "ar_order must be 1 or 2";
  if (!std::isfinite(s.warmup_blocks) || !(s.warmup_blocks == 0.0 || s.warmup_blocks >= 1.0)) {
    return "warmup_blocks must be 0 (gain 1/k from the start) or a finite number >= 1";
  }
  if (!(s.lambda_start > 0.0 && s.lambda_start <= 1.0)) return "lambda_start must be in (0, 1]";
  if (!std::isfinite(s.info_blocks) || !(s.info_blocks == 0.0 || s.info_blocks >= 1.0)) {
    return "info_blocks must be 0 or a finite number >= 1";
  }
  if (!std::isfinite(s.min_ar_wald) || !(s.min_ar_wald >= 0.0)) return "min_ar_wald must be a finite number >= 0";
  return "";
}

void check_settings(const Settings& s) {
  const std::string p = settings_problem(s);
  if (!p.empty()) throw py::value_error("OnlineDriftSettings: " + p);
}

template <class Scalar>
py::tuple model_tuple(const DriftModelParams<Scalar>& p) {
  return py::make_tuple(static_cast<double>(p.a1), static_cast<double>(p.a2), static_cast<double>(p.q),
                        static_cast<double>(p.r), static_cast<double>(p.mean));
}

template <class Scalar>
void put_model(double* o, const DriftModelParams<Scalar>& p) {
  o[0] = static_cast<double>(p.a1);
  o[1] = static_cast<double>(p.a2);
  o[2] = static_cast<double>(p.q);
  o[3] = static_cast<double>(p.r);
  o[4] = static_cast<double>(p.mean);
}

template <class Scalar>
OnlineDriftSettings<Scalar> native_settings(const Settings& s) {
  check_settings(s);
  OnlineDriftSettings<Scalar> cs;
  cs.block_samples = s.block_samples;
  cs.retune_blocks = s.retune_blocks;
  cs.min_samples = s.min_samples;
  cs.memory_blocks = static_cast<Scalar>(s.memory_blocks);
  cs.max_step = static_cast<Scalar>(s.max_step);
  cs.max_rel_stderr = static_cast<Scalar>(s.max_rel_stderr);
  cs.max_innovation_ratio = static_cast<Scalar>(s.max_innovation_ratio);
  cs.ar_order = s.ar_order;
  cs.warmup_blocks = static_cast<Scalar>(s.warmup_blocks);
  cs.lambda_start = static_cast<Scalar>(s.lambda_start);
  cs.adapt_ar = s.adapt_ar;
  cs.info_blocks = static_cast<Scalar>(s.info_blocks);
  cs.min_ar_wald = static_cast<Scalar>(s.min_ar_wald);
  return cs;
}

// Why OnlineDriftIdentifier::configure refused a model (the settings are checked before).
template <class Scalar>
std::string model_problem(const DriftModelParams<Scalar>& m, const OnlineDriftSettings<Scalar>& cs) {
  const Ar2Status st = drift_params_status(m);
  std::string why = st != Ar2Status::ok ? std::string(to_string(st)) : std::string();
  if (why.empty() && !(m.r > Scalar(0))) why = "r must be > 0";
  if (why.empty() && cs.ar_order == 1 && m.a2 != Scalar(0)) why = "a2 must be 0 with ar_order 1";
  if (why.empty()) why = "its steady-state gain does not converge";
  return why;
}

template <class Scalar>
class OnlineDriftPy {
 public:
  OnlineDriftPy(double a1, double a2, double q, double r, double mean, const Settings& s) {
    const OnlineDriftSettings<Scalar> cs = native_settings<Scalar>(s);
    const DriftModelParams<Scalar> m{static_cast<Scalar>(a1), static_cast<Scalar>(a2), static_cast<Scalar>(q),
                                     static_cast<Scalar>(r), static_cast<Scalar>(mean)};
    if (!core_.configure(m, cs)) {
      throw py::value_error("OnlineDriftIdentifier: the configured model is refused: " + model_problem(m, cs));
    }
    block_samples_ = s.block_samples;
  }

  py::tuple push(const CArray<Scalar>& y) {
    if (y.ndim() != 1) throw py::value_error("y: expected a 1-D array, got ndim=" + std::to_string(y.ndim()));
    const auto n = static_cast<std::size_t>(y.shape(0));
    const Scalar* data = y.data();
    std::size_t cap = 0;
    {
      ReleasedAndLocked guard(this);
      const std::uint64_t in_block = core_.samples() - std::uint64_t{core_.blocks()} * block_samples_;
      cap = static_cast<std::size_t>((in_block + n) / block_samples_);
    }
    const auto rows = static_cast<py::ssize_t>(cap);
    py::array_t<std::int64_t> samples(rows);
    py::array_t<double> estimate({rows, py::ssize_t{5}}), in_use({rows, py::ssize_t{5}});
    py::array_t<double> gain({rows, py::ssize_t{2}}), stderr_out({rows, py::ssize_t{5}});
    py::array_t<std::uint8_t> status(rows);
    py::array_t<bool> retuned(rows);
    std::int64_t* o_samples = samples.mutable_data();
    double* o_est = estimate.mutable_data();
    double* o_use = in_use.mutable_data();
    double* o_gain = gain.mutable_data();
    double* o_se = stderr_out.mutable_data();
    std::uint8_t* o_status = status.mutable_data();
    bool* o_retuned = retuned.mutable_data();
    std::size_t accepted = 0, nb = 0;
    {
      ReleasedAndLocked guard(this);
      bool any_retune = false;
      for (std::size_t i = 0; i < n; ++i) {
        if (core_.push(data[i])) ++accepted;
        any_retune = any_retune || core_.retuned();
        if (core_.block_updated() && nb < cap) {
          o_samples[nb] = static_cast<std::int64_t>(core_.samples());
          put_model(o_est + 5 * nb, core_.estimate());
          put_model(o_use + 5 * nb, core_.in_use());
          o_gain[2 * nb] = static_cast<double>(core_.gain0());
          o_gain[2 * nb + 1] = static_cast<double>(core_.gain1());
          o_status[nb] = static_cast<std::uint8_t>(core_.status());
          DriftModelParams<Scalar> se{};
          if (core_.stderrs(se)) {
            put_model(o_se + 5 * nb, se);
          } else {
            for (int j = 0; j < 5; ++j) o_se[5 * nb + static_cast<std::size_t>(j)] = std::numeric_limits<double>::quiet_NaN();
          }
          o_retuned[nb] = any_retune;
          any_retune = false;
          ++nb;
        }
      }
    }
    const auto used = static_cast<py::ssize_t>(nb);
    auto cut = [used](const py::array& a) { return a[py::slice(0, used, 1)]; };
    return py::make_tuple(static_cast<std::int64_t>(accepted), cut(samples), cut(estimate), cut(in_use), cut(gain),
                          cut(status), cut(stderr_out), cut(retuned));
  }

  void reset() {
    ReleasedAndLocked guard(this);
    core_.reset();
  }

  template <class F>
  auto locked(F f) const {
    ReleasedAndLocked guard(this);
    return f(core_);
  }

  py::tuple estimate() const { return model_tuple(locked([](const auto& c) { return c.estimate(); })); }
  py::tuple in_use() const { return model_tuple(locked([](const auto& c) { return c.in_use(); })); }
  py::tuple configured() const { return model_tuple(core_.configured()); }
  py::object stderrs() const {
    DriftModelParams<Scalar> se{};
    const bool ok = locked([&se](const auto& c) { return c.stderrs(se); });
    if (!ok) return py::none();
    return model_tuple(se);
  }
  py::tuple gain() const {
    const auto g = locked([](const auto& c) { return std::pair<Scalar, Scalar>(c.gain0(), c.gain1()); });
    return py::make_tuple(static_cast<double>(g.first), static_cast<double>(g.second));
  }
  int status() const { return static_cast<int>(locked([](const auto& c) { return c.status(); })); }
  std::int64_t samples() const { return static_cast<std::int64_t>(locked([](const auto& c) { return c.samples(); })); }
  std::int64_t rejected() const {
    return static_cast<std::int64_t>(locked([](const auto& c) { return c.rejected(); }));
  }
  std::int64_t blocks() const { return static_cast<std::int64_t>(locked([](const auto& c) { return c.blocks(); })); }
  std::int64_t retunes() const { return static_cast<std::int64_t>(locked([](const auto& c) { return c.retunes(); })); }
  std::int64_t refused_retunes() const {
    return static_cast<std::int64_t>(locked([](const auto& c) { return c.refused_retunes(); }));
  }
  static std::int64_t state_bytes() { return static_cast<std::int64_t>(sizeof(OnlineDriftIdentifier<Scalar>)); }

 private:
  OnlineDriftIdentifier<Scalar> core_{};
  std::uint32_t block_samples_ = 1;
};

template <class Scalar>
void bind_one(py::module_& m, const char* name, const char* doc) {
  using T = OnlineDriftPy<Scalar>;
  py::class_<T>(m, name, doc)
      .def(py::init<double, double, double, double, double, const Settings&>(), py::kw_only(), py::arg("a1"),
           py::arg("a2"), py::arg("q"), py::arg("r"), py::arg("mean"), py::arg("settings"))
      .def("push", &T::push, py::arg("y").noconvert(),
           "Push rate samples (1-D, C-contiguous); returns (accepted, samples, estimate, in_use, gain, "
           "status, stderr, retuned), one row per block completed. GIL released.")
      .def("reset", &T::reset, "Back to the configured model, counters cleared.")
      .def_property_readonly("estimate", &T::estimate, "(a1, a2, q, r, mean) of the running estimate")
      .def_property_readonly("in_use", &T::in_use, "(a1, a2, q, r, mean) of the gain's model")
      .def_property_readonly("configured", &T::configured, "(a1, a2, q, r, mean) configured")
      .def_property_readonly("stderrs", &T::stderrs, "standard errors (a1, a2, q, r, mean) or None")
      .def_property_readonly("gain", &T::gain, "steady-state gain (k0, k1) of in_use")
      .def_property_readonly("status", &T::status, "OnlineDriftStatus code")
      .def_property_readonly("samples", &T::samples)
      .def_property_readonly("rejected", &T::rejected)
      .def_property_readonly("blocks", &T::blocks)
      .def_property_readonly("retunes", &T::retunes)
      .def_property_readonly("refused_retunes", &T::refused_retunes)
      .def_property_readonly_static("state_bytes", [](const py::object&) { return T::state_bytes(); },
                                    "sizeof the C++ identifier (bytes)");
}

// The channels one shared identifier serves in the processor (its gyro monitor slots: gx, gy, gz).
constexpr std::size_t kSharedChannels = 3;

template <class Scalar>
class SharedDriftPy {
 public:
  using Core = SharedDriftIdentifier<Scalar, kSharedChannels>;

  SharedDriftPy(const CArray<double>& models, const Settings& s) {
    const OnlineDriftSettings<Scalar> cs = native_settings<Scalar>(s);
    if (models.ndim() != 2 || models.shape(1) != 5) {
      throw py::value_error("SharedDriftIdentifier: models: expected shape (channels, 5), got ndim=" +
                            std::to_string(models.ndim()));
    }
    const auto n = static_cast<std::size_t>(models.shape(0));
    if (n < 1 || n > kSharedChannels) {
      throw py::value_error("SharedDriftIdentifier: 1 to " + std::to_string(kSharedChannels) +
                            " channels, got " + std::to_string(n));
    }
    std::array<DriftModelParams<Scalar>, kSharedChannels> m{};
    const double* d = models.data();
    for (std::size_t c = 0; c < n; ++c) {
      m[c] = DriftModelParams<Scalar>{static_cast<Scalar>(d[5 * c]), static_cast<Scalar>(d[5 * c + 1]),
                                      static_cast<Scalar>(d[5 * c + 2]), static_cast<Scalar>(d[5 * c + 3]),
                                      static_cast<Scalar>(d[5 * c + 4])};
    }
    std::size_t failed = 0;
    if (!core_.configure(m.data(), n, cs, &failed)) {
      throw py::value_error("SharedDriftIdentifier: the configured model of channel " + std::to_string(failed) +
                            " is refused: " + model_problem(m[failed < n ? failed : 0], cs));
    }
  }

  py::tuple push(const CArray<Scalar>& y) {
    const std::size_t n = core_.channels();
    if (y.ndim() != 2 || static_cast<std::size_t>(y.shape(1)) != n) {
      throw py::value_error("y: expected shape (samples, " + std::to_string(n) + "), got ndim=" +
                            std::to_string(y.ndim()) + (y.ndim() == 2 ? ", " + std::to_string(y.shape(1)) + " columns"
                                                                      : std::string()));
    }
    const auto rows_in = static_cast<std::size_t>(y.shape(0));
    const Scalar* data = y.data();
    std::vector<std::int64_t> channel, samples;
    std::vector<double> est, use, gain;
    std::vector<std::uint8_t> status;
    std::vector<std::uint8_t> retuned;
    {
      ReleasedAndLocked guard(this);
      for (std::size_t k = 0; k < rows_in; ++k) {
        for (std::size_t c = 0; c < n; ++c) {
          const std::uint32_t before = core_.blocks(c);
          core_.push(c, data[k * n + c]);
          if (core_.blocks(c) == before) continue;
          channel.push_back(static_cast<std::int64_t>(c));
          samples.push_back(static_cast<std::int64_t>(core_.samples(c)));
          double o[5];
          put_model(o, core_.estimate(c));
          est.insert(est.end(), o, o + 5);
          put_model(o, core_.in_use(c));
          use.insert(use.end(), o, o + 5);
          gain.push_back(static_cast<double>(core_.gain0(c)));
          gain.push_back(static_cast<double>(core_.gain1(c)));
          status.push_back(static_cast<std::uint8_t>(core_.status(c)));
          retuned.push_back(core_.retuned() ? 1U : 0U);
        }
      }
    }
    const auto nb = static_cast<py::ssize_t>(channel.size());
    py::array_t<std::int64_t> o_channel(nb, channel.data()), o_samples(nb, samples.data());
    py::array_t<double> o_est({nb, py::ssize_t{5}}, est.data()), o_use({nb, py::ssize_t{5}}, use.data());
    py::array_t<double> o_gain({nb, py::ssize_t{2}}, gain.data());
    py::array_t<std::uint8_t> o_status(nb, status.data());
    py::array_t<bool> o_retuned(nb);
    bool* r = o_retuned.mutable_data();
    for (std::size_t i = 0; i < retuned.size(); ++i) r[i] = retuned[i] != 0U;
    return py::make_tuple(o_channel, o_samples, o_est, o_use, o_gain, o_status, o_retuned);
  }

  void reset() {
    ReleasedAndLocked guard(this);
    core_.reset();
  }

  template <class F>
  auto locked(F f) const {
    ReleasedAndLocked guard(this);
    return f(core_);
  }

  std::size_t check(std::size_t c) const {
    if (c >= core_.channels()) {
      throw py::index_error("channel " + std::to_string(c) + " out of range (" + std::to_string(core_.channels()) +
                            " channels)");
    }
    return c;
  }

  py::tuple estimate(std::size_t c) const {
    check(c);
    return model_tuple(locked([c](const Core& k) { return k.estimate(c); }));
  }
  py::tuple in_use(std::size_t c) const {
    check(c);
    return model_tuple(locked([c](const Core& k) { return k.in_use(c); }));
  }
  py::tuple configured(std::size_t c) const {
    check(c);
    return model_tuple(locked([c](const Core& k) { return k.configured(c); }));
  }
  py::tuple gain(std::size_t c) const {
    check(c);
    const auto g = locked([c](const Core& k) { return std::pair<Scalar, Scalar>(k.gain0(c), k.gain1(c)); });
    return py::make_tuple(static_cast<double>(g.first), static_cast<double>(g.second));
  }
  int status(std::size_t c) const {
    check(c);
    return static_cast<int>(locked([c](const Core& k) { return k.status(c); }));
  }
  std::int64_t samples(std::size_t c) const {
    check(c);
    return static_cast<std::int64_t>(locked([c](const Core& k) { return k.samples(c); }));
  }
  std::int64_t rejected(std::size_t c) const {
    check(c);
    return static_cast<std::int64_t>(locked([c](const Core& k) { return k.rejected(c); }));
  }
  std::int64_t blocks(std::size_t c) const {
    check(c);
    return static_cast<std::int64_t>(locked([c](const Core& k) { return k.blocks(c); }));
  }
  std::int64_t retunes(std::size_t c) const {
    check(c);
    return static_cast<std::int64_t>(locked([c](const Core& k) { return k.retunes(c); }));
  }
  std::int64_t refused_retunes(std::size_t c) const {
    check(c);
    return static_cast<std::int64_t>(locked([c](const Core& k) { return k.refused_retunes(c); }));
  }
  std::int64_t channels() const { return static_cast<std::int64_t>(core_.channels()); }
  std::int64_t turn() const { return static_cast<std::int64_t>(locked([](const Core& k) { return k.turn(); })); }
  static std::int64_t state_bytes() { return static_cast<std::int64_t>(sizeof(Core)); }

 private:
  Core core_{};
};

template <class Scalar>
void bind_shared(py::module_& m, const char* name, const char* doc) {
  using T = SharedDriftPy<Scalar>;
  py::class_<T>(m, name, doc)
      .def(py::init<const CArray<double>&, const Settings&>(), py::kw_only(), py::arg("models").noconvert(),
           py::arg("settings"))
      .def("push", &T::push, py::arg("y").noconvert(),
           "Push rows of samples (samples, channels), each row in channel order; returns (channel, samples, "
           "estimate, in_use, gain, status, retuned), one row per block completed. GIL released.")
      .def("reset", &T::reset, "Every channel back to its configured model, the turn at channel 0.")
      .def("estimate", &T::estimate, py::arg("c"), "(a1, a2, q, r, mean) of channel c's running estimate")
      .def("in_use", &T::in_use, py::arg("c"), "(a1, a2, q, r, mean) of channel c's gain's model")
      .def("configured", &T::configured, py::arg("c"), "(a1, a2, q, r, mean) configured for channel c")
      .def("gain", &T::gain, py::arg("c"), "steady-state gain (k0, k1) of channel c's in_use")
      .def("status", &T::status, py::arg("c"), "OnlineDriftStatus code of channel c")
      .def("samples", &T::samples, py::arg("c"))
      .def("rejected", &T::rejected, py::arg("c"))
      .def("blocks", &T::blocks, py::arg("c"))
      .def("retunes", &T::retunes, py::arg("c"))
      .def("refused_retunes", &T::refused_retunes, py::arg("c"))
      .def_property_readonly("channels", &T::channels)
      .def_property_readonly("turn", &T::turn, "the channel whose block runs now")
      .def_property_readonly_static("capacity", [](const py::object&) { return std::int64_t{kSharedChannels}; })
      .def_property_readonly_static("state_bytes", [](const py::object&) { return T::state_bytes(); },
                                    "sizeof the C++ shared identifier (bytes)");
}

}  // namespace

void bind_online_drift(py::module_& m) {
  py::class_<Settings>(m, "OnlineDriftSettings",
                       "Settings of the online drift identifier (keyword-only; defaults from C++).")
      .def(py::init([](std::uint32_t block_samples, std::uint32_t retune_blocks, std::uint64_t min_samples,
                       double memory_blocks, double max_step, double max_rel_stderr, double max_innovation_ratio,
                       std::uint8_t ar_order, double warmup_blocks, double lambda_start, bool adapt_ar,
                       double info_blocks, double min_ar_wald) {
             Settings s;
             s.block_samples = block_samples;
             s.retune_blocks = retune_blocks;
             s.min_samples = min_samples;
             s.memory_blocks = memory_blocks;
             s.max_step = max_step;
             s.max_rel_stderr = max_rel_stderr;
             s.max_innovation_ratio = max_innovation_ratio;
             s.ar_order = ar_order;
             s.warmup_blocks = warmup_blocks;
             s.lambda_start = lambda_start;
             s.adapt_ar = adapt_ar;
             s.info_blocks = info_blocks;
             s.min_ar_wald = min_ar_wald;
             check_settings(s);
             return s;
           }),
           py::kw_only(), py::arg("block_samples") = Settings{}.block_samples,
           py::arg("retune_blocks") = Settings{}.retune_blocks, py::arg("min_samples") = Settings{}.min_samples,
           py::arg("memory_blocks") = Settings{}.memory_blocks, py::arg("max_step") = Settings{}.max_step,
           py::arg("max_rel_stderr") = Settings{}.max_rel_stderr,
           py::arg("max_innovation_ratio") = Settings{}.max_innovation_ratio,
           py::arg("ar_order") = Settings{}.ar_order, py::arg("warmup_blocks") = Settings{}.warmup_blocks,
           py::arg("lambda_start") = Settings{}.lambda_start, py::arg("adapt_ar") = Settings{}.adapt_ar,
           py::arg("info_blocks") = Settings{}.info_blocks, py::arg("min_ar_wald") = Settings{}.min_ar_wald)
      .def_readwrite("block_samples", &Settings::block_samples)
      .def_readwrite("retune_blocks", &Settings::retune_blocks)
      .def_readwrite("min_samples", &Settings::min_samples)
      .def_readwrite("memory_blocks", &Settings::memory_blocks)
      .def_readwrite("max_step", &Settings::max_step)
      .def_readwrite("max_rel_stderr", &Settings::max_rel_stderr)
      .def_readwrite("max_innovation_ratio", &Settings::max_innovation_ratio)
      .def_readwrite("ar_order", &Settings::ar_order)
      .def_readwrite("warmup_blocks", &Settings::warmup_blocks)
      .def_readwrite("lambda_start", &Settings::lambda_start)
      .def_readwrite("adapt_ar", &Settings::adapt_ar)
      .def_readwrite("info_blocks", &Settings::info_blocks)
      .def_readwrite("min_ar_wald", &Settings::min_ar_wald);
  bind_one<double>(m, "OnlineDriftIdentifier",
                   "Online recursive-prediction-error identifier of the drift model, double state; "
                   "push(float64 array).");
  bind_one<float>(m, "OnlineDriftIdentifierF32",
                  "OnlineDriftIdentifier with float state, as on the target; push(float32 array).");
  bind_shared<double>(m, "SharedDriftIdentifier",
                      "One online drift identifier shared in turns of one block among 1 to 3 gyro channels, "
                      "double state; push(float64 array (samples, channels)).");
  bind_shared<float>(m, "SharedDriftIdentifierF32",
                     "SharedDriftIdentifier with float state, as on the target; push(float32 array).");
}

}  // namespace gyrodrift::py_bindings
