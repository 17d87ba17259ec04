// The gyro monitor (include/gyrodrift/imu/gyro_monitor.hpp) over whole records, for
// gyrodrift.imu.monitor (part of the imu area):
//   GyroMonitorSettings(*, rate_hz, octaves, arw_factor, bias_instability_factor,
//       rate_random_walk_factor, false_alarm_probability, stuck_samples, saturated_samples,
//       reidentify, block_samples, retune_blocks, min_samples, memory_blocks, max_step,
//       max_rel_stderr, adapt_ar, min_ar_wald, identifier, fit_delay_samples, restart_after_fit)
//                                             durations in samples (the caller converts seconds);
//       identifier "recursive" (online_drift_identifier.hpp) or "lag" (lag_drift_identifier.hpp)
//   GyroMonitorRun(settings, model, reference_avar, reference_edf)      double state
//   GyroMonitorRunF32(settings, model, reference_avar, reference_edf)   float state, as on the target
//     model: (a1, a2, q, r, mean); reference_avar: expected Allan variance per octave;
//     reference_edf: edf per term of the alarms' block test per octave (0: from the slope)
//     .run(y, stuck, saturated, report_every, coverage) -> dict of per-report arrays (the lag
//       identifier's fit status and paused samples too: -1 and 0 with the recursive one)
//     .latched(y, stuck, saturated) -> u16 latched alarm bits after each sample
//     .trips() -> {alarm name: {statistic, threshold, tau_s, sample}} for the raised alarms
//     .reset()
// run() releases the GIL and takes the object's lock; it continues from the state the last
// run() left (a record may come in pieces).
#include <gyrodrift/imu/gyro_monitor.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

constexpr std::size_t kMonitorOctaves = 40;

struct MonitorSettingsPy {
  double rate_hz = 0.0;
  std::int64_t octaves = 0;
  double arw_factor = 2.0;
  double bias_instability_factor = 2.0;
  double rate_random_walk_factor = 2.0;
  double false_alarm_probability = 1e-6;
  std::int64_t stuck_samples = 0;
  std::int64_t saturated_samples = 0;
  bool reidentify = false;
  std::int64_t block_samples = 400;
  std::int64_t retune_blocks = 60;
  std::int64_t min_samples = 240000;
  double memory_blocks = 0.0;
  double max_step = 0.1;
  double max_rel_stderr = 0.5;
  bool adapt_ar = true;  // false: a1, a2 held, q and r tracked
  double min_ar_wald = static_cast<double>(OnlineDriftSettings<double>{}.min_ar_wald);
  std::string identifier = "recursive";  // or "lag"
  std::int64_t fit_delay_samples = LagDriftSettings<double>{}.fit_delay_samples;
  bool restart_after_fit = LagDriftSettings<double>{}.restart_after_fit;

