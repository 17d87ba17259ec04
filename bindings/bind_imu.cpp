// gyrodrift._core: IMU processor and the frame codecs (serial, CAN, SLCAN).
//
// Low-level, strict API (gyrodrift.imu adds the config dataclasses and messages):
//   ImuWaveletSettings(*, wavelet "db4"|"db8", window (power of two, 16..4096), level,
//       threshold "forced"|"soft"|"hard" = schema default)        one channel's wavelet stage
//   ImuChannelSettings(*, filter, filter2 (stage names "pass_through" "bias_removal" "wavelet"
//       "ar2_kalman"), steady_state, bias, a1, a2, sigma2, mean (the Ar2Model), q, r, p0,
//       saturation, stuck_samples, wavelet: ImuWaveletSettings | None)      one channel's chain
//   ImuProcessorSettings(*, channels [ImuChannelSettings] * 6, period_us, time_tolerance_us)
//     keyword-only, closed to unknown fields, checked when built and again by the processor;
//     defaults from ImuChannelConfig / ImuConfig (imu/imu_processor.hpp), field names those
//     of the configuration schema (imu/config_schema.hpp). Nested values (channels, wavelet)
//     are copied in and out: assign the whole object to change one.
//   ImuProcessor / ImuProcessorF32(settings)   float64 / float32; the wavelet stages
//       (RealtimeWavelet<T, window> per channel, RealtimeWaveletAnyWindow) exist only when a
//       channel's chain uses one
//     .process(seq u16[n], t_us u64[n], values (n, 6) float64|float32)
//         -> (out (n, 6), flags u16[n])   rows with flags & 0x8000 (rejected) are NaN
//     .health() -> dict, .reset(), .status -> str, .bad_channel -> int
//   IMU_FLAGS {name: bit}, IMU_HEALTH_KEYS, IMU_REJECTION_KEYS (tuples), IMU_RESYNC_AFTER,
//   IMU_DEFAULT_PERIOD_US, IMU_DEFAULT_TIME_TOLERANCE_US, IMU_CHANNELS,
//   IMU_DEMO_AR2 {a1 a2 sigma2 mean q r}: the processor contract from imu/imu_processor.hpp
//   crc16_ccitt_false(bytes) -> int
//   serial_encode_frame(frame_type, seq, flags, t_us, values[6]) -> bytes
//   serial_parse(data, chunk, finish) -> (frames list, stats dict)   (C++ parser, 256-B buffer)
//   can_encode_sample(seq, flags, values[6], base_id) -> [(id, bytes)] * 4
//   can_assemble(frames [(id, data[, extended, remote])], base_id, finish) -> (samples, stats)
//   slcan_encode(id, data, extended, remote) -> bytes
//   slcan_parse(data) -> (events, stats)   events: ("frame", id, data, ext, rtr, reply) |
//                                          ("command", letter, arg bytes, reply) | ("error", reply)
//   can_signal_table(text) -> [entry dict]            (a user-DBC decode table, parsed in C++)
//   can_signal_decode(text, frames) -> [{role: value}] per frame (codecs/can_signal_decode.hpp)
//   can_signal_assemble(text, frames, finish) -> ([(seq, t_us | None, values)], stats)
// Arrays are C-contiguous and taken without copy (.noconvert(): a wrong dtype is a TypeError).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <gyrodrift/codecs/can_frames.hpp>
#include <gyrodrift/codecs/can_signal_decode.hpp>
#include <gyrodrift/codecs/crc16.hpp>
#include <gyrodrift/codecs/serial_frame.hpp>
#include <gyrodrift/codecs/slcan.hpp>
#include <gyrodrift/filters/realtime_wavelet.hpp>
#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/config_schema.hpp>
#include <gyrodrift/imu/imu_processor.hpp>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

namespace schema = config_schema;

const char* status_name(ImuStatus s) {
  switch (s) {
    case ImuStatus::ok: return "ok";
    case ImuStatus::bad_channel_config: return "bad channel config";
    case ImuStatus::wavelet_unavailable: return "wavelet unavailable";
    case ImuStatus::bad_timing: return "period_us is 0 while the timestamp check is on";
  }
  return "unknown";
}

py::dict health_dict(const ImuHealth& h) {
  py::dict d;
  for_each_health_field(h, [&d](const char* name, std::uint64_t v) { d[name] = v; });
  return d;
}

// ---- Processor configuration: the bound settings objects --------------------------------

// Stage names of a channel's chain (the configuration file's stage types).
constexpr std::array<const char*, 4> kStageNames = {"pass_through", "bias_removal", "ar2_kalman", "wavelet"};

const char* stage_name(ChannelFilter f) { return kStageNames[static_cast<std::size_t>(f)]; }

ChannelFilter parse_stage(const std::string& at, const char* field, const std::string& name) {
  for (std::size_t i = 0; i < kStageNames.size(); ++i) {
    if (name == kStageNames[i]) return static_cast<ChannelFilter>(i);
  }
  throw py::value_error(at + field + ": expected one of pass_through, bias_removal, wavelet, ar2_kalman, got '" +
                        name + "'");
}

