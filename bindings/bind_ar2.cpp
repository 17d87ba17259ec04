// gyrodrift._core: AR(2) identification, AR filter and AR(2)-Kalman filters.
//
// Low-level, strict API (the Python layer gyrodrift.ar2 adds conversions and messages):
//   ar2_fit(x: float32/float64[n] C-contiguous, method) -> (status, a1, a2, sigma2, mean, r)
//   ar2_kalman_batch(x, params, p0, steady_state, out=None) -> (out, faults[axes])
//   ar_filter_batch(x, params, out=None) -> (out, faults[axes])
// x is float32 or float64, 1-D or (n, 3), C-contiguous, taken without copy (.noconvert());
// params is a list of 1 (all axes) or `axes` Ar2KalmanSettings (a bound configuration
// struct: a1, a2, sigma2, mean, q, r, keyword-only). Classes Ar2Kalman / Ar2KalmanF32
// (settings, p0) / Ar2SteadyStateKalman / Ar2SteadyStateKalmanF32 (settings) are per-sample
// stateful filters.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/ar2_kalman.hpp>
#include <gyrodrift/filters/ar2_model.hpp>
#include <gyrodrift/filters/ar2_steady_state.hpp>
#include <gyrodrift/filters/ar_filter.hpp>
#include <string>
#include <type_traits>
#include <vector>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

using Params = std::array<double, 6>;  // a1, a2, sigma2, mean, q, r

// The model and filter variances of one AR(2)-Kalman channel, as one bound object.
struct Ar2KalmanSettings {
  double a1{0.0}, a2{0.0}, sigma2{0.0}, mean{0.0}, q{0.0}, r{0.0};
  Params params() const { return Params{a1, a2, sigma2, mean, q, r}; }
};

std::vector<Params> params_of(const std::vector<Ar2KalmanSettings>& settings) {
  std::vector<Params> out;
  out.reserve(settings.size());
  for (const auto& st : settings) out.push_back(st.params());
  return out;
}

template <class T>
Ar2Model<T> model_of(const Params& p) {
  return Ar2Model<T>{static_cast<T>(p[0]), static_cast<T>(p[1]), static_cast<T>(p[2]),
                     static_cast<T>(p[3])};
}

[[noreturn]] void throw_status(Ar2Status s, const std::string& what) {
  throw py::value_error(what + ": " + to_string(s));
}

template <class Filter>
void require_ok(const Filter& f, const char* what) {
  if (f.status() != Ar2Status::ok) throw_status(f.status(), what);
}

std::size_t axes_of(const py::array& a) {
  return a.ndim() == 1 ? std::size_t{1} : static_cast<std::size_t>(a.shape(1));
}

