// gyrodrift-loop command line: the options, their parsing and the usage text.
#pragma once
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "processing.hpp"

namespace gyrodrift::loop {

inline bool is_processor_option(const std::string& a) {
  return a.rfind("--gyro-", 0) == 0 || a.rfind("--accel-", 0) == 0 || a == "--stuck-samples" ||
         a == "--time-tolerance-us";
}

enum class Mode { kSerial, kSlcan, kSocketCan };

struct Options {
  Mode mode = Mode::kSerial;
  std::string device;
  long baud = 921600;
  double rate_hz = 400.0;
  double sample_rate_hz = 400.0;  // CAN carries no timestamp: t_us = unwrapped seq / rate
  bool realtime = true;
  int rt_priority = 80;
  std::size_t max_bytes_per_cycle = 65536;
  double idle_exit_s = 0.0;  // 0: never (exit on EOF or signal)
  double duration_s = 0.0;   // 0: unlimited
  std::string stats_path;
  std::string can_signals_path;  // --can-signals: decode CAN input through a user DBC table
  std::string config_path;  // --config FILE: the processor (and rates) from the file
  bool rate_given = false, sample_rate_given = false;
  ProcessingOptions proc;
  bool proc_option_given = false;  // a processor option on the command line (not with --config)
};

inline void usage(std::FILE* f) {
  std::fputs(
      "usage: gyrodrift-loop (--serial DEV | --slcan DEV | --socketcan IFACE) [options]\n"
      "  DEV is a device path (/dev/ttyUSB0, /dev/pts/N) or fd:N (inherited descriptor)\n"
      "  --baud N              serial line rate (default 921600; a pty ignores it)\n"
      "  --rate-hz F           loop rate, 1..2000 Hz (default 400)\n"
      "  --sample-rate-hz F    IMU sample rate for CAN timestamps (default 400)\n"
      "  --no-rt               do not request SCHED_FIFO and mlockall\n"
      "  --rt-priority N       SCHED_FIFO priority (default 80)\n"
      "  --max-bytes-per-cycle N  input read budget per cycle (default 65536)\n"
      "  --idle-exit-s S       exit after S seconds without input (default: never)\n"
      "  --duration-s S        exit after S seconds (default: never)\n"
      "  --stats-json PATH     also write the final statistics to PATH\n"
      "  --can-signals FILE    CAN input in a user's DBC layout: the decode table generated\n"
      "                        from it (gyrodrift.codecs.can_signals.decode_table_text)\n"
      "  --config FILE         processor configuration file (TOML, version 1; README \"Processor\n"
      "                        configuration file\"): per-channel chains incl. the wavelet stage,\n"
      "                        rates and tolerances. Excludes the processor options below;\n"
      "                        --rate-hz/--sample-rate-hz override its timing.\n"
      "processor without --config (ImuProcessor<float>; the same settings go to the Python reference):\n"
      "  --gyro-filter F       ar2_kalman (default) | bias_removal | pass_through\n"
      "  --accel-filter F      pass_through (default) | bias_removal | ar2_kalman\n"
      "  --gyro-ar2 A1,A2,SIGMA2,MEAN  AR(2) model (default 1.0,-0.25,1e-10,0: a demo model)\n"
      "  --gyro-q Q --gyro-r R Kalman process/measurement variances (default 1e-10, 1e-8)\n"
      "  --gyro-bias B --accel-bias B  subtracted after the filter (default 0)\n"
      "  --gyro-saturation S --accel-saturation S  |x| >= S is saturated (default inf)\n"
      "  --stuck-samples N     N identical values in a row = stuck (default 0: off)\n"
      "  --time-tolerance-us N timestamp check tolerance (default half a period)\n",
      f);
}

inline bool parse_double(const char* s, double& out) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s, &end);
  if (end == s || *end != '\0' || errno != 0 || !std::isfinite(v)) return false;
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