void check_u32(const std::string& at, const char* field, std::int64_t v, const char* bounds_text) {
  if (v < 0 || v > static_cast<std::int64_t>(std::numeric_limits<std::uint32_t>::max())) {
    throw py::value_error(at + field + ": expected " + bounds_text + ", got " + std::to_string(v));
  }
}

// The wavelet stage over every window of the configuration format (16..4096), chosen per
// channel at construction; the filter itself is RealtimeWavelet<T, N> for that window.
template <class T>
using WaveletStage = RealtimeWaveletAnyWindow<T>;

// One wavelet stage's settings, checked (RealtimeWaveletWindows' constructor arguments).
struct WaveletSpec {
  WaveletKind kind = WaveletKind::db4;
  std::size_t window = 0;
  int level = 0;
  WaveletMode mode = WaveletMode::forced;
};

// gyrodrift._core.ImuWaveletSettings: the schema's "wavelet" stage (wavelet, window and level
// required; threshold defaults to the schema's). ValueError "<at>window: ..." in the
// configuration reader's wording (at: "" or "channels[c].wavelet.").
struct ImuWaveletSettings {
  std::string wavelet;
  std::int64_t window = 0;
  int level = 0;
  std::string threshold{schema::kWaveletThreshold.default_text};

  WaveletSpec spec(const std::string& at) const {
    WaveletSpec w;
    if (wavelet == "db4") {
      w.kind = WaveletKind::db4;
    } else if (wavelet == "db8") {
      w.kind = WaveletKind::db8;
    } else {
      throw py::value_error(at + "wavelet: expected " + schema::kWaveletWavelet.bounds_text + ", got '" + wavelet +
                            "'");
    }
    if (threshold == "forced") {
      w.mode = WaveletMode::forced;
    } else if (threshold == "soft") {
      w.mode = WaveletMode::soft;
    } else if (threshold == "hard") {
      w.mode = WaveletMode::hard;
    } else {
      throw py::value_error(at + "threshold: expected " + schema::kWaveletThreshold.bounds_text + ", got '" +
                            threshold + "'");
    }
    if (!config_wavelet_window_ok(window)) {
      throw py::value_error(at + "window: expected " + schema::kWaveletWindow.bounds_text + ", got " +
                            std::to_string(window));
    }
    w.window = static_cast<std::size_t>(window);
    const int jmax = realtime_wavelet_max_level(w.window, w.kind);
    if (level < 1 || level > jmax) {
      throw py::value_error(at + "level: expected 1.." + std::to_string(jmax) + " for " + wavelet + " with window " +
                            std::to_string(window) + ", got " + std::to_string(level));
    }
    w.level = level;
    return w;
  }
};

// gyrodrift._core.ImuChannelSettings: ImuChannelConfig with the stages by name, the model's
// fields flat (the schema's names) and the channel's wavelet stage (None: none). Values are
// stored in double and rounded to the processor's scalar when it is built, as before.
struct ImuChannelSettings {
  std::string filter, filter2;
  bool steady_state = false;
  double bias = 0, a1 = 0, a2 = 0, sigma2 = 0, mean = 0, q = 0, r = 0, p0 = 0, saturation = 0;
  std::int64_t stuck_samples = 0;
  std::optional<ImuWaveletSettings> wavelet;

  static ImuChannelSettings of(const ImuChannelConfig<double>& c) {
    return ImuChannelSettings{stage_name(c.filter), stage_name(c.filter2), c.steady_state, c.bias,
                              c.model.a1, c.model.a2, c.model.sigma2, c.model.mean, c.q, c.r, c.p0,
                              c.saturation, static_cast<std::int64_t>(c.stuck_samples), std::nullopt};
  }

  bool uses_wavelet() const { return filter == "wavelet" || filter2 == "wavelet"; }

  // Field checks (names, integer ranges, the wavelet stage); the values' meaning (model,
  // saturation, chain) is the processor's status, as for the C++ ImuProcessor.
  template <class T>
  ImuChannelConfig<T> config(const std::string& at) const {
    ImuChannelConfig<T> cc;
    cc.filter = parse_stage(at, "filter", filter);
    cc.filter2 = parse_stage(at, "filter2", filter2);
    check_u32(at, "stuck_samples", stuck_samples, schema::kChannelStuckSamples.bounds_text);
    if (wavelet) wavelet->spec(at + "wavelet.");
    cc.steady_state = steady_state;
    cc.bias = static_cast<T>(bias);
    cc.model = Ar2Model<T>{static_cast<T>(a1), static_cast<T>(a2), static_cast<T>(sigma2), static_cast<T>(mean)};
    cc.q = static_cast<T>(q);
    cc.r = static_cast<T>(r);
    cc.p0 = static_cast<T>(p0);
    cc.saturation = static_cast<T>(saturation);
    cc.stuck_samples = static_cast<std::uint32_t>(stuck_samples);
    return cc;
  }
};