// Runs one filter per axis over the rows of x (row-major, `axes` columns), GIL released.
template <class T, class MakeFilter>
py::tuple run_batch(const CArray<T>& x, const std::vector<Params>& params, MakeFilter make,
                    const char* what, const py::object& out_obj) {
  const std::size_t n = require_1d_or_n3(x, what);
  const std::size_t axes = axes_of(x);
  if (params.size() != 1 && params.size() != axes) {
    throw py::value_error(std::string(what) + ": expected 1 or " + std::to_string(axes) +
                          " parameter sets, got " + std::to_string(params.size()));
  }
  using Filter = decltype(make(Params{}));
  std::vector<Filter> filters;
  filters.reserve(axes);
  for (std::size_t i = 0; i < axes; ++i) {
    filters.push_back(make(params[params.size() == 1 ? 0 : i]));
    require_ok(filters.back(), what);
  }
  std::vector<py::ssize_t> shape(x.shape(), x.shape() + x.ndim());
  CArray<T> out;
  if (out_obj.is_none()) {
    out = CArray<T>(shape);
  } else {
    // Caller-owned output (may be x itself: each sample is read before it is overwritten).
    if (!py::isinstance<CArray<T>>(out_obj)) {
      throw py::type_error(std::string(what) + ": out must be a C-contiguous " +
                           (sizeof(T) == 4 ? "float32" : "float64") + " array like x");
    }
    out = py::reinterpret_borrow<CArray<T>>(out_obj);
    if (out.ndim() != x.ndim() || !std::equal(shape.begin(), shape.end(), out.shape())) {
      throw py::value_error(std::string(what) + ": out must have the shape of x");
    }
    if (!out.writeable()) throw py::value_error(std::string(what) + ": out is read-only");
  }
  py::array_t<std::uint32_t> faults(static_cast<py::ssize_t>(axes));
  const T* in = x.data();
  // out may be x itself (each sample is read before it is written), but an out that only
  // partly overlaps x (e.g. x[1:] into x[:-1]) would be overwritten before it is read:
  // filter a copy of x then. Both are C-contiguous, so the byte ranges tell (what
  // numpy.shares_memory computes for such arrays).
  CArray<T> x_copy;
  {
    const auto nbytes = static_cast<std::uintptr_t>(n * axes * sizeof(T));
    const auto xa = reinterpret_cast<std::uintptr_t>(x.data());
    const auto oa = reinterpret_cast<std::uintptr_t>(out.data());
    if (oa != xa && oa < xa + nbytes && xa < oa + nbytes) {
      x_copy = CArray<T>(shape);
      std::copy(x.data(), x.data() + n * axes, x_copy.mutable_data());
      in = x_copy.data();
    }
  }
  T* o = out.mutable_data();
  std::uint32_t* fc = faults.mutable_data();
  {
    py::gil_scoped_release release;
    // Filters are copied to locals for the loop: the output stores cannot alias their state,
    // so it stays in registers (2x faster than stepping the vector elements in place).
    if (axes == 1) {
      Filter f = filters[0];
      if constexpr (std::is_same_v<Filter, Ar2Kalman<T>>) {
        f.process(in, o, n);  // register-resident state while the covariance is latched
      } else {
        for (std::size_t k = 0; k < n; ++k) o[k] = f.step(in[k]);
      }
      filters[0] = f;
    } else {
      Filter f0 = filters[0], f1 = filters[1], f2 = filters[2];
      for (std::size_t k = 0; k < n; ++k) {
        o[3 * k] = f0.step(in[3 * k]);
        o[3 * k + 1] = f1.step(in[3 * k + 1]);
        o[3 * k + 2] = f2.step(in[3 * k + 2]);
      }
      filters[0] = f0;
      filters[1] = f1;
      filters[2] = f2;
    }
  }
  for (std::size_t i = 0; i < axes; ++i) fc[i] = filters[i].fault_count();
  return py::make_tuple(out, faults);
}

template <class T>
void def_batches(py::module_& m) {
  m.def(
      "ar2_kalman_batch",
      [](const CArray<T>& x, const std::vector<Ar2KalmanSettings>& settings, double p0,
         bool steady_state, const py::object& out) {
        const std::vector<Params> params = params_of(settings);
        if (steady_state) {
          return run_batch<T>(
              x, params,
              [](const Params& p) {
                return Ar2SteadyStateKalman<T>(model_of<T>(p), static_cast<T>(p[4]), static_cast<T>(p[5]));
              },
              "ar2_kalman_batch (steady state)", out);
        }
        return run_batch<T>(
            x, params,
            [p0](const Params& p) {
              return Ar2Kalman<T>(model_of<T>(p), static_cast<T>(p[4]), static_cast<T>(p[5]),
                                  static_cast<T>(p0));
            },
            "ar2_kalman_batch", out);
      },
      py::arg("x").noconvert(), py::arg("params"), py::arg("p0") = 1.0,
      py::arg("steady_state") = false, py::arg("out") = py::none(),
      "AR(2)-Kalman over a C-contiguous float32/float64 array (n,) or (n, 3); returns (out, faults).");
  m.def(
      "ar_filter_batch",
      [](const CArray<T>& x, const std::vector<Ar2KalmanSettings>& settings, const py::object& out) {
        const std::vector<Params> params = params_of(settings);
        return run_batch<T>(
            x, params, [](const Params& p) { return ArFilter<T>(model_of<T>(p)); }, "ar_filter_batch",
            out);
      },
      py::arg("x").noconvert(), py::arg("params"), py::arg("out") = py::none(),
      "AR(2) one-step-prediction filter over (n,) or (n, 3); returns (out, faults).");
}

