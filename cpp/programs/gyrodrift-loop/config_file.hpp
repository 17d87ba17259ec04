// The processor configuration file (version 1, README "Processor configuration file") read by
// `gyrodrift-loop --config FILE`. The file is TOML; this reader accepts the canonical subset
// that `gyrodrift config` / gyrodrift.config.write_config emit (`key = value` lines,
// `[table]` and `[[channels.X.stages]]` headers, `#` comments; strings, integers, floats incl.
// inf, booleans) and refuses anything else with the line number. It applies the same checks
// as the Python reader (gyrodrift/config.py) and names the key in every error, so a file the
// Python side accepts builds the same processor here (tests/test_config_file.py).
//
// Program code (standard library allowed): the header-only core stays free of parsing.
#pragma once
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <gyrodrift/filters/realtime_wavelet.hpp>
#include <gyrodrift/filters/realtime_wavelet_windows.hpp>
#include <gyrodrift/imu/imu_processor.hpp>

namespace gyrodrift::loop {

// One channel's wavelet stage as read from the file (used only if the chain has one).
struct WaveletSpec {
  WaveletKind kind = WaveletKind::db4;
  int level = 5;
  WaveletMode mode = WaveletMode::forced;
  std::size_t window = 256;
};

struct FileConfig {
  ImuConfig<float> imu;
  std::array<WaveletSpec, kImuChannels> wavelets{};
  double sample_rate_hz = 400.0;
  double loop_rate_hz = 0.0;  // 0: not given (the sample rate)
};

namespace detail {

struct TomlValue {
  enum class Kind { string, integer, floating, boolean } kind = Kind::string;
  std::string s;
  double d = 0.0;
  long long i = 0;
  bool b = false;
  int line = 0;
};

inline std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  const auto b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

inline bool bare_key(const std::string& k) {
  if (k.empty()) return false;
  for (const char c : k) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                    c == '-' || c == '.';
    if (!ok) return false;
  }
  return k.front() != '.' && k.back() != '.' && k.find("..") == std::string::npos;
}

// Parses the value text (comment already removed); false if it is not in the subset.
inline bool parse_value(const std::string& text, TomlValue& v) {
  if (text.empty()) return false;
  if (text.front() == '"') {
    std::string out;
    std::size_t i = 1;
    for (; i < text.size() && text[i] != '"'; ++i) {
      if (text[i] == '\\') {
        if (++i >= text.size()) return false;
        const char e = text[i];
        if (e == '"' || e == '\\') out += e;
        else if (e == 'n') out += '\n';
        else if (e == 't') out += '\t';
        else if (e == 'u' && i + 4 < text.size()) {
          out += static_cast<char>(std::strtol(text.substr(i + 1, 4).c_str(), nullptr, 16));
          i += 4;
        } else return false;
      } else {
        out += text[i];
      }
    }
    if (i != text.size() - 1) return false;  // unterminated or trailing text
    v.kind = TomlValue::Kind::string;
    v.s = out;
    return true;
  }
  if (text == "true" || text == "false") {
    v.kind = TomlValue::Kind::boolean;
    v.b = text == "true";
    return true;
  }
  if (text == "inf" || text == "+inf" || text == "-inf" || text == "nan" || text == "+nan" || text == "-nan") {
    v.kind = TomlValue::Kind::floating;
    v.d = text.find("nan") != std::string::npos ? NAN : (text[0] == '-' ? -INFINITY : INFINITY);
    return true;
  }
  std::string t;
  for (const char c : text) {
    if (c != '_') t += c;  // TOML digit separators
  }
  const bool is_float = t.find_first_of(".eE") != std::string::npos;
  char* end = nullptr;
  errno = 0;
  if (is_float) {
    v.d = std::strtod(t.c_str(), &end);
    v.kind = TomlValue::Kind::floating;
  } else {
    v.i = std::strtoll(t.c_str(), &end, 10);
    v.d = static_cast<double>(v.i);
    v.kind = TomlValue::Kind::integer;
  }
  return end != t.c_str() && *end == '\0' && errno == 0;
}

class Doc {
 public:
  std::map<std::string, TomlValue> values;
  std::map<std::string, bool> used;
  std::map<std::string, int> stage_count;  // "channels.gx" -> number of [[...stages]] headers
  std::map<std::string, bool> tables;

