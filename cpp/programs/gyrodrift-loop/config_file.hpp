// The processor configuration file (version 1, README "Processor configuration file") read by
// `gyrodrift-loop --config FILE` and `--check-config FILE`, and the built-in default
// configuration (config_schema::kDefaultConfigToml) read by the same code.
//
// Every field is read through its FieldSpec (include/gyrodrift/imu/config_schema.hpp,
// generated from python/gyrodrift/imu/schema.py): required or its default (an optional field
// without a default is derived, as its help says), its kind, its bounds, with the error
// "<key>: expected <bounds_text>, got <value>" naming the same key as the Python reader
// (gyrodrift/imu/config.py). The relations between fields (AR(2) stationarity, the wavelet
// level for the wavelet and window, the stage combinations) and the wrong-units and
// unknown-key errors follow the Python reader too (tests/test_config_schema.py,
// tests/test_config_file.py).
//
// Program code (standard library allowed): the header-only core stays free of parsing.
#pragma once
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include <gyrodrift/filters/realtime_wavelet.hpp>
#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/config_schema.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

#include "toml_subset.hpp"

namespace gyrodrift::loop {

namespace schema = gyrodrift::config_schema;

// The loop builds every window the schema allows, and every level it allows.
static_assert(schema::kWaveletWindow.lo == static_cast<double>(kConfigMinWaveletWindow) &&
                  schema::kWaveletWindow.hi == static_cast<double>(kConfigMaxWaveletWindow),
              "the schema's wavelet windows are the ones RealtimeWaveletAnyWindow holds");
static_assert(schema::kWaveletLevel.hi == static_cast<double>(kMaxWaveletLevel), "wavelet levels");
static_assert(schema::kMaxStages == 2, "ImuChannelConfig holds two stages");
static_assert(sizeof(schema::kChannelNames) / sizeof(schema::kChannelNames[0]) == kImuChannels, "six channels");

// One channel's wavelet stage as read from the file (used only if the chain has one).
// Defaults: the paper's prefilter (schema kPrefilter*); a stage read from a file sets them all.
struct WaveletSpec {
  WaveletKind kind = WaveletKind::db4;
  int level = schema::kPrefilterLevel;
  WaveletMode mode = WaveletMode::forced;
  std::size_t window = schema::kPrefilterWindow;
};

struct FileConfig {
  ImuConfig<float> imu;
  std::array<WaveletSpec, kImuChannels> wavelets{};
  double sample_rate_hz = schema::kDefaultSampleRateHz;  // timing.sample_rate_hz
  double loop_rate_hz = schema::kDefaultSampleRateHz;    // timing.loop_rate_hz (absent: the sample rate)
};

namespace detail {

inline bool is_gyro(const std::string& channel) { return !channel.empty() && channel[0] == 'g'; }

// The key suffix of a channel's unit ("" outside a channel).
inline std::string unit_suffix(const std::string& channel) {
  if (channel.empty()) return "";
  return is_gyro(channel) ? "_rad_s" : "_m_s2";
}

inline std::string wrong_units_message(const std::string& base, const std::string& channel) {
  return std::string("wrong units for a") +
         (is_gyro(channel) ? " gyro channel (rad/s)" : "n accelerometer channel (m/s^2)") + ": use " + base +
         unit_suffix(channel);
}

// Suffixes that name a unit the processor refuses (a key with one gets a wrong-units error).
inline constexpr const char* kOtherSuffixes[] = {"_deg_s", "_deg_h", "_rad_h", "_mrad_s", "_g",
                                                 "_mg",    "_ug",    "_ft_s2", "_rad_s",  "_m_s2"};

inline bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

inline const char* kind_words(schema::FieldKind kind) {
  switch (kind) {
    case schema::FieldKind::integer:
      return "an integer";
    case schema::FieldKind::boolean:
      return "true or false";
    case schema::FieldKind::string:
      return "a string";
    case schema::FieldKind::number:
    default:
      return "a number";
  }
}

inline bool kind_ok(schema::FieldKind kind, const toml::Value& v) {
  using K = toml::Value::Kind;
  switch (kind) {
    case schema::FieldKind::integer:
      return v.kind == K::integer;
    case schema::FieldKind::boolean:
      return v.kind == K::boolean;
    case schema::FieldKind::string:
      return v.kind == K::string;
    case schema::FieldKind::number:
    default:
      return v.kind == K::integer || v.kind == K::floating;
  }
}

inline bool in_choices(const char* choices, const std::string& s) {
  std::string rest = choices;
  for (std::size_t bar = 0; bar != std::string::npos; rest.erase(0, bar + 1)) {
    bar = rest.find('|');
    if (rest.substr(0, bar) == s) return true;
  }
  return false;
}

// The field's own bounds (relations between fields are checked apart), as
// gyrodrift.imu.schema.Field.accepts.
inline bool accepts(const schema::FieldSpec& f, const toml::Value& v) {
  if (f.choices[0] != '\0') return in_choices(f.choices, v.s);
  if (f.kind == schema::FieldKind::boolean || f.kind == schema::FieldKind::string) return true;
  const double x = v.d;
  if (std::isnan(x) || (f.finite && std::isinf(x))) return false;
  if (f.lo_open ? x <= f.lo : x < f.lo) return false;
  if (f.hi_open ? x >= f.hi : x > f.hi) return false;
  if (f.power_of_two) return v.i > 0 && (v.i & (v.i - 1)) == 0;
  return true;
}

// A field's value: from the file, or the field's default; `given` false: absent and without a
// default (derived, as the field's help says).
struct FieldValue {
  bool given = false;
  double number = 0.0;    // number and integer fields
  long long integer = 0;  // integer fields
  bool boolean = false;
  std::string text;  // string fields
};

// Reads the document's keys table by table and remembers which it read: what nothing read is
// an unknown key.
class Reader {
 public:
  explicit Reader(const toml::Doc& doc) : doc_(doc) {}