// gyrodrift._core.ImuProcessorSettings: ImuConfig (six channels and the timing).
struct ImuProcessorSettings {
  std::vector<ImuChannelSettings> channels;
  std::int64_t period_us = 0;
  std::int64_t time_tolerance_us = 0;

  static ImuProcessorSettings of(const ImuConfig<double>& c) {
    ImuProcessorSettings s{{}, c.period_us, c.time_tolerance_us};
    for (const auto& cc : c.channels) s.channels.push_back(ImuChannelSettings::of(cc));
    return s;
  }

  std::string at(std::size_t c) const { return "channels[" + std::to_string(c) + "]."; }

  template <class T>
  ImuConfig<T> config() const {
    if (channels.size() != kImuChannels) {
      throw py::value_error("channels: expected 6 ImuChannelSettings, got " + std::to_string(channels.size()));
    }
    ImuConfig<T> cfg;
    for (std::size_t c = 0; c < kImuChannels; ++c) cfg.channels[c] = channels[c].config<T>(at(c));
    check_u32("", "period_us", period_us, "0..4294967295 us");
    check_u32("", "time_tolerance_us", time_tolerance_us, schema::kTimingTimeToleranceUs.bounds_text);
    cfg.period_us = static_cast<std::uint32_t>(period_us);
    cfg.time_tolerance_us = static_cast<std::uint32_t>(time_tolerance_us);
    return cfg;
  }

  bool uses_wavelet() const {
    for (const auto& ch : channels) {
      if (ch.uses_wavelet()) return true;
    }
    return false;
  }
};

// ---- Binding the settings objects ---------------------------------------------------------

// A bool field that refuses anything but a bool (numpy.bool_ included): steady_state=1 or
// None is a TypeError, not a silent truth value.
template <class S>
void def_bool_field(py::class_<S>& cls, const char* name, bool S::*field) {
  cls.def_property(
      name, [field](const S& s) { return s.*field; },
      py::cpp_function([field](S& s, bool v) { s.*field = v; }, py::is_method(cls), py::arg("value").noconvert()));
}

void bind_wavelet_settings(py::module_& m) {
  using W = ImuWaveletSettings;
  py::class_<W>(m, "ImuWaveletSettings",
                "One channel's real-time wavelet stage (the configuration schema's 'wavelet' stage): "
                "wavelet ('db4' or 'db8'), window (a power of two in 16..4096), level (1..the "
                "window's deepest), threshold ('forced', 'soft' or 'hard'). Keyword-only; checked "
                "when built and by the processor.")
      .def(py::init([](const std::string& wavelet, std::int64_t window, int level, const std::string& threshold) {
             W w{wavelet, window, level, threshold};
             w.spec("");
             return w;
           }),
           py::kw_only(), py::arg("wavelet"), py::arg("window"), py::arg("level"),
           py::arg("threshold") = std::string(schema::kWaveletThreshold.default_text))
      .def_readwrite("wavelet", &W::wavelet)
      .def_readwrite("window", &W::window)
      .def_readwrite("level", &W::level)
      .def_readwrite("threshold", &W::threshold)
      .def("__repr__", [](const W& w) {
        return py::str("ImuWaveletSettings(wavelet={!r}, window={!r}, level={!r}, threshold={!r})")
            .format(w.wavelet, w.window, w.level, w.threshold);
      });
}

void bind_channel_settings(py::module_& m) {
  using C = ImuChannelSettings;
  const C d = C::of(ImuChannelConfig<double>{});  // the defaults: ImuChannelConfig's
  py::class_<C> cls(m, "ImuChannelSettings",
                    "One channel's chain (ImuChannelConfig): filter then filter2 (stage names "
                    "'pass_through', 'bias_removal', 'wavelet', 'ar2_kalman'; filter2 "
                    "'pass_through': none), steady_state, bias, the AR(2) model a1, a2, sigma2, "
                    "mean, the Kalman q, r, p0, saturation, stuck_samples and the wavelet stage "
                    "(ImuWaveletSettings or None). Keyword-only, defaults from ImuChannelConfig; "
                    "checked when built and by the processor.");
  cls.def(py::init([](const std::string& filter, const std::string& filter2, bool steady_state, double bias,
                      double a1, double a2, double sigma2, double mean, double q, double r, double p0,
                      double saturation, std::int64_t stuck_samples,
                      const std::optional<ImuWaveletSettings>& wavelet) {
            C c{filter, filter2, steady_state, bias, a1, a2, sigma2, mean, q, r, p0, saturation,
                stuck_samples, wavelet};
            c.config<double>("");
            return c;
          }),
          py::kw_only(), py::arg("filter") = d.filter, py::arg("filter2") = d.filter2,
          py::arg("steady_state").noconvert() = d.steady_state, py::arg("bias") = d.bias, py::arg("a1") = d.a1,
          py::arg("a2") = d.a2, py::arg("sigma2") = d.sigma2, py::arg("mean") = d.mean, py::arg("q") = d.q,
          py::arg("r") = d.r, py::arg("p0") = d.p0, py::arg("saturation") = d.saturation,
          py::arg("stuck_samples") = d.stuck_samples, py::arg("wavelet") = py::none());
  cls.def_readwrite("filter", &C::filter).def_readwrite("filter2", &C::filter2);
  def_bool_field(cls, "steady_state", &C::steady_state);
  cls.def_readwrite("bias", &C::bias)
      .def_readwrite("a1", &C::a1)
      .def_readwrite("a2", &C::a2)
      .def_readwrite("sigma2", &C::sigma2)
      .def_readwrite("mean", &C::mean)
      .def_readwrite("q", &C::q)
      .def_readwrite("r", &C::r)
      .def_readwrite("p0", &C::p0)
      .def_readwrite("saturation", &C::saturation)
      .def_readwrite("stuck_samples", &C::stuck_samples)
      .def_readwrite("wavelet", &C::wavelet)
      .def("__repr__", [](const C& c) {
        return py::str("ImuChannelSettings(filter={!r}, filter2={!r}, steady_state={!r}, bias={!r}, a1={!r}, "
                       "a2={!r}, sigma2={!r}, mean={!r}, q={!r}, r={!r}, p0={!r}, saturation={!r}, "
                       "stuck_samples={!r}, wavelet={!r})")
            .format(c.filter, c.filter2, c.steady_state, c.bias, c.a1, c.a2, c.sigma2, c.mean, c.q, c.r, c.p0,
                    c.saturation, c.stuck_samples, c.wavelet);
      });
}