  void check() const {
    auto bad = [](const std::string& what) { throw py::value_error("GyroMonitorSettings." + what); };
    if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) bad("rate_hz: expected a positive finite number");
    if (octaves < 1 || octaves > static_cast<std::int64_t>(kMonitorOctaves)) {
      bad("octaves: expected 1.." + std::to_string(kMonitorOctaves) + ", got " + std::to_string(octaves));
    }
    for (double f : {arw_factor, bias_instability_factor, rate_random_walk_factor}) {
      if (!(f > 1.0) || !std::isfinite(f)) bad("*_factor: expected a finite number > 1");
    }
    if (!(false_alarm_probability > 0.0 && false_alarm_probability < 1.0)) {
      bad("false_alarm_probability: expected 0 < p < 1");
    }
    const auto u32 = static_cast<std::int64_t>(std::numeric_limits<std::uint32_t>::max());
    if (stuck_samples < 0 || stuck_samples > u32) bad("stuck_samples: expected 0..2^32-1");
    if (saturated_samples < 0 || saturated_samples > u32) bad("saturated_samples: expected 0..2^32-1");
    if (block_samples < 8 || block_samples > u32) bad("block_samples: expected 8..2^32-1");
    if (retune_blocks < 1 || retune_blocks > u32) bad("retune_blocks: expected 1..2^32-1");
    if (min_samples < 0) bad("min_samples: expected >= 0");
    if (!(memory_blocks == 0.0 || memory_blocks >= 1.0) || !std::isfinite(memory_blocks)) {
      bad("memory_blocks: expected 0 or a finite number >= 1");
    }
    if (!(max_step > 0.0) || !std::isfinite(max_step)) bad("max_step: expected a finite number > 0");
    if (!(max_rel_stderr > 0.0) || !std::isfinite(max_rel_stderr)) bad("max_rel_stderr: expected a finite number > 0");
    if (!(min_ar_wald >= 0.0) || !std::isfinite(min_ar_wald)) bad("min_ar_wald: expected a finite number >= 0");
    if (identifier != "recursive" && identifier != "lag") {
      bad("identifier: expected 'recursive' or 'lag', got '" + identifier + "'");
    }
    if (fit_delay_samples < 0 || fit_delay_samples > u32) bad("fit_delay_samples: expected 0..2^32-1");
  }

  DriftIdentifierKind kind() const { return identifier == "lag" ? DriftIdentifierKind::lag : DriftIdentifierKind::recursive; }

  template <class Scalar>
  GyroMonitorSettings<Scalar> to_core() const {
    check();
    GyroMonitorSettings<Scalar> s;
    s.sample_rate_hz = static_cast<Scalar>(rate_hz);
    s.octaves = static_cast<std::size_t>(octaves);
    s.alarms.arw_factor = static_cast<Scalar>(arw_factor);
    s.alarms.bias_instability_factor = static_cast<Scalar>(bias_instability_factor);
    s.alarms.rate_random_walk_factor = static_cast<Scalar>(rate_random_walk_factor);
    s.alarms.false_alarm_probability = static_cast<Scalar>(false_alarm_probability);
    s.alarms.stuck_samples = static_cast<std::uint32_t>(stuck_samples);
    s.alarms.saturated_samples = static_cast<std::uint32_t>(saturated_samples);
    s.reidentify = reidentify;
    s.drift.block_samples = static_cast<std::uint32_t>(block_samples);
    s.drift.retune_blocks = static_cast<std::uint32_t>(retune_blocks);
    s.drift.min_samples = static_cast<std::uint64_t>(min_samples);
    s.drift.memory_blocks = static_cast<Scalar>(memory_blocks);
    s.drift.max_step = static_cast<Scalar>(max_step);
    s.drift.max_rel_stderr = static_cast<Scalar>(max_rel_stderr);
    s.drift.adapt_ar = adapt_ar;
    s.drift.min_ar_wald = static_cast<Scalar>(min_ar_wald);
    s.identifier = kind();
    s.lag.fit_delay_samples = static_cast<std::uint32_t>(fit_delay_samples);
    s.lag.restart_after_fit = restart_after_fit;
    return s;
  }
};

// The monitor of one settings object: with the recursive re-identification or with the lag
// one (GyroMonitor's Kind: the build choice of a target, a run-time choice here).
template <class Scalar>
class AnyMonitor {
 public:
  using Rec = GyroMonitor<Scalar, kMonitorOctaves>;
  using Lag = GyroMonitor<Scalar, kMonitorOctaves, true, true, DriftIdentifierKind::lag>;
  using Reference = typename Rec::Reference;
  static_assert(std::is_same_v<Reference, typename Lag::Reference>, "one reference type");

  // The identifier's state a report row shows.
  struct IdView {
    DriftModelParams<Scalar> use{}, est{};
    Scalar gain0{0}, gain1{0};
    int status = 0;
    std::uint32_t retunes = 0, refused = 0;
    int fit_status = -1;  // the lag identifier's last applied fit (-1: the recursive one)
    std::uint64_t paused = 0;
    std::uint32_t late_fits = 0;
  };

  GyroMonitorStatus configure(const GyroMonitorSettings<Scalar>& s, const DriftModelParams<Scalar>& p,
                              const Reference& ref) {
    rec_.reset();
    lag_.reset();
    if (s.identifier == DriftIdentifierKind::lag) {
      lag_.emplace();
      return lag_->configure(s, p, ref);
    }
    rec_.emplace();
    return rec_->configure(s, p, ref);
  }

  template <class F>
  auto with(F&& f) -> decltype(f(std::declval<Rec&>())) {
    if (lag_) return f(*lag_);
    return f(*rec_);
  }
  template <class F>
  auto with_const(F&& f) const -> decltype(f(std::declval<const Rec&>())) {
    if (lag_) return f(*lag_);
    return f(*rec_);
  }

