// gyrodrift._core: IMU processor and the frame codecs (serial, CAN, SLCAN).
//
// Low-level, strict API (gyrodrift.imu adds the config dataclasses and messages):
//   ImuProcessor / ImuProcessorF32(filters[6], bias[6], a1[6], a2[6], sigma2[6], mean[6],
//       q[6], r[6], p0[6], saturation[6], stuck_samples[6], period_us, time_tolerance_us)
//     .process(seq u16[n], t_us u64[n], values (n, 6) float64|float32)
//         -> (out (n, 6), flags u16[n])   rows with flags & 0x8000 (rejected) are NaN
//     .health() -> dict, .reset(), .status -> str
//     keyword-only extras: filters2[6] (second stage, 0 = none), steady_state[6] (bool)
//   ImuProcessorWavelet / ImuProcessorWaveletF32(..., wavelet "db4"|"db8", level, mode
//       "forced"|"soft"|"hard"[, channel_wavelets=[(wavelet, window, level, mode) or None] * 6,
//       window=256]): the same with RealtimeWavelet<T, window> as the wavelet stage (window a
//       power of two in 16..4096, chosen per channel at construction: RealtimeWaveletAnyWindow)
//   IMU_FLAGS {name: bit}, IMU_HEALTH_KEYS, IMU_REJECTION_KEYS (tuples), IMU_RESYNC_AFTER, IMU_DEFAULT_PERIOD_US,
//   IMU_DEFAULT_TIME_TOLERANCE_US, IMU_DEMO_AR2 {a1 a2 sigma2 mean q r}: the processor contract
//   from imu/imu_processor.hpp
//   crc16_ccitt_false(bytes) -> int
//   serial_encode_frame(frame_type, seq, flags, t_us, values[6]) -> bytes
//   serial_parse(data, chunk, finish) -> (frames list, stats dict)   (C++ parser, 256-B buffer)
//   can_encode_sample(seq, flags, values[6], base_id) -> [(id, bytes)] * 4
//   can_assemble(frames [(id, data[, extended, remote])], base_id, finish) -> (samples, stats)
//   slcan_encode(id, data, extended, remote) -> bytes
//   can_signal_table(text) -> [entry dict]            (a user-DBC decode table, parsed in C++)
//   can_signal_decode(text, frames) -> [{role: value}] per frame (codecs/can_signal_decode.hpp)
//   can_signal_assemble(text, frames, finish) -> ([(seq, t_us | None, values)], stats)
//   slcan_parse(data) -> (events, stats)   events: ("frame", id, data, ext, rtr, reply) |
//                                          ("command", letter, arg bytes, reply) | ("error", reply)
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
#include <gyrodrift/imu/imu_processor.hpp>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {

