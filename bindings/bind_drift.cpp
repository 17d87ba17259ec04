// gyrodrift._core: exact Gaussian log-likelihood of the drift model (AR(2)/AR(1) drift + white
// noise) through the Kalman filter, include/gyrodrift/filters/drift_likelihood.hpp.
//
//   drift_loglike(x, a1, a2, q, r, mean, innovations=None)
//       -> (loglike, sum_log_f, sum_ee, sum_eg, sum_gg)
// x: float32/float64 1-D array, any stride (a column x[:, i] of an (n, 3) array is read in place,
// no copy); computes in x's dtype. innovations: optional writable 1-D array of x's dtype and
// length, receives the standardised innovations e_k / sqrt(F_k). GIL released during the pass.
//
//   DriftLoglikeStream(*, a1, a2, q, r, mean)   the same pass over a record read in pieces
//       .update(x, innovations=None)            the next piece (float64, any stride)
//       .result() -> (loglike, sum_log_f, sum_ee, sum_eg, sum_gg)   of all pieces so far
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <gyrodrift/filters/drift_likelihood.hpp>
#include <memory>
#include <string>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

template <class T>
std::ptrdiff_t element_stride(const py::array_t<T>& a, const char* what) {
  const auto s = a.strides(0);
  if (s % static_cast<py::ssize_t>(sizeof(T)) != 0) {
    throw py::value_error(std::string(what) + ": stride is not a multiple of the item size");
  }
  return static_cast<std::ptrdiff_t>(s / static_cast<py::ssize_t>(sizeof(T)));
}

template <class T>
void def_loglike(py::module_& m) {
  m.def(
      "drift_loglike",
      [](const py::array_t<T>& x, double a1, double a2, double q, double r, double mean,
         const py::object& innovations) {
        if (x.ndim() != 1) {
          throw py::value_error("drift_loglike: expected a 1-D array (a column of an (n, 3) array "
                                "is read in place), got ndim=" + std::to_string(x.ndim()));
        }
        const auto n = static_cast<std::size_t>(x.shape(0));
        const std::ptrdiff_t stride = element_stride(x, "drift_loglike");
        T* innov = nullptr;
        std::ptrdiff_t innov_stride = 1;
        py::array_t<T> inn;
        if (!innovations.is_none()) {
          if (!py::isinstance<py::array_t<T>>(innovations) ||
              !py::array(innovations).dtype().is(py::dtype::of<T>())) {
            throw py::type_error("drift_loglike: innovations must be an array of x's dtype");
          }
          inn = py::reinterpret_borrow<py::array_t<T>>(innovations);
          if (inn.ndim() != 1 || static_cast<std::size_t>(inn.shape(0)) != n) {
            throw py::value_error("drift_loglike: innovations must be 1-D with x's length");
          }
          if (!inn.writeable()) throw py::value_error("drift_loglike: innovations is read-only");
          innov = inn.mutable_data();
          innov_stride = element_stride(inn, "drift_loglike innovations");
        }
        const DriftModelParams<T> p{static_cast<T>(a1), static_cast<T>(a2), static_cast<T>(q),
                                    static_cast<T>(r), static_cast<T>(mean)};
        DriftLikelihoodSums<T> sums;
        Ar2Status s;
        {
          py::gil_scoped_release release;
          s = drift_likelihood(x.data(), n, stride, p, sums, innov, innov_stride);
        }
        // The status name is the first word of the message (gyrodrift.drift_model maps it).
        if (s != Ar2Status::ok) {
          throw py::value_error(std::string(to_string(s)) + ": drift log-likelihood of " +
                                std::to_string(n) + " samples rejected");
        }
        return py::make_tuple(static_cast<double>(sums.loglike()), static_cast<double>(sums.sum_log_f),
                              static_cast<double>(sums.sum_ee), static_cast<double>(sums.sum_eg),
                              static_cast<double>(sums.sum_gg));
      },
      py::arg("x").noconvert(), py::arg("a1"), py::arg("a2"), py::arg("q"), py::arg("r"),
      py::arg("mean"), py::arg("innovations") = py::none(),
      "Exact Gaussian log-likelihood of AR(2) drift + white noise (Kalman filter, stationary "
      "start); returns (loglike, sum_log_f, sum_ee, sum_eg, sum_gg).");
}