  std::uint16_t push(Scalar y, bool stuck, bool saturated) noexcept {
    return with([&](auto& m) noexcept { return m.push(y, stuck, saturated); });
  }
  bool retuned() const noexcept {
    return with_const([](const auto& m) noexcept { return m.retuned(); });
  }
  const StreamingAllan<Scalar, kMonitorOctaves>& allan() const noexcept {
    return with_const([](const auto& m) noexcept -> const StreamingAllan<Scalar, kMonitorOctaves>& { return m.allan(); });
  }
  const typename Rec::Alarms& alarms() const noexcept {
    return with_const([](const auto& m) noexcept -> const typename Rec::Alarms& { return m.alarms(); });
  }
  void reset() noexcept {
    with([](auto& m) noexcept { m.reset(); });
  }
  std::uint64_t samples() const noexcept {
    return with_const([](const auto& m) noexcept { return m.samples(); });
  }
  std::uint64_t used() const noexcept {
    return with_const([](const auto& m) noexcept { return m.used(); });
  }
  std::uint16_t latched() const noexcept {
    return with_const([](const auto& m) noexcept { return m.latched(); });
  }
  bool reidentifying() const noexcept {
    return with_const([](const auto& m) noexcept { return m.reidentifying(); });
  }
  bool noise(Scalar coverage, NoiseEstimates<Scalar>& out) const noexcept {
    return with_const([&](const auto& m) noexcept { return m.noise(coverage, out); });
  }

  IdView view() const noexcept {
    IdView v;
    if (lag_) {
      const LagDriftIdentifier<Scalar, 1>& id = lag_->identifier();
      v.use = id.in_use(0);
      v.est = id.estimate(0);
      v.gain0 = id.gain0(0);
      v.gain1 = id.gain1(0);
      v.status = static_cast<int>(id.status(0));
      v.retunes = id.retunes(0);
      v.refused = id.refused_retunes(0);
      v.fit_status = static_cast<int>(id.fit_status(0));
      v.paused = id.paused(0);
      v.late_fits = id.late_fits();
    } else {
      const OnlineDriftIdentifier<Scalar>& id = rec_->identifier();
      v.use = id.in_use();
      v.est = id.estimate();
      v.gain0 = id.gain0();
      v.gain1 = id.gain1();
      v.status = static_cast<int>(id.status());
      v.retunes = id.retunes();
      v.refused = id.refused_retunes();
    }
    return v;
  }

 private:
  std::optional<Rec> rec_;
  std::optional<Lag> lag_;
};

template <class Scalar>
class GyroMonitorRunPy {
  using Monitor = AnyMonitor<Scalar>;

 public:
  GyroMonitorRunPy(const MonitorSettingsPy& settings, py::tuple model, const CArray<double>& reference_avar,
                   const CArray<double>& reference_edf) {
    const GyroMonitorSettings<Scalar> s = settings.to_core<Scalar>();
    if (model.size() != 5) throw py::value_error("model: expected (a1, a2, q, r, mean)");
    DriftModelParams<Scalar> p{};
    p.a1 = static_cast<Scalar>(model[0].cast<double>());
    p.a2 = static_cast<Scalar>(model[1].cast<double>());
    p.q = static_cast<Scalar>(model[2].cast<double>());
    p.r = static_cast<Scalar>(model[3].cast<double>());
    p.mean = static_cast<Scalar>(model[4].cast<double>());
    if (reference_avar.ndim() != 1 || reference_avar.shape(0) < 1 ||
        reference_avar.shape(0) > static_cast<py::ssize_t>(s.octaves)) {
      throw py::value_error("reference_avar: expected a 1-D array of 1..octaves values");
    }
    typename Monitor::Reference ref{};
    ref.octaves = static_cast<std::size_t>(reference_avar.shape(0));
    if (reference_edf.ndim() != 1 || reference_edf.shape(0) != reference_avar.shape(0)) {
      throw py::value_error("reference_edf: expected one value per reference octave (0: from the slope)");
    }
    for (std::size_t k = 0; k < ref.octaves; ++k) {
      ref.avar[k] = static_cast<Scalar>(reference_avar.data()[k]);
      ref.edf_per_term[k] = static_cast<Scalar>(reference_edf.data()[k]);
    }
    const GyroMonitorStatus st = monitor_.configure(s, p, ref);
    if (st == GyroMonitorStatus::bad_model) {
      throw py::value_error("model: not a valid stationary drift model (a1, a2, q >= 0, r >= 0, q + r > 0, mean)");
    }
    if (st != GyroMonitorStatus::ok) {
      throw py::value_error("reference_avar: every value must be positive and finite (in this precision), at "
                            "most octaves of them; or the re-identification refuses the settings");
    }
  }

