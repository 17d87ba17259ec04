// The processor configuration file's TOML, read by toml++ (TOML 1.0), and the rules both
// configuration readers add to TOML (python/gyrodrift/imu/config.py: parse_config and
// _check_document), in the same order:
//   - the file is UTF-8 without a byte-order mark, and valid TOML 1.0 (integers in 64 bits);
//   - every float is a normal double or zero written as zero: a literal that overflows, or
//     whose nonzero value rounds to zero or a subnormal number (1e-400, 1e-310), is refused;
//   - tables and arrays nest at most kMaxNesting deep (the document is depth 0);
//   - then, by key in sorted order: a value that is not a string, number, boolean or table
//     (an array other than an array of tables, a date, a time) is not in the format.
// The first three are errors of the file ("<source>: not valid TOML: ..."), the last names
// the key. Also the values' text in errors, spelled as Python's repr spells them.
//
// Program code (standard library and toml++ allowed): the header-only core stays free of
// parsing.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wsign-conversion"
#pragma GCC diagnostic ignored "-Wfloat-equal"
#pragma GCC diagnostic ignored "-Wshadow"
#endif
#include <toml++/toml.h>
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

namespace gyrodrift::loop::tomldoc {

inline constexpr int kMaxNesting = 128;

// Strict UTF-8 (no overlong forms, no surrogates, at most U+10FFFF): what Python's
// bytes.decode("utf-8") accepts.
inline bool valid_utf8(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x80U) {
      ++i;
      continue;
    }
    std::size_t n = 0;
    std::uint32_t cp = 0;
    if (c >= 0xC2U && c <= 0xDFU) {
      n = 1;
      cp = c & 0x1FU;
    } else if (c >= 0xE0U && c <= 0xEFU) {
      n = 2;
      cp = c & 0x0FU;
    } else if (c >= 0xF0U && c <= 0xF4U) {
      n = 3;
      cp = c & 0x07U;
    } else {
      return false;
    }
    if (i + n >= s.size()) return false;
    for (std::size_t k = 1; k <= n; ++k) {
      const auto d = static_cast<unsigned char>(s[i + k]);
      if ((d & 0xC0U) != 0x80U) return false;
      cp = (cp << 6U) | (d & 0x3FU);
    }
    if ((n == 2 && (cp < 0x800U || (cp >= 0xD800U && cp <= 0xDFFFU))) || (n == 3 && (cp < 0x10000U || cp > 0x10FFFFU))) {
      return false;
    }
    i += n + 1;
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
  while (digits.size() > 1 && digits.back() == '0') digits.pop_back();
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

// A string as Python's repr writes it (single quotes unless the text holds one and no
// double quote; control characters escaped).
inline std::string repr_string(const std::string& s) {
  const bool dq = s.find('\'') != std::string::npos && s.find('"') == std::string::npos;
  const char q = dq ? '"' : '\'';
  std::string out(1, q);
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (ch == '\\') out += "\\\\";
    else if (ch == q) out += std::string("\\") + q;
    else if (ch == '\n') out += "\\n";
    else if (ch == '\r') out += "\\r";
    else if (ch == '\t') out += "\\t";
    else if (c < 0x20U || c == 0x7FU) {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02x", static_cast<unsigned>(c));
      out += b;
    } else out += ch;
  }
  return out + q;
}

// Python's repr of a scalar, "a table" / "an array" for the others.
inline std::string repr(const toml::node& n) {
  if (const auto* s = n.as_string()) return repr_string(s->get());
  if (const auto* i = n.as_integer()) return std::to_string(i->get());
  if (const auto* f = n.as_floating_point()) return repr_number(f->get());
  if (const auto* b = n.as_boolean()) return b->get() ? "True" : "False";
  if (n.is_table()) return "a table";
  return "an array";
}

// Python's type name of a value (the "expected a table, got int" errors).
inline const char* type_name(const toml::node& n) {
  if (n.is_string()) return "str";
  if (n.is_integer()) return "int";
  if (n.is_floating_point()) return "float";
  if (n.is_boolean()) return "bool";
  if (n.is_table()) return "dict";
  if (n.is_array()) return "list";
  return "date";
}

inline bool is_array_of_tables(const toml::array& a) {
  for (const auto& e : a) {
    if (!e.is_table()) return false;
  }
  return true;  // also the empty array, as the Python reader
}