void bind_processor_settings(py::module_& m) {
  using P = ImuProcessorSettings;
  const P d = P::of(ImuConfig<double>{});  // the defaults: ImuConfig's
  py::class_<P>(m, "ImuProcessorSettings",
                "The processor's configuration (ImuConfig): channels (6 ImuChannelSettings: gyro x "
                "y z, accel x y z), period_us and time_tolerance_us (0: timestamp check off). "
                "Keyword-only, defaults from ImuConfig; checked when built and by the processor. "
                "channels is copied in and out: assign the whole list to change a channel.")
      .def(py::init([](const std::vector<ImuChannelSettings>& channels, std::int64_t period_us,
                       std::int64_t time_tolerance_us) {
             P s{channels, period_us, time_tolerance_us};
             s.config<double>();
             return s;
           }),
           py::kw_only(), py::arg("channels") = d.channels, py::arg("period_us") = d.period_us,
           py::arg("time_tolerance_us") = d.time_tolerance_us)
      .def_readwrite("channels", &P::channels)
      .def_readwrite("period_us", &P::period_us)
      .def_readwrite("time_tolerance_us", &P::time_tolerance_us)
      .def("__repr__", [](const P& s) {
        return py::str("ImuProcessorSettings(channels={!r}, period_us={!r}, time_tolerance_us={!r})")
            .format(s.channels, s.period_us, s.time_tolerance_us);
      });
}

// ---- Processors ---------------------------------------------------------------------------

// The C++ processor of one settings object: ImuProcessor<T> when no channel uses the wavelet
// stage, else ImuProcessor<T, WaveletStage<T>> with each wavelet channel's stage built in
// place (six stages sized for the largest window: on the heap). A channel whose chain uses
// the wavelet stage without settings gets an empty stage (status: wavelet unavailable).
template <class T>
class BoundImuProcessor {
 public:
  using Plain = ImuProcessor<T>;
  using WithWavelet = ImuProcessor<T, WaveletStage<T>>;

  explicit BoundImuProcessor(const ImuProcessorSettings& s) {
    const ImuConfig<T> cfg = s.config<T>();  // checked again: the fields are writable
    if (!s.uses_wavelet()) {
      plain_ = std::make_unique<Plain>(cfg);
      return;
    }
    std::array<std::optional<WaveletSpec>, kImuChannels> specs;
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      const ImuChannelSettings& ch = s.channels[c];
      if (ch.uses_wavelet() && ch.wavelet) specs[c] = ch.wavelet->spec(s.at(c) + "wavelet.");
    }
    wavelet_ = std::make_unique<WithWavelet>(cfg, [&specs](std::size_t c) {
      if (!specs[c]) return WaveletStage<T>();
      const WaveletSpec& w = *specs[c];
      return WaveletStage<T>(w.window, w.kind, w.level, w.mode);
    });
  }

  // f(processor) on the held processor.
  template <class F>
  decltype(auto) visit(F&& f) {
    if (wavelet_) return f(*wavelet_);
    return f(*plain_);
  }
  template <class F>
  decltype(auto) visit(F&& f) const {
    if (wavelet_) return f(static_cast<const WithWavelet&>(*wavelet_));
    return f(static_cast<const Plain&>(*plain_));
  }

 private:
  std::unique_ptr<Plain> plain_;
  std::unique_ptr<WithWavelet> wavelet_;
};