  py::dict run(const CArray<Scalar>& y, const CArray<bool>& stuck, const CArray<bool>& saturated,
               std::int64_t report_every, double coverage) {
    if (y.ndim() != 1) throw py::value_error("y: expected a 1-D array");
    const auto n = static_cast<std::size_t>(y.shape(0));
    if (stuck.ndim() != 1 || static_cast<std::size_t>(stuck.shape(0)) != n || saturated.ndim() != 1 ||
        static_cast<std::size_t>(saturated.shape(0)) != n) {
      throw py::value_error("stuck, saturated: expected 1-D bool arrays as long as y");
    }
    if (report_every < 1) throw py::value_error("report_every: expected >= 1 samples");
    if (!(coverage > 0.0 && coverage < 1.0)) throw py::value_error("coverage: expected 0 < coverage < 1");
    const std::size_t every = static_cast<std::size_t>(report_every);
    const std::size_t octaves = monitor_.allan().octaves();
    std::vector<double> rows;  // kCols per report
    std::vector<double> avar;  // octaves per report
    const Scalar* yd = y.data();
    const bool* sd = stuck.data();
    const bool* td = saturated.data();
    {
      ReleasedAndLocked guard(this);
      rows.reserve((n / every + 1) * kCols);
      avar.reserve((n / every + 1) * octaves);
      for (std::size_t i = 0; i < n; ++i) {
        monitor_.push(yd[i], sd[i], td[i]);
        if (monitor_.retuned()) ++retunes_seen_;
        if (++since_report_ < every) continue;
        since_report_ = 0;
        append_row(static_cast<Scalar>(coverage), rows, avar, octaves);
      }
    }
    const std::size_t m = rows.size() / kCols;
    py::dict out;
    const char* names[kCols] = {"sample", "n", "n_lo", "n_hi", "b", "b_lo", "b_hi", "b_tau_s", "k", "k_lo", "k_hi",
                                "k_upper_limit", "a1", "a2", "q", "r", "mean", "gain0", "gain1", "status",
                                "health", "est_a1", "est_a2", "est_q", "est_r", "est_mean", "retunes",
                                "refused_retunes", "used", "fit_status", "paused", "late_fits"};
    for (std::size_t c = 0; c < kCols; ++c) {
      py::array_t<double> col(static_cast<py::ssize_t>(m));
      double* o = col.mutable_data();
      for (std::size_t r = 0; r < m; ++r) o[r] = rows[r * kCols + c];
      out[names[c]] = col;
    }
    py::array_t<double> av({static_cast<py::ssize_t>(m), static_cast<py::ssize_t>(octaves)});
    double* o = av.mutable_data();
    for (std::size_t i = 0; i < avar.size(); ++i) o[i] = avar[i];
    out["avar"] = av;
    return out;
  }

  // The latched alarm bits after each sample (what the processor's health_alarm flag follows).
  py::array_t<std::uint16_t> latched(const CArray<Scalar>& y, const CArray<bool>& stuck, const CArray<bool>& saturated) {
    if (y.ndim() != 1) throw py::value_error("y: expected a 1-D array");
    const auto n = static_cast<std::size_t>(y.shape(0));
    if (stuck.ndim() != 1 || static_cast<std::size_t>(stuck.shape(0)) != n || saturated.ndim() != 1 ||
        static_cast<std::size_t>(saturated.shape(0)) != n) {
      throw py::value_error("stuck, saturated: expected 1-D bool arrays as long as y");
    }
    py::array_t<std::uint16_t> out(static_cast<py::ssize_t>(n));
    std::uint16_t* o = out.mutable_data();
    const Scalar* yd = y.data();
    const bool* sd = stuck.data();
    const bool* td = saturated.data();
    {
      ReleasedAndLocked guard(this);
      for (std::size_t i = 0; i < n; ++i) o[i] = monitor_.push(yd[i], sd[i], td[i]);
    }
    return out;
  }

  py::dict trips() const {
    py::dict out;
    for (std::size_t i = 0; i < kHealthAlarmCount; ++i) {
      std::uint32_t raised = 0;
      HealthTrip<Scalar> t{};
      {
        ReleasedAndLocked guard(this);
        raised = monitor_.alarms().raised(i);
        t = monitor_.alarms().trip(i);
      }
      if (raised == 0) continue;
      py::dict d;
      d["statistic"] = static_cast<double>(t.statistic);
      d["threshold"] = static_cast<double>(t.threshold);
      d["tau_s"] = static_cast<double>(t.tau_s);
      d["sample"] = t.sample;
      d["raised"] = raised;
      out[kHealthAlarmNames[i].name] = d;
    }
    return out;
  }