  bool has(const std::string& key) const { return values.count(key) != 0; }
};

inline bool parse_doc(std::istream& in, Doc& doc, std::string& error) {
  std::string line;
  std::string table;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    // Strip a comment outside strings.
    bool in_str = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
      if (line[i] == '\\' && in_str) {
        ++i;
        continue;
      }
      if (line[i] == '"') in_str = !in_str;
      if (line[i] == '#' && !in_str) {
        line.resize(i);
        break;
      }
    }
    const std::string s = trim(line);
    if (s.empty()) continue;
    if (s.rfind("[[", 0) == 0) {
      const auto close = s.find("]]");
      const std::string name = close == std::string::npos ? "" : trim(s.substr(2, close - 2));
      if (close != s.size() - 2 || name.size() < 7 || name.compare(name.size() - 7, 7, ".stages") != 0 ||
          name.rfind("channels.", 0) != 0) {
        error = "line " + std::to_string(n) + ": only [[channels.<name>.stages]] arrays are supported";
        return false;
      }
      const std::string ch = name.substr(0, name.size() - 7);
      const int idx = doc.stage_count[ch]++;
      table = ch + ".stages[" + std::to_string(idx) + "]";
      doc.tables[ch] = true;
      continue;
    }
    if (s.front() == '[') {
      if (s.back() != ']' || !bare_key(trim(s.substr(1, s.size() - 2)))) {
        error = "line " + std::to_string(n) + ": bad table header (canonical layout: see gyrodrift config show)";
        return false;
      }
      table = trim(s.substr(1, s.size() - 2));
      doc.tables[table] = true;
      continue;
    }
    const auto eq = s.find('=');
    if (eq == std::string::npos) {
      error = "line " + std::to_string(n) + ": expected key = value";
      return false;
    }
    const std::string key = trim(s.substr(0, eq));
    if (!bare_key(key)) {
      error = "line " + std::to_string(n) + ": unsupported key syntax '" + key + "'";
      return false;
    }
    TomlValue v;
    v.line = n;
    if (!parse_value(trim(s.substr(eq + 1)), v)) {
      error = "line " + std::to_string(n) + ": " + (table.empty() ? key : table + "." + key) +
              ": value not in the supported TOML subset (string, integer, float, inf, true/false)";
      return false;
    }
    const std::string full = table.empty() ? key : table + "." + key;
    if (doc.values.count(full) != 0) {
      error = full + ": given twice (line " + std::to_string(n) + ")";
      return false;
    }
    doc.values[full] = v;
  }
  return true;
}

class Reader {
 public:
  explicit Reader(Doc& doc) : doc_(doc) {}

  bool number(const std::string& key, double& out, bool required, std::string& err) {
    const auto it = doc_.values.find(key);
    if (it == doc_.values.end()) {
      if (required) err = key + ": missing value";
      return !required;
    }
    doc_.used[key] = true;
    if (it->second.kind != TomlValue::Kind::floating && it->second.kind != TomlValue::Kind::integer) {
      err = key + ": expected a number";
      return false;
    }
    out = it->second.d;
    return true;
  }

  bool integer(const std::string& key, long long& out, bool required, std::string& err) {
    const auto it = doc_.values.find(key);
    if (it == doc_.values.end()) {
      if (required) err = key + ": missing value";
      return !required;
    }
    doc_.used[key] = true;
    if (it->second.kind != TomlValue::Kind::integer) {
      err = key + ": expected an integer";
      return false;
    }
    out = it->second.i;
    return true;
  }