// Steps every row of (seq, t_us, values) through p; rejected rows are NaN. GIL released.
template <class T, class Proc>
void process_rows(Proc& p, const std::uint16_t* s, const std::uint64_t* t, const T* v, std::size_t n, T* o,
                  std::uint16_t* f) {
  ImuSample<T> in;
  ImuOutput<T> res;
  for (std::size_t k = 0; k < n; ++k) {
    in.seq = s[k];
    in.t_us = t[k];
    for (std::size_t c = 0; c < kImuChannels; ++c) in.values[c] = v[k * kImuChannels + c];
    f[k] = p.step(in, res);
    const bool rejected = (f[k] & kFlagRejected) != 0;
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      o[k * kImuChannels + c] = rejected ? std::numeric_limits<T>::quiet_NaN() : res.values[c];
    }
  }
}

template <class T>
py::tuple process(BoundImuProcessor<T>& p, const CArray<std::uint16_t>& seq, const CArray<std::uint64_t>& t_us,
                  const CArray<T>& values) {
  if (values.ndim() != 2 || values.shape(1) != static_cast<py::ssize_t>(kImuChannels)) {
    throw py::value_error("values: expected an (n, 6) array, got ndim=" + std::to_string(values.ndim()));
  }
  const auto n = static_cast<std::size_t>(values.shape(0));
  if (seq.ndim() != 1 || t_us.ndim() != 1 || static_cast<std::size_t>(seq.shape(0)) != n ||
      static_cast<std::size_t>(t_us.shape(0)) != n) {
    throw py::value_error("seq and t_us: expected 1-D arrays of length " + std::to_string(n));
  }
  CArray<T> out({static_cast<py::ssize_t>(n), static_cast<py::ssize_t>(kImuChannels)});
  py::array_t<std::uint16_t> flags(static_cast<py::ssize_t>(n));
  const std::uint16_t* s = seq.data();
  const std::uint64_t* t = t_us.data();
  const T* v = values.data();
  T* o = out.mutable_data();
  std::uint16_t* f = flags.mutable_data();
  {
    ReleasedAndLocked guard(&p);  // GIL released, then this processor's lock
    p.visit([&](auto& proc) { process_rows<T>(proc, s, t, v, n, o, f); });
  }
  return py::make_tuple(out, flags);
}

template <class T>
void bind_processor(py::module_& m, const char* name, const char* doc) {
  using P = BoundImuProcessor<T>;
  py::class_<P>(m, name, doc)
      .def(py::init<const ImuProcessorSettings&>(), py::arg("settings"))
      .def("process", &process<T>, py::arg("seq").noconvert(), py::arg("t_us").noconvert(),
           py::arg("values").noconvert())
      .def("health",
           [](const P& p) {
             ImuHealth h;
             {
               ReleasedAndLocked guard(&p);
               h = p.visit([](const auto& proc) { return proc.health(); });
             }
             return health_dict(h);
           })
      .def("reset",
           [](P& p) {
             ReleasedAndLocked guard(&p);
             p.visit([](auto& proc) { proc.reset(); });
           })
      .def_property_readonly("status",
                             [](const P& p) {
                               return std::string(status_name(p.visit([](const auto& proc) { return proc.status(); })));
                             })
      .def_property_readonly("bad_channel",
                             [](const P& p) { return p.visit([](const auto& proc) { return proc.bad_channel(); }); });
}

// ---- Codecs ------------------------------------------------------------------------------

const std::uint8_t* bytes_ptr(const py::bytes& b, std::size_t& n) {
  char* p = nullptr;
  py::ssize_t len = 0;
  PyBytes_AsStringAndSize(b.ptr(), &p, &len);
  n = static_cast<std::size_t>(len);
  return reinterpret_cast<const std::uint8_t*>(p);
}

py::bytes to_bytes(const std::uint8_t* p, std::size_t n) {
  return py::bytes(reinterpret_cast<const char*>(p), n);
}

py::dict serial_stats_dict(const serial::SerialParserStats& s) {
  py::dict d;
  d["bytes_in"] = s.bytes_in;
  d["frames_ok"] = s.frames_ok;
  d["discarded_bytes"] = s.discarded_bytes;
  d["garbage_bytes"] = s.garbage_bytes;
  d["bad_header"] = s.bad_header;
  d["crc_errors"] = s.crc_errors;
  d["truncated"] = s.truncated;
  d["overflow_bytes"] = s.overflow_bytes;
  return d;
}

py::dict can_stats_dict(const can::CanRxStats& s) {
  py::dict d;
  d["frames_in"] = s.frames_in;
  d["frames_used"] = s.frames_used;
  d["frames_dropped"] = s.frames_dropped;
  d["foreign_frames"] = s.foreign_frames;
  d["bad_dlc"] = s.bad_dlc;
  d["orphan_frames"] = s.orphan_frames;
  d["duplicate_frames"] = s.duplicate_frames;
  d["complete_samples"] = s.complete_samples;
  d["incomplete_samples"] = s.incomplete_samples;
  return d;
}