  void reset() {
    ReleasedAndLocked guard(this);
    monitor_.reset();
    since_report_ = 0;
    retunes_seen_ = 0;
  }

  std::int64_t samples() const {
    ReleasedAndLocked guard(this);
    return static_cast<std::int64_t>(monitor_.samples());
  }

 private:
  static constexpr std::size_t kCols = 32;

  void append_row(Scalar coverage, std::vector<double>& rows, std::vector<double>& avar, std::size_t octaves) const {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    NoiseEstimates<Scalar> e{};
    monitor_.noise(coverage, e);
    auto term = [&](const NoiseTermEstimate<Scalar>& t) {
      // value and lo are meaningless for an upper limit; hi holds it
      rows.push_back(t.valid && !t.upper_limit ? static_cast<double>(t.value) : nan);
      rows.push_back(t.valid && !t.upper_limit ? static_cast<double>(t.lo) : nan);
      rows.push_back(t.valid ? static_cast<double>(t.hi) : nan);
    };
    rows.push_back(static_cast<double>(monitor_.samples()));
    term(e.n);
    term(e.b);
    rows.push_back(e.b.valid ? static_cast<double>(e.b_tau_s) : nan);
    term(e.k);
    rows.push_back(e.k.valid && e.k.upper_limit ? 1.0 : 0.0);
    const bool reid = monitor_.reidentifying();
    const typename Monitor::IdView id = reid ? monitor_.view() : typename Monitor::IdView{};
    const DriftModelParams<Scalar>& use = id.use;
    const DriftModelParams<Scalar>& est = id.est;
    for (Scalar v : {use.a1, use.a2, use.q, use.r, use.mean}) rows.push_back(reid ? static_cast<double>(v) : nan);
    rows.push_back(reid ? static_cast<double>(id.gain0) : nan);
    rows.push_back(reid ? static_cast<double>(id.gain1) : nan);
    rows.push_back(reid ? static_cast<double>(id.status) : -1.0);
    rows.push_back(static_cast<double>(monitor_.latched()));
    for (Scalar v : {est.a1, est.a2, est.q, est.r, est.mean}) rows.push_back(reid ? static_cast<double>(v) : nan);
    rows.push_back(reid ? static_cast<double>(id.retunes) : 0.0);
    rows.push_back(reid ? static_cast<double>(id.refused) : 0.0);
    rows.push_back(static_cast<double>(monitor_.used()));
    rows.push_back(reid ? static_cast<double>(id.fit_status) : -1.0);
    rows.push_back(reid ? static_cast<double>(id.paused) : 0.0);
    rows.push_back(reid ? static_cast<double>(id.late_fits) : 0.0);
    for (std::size_t k = 0; k < octaves; ++k) {
      Scalar v{0};
      avar.push_back(monitor_.allan().avar(k, v) ? static_cast<double>(v) : nan);
    }
  }

  Monitor monitor_{};
  std::size_t since_report_ = 0;
  std::uint64_t retunes_seen_ = 0;
};

template <class Scalar>
void bind_run(py::module_& m, const char* name, const char* doc) {
  using T = GyroMonitorRunPy<Scalar>;
  py::class_<T>(m, name, doc)
      .def(py::init<const MonitorSettingsPy&, py::tuple, const CArray<double>&, const CArray<double>&>(),
           py::arg("settings"), py::arg("model"), py::arg("reference_avar").noconvert(),
           py::arg("reference_edf").noconvert())
      .def("run", &T::run, py::arg("y").noconvert(), py::arg("stuck").noconvert(),
           py::arg("saturated").noconvert(), py::arg("report_every"), py::arg("coverage"),
           "Push the samples (1-D, C-contiguous) with their stuck/saturated flags; returns the "
           "per-report arrays (one row every `report_every` samples). GIL released.")
      .def("latched", &T::latched, py::arg("y").noconvert(), py::arg("stuck").noconvert(),
           py::arg("saturated").noconvert(),
           "Push the samples; returns the latched alarm bits after each one (u16). GIL released.")
      .def("trips", &T::trips, "The statistic that tripped each alarm raised so far.")
      .def("reset", &T::reset, "Forget every sample and clear the alarms (keeps the configuration).")
      .def_property_readonly("samples", &T::samples);
}

}  // namespace

