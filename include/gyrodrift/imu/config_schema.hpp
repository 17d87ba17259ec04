// Generated from python/gyrodrift/imu/schema.py by scripts/gen-config-schema: do not edit.
// The processor configuration's fields (keys, units, defaults, bounds) are written once,
// in that Python table; the C++ defaults (imu_processor.hpp), the loop's configuration
// reader and its built-in default configuration follow from this header.
#pragma once
#include <cstddef>
#include <cstdint>
#include <limits>

namespace gyrodrift::config_schema {

enum class FieldKind : std::uint8_t { number, integer, boolean, string };

// One field of the file: its table ("timing", "channel" or a stage type), its name
// (the key, plus _rad_s / _m_s2 where channel_unit), its kind, whether it is required,
// its default (number or text) when it has one (absent and no default: derived, see
// help), its bounds (open or closed; +-kInf: none), finite-only, power of two, the
// accepted strings ('|'-separated), the bounds in words (both readers' error text), its
// unit and its help text.
struct FieldSpec {
  const char* section;
  const char* name;
  bool channel_unit;
  FieldKind kind;
  bool required;
  bool has_default;
  double default_value;
  const char* default_text;
  double lo;
  bool lo_open;
  double hi;
  bool hi_open;
  bool finite;
  bool power_of_two;
  bool float32;  // the processors hold it as a float32: it must fit one
  const char* choices;
  const char* bounds_text;
  const char* unit;
  const char* help;
};

inline constexpr double kInf = std::numeric_limits<double>::infinity();

inline constexpr FieldSpec kTimingSampleRateHz{
    "timing", "sample_rate_hz", false, FieldKind::number,
    true, false, 0.0, "",
    1.0, false, 100000.0, false, true, false, false,
    "", "1..100000 Hz", "Hz",
    "IMU sample rate: the nominal period of the timestamps is 1e6 / rate us"};
inline constexpr FieldSpec kTimingTimeToleranceUs{
    "timing", "time_tolerance_us", false, FieldKind::integer,
    false, false, 0.0, "",
    0.0, false, 4294967295.0, false, true, false, false,
    "", "0..4294967295 us", "us",
    "timestamp check: |dt - k period| above it is a time jump (absent: half a sample period; 0: check off)"};
inline constexpr FieldSpec kTimingLoopRateHz{
    "timing", "loop_rate_hz", false, FieldKind::number,
    false, false, 0.0, "",
    1.0, false, 2000.0, false, true, false, false,
    "", "1..2000 Hz", "Hz",
    "rate of the loop program's cycle (absent: the sample rate)"};
inline constexpr FieldSpec kChannelSaturation{
    "channel", "saturation", true, FieldKind::number,
    false, true, kInf, "",
    0.0, true, kInf, false, false, false, true,
    "", "> 0 (or inf: off)", "channel",
    "|x| >= saturation marks a value saturated (inf: off)"};
inline constexpr FieldSpec kChannelStuckSamples{
    "channel", "stuck_samples", false, FieldKind::integer,
    false, true, 0.0, "",
    0.0, false, 4294967295.0, false, true, false, false,
    "", "0..4294967295", "samples",
    "the N-th identical value in a row marks the channel stuck (0: off)"};
inline constexpr FieldSpec kBiasRemovalBias{
    "bias_removal", "bias", true, FieldKind::number,
    true, false, 0.0, "",
    -kInf, false, kInf, false, true, false, true,
    "", "finite", "channel",
    "subtracted from every sample"};
inline constexpr FieldSpec kWaveletWavelet{
    "wavelet", "wavelet", false, FieldKind::string,
    true, false, 0.0, "",
    -kInf, false, kInf, false, true, false, false,
    "db4|db8", "one of db4, db8", "",
    "wavelet of the real-time sliding-window prefilter"};
inline constexpr FieldSpec kWaveletWindow{
    "wavelet", "window", false, FieldKind::integer,
    true, false, 0.0, "",
    16.0, false, 4096.0, false, true, true, false,
    "", "a power of two in 16..4096", "samples",
    "sliding window length N"};
inline constexpr FieldSpec kWaveletLevel{
    "wavelet", "level", false, FieldKind::integer,
    true, false, 0.0, "",
    1.0, false, 8.0, false, true, false, false,
    "", "1..8", "",
    "decomposition level J (at most the deepest level of the extended window 2N)"};
inline constexpr FieldSpec kWaveletThreshold{
    "wavelet", "threshold", false, FieldKind::string,
    false, true, 0.0, "forced",
    -kInf, false, kInf, false, true, false, false,
    "forced|soft|hard", "one of forced, soft, hard", "",
    "detail handling: forced (all details zeroed), soft or hard"};
inline constexpr FieldSpec kAr2KalmanA1{
    "ar2_kalman", "a1", false, FieldKind::number,
    true, false, 0.0, "",
    -kInf, false, kInf, false, true, false, true,
    "", "finite", "",
    "AR(2) coefficient of x[k-1] (the model must be stationary)"};
inline constexpr FieldSpec kAr2KalmanA2{
    "ar2_kalman", "a2", false, FieldKind::number,
    true, false, 0.0, "",
    -kInf, false, kInf, false, true, false, true,
    "", "finite", "",
    "AR(2) coefficient of x[k-2]"};
inline constexpr FieldSpec kAr2KalmanMean{
    "ar2_kalman", "mean", true, FieldKind::number,
    true, false, 0.0, "",
    -2.028240839472585e+31, false, 2.028240839472585e+31, false, true, false, true,
    "", "-2.028240839472585e+31..2.028240839472585e+31", "channel",
    "model mean (constant drift; within the float32 filters' input range)"};
inline constexpr FieldSpec kAr2KalmanSigma2{
    "ar2_kalman", "sigma2", false, FieldKind::number,
    false, false, 0.0, "",
    0.0, false, 1e+30, false, true, false, true,
    "", "0..1e+30", "channel^2",
    "AR(2) driving-noise variance (absent: q)"};
inline constexpr FieldSpec kAr2KalmanQ{
    "ar2_kalman", "q", false, FieldKind::number,
    true, false, 0.0, "",
    0.0, false, 1e+30, false, true, false, true,
    "", "0..1e+30", "channel^2",
    "Kalman process-noise variance"};
inline constexpr FieldSpec kAr2KalmanR{
    "ar2_kalman", "r", false, FieldKind::number,
    true, false, 0.0, "",
    0.0, true, 1e+30, false, true, false, true,
    "", "> 0 and <= 1e+30", "channel^2",
    "Kalman measurement-noise variance"};
inline constexpr FieldSpec kAr2KalmanP0{
    "ar2_kalman", "p0", false, FieldKind::number,
    false, true, 1.0, "",
    0.0, false, 1e+30, false, true, false, true,
    "", "0..1e+30", "channel^2",
    "initial state covariance P_0 = p0 I"};
inline constexpr FieldSpec kAr2KalmanSteadyState{
    "ar2_kalman", "steady_state", false, FieldKind::boolean,
    false, true, 0.0, "",
    -kInf, false, kInf, false, true, false, false,
    "", "finite", "",
    "constant (DARE steady-state) Kalman gain instead of the time-varying one"};
inline constexpr FieldSpec kMonitorEnabled{
    "monitor", "enabled", false, FieldKind::boolean,
    false, true, 0.0, "",
    -kInf, false, kInf, false, true, false, false,
    "", "finite", "",
    "run the gyro monitor (streaming Allan statistics, health alarms, online re-identification) on every gyro channel whose first stage is ar2_kalman (its model is the reference and the fallback)"};
inline constexpr FieldSpec kMonitorOctaves{
    "monitor", "octaves", false, FieldKind::integer,
    false, true, 16.0, "",
    2.0, false, 24.0, false, true, false, false,
    "", "2..24", "",
    "octaves of the streaming Allan curve: tau = 2^k / sample rate, k = 0 .. octaves - 1"};
inline constexpr FieldSpec kMonitorReportIntervalS{
    "monitor", "report_interval_s", false, FieldKind::number,
    false, true, 10.0, "",
    0.0, true, 86400.0, false, true, false, false,
    "", "> 0 and <= 86400", "s",
    "interval of the monitor's reports (noise estimates, model in use, alarms)"};
inline constexpr FieldSpec kMonitorCoverage{
    "monitor", "coverage", false, FieldKind::number,
    false, true, 0.6826894921370859, "",
    0.0, true, 1.0, true, true, false, true,
    "", "> 0 and < 1", "",
    "coverage of the noise estimates' intervals (default: one sigma)"};
inline constexpr FieldSpec kMonitorArwFactor{
    "monitor", "arw_factor", false, FieldKind::number,
    false, true, 2.0, "",
    1.0, true, 1000.0, false, true, false, true,
    "", "> 1 and <= 1000", "",
    "alarm when the angle random walk N is up by more than this factor"};
inline constexpr FieldSpec kMonitorBiasInstabilityFactor{
    "monitor", "bias_instability_factor", false, FieldKind::number,
    false, true, 2.0, "",
    1.0, true, 1000.0, false, true, false, true,
    "", "> 1 and <= 1000", "",
    "alarm when the bias instability B is up by more than this factor"};
inline constexpr FieldSpec kMonitorRateRandomWalkFactor{
    "monitor", "rate_random_walk_factor", false, FieldKind::number,
    false, true, 2.0, "",
    1.0, true, 1000.0, false, true, false, true,
    "", "> 1 and <= 1000", "",
    "alarm when the rate random walk K is up by more than this factor"};
inline constexpr FieldSpec kMonitorFalseAlarmProbability{
    "monitor", "false_alarm_probability", false, FieldKind::number,
    false, true, 1e-06, "",
    0.0, true, 0.5, false, true, false, true,
    "", "> 0 and <= 0.5", "",
    "false-alarm probability of one check of one octave (the chi-square bound)"};
inline constexpr FieldSpec kMonitorStuckAlarmS{
    "monitor", "stuck_alarm_s", false, FieldKind::number,
    false, true, 1.0, "",
    0.0, false, 86400.0, false, true, false, false,
    "", "0..86400", "s",
    "a channel stuck this long without a break raises the stuck alarm (0: off)"};
inline constexpr FieldSpec kMonitorSaturatedAlarmS{
    "monitor", "saturated_alarm_s", false, FieldKind::number,
    false, true, 1.0, "",
    0.0, false, 86400.0, false, true, false, false,
    "", "0..86400", "s",
    "a channel saturated this long without a break raises the saturated alarm (0: off)"};
inline constexpr FieldSpec kMonitorReidentify{
    "monitor", "reidentify", false, FieldKind::boolean,
    false, true, 0.0, "",
    -kInf, false, kInf, false, true, false, false,
    "", "finite", "",
    "re-identify the drift model online and retune the steady-state AR(2)-Kalman gain"};
inline constexpr FieldSpec kMonitorIdentifier{
    "monitor", "identifier", false, FieldKind::string,
    false, true, 0.0, "recursive",
    -kInf, false, kInf, false, true, false, false,
    "recursive|lag", "one of recursive, lag", "",
    "the re-identification's method: recursive (a recursive estimator updated every block, with an optional forgetting memory, memory_s: follows a change, but does not settle on the offline maximum-likelihood fit on every record) or lag (whole-record lag statistics per gyro and their maximum-likelihood fit every retune_s: converges to the offline fit of the samples seen; restart_after_fit to follow a change)"};
inline constexpr FieldSpec kMonitorReidentifyAr{
    "monitor", "reidentify_ar", false, FieldKind::boolean,
    false, true, 1.0, "",
    -kInf, false, kInf, false, true, false, false,
    "", "finite", "",
    "both identifiers: re-identify the drift's AR coefficients a1, a2 too (false: hold them at the configured model and fit q and r only, which follows a change of the noise levels in a shorter memory)"};
inline constexpr FieldSpec kMonitorBlockS{
    "monitor", "block_s", false, FieldKind::number,
    false, true, 1.0, "",
    0.0, true, 3600.0, false, true, false, false,
    "", "> 0 and <= 3600", "s",
    "recursive identifier: samples per update of the re-identified parameters, in seconds (at least 8 samples); both identifiers: the unit retune_s is rounded to"};
inline constexpr FieldSpec kMonitorRetuneS{
    "monitor", "retune_s", false, FieldKind::number,
    false, true, 60.0, "",
    0.0, true, 86400.0, false, true, false, false,
    "", "> 0 and <= 86400", "s",
    "both identifiers: time between gain retunes of one gyro (rounded to whole blocks, at least one)"};
inline constexpr FieldSpec kMonitorMinLearnS{
    "monitor", "min_learn_s", false, FieldKind::number,
    false, true, 600.0, "",
    0.0, false, 10000000.0, false, true, false, false,
    "", "0..10000000", "s",
    "both identifiers: no retune before this much accepted data (lag: data in the gyro's statistics)"};
inline constexpr FieldSpec kMonitorMemoryS{
    "monitor", "memory_s", false, FieldKind::number,
    false, true, 0.0, "",
    0.0, false, 10000000.0, false, true, false, false,
    "", "0..10000000", "s",
    "recursive identifier: forgetting horizon of the re-identification (0: none, for a stationary sensor: the estimate settles near the maximum-likelihood fit of everything seen; else at least one block, to track a change)"};
inline constexpr FieldSpec kMonitorMaxStep{
    "monitor", "max_step", false, FieldKind::number,
    false, true, 0.1, "",
    0.0, true, 10.0, false, true, false, true,
    "", "> 0 and <= 10", "",
    "both identifiers: largest change of one parameter per update (log q, log r; the AR part; lag: per retune)"};
inline constexpr FieldSpec kMonitorIdentifiedMaxRelStderr{
    "monitor", "identified_max_rel_stderr", false, FieldKind::number,
    false, true, 0.5, "",
    0.0, true, 10.0, false, true, false, true,
    "", "> 0 and <= 10", "",
    "both identifiers: retune only when the relative standard errors of q and r are at most this (the drift/noise split is identified)"};
inline constexpr FieldSpec kMonitorFitDelayS{
    "monitor", "fit_delay_s", false, FieldKind::number,
    false, true, 15.0, "",
    0.0, true, 86400.0, false, true, false, false,
    "", "> 0 and <= 86400", "s",
    "lag identifier: time from a fit's start to the retune that applies it; the target runs the fit in the background and must finish it within this time, while the gyro's statistics pause. With n watched gyros n x fit_delay_s must be at most retune_s (in samples). Default: a fit takes under a second of a 168 MHz Cortex-M4F beside a 400 Hz loop (3e7 to 1e8 instructions), so 15 s leaves a wide margin, and three gyros then take their turns within the default retune_s, with room for the rounding to whole samples"};
inline constexpr FieldSpec kMonitorRestartAfterFit{
    "monitor", "restart_after_fit", false, FieldKind::boolean,
    false, true, 0.0, "",
    -kInf, false, kInf, false, true, false, false,
    "", "finite", "",
    "lag identifier: each fit uses only the samples since that gyro's previous fit, to follow a change of the noise (false: everything since the start, converging on a stationary sensor)"};

inline constexpr const FieldSpec* kFields[] = {
    &kTimingSampleRateHz,
    &kTimingTimeToleranceUs,
    &kTimingLoopRateHz,
    &kChannelSaturation,
    &kChannelStuckSamples,
    &kBiasRemovalBias,
    &kWaveletWavelet,
    &kWaveletWindow,
    &kWaveletLevel,
    &kWaveletThreshold,
    &kAr2KalmanA1,
    &kAr2KalmanA2,
    &kAr2KalmanMean,
    &kAr2KalmanSigma2,
    &kAr2KalmanQ,
    &kAr2KalmanR,
    &kAr2KalmanP0,
    &kAr2KalmanSteadyState,
    &kMonitorEnabled,
    &kMonitorOctaves,
    &kMonitorReportIntervalS,
    &kMonitorCoverage,
    &kMonitorArwFactor,
    &kMonitorBiasInstabilityFactor,
    &kMonitorRateRandomWalkFactor,
    &kMonitorFalseAlarmProbability,
    &kMonitorStuckAlarmS,
    &kMonitorSaturatedAlarmS,
    &kMonitorReidentify,
    &kMonitorIdentifier,
    &kMonitorReidentifyAr,
    &kMonitorBlockS,
    &kMonitorRetuneS,
    &kMonitorMinLearnS,
    &kMonitorMemoryS,
    &kMonitorMaxStep,
    &kMonitorIdentifiedMaxRelStderr,
    &kMonitorFitDelayS,
    &kMonitorRestartAfterFit,
};
inline constexpr std::size_t kFieldCount = 39;

inline constexpr const char* kSchema = "gyrodrift.processor";
inline constexpr int kVersion = 1;
inline constexpr const char* kChannelNames[] = {"gx", "gy", "gz", "ax", "ay", "az"};
inline constexpr int kMaxStages = 2;

// The shipped default configuration's sample rate and the timing derived from it.
inline constexpr double kDefaultSampleRateHz = 400.0;
inline constexpr std::uint32_t kDefaultPeriodUs = 2500U;
inline constexpr std::uint32_t kDefaultTimeToleranceUs = 1250U;

// The shipped default configuration's bad-value detection on the gyros (rad/s) and
// the accelerometers (m/s^2).
inline constexpr double kDefaultGyroSaturationRadS = 8.0;
inline constexpr double kDefaultAccelSaturationMS2 = 160.0;
inline constexpr std::uint32_t kDefaultGyroStuckSamples = 50U;

// The real-time prefilter of the 2014 paper: the wavelet stage's defaults.
inline constexpr const char* kPrefilterWavelet = "db4";
inline constexpr std::size_t kPrefilterWindow = 256;
inline constexpr int kPrefilterLevel = 5;

// The demonstration AR(2)-Kalman model of the default configuration (sigma2 = q).
struct DemoAr2 {
  static constexpr double a1 = 1.0, a2 = -0.25, mean = 0.0, q = 1e-10, r = 1e-08, sigma2 = 1e-10;
};

// The shipped default configuration (`gyrodrift config write-default`), canonical text.
inline constexpr const char kDefaultConfigToml[] = R"gyrodrift(# gyrodrift processor configuration (see the configuration file guide in the documentation)
schema = "gyrodrift.processor"
version = 1

[meta]
written_by = "gyrodrift config write-default"

[timing]
sample_rate_hz = 400.0
time_tolerance_us = 1250
loop_rate_hz = 400.0

[channels.gx]
saturation_rad_s = 8.0
stuck_samples = 50

[[channels.gx.stages]]
type = "wavelet"
wavelet = "db4"
window = 256
level = 5
threshold = "forced"

[[channels.gx.stages]]
type = "ar2_kalman"
a1 = 1.0
a2 = -0.25
mean_rad_s = 0.0
sigma2 = 1e-10
q = 1e-10
r = 1e-08
p0 = 1.0
steady_state = true

[channels.gy]
saturation_rad_s = 8.0
stuck_samples = 50

[[channels.gy.stages]]
type = "wavelet"
wavelet = "db4"
window = 256
level = 5
threshold = "forced"

[[channels.gy.stages]]
type = "ar2_kalman"
a1 = 1.0
a2 = -0.25
mean_rad_s = 0.0
sigma2 = 1e-10
q = 1e-10
r = 1e-08
p0 = 1.0
steady_state = true

[channels.gz]
saturation_rad_s = 8.0
stuck_samples = 50

[[channels.gz.stages]]
type = "wavelet"
wavelet = "db4"
window = 256
level = 5
threshold = "forced"

[[channels.gz.stages]]
type = "ar2_kalman"
a1 = 1.0
a2 = -0.25
mean_rad_s = 0.0
sigma2 = 1e-10
q = 1e-10
r = 1e-08
p0 = 1.0
steady_state = true

[channels.ax]
saturation_m_s2 = 160.0
stuck_samples = 0

[[channels.ax.stages]]
type = "bias_removal"
bias_m_s2 = 0.0

[channels.ay]
saturation_m_s2 = 160.0
stuck_samples = 0

[[channels.ay.stages]]
type = "bias_removal"
bias_m_s2 = 0.0

[channels.az]
saturation_m_s2 = 160.0
stuck_samples = 0

[[channels.az.stages]]
type = "bias_removal"
bias_m_s2 = 0.0
)gyrodrift";

}  // namespace gyrodrift::config_schema
