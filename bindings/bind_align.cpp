// Strapdown navigation and SINS alignment: whole-run entry points over numpy arrays
// of increments, so a Monte Carlo run costs one call with the GIL released.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <gyrodrift/nav/align_pipeline.hpp>
#include <gyrodrift/nav/coarse_align.hpp>
#include <gyrodrift/nav/strapdown.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

using Vec3 = Eigen::Matrix<double, 3, 1>;
using Mat3 = Eigen::Matrix<double, 3, 3>;
constexpr int kMaxTaps = 256;
constexpr int kMaxDelay = 32;

// Everything align_run needs besides the data, as one bound configuration object (Python:
// gyrodrift._core.AlignRunConfig, filled by gyrodrift.align.run_alignment from AlignConfig).
struct AlignRunConfig {
  AlignSettings<double> settings{};
  int n_states{15};
  std::vector<double> p0_diag, q_diag, r_diag, floor_diag;
  std::vector<double> taps;  // prefilter taps, oldest first (the pipeline's order); empty = off
};

std::size_t require_n3_pair(const CArray<double>& dtheta, const CArray<double>& dv) {
  if (dtheta.ndim() != 2 || dtheta.shape(1) != 3)
    throw py::value_error("dtheta: expected an (n, 3) float64 array of gyro angle increments (rad)");
  if (dv.ndim() != 2 || dv.shape(1) != 3)
    throw py::value_error("dv: expected an (n, 3) float64 array of velocity increments (m/s)");
  if (dtheta.shape(0) != dv.shape(0))
    throw py::value_error("dtheta and dv must have the same number of rows, got " +
                          std::to_string(dtheta.shape(0)) + " and " + std::to_string(dv.shape(0)));
  return static_cast<std::size_t>(dtheta.shape(0));
}

template <int N>
Eigen::Matrix<double, N, 1> vec_n(const std::vector<double>& a, const char* what) {
  if (a.size() != static_cast<std::size_t>(N))
    throw py::value_error(std::string(what) + ": expected " + std::to_string(N) + " values, got " +
                          std::to_string(a.size()));
  require_finite(a.data(), a.size(), what);
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v(i) = a[static_cast<std::size_t>(i)];
  return v;
}

template <int N>
Eigen::Matrix<double, N, 1> vec_n(const CArray<double>& a, const char* what) {
  if (a.ndim() != 1 || a.shape(0) != N)
    throw py::value_error(std::string(what) + ": expected a 1-D array of length " + std::to_string(N));
  require_finite(a.data(), static_cast<std::size_t>(N), what);
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v(i) = a.data()[i];
  return v;
}

