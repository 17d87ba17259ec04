// Health alarms (include/gyrodrift/imu/health_alarms.hpp) over a whole record, the model Allan
// variance (include/gyrodrift/stability/model_allan.hpp) and the target's edf and chi-square
// quantiles (include/gyrodrift/stability/allan_chi2.hpp), for gyrodrift.stability.health,
// gyrodrift.stability.model_allan and gyrodrift.stability.online_noise (part of the allan area):
//   HealthAlarmSettings()                        fields of the C++ settings (defaults from it)
//   HealthAlarms(rate_hz, reference_avar, settings) / HealthAlarmsF32(...)
//       a StreamingAllan and the alarms of one channel; run(y, stuck, saturated, every)
//       pushes every sample, updates the alarms and returns the latched bits after every
//       `every`-th sample (GIL released, object lock held)
//   ar2_white_avar(a1, a2, q, r, n_octaves), ieee952_avar(q, n, b, k, tau_s)
//   nonoverlapped_edf(noise, n, m), normal_quantile(p), chi2_quantile_wh(nu, z)
#include <gyrodrift/imu/health_alarms.hpp>
#include <gyrodrift/stability/allan_chi2.hpp>
#include <gyrodrift/stability/model_allan.hpp>
#include <gyrodrift/stability/online_noise.hpp>
#include <gyrodrift/stability/streaming_allan.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

template <class Scalar>
py::tuple noise_tuple(bool ok, const NoiseEstimates<Scalar>& e);  // bind_streaming_allan.cpp

namespace {

constexpr std::size_t kMaxOctaves = 40;

void check_settings(const HealthAlarmSettings<double>& s) {
  const double f[3] = {s.arw_factor, s.bias_instability_factor, s.rate_random_walk_factor};
  const char* names[3] = {"arw_factor", "bias_instability_factor", "rate_random_walk_factor"};
  for (int i = 0; i < 3; ++i) {
    if (!(f[i] >= 1.0) || !std::isfinite(f[i])) {
      throw py::value_error(std::string(names[i]) + " must be a finite number >= 1, got " +
                            std::to_string(f[i]));
    }
  }
  if (!(s.false_alarm_probability > 0.0) || !(s.false_alarm_probability <= 0.5)) {
    throw py::value_error("false_alarm_probability must lie in (0, 0.5], got " +
                          std::to_string(s.false_alarm_probability));
  }
  if (s.block_terms < 4) {
    throw py::value_error("block_terms must be >= 4, got " + std::to_string(s.block_terms));
  }
}

template <class Scalar>
class HealthAlarmsPy {
 public:
  HealthAlarmsPy(double rate_hz, const CArray<double>& reference_avar,
                 const HealthAlarmSettings<double>& settings, const py::object& edf_per_term) {
    if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
      throw py::value_error("rate_hz must be a positive finite number, got " + std::to_string(rate_hz));
    }
    if (reference_avar.ndim() != 1 || reference_avar.shape(0) < 1 ||
        reference_avar.shape(0) > static_cast<py::ssize_t>(kMaxOctaves)) {
      throw py::value_error("reference_avar: expected a 1-D array of 1.." + std::to_string(kMaxOctaves) +
                            " octaves");
    }
    check_settings(settings);
    const auto n = static_cast<std::size_t>(reference_avar.shape(0));
    HealthReference<Scalar, kMaxOctaves> ref{};
    for (std::size_t k = 0; k < n; ++k) {
      const double v = reference_avar.data()[k];
      if (!(v > 0.0) || !std::isfinite(v)) {
        throw py::value_error("reference_avar must be positive and finite, got " + std::to_string(v) +
                              " at octave " + std::to_string(k));
      }
      ref.avar[k] = static_cast<Scalar>(v);
    }
    ref.octaves = n;
    if (!edf_per_term.is_none()) {
      const auto e = py::cast<CArray<double>>(edf_per_term);
      if (e.ndim() != 1 || static_cast<std::size_t>(e.shape(0)) != n) {
        throw py::value_error("edf_per_term: expected one value per octave of reference_avar");
      }
      for (std::size_t k = 0; k < n; ++k) {
        const double v = e.data()[k];
        if (!(v >= 0.0) || v > 1.0) {
          throw py::value_error("edf_per_term must lie in [0, 1], got " + std::to_string(v));
        }
        ref.edf_per_term[k] = static_cast<Scalar>(v);
      }
    }
    HealthAlarmSettings<Scalar> s{};
    s.arw_factor = static_cast<Scalar>(settings.arw_factor);
    s.bias_instability_factor = static_cast<Scalar>(settings.bias_instability_factor);
    s.rate_random_walk_factor = static_cast<Scalar>(settings.rate_random_walk_factor);
    s.false_alarm_probability = static_cast<Scalar>(settings.false_alarm_probability);
    s.stuck_samples = settings.stuck_samples;
    s.saturated_samples = settings.saturated_samples;
    s.block_terms = settings.block_terms;
    if (!allan_.configure(static_cast<Scalar>(rate_hz), n) || !alarms_.configure(ref, s)) {
      throw py::value_error("the reference or the settings are out of range for this precision");
    }
  }