  // Field `f` of `table` ("timing", "channels.gx", "channels.gx.stages[1]"; `channel` names the
  // channel for the unit suffix, "" outside one). `own_bounds` false: the caller checks the
  // value (a bound that depends on other fields).
  bool field(const schema::FieldSpec& f, const std::string& table, const std::string& channel, FieldValue& out,
             std::string& err, bool own_bounds = true) {
    out = FieldValue{};
    const std::string name = std::string(f.name) + (f.channel_unit ? unit_suffix(channel) : "");
    const std::string key = table + "." + name;
    if (f.channel_unit && wrong_units(table, f.name, channel, err)) return false;
    const auto it = doc_.values.find(key);
    if (it == doc_.values.end()) {
      if (f.required) {
        err = key + ": missing value";
        return false;
      }
      if (f.has_default) set_default(f, out);
      return true;
    }
    used_.insert(key);
    const toml::Value& v = it->second;
    if (!kind_ok(f.kind, v)) {
      err = key + ": expected " + kind_words(f.kind) + ", got " + toml::repr(v);
      return false;
    }
    if (own_bounds && !accepts(f, v)) {
      err = key + ": expected " + f.bounds_text + ", got " + toml::repr(v);
      return false;
    }
    out.given = true;
    out.number = v.d;
    out.integer = v.i;
    out.boolean = v.b;
    out.text = v.s;
    return true;
  }

  // A required string that is not a schema field (schema, a stage's type).
  bool text(const std::string& key, std::string& out, std::string& err) {
    const toml::Value* v = required(key, toml::Value::Kind::string, "a string", err);
    if (v != nullptr) out = v->s;
    return v != nullptr;
  }

  // A required integer that is not a schema field (version).
  bool integer(const std::string& key, long long& out, std::string& err) {
    const toml::Value* v = required(key, toml::Value::Kind::integer, "an integer", err);
    if (v != nullptr) out = v->i;
    return v != nullptr;
  }