// step / process / reset / fault_count, the same on both per-sample filter classes;
// run(k, in, out, n) is the class's block loop.
template <class T, class K, class Run>
void def_filter_methods(py::class_<K>& cls, Run run) {
  cls.def("step", [](K& k, double y) { return static_cast<double>(k.step(static_cast<T>(y))); },
          py::arg("y"))
      .def("process",
           [run](K& k, const CArray<T>& x) {
             if (x.ndim() != 1) throw py::value_error("process: expected a 1-D array");
             CArray<T> out(x.shape(0));
             // The GIL stays held: it serialises concurrent calls on this (mutable) object.
             run(k, x.data(), out.mutable_data(), static_cast<std::size_t>(x.shape(0)));
             return out;
           },
           py::arg("x").noconvert())
      .def("reset", &K::reset)
      .def_property_readonly("fault_count", &K::fault_count);
}

template <class T>
void def_kalman_class(py::module_& m, const char* name) {
  using K = Ar2Kalman<T>;
  py::class_<K> cls(m, name, "Per-sample AR(2)-Kalman filter (Joseph form).");
  cls.def(py::init([](const Ar2KalmanSettings& st, double p0) {
            K k(model_of<T>(st.params()), static_cast<T>(st.q), static_cast<T>(st.r),
                static_cast<T>(p0));
            require_ok(k, "Ar2Kalman");
            return k;
          }),
          py::arg("settings"), py::arg("p0") = 1.0);
  def_filter_methods<T>(cls, [](K& k, const T* in, T* o, std::size_t n) { k.process(in, o, n); });
  cls.def_property_readonly("state",
                            [](const K& k) {
                              return py::make_tuple(static_cast<double>(k.state()(0)),
                                                    static_cast<double>(k.state()(1)));
                            })
      .def_property_readonly("covariance", [](const K& k) {
        py::array_t<double> p({2, 2});
        for (py::ssize_t i = 0; i < 2; ++i)
          for (py::ssize_t j = 0; j < 2; ++j) p.mutable_at(i, j) = static_cast<double>(k.covariance()(i, j));
        return p;
      });
}

template <class T>
void def_steady_class(py::module_& m, const char* name) {
  using K = Ar2SteadyStateKalman<T>;
  py::class_<K> cls(m, name, "Per-sample constant-gain AR(2)-Kalman filter (DARE gain).");
  cls.def(py::init([](const Ar2KalmanSettings& st) {
            K k(model_of<T>(st.params()), static_cast<T>(st.q), static_cast<T>(st.r));
            require_ok(k, "Ar2SteadyStateKalman");
            return k;
          }),
          py::arg("settings"));
  def_filter_methods<T>(cls, [](K& k, const T* in, T* o, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) o[i] = k.step(in[i]);
  });
  cls.def_property_readonly("iterations", &K::iterations)
      .def_property_readonly("gain", [](const K& k) {
        return py::make_tuple(static_cast<double>(k.gain()(0)), static_cast<double>(k.gain()(1)));
      });
}

