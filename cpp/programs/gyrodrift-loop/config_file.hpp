// The processor configuration file (version 1; the documentation's configuration file guide), read by
// `gyrodrift-loop --config FILE` and `--check-config FILE`, and the built-in default
// configuration (config_schema::kDefaultConfigToml) read by the same code.
//
// The TOML is read by toml++ with the rules both readers add (toml_document.hpp). The reader
// below is the twin of the Python reader (python/gyrodrift/imu/config.py: config_from_dict,
// then validate), step for step and in the same order, so that both refuse the same files
// naming the same first key (tests/test_config_schema.py, tests/data/config_corpus): first
// the structure (schema, version, meta, timing, the channels and their stages, each table's
// unknown keys in sorted order), then the values: every field through its FieldSpec
// (include/gyrodrift/imu/config_schema.hpp, generated from python/gyrodrift/imu/schema.py;
// a float32 field must fit a float32 and its bounds hold for the rounded value), the
// relations between fields (AR(2) stationarity in double and in float32, the wavelet level
// for the wavelet and window, the stage combinations), then the timing.
//
// Program code (standard library allowed): the header-only core stays free of parsing.
#pragma once
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <vector>
#include <sstream>
#include <string>

#include <gyrodrift/filters/realtime_wavelet.hpp>
#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/config_schema.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

#include "toml_document.hpp"

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

// The [monitor] table (gyrodrift.imu.config.MonitorConfig), durations converted to samples at
// the sample rate as MonitorConfig.samples does (lround of seconds times rate).
struct MonitorSpec {
  bool enabled = false;
  std::size_t octaves = 0;
  std::uint64_t report_samples = 0;
  double coverage = 0.0;
  double arw_factor = 0.0, bias_instability_factor = 0.0, rate_random_walk_factor = 0.0;
  double false_alarm_probability = 0.0;
  std::uint32_t stuck_samples = 0, saturated_samples = 0;
  bool reidentify = false;
  bool reidentify_ar = true;  // false: a1, a2 held, q and r tracked
  std::uint32_t block_samples = 0, retune_blocks = 0;
  std::uint64_t min_samples = 0;
  double memory_blocks = 0.0, max_step = 0.0, max_rel_stderr = 0.0;
  bool lag_identifier = false;          // identifier = "lag" (else the recursive one)
  std::uint32_t fit_delay_samples = 0;  // lag: samples from a fit's request to its retune
  bool restart_after_fit = false;       // lag: each fit from the samples since the previous one
  std::array<bool, kImuChannels> channels{};  // monitored: a gyro whose first stage is ar2_kalman
};