  // Latched bits after every `every`-th sample (and after the last one).
  py::array_t<std::uint16_t> run(const CArray<Scalar>& y, const py::object& stuck,
                                 const py::object& saturated, std::int64_t every) {
    if (y.ndim() != 1) throw py::value_error("y: expected a 1-D array, got ndim=" + std::to_string(y.ndim()));
    if (every < 1) throw py::value_error("every must be >= 1, got " + std::to_string(every));
    const auto n = static_cast<std::size_t>(y.shape(0));
    CArray<bool> st;
    CArray<bool> sa;
    const bool* st_p = flags(stuck, n, "stuck", st);
    const bool* sa_p = flags(saturated, n, "saturated", sa);
    const auto step = static_cast<std::size_t>(every);
    const std::size_t n_out = n == 0 ? 0 : (n + step - 1) / step;
    py::array_t<std::uint16_t> out(static_cast<py::ssize_t>(n_out));
    std::uint16_t* o = out.mutable_data();
    const Scalar* d = y.data();
    {
      ReleasedAndLocked guard(this);
      std::size_t j = 0;
      for (std::size_t i = 0; i < n; ++i) {
        alarms_.push(allan_, d[i], st_p != nullptr && st_p[i], sa_p != nullptr && sa_p[i]);
        const std::uint16_t bits = alarms_.latched();
        if ((i + 1) % step == 0 || i + 1 == n) o[j++] = bits;
      }
    }
    return out;
  }

  py::tuple estimate_noise(double coverage) const {
    NoiseEstimates<Scalar> e{};
    bool ok = false;
    {
      ReleasedAndLocked guard(this);
      ok = gyrodrift::estimate_noise(allan_, static_cast<Scalar>(coverage), e);
    }
    return noise_tuple(ok, e);
  }