template <class T>
void def_fit(py::module_& m) {
  m.def(
      "ar2_fit",
      [](const CArray<T>& x, Ar2Method method) {
        if (x.ndim() != 1) {
          throw py::value_error("ar2_fit: expected a 1-D array, got ndim=" + std::to_string(x.ndim()));
        }
        const auto n = static_cast<std::size_t>(x.shape(0));
        Ar2Model<T> model{};
        Ar2Status s;
        T r = T(0);
        {
          py::gil_scoped_release release;
          s = fit_ar2(x.data(), n, method, model);
          if (s == Ar2Status::ok) r = ar2_residual_variance(x.data(), n, model);
        }
        // The status travels as a value: gyrodrift.ar2 turns a rejection into Ar2FitError with
        // .cause = status.name (no message parsing).
        if (s != Ar2Status::ok) return py::make_tuple(s, 0.0, 0.0, 0.0, 0.0, 0.0);
        return py::make_tuple(s, static_cast<double>(model.a1), static_cast<double>(model.a2),
                              static_cast<double>(model.sigma2), static_cast<double>(model.mean),
                              static_cast<double>(r));
      },
      py::arg("x").noconvert(), py::arg("method"),
      "Fit an AR(2) model to a C-contiguous 1-D array, computing in its dtype (float32 as on "
      "target, or float64); returns (status, a1, a2, sigma2, mean, r) with status an Ar2Status "
      "(the numbers are 0 unless status is Ar2Status.ok).");
}

}  // namespace

void bind_ar2(py::module_& m) {
  py::enum_<Ar2Method>(m, "Ar2Method")
      .value("yule_walker", Ar2Method::yule_walker)
      .value("burg", Ar2Method::burg)
      .value("least_squares", Ar2Method::least_squares);
  py::enum_<Ar2Status>(m, "Ar2Status")
      .value("ok", Ar2Status::ok)
      .value("too_short", Ar2Status::too_short)
      .value("constant", Ar2Status::constant)
      .value("non_finite", Ar2Status::non_finite)
      .value("non_stationary", Ar2Status::non_stationary)
      .value("bad_argument", Ar2Status::bad_argument)
      .value("not_converged", Ar2Status::not_converged);
  m.attr("AR2_MIN_SAMPLES") = kAr2MinSamples;
  py::class_<Ar2KalmanSettings>(m, "Ar2KalmanSettings",
                                "AR(2) model (a1, a2, sigma2, mean) and Kalman variances q, r of "
                                "one channel, in (record units)^2.")
      .def(py::init([](double a1, double a2, double sigma2, double mean, double q, double r) {
             return Ar2KalmanSettings{a1, a2, sigma2, mean, q, r};
           }),
           py::kw_only(), py::arg("a1"), py::arg("a2"), py::arg("sigma2"), py::arg("mean") = 0.0,
           py::arg("q"), py::arg("r"))
      .def_readwrite("a1", &Ar2KalmanSettings::a1)
      .def_readwrite("a2", &Ar2KalmanSettings::a2)
      .def_readwrite("sigma2", &Ar2KalmanSettings::sigma2)
      .def_readwrite("mean", &Ar2KalmanSettings::mean)
      .def_readwrite("q", &Ar2KalmanSettings::q)
      .def_readwrite("r", &Ar2KalmanSettings::r);

  def_fit<double>(m);
  def_fit<float>(m);

  m.def(
      "ar2_yule_walker_stream",
      [](const CArray<double>& x) {
        if (x.ndim() != 1) throw py::value_error("ar2_yule_walker_stream: expected a 1-D array");
        Ar2YuleWalkerAccumulator<double> acc;
        const double* d = x.data();
        for (py::ssize_t i = 0; i < x.shape(0); ++i) acc.push(d[i]);
        Ar2Model<double> model{};
        const Ar2Status s = acc.fit(model);
        if (s != Ar2Status::ok) throw py::value_error(std::string(to_string(s)) + ": streaming fit rejected");
        return py::make_tuple(model.a1, model.a2, model.sigma2, model.mean);
      },
      py::arg("x").noconvert(),
      "Streaming (sample-by-sample) Yule-Walker fit, as used on target; returns (a1, a2, sigma2, mean).");

  def_batches<double>(m);
  def_batches<float>(m);
  def_kalman_class<double>(m, "Ar2Kalman");
  def_kalman_class<float>(m, "Ar2KalmanF32");
  def_steady_class<double>(m, "Ar2SteadyStateKalman");
  def_steady_class<float>(m, "Ar2SteadyStateKalmanF32");
}

}  // namespace gyrodrift::py_bindings