struct FileConfig {
  ImuConfig<float> imu;
  MonitorSpec monitor;
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

inline bool in_choices(const char* choices, const std::string& s) {
  std::string rest = choices;
  for (std::size_t bar = 0; bar != std::string::npos; rest.erase(0, bar + 1)) {
    bar = rest.find('|');
    if (rest.substr(0, bar) == s) return true;
  }
  return false;
}

// x rounded to float32 as the processors hold it; false when a nonzero value does not fit
// (overflows, or rounds to zero or a subnormal): gyrodrift.imu.schema.to_float32.
inline bool to_float32(double x, double& out) {
  if (x == 0.0 || std::isinf(x) || std::isnan(x)) {
    out = x;
    return true;
  }
  // |x| at or beyond the midpoint between FLT_MAX and 2^128 rounds to infinity.
  const double overflow = std::ldexp(1.0, 128) - std::ldexp(1.0, 103);
  if (std::fabs(x) >= overflow) return false;
  const float y = static_cast<float>(x);
  if (std::fabs(y) < std::numeric_limits<float>::min()) return false;
  out = static_cast<double>(y);
  return true;
}

// A field's value as read: absent (given false; the default applied later where it has one)
// or the file's value, already of the field's kind.
struct FieldValue {
  bool given = false;
  double number = 0.0;    // number and integer fields
  long long integer = 0;  // integer fields
  bool boolean = false;
  std::string text;  // string fields
};

// The field's own bounds: gyrodrift.imu.schema.Field.accepts (a float32 field: the rounded
// value).
inline bool accepts(const schema::FieldSpec& f, const FieldValue& v) {
  if (f.choices[0] != '\0') return in_choices(f.choices, v.text);
  if (f.kind == schema::FieldKind::boolean || f.kind == schema::FieldKind::string) return true;
  double x = v.number;
  if (std::isnan(x) || (f.finite && std::isinf(x))) return false;
  double lo = f.lo, hi = f.hi;
  if (f.float32) {  // the rounded value against the rounded bounds
    if (!to_float32(v.number, x)) return false;
    to_float32(f.lo, lo);  // the schema's bounds fit a float32 (or are infinite)
    to_float32(f.hi, hi);
  }
  if (f.lo_open ? x <= lo : x < lo) return false;
  if (f.hi_open ? x >= hi : x > hi) return false;
  if (f.power_of_two) return v.integer > 0 && (v.integer & (v.integer - 1)) == 0;
  return true;
}

inline std::string repr(const schema::FieldSpec& f, const FieldValue& v) {
  switch (f.kind) {
    case schema::FieldKind::integer:
      return std::to_string(v.integer);
    case schema::FieldKind::boolean:
      return v.boolean ? "True" : "False";
    case schema::FieldKind::string:
      return tomldoc::repr_string(v.text);
    case schema::FieldKind::number:
    default:
      return tomldoc::repr_number(v.number);
  }
}

// gyrodrift.imu.config._check_field: a field's own bounds, in the words both readers use.
inline bool check_field(const std::string& key, const schema::FieldSpec& f, const FieldValue& v, std::string& err) {
  if (!v.given) return true;  // absent: its default, within its bounds, or derived
  double rounded = 0.0;
  if (f.float32 && f.kind == schema::FieldKind::number && !to_float32(v.number, rounded)) {
    err = key + ": " + tomldoc::repr_number(v.number) +
          " does not fit a float32, the processor's scalar (a magnitude 1.1754944e-38..3.4028235e+38, or 0)";
    return false;
  }
  if (!accepts(f, v)) {
    err = key + ": expected " + f.bounds_text + ", got " + repr(f, v);
    return false;
  }
  return true;
}

// A TOML table read key by key (gyrodrift.imu.config._Table): what nothing read is an unknown
// key, reported in sorted key order.
class Table {
 public:
  // `node` null: the caller reported it missing. False (with err) if it is not a table.
  bool open(const std::string& key, const toml::node* node, std::string& err) {
    key_ = key;
    table_ = node == nullptr ? nullptr : node->as_table();
    if (table_ == nullptr) {
      err = key + ": expected a table, got " + (node == nullptr ? "None" : tomldoc::type_name(*node));
      return false;
    }
    return true;
  }

  std::string k(const std::string& name) const { return key_.empty() ? name : key_ + "." + name; }
  bool has(const std::string& name) const { return table_->contains(name); }
  const toml::table& data() const { return *table_; }

  // The node of `name`, marked read; null (and "missing value") if absent.
  const toml::node* any(const std::string& name, std::string& err) {
    const toml::node* n = table_->get(name);
    if (n == nullptr) {
      err = k(name) + ": missing value";
      return nullptr;
    }
    used_.insert(name);
    return n;
  }