  void reset() {
    ReleasedAndLocked guard(this);
    allan_.reset();
    alarms_.reset();
  }
  void unlatch() {
    ReleasedAndLocked guard(this);
    alarms_.unlatch();
  }
  std::uint16_t latched() const { return alarms_.latched(); }
  py::list counts(bool exceed) const {
    py::list out;
    for (std::size_t i = 0; i < kHealthAlarmCount; ++i) {
      out.append(exceed ? alarms_.exceedances(i) : alarms_.raised(i));
    }
    return out;
  }
  py::list trips() const {
    py::list out;
    for (std::size_t i = 0; i < kHealthAlarmCount; ++i) {
      const auto& t = alarms_.trip(i);
      out.append(py::make_tuple(static_cast<double>(t.statistic), static_cast<double>(t.threshold),
                                static_cast<double>(t.tau_s), static_cast<std::int64_t>(t.sample)));
    }
    return out;
  }
  py::list octave_alarms() const {
    py::list out;
    for (std::size_t k = 0; k < alarms_.reference().octaves; ++k) out.append(alarms_.octave_alarm(k));
    return out;
  }
  py::array_t<double> avar() const {
    const std::size_t n = allan_.octaves();
    py::array_t<double> out(static_cast<py::ssize_t>(n));
    double* o = out.mutable_data();
    for (std::size_t k = 0; k < n; ++k) {
      Scalar v{0};
      o[k] = allan_.avar(k, v) ? static_cast<double>(v) : std::nan("");
    }
    return out;
  }
  std::int64_t samples() const { return static_cast<std::int64_t>(allan_.samples()); }
  std::int64_t state_bytes() const {
    return static_cast<std::int64_t>(sizeof(HealthAlarms<Scalar, kMaxOctaves>));
  }

 private:
  static const bool* flags(const py::object& obj, std::size_t n, const char* what, CArray<bool>& keep) {
    if (obj.is_none()) return nullptr;
    keep = py::cast<CArray<bool>>(obj);
    if (keep.ndim() != 1 || static_cast<std::size_t>(keep.shape(0)) != n) {
      throw py::value_error(std::string(what) + ": expected a 1-D bool array of the length of y");
    }
    return keep.data();
  }

  StreamingAllan<Scalar, kMaxOctaves> allan_{};
  HealthAlarms<Scalar, kMaxOctaves> alarms_{};
};

template <class Scalar>
void bind_alarms(py::module_& m, const char* name, const char* doc) {
  using T = HealthAlarmsPy<Scalar>;
  py::class_<T>(m, name, doc)
      .def(py::init<double, const CArray<double>&, const HealthAlarmSettings<double>&, const py::object&>(),
           py::arg("rate_hz"), py::arg("reference_avar"), py::arg("settings"),
           py::arg("edf_per_term") = py::none())
      .def("run", &T::run, py::arg("y").noconvert(), py::arg("stuck") = py::none(),
           py::arg("saturated") = py::none(), py::arg("every") = 1,
           "Push the samples and update the alarms after each; the latched bits after every "
           "`every`-th sample and after the last. GIL released.")
      .def("estimate_noise", &T::estimate_noise, py::arg("coverage"))
      .def("reset", &T::reset)
      .def("unlatch", &T::unlatch)
      .def_property_readonly("latched", &T::latched)
      .def_property_readonly("raised", [](const T& t) { return t.counts(false); })
      .def_property_readonly("exceedances", [](const T& t) { return t.counts(true); })
      .def_property_readonly("trips", &T::trips, "(statistic, threshold, tau_s, sample) per alarm")
      .def_property_readonly("octave_alarms", &T::octave_alarms)
      .def_property_readonly("avar", &T::avar)
      .def_property_readonly("samples", &T::samples)
      .def_property_readonly("state_bytes", &T::state_bytes,
                             "sizeof the C++ HealthAlarms at this precision and 40 octaves");
}

py::array_t<double> ar2_white_avar_py(double a1, double a2, double q, double r, std::int64_t n_octaves) {
  if (n_octaves < 1 || n_octaves > 60) {
    throw py::value_error("n_octaves must be in 1..60, got " + std::to_string(n_octaves));
  }
  py::array_t<double> out(static_cast<py::ssize_t>(n_octaves));
  if (!ar2_white_avar<double>(a1, a2, q, r, static_cast<std::size_t>(n_octaves), out.mutable_data())) {
    throw py::value_error("the model needs a stationary AR(2), finite q >= 0 and r >= 0, q + r > 0");
  }
  return out;
}