py::dict slcan_stats_dict(const slcan::SlcanStats& s) {
  py::dict d;
  d["bytes_in"] = s.bytes_in;
  d["lines"] = s.lines;
  d["frames"] = s.frames;
  d["commands"] = s.commands;
  d["malformed"] = s.malformed;
  d["overlong"] = s.overlong;
  d["bells"] = s.bells;
  return d;
}

py::tuple frame_tuple(const serial::ImuFrame& f) {
  py::tuple v(kImuChannels);
  for (std::size_t c = 0; c < kImuChannels; ++c) v[c] = static_cast<double>(f.values[c]);
  return py::make_tuple(f.type, f.seq, f.flags, f.t_us, v);
}

// A decode table from its text (the loop's --can-signals file); ValueError names the line.
can::SignalTable<> parse_signal_table(const std::string& text) {
  can::SignalTable<> table;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    const std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    can::SignalEntry e;
    can::PageSet pages;
    const char* error = "";
    const can::LineResult r = can::parse_table_line(line.c_str(), e, pages, &error);
    if (r == can::LineResult::kError) {
      throw py::value_error("can signal table line " + std::to_string(line_no) + ": bad " + error);
    }
    if (r == can::LineResult::kPages && !table.add_pages(pages)) {
      throw py::value_error("can signal table line " + std::to_string(line_no) +
                            ": pages of one message given twice");
    }
    if (r == can::LineResult::kEntry && !table.add(e)) {
      throw py::value_error("can signal table line " + std::to_string(line_no) +
                            ": role mapped twice");
    }
  }
  if (!table.complete()) throw py::value_error("can signal table: not all six channels mapped");
  return table;
}

can::CanFrame frame_from_tuple(const py::handle& item, const char* who) {
  const auto t = item.cast<py::tuple>();
  if (t.size() < 2) throw py::value_error(std::string(who) + ": each frame is (id, data[, extended, remote])");
  can::CanFrame fr;
  fr.id = t[0].cast<std::uint32_t>();
  const auto data = t[1].cast<py::bytes>();
  std::size_t n = 0;
  const std::uint8_t* p = bytes_ptr(data, n);
  if (n > 8) throw py::value_error(std::string(who) + ": classic CAN data is at most 8 bytes");
  fr.dlc = static_cast<std::uint8_t>(n);
  for (std::size_t i = 0; i < n; ++i) fr.data[i] = p[i];
  if (t.size() > 2) fr.extended = t[2].cast<bool>();
  if (t.size() > 3) fr.remote = t[3].cast<bool>();
  return fr;
}

const char* role_name(can::SignalRole r) {
  static constexpr std::array<const char*, can::kSignalRoles> kNames = {
      "gx", "gy", "gz", "ax", "ay", "az", "seq", "time"};
  return kNames[static_cast<std::size_t>(r)];
}

py::dict signal_stats_dict(const can::SignalRxStats& s) {
  py::dict d;
  d["frames_in"] = s.frames_in;
  d["frames_used"] = s.frames_used;
  d["frames_dropped"] = s.frames_dropped;
  d["foreign_frames"] = s.foreign_frames;
  d["ignored_frames"] = s.ignored_frames;
  d["undefined_page_frames"] = s.undefined_page_frames;
  d["bad_dlc"] = s.bad_dlc;
  d["complete_samples"] = s.complete_samples;
  d["incomplete_samples"] = s.incomplete_samples;
  return d;
}

// ---- Module contents ---------------------------------------------------------------------

// The processor contract (imu/imu_processor.hpp), the one source for Python, loop and harness.
void bind_contract(py::module_& m) {
  py::dict flag_bits;
  for (const ImuFlagName& f : kImuFlagNames) flag_bits[f.name] = f.bit;
  m.attr("IMU_FLAGS") = flag_bits;
  py::list keys;
  const ImuHealth h0{};
  for_each_health_field(h0, [&keys](const char* name, std::uint64_t) { keys.append(name); });
  m.attr("IMU_HEALTH_KEYS") = py::tuple(keys);
  py::list rejections;
  for_each_rejection_field(h0, [&rejections](const char* name, std::uint64_t) { rejections.append(name); });
  m.attr("IMU_REJECTION_KEYS") = py::tuple(rejections);
  m.attr("IMU_RESYNC_AFTER") = kImuResyncAfter;
  m.attr("IMU_DEMO_AR2") = py::dict(py::arg("a1") = ImuDemoAr2::a1, py::arg("a2") = ImuDemoAr2::a2,
                                    py::arg("sigma2") = ImuDemoAr2::sigma2, py::arg("mean") = ImuDemoAr2::mean,
                                    py::arg("q") = ImuDemoAr2::q, py::arg("r") = ImuDemoAr2::r);
  m.attr("IMU_DEFAULT_PERIOD_US") = kImuDefaultPeriodUs;
  m.attr("IMU_DEFAULT_TIME_TOLERANCE_US") = kImuDefaultTimeToleranceUs;
  m.attr("IMU_CHANNELS") = kImuChannels;
}