template <int N>
py::dict run_pipeline(const CArray<double>& dtheta, const CArray<double>& dv,
                      const AlignRunConfig& c) {
  const AlignSettings<double>& s = c.settings;
  const std::vector<double>& taps = c.taps;
  const std::size_t n = require_n3_pair(dtheta, dv);
  const long n_taps = static_cast<long>(taps.size());
  const long warmup = n_taps > 0 ? std::max(n_taps - 1, static_cast<long>(s.accel_delay_samples))
                                 : static_cast<long>(s.accel_delay_samples);
  if (static_cast<long>(n) <= s.coarse_samples + warmup)
    throw py::value_error("need more samples (" + std::to_string(n) +
                          ") than the prefilter warm-up plus the coarse-alignment window (" +
                          std::to_string(warmup + s.coarse_samples) + ")");
  if (n_taps > kMaxTaps)
    throw py::value_error("taps: expected at most 256 prefilter taps (empty = off)");
  require_finite(taps.data(), taps.size(), "taps");
  if (s.accel_delay_samples < 0 || s.accel_delay_samples > kMaxDelay)
    throw py::value_error("accel_delay_samples must be in [0, 32]");
  auto pipe = std::make_unique<AlignPipeline<double, N, kMaxTaps, kMaxDelay>>();
  if (!pipe->reset(s, vec_n<N>(c.p0_diag, "p0_diag"), vec_n<N>(c.q_diag, "q_diag"),
                   vec_n<3>(c.r_diag, "r_diag"), vec_n<N>(c.floor_diag, "floor_diag"), taps.data(),
                   static_cast<int>(n_taps)))
    throw py::value_error("invalid alignment settings (dt_s > 0, coarse_samples >= 4, kf_every >= 1, "
                          "p0 and r > 0, q and floors >= 0)");
  const std::size_t n_kf = n / static_cast<std::size_t>(s.kf_every) + 1;
  std::vector<double> t_s, att, eb, db, p_phi;
  t_s.reserve(n_kf);
  att.reserve(3 * n_kf);
  eb.reserve(3 * n_kf);
  db.reserve(3 * n_kf);
  p_phi.reserve(3 * n_kf);
  const double* pt = dtheta.data();
  const double* pv = dv.data();
  bool failed = false;
  bool coarse_done = false;
  std::size_t failed_at = 0;
  {
    py::gil_scoped_release release;
    for (std::size_t k = 0; k < n; ++k) {
      const Vec3 g(pt[3 * k], pt[3 * k + 1], pt[3 * k + 2]);
      const Vec3 a(pv[3 * k], pv[3 * k + 1], pv[3 * k + 2]);
      const AlignStatus st = pipe->step(g, a);
      if (st == AlignStatus::kFailed) {
        failed = true;
        failed_at = k;
        break;
      }
      if (st == AlignStatus::kCoarseDone) coarse_done = true;
      if (st != AlignStatus::kKfUpdated) continue;
      // The solution refers to the delayed (prefilter-matched) instant.
      t_s.push_back(static_cast<double>(static_cast<long>(k) + 1 - s.accel_delay_samples) * s.dt_s);
      const Vec3 e = pipe->attitude();
      for (int i = 0; i < 3; ++i) {
        att.push_back(e(i));
        eb.push_back(pipe->gyro_drift()(i));
        db.push_back(pipe->accel_bias()(i));
        p_phi.push_back(std::sqrt(pipe->kf().P()(i, i)));
      }
    }
  }
  auto to_array = [](const std::vector<double>& v, py::ssize_t cols) {
    const py::ssize_t rows = static_cast<py::ssize_t>(v.size()) / cols;
    py::array_t<double> out(cols == 1 ? std::vector<py::ssize_t>{rows}
                                      : std::vector<py::ssize_t>{rows, cols});
    std::copy(v.begin(), v.end(), out.mutable_data());
    return out;
  };
  py::dict out;
  out["t_s"] = to_array(t_s, 1);
  out["att"] = to_array(att, 3);
  out["eb"] = to_array(eb, 3);
  out["db"] = to_array(db, 3);
  out["p_phi"] = to_array(p_phi, 3);
  py::array_t<double> cnb({3, 3});
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) cnb.mutable_at(i, j) = pipe->coarse_cnb()(i, j);
  out["coarse_cnb"] = cnb;
  // An alignment that never produced a solution failed, whatever the reason (an
  // all-NaN record once gave empty histories with failed=False).
  std::string reason;
  const auto bad = static_cast<std::size_t>(pipe->bad_samples());
  if (failed) {
    reason = "numerics failed at sample " + std::to_string(failed_at) +
             " (coarse solve, strapdown or Kalman update not finite)";
  } else if (t_s.empty()) {
    failed = true;
    if (bad == n) {
      reason = "all " + std::to_string(n) + " samples are NaN/Inf";
    } else if (!coarse_done) {
      reason = "only " + std::to_string(n - bad) + " of " + std::to_string(n) +
               " samples are finite: too few for the prefilter warm-up plus the coarse window (" +
               std::to_string(warmup + s.coarse_samples) + ")";
    } else {
      reason = "no Kalman update after the coarse window: " + std::to_string(bad) + " of " +
               std::to_string(n) + " samples are NaN/Inf";
    }
  }
  out["bad_samples"] = pipe->bad_samples();
  out["failed"] = failed;
  out["reason"] = reason;
  return out;
}

}  // namespace

