// Whole-record lag statistics (include/gyrodrift/filters/lag_statistics.hpp) for
// gyrodrift.filters.lag_statistics (part of the drift area), at L = 32 lags:
//   LagStatistics()      double state, push(float64 array)
//   LagStatisticsF32()   float state (as on the target), push(float32 array)
// and without the first values (LagStatisticsNoHead) at L = 12 and 8, for Whittle's
// likelihood without them (the kind whittle_no_head, their fit's default; no `head`):
//   LagStatisticsNoHead12(), LagStatisticsNoHead12F32(), LagStatisticsNoHead8(),
//   LagStatisticsNoHead8F32()
// push(y) runs every sample through the statistics (GIL released, the object's lock held) and
// returns the number accepted (non-finite samples are refused and counted in `rejected`).
// The sums are read out in double: hi + lo of the C++ pair sums.
// The fit from them (include/gyrodrift/filters/lag_drift_fit.hpp), in double on either state:
//   lag_drift_fit(stats, kind)   -> (status, a1, a2, q, r, mean, loglike, truncation,
//                                    iterations, evaluations, runs); the numbers are 0 for
//                                    too_few_samples and non_finite
//   lag_drift_loglike(stats, a1, a2, q, r, mean, kind) -> (status, loglike)
//   lag_drift_profile(stats, a1, a2, lam, kind)        -> (status, loglike, mean, q, r)
// each on a snapshot of the statistics taken under the object's lock, the GIL released.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <cstdint>
#include <gyrodrift/filters/lag_drift_fit.hpp>
#include <gyrodrift/filters/lag_statistics.hpp>
#include <string>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

constexpr std::size_t kLags = 32;

template <class Scalar, std::size_t Lags, bool KeepHead>
class LagStatisticsPy {
 public:
  using Core = LagStatistics<Scalar, Lags, KeepHead>;

  std::int64_t push(const CArray<Scalar>& y) {
    if (y.ndim() != 1) throw py::value_error("y: expected a 1-D array, got ndim=" + std::to_string(y.ndim()));
    const auto n = static_cast<std::size_t>(y.shape(0));
    const Scalar* data = y.data();
    ReleasedAndLocked guard(this);
    return static_cast<std::int64_t>(core_.push(data, n));
  }

  void reset() {
    ReleasedAndLocked guard(this);
    core_.reset();
  }

  // A copy of the state, taken under the object's lock (the readers below work on it).
  Core snapshot() const {
    ReleasedAndLocked guard(this);
    return core_;
  }

  static double value(const typename Core::Sum& s) { return static_cast<double>(s.sum) + static_cast<double>(s.comp); }

  std::int64_t samples() const { return static_cast<std::int64_t>(snapshot().samples()); }
  std::int64_t rejected() const { return static_cast<std::int64_t>(snapshot().rejected()); }
  double centre() const { return static_cast<double>(snapshot().centre()); }
  double total() const { return value(snapshot().total()); }

  py::array_t<double> products() const {
    const Core c = snapshot();
    py::array_t<double> out(static_cast<py::ssize_t>(Lags + 1));
    double* o = out.mutable_data();
    for (std::size_t k = 0; k <= Lags; ++k) o[k] = value(c.product(k));
    return out;
  }

  template <bool Head>
  py::array_t<double> ends() const {
    const Core c = snapshot();
    const std::size_t m = c.kept();
    py::array_t<double> out(static_cast<py::ssize_t>(m));
    double* o = out.mutable_data();
    for (std::size_t i = 0; i < m; ++i) {
      if constexpr (Head) {
        o[i] = static_cast<double>(c.head(i));
      } else {
        o[i] = static_cast<double>(c.tail(i));
      }
    }
    return out;
  }

 private:
  Core core_{};
};