  // A value of `kind`; `required` false: absent gives given = false.
  bool get(const std::string& name, schema::FieldKind kind, bool required, FieldValue& out, std::string& err) {
    out = FieldValue{};
    const toml::node* n = table_->get(name);
    if (n == nullptr) {
      if (!required) return true;
      err = k(name) + ": missing value";
      return false;
    }
    used_.insert(name);
    const std::string key = k(name);
    if (n->is_table() || n->is_array()) {
      err = key + ": expected " + kind_words(kind) + ", got " + tomldoc::repr(*n);
      return false;
    }
    switch (kind) {
      case schema::FieldKind::number:
        if (const auto* i = n->as_integer()) out.number = static_cast<double>(i->get());
        else if (const auto* f = n->as_floating_point()) out.number = f->get();
        else return err = key + ": expected a number, got " + tomldoc::repr(*n), false;
        break;
      case schema::FieldKind::integer:
        if (const auto* i = n->as_integer()) {
          out.integer = i->get();
          out.number = static_cast<double>(out.integer);
        } else {
          return err = key + ": expected an integer, got " + tomldoc::repr(*n), false;
        }
        break;
      case schema::FieldKind::boolean:
        if (const auto* b = n->as_boolean()) out.boolean = b->get();
        else return err = key + ": expected true or false, got " + tomldoc::repr(*n), false;
        break;
      case schema::FieldKind::string:
      default:
        if (const auto* s = n->as_string()) out.text = s->get();
        else return err = key + ": expected a string, got " + tomldoc::repr(*n), false;
        break;
    }
    out.given = true;
    return true;
  }

  // The first key (sorted) nothing read: unknown, or in a channel's tables a key with
  // another unit's suffix.
  bool finish(const std::string& channel, std::string& err) const {
    for (const auto& kv : *table_) {
      const std::string name(kv.first.str());
      if (used_.count(name) != 0) continue;
      if (!channel.empty()) {
        const std::string want = unit_suffix(channel);
        for (const char* suffix : kOtherSuffixes) {
          if (ends_with(name, suffix) && want != suffix) {
            err = k(name) + ": " + wrong_units_message(name.substr(0, name.size() - std::strlen(suffix)), channel);
            return false;
          }
        }
      }
      err = k(name) + ": unknown key";
      return false;
    }
    return true;
  }

  // `base` given with another unit's suffix (and not with this channel's): the wrong-units
  // error for that key, rather than "missing value" (_wrong_unit_key).
  bool wrong_units(const std::string& base, const std::string& channel, std::string& err) const {
    const std::string want = unit_suffix(channel);
    if (table_->contains(base + want)) return false;
    for (const char* suffix : kOtherSuffixes) {
      if (want == suffix || !table_->contains(base + suffix)) continue;
      err = k(base + suffix) + ": " + wrong_units_message(base, channel);
      return true;
    }
    return false;
  }