void bind_monitor(pybind11::module_& m) {
  using S = MonitorSettingsPy;
  const S d{};
  py::class_<S>(m, "GyroMonitorSettings",
                "Settings of the gyro monitor (gyro_monitor.hpp); durations in samples.")
      .def(py::init([](double rate_hz, std::int64_t octaves, double arw_factor, double bias_instability_factor,
                       double rate_random_walk_factor, double false_alarm_probability, std::int64_t stuck_samples,
                       std::int64_t saturated_samples, bool reidentify, std::int64_t block_samples,
                       std::int64_t retune_blocks, std::int64_t min_samples, double memory_blocks, double max_step,
                       double max_rel_stderr, bool adapt_ar, double min_ar_wald, std::string identifier,
                       std::int64_t fit_delay_samples, bool restart_after_fit) {
             S s{rate_hz, octaves, arw_factor, bias_instability_factor, rate_random_walk_factor,
                 false_alarm_probability, stuck_samples, saturated_samples, reidentify, block_samples,
                 retune_blocks, min_samples, memory_blocks, max_step, max_rel_stderr, adapt_ar,
                 min_ar_wald, std::move(identifier), fit_delay_samples, restart_after_fit};
             s.check();
             return s;
           }),
           py::kw_only(), py::arg("rate_hz"), py::arg("octaves"), py::arg("arw_factor") = d.arw_factor,
           py::arg("bias_instability_factor") = d.bias_instability_factor,
           py::arg("rate_random_walk_factor") = d.rate_random_walk_factor,
           py::arg("false_alarm_probability") = d.false_alarm_probability,
           py::arg("stuck_samples") = d.stuck_samples, py::arg("saturated_samples") = d.saturated_samples,
           py::arg("reidentify") = d.reidentify, py::arg("block_samples") = d.block_samples,
           py::arg("retune_blocks") = d.retune_blocks, py::arg("min_samples") = d.min_samples,
           py::arg("memory_blocks") = d.memory_blocks, py::arg("max_step") = d.max_step,
           py::arg("max_rel_stderr") = d.max_rel_stderr, py::arg("adapt_ar") = d.adapt_ar,
           py::arg("min_ar_wald") = d.min_ar_wald, py::arg("identifier") = d.identifier, py::arg("fit_delay_samples") = d.fit_delay_samples,
           py::arg("restart_after_fit") = d.restart_after_fit)
      .def_readwrite("rate_hz", &S::rate_hz)
      .def_readwrite("octaves", &S::octaves)
      .def_readwrite("arw_factor", &S::arw_factor)
      .def_readwrite("bias_instability_factor", &S::bias_instability_factor)
      .def_readwrite("rate_random_walk_factor", &S::rate_random_walk_factor)
      .def_readwrite("false_alarm_probability", &S::false_alarm_probability)
      .def_readwrite("stuck_samples", &S::stuck_samples)
      .def_readwrite("saturated_samples", &S::saturated_samples)
      .def_readwrite("reidentify", &S::reidentify)
      .def_readwrite("block_samples", &S::block_samples)
      .def_readwrite("retune_blocks", &S::retune_blocks)
      .def_readwrite("min_samples", &S::min_samples)
      .def_readwrite("memory_blocks", &S::memory_blocks)
      .def_readwrite("max_step", &S::max_step)
      .def_readwrite("max_rel_stderr", &S::max_rel_stderr)
      .def_readwrite("adapt_ar", &S::adapt_ar)
      .def_readwrite("min_ar_wald", &S::min_ar_wald)
      .def_readwrite("identifier", &S::identifier)
      .def_readwrite("fit_delay_samples", &S::fit_delay_samples)
      .def_readwrite("restart_after_fit", &S::restart_after_fit);
  bind_run<double>(m, "GyroMonitorRun", "The gyro monitor with double state over whole records.");
  bind_run<float>(m, "GyroMonitorRunF32", "The gyro monitor with float state (as on the target).");
  py::list names;
  for (const HealthAlarmName& a : kHealthAlarmNames) names.append(a.name);
  m.attr("MONITOR_ALARM_NAMES") = py::tuple(names);
  m.attr("MONITOR_MAX_OCTAVES") = kMonitorOctaves;
}

}  // namespace gyrodrift::py_bindings