// ImuWaveletSettings, ImuChannelSettings, ImuProcessorSettings (in that order: each default
// and signature uses the one before).
void bind_processor_config(py::module_& m) {
  bind_wavelet_settings(m);
  bind_channel_settings(m);
  bind_processor_settings(m);
}

void bind_processors(py::module_& m) {
  bind_processor<double>(m, "ImuProcessor", "The six-channel IMU processor in float64 "
                         "(include/gyrodrift/imu/imu_processor.hpp), built from ImuProcessorSettings.");
  bind_processor<float>(m, "ImuProcessorF32", "The six-channel IMU processor in float32 (as on target), "
                        "built from ImuProcessorSettings.");
}

void bind_serial_codec(py::module_& m) {
  m.def("crc16_ccitt_false", [](const py::bytes& data) {
    std::size_t n = 0;
    const std::uint8_t* p = bytes_ptr(data, n);
    return crc16_ccitt_false(p, n);
  }, py::arg("data"));

  m.def("serial_encode_frame",
        [](std::uint8_t frame_type, std::uint16_t seq, std::uint16_t flags, std::uint64_t t_us,
           const std::array<float, kImuChannels>& values) {
          serial::ImuFrame f;
          f.type = frame_type;
          f.seq = seq;
          f.flags = flags;
          f.t_us = t_us;
          f.values = values;
          std::array<std::uint8_t, serial::kFrameSize> buf{};
          serial::encode_frame(f, buf.data(), buf.size());
          return to_bytes(buf.data(), buf.size());
        },
        py::arg("frame_type"), py::arg("seq"), py::arg("flags"), py::arg("t_us"), py::arg("values"));

  m.def("serial_parse",
        [](const py::bytes& data, std::size_t chunk, bool finish) {
          if (chunk == 0) throw py::value_error("chunk must be >= 1");
          std::size_t n = 0;
          const std::uint8_t* p = bytes_ptr(data, n);
          serial::SerialFrameParser<256> parser;
          std::vector<serial::ImuFrame> frames;
          serial::ImuFrame f;
          std::size_t pos = 0;
          while (pos < n) {
            // Offer only what fits (the rest is offered again after draining), so the
            // parser's overflow_bytes keeps its meaning: bytes refused for good (none here).
            const std::size_t room = parser.capacity() - parser.buffered();
            std::size_t want = n - pos < chunk ? n - pos : chunk;
            if (want > room) want = room;
            pos += parser.feed(p + pos, want);
            while (parser.next(f)) frames.push_back(f);
          }
          if (finish) parser.finish();
          py::list out;
          for (const auto& fr : frames) out.append(frame_tuple(fr));
          py::dict stats = serial_stats_dict(parser.stats());
          stats["buffered"] = parser.buffered();
          return py::make_tuple(out, stats);
        },
        py::arg("data"), py::arg("chunk") = 4096, py::arg("finish") = true);
}

void bind_can_codec(py::module_& m) {
  m.def("can_encode_sample",
        [](std::uint16_t seq, std::uint16_t flags, const std::array<float, kImuChannels>& values,
           std::uint32_t base_id) {
          can::CanSample s;
          s.seq = seq;
          s.flags = flags;
          s.values = values;
          std::array<can::CanFrame, can::kFramesPerSample> frames{};
          can::encode_sample(s, base_id, frames);
          py::list out;
          for (const auto& fr : frames) out.append(py::make_tuple(fr.id, to_bytes(fr.data.data(), fr.dlc)));
          return out;
        },
        py::arg("seq"), py::arg("flags"), py::arg("values"), py::arg("base_id") = can::kInputBaseId);

  m.def("can_assemble",
        [](const py::list& frames, std::uint32_t base_id, bool finish) {
          can::CanSampleAssembler<4> assembler(base_id);
          py::list samples;
          for (const py::handle& item : frames) {
            const can::CanFrame fr = frame_from_tuple(item, "can_assemble");
            can::CanSample s;
            if (assembler.push(fr, s)) {
              py::tuple v(kImuChannels);
              for (std::size_t c = 0; c < kImuChannels; ++c) v[c] = static_cast<double>(s.values[c]);
              samples.append(py::make_tuple(s.seq, s.flags, v));
            }
          }
          if (finish) assembler.finish();
          py::dict stats = can_stats_dict(assembler.stats());
          stats["pending_frames"] = assembler.pending_frames();
          return py::make_tuple(samples, stats);
        },
        py::arg("frames"), py::arg("base_id") = can::kInputBaseId, py::arg("finish") = true);
}