 private:
  std::string key_;
  const toml::table* table_ = nullptr;
  std::set<std::string> used_;
};

// The fields of one section as read (by their FieldSpec), in the schema's order.
struct Section {
  std::vector<const schema::FieldSpec*> specs;
  std::vector<FieldValue> values;
  const FieldValue& operator[](const schema::FieldSpec& f) const {
    for (std::size_t i = 0; i < specs.size(); ++i) {
      if (specs[i] == &f) return values[i];
    }
    static const FieldValue kNone{};
    return kNone;
  }
  // The value, or the field's default where it has one (given false: derived).
  FieldValue value(const schema::FieldSpec& f) const {
    FieldValue v = (*this)[f];
    if (v.given || !f.has_default) return v;
    v.given = true;
    v.text = f.default_text;
    v.boolean = f.default_value != 0.0;
    v.number = f.default_value;
    v.integer = static_cast<long long>(f.default_value);
    return v;
  }
};

// gyrodrift.imu.config._read_fields: a section's fields from table `t`.
inline bool read_fields(Table& t, const std::string& section, const std::string& ch, Section& out, std::string& err) {
  out = Section{};
  for (const schema::FieldSpec* f : schema::kFields) {
    if (section != f->section) continue;
    if (f->channel_unit && t.wrong_units(f->name, ch, err)) return false;
    const std::string name = std::string(f->name) + (f->channel_unit ? unit_suffix(ch) : "");
    FieldValue v;
    if (!t.get(name, f->kind, f->required, v, err)) return false;
    out.specs.push_back(f);
    out.values.push_back(v);
  }
  return true;
}

inline std::string field_key(const std::string& table, const schema::FieldSpec& f, const std::string& ch) {
  return table + "." + f.name + (f.channel_unit ? unit_suffix(ch) : "");
}

struct StageRead {
  std::string type;
  Section fields;
};

struct ChannelRead {
  Section fields;
  std::vector<StageRead> stages;
};

inline const char* const kStageTypes[] = {"pass_through", "bias_removal", "wavelet", "ar2_kalman"};

inline bool read_stage(const std::string& key, const std::string& ch, const toml::node& node, StageRead& st,
                       std::string& err) {
  Table t;
  if (!t.open(key, &node, err)) return false;
  FieldValue type;
  if (!t.get("type", schema::FieldKind::string, true, type, err)) return false;
  bool known = false;
  for (const char* name : kStageTypes) known = known || type.text == name;
  if (!known) {
    err = key + ".type: expected one of pass_through, bias_removal, wavelet, ar2_kalman, got " +
          tomldoc::repr_string(type.text);
    return false;
  }
  st.type = type.text;
  return read_fields(t, st.type, ch, st.fields, err) && t.finish(ch, err);
}

inline bool ar2_stationary(double a1, double a2) { return std::fabs(a2) < 1.0 && a1 + a2 < 1.0 && a2 - a1 < 1.0; }

// gyrodrift.imu.config._check_stage.
inline bool check_stage(const std::string& key, const std::string& ch, const StageRead& s, std::string& err) {
  for (const schema::FieldSpec* f : schema::kFields) {
    if (s.type != f->section) continue;
    const FieldValue v = s.fields.value(*f);
    if (f == &schema::kWaveletLevel) {
      const FieldValue wavelet = s.fields.value(schema::kWaveletWavelet);
      const FieldValue window = s.fields.value(schema::kWaveletWindow);
      const WaveletKind kind = wavelet.text == "db8" ? WaveletKind::db8 : WaveletKind::db4;
      const int jmax = realtime_wavelet_max_level(static_cast<std::size_t>(window.integer), kind);
      if (v.integer < 1 || v.integer > jmax) {
        err = key + ".level: expected 1.." + std::to_string(jmax) + " for " + wavelet.text + " with window " +
              std::to_string(window.integer) + ", got " + std::to_string(v.integer);
        return false;
      }
      continue;
    }
    if (!check_field(field_key(key, *f, ch), *f, v, err)) return false;
  }
  if (s.type == "ar2_kalman") {
    const double a1 = s.fields.value(schema::kAr2KalmanA1).number;
    const double a2 = s.fields.value(schema::kAr2KalmanA2).number;
    if (!ar2_stationary(a1, a2)) {
      err = key + ".a1: AR(2) model is not stationary (a1=" + tomldoc::repr_number(a1) +
            ", a2=" + tomldoc::repr_number(a2) + "; needs |a2| < 1, a1 + a2 < 1, a2 - a1 < 1)";
      return false;
    }
    // The float32 processor's own test (ar2_is_stationary<float>), in float arithmetic.
    const float one = 1.0F - 64.0F * std::numeric_limits<float>::epsilon();
    const auto x1 = static_cast<float>(a1), x2 = static_cast<float>(a2);  // both fit: checked with the fields
    if (!(x2 < one && x2 > -one && x1 + x2 < one && x2 - x1 < one)) {
      err = key + ".a1: AR(2) model is not stationary in float32, the processor's scalar (a1=" +
            tomldoc::repr_number(a1) + ", a2=" + tomldoc::repr_number(a2) +
            "; in float32 |a2|, a1 + a2 and a2 - a1 must stay below 1 - 64 eps = " +
            tomldoc::repr_number(static_cast<double>(one)) + ")";
      return false;
    }
  }
  return true;
}

inline std::string type_list(const std::vector<StageRead>& stages) {
  std::string out = "[";
  for (std::size_t i = 0; i < stages.size(); ++i) out += (i ? ", '" : "'") + stages[i].type + "'";
  return out + "]";
}

// gyrodrift.imu.config.validate: channels, then timing, then the loop rate's relation.
inline long long lround_nonneg(double x) { return static_cast<long long>(std::floor(x + 0.5)); }

// gyrodrift.imu.config._check_monitor: the fields, then their relations.
inline bool check_monitor(const std::array<ChannelRead, kImuChannels>& chans, const Section& timing,
                          const Section& monitor, std::string& err) {
  for (const schema::FieldSpec* f : schema::kFields) {
    if (std::string(f->section) != "monitor") continue;
    if (!check_field(field_key("monitor", *f, ""), *f, monitor.value(*f), err)) return false;
  }
  const double rate = timing.value(schema::kTimingSampleRateHz).number;
  const double block_s = monitor.value(schema::kMonitorBlockS).number;
  const long long block = lround_nonneg(block_s * rate);
  const double u32 = static_cast<double>(std::numeric_limits<std::uint32_t>::max());
  if (static_cast<double>(block) > u32) {
    err = "monitor.block_s: more than 4294967295 samples at " + tomldoc::repr_number(rate) + " Hz";
    return false;
  }
  for (const schema::FieldSpec* f : {&schema::kMonitorStuckAlarmS, &schema::kMonitorSaturatedAlarmS}) {
    if (static_cast<double>(lround_nonneg(monitor.value(*f).number * rate)) > u32) {
      err = std::string("monitor.") + f->name + ": more than 4294967295 samples at " + tomldoc::repr_number(rate) + " Hz";
      return false;
    }
  }
  if (monitor.value(schema::kMonitorEnabled).boolean) {
    bool any = false;
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      any = any || (is_gyro(schema::kChannelNames[c]) && chans[c].stages[0].type == "ar2_kalman");
    }
    if (!any) {
      err = "monitor.enabled: no gyro channel has ar2_kalman as its first stage (the drift model the monitor "
            "starts from)";
      return false;
    }
  }
  // MonitorConfig.check_fit_delay: the lag identifier's fits of the watched gyros (the one
  // `gyrodrift monitor` runs when the monitor is off) within one retune interval, in samples.
  if (monitor.value(schema::kMonitorIdentifier).text == "lag") {
    long long gyros = 0;
    if (monitor.value(schema::kMonitorEnabled).boolean) {
      for (std::size_t c = 0; c < kImuChannels; ++c) {
        if (is_gyro(schema::kChannelNames[c]) && chans[c].stages[0].type == "ar2_kalman") ++gyros;
      }
    } else {
      gyros = 1;
    }
    const long long fit_delay = std::max(1LL, lround_nonneg(monitor.value(schema::kMonitorFitDelayS).number * rate));
    const long long cadence =
        std::max(1LL, lround_nonneg(monitor.value(schema::kMonitorRetuneS).number / block_s)) * std::max(8LL, block);
    if (static_cast<double>(fit_delay) > u32) {
      err = "monitor.fit_delay_s: more than 4294967295 samples at " + tomldoc::repr_number(rate) + " Hz";
      return false;
    }
    if (gyros * fit_delay > cadence) {
      err = "monitor.fit_delay_s: " + std::to_string(gyros) + (gyros == 1 ? " gyro x " : " gyros x ") +
            std::to_string(fit_delay) + " samples exceed retune_s = " + std::to_string(cadence) + " samples at " +
            tomldoc::repr_number(rate) +
            " Hz: the lag identifier needs watched gyros x fit_delay_s <= retune_s (each gyro's fit is applied "
            "before the next one's starts)";
      return false;
    }
  }
  return true;
}