void bind_align(py::module_& m) {
  py::class_<AlignSettings<double>>(m, "AlignSettings",
                                    "Scalar settings of the alignment pipeline (AlignSettings<double>).")
      .def(py::init<>())
      .def_readwrite("dt_s", &AlignSettings<double>::dt_s)
      .def_readwrite("lat_rad", &AlignSettings<double>::lat_rad)
      .def_readwrite("lon_rad", &AlignSettings<double>::lon_rad)
      .def_readwrite("h_m", &AlignSettings<double>::h_m)
      .def_readwrite("coarse_samples", &AlignSettings<double>::coarse_samples)
      .def_readwrite("coarse_position_integral", &AlignSettings<double>::coarse_position_integral)
      .def_readwrite("kf_every", &AlignSettings<double>::kf_every)
      .def_readwrite("accel_delay_samples", &AlignSettings<double>::accel_delay_samples)
      .def_readwrite("heading_stage_cycles", &AlignSettings<double>::heading_stage_cycles)
      .def_readwrite("heading_stage_q", &AlignSettings<double>::heading_stage_q);
  py::class_<AlignRunConfig>(m, "AlignRunConfig",
                             "Settings, state count, KF diagonals and prefilter taps of align_run.")
      .def(py::init<>())
      .def_readwrite("settings", &AlignRunConfig::settings)
      .def_readwrite("n_states", &AlignRunConfig::n_states)
      .def_readwrite("p0_diag", &AlignRunConfig::p0_diag)
      .def_readwrite("q_diag", &AlignRunConfig::q_diag)
      .def_readwrite("r_diag", &AlignRunConfig::r_diag)
      .def_readwrite("floor_diag", &AlignRunConfig::floor_diag)
      .def_readwrite("taps", &AlignRunConfig::taps);

  m.def(
      "align_run",
      [](const CArray<double>& dtheta, const CArray<double>& dv, const AlignRunConfig& c) -> py::dict {
        const AlignSettings<double>& s = c.settings;
        if (s.heading_stage_cycles < 0 || !(s.heading_stage_q >= 0.0) ||
            !std::isfinite(s.heading_stage_q))
          throw py::value_error("heading_stage_cycles must be >= 0 and heading_stage_q finite >= 0");
        if (!(s.dt_s > 0.0)) throw py::value_error("dt_s must be > 0");
        if (c.n_states == 15) return run_pipeline<15>(dtheta, dv, c);
        if (c.n_states == 12) return run_pipeline<12>(dtheta, dv, c);
        throw py::value_error("n_states must be 12 or 15, got " + std::to_string(c.n_states));
      },
      py::arg("dtheta").noconvert(), py::arg("dv").noconvert(), py::arg("config"),
      "Whole alignment (prefilter, coarse, strapdown + fine KF) over (n, 3) float64 increments "
      "with an AlignRunConfig; GIL released. gyrodrift.align.run_alignment is the wrapper.");

  m.def(
      "strapdown_run",
      [](const CArray<double>& dtheta, const CArray<double>& dv, double dt_s,
         const CArray<double>& q0, const CArray<double>& v0, const CArray<double>& pos0) {
        const std::size_t n = require_n3_pair(dtheta, dv);
        if (!(dt_s > 0.0)) throw py::value_error("dt_s must be > 0");
        Strapdown<double> sd;
        const Eigen::Matrix<double, 4, 1> q = vec_n<4>(q0, "q0");
        sd.reset(q, vec_n<3>(v0, "v0"), vec_n<3>(pos0, "pos0"));
        py::array_t<double> q_out({static_cast<py::ssize_t>(n), py::ssize_t{4}});
        py::array_t<double> v_out({static_cast<py::ssize_t>(n), py::ssize_t{3}});
        double* qo = q_out.mutable_data();
        double* vo = v_out.mutable_data();
        const double* pt = dtheta.data();
        const double* pv = dv.data();
        long bad = 0;
        {
          py::gil_scoped_release release;
          Vec3 dvn;
          for (std::size_t k = 0; k < n; ++k) {
            if (!sd.step(Vec3(pt[3 * k], pt[3 * k + 1], pt[3 * k + 2]),
                         Vec3(pv[3 * k], pv[3 * k + 1], pv[3 * k + 2]), dt_s, dvn))
              ++bad;
            for (int i = 0; i < 4; ++i) qo[4 * k + static_cast<std::size_t>(i)] = sd.q()(i);
            for (int i = 0; i < 3; ++i) vo[3 * k + static_cast<std::size_t>(i)] = sd.vn()(i);
          }
        }
        py::array_t<double> p_out(3);
        for (int i = 0; i < 3; ++i) p_out.mutable_at(i) = sd.pos()(i);
        return py::make_tuple(q_out, v_out, p_out, bad);
      },
      py::arg("dtheta").noconvert(), py::arg("dv").noconvert(), py::arg("dt_s"),
      py::arg("q0").noconvert(), py::arg("v0").noconvert(), py::arg("pos0").noconvert(),
      "ENU strapdown over (n, 3) increments; returns (q history (n, 4), v history (n, 3), "
      "final [lat, lon, h], number of skipped non-finite samples).");

  m.def(
      "coarse_align",
      [](const CArray<double>& dtheta, const CArray<double>& dv, double dt_s, double lat_rad,
         double h_m, bool position_integral) {
        const std::size_t n = require_n3_pair(dtheta, dv);
        InertialCoarseAlign<double> c;
        if (!c.reset(static_cast<long>(n), dt_s, lat_rad, h_m, position_integral))
          throw py::value_error("coarse alignment needs dt_s > 0 and at least 4 samples");
        const double* pt = dtheta.data();
        const double* pv = dv.data();
        Mat3 cnb;
        bool ok = true;
        {
          py::gil_scoped_release release;
          for (std::size_t k = 0; k < n && ok; ++k)
            ok = c.add(Vec3(pt[3 * k], pt[3 * k + 1], pt[3 * k + 2]),
                       Vec3(pv[3 * k], pv[3 * k + 1], pv[3 * k + 2]));
          ok = ok && c.solve(cnb);
        }
        if (!ok)
          throw py::value_error("coarse alignment failed: non-finite sample or degenerate "
                                "(parallel) gravity vectors");
        py::array_t<double> out({3, 3});
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) out.mutable_at(i, j) = cnb(i, j);
        return out;
      },
      py::arg("dtheta").noconvert(), py::arg("dv").noconvert(), py::arg("dt_s"),
      py::arg("lat_rad"), py::arg("h_m"), py::arg("position_integral") = true,
      "Inertial-frame coarse alignment over the whole (n, 3) window; returns C_b^n at its end.");
}

}  // namespace gyrodrift::py_bindings