void bind_slcan(py::module_& m) {
  m.def("slcan_encode",
        [](std::uint32_t id, const py::bytes& data, bool extended, bool remote) {
          std::size_t n = 0;
          const std::uint8_t* p = bytes_ptr(data, n);
          if (n > 8) throw py::value_error("slcan_encode: classic CAN data is at most 8 bytes");
          can::CanFrame fr;
          fr.id = id;
          fr.dlc = static_cast<std::uint8_t>(n);
          fr.extended = extended;
          fr.remote = remote;
          for (std::size_t i = 0; i < n; ++i) fr.data[i] = p[i];
          std::array<char, slcan::kMaxFrameLine> line{};
          const std::size_t len = slcan::encode_frame(fr, line.data(), line.size());
          if (len == 0) throw py::value_error("slcan_encode: identifier out of range");
          return py::bytes(line.data(), len);
        },
        py::arg("id"), py::arg("data"), py::arg("extended") = false, py::arg("remote") = false);

  m.def("slcan_parse", [](const py::bytes& data) {
    std::size_t n = 0;
    const std::uint8_t* p = bytes_ptr(data, n);
    slcan::SlcanParser<> parser;
    slcan::Event ev;
    py::list events;
    std::array<char, 16> reply{};
    for (std::size_t i = 0; i < n; ++i) {
      if (!parser.push(p[i], ev)) continue;
      const std::size_t rn = slcan::command_reply(ev, reply.data(), reply.size());
      const py::bytes rep(reply.data(), rn);
      if (ev.kind == slcan::EventKind::kFrame) {
        events.append(py::make_tuple("frame", ev.frame.id, to_bytes(ev.frame.data.data(), ev.frame.remote ? 0 : ev.frame.dlc),
                                     ev.frame.extended, ev.frame.remote, rep));
      } else if (ev.kind == slcan::EventKind::kCommand) {
        events.append(py::make_tuple("command", std::string(1, ev.command),
                                     py::bytes(ev.arg.data(), ev.arg_len), rep));
      } else {
        events.append(py::make_tuple("error", rep));
      }
    }
    py::dict stats = slcan_stats_dict(parser.stats());
    stats["buffered"] = parser.buffered();
    return py::make_tuple(events, stats);
  }, py::arg("data"));
}

void bind_can_signals(py::module_& m) {
  m.def("can_signal_table", [](const std::string& text) {
    const can::SignalTable<> table = parse_signal_table(text);
    py::list out;
    for (std::size_t i = 0; i < table.size(); ++i) {
      const can::SignalEntry& e = table[i];
      py::dict d;
      d["role"] = role_name(e.role);
      d["id"] = e.id;
      d["extended"] = e.extended;
      d["dlc"] = e.dlc;
      d["start"] = e.field.start;
      d["length"] = e.field.length;
      d["order"] = e.field.order == can::ByteOrder::kIntel ? "le" : "be";
      static constexpr std::array<const char*, 4> kTypes = {"u", "s", "f32", "f64"};
      d["type"] = kTypes[static_cast<std::size_t>(e.type)];
      d["scale"] = e.scale;
      d["offset"] = e.offset;
      d["factor"] = e.factor;
      if (e.muxed) {
        d["mux"] = py::make_tuple(e.mux.start, e.mux.length,
                                  e.mux.order == can::ByteOrder::kIntel ? "le" : "be", e.mux_value);
      } else {
        d["mux"] = py::none();
      }
      out.append(d);
    }
    return out;
  }, py::arg("text"));

  m.def("can_signal_decode", [](const std::string& text, const py::list& frames) {
    const can::SignalTable<> table = parse_signal_table(text);
    py::list out;
    for (const py::handle& item : frames) {
      const can::CanFrame fr = frame_from_tuple(item, "can_signal_decode");
      py::dict d;
      for (std::size_t i = 0; i < table.size() && table.page_defined(fr); ++i) {
        double v = 0.0;
        if (can::decode_entry(table[i], fr, v) == can::EntryMatch::kValue) d[role_name(table[i].role)] = v;
      }
      out.append(d);
    }
    return out;
  }, py::arg("text"), py::arg("frames"));

  m.def("can_signal_assemble", [](const std::string& text, const py::list& frames, bool finish) {
    const can::SignalTable<> table = parse_signal_table(text);
    can::SignalSampleAssembler<> assembler(table);
    py::list samples;
    for (const py::handle& item : frames) {
      const can::CanFrame fr = frame_from_tuple(item, "can_signal_assemble");
      can::SignalSample s;
      if (assembler.push(fr, s)) {
        py::tuple v(kImuChannels);
        for (std::size_t c = 0; c < kImuChannels; ++c) v[c] = static_cast<double>(s.values[c]);
        samples.append(py::make_tuple(s.seq, s.has_time ? py::object(py::int_(s.t_us)) : py::object(py::none()), v));
      }
    }
    if (finish) assembler.finish();
    py::dict stats = signal_stats_dict(assembler.stats());
    stats["pending_frames"] = assembler.pending_frames();
    return py::make_tuple(samples, stats);
  }, py::arg("text"), py::arg("frames"), py::arg("finish") = true);
}

}  // namespace

void bind_imu(py::module_& m) {
  bind_contract(m);
  bind_monitor(m);  // bind_monitor.cpp: GyroMonitorSettings, GyroMonitorRun, GyroMonitorRunF32
  bind_processor_config(m);
  bind_processors(m);
  bind_serial_codec(m);
  bind_can_codec(m);
  bind_slcan(m);
  bind_can_signals(m);
}

}  // namespace gyrodrift::py_bindings