py::array_t<double> ar2_white_edf_py(double a1, double a2, double q, double r, std::int64_t n_octaves,
                                     std::int64_t n) {
  if (n_octaves < 1 || n_octaves > 60 || n < 1 || n > 1000000) {
    throw py::value_error("n_octaves must be in 1..60 and n in 1..1000000");
  }
  py::array_t<double> out(static_cast<py::ssize_t>(n_octaves));
  double* o = out.mutable_data();
  bool ok = false;
  {
    py::gil_scoped_release release;
    ok = ar2_white_edf_per_term<double>(a1, a2, q, r, static_cast<std::size_t>(n_octaves),
                                        static_cast<std::uint32_t>(n), o);
  }
  if (!ok) throw py::value_error("the model needs a stationary AR(2), finite q >= 0 and r >= 0, q + r > 0");
  return out;
}

}  // namespace

void bind_health(py::module_& m) {
  py::class_<HealthAlarmSettings<double>>(m, "HealthAlarmSettings",
                                          "Settings of the health alarms (defaults from the C++ struct).")
      .def(py::init<>())
      .def_readwrite("arw_factor", &HealthAlarmSettings<double>::arw_factor)
      .def_readwrite("bias_instability_factor", &HealthAlarmSettings<double>::bias_instability_factor)
      .def_readwrite("rate_random_walk_factor", &HealthAlarmSettings<double>::rate_random_walk_factor)
      .def_readwrite("false_alarm_probability", &HealthAlarmSettings<double>::false_alarm_probability)
      .def_readwrite("stuck_samples", &HealthAlarmSettings<double>::stuck_samples)
      .def_readwrite("saturated_samples", &HealthAlarmSettings<double>::saturated_samples)
      .def_readwrite("block_terms", &HealthAlarmSettings<double>::block_terms);
  bind_alarms<double>(m, "HealthAlarms", "A streaming Allan variance and the health alarms of one channel, double state.");
  bind_alarms<float>(m, "HealthAlarmsF32", "HealthAlarms with float state, as on the target.");
  m.def("ar2_white_avar", &ar2_white_avar_py, py::arg("a1"), py::arg("a2"), py::arg("q"), py::arg("r"),
        py::arg("n_octaves"), "Expected Allan variance of AR(2) drift + white noise at m = 2^k.");
  m.def("ar2_white_edf_per_term", &ar2_white_edf_py, py::arg("a1"), py::arg("a2"), py::arg("q"), py::arg("r"),
        py::arg("n_octaves"), py::arg("n"), "edf per term of n squared differences at m = 2^k under the model.");
  m.def("ieee952_avar", &ieee952_avar<double>, py::arg("q_angle"), py::arg("n"), py::arg("b"), py::arg("k"),
        py::arg("tau_s"));
  m.def(
      "nonoverlapped_edf",
      [](int noise, std::int64_t n, std::int64_t mm, bool f32) {
        if (noise < 0 || noise > 2 || n < 0 || mm < 1) throw py::value_error("noise 0..2, n >= 0, m >= 1");
        const auto nz = static_cast<AllanNoise>(noise);
        const auto un = static_cast<std::uint64_t>(n);
        const auto um = static_cast<std::uint64_t>(mm);
        return f32 ? static_cast<double>(nonoverlapped_edf<float>(nz, un, um))
                   : nonoverlapped_edf<double>(nz, un, um);
      },
      py::arg("noise"), py::arg("n"), py::arg("m"), py::arg("f32") = false);
  m.def(
      "normal_quantile",
      [](double p, bool f32) {
        return f32 ? static_cast<double>(normal_quantile<float>(static_cast<float>(p))) : normal_quantile<double>(p);
      },
      py::arg("p"), py::arg("f32") = false);
  m.def(
      "chi2_quantile_wh",
      [](double nu, double z, bool f32) {
        return f32 ? static_cast<double>(chi2_quantile_wh<float>(static_cast<float>(nu), static_cast<float>(z)))
                   : chi2_quantile_wh<double>(nu, z);
      },
      py::arg("nu"), py::arg("z"), py::arg("f32") = false);
}

}  // namespace gyrodrift::py_bindings
