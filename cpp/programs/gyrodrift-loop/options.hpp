// gyrodrift-loop command line: the options, their parsing and the usage text.
//
// One meaning per flag: the command line says where the samples come from and how the
// program runs; the processor and the rates (the sample rate of the timestamps, the loop's
// cycle rate) come only from a configuration: --config FILE, or the built-in default
// configuration (config_schema::kDefaultConfigToml).
#pragma once
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <gyrodrift/imu/config_schema.hpp>

namespace gyrodrift::loop {

enum class Mode { kSerial, kSlcan, kSocketCan };

struct Options {
  Mode mode = Mode::kSerial;
  std::string device;
  long baud = 921600;
  bool realtime = true;
  int rt_priority = 80;
  std::size_t max_bytes_per_cycle = 65536;
  double idle_exit_s = 0.0;  // 0: never (exit on EOF or signal)
  double duration_s = 0.0;   // 0: unlimited
  std::string stats_path;
  std::string can_signals_path;   // --can-signals: decode CAN input through a user DBC table
  std::string config_path;        // --config FILE: the processor and the rates (empty: built-in default)
  std::string check_config_path;  // --check-config FILE: only read and check FILE
};

inline void usage(std::FILE* f) {
  std::fputs(
      "usage: gyrodrift-loop (--serial DEV | --slcan DEV | --socketcan IFACE) [--config FILE] [options]\n"
      "       gyrodrift-loop --check-config FILE\n"
      "  DEV is a device path (/dev/ttyUSB0, /dev/pts/N) or fd:N (inherited descriptor)\n"
      "  --config FILE         the processor configuration (TOML, version 1; the configuration\n"
      "                        file guide in the documentation): per-channel chains incl. the\n"
      "                        wavelet stage, saturation and stuck detection, and [timing]:\n"
      "                        sample_rate_hz (the\n"
      "                        timestamps' period, CAN timestamps), time_tolerance_us, loop_rate_hz\n"
      "                        (this loop's cycle, 1..2000 Hz; absent: the sample rate)\n",
      f);
  std::fprintf(f,
               "                        Without --config: the built-in default configuration, the file\n"
               "                        `gyrodrift config write-default` writes (sample rate %g Hz)\n",
               config_schema::kDefaultSampleRateHz);
  std::fputs(
      "  --check-config FILE   read and check FILE as --config does: print \"FILE: ok\" (exit 0) or\n"
      "                        the error naming the key (exit 2); no device\n"
      "  --baud N              serial line rate (default 921600; a pty ignores it)\n"
      "  --no-rt               do not request SCHED_FIFO and mlockall\n"
      "  --rt-priority N       SCHED_FIFO priority (default 80)\n"
      "  --max-bytes-per-cycle N  input read budget per cycle (default 65536)\n"
      "  --idle-exit-s S       exit after S seconds without input (default: never)\n"
      "  --duration-s S        exit after S seconds (default: never)\n"
      "  --stats-json PATH     also write the final statistics to PATH\n"
      "  --can-signals FILE    CAN input in a user's DBC layout: the decode table generated\n"
      "                        from it (gyrodrift.codecs.can_signals.decode_table_text)\n",
      f);
}

// Options this program no longer has, and where their meaning went.
inline const char* retired_option(const std::string& a) {
  static const char* const kProcessor[] = {"--gyro-filter",      "--accel-filter",     "--gyro-ar2",
                                           "--gyro-q",           "--gyro-r",           "--gyro-bias",
                                           "--accel-bias",       "--gyro-saturation",  "--accel-saturation",
                                           "--stuck-samples",    "--time-tolerance-us"};
  for (const char* p : kProcessor) {
    if (a == p) return "no such option: the processor comes from --config FILE (gyrodrift config write-default)";
  }
  if (a == "--rate-hz" || a == "--sample-rate-hz") {
    return "no such option: the rates come from the configuration's [timing] sample_rate_hz and loop_rate_hz";
  }
  return nullptr;
}

inline bool parse_double(const char* s, double& out) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s, &end);
  if (end == s || *end != '\0' || errno != 0 || !std::isfinite(v)) return false;
  out = v;
  return true;
}

