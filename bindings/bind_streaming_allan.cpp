// Streaming octave Allan variance (include/gyrodrift/stability/streaming_allan.hpp) for
// gyrodrift.stability.streaming (part of the allan area):
//   StreamingAllan(rate_hz, n_octaves)      double state, push(float64 array)
//   StreamingAllanF32(rate_hz, n_octaves)   float state (as on the target), push(float32 array)
// Both: push(y) -> samples accepted (non-finite ones are counted in `rejected` and skipped),
// tau_s, avar (NaN where an octave has no term yet), counts (terms per octave), samples,
// rejected, reset(), estimate_noise(coverage) (include/gyrodrift/stability/online_noise.hpp:
// (ok, n, b, k, b_tau_s), each term a tuple (value, lo, hi, valid, upper_limit)).
// push releases the GIL and takes the object's lock.
#include <gyrodrift/stability/online_noise.hpp>
#include <gyrodrift/stability/streaming_allan.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

constexpr std::size_t kMaxOctaves = 40;

template <class Scalar>
py::tuple term_tuple(const NoiseTermEstimate<Scalar>& t) {
  return py::make_tuple(static_cast<double>(t.value), static_cast<double>(t.lo),
                        static_cast<double>(t.hi), t.valid, t.upper_limit);
}

}  // namespace

template <class Scalar>
py::tuple noise_tuple(bool ok, const NoiseEstimates<Scalar>& e) {
  return py::make_tuple(ok, term_tuple(e.n), term_tuple(e.b), term_tuple(e.k),
                        static_cast<double>(e.b_tau_s));
}
template py::tuple noise_tuple<double>(bool, const NoiseEstimates<double>&);
template py::tuple noise_tuple<float>(bool, const NoiseEstimates<float>&);

namespace {

template <class Scalar>
class StreamingAllanPy {
 public:
  StreamingAllanPy(double rate_hz, std::int64_t n_octaves) {
    if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
      throw py::value_error("rate_hz must be a positive finite number, got " +
                            std::to_string(rate_hz));
    }
    if (n_octaves < 1 || n_octaves > static_cast<std::int64_t>(kMaxOctaves)) {
      throw py::value_error("n_octaves must be in 1.." + std::to_string(kMaxOctaves) + ", got " +
                            std::to_string(n_octaves));
    }
    if (!core_.configure(static_cast<Scalar>(rate_hz), static_cast<std::size_t>(n_octaves))) {
      throw py::value_error("rate_hz is out of range for this precision");
    }
  }

  std::int64_t push(const CArray<Scalar>& y) {
    if (y.ndim() != 1) {
      throw py::value_error("y: expected a 1-D array, got ndim=" + std::to_string(y.ndim()));
    }
    const auto n = static_cast<std::size_t>(y.shape(0));
    const Scalar* data = y.data();
    std::size_t accepted = 0;
    {
      ReleasedAndLocked guard(this);
      accepted = core_.push(data, n);
    }
    return static_cast<std::int64_t>(accepted);
  }

  void reset() {
    ReleasedAndLocked guard(this);
    core_.reset();
  }

  py::array_t<double> tau_s() const {
    py::array_t<double> out(static_cast<py::ssize_t>(core_.octaves()));
    double* o = out.mutable_data();
    for (std::size_t k = 0; k < core_.octaves(); ++k) {
      o[k] = static_cast<double>(core_.tau_s(k));
    }
    return out;
  }

  py::array_t<double> avar() const {
    const std::size_t n = core_.octaves();
    py::array_t<double> out(static_cast<py::ssize_t>(n));
    double* o = out.mutable_data();
    {
      ReleasedAndLocked guard(this);
      for (std::size_t k = 0; k < n; ++k) {
        Scalar v{0};
        o[k] = core_.avar(k, v) ? static_cast<double>(v) : std::numeric_limits<double>::quiet_NaN();
      }
    }
    return out;
  }

  py::array_t<std::int64_t> counts() const {
    const std::size_t n = core_.octaves();
    py::array_t<std::int64_t> out(static_cast<py::ssize_t>(n));
    std::int64_t* o = out.mutable_data();
    {
      ReleasedAndLocked guard(this);
      for (std::size_t k = 0; k < n; ++k) o[k] = static_cast<std::int64_t>(core_.terms(k));
    }
    return out;
  }

  std::int64_t samples() const {
    ReleasedAndLocked guard(this);
    return static_cast<std::int64_t>(core_.samples());
  }

  std::int64_t rejected() const {
    ReleasedAndLocked guard(this);
    return static_cast<std::int64_t>(core_.rejected());
  }

  std::int64_t n_octaves() const { return static_cast<std::int64_t>(core_.octaves()); }

  py::tuple estimate_noise(double coverage) const {
    NoiseEstimates<Scalar> e{};
    bool ok = false;
    {
      ReleasedAndLocked guard(this);
      ok = gyrodrift::estimate_noise(core_, static_cast<Scalar>(coverage), e);
    }
    return noise_tuple(ok, e);
  }

 private:
  StreamingAllan<Scalar, kMaxOctaves> core_{};
};

template <class Scalar>
void bind_one(py::module_& m, const char* name, const char* doc) {
  using T = StreamingAllanPy<Scalar>;
  py::class_<T>(m, name, doc)
      .def(py::init<double, std::int64_t>(), py::arg("rate_hz"), py::arg("n_octaves"))
      .def("push", &T::push, py::arg("y").noconvert(),
           "Push rate samples (1-D, C-contiguous); returns how many were accepted "
           "(non-finite ones are skipped and counted in `rejected`). GIL released.")
      .def("reset", &T::reset, "Forget every sample (keeps rate_hz and n_octaves).")
      .def_property_readonly("tau_s", &T::tau_s, "tau0 * 2^k, k = 0..n_octaves-1 (s)")
      .def_property_readonly("avar", &T::avar,
                             "non-overlapped Allan variance per octave ((rate units)^2; NaN "
                             "before the octave has two clusters)")
      .def_property_readonly("counts", &T::counts,
                             "squared differences per octave: floor(N / 2^k) - 1")
      .def_property_readonly("samples", &T::samples)
      .def_property_readonly("rejected", &T::rejected)
      .def_property_readonly("n_octaves", &T::n_octaves)
      .def("estimate_noise", &T::estimate_noise, py::arg("coverage"),
           "IEEE 952 N, B, K read from the curve so far with intervals at `coverage`: "
           "(ok, n, b, k, b_tau_s), each term (value, lo, hi, valid, upper_limit).");
}

}  // namespace

void bind_streaming_allan(pybind11::module_& m) {
  bind_one<double>(m, "StreamingAllan",
                   "Streaming non-overlapped Allan variance at tau0 * 2^k (cascaded pairwise "
                   "cluster means, compensated sums), double state; push(float64 array).");
  bind_one<float>(m, "StreamingAllanF32",
                  "StreamingAllan with float state, as on the target; push(float32 array).");
}

}  // namespace gyrodrift::py_bindings
