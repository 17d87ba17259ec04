// Bindings of the lifting wavelet transform and the real-time wavelet prefilter.
//   wavedec_periodization(x, wavelet, level, inverse=False)   lifting DWT, Mallat layout
//   RealtimeWaveletConfig(wavelet=, window=, level=, mode=, channels=)   one bound
//       configuration struct (keyword-only, checked) for
//   RealtimeWaveletBankF64 / RealtimeWaveletBankF32(config)   per-channel real-time filters
#include <gyrodrift/filters/lifting_transform.hpp>
#include <gyrodrift/filters/realtime_wavelet.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "array_checks.hpp"
#include "bindings.hpp"

namespace gyrodrift::py_bindings {
namespace {

WaveletKind parse_wavelet(const std::string& name) {
  if (name == "db8") return WaveletKind::db8;
  if (name == "db4") return WaveletKind::db4;
  throw py::value_error("unsupported wavelet '" + name + "': the lifting core has 'db4' and 'db8'");
}

WaveletMode parse_mode(const std::string& name) {
  if (name == "forced") return WaveletMode::forced;
  if (name == "soft") return WaveletMode::soft;
  if (name == "hard") return WaveletMode::hard;
  throw py::value_error("unsupported mode '" + name + "': expected 'forced', 'soft' or 'hard'");
}

void check_levels(std::size_t n, int level) {
  if (level < 1 || level > kMaxWaveletLevel) {
    throw py::value_error("level must be in 1.." + std::to_string(kMaxWaveletLevel) + ", got " +
                          std::to_string(level));
  }
  if (n == 0 || n % (std::size_t{1} << static_cast<unsigned>(level)) != 0) {
    throw py::value_error("length " + std::to_string(n) + " is not a positive multiple of 2**level = " +
                          std::to_string(std::size_t{1} << static_cast<unsigned>(level)));
  }
}

// Multi-level periodized transform of a 1-D array (returns a new array, Mallat layout).
template <class T>
py::array_t<T> transform(const CArray<T>& x, const std::string& wavelet, int level, bool inverse) {
  const WaveletKind w = parse_wavelet(wavelet);
  if (x.ndim() != 1) throw py::value_error("x: expected a 1-D array");
  const auto n = static_cast<std::size_t>(x.shape(0));
  check_levels(n, level);
  require_finite(x.data(), n, "x");
  py::array_t<T> out(static_cast<py::ssize_t>(n));
  std::vector<T> scratch(n);
  T* o = out.mutable_data();
  const T* in = x.data();
  {
    py::gil_scoped_release release;
    std::copy(in, in + n, o);
    if (inverse) {
      LiftingTransform<T>::inverse(w, o, n, level, scratch.data());
    } else {
      LiftingTransform<T>::forward(w, o, n, level, scratch.data());
    }
  }
  return out;
}

// Type-erased channel bank over the compile-time window sizes.
template <class T>
struct AnyRealtime {
  virtual ~AnyRealtime() = default;
  virtual T step(T x) = 0;
  virtual T recompute_step(T x) = 0;  // same state machine, output from the full recompute
  virtual void reset() = 0;
  virtual bool ready() const = 0;
  virtual std::uint32_t faults() const = 0;
  virtual const T* taps() const = 0;
  virtual RealtimeWaveletStatus status() const = 0;
};

template <class T, std::size_t N>
struct RealtimeImpl final : AnyRealtime<T> {
  RealtimeImpl(WaveletKind w, int level, WaveletMode mode) : f(w, level, mode) {}
  T step(T x) override { return f.step(x); }
  T recompute_step(T x) override {
    const T fast = f.step(x);
    if (!RealtimeWavelet<T, N>::accepts(x)) return fast;
    hist[hpos] = x;  // the newest N accepted samples, rebuilt oldest-first by window()
    hpos = (hpos + 1) % N;
    if (!f.ready() || f.status() != RealtimeWaveletStatus::ok) return fast;
    return f.recompute(window());
  }
  const T* window() {
    for (std::size_t i = 0; i < N; ++i) win[i] = hist[(hpos + i) % N];
    return win;
  }
  void reset() override {
    f.reset();
    hpos = 0;
  }
  bool ready() const override { return f.ready(); }
  std::uint32_t faults() const override { return f.fault_count(); }
  const T* taps() const override { return f.taps(); }
  RealtimeWaveletStatus status() const override { return f.status(); }
  RealtimeWavelet<T, N> f;
  T hist[N] = {};
  T win[N] = {};
  std::size_t hpos = 0;
};

template <class T>
std::unique_ptr<AnyRealtime<T>> make_realtime(std::size_t window, WaveletKind w, int level, WaveletMode m) {
  switch (window) {
    case 8: return std::make_unique<RealtimeImpl<T, 8>>(w, level, m);
    case 16: return std::make_unique<RealtimeImpl<T, 16>>(w, level, m);
    case 32: return std::make_unique<RealtimeImpl<T, 32>>(w, level, m);
    case 64: return std::make_unique<RealtimeImpl<T, 64>>(w, level, m);
    case 128: return std::make_unique<RealtimeImpl<T, 128>>(w, level, m);
    case 256: return std::make_unique<RealtimeImpl<T, 256>>(w, level, m);
    case 512: return std::make_unique<RealtimeImpl<T, 512>>(w, level, m);
    case 1024: return std::make_unique<RealtimeImpl<T, 1024>>(w, level, m);
    case 2048: return std::make_unique<RealtimeImpl<T, 2048>>(w, level, m);
    default:
      throw py::value_error("window must be a power of two in 8..2048, got " + std::to_string(window));
  }
}

// The configuration of a real-time filter bank as one bound object
// (gyrodrift._core.RealtimeWaveletConfig): wavelet ('db4' or 'db8'), window (a power of two in
// 8..2048), level (1..the window's maximum), mode ('forced', 'soft' or 'hard') and channels
// (1 or 3). Checked when built and again by the bank (the fields are writable).
struct RealtimeWaveletConfig {
  std::string wavelet{"db4"};
  std::size_t window{256};
  int level{1};
  std::string mode{"forced"};
  std::size_t channels{1};

