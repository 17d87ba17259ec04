// The TOML subset of the processor configuration file (config_file.hpp reads its fields):
// `key = value` lines, `[table]` and `[[channels.X.stages]]` headers, `#` comments; strings,
// integers, floats incl. inf/nan, booleans. Anything else is refused with the line number.
// Also the values' text in errors, spelled as the Python reader spells them (repr), so both
// readers print the same message.
//
// Program code (standard library allowed): the header-only core stays free of parsing.
#pragma once
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <istream>
#include <map>
#include <set>
#include <string>

namespace gyrodrift::loop::toml {

struct Value {
  enum class Kind { string, integer, floating, boolean } kind = Kind::string;
  std::string s;
  double d = 0.0;  // floating, or the integer as a double
  long long i = 0;
  bool b = false;
  int line = 0;
};

// The parsed file: every value under its dotted key (a stage's keys under
// "channels.gx.stages[k]."), the tables named by headers and the stage count per channel.
struct Doc {
  std::map<std::string, Value> values;
  std::set<std::string> tables;            // "timing", "channels.gx", ... (stage arrays: their channel)
  std::map<std::string, int> stage_count;  // "channels.gx" -> number of [[channels.gx.stages]] headers

  // A table named by a header, or by the dotted keys under it.
  bool has_table(const std::string& name) const {
    if (tables.count(name) != 0) return true;
    const auto it = values.lower_bound(name + ".");
    return it != values.end() && it->first.rfind(name + ".", 0) == 0;
  }
  int stages(const std::string& channel_table) const {
    const auto it = stage_count.find(channel_table);
    return it == stage_count.end() ? 0 : it->second;
  }
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

// A basic string "..." with the escapes \" \\ \n \t \uXXXX; false if malformed.
inline bool parse_string(const std::string& text, std::string& out) {
  std::size_t i = 1;
  for (; i < text.size() && text[i] != '"'; ++i) {
    if (text[i] != '\\') {
      out += text[i];
      continue;
    }
    if (++i >= text.size()) return false;
    const char e = text[i];
    if (e == '"' || e == '\\') out += e;
    else if (e == 'n') out += '\n';
    else if (e == 't') out += '\t';
    else if (e == 'u' && i + 4 < text.size()) {
      out += static_cast<char>(std::strtol(text.substr(i + 1, 4).c_str(), nullptr, 16));
      i += 4;
    } else return false;
  }
  return i == text.size() - 1;  // false: unterminated or trailing text
}

// Parses the value text (comment already removed); false if it is not in the subset.
inline bool parse_value(const std::string& text, Value& v) {
  if (text.empty()) return false;
  if (text.front() == '"') {
    v.kind = Value::Kind::string;
    return parse_string(text, v.s);
  }
  if (text == "true" || text == "false") {
    v.kind = Value::Kind::boolean;
    v.b = text == "true";
    return true;
  }
  if (text == "inf" || text == "+inf" || text == "-inf" || text == "nan" || text == "+nan" || text == "-nan") {
    v.kind = Value::Kind::floating;
    v.d = text.find("nan") != std::string::npos ? NAN : (text[0] == '-' ? -INFINITY : INFINITY);
    return true;
  }
  std::string t;
  for (const char c : text) {
    if (c != '_') t += c;  // TOML digit separators
  }
  char* end = nullptr;
  errno = 0;
  if (t.find_first_of(".eE") != std::string::npos) {
    v.d = std::strtod(t.c_str(), &end);
    v.kind = Value::Kind::floating;
  } else {
    v.i = std::strtoll(t.c_str(), &end, 10);
    v.d = static_cast<double>(v.i);
    v.kind = Value::Kind::integer;
  }
  return end != t.c_str() && *end == '\0' && errno == 0;
}

// The line without its comment (a '#' outside a string).
inline std::string strip_comment(const std::string& line) {
  bool in_str = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (line[i] == '\\' && in_str) {
      ++i;
      continue;
    }
    if (line[i] == '"') in_str = !in_str;
    if (line[i] == '#' && !in_str) return line.substr(0, i);
  }
  return line;
}

// A `[table]` or `[[channels.X.stages]]` header line; sets `table` (the prefix of the keys
// that follow) or `error`.
inline bool parse_header(const std::string& s, int n, Doc& doc, std::string& table, std::string& error) {
  if (s.rfind("[[", 0) == 0) {
    const auto close = s.find("]]");
    const std::string name = close == std::string::npos ? "" : trim(s.substr(2, close - 2));
    if (close != s.size() - 2 || name.size() < 7 || name.compare(name.size() - 7, 7, ".stages") != 0 ||
        name.rfind("channels.", 0) != 0) {
      error = "line " + std::to_string(n) + ": only [[channels.<name>.stages]] arrays are supported";
      return false;
    }
    const std::string channel = name.substr(0, name.size() - 7);
    const int idx = doc.stage_count[channel]++;
    table = channel + ".stages[" + std::to_string(idx) + "]";
    doc.tables.insert(channel);
    return true;
  }
  const std::string name = trim(s.substr(1, s.size() - 2));
  if (s.back() != ']' || !bare_key(name)) {
    error = "line " + std::to_string(n) + ": bad table header (canonical layout: see gyrodrift config show)";
    return false;
  }
  table = name;
  doc.tables.insert(table);
  return true;
}

// A `key = value` line under `table`.
inline bool parse_assignment(const std::string& s, int n, const std::string& table, Doc& doc, std::string& error) {
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
  const std::string full = table.empty() ? key : table + "." + key;
  Value v;
  v.line = n;
  if (!parse_value(trim(s.substr(eq + 1)), v)) {
    error = "line " + std::to_string(n) + ": " + full +
            ": value not in the supported TOML subset (string, integer, float, inf, true/false)";
    return false;
  }
  if (doc.values.count(full) != 0) {
    error = full + ": given twice (line " + std::to_string(n) + ")";
    return false;
  }
  doc.values[full] = v;
  return true;
}

inline bool parse_doc(std::istream& in, Doc& doc, std::string& error) {
  std::string line;
  std::string table;
  for (int n = 1; std::getline(in, line); ++n) {
    const std::string s = trim(strip_comment(line));
    if (s.empty()) continue;
    const bool ok = s.front() == '[' ? parse_header(s, n, doc, table, error)
                                     : parse_assignment(s, n, table, doc, error);
    if (!ok) return false;
  }
  return true;
}

// A number as Python's repr(float) writes it: the shortest digits that read back to the same
// double, fixed notation for exponents -4..15, else d.ddde+XX ("400.0", "1e-10", "inf").
inline std::string repr_number(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char buf[40];
  for (int p = 0; p <= 16; ++p) {
    std::snprintf(buf, sizeof buf, "%.*e", p, x);
    if (std::strtod(buf, nullptr) == x) break;
  }
  std::string s(buf);  // [-]d[.ddd]e(+|-)XX
  const bool neg = s[0] == '-';
  if (neg) s.erase(0, 1);
  const auto e = s.find('e');
  const int exp10 = std::atoi(s.c_str() + e + 1);
  std::string digits = s.substr(0, e);
  if (digits.size() > 1) digits.erase(1, 1);  // drop the '.'
  std::string out;
  if (exp10 >= -4 && exp10 < 16) {
    if (exp10 < 0) {
      out = "0." + std::string(static_cast<std::size_t>(-exp10 - 1), '0') + digits;
    } else {
      const auto whole = static_cast<std::size_t>(exp10) + 1;
      if (digits.size() <= whole) out = digits + std::string(whole - digits.size(), '0') + ".0";
      else out = digits.substr(0, whole) + "." + digits.substr(whole);
    }
  } else {
    out = digits.substr(0, 1) + (digits.size() > 1 ? "." + digits.substr(1) : "");
    char ex[16];
    std::snprintf(ex, sizeof ex, "e%c%02d", exp10 < 0 ? '-' : '+', exp10 < 0 ? -exp10 : exp10);
    out += ex;
  }
  return neg ? "-" + out : out;
}

// A value as Python's repr writes it ('text', 5, 400.0, True).
inline std::string repr(const Value& v) {
  switch (v.kind) {
    case Value::Kind::string:
      return "'" + v.s + "'";
    case Value::Kind::integer:
      return std::to_string(v.i);
    case Value::Kind::boolean:
      return v.b ? "True" : "False";
    case Value::Kind::floating:
    default:
      return repr_number(v.d);
  }
}

}  // namespace gyrodrift::loop::toml