  bool string(const std::string& key, std::string& out, bool required, std::string& err) {
    const auto it = doc_.values.find(key);
    if (it == doc_.values.end()) {
      if (required) err = key + ": missing value";
      return !required;
    }
    doc_.used[key] = true;
    if (it->second.kind != TomlValue::Kind::string) {
      err = key + ": expected a string";
      return false;
    }
    out = it->second.s;
    return true;
  }

  bool boolean(const std::string& key, bool& out, std::string& err) {
    const auto it = doc_.values.find(key);
    if (it == doc_.values.end()) return true;
    doc_.used[key] = true;
    if (it->second.kind != TomlValue::Kind::boolean) {
      err = key + ": expected true or false";
      return false;
    }
    out = it->second.b;
    return true;
  }

  // A key given with the other channel kind's (or another) unit suffix.
  bool wrong_units(const std::string& prefix, const std::string& base, bool gyro, std::string& err) {
    static const char* const kSuffixes[] = {"_deg_s", "_deg_h", "_rad_h", "_mrad_s", "_g", "_mg", "_ug",
                                            "_ft_s2", "_rad_s", "_m_s2"};
    const std::string want = gyro ? "_rad_s" : "_m_s2";
    if (doc_.has(prefix + base + want)) return false;
    for (const char* suf : kSuffixes) {
      if (want == suf || !doc_.has(prefix + base + suf)) continue;
      err = prefix + base + suf + ": wrong units for a" + (gyro ? " gyro channel (rad/s)" : "n accelerometer channel (m/s^2)") +
            ": use " + base + want;
      return true;
    }
    return false;
  }

  // The first key under `prefix` that nothing read.
  bool unknown(const std::string& prefix, std::string& err) {
    for (const auto& kv : doc_.values) {
      if (kv.first.rfind(prefix, 0) == 0 && doc_.used.count(kv.first) == 0) {
        err = kv.first + ": unknown key";
        return true;
      }
    }
    return false;
  }

 private:
  Doc& doc_;
};

inline bool stage_type(const std::string& s, ChannelFilter& f) {
  if (s == "pass_through") f = ChannelFilter::pass_through;
  else if (s == "bias_removal") f = ChannelFilter::bias_removal;
  else if (s == "ar2_kalman") f = ChannelFilter::ar2_kalman;
  else if (s == "wavelet") f = ChannelFilter::wavelet;
  else return false;
  return true;
}

}  // namespace detail