  void check() const {
    const WaveletKind w = parse_wavelet(wavelet);
    parse_mode(mode);
    if (channels != 1 && channels != 3) {
      throw py::value_error("channels must be 1 or 3, got " + std::to_string(channels));
    }
    if (window < 8 || window > 2048 || (window & (window - 1)) != 0) {
      throw py::value_error("window must be a power of two in 8..2048, got " + std::to_string(window));
    }
    const int max_level = realtime_wavelet_max_level(window, w);
    if (level < 1 || level > max_level) {
      throw py::value_error("level " + std::to_string(level) + " is out of range for window " +
                            std::to_string(window) + " and " + wavelet + ": need 1 <= level <= " +
                            std::to_string(max_level) + " (pywt.dwt_max_level(2*window, filter length))");
    }
  }
};

// A bank of identical per-channel filters (1 channel for (n,) input, 3 for (n, 3)).
template <class T>
class RealtimeBank {
 public:
  explicit RealtimeBank(const RealtimeWaveletConfig& c) : window_(c.window) {
    c.check();
    const WaveletKind w = parse_wavelet(c.wavelet);
    const WaveletMode m = parse_mode(c.mode);
    for (std::size_t k = 0; k < c.channels; ++k) {
      ch_.push_back(make_realtime<T>(c.window, w, c.level, m));
    }
  }

  std::size_t channels() const { return ch_.size(); }

  py::array_t<T> filter(const CArray<T>& x, bool recompute) {
    const std::size_t n = require_1d_or_n3(x, "x");
    const std::size_t nch = x.ndim() == 1 ? 1 : 3;
    if (nch != ch_.size()) {
      throw py::value_error("this filter has " + std::to_string(ch_.size()) + " channel(s), got " +
                            (x.ndim() == 1 ? std::string("a 1-D array") : std::string("an (n, 3) array")));
    }
    py::array_t<T> out(x.request().shape);
    const T* in = x.data();
    T* o = out.mutable_data();
    {
      ReleasedAndLocked guard(this);  // GIL released, then this bank's lock
      for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t c = 0; c < nch; ++c) {
          auto& f = *ch_[c];
          o[i * nch + c] = recompute ? f.recompute_step(in[i * nch + c]) : f.step(in[i * nch + c]);
        }
      }
    }
    return out;
  }