inline bool validate(const std::array<ChannelRead, kImuChannels>& chans, const Section& timing,
                     const Section& monitor, std::string& err) {
  for (std::size_t c = 0; c < kImuChannels; ++c) {
    const std::string ch = schema::kChannelNames[c];
    const std::string key = "channels." + ch;
    const auto& stages = chans[c].stages;
    const auto n = static_cast<int>(stages.size());
    if (n < 1 || n > schema::kMaxStages) {
      err = key + ".stages: expected 1.." + std::to_string(schema::kMaxStages) + " stages, got " + std::to_string(n);
      return false;
    }
    bool pass = false;
    for (const auto& s : stages) pass = pass || s.type == "pass_through";
    if (pass && n > 1) {
      err = key + ".stages: pass_through must be the only stage of a chain";
      return false;
    }
    if (n > 1 && stages[0].type == stages[1].type) {
      err = key + ".stages: at most one stage of each type, got " + type_list(stages);
      return false;
    }
    for (int i = 0; i < n; ++i) {
      if (!check_stage(key + ".stages[" + std::to_string(i) + "]", ch, stages[static_cast<std::size_t>(i)], err)) {
        return false;
      }
    }
    for (const schema::FieldSpec* f : schema::kFields) {
      if (std::string(f->section) != "channel") continue;
      if (!check_field(field_key(key, *f, ch), *f, chans[c].fields.value(*f), err)) return false;
    }
  }
  for (const schema::FieldSpec* f : schema::kFields) {
    if (std::string(f->section) != "timing") continue;
    if (!check_field(field_key("timing", *f, ""), *f, timing.value(*f), err)) return false;
  }
  if (!check_monitor(chans, timing, monitor, err)) return false;
  const FieldValue loop = timing.value(schema::kTimingLoopRateHz);
  const FieldValue rate = timing.value(schema::kTimingSampleRateHz);
  if (!loop.given && !accepts(schema::kTimingLoopRateHz, rate)) {
    // Valid for the format, not for this program: its cycle runs at most at 2000 Hz.
    err = std::string("timing.") + schema::kTimingLoopRateHz.name + ": absent, so the sample rate " +
          tomldoc::repr_number(rate.number) + " Hz, outside the loop's " + schema::kTimingLoopRateHz.bounds_text +
          ": give it";
    return false;
  }
  return true;
}