// Reads and checks a configuration file; false with a one-line `error` naming the key.
inline bool read_config_file(const std::string& path, FileConfig& out, std::string& error) {
  std::ifstream file(path);
  if (!file) {
    error = "cannot read configuration '" + path + "'";
    return false;
  }
  detail::Doc doc;
  std::string err;
  if (!detail::parse_doc(file, doc, err)) {
    error = path + ": " + err;
    return false;
  }
  auto fail = [&](const std::string& e) {
    error = path + ": " + e;
    return false;
  };
  detail::Reader rd(doc);
  std::string schema;
  long long version = 0;
  if (!rd.string("schema", schema, true, err)) return fail(err);
  if (schema != "gyrodrift.processor") return fail("schema: expected 'gyrodrift.processor', got '" + schema + "'");
  if (!rd.integer("version", version, true, err)) return fail(err);
  if (version != 1) return fail("version: this gyrodrift-loop reads version 1, got " + std::to_string(version));
  for (const auto& kv : doc.values) {
    if (kv.first.rfind("meta.", 0) == 0) doc.used[kv.first] = true;  // free-form, ignored
  }
  FileConfig fc;
  double rate = 0.0;
  if (!rd.number("timing.sample_rate_hz", rate, true, err)) return fail(err);
  if (!(std::isfinite(rate) && rate >= 1.0 && rate <= 1e5)) return fail("timing.sample_rate_hz: expected 1..100000 Hz");
  fc.sample_rate_hz = rate;
  const double period_us = 1e6 / rate;
  fc.imu.period_us = static_cast<std::uint32_t>(std::lround(period_us));
  long long tol = std::lround(period_us / 2.0);
  if (!rd.integer("timing.time_tolerance_us", tol, false, err)) return fail(err);
  if (tol < 0 || tol > 0xFFFFFFFFLL) return fail("timing.time_tolerance_us: expected 0..2^32-1");
  fc.imu.time_tolerance_us = static_cast<std::uint32_t>(tol);
  if (!rd.number("timing.loop_rate_hz", fc.loop_rate_hz, false, err)) return fail(err);
  if (doc.has("timing.loop_rate_hz") && !(fc.loop_rate_hz >= 1.0 && fc.loop_rate_hz <= 2000.0)) {
    return fail("timing.loop_rate_hz: expected 1..2000 Hz");
  }

  static const char* const kNames[kImuChannels] = {"gx", "gy", "gz", "ax", "ay", "az"};
  for (std::size_t c = 0; c < kImuChannels; ++c) {
    const std::string ch = std::string("channels.") + kNames[c];
    const bool gyro = c < 3;
    const std::string u = gyro ? "_rad_s" : "_m_s2";
    ImuChannelConfig<float>& cc = fc.imu.channels[c];
    cc = ImuChannelConfig<float>{};
    if (doc.tables.count(ch) == 0 && doc.stage_count.count(ch) == 0) return fail(ch + ": missing channel");
    if (rd.wrong_units(ch + ".", "saturation", gyro, err)) return fail(err);
    double sat = INFINITY;
    if (!rd.number(ch + ".saturation" + u, sat, false, err)) return fail(err);
    if (std::isnan(sat) || !(sat > 0.0)) return fail(ch + ".saturation" + u + ": must be > 0 (or inf: off)");
    cc.saturation = static_cast<float>(sat);
    long long stuck = 0;
    if (!rd.integer(ch + ".stuck_samples", stuck, false, err)) return fail(err);
    if (stuck < 0 || stuck > 0xFFFFFFFFLL) return fail(ch + ".stuck_samples: expected 0..2^32-1");
    cc.stuck_samples = static_cast<std::uint32_t>(stuck);
    const int n = doc.stage_count.count(ch) != 0 ? doc.stage_count[ch] : 0;
    if (n < 1 || n > 2) return fail(ch + ".stages: expected 1..2 stages, got " + std::to_string(n));
    ChannelFilter types[2] = {ChannelFilter::pass_through, ChannelFilter::pass_through};
    for (int k = 0; k < n; ++k) {
      const std::string st = ch + ".stages[" + std::to_string(k) + "]";
      std::string type;
      if (!rd.string(st + ".type", type, true, err)) return fail(err);
      ChannelFilter f = ChannelFilter::pass_through;
      if (!detail::stage_type(type, f)) {
        return fail(st + ".type: expected one of pass_through, bias_removal, wavelet, ar2_kalman, got '" + type + "'");
      }
      types[k] = f;
      if (f == ChannelFilter::bias_removal) {
        if (rd.wrong_units(st + ".", "bias", gyro, err)) return fail(err);
        double b = 0.0;
        if (!rd.number(st + ".bias" + u, b, true, err)) return fail(err);
        if (!std::isfinite(b)) return fail(st + ".bias" + u + ": must be finite");
        cc.bias = static_cast<float>(b);
      } else if (f == ChannelFilter::wavelet) {
        std::string w, thr = "forced";
        long long window = 0, level = 0;
        if (!rd.string(st + ".wavelet", w, true, err)) return fail(err);
        if (w != "db4" && w != "db8") return fail(st + ".wavelet: expected 'db4' or 'db8', got '" + w + "'");
        if (!rd.integer(st + ".window", window, true, err)) return fail(err);
        if (!rd.integer(st + ".level", level, true, err)) return fail(err);
        if (!rd.string(st + ".threshold", thr, false, err)) return fail(err);
        WaveletSpec& ws = fc.wavelets[c];
        ws.kind = w == "db4" ? WaveletKind::db4 : WaveletKind::db8;
        if (!config_wavelet_window_ok(window)) {
          return fail(st + ".window: expected a power of two in 16..4096, got " + std::to_string(window));
        }
        ws.window = static_cast<std::size_t>(window);
        const int jmax = realtime_wavelet_max_level(ws.window, ws.kind);
        if (level < 1 || level > jmax) {
          return fail(st + ".level: expected 1.." + std::to_string(jmax) + " for " + w + " with window " +
                      std::to_string(window) + ", got " + std::to_string(level));
        }
        ws.level = static_cast<int>(level);
        if (thr == "forced") ws.mode = WaveletMode::forced;
        else if (thr == "soft") ws.mode = WaveletMode::soft;
        else if (thr == "hard") ws.mode = WaveletMode::hard;
        else return fail(st + ".threshold: expected forced, soft or hard, got '" + thr + "'");
      } else if (f == ChannelFilter::ar2_kalman) {
        double a1 = 0, a2 = 0, mean = 0, q = 0, r = 0, p0 = 1.0, sigma2 = NAN;
        if (!rd.number(st + ".a1", a1, true, err) || !rd.number(st + ".a2", a2, true, err)) return fail(err);
        if (rd.wrong_units(st + ".", "mean", gyro, err)) return fail(err);
        if (!rd.number(st + ".mean" + u, mean, true, err) || !rd.number(st + ".q", q, true, err) ||
            !rd.number(st + ".r", r, true, err) || !rd.number(st + ".p0", p0, false, err) ||
            !rd.number(st + ".sigma2", sigma2, false, err) || !rd.boolean(st + ".steady_state", cc.steady_state, err)) {
          return fail(err);
        }
        if (std::isnan(sigma2)) sigma2 = q;
        const char* names[] = {"a1", "a2", "q", "r", "p0", "sigma2"};
        const double vals[] = {a1, a2, q, r, p0, sigma2};
        for (int i = 0; i < 6; ++i) {
          if (!std::isfinite(vals[i])) return fail(st + "." + names[i] + ": must be finite");
        }
        if (!std::isfinite(mean)) return fail(st + ".mean" + u + ": must be finite");
        if (!(std::fabs(a2) < 1.0 && a1 + a2 < 1.0 && a2 - a1 < 1.0)) {
          std::ostringstream m;
          m.precision(17);
          m << st << ".a1: AR(2) model is not stationary (a1=" << a1 << ", a2=" << a2
            << "; needs |a2| < 1, a1 + a2 < 1, a2 - a1 < 1)";
          return fail(m.str());
        }
        if (q < 0) return fail(st + ".q: a variance must be >= 0");
        if (!(r > 0)) return fail(st + ".r: must be > 0");
        if (p0 < 0) return fail(st + ".p0: must be >= 0");
        if (sigma2 < 0) return fail(st + ".sigma2: a variance must be >= 0");
        cc.model = Ar2Model<float>{static_cast<float>(a1), static_cast<float>(a2), static_cast<float>(sigma2),
                                   static_cast<float>(mean)};
        cc.q = static_cast<float>(q);
        cc.r = static_cast<float>(r);
        cc.p0 = static_cast<float>(p0);
      }
      if (rd.unknown(st + ".", err)) return fail(err);
    }
    if ((types[0] == ChannelFilter::pass_through && n > 1) || (n > 1 && types[1] == ChannelFilter::pass_through)) {
      return fail(ch + ".stages: pass_through must be the only stage of a chain");
    }
    if (n > 1 && types[0] == types[1]) return fail(ch + ".stages: at most one stage of each type");
    cc.filter = types[0];
    cc.filter2 = n > 1 ? types[1] : ChannelFilter::pass_through;
  }
  for (const char* prefix : {"timing.", "channels.", ""}) {
    if (rd.unknown(prefix, err)) return fail(err);
  }
  out = fc;
  return true;
}

}  // namespace gyrodrift::loop