template <class Scalar, std::size_t Lags, bool KeepHead>
void bind_one(py::module_& m, const char* name, const char* doc) {
  using T = LagStatisticsPy<Scalar, Lags, KeepHead>;
  constexpr LagLikelihoodKind default_kind = detail::lag_default_kind(KeepHead);
  auto cls = py::class_<T>(m, name, doc);
  cls
      .def(py::init<>())
      .def("push", &T::push, py::arg("y").noconvert(),
           "Push rate samples (1-D, C-contiguous) in time order; returns the number accepted. GIL released.")
      .def("reset", &T::reset, "Forget every sample and the rejected count.")
      .def_property_readonly("n", &T::samples, "accepted samples")
      .def_property_readonly("rejected", &T::rejected, "refused (non-finite) samples")
      .def_property_readonly("centre", &T::centre, "c, the first accepted sample")
      .def_property_readonly("total", &T::total, "sum of w = y - c")
      .def_property_readonly("products", &T::products, "lag products P_0..P_L (float64)")
      .def_property_readonly("tail", &T::template ends<false>, "last min(n, L) values of w, oldest first (float64)")
      .def_property_readonly_static("lags", [](const py::object&) { return std::int64_t{Lags}; }, "L")
      .def_property_readonly_static(
          "state_bytes", [](const py::object&) { return static_cast<std::int64_t>(sizeof(typename T::Core)); },
          "sizeof the C++ statistics (bytes)");
  if constexpr (KeepHead) {
    cls.def_property_readonly("head", &T::template ends<true>, "first min(n, L) values of w (float64)");
  }
  m.def(
      "lag_drift_fit",
      [](const T& stats, LagLikelihoodKind kind, std::uint32_t max_iterations) {
        const typename T::Core snap = stats.snapshot();
        LagDriftFitResult<double> r;
        {
          py::gil_scoped_release release;
          r = gyrodrift::lag_drift_fit<double>(snap, kind, max_iterations);
        }
        return py::make_tuple(r.status, r.model.a1, r.model.a2, r.model.q, r.model.r, r.model.mean, r.loglike,
                              r.truncation, r.iterations, r.evaluations, r.runs);
      },
      py::arg("stats"), py::arg("kind") = default_kind,
      py::arg("max_iterations") = gyrodrift::kLagDriftMaxIterations,
      "Fit the drift model from the statistics (double; GIL released; at most max_iterations BFGS "
      "iterations a run): (status, a1, a2, q, r, mean, loglike, truncation, iterations, evaluations, "
      "runs), status a LagDriftFitStatus.");
  m.def(
      "lag_drift_loglike",
      [](const T& stats, double a1, double a2, double q, double r, double mean, LagLikelihoodKind kind) {
        const typename T::Core snap = stats.snapshot();
        double ll = 0.0;
        LagDriftFitStatus s;
        {
          py::gil_scoped_release release;
          s = gyrodrift::lag_drift_loglike(snap, DriftModelParams<double>{a1, a2, q, r, mean}, ll, kind);
        }
        return py::make_tuple(s, ll);
      },
      py::arg("stats"), py::arg("a1"), py::arg("a2"), py::arg("q"), py::arg("r"), py::arg("mean"),
      py::arg("kind") = default_kind,
      "Log-likelihood of the model from the statistics: (status, loglike), loglike 0 unless status is ok.");
  m.def(
      "lag_drift_profile",
      [](const T& stats, double a1, double a2, double lam, LagLikelihoodKind kind) {
        const typename T::Core snap = stats.snapshot();
        LagDriftProfile<double> p;
        LagDriftFitStatus s;
        {
          py::gil_scoped_release release;
          s = gyrodrift::lag_drift_profile(snap, a1, a2, lam, p, kind);
        }
        return py::make_tuple(s, p.loglike, p.mean, p.q, p.r);
      },
      py::arg("stats"), py::arg("a1"), py::arg("a2"), py::arg("lam"), py::arg("kind") = default_kind,
      "Profile log-likelihood at (a1, a2, lam = q / (q + r)) over the mean and the scale: (status, loglike, "
      "mean, q, r).");
}

}  // namespace

void bind_lag_statistics(py::module_& m) {
  py::enum_<LagLikelihoodKind>(m, "LagLikelihoodKind")
      .value("exact", LagLikelihoodKind::exact)
      .value("whittle", LagLikelihoodKind::whittle)
      .value("whittle_no_head", LagLikelihoodKind::whittle_no_head);
  py::enum_<LagDriftFitStatus>(m, "LagDriftFitStatus")
      .value("ok", LagDriftFitStatus::ok)
      .value("too_few_samples", LagDriftFitStatus::too_few_samples)
      .value("truncation", LagDriftFitStatus::truncation)
      .value("not_converged", LagDriftFitStatus::not_converged)
      .value("non_finite", LagDriftFitStatus::non_finite)
      .value("bad_model", LagDriftFitStatus::bad_model)
      .value("needs_head", LagDriftFitStatus::needs_head);
  m.attr("LAG_DRIFT_TRUNCATION_TOL") = kLagDriftTruncationTol;
  m.attr("LAG_DRIFT_WHITTLE_NO_HEAD_TRUNCATION_TOL") = kLagDriftWhittleNoHeadTruncationTol;
  m.attr("LAG_DRIFT_MIN_SAMPLES") = static_cast<std::int64_t>(lag_drift_min_samples(kLags));
  bind_one<double, kLags, true>(m, "LagStatistics",
                                "Whole-record lag statistics of the drift model (L = 32), double state; "
                                "push(float64 array).");
  bind_one<float, kLags, true>(m, "LagStatisticsF32",
                               "LagStatistics with float state, as on the target; push(float32 array).");
  bind_one<double, 12, false>(m, "LagStatisticsNoHead12",
                              "Lag statistics without the first values (L = 12), double state; push(float64 array).");
  bind_one<float, 12, false>(m, "LagStatisticsNoHead12F32",
                             "LagStatisticsNoHead12 with float state, as on the target; push(float32 array).");
  bind_one<double, 8, false>(m, "LagStatisticsNoHead8",
                             "Lag statistics without the first values (L = 8), double state; push(float64 array).");
  bind_one<float, 8, false>(m, "LagStatisticsNoHead8F32",
                            "LagStatisticsNoHead8 with float state, as on the target; push(float32 array).");
}

}  // namespace gyrodrift::py_bindings