  // Marks every key under `prefix` read (free-form tables such as [meta]).
  void skip(const std::string& prefix) {
    for (const auto& kv : doc_.values) {
      if (kv.first.rfind(prefix, 0) == 0) used_.insert(kv.first);
    }
  }

  // The first key directly in `table` that nothing read: unknown, or (in a channel's tables)
  // a key with another unit's suffix.
  bool unread_key(const std::string& table, const std::string& channel, std::string& err) const {
    const std::string prefix = table + ".";
    for (const auto& kv : doc_.values) {
      if (kv.first.rfind(prefix, 0) != 0 || used_.count(kv.first) != 0) continue;
      const std::string name = kv.first.substr(prefix.size());
      err = kv.first + ": unknown key";
      if (channel.empty()) return true;
      for (const char* suffix : kOtherSuffixes) {
        if (ends_with(name, suffix) && suffix != unit_suffix(channel)) {
          err = kv.first + ": " + wrong_units_message(name.substr(0, name.size() - std::strlen(suffix)), channel);
          return true;
        }
      }
      return true;
    }
    return false;
  }

  // The first key of the whole document that nothing read.
  bool unread_key(std::string& err) const {
    for (const auto& kv : doc_.values) {
      if (used_.count(kv.first) == 0) {
        err = kv.first + ": unknown key";
        return true;
      }
    }
    return false;
  }

 private:
  static void set_default(const schema::FieldSpec& f, FieldValue& out) {
    out.given = true;
    out.text = f.default_text;
    if (f.kind == schema::FieldKind::boolean) out.boolean = f.default_value != 0.0;
    else out.number = f.default_value;
    if (f.kind == schema::FieldKind::integer) out.integer = static_cast<long long>(f.default_value);
  }

  const toml::Value* required(const std::string& key, toml::Value::Kind kind, const char* words, std::string& err) {
    const auto it = doc_.values.find(key);
    if (it == doc_.values.end()) {
      err = key + ": missing value";
      return nullptr;
    }
    used_.insert(key);
    if (it->second.kind != kind) {
      err = key + ": expected " + words + ", got " + toml::repr(it->second);
      return nullptr;
    }
    return &it->second;
  }

  // `base` given with another unit's suffix (and not with this channel's): the wrong-units
  // error for that key, rather than "missing value".
  bool wrong_units(const std::string& table, const std::string& base, const std::string& channel,
                   std::string& err) const {
    const std::string want = unit_suffix(channel);
    if (doc_.values.count(table + "." + base + want) != 0) return false;
    for (const char* suffix : kOtherSuffixes) {
      const std::string key = table + "." + base + suffix;
      if (want == suffix || doc_.values.count(key) == 0) continue;
      err = key + ": " + wrong_units_message(base, channel);
      return true;
    }
    return false;
  }