inline ChannelFilter filter_of(const std::string& type) {
  if (type == "bias_removal") return ChannelFilter::bias_removal;
  if (type == "ar2_kalman") return ChannelFilter::ar2_kalman;
  if (type == "wavelet") return ChannelFilter::wavelet;
  return ChannelFilter::pass_through;
}

// The checked values into the loop's configuration (float32 where the processor holds them).
inline void build(const std::array<ChannelRead, kImuChannels>& chans, const Section& timing,
                  const Section& monitor, FileConfig& fc) {
  fc.sample_rate_hz = timing.value(schema::kTimingSampleRateHz).number;
  {
    const double rate = fc.sample_rate_hz;
    MonitorSpec& m = fc.monitor;
    auto num = [&monitor](const schema::FieldSpec& f) { return monitor.value(f).number; };
    m.enabled = monitor.value(schema::kMonitorEnabled).boolean;
    m.octaves = static_cast<std::size_t>(monitor.value(schema::kMonitorOctaves).integer);
    m.report_samples = static_cast<std::uint64_t>(std::max(1LL, lround_nonneg(num(schema::kMonitorReportIntervalS) * rate)));
    m.coverage = num(schema::kMonitorCoverage);
    m.arw_factor = num(schema::kMonitorArwFactor);
    m.bias_instability_factor = num(schema::kMonitorBiasInstabilityFactor);
    m.rate_random_walk_factor = num(schema::kMonitorRateRandomWalkFactor);
    m.false_alarm_probability = num(schema::kMonitorFalseAlarmProbability);
    m.stuck_samples = static_cast<std::uint32_t>(lround_nonneg(num(schema::kMonitorStuckAlarmS) * rate));
    m.saturated_samples = static_cast<std::uint32_t>(lround_nonneg(num(schema::kMonitorSaturatedAlarmS) * rate));
    m.reidentify = monitor.value(schema::kMonitorReidentify).boolean;
    m.reidentify_ar = monitor.value(schema::kMonitorReidentifyAr).boolean;
    const double block_s = num(schema::kMonitorBlockS);
    m.block_samples = static_cast<std::uint32_t>(std::max(8LL, lround_nonneg(block_s * rate)));  // MIN_BLOCK_SAMPLES
    m.retune_blocks = static_cast<std::uint32_t>(std::max(1LL, lround_nonneg(num(schema::kMonitorRetuneS) / block_s)));
    m.min_samples = static_cast<std::uint64_t>(lround_nonneg(num(schema::kMonitorMinLearnS) * rate));
    const double memory = num(schema::kMonitorMemoryS) / block_s;
    m.memory_blocks = memory > 0.0 ? std::max(1.0, memory) : 0.0;  // 0, or at least one block
    m.max_step = num(schema::kMonitorMaxStep);
    m.max_rel_stderr = num(schema::kMonitorIdentifiedMaxRelStderr);
    m.lag_identifier = monitor.value(schema::kMonitorIdentifier).text == "lag";
    m.fit_delay_samples = static_cast<std::uint32_t>(std::max(1LL, lround_nonneg(num(schema::kMonitorFitDelayS) * rate)));
    m.restart_after_fit = monitor.value(schema::kMonitorRestartAfterFit).boolean;
    for (std::size_t c = 0; c < kImuChannels; ++c) {
      m.channels[c] = m.enabled && is_gyro(schema::kChannelNames[c]) && chans[c].stages[0].type == "ar2_kalman";
    }
  }
  const double period_us = 1e6 / fc.sample_rate_hz;
  fc.imu.period_us = static_cast<std::uint32_t>(std::lround(period_us));
  const FieldValue tol = timing.value(schema::kTimingTimeToleranceUs);
  fc.imu.time_tolerance_us = static_cast<std::uint32_t>(tol.given ? tol.integer : std::lround(period_us / 2.0));
  const FieldValue loop = timing.value(schema::kTimingLoopRateHz);
  fc.loop_rate_hz = loop.given ? loop.number : fc.sample_rate_hz;
  for (std::size_t c = 0; c < kImuChannels; ++c) {
    ImuChannelConfig<float>& cc = fc.imu.channels[c];
    cc = ImuChannelConfig<float>{};
    cc.saturation = static_cast<float>(chans[c].fields.value(schema::kChannelSaturation).number);
    cc.stuck_samples = static_cast<std::uint32_t>(chans[c].fields.value(schema::kChannelStuckSamples).integer);
    const auto& stages = chans[c].stages;
    cc.filter = filter_of(stages[0].type);
    cc.filter2 = stages.size() > 1 ? filter_of(stages[1].type) : ChannelFilter::pass_through;
    for (const auto& s : stages) {
      const Section& v = s.fields;
      if (s.type == "bias_removal") {
        cc.bias = static_cast<float>(v.value(schema::kBiasRemovalBias).number);
      } else if (s.type == "wavelet") {
        WaveletSpec& ws = fc.wavelets[c];
        const std::string threshold = v.value(schema::kWaveletThreshold).text;
        ws.kind = v.value(schema::kWaveletWavelet).text == "db8" ? WaveletKind::db8 : WaveletKind::db4;
        ws.window = static_cast<std::size_t>(v.value(schema::kWaveletWindow).integer);
        ws.level = static_cast<int>(v.value(schema::kWaveletLevel).integer);
        ws.mode = threshold == "soft" ? WaveletMode::soft : (threshold == "hard" ? WaveletMode::hard : WaveletMode::forced);
      } else if (s.type == "ar2_kalman") {
        const double q = v.value(schema::kAr2KalmanQ).number;
        const FieldValue sigma2 = v.value(schema::kAr2KalmanSigma2);
        const double s2 = sigma2.given ? sigma2.number : q;  // absent: q
        cc.model = Ar2Model<float>{static_cast<float>(v.value(schema::kAr2KalmanA1).number),
                                   static_cast<float>(v.value(schema::kAr2KalmanA2).number), static_cast<float>(s2),
                                   static_cast<float>(v.value(schema::kAr2KalmanMean).number)};
        cc.q = static_cast<float>(q);
        cc.r = static_cast<float>(v.value(schema::kAr2KalmanR).number);
        cc.p0 = static_cast<float>(v.value(schema::kAr2KalmanP0).number);
        cc.steady_state = v.value(schema::kAr2KalmanSteadyState).boolean;
      }
    }
  }
}