// Nesting depth of tables and arrays (the document 0; a scalar counts at its depth).
inline int depth(const toml::node& n, int d) {
  int best = d;
  if (const auto* t = n.as_table()) {
    for (const auto& kv : *t) best = std::max(best, depth(kv.second, d + 1));
  } else if (const auto* a = n.as_array()) {
    for (const auto& e : *a) best = std::max(best, depth(e, d + 1));
  }
  return best;
}

// Every leaf under `n` with its dotted key, keys sorted; an array of tables is walked as
// tables (key[i]), any other array is a leaf.
inline void walk(const toml::node& n, const std::string& key, std::vector<std::pair<std::string, const toml::node*>>& out) {
  if (const auto* t = n.as_table()) {
    for (const auto& kv : *t) {
      const std::string k(kv.first.str());
      walk(kv.second, key.empty() ? k : key + "." + k, out);
    }
    return;
  }
  if (const auto* a = n.as_array()) {
    if (is_array_of_tables(*a)) {
      for (std::size_t i = 0; i < a->size(); ++i) walk(*a->get(i), key + "[" + std::to_string(i) + "]", out);
      return;
    }
  }
  out.emplace_back(key, &n);
}

// The literal text of a float value in the document (from its source position).
inline std::string literal_at(std::string_view text, const toml::source_position& pos) {
  std::size_t i = 0;
  for (std::uint32_t line = 1; line < pos.line && i < text.size(); ++i) {
    if (text[i] == '\n') ++line;
  }
  for (std::uint32_t col = 1; col < pos.column && i < text.size(); ++i) {
    if ((static_cast<unsigned char>(text[i]) & 0xC0U) != 0x80U) ++col;  // columns count code points
    while (i + 1 < text.size() && (static_cast<unsigned char>(text[i + 1]) & 0xC0U) == 0x80U) ++i;
  }
  std::string lit;
  for (; i < text.size(); ++i) {
    const char c = text[i];
    if ((c >= '0' && c <= '9') || c == '.' || c == 'e' || c == 'E' || c == '+' || c == '-' || c == '_') lit += c;
    else break;
  }
  return lit;
}

// A float literal whose nonzero value rounds to zero or a subnormal double.
inline bool underflows(const std::string& literal) {
  std::string mantissa = literal.substr(0, literal.find_first_of("eE"));
  return mantissa.find_first_of("123456789") != std::string::npos;
}

// Parses `text` and applies the rules above; false with `error` ("<key>: ..." or
// "<source>: ...", the source given) if the document is refused.
inline bool parse(const std::string& text, const std::string& source, toml::table& out, std::string& error) {
  if (!valid_utf8(text)) {
    error = source + ": not a UTF-8 text file";
    return false;
  }
  if (text.rfind("\xEF\xBB\xBF", 0) == 0) {
    error = source + ": not valid TOML: a byte-order mark (at line 1, column 1)";
    return false;
  }
  try {
    out = toml::parse(std::string_view(text), std::string_view(source));
  } catch (const toml::parse_error& e) {
    error = source + ": not valid TOML: " + std::string(e.description()) + " (at line " +
            std::to_string(e.source().begin.line) + ", column " + std::to_string(e.source().begin.column) + ")";
    return false;
  }
  std::vector<std::pair<std::string, const toml::node*>> leaves;
  walk(out, "", leaves);
  for (const auto& kv : leaves) {
    const auto* f = kv.second->as_floating_point();
    if (f == nullptr) continue;
    const double x = f->get();
    if (!std::isfinite(x) || std::fpclassify(x) == FP_NORMAL) continue;
    const std::string lit = literal_at(text, f->source().begin);
    if (underflows(lit)) {
      error = source + ": not valid TOML: float " + lit +
              " is outside the range of a double (normal magnitudes 2.2250738585072014e-308.."
              "1.7976931348623157e+308, or 0)";
      return false;
    }
  }
  if (depth(out, 0) > kMaxNesting) {
    error = source + ": not valid TOML: tables or arrays nested deeper than " + std::to_string(kMaxNesting);
    return false;
  }
  for (const auto& kv : leaves) {
    const toml::node& n = *kv.second;
    if (n.is_array() || n.is_date() || n.is_time() || n.is_date_time()) {
      error = source + ": " + kv.first + ": value not in the supported TOML subset (string, integer, float, inf, nan, true/false, tables)";
      return false;
    }
  }
  return true;
}

}  // namespace gyrodrift::loop::tomldoc