  void reset() {
    ReleasedAndLocked guard(this);
    for (auto& c : ch_) c->reset();
  }
  bool ready() const {
    ReleasedAndLocked guard(this);
    return ch_[0]->ready();
  }
  py::array_t<std::uint32_t> faults() const {
    std::vector<std::uint32_t> counts(ch_.size());
    {
      ReleasedAndLocked guard(this);
      for (std::size_t c = 0; c < ch_.size(); ++c) counts[c] = ch_[c]->faults();
    }
    py::array_t<std::uint32_t> out(static_cast<py::ssize_t>(ch_.size()));
    std::copy(counts.begin(), counts.end(), out.mutable_data());
    return out;
  }
  py::array_t<T> taps() const {
    py::array_t<T> out(static_cast<py::ssize_t>(window_));
    std::copy(ch_[0]->taps(), ch_[0]->taps() + window_, out.mutable_data());
    return out;
  }

 private:
  std::size_t window_;
  std::vector<std::unique_ptr<AnyRealtime<T>>> ch_;
};

template <class T>
void bind_bank(py::module_& m, const char* name) {
  py::class_<RealtimeBank<T>>(m, name,
                              "Per-channel real-time sliding-window wavelet filters (C++ core); "
                              "see include/gyrodrift/filters/realtime_wavelet.hpp")
      .def(py::init<const RealtimeWaveletConfig&>(), py::arg("config"))
      .def("filter", &RealtimeBank<T>::filter, py::arg("x").noconvert(), py::arg("recompute") = false,
           "Filter (n,) or (n, 3) samples, continuing the stream; recompute=True takes every "
           "output from the full window recompute instead of the streaming path")
      .def("reset", &RealtimeBank<T>::reset)
      .def_property_readonly("ready", &RealtimeBank<T>::ready)
      .def_property_readonly("channels", &RealtimeBank<T>::channels)
      .def("fault_counts", &RealtimeBank<T>::faults)
      .def("taps", &RealtimeBank<T>::taps);
}

}  // namespace

void bind_wavelet(pybind11::module_& m) {
  py::class_<RealtimeWaveletConfig>(m, "RealtimeWaveletConfig",
                                    "Configuration of a real-time wavelet filter bank: wavelet "
                                    "('db4' or 'db8'), window (power of two, 8..2048), level, "
                                    "mode ('forced', 'soft' or 'hard'), channels (1 or 3). "
                                    "Keyword-only; checked when built and by the bank.")
      .def(py::init([](const std::string& wavelet, std::size_t window, int level,
                       const std::string& mode, std::size_t channels) {
             RealtimeWaveletConfig c{wavelet, window, level, mode, channels};
             c.check();
             return c;
           }),
           py::kw_only(), py::arg("wavelet"), py::arg("window"), py::arg("level"),
           py::arg("mode") = "forced", py::arg("channels") = 1)
      .def_readwrite("wavelet", &RealtimeWaveletConfig::wavelet)
      .def_readwrite("window", &RealtimeWaveletConfig::window)
      .def_readwrite("level", &RealtimeWaveletConfig::level)
      .def_readwrite("mode", &RealtimeWaveletConfig::mode)
      .def_readwrite("channels", &RealtimeWaveletConfig::channels)
      .def("__repr__", [](const RealtimeWaveletConfig& c) {
        return "RealtimeWaveletConfig(wavelet='" + c.wavelet + "', window=" +
               std::to_string(c.window) + ", level=" + std::to_string(c.level) + ", mode='" +
               c.mode + "', channels=" + std::to_string(c.channels) + ")";
      });
  m.def("wavedec_periodization", &transform<double>, py::arg("x").noconvert(), py::arg("wavelet"),
        py::arg("level"), py::arg("inverse") = false,
        "Lifting DWT (or inverse) in Mallat layout = concatenate(pywt.wavedec(x, w, 'periodization', level))");
  m.def("wavedec_periodization", &transform<float>, py::arg("x").noconvert(), py::arg("wavelet"),
        py::arg("level"), py::arg("inverse") = false);
  m.def("realtime_wavelet_max_level", [](std::size_t window, const std::string& wavelet) {
    return realtime_wavelet_max_level(window, parse_wavelet(wavelet));
  });
  bind_bank<double>(m, "RealtimeWaveletBankF64");
  bind_bank<float>(m, "RealtimeWaveletBankF32");
}

}  // namespace gyrodrift::py_bindings