py::tuple sums_tuple(const DriftLikelihoodSums<double>& sums) {
  return py::make_tuple(sums.loglike(), sums.sum_log_f, sums.sum_ee, sums.sum_eg, sums.sum_gg);
}

void def_stream(py::module_& m) {
  using Stream = DriftLikelihoodStream<double>;
  py::class_<Stream>(m, "DriftLoglikeStream",
                     "The drift log-likelihood pass over a record read in pieces: update() "
                     "with consecutive float64 pieces, result() for the sums of all of them "
                     "(the same numbers as drift_loglike over the whole record).")
      .def(py::init([](double a1, double a2, double q, double r, double mean) {
             auto s = std::make_unique<Stream>();
             const Ar2Status st = s->begin(DriftModelParams<double>{a1, a2, q, r, mean});
             if (st != Ar2Status::ok) {
               throw py::value_error(std::string(to_string(st)) +
                                     ": drift log-likelihood parameters rejected");
             }
             return s;
           }),
           py::kw_only(), py::arg("a1"), py::arg("a2"), py::arg("q"), py::arg("r"),
           py::arg("mean"))
      .def(
          "update",
          [](Stream& s, const py::array_t<double>& x, const py::object& innovations) {
            if (x.ndim() != 1) {
              throw py::value_error("DriftLoglikeStream.update: expected a 1-D array, got ndim=" +
                                    std::to_string(x.ndim()));
            }
            const auto n = static_cast<std::size_t>(x.shape(0));
            const std::ptrdiff_t stride = element_stride(x, "DriftLoglikeStream.update");
            double* innov = nullptr;
            std::ptrdiff_t innov_stride = 1;
            py::array_t<double> inn;
            if (!innovations.is_none()) {
              if (!py::isinstance<py::array_t<double>>(innovations) ||
                  !py::array(innovations).dtype().is(py::dtype::of<double>())) {
                throw py::type_error("DriftLoglikeStream.update: innovations must be float64");
              }
              inn = py::reinterpret_borrow<py::array_t<double>>(innovations);
              if (inn.ndim() != 1 || static_cast<std::size_t>(inn.shape(0)) != n) {
                throw py::value_error(
                    "DriftLoglikeStream.update: innovations must be 1-D with x's length");
              }
              if (!inn.writeable()) {
                throw py::value_error("DriftLoglikeStream.update: innovations is read-only");
              }
              innov = inn.mutable_data();
              innov_stride = element_stride(inn, "DriftLoglikeStream.update innovations");
            }
            Ar2Status st;
            {
              py::gil_scoped_release release;
              st = s.update(x.data(), n, stride, innov, innov_stride);
            }
            if (st != Ar2Status::ok) {
              throw py::value_error(std::string(to_string(st)) +
                                    ": drift log-likelihood piece of " + std::to_string(n) +
                                    " samples rejected");
            }
          },
          py::arg("x").noconvert(), py::arg("innovations") = py::none())
      .def("result", [](const Stream& s) {
        DriftLikelihoodSums<double> sums;
        const Ar2Status st = s.finish(sums);
        if (st != Ar2Status::ok) {
          throw py::value_error(std::string(to_string(st)) + ": drift log-likelihood rejected");
        }
        return sums_tuple(sums);
      });
}

}  // namespace

void bind_drift(py::module_& m) {
  def_loglike<double>(m);
  def_loglike<float>(m);
  def_stream(m);
  bind_online_drift(m);  // bind_online_drift.cpp: OnlineDriftIdentifier, OnlineDriftIdentifierF32
  bind_lag_statistics(m);  // bind_lag_statistics.cpp: LagStatistics, LagStatisticsF32
}

}  // namespace gyrodrift::py_bindings