inline bool parse_args(int argc, char** argv, Options& o, std::string& err) {
  int modes = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto need = [&](const char* what) -> const char* {
      if (i + 1 >= argc) {
        err = std::string(what) + " needs a value";
        return nullptr;
      }
      return argv[++i];
    };
    const char* v = nullptr;
    if (is_processor_option(a)) o.proc_option_given = true;
    if (a == "-h" || a == "--help") {
      usage(stdout);
      std::exit(0);
    } else if (a == "--serial" || a == "--slcan" || a == "--socketcan") {
      if ((v = need(a.c_str())) == nullptr) return false;
      o.mode = a == "--serial" ? Mode::kSerial : (a == "--slcan" ? Mode::kSlcan : Mode::kSocketCan);
      o.device = v;
      ++modes;
    } else if (a == "--baud") {
      if ((v = need("--baud")) == nullptr || !parse_long(v, o.baud)) return err = "bad --baud", false;
    } else if (a == "--rate-hz") {
      if ((v = need("--rate-hz")) == nullptr || !parse_double(v, o.rate_hz)) return err = "bad --rate-hz", false;
      o.rate_given = true;
    } else if (a == "--sample-rate-hz") {
      if ((v = need("--sample-rate-hz")) == nullptr || !parse_double(v, o.sample_rate_hz) ||
          o.sample_rate_hz <= 0.0) {
        return err = "bad --sample-rate-hz", false;
      }
      o.sample_rate_given = true;
    } else if (a == "--config") {
      if ((v = need("--config")) == nullptr) return false;
      o.config_path = v;
    } else if (a == "--gyro-filter" || a == "--accel-filter") {
      if ((v = need(a.c_str())) == nullptr ||
          !parse_filter(v, a == "--gyro-filter" ? o.proc.gyro_filter : o.proc.accel_filter)) {
        return err = "bad " + a + " (ar2_kalman, bias_removal, pass_through)", false;
      }
    } else if (a == "--gyro-ar2") {
      double m[4] = {0, 0, 0, 0};
      if ((v = need("--gyro-ar2")) == nullptr || !parse_csv4(v, m)) {
        return err = "bad --gyro-ar2 (A1,A2,SIGMA2,MEAN)", false;
      }
      o.proc.a1 = m[0];
      o.proc.a2 = m[1];
      o.proc.sigma2 = m[2];
      o.proc.mean = m[3];
    } else if (a == "--gyro-q" || a == "--gyro-r" || a == "--gyro-bias" || a == "--accel-bias" ||
               a == "--gyro-saturation" || a == "--accel-saturation") {
      double x = 0.0;
      const bool sat = a == "--gyro-saturation" || a == "--accel-saturation";
      if ((v = need(a.c_str())) == nullptr) return false;
      if (sat && std::string(v) == "inf") x = INFINITY;
      else if (!parse_double(v, x)) return err = "bad " + a, false;
      if (a == "--gyro-q") o.proc.q = x;
      else if (a == "--gyro-r") o.proc.r = x;
      else if (a == "--gyro-bias") o.proc.gyro_bias = x;
      else if (a == "--accel-bias") o.proc.accel_bias = x;
      else if (a == "--gyro-saturation") o.proc.gyro_saturation = x;
      else o.proc.accel_saturation = x;
    } else if (a == "--stuck-samples") {
      long n = 0;
      if ((v = need("--stuck-samples")) == nullptr || !parse_long(v, n) || n < 0 || n > 1000000) {
        return err = "bad --stuck-samples", false;
      }
      o.proc.stuck_samples = static_cast<std::uint32_t>(n);
    } else if (a == "--time-tolerance-us") {
      if ((v = need("--time-tolerance-us")) == nullptr || !parse_long(v, o.proc.time_tolerance_us) ||
          o.proc.time_tolerance_us < 0) {
        return err = "bad --time-tolerance-us", false;
      }
    } else if (a == "--no-rt") {
      o.realtime = false;
    } else if (a == "--rt-priority") {
      long p = 0;
      if ((v = need("--rt-priority")) == nullptr || !parse_long(v, p) || p < 1 || p > 99) {
        return err = "bad --rt-priority (1..99)", false;
      }
      o.rt_priority = static_cast<int>(p);
    } else if (a == "--max-bytes-per-cycle") {
      long n = 0;
      if ((v = need("--max-bytes-per-cycle")) == nullptr || !parse_long(v, n) || n < 64 || n > (1L << 20)) {
        return err = "bad --max-bytes-per-cycle (64..1048576)", false;
      }
      o.max_bytes_per_cycle = static_cast<std::size_t>(n);
    } else if (a == "--idle-exit-s") {
      if ((v = need("--idle-exit-s")) == nullptr || !parse_double(v, o.idle_exit_s) || o.idle_exit_s < 0.0) {
        return err = "bad --idle-exit-s", false;
      }
    } else if (a == "--duration-s") {
      if ((v = need("--duration-s")) == nullptr || !parse_double(v, o.duration_s) || o.duration_s < 0.0) {
        return err = "bad --duration-s", false;
      }
    } else if (a == "--stats-json") {
      if ((v = need("--stats-json")) == nullptr) return false;
      o.stats_path = v;
    } else if (a == "--can-signals") {
      if ((v = need("--can-signals")) == nullptr) return false;
      o.can_signals_path = v;
    } else {
      err = "unknown argument '" + a + "'";
      return false;
    }
  }
  if (!o.config_path.empty() && o.proc_option_given) {
    err = "--config gives the processor: do not combine it with --gyro-*/--accel-*/--stuck-samples/"
          "--time-tolerance-us options";
    return false;
  }
  if (modes != 1) {
    err = "give exactly one of --serial, --slcan, --socketcan";
    return false;
  }
  if (!o.can_signals_path.empty() && o.mode == Mode::kSerial) {
    err = "--can-signals applies to --slcan and --socketcan input";
    return false;
  }
  if (!(o.rate_hz >= 1.0 && o.rate_hz <= 2000.0)) {
    err = "--rate-hz must be within 1..2000";
    return false;
  }
  return true;
}

}  // namespace gyrodrift::loop