  const toml::Doc& doc_;
  std::set<std::string> used_;
};

inline bool stage_type(const std::string& s, ChannelFilter& f) {
  if (s == "pass_through") f = ChannelFilter::pass_through;
  else if (s == "bias_removal") f = ChannelFilter::bias_removal;
  else if (s == "ar2_kalman") f = ChannelFilter::ar2_kalman;
  else if (s == "wavelet") f = ChannelFilter::wavelet;
  else return false;
  return true;
}

inline const char* stage_name(ChannelFilter f) {
  switch (f) {
    case ChannelFilter::bias_removal:
      return "bias_removal";
    case ChannelFilter::ar2_kalman:
      return "ar2_kalman";
    case ChannelFilter::wavelet:
      return "wavelet";
    case ChannelFilter::pass_through:
    default:
      return "pass_through";
  }
}

// ---------------------------------------------------------------- one section each

inline bool read_header(Reader& rd, const toml::Doc& doc, std::string& err) {
  std::string schema_name;
  long long version = 0;
  if (!rd.text("schema", schema_name, err)) return false;
  if (schema_name != schema::kSchema) {
    err = std::string("schema: expected '") + schema::kSchema + "', got '" + schema_name + "'";
    return false;
  }
  if (!rd.integer("version", version, err)) return false;
  if (version != schema::kVersion) {
    err = "version: this gyrodrift-loop reads version " + std::to_string(schema::kVersion) + ", got " +
          std::to_string(version);
    return false;
  }
  if (doc.values.count("meta") != 0) {
    err = "meta: expected a table";
    return false;
  }
  rd.skip("meta.");  // free-form (who wrote the file, from which record), not read
  return true;
}

// [timing]: the sample rate (the timestamps' nominal period), the timestamp tolerance
// (absent: half a period) and the loop rate (absent: the sample rate).
inline bool read_timing(Reader& rd, const toml::Doc& doc, FileConfig& fc, std::string& err) {
  if (!doc.has_table("timing")) {
    err = "timing: missing value";
    return false;
  }
  FieldValue sample_rate, tolerance, loop_rate;
  if (!rd.field(schema::kTimingSampleRateHz, "timing", "", sample_rate, err) ||
      !rd.field(schema::kTimingTimeToleranceUs, "timing", "", tolerance, err) ||
      !rd.field(schema::kTimingLoopRateHz, "timing", "", loop_rate, err)) {
    return false;
  }
  fc.sample_rate_hz = sample_rate.number;
  const double period_us = 1e6 / fc.sample_rate_hz;
  fc.imu.period_us = static_cast<std::uint32_t>(std::lround(period_us));
  fc.imu.time_tolerance_us = static_cast<std::uint32_t>(tolerance.given ? tolerance.integer : std::lround(period_us / 2.0));
  fc.loop_rate_hz = loop_rate.given ? loop_rate.number : fc.sample_rate_hz;
  if (!loop_rate.given && fc.loop_rate_hz > schema::kTimingLoopRateHz.hi) {
    // Valid for the format, not for this program: its cycle runs at most at 2000 Hz.
    err = std::string("timing.") + schema::kTimingLoopRateHz.name + ": absent, so the sample rate " +
          toml::repr_number(fc.loop_rate_hz) + " Hz, outside the loop's " + schema::kTimingLoopRateHz.bounds_text +
          ": give it";
    return false;
  }
  return !rd.unread_key("timing", "", err);
}

inline bool read_bias_stage(Reader& rd, const std::string& st, const std::string& ch, ImuChannelConfig<float>& cc,
                            std::string& err) {
  FieldValue bias;
  if (!rd.field(schema::kBiasRemovalBias, st, ch, bias, err)) return false;
  cc.bias = static_cast<float>(bias.number);
  return true;
}

inline bool read_wavelet_stage(Reader& rd, const std::string& st, const std::string& ch, WaveletSpec& ws,
                               std::string& err) {
  FieldValue wavelet, window, level, threshold;
  if (!rd.field(schema::kWaveletWavelet, st, ch, wavelet, err) || !rd.field(schema::kWaveletWindow, st, ch, window, err) ||
      !rd.field(schema::kWaveletLevel, st, ch, level, err, /*own_bounds=*/false)) {
    return false;
  }
  ws.kind = wavelet.text == "db8" ? WaveletKind::db8 : WaveletKind::db4;
  ws.window = static_cast<std::size_t>(window.integer);
  // The deepest level of the extended window 2N depends on the wavelet and the window.
  const int jmax = realtime_wavelet_max_level(ws.window, ws.kind);
  if (level.integer < 1 || level.integer > jmax) {
    err = st + "." + schema::kWaveletLevel.name + ": expected 1.." + std::to_string(jmax) + " for " + wavelet.text +
          " with window " + std::to_string(window.integer) + ", got " + std::to_string(level.integer);
    return false;
  }
  ws.level = static_cast<int>(level.integer);
  if (!rd.field(schema::kWaveletThreshold, st, ch, threshold, err)) return false;
  ws.mode = threshold.text == "soft" ? WaveletMode::soft
                                     : (threshold.text == "hard" ? WaveletMode::hard : WaveletMode::forced);
  return true;
}

inline bool read_ar2_stage(Reader& rd, const std::string& st, const std::string& ch, ImuChannelConfig<float>& cc,
                           std::string& err) {
  FieldValue a1, a2, mean, sigma2, q, r, p0, steady_state;
  if (!rd.field(schema::kAr2KalmanA1, st, ch, a1, err) || !rd.field(schema::kAr2KalmanA2, st, ch, a2, err) ||
      !rd.field(schema::kAr2KalmanMean, st, ch, mean, err) || !rd.field(schema::kAr2KalmanSigma2, st, ch, sigma2, err) ||
      !rd.field(schema::kAr2KalmanQ, st, ch, q, err) || !rd.field(schema::kAr2KalmanR, st, ch, r, err) ||
      !rd.field(schema::kAr2KalmanP0, st, ch, p0, err) ||
      !rd.field(schema::kAr2KalmanSteadyState, st, ch, steady_state, err)) {
    return false;
  }
  const double x1 = a1.number, x2 = a2.number;
  if (!(std::fabs(x2) < 1.0 && x1 + x2 < 1.0 && x2 - x1 < 1.0)) {
    err = st + "." + schema::kAr2KalmanA1.name + ": AR(2) model is not stationary (a1=" + toml::repr_number(x1) +
          ", a2=" + toml::repr_number(x2) + "; needs |a2| < 1, a1 + a2 < 1, a2 - a1 < 1)";
    return false;
  }
  const double s2 = sigma2.given ? sigma2.number : q.number;  // absent: q
  cc.model = Ar2Model<float>{static_cast<float>(x1), static_cast<float>(x2), static_cast<float>(s2),
                             static_cast<float>(mean.number)};
  cc.q = static_cast<float>(q.number);
  cc.r = static_cast<float>(r.number);
  cc.p0 = static_cast<float>(p0.number);
  cc.steady_state = steady_state.boolean;
  return true;
}

// One stage `st` ("channels.gx.stages[k]"): its type and its fields, nothing else.
inline bool read_stage(Reader& rd, const std::string& st, const std::string& ch, ImuChannelConfig<float>& cc,
                       WaveletSpec& ws, ChannelFilter& type, std::string& err) {
  std::string name;
  if (!rd.text(st + ".type", name, err)) return false;
  if (!stage_type(name, type)) {
    err = st + ".type: expected one of pass_through, bias_removal, wavelet, ar2_kalman, got '" + name + "'";
    return false;
  }
  bool ok = true;
  if (type == ChannelFilter::bias_removal) ok = read_bias_stage(rd, st, ch, cc, err);
  else if (type == ChannelFilter::wavelet) ok = read_wavelet_stage(rd, st, ch, ws, err);
  else if (type == ChannelFilter::ar2_kalman) ok = read_ar2_stage(rd, st, ch, cc, err);
  return ok && !rd.unread_key(st, ch, err);
}

// A chain: pass_through only alone, at most one stage of each type.
inline bool check_chain(const std::string& table, const ChannelFilter* types, int n, std::string& err) {
  const bool pass = types[0] == ChannelFilter::pass_through || (n > 1 && types[1] == ChannelFilter::pass_through);
  if (pass && n > 1) {
    err = table + ".stages: pass_through must be the only stage of a chain";
    return false;
  }
  if (n > 1 && types[0] == types[1]) {
    err = table + ".stages: at most one stage of each type, got ['" + stage_name(types[0]) + "', '" +
          stage_name(types[1]) + "']";
    return false;
  }
  return true;
}

// [channels.<ch>] and its [[channels.<ch>.stages]].
inline bool read_channel(Reader& rd, const toml::Doc& doc, const std::string& ch, ImuChannelConfig<float>& cc,
                         WaveletSpec& ws, std::string& err) {
  const std::string table = "channels." + ch;
  if (!doc.has_table(table)) {
    err = table + ": missing value";
    return false;
  }
  cc = ImuChannelConfig<float>{};
  FieldValue saturation, stuck_samples;
  if (!rd.field(schema::kChannelSaturation, table, ch, saturation, err) ||
      !rd.field(schema::kChannelStuckSamples, table, ch, stuck_samples, err)) {
    return false;
  }
  cc.saturation = static_cast<float>(saturation.number);
  cc.stuck_samples = static_cast<std::uint32_t>(stuck_samples.integer);
  const int n = doc.stages(table);
  if (n < 1 || n > schema::kMaxStages) {
    err = table + ".stages: expected 1.." + std::to_string(schema::kMaxStages) + " stages, got " + std::to_string(n);
    return false;
  }
  ChannelFilter types[schema::kMaxStages] = {ChannelFilter::pass_through, ChannelFilter::pass_through};
  for (int k = 0; k < n; ++k) {
    if (!read_stage(rd, table + ".stages[" + std::to_string(k) + "]", ch, cc, ws, types[k], err)) return false;
  }
  if (!check_chain(table, types, n, err)) return false;
  cc.filter = types[0];
  cc.filter2 = types[1];  // pass_through: no second stage
  return !rd.unread_key(table, ch, err);
}

// A table header the format does not have ([foo], [channels.qx], [meta.sub]).
inline bool unknown_table(const toml::Doc& doc, std::string& err) {
  for (const std::string& t : doc.tables) {
    bool known = t == "timing" || t == "meta" || t == "channels";
    for (const char* ch : schema::kChannelNames) known = known || t == std::string("channels.") + ch;
    if (!known) {
      err = t.rfind("meta.", 0) == 0 ? t + ": expected a string, number or boolean" : t + ": unknown key";
      return true;
    }
  }
  return false;
}

// The whole document.
inline bool read_doc(const toml::Doc& doc, FileConfig& out, std::string& err) {
  Reader rd(doc);
  FileConfig fc;
  if (!read_header(rd, doc, err) || !read_timing(rd, doc, fc, err)) return false;
  for (std::size_t c = 0; c < kImuChannels; ++c) {
    if (!read_channel(rd, doc, schema::kChannelNames[c], fc.imu.channels[c], fc.wavelets[c], err)) return false;
  }
  if (rd.unread_key(err) || unknown_table(doc, err)) return false;
  out = fc;
  return true;
}

}  // namespace detail

// Reads and checks a configuration's text; false with a one-line `error` "<source>: <key>: ...".
inline bool read_config_text(const std::string& text, const std::string& source, FileConfig& out,
                             std::string& error) {
  toml::Doc doc;
  std::istringstream in(text);
  std::string err;
  if (!toml::parse_doc(in, doc, err) || !detail::read_doc(doc, out, err)) {
    error = source + ": " + err;
    return false;
  }
  return true;
}

// Reads and checks a configuration file (see read_config_text).
inline bool read_config_file(const std::string& path, FileConfig& out, std::string& error) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    error = path + ": cannot read the configuration (" + std::strerror(errno) + ")";
    return false;
  }
  std::ostringstream text;
  text << file.rdbuf();
  if (file.bad()) {
    error = path + ": cannot read the configuration";
    return false;
  }
  return read_config_text(text.str(), path, out, error);
}

// The built-in default configuration (no --config): the shipped default file's text, through
// the same reader.
inline constexpr const char* kBuiltinConfigSource = "built-in default configuration";

inline bool read_builtin_config(FileConfig& out, std::string& error) {
  return read_config_text(schema::kDefaultConfigToml, kBuiltinConfigSource, out, error);
}

}  // namespace gyrodrift::loop