// A duration in seconds: finite, 0..1e9 (some 30 years; its nanoseconds fit 64 bits).
inline bool parse_seconds(const char* s, double& out) {
  double v = 0.0;
  if (!parse_double(s, v) || !(v >= 0.0 && v <= 1e9)) return false;
  out = v;
  return true;
}

inline bool parse_long(const char* s, long& out) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(s, &end, 10);
  if (end == s || *end != '\0' || errno != 0) return false;
  out = v;
  return true;
}

inline bool takes_value(const std::string& a) {
  static const char* const kValued[] = {"--serial",     "--slcan",      "--socketcan",          "--baud",
                                        "--config",     "--check-config", "--rt-priority",      "--max-bytes-per-cycle",
                                        "--idle-exit-s", "--duration-s", "--stats-json",         "--can-signals"};
  for (const char* p : kValued) {
    if (a == p) return true;
  }
  return false;
}

// Option `a` (one of takes_value) with its value `v`; false with `err` if the value is bad.
inline bool set_value_option(const std::string& a, const char* v, Options& o, std::string& err) {
  long n = 0;
  if (a == "--serial" || a == "--slcan" || a == "--socketcan") {
    o.mode = a == "--serial" ? Mode::kSerial : (a == "--slcan" ? Mode::kSlcan : Mode::kSocketCan);
    o.device = v;
  } else if (a == "--config") {
    o.config_path = v;
  } else if (a == "--check-config") {
    o.check_config_path = v;
  } else if (a == "--stats-json") {
    o.stats_path = v;
  } else if (a == "--can-signals") {
    o.can_signals_path = v;
  } else if (a == "--baud") {
    if (!parse_long(v, n) || n < 50 || n > 4000000) return err = "bad --baud (50..4000000)", false;
    o.baud = n;
  } else if (a == "--rt-priority") {
    if (!parse_long(v, n) || n < 1 || n > 99) return err = "bad --rt-priority (1..99)", false;
    o.rt_priority = static_cast<int>(n);
  } else if (a == "--max-bytes-per-cycle") {
    if (!parse_long(v, n) || n < 64 || n > (1L << 20)) return err = "bad --max-bytes-per-cycle (64..1048576)", false;
    o.max_bytes_per_cycle = static_cast<std::size_t>(n);
  } else if (a == "--idle-exit-s") {
    if (!parse_seconds(v, o.idle_exit_s)) return err = "bad --idle-exit-s (0..1e9)", false;
  } else if (a == "--duration-s") {
    if (!parse_seconds(v, o.duration_s)) return err = "bad --duration-s (0..1e9)", false;
  }
  return true;
}

// The combinations: one input interface, or --check-config alone.
inline bool check_combination(const Options& o, int modes, int given, std::string& err) {
  if (!o.check_config_path.empty()) {
    if (given != 1) return err = "--check-config FILE takes no other option", false;
    return true;
  }
  if (modes != 1) return err = "give exactly one of --serial, --slcan, --socketcan (or --check-config FILE)", false;
  if (!o.can_signals_path.empty() && o.mode == Mode::kSerial) {
    return err = "--can-signals applies to --slcan and --socketcan input", false;
  }
  return true;
}

inline bool parse_args(int argc, char** argv, Options& o, std::string& err) {
  int modes = 0;
  int given = 0;  // options given
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    ++given;
    if (a == "-h" || a == "--help") {
      usage(stdout);
      std::exit(0);
    } else if (a == "--no-rt") {
      o.realtime = false;
    } else if (const char* why = retired_option(a)) {
      return err = a + ": " + why, false;
    } else if (!takes_value(a)) {
      return err = "unknown argument '" + a + "' (gyrodrift-loop --help lists the options)", false;
    } else if (i + 1 >= argc) {
      return err = a + " needs a value", false;
    } else if (!set_value_option(a, argv[++i], o, err)) {
      return false;
    }
    if (a == "--serial" || a == "--slcan" || a == "--socketcan") ++modes;
  }
  return check_combination(o, modes, given, err);
}

}  // namespace gyrodrift::loop