namespace {

using Six = std::array<double, kImuChannels>;
using SixInt = std::array<int, kImuChannels>;
using SixBool = std::array<bool, kImuChannels>;

const char* status_name(ImuStatus s) {
  switch (s) {
    case ImuStatus::ok: return "ok";
    case ImuStatus::bad_channel_config: return "bad channel config";
    case ImuStatus::wavelet_unavailable: return "wavelet unavailable";
    case ImuStatus::bad_timing: return "period_us is 0 while the timestamp check is on";
  }
  return "unknown";
}

template <class T>
ImuConfig<T> make_config(const std::array<int, kImuChannels>& filters, const Six& bias, const Six& a1,
                         const Six& a2, const Six& sigma2, const Six& mean, const Six& q, const Six& r,
                         const Six& p0, const Six& saturation,
                         const std::array<std::uint32_t, kImuChannels>& stuck, std::uint32_t period_us,
                         std::uint32_t tol_us, const std::optional<SixInt>& filters2,
                         const std::optional<SixBool>& steady_state) {
  ImuConfig<T> cfg;
  for (std::size_t c = 0; c < kImuChannels; ++c) {
    if (filters[c] < 0 || filters[c] > 3) {
      throw py::value_error("filters[" + std::to_string(c) + "]: expected 0..3 (pass_through, "
                            "bias_removal, ar2_kalman, wavelet), got " + std::to_string(filters[c]));
    }
    ImuChannelConfig<T>& cc = cfg.channels[c];
    cc.filter = static_cast<ChannelFilter>(filters[c]);
    if (filters2) {
      const int f2 = (*filters2)[c];
      if (f2 < 0 || f2 > 3) {
        throw py::value_error("filters2[" + std::to_string(c) + "]: expected 0..3, got " + std::to_string(f2));
      }
      cc.filter2 = static_cast<ChannelFilter>(f2);
    }
    if (steady_state) cc.steady_state = (*steady_state)[c];
    cc.bias = static_cast<T>(bias[c]);
    cc.model = Ar2Model<T>{static_cast<T>(a1[c]), static_cast<T>(a2[c]), static_cast<T>(sigma2[c]),
                           static_cast<T>(mean[c])};
    cc.q = static_cast<T>(q[c]);
    cc.r = static_cast<T>(r[c]);
    cc.p0 = static_cast<T>(p0[c]);
    cc.saturation = static_cast<T>(saturation[c]);
    cc.stuck_samples = stuck[c];
  }
  cfg.period_us = period_us;
  cfg.time_tolerance_us = tol_us;
  return cfg;
}

py::dict health_dict(const ImuHealth& h) {
  py::dict d;
  for_each_health_field(h, [&d](const char* name, std::uint64_t v) { d[name] = v; });
  return d;
}

// The wavelet stage over every window of the configuration format (16..4096), chosen per
// channel at construction; the filter itself is RealtimeWavelet<T, N> for that window.
template <class T>
using WaveletStage = RealtimeWaveletAnyWindow<T>;

// One wavelet stage's settings, checked; ValueError "<who>.window: ..." / "<who>.level: ..."
// (who empty: the shared wavelet arguments) in the configuration reader's wording.
struct WaveletSpec {
  WaveletKind kind = WaveletKind::db8;
  std::size_t window = 256;
  int level = 5;
  WaveletMode mode = WaveletMode::forced;
};

WaveletSpec wavelet_spec(const std::string& who, const std::string& wavelet, long long window, int level,
                         const std::string& mode) {
  const std::string at = who.empty() ? "" : who + ".";
  WaveletSpec w;
  if (wavelet == "db4") w.kind = WaveletKind::db4;
  else if (wavelet != "db8") throw py::value_error(at + "wavelet: expected 'db4' or 'db8', got '" + wavelet + "'");
  if (mode == "soft") w.mode = WaveletMode::soft;
  else if (mode == "hard") w.mode = WaveletMode::hard;
  else if (mode != "forced") throw py::value_error(at + "mode: expected 'forced', 'soft' or 'hard', got '" + mode + "'");
  if (!config_wavelet_window_ok(window)) {
    throw py::value_error(at + "window: expected a power of two in 16..4096, got " + std::to_string(window));
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

template <class T, class Proc, class Cls>
void def_processor_methods(Cls& cls) {
  cls.def(
         "process",
         [](Proc& p, const CArray<std::uint16_t>& seq, const CArray<std::uint64_t>& t_us,
            const CArray<T>& values) {
           if (values.ndim() != 2 || values.shape(1) != static_cast<py::ssize_t>(kImuChannels)) {
             throw py::value_error("values: expected an (n, 6) array, got ndim=" +
                                   std::to_string(values.ndim()));
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
           return py::make_tuple(out, flags);
         },
         py::arg("seq").noconvert(), py::arg("t_us").noconvert(), py::arg("values").noconvert())
      .def("health",
           [](const Proc& p) {
             ImuHealth h;
             {
               ReleasedAndLocked guard(&p);
               h = p.health();
             }
             return health_dict(h);
           })
      .def("reset",
           [](Proc& p) {
             ReleasedAndLocked guard(&p);
             p.reset();
           })
      .def_property_readonly("status", [](const Proc& p) { return std::string(status_name(p.status())); })
      .def_property_readonly("bad_channel", &Proc::bad_channel);
}

template <class T>
void bind_processor(py::module_& m, const char* name) {
  using Proc = ImuProcessor<T>;
  py::class_<Proc> cls(m, name);
  cls.def(py::init([](const std::array<int, kImuChannels>& filters, const Six& bias, const Six& a1,
                      const Six& a2, const Six& sigma2, const Six& mean, const Six& q, const Six& r,
                      const Six& p0, const Six& saturation,
                      const std::array<std::uint32_t, kImuChannels>& stuck, std::uint32_t period_us,
                      std::uint32_t tol_us, const std::optional<SixInt>& filters2,
                      const std::optional<SixBool>& steady_state) {
            return Proc(make_config<T>(filters, bias, a1, a2, sigma2, mean, q, r, p0, saturation,
                                       stuck, period_us, tol_us, filters2, steady_state));
          }),
          py::arg("filters"), py::arg("bias"), py::arg("a1"), py::arg("a2"), py::arg("sigma2"),
          py::arg("mean"), py::arg("q"), py::arg("r"), py::arg("p0"), py::arg("saturation"),
          py::arg("stuck_samples"), py::arg("period_us"), py::arg("time_tolerance_us"), py::kw_only(),
          py::arg("filters2") = py::none(), py::arg("steady_state") = py::none());
  def_processor_methods<T, Proc>(cls);
}

template <class T>
void bind_wavelet_processor(py::module_& m, const char* name) {
  using Proc = ImuProcessor<T, WaveletStage<T>>;
  py::class_<Proc> cls(m, name);
  using ChannelWavelet = std::tuple<std::string, long long, int, std::string>;  // wavelet, window, level, mode
  cls.def(py::init([](const std::array<int, kImuChannels>& filters, const Six& bias, const Six& a1,
                      const Six& a2, const Six& sigma2, const Six& mean, const Six& q, const Six& r,
                      const Six& p0, const Six& saturation,
                      const std::array<std::uint32_t, kImuChannels>& stuck, std::uint32_t period_us,
                      std::uint32_t tol_us, const std::string& wavelet, int level, const std::string& mode,
                      const std::optional<SixInt>& filters2, const std::optional<SixBool>& steady_state,
                      const std::optional<std::vector<std::optional<ChannelWavelet>>>& channel_wavelets,
                      long long window) {
            // Six wavelet stages sized for the largest window: keep the processor on the heap.
            const ImuConfig<T> cfg = make_config<T>(filters, bias, a1, a2, sigma2, mean, q, r, p0, saturation,
                                                    stuck, period_us, tol_us, filters2, steady_state);
            std::array<WaveletSpec, kImuChannels> specs;
            specs.fill(wavelet_spec("", wavelet, window, level, mode));
            if (channel_wavelets) {
              if (channel_wavelets->size() != kImuChannels) {
                throw py::value_error("channel_wavelets: expected 6 entries (None or (wavelet, window, level, mode))");
              }
              for (std::size_t c = 0; c < kImuChannels; ++c) {
                const auto& e = (*channel_wavelets)[c];
                if (e) {
                  specs[c] = wavelet_spec("channel_wavelets[" + std::to_string(c) + "]", std::get<0>(*e),
                                          std::get<1>(*e), std::get<2>(*e), std::get<3>(*e));
                }
              }
            }
            // Each stage built in place in the processor (no window-sized temporaries).
            return std::make_unique<Proc>(cfg, [&specs](std::size_t c) {
              const WaveletSpec& w = specs[c];
              return WaveletStage<T>(w.window, w.kind, w.level, w.mode);
            });
          }),
          py::arg("filters"), py::arg("bias"), py::arg("a1"), py::arg("a2"), py::arg("sigma2"),
          py::arg("mean"), py::arg("q"), py::arg("r"), py::arg("p0"), py::arg("saturation"),
          py::arg("stuck_samples"), py::arg("period_us"), py::arg("time_tolerance_us"),
          py::arg("wavelet"), py::arg("level"), py::arg("mode"), py::kw_only(),
          py::arg("filters2") = py::none(), py::arg("steady_state") = py::none(),
          py::arg("channel_wavelets") = py::none(), py::arg("window") = 256);
  def_processor_methods<T, Proc>(cls);
}

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
    const char* error = "";
    const can::LineResult r = can::parse_signal_line(line.c_str(), e, &error);
    if (r == can::LineResult::kError) {
      throw py::value_error("can signal table line " + std::to_string(line_no) + ": bad " + error);
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
  d["bad_dlc"] = s.bad_dlc;
  d["complete_samples"] = s.complete_samples;
  d["incomplete_samples"] = s.incomplete_samples;
  return d;
}

}  // namespace

void bind_imu(py::module_& m) {
  // The processor contract (imu/imu_processor.hpp), the one source for Python, loop and harness.
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

  bind_processor<double>(m, "ImuProcessor");
  bind_processor<float>(m, "ImuProcessorF32");
  bind_wavelet_processor<double>(m, "ImuProcessorWavelet");
  bind_wavelet_processor<float>(m, "ImuProcessorWaveletF32");

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
            const auto t = item.cast<py::tuple>();
            if (t.size() < 2) throw py::value_error("can_assemble: each frame is (id, data[, extended, remote])");
            can::CanFrame fr;
            fr.id = t[0].cast<std::uint32_t>();
            const auto data = t[1].cast<py::bytes>();
            std::size_t n = 0;
            const std::uint8_t* p = bytes_ptr(data, n);
            if (n > 8) throw py::value_error("can_assemble: classic CAN data is at most 8 bytes");
            fr.dlc = static_cast<std::uint8_t>(n);
            for (std::size_t i = 0; i < n; ++i) fr.data[i] = p[i];
            if (t.size() > 2) fr.extended = t[2].cast<bool>();
            if (t.size() > 3) fr.remote = t[3].cast<bool>();
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
      for (std::size_t i = 0; i < table.size(); ++i) {
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

}  // namespace gyrodrift::py_bindings