// gyrodrift.imu.config.config_from_dict, then validate.
inline bool read_doc(const toml::table& doc, FileConfig& out, std::string& err) {
  Table top;
  if (!top.open("", &doc, err)) return false;
  FieldValue v;
  if (!top.get("schema", schema::FieldKind::string, true, v, err)) return false;
  if (v.text != schema::kSchema) {
    err = std::string("schema: expected '") + schema::kSchema + "', got " + tomldoc::repr_string(v.text);
    return false;
  }
  if (!top.get("version", schema::FieldKind::integer, true, v, err)) return false;
  if (v.integer != schema::kVersion) {
    err = "version: this gyrodrift reads version " + std::to_string(schema::kVersion) + ", got " +
          std::to_string(v.integer);
    return false;
  }
  if (top.has("meta")) {
    const toml::node* meta = top.any("meta", err);
    if (!meta->is_table()) {
      err = "meta: expected a table";
      return false;
    }
    for (const auto& kv : *meta->as_table()) {  // free-form (who wrote the file), not read
      const toml::node& n = kv.second;
      if (!(n.is_string() || n.is_integer() || n.is_floating_point() || n.is_boolean())) {
        err = "meta." + std::string(kv.first.str()) + ": expected a string, number or boolean";
        return false;
      }
    }
  }
  Table tt;
  const toml::node* node = top.any("timing", err);
  if (node == nullptr || !tt.open("timing", node, err)) return false;
  Section timing;
  if (!read_fields(tt, "timing", "", timing, err) || !tt.finish("", err)) return false;
  Table ct;
  node = top.any("channels", err);
  if (node == nullptr || !ct.open("channels", node, err)) return false;
  std::array<ChannelRead, kImuChannels> chans{};
  for (std::size_t c = 0; c < kImuChannels; ++c) {
    const std::string ch = schema::kChannelNames[c];
    const std::string key = "channels." + ch;
    Table t;
    node = ct.any(ch, err);
    if (node == nullptr || !t.open(key, node, err)) return false;
    if (!read_fields(t, "channel", ch, chans[c].fields, err)) return false;
    const toml::node* raw = t.any("stages", err);
    if (raw == nullptr) return false;
    const toml::array* arr = raw->as_array();
    if (arr == nullptr) {
      err = key + ".stages: expected an array of tables ([[...stages]])";
      return false;
    }
    for (std::size_t i = 0; i < arr->size(); ++i) {
      StageRead st;
      if (!read_stage(key + ".stages[" + std::to_string(i) + "]", ch, *arr->get(i), st, err)) return false;
      chans[c].stages.push_back(st);
    }
    if (!t.finish(ch, err)) return false;
  }
  if (!ct.finish("", err)) return false;
  Section monitor;  // absent: every field its default (read_fields on an empty table)
  {
    toml::table empty;
    Table mt;
    const toml::node* mnode = top.has("monitor") ? top.any("monitor", err) : &empty;
    if (!mt.open("monitor", mnode, err)) return false;
    if (!read_fields(mt, "monitor", "", monitor, err) || !mt.finish("", err)) return false;
  }
  if (!top.finish("", err)) return false;
  if (!validate(chans, timing, monitor, err)) return false;
  build(chans, timing, monitor, out);
  return true;
}

}  // namespace detail

// One line: control characters (of a quoted key, of the parser's message) escaped as \xNN,
// as the Python reader does.
inline std::string one_line(const std::string& s) {
  std::string out;
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20U && u != 0x7FU) {
      out += c;
      continue;
    }
    char b[8];
    std::snprintf(b, sizeof b, "\\x%02x", static_cast<unsigned>(u));
    out += b;
  }
  return out;
}

// Reads and checks a configuration's text; false with a one-line `error` "<source>: <key>: ...".
inline bool read_config_text(const std::string& text, const std::string& source, FileConfig& out,
                             std::string& error) {
  toml::table doc;
  std::string err;
  if (!tomldoc::parse(text, source, doc, err)) {
    error = one_line(err);
    return false;
  }
  FileConfig fc;
  if (!detail::read_doc(doc, fc, err)) {
    error = one_line(source + ": " + err);
    return false;
  }
  out = fc;
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
