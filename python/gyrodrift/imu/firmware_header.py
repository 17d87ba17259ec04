"""`gyrodrift config emit-cpp`: a processor configuration as a constexpr C++ header for firmware.

The header holds the same values as the file, as float literals (the MCU build is float), and
the FIR taps of every forced wavelet stage as a constexpr table (flash on an MCU: the forced
prefilter is an exact FIR whose taps depend only on the wavelet, the window and the level;
include/gyrodrift/filters/fir_prefilter.hpp). A firmware project writes::

    #include "imu_config.hpp"   // generated
    gyrodrift_config::Processor proc(gyrodrift_config::kImuConfig, gyrodrift_config::make_wavelet);

and pays only for what it uses: the wavelet window exists on channels 0..kWaveletChannels-1,
with one window copy per channel and the taps in flash.

Threshold (soft/hard) wavelet stages are not FIRs; the header then refuses to be generated
(one line, key named): use RealtimeWavelet in firmware for those.
"""

from __future__ import annotations

import math

import numpy as np

from gyrodrift.defaults import PREFILTER_LEVEL, PREFILTER_WAVELET, PREFILTER_WINDOW
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.imu.config import (
    Ar2KalmanStage,
    BiasRemoval,
    ChannelConfig,
    ConfigError,
    ProcessorConfig,
    WaveletStage,
)
from gyrodrift.imu.schema import (
    CHANNEL_NAMES,
    DEFAULT_ACCEL_SATURATION_M_S2,
    DEFAULT_GYRO_SATURATION_RAD_S,
    DEFAULT_GYRO_STUCK_SAMPLES,
    DEFAULT_SAMPLE_RATE_HZ,
    DEMO_AR2,
    FIELDS,
    MAX_STAGES,
    SCHEMA,
    VERSION,
    Field,
    default_period_us,
    default_time_tolerance_us,
    field_spec,
    to_float32,
)

__all__ = ["emit_cpp", "emit_schema_header", "float_literal"]

_FILTER_ENUM = {
    "pass_through": "pass_through",
    "bias_removal": "bias_removal",
    "ar2_kalman": "ar2_kalman",
    "wavelet": "wavelet",
}


def float_literal(x: float) -> str:
    """The float32 value of x as the shortest C++ float literal that reads back exactly.

    Examples
    --------
    >>> float_literal(0.1), float_literal(1e-10), float_literal(float("inf"))
    ('1.0e-01f', '1.0e-10f', 'std::numeric_limits<float>::infinity()')
    >>> float_literal(1e-50)  # would be 0.0f: refused
    Traceback (most recent call last):
    ...
    gyrodrift.errors.GyrodriftValueError: 1e-50 does not fit a float32 (a magnitude ...
    """
    if to_float32(float(x)) is None:
        raise GyrodriftValueError(f"{float(x)!r} does not fit a float32 (a magnitude "
                                  "1.1754944e-38..3.4028235e+38, or 0)")
    v = np.float32(x)
    if np.isinf(v):
        return ("-" if v < 0 else "") + "std::numeric_limits<float>::infinity()"
    if np.isnan(v):
        raise GyrodriftValueError("NaN has no place in a configuration")
    return np.format_float_scientific(v, unique=True, trim="0") + "f"


def _ident(name: str) -> str:
    if not name.replace("_", "a").isalnum() or name[0].isdigit():
        raise ConfigError("namespace", f"not a C++ identifier: {name!r}")
    return name


def _wavelet_tables(cfg: ProcessorConfig) -> tuple[int, int, dict[tuple[str, int, int], str],
                                                  list[str]]:
    """The forced wavelet stages: (window, number of channels that need the stage, tap table
    name per (wavelet, window, level), each channel's table or "nullptr")."""
    windows = set()
    wavelet_channels = 0
    tables: dict[tuple[str, int, int], str] = {}
    chan_taps: list[str] = []
    for c, cc in enumerate(cfg.channels):
        tname = "nullptr"
        for i, st in enumerate(cc.stages):
            if isinstance(st, WaveletStage):
                if st.threshold != "forced":
                    raise ConfigError(
                        f"channels.{cc.name}.stages[{i}].threshold",
                        "emit-cpp generates FIR taps for forced wavelet stages only "
                        "(soft/hard thresholding needs RealtimeWavelet in firmware)",
                    )
                windows.add(st.window)
                wavelet_channels = c + 1
                key = (st.wavelet, st.window, st.level)
                tables.setdefault(key, f"kTaps_{st.wavelet}_n{st.window}_j{st.level}")
                tname = tables[key]
        chan_taps.append(tname)
    if len(windows) > 1:
        raise ConfigError("channels", f"all wavelet stages must share one window, got {windows}")
    return (windows.pop() if windows else 0), wavelet_channels, tables, chan_taps


def _tap_table_lines(tables: dict[tuple[str, int, int], str]) -> list[str]:
    """Each forced stage's FIR taps as a constexpr float table, oldest first."""
    from gyrodrift.filters.fir import forced_fir_taps  # the C++ core's taps (double), newest first

    out = []
    for (wname, n, level), tname in tables.items():
        taps = forced_fir_taps(wname, n, level)[::-1]  # FirPrefilter takes them oldest first
        out.append(f"// forced {wname}, window {n}, level {level}: y = sum_i taps[i] "
                   "x[n-(N-1)+i] (oldest first)")
        out.append(f"inline constexpr float {tname}[{n}] = {{")
        lits = [float_literal(t) for t in taps]
        for k in range(0, n, 6):
            out.append("    " + ", ".join(lits[k:k + 6]) + ",")
        out.append("};")
        out.append("")
    return out


def _channel_initializer(cc: ChannelConfig) -> str:
    """One ImuChannelConfig<float> aggregate initializer (fields in declaration order)."""
    types = [st.type for st in cc.stages]
    f1 = _FILTER_ENUM[types[0]]
    f2 = _FILTER_ENUM[types[1]] if len(types) > 1 else "pass_through"
    bias = 0.0
    a1 = a2 = sigma2 = mean = q = r = math.nan
    p0 = float(field_spec("ar2_kalman", "p0").default)
    steady = False
    for st in cc.stages:
        if isinstance(st, BiasRemoval):
            bias = st.bias
        elif isinstance(st, Ar2KalmanStage):
            a1, a2, sigma2, mean = st.a1, st.a2, st.sigma2_value, st.mean
            q, r, p0, steady = st.q, st.r, st.p0, st.steady_state

    def lit(x: float) -> str:
        return "kNaN" if math.isnan(x) else float_literal(x)

    return (
        f"      {{gyrodrift::ChannelFilter::{f1}, gyrodrift::ChannelFilter::{f2}, "
        f"{'true' if steady else 'false'}, {lit(bias)},\n"
        f"       gyrodrift::Ar2Model<float>{{{lit(a1)}, {lit(a2)}, {lit(sigma2)}, "
        f"{lit(mean)}}},\n"
        f"       {lit(q)}, {lit(r)}, {lit(p0)}, {lit(cc.saturation)}, "
        f"{int(cc.stuck_samples)}U}},"
        f"  // {cc.name}"
    )


def _monitor_octaves(cfg: ProcessorConfig) -> int:
    """The processor's monitor capacity: the configured octaves when the monitor is on, else 0
    (no monitor in the image)."""
    return int(cfg.monitor.octaves) if cfg.monitor.enabled else 0


def _monitor_lines(cfg: ProcessorConfig) -> list[str]:
    """start_monitor(p): the gyro monitor of the [monitor] table started on the processor
    (durations in samples, each monitored channel's reference Allan curve from its model as a
    flash table), or nothing when the monitor is off."""
    if not cfg.monitor.enabled:
        return [
            "// The gyro monitor is off ([monitor] enabled = false): the image has none.",
            "inline constexpr bool kMonitorEnabled = false;",
            "inline bool start_monitor(Processor&) noexcept { return true; }",
        ]
    from gyrodrift.imu.monitor import reference_from_config

    m = cfg.monitor
    rate = cfg.timing.sample_rate_hz
    n = m.samples(rate)
    monitored = cfg.monitored_channels()
    table = []
    for ch in CHANNEL_NAMES[:3]:
        if ch in monitored:
            ref = reference_from_config(cfg, ch)
            if ref.edf_per_term is None:  # the target derives none (no hardware double)
                raise ConfigError(f"channels.{ch}", "the monitor's reference has no edf per "
                                                    "term for the firmware image")
            edf = ref.edf_per_term
            try:
                lits = [float_literal(float(v)) for v in ref.avar]
                edf_lits = [float_literal(float(v)) for v in edf]
            except GyrodriftValueError as exc:
                raise ConfigError(f"channels.{ch}", f"the monitor's reference Allan variance "
                                                    f"of this channel's model: {exc}") from None
            table.append(f"    Processor::MonitorReference{{{{{', '.join(lits)}}}, "
                         f"kMonitorOctaves,\n"
                         f"                                {{{', '.join(edf_lits)}}}}},  // {ch}")
        else:
            table.append(f"    Processor::MonitorReference{{}},  // {ch}: not watched")
    flags = ", ".join("true" if ch in monitored else "false" for ch in CHANNEL_NAMES[:3])
    return [
        "// The gyro monitor ([monitor] table): durations in samples at the sample rate, and each",
        "// monitored gyro's reference: its ar2_kalman model's Allan variance per octave and the",
        "// edf per squared difference of the alarms' block test under the model, a constant",
        "// table in flash that the monitors read in place (they keep no copy in RAM).",
        "inline constexpr bool kMonitorEnabled = true;",
        f"inline constexpr bool kMonitorChannels[3] = {{{flags}}};",
        "// The re-identification's method ([monitor] identifier; with lag a target runs the fits",
        "// in thread mode: defer_monitor_fits(true), then run_pending_monitor_fit() whenever",
        "// monitor_fit_pending()).",
        "inline constexpr gyrodrift::DriftIdentifierKind kMonitorIdentifier = "
        f"gyrodrift::DriftIdentifierKind::{m.identifier};",
        "inline constexpr std::array<Processor::MonitorReference, 3> kMonitorReferences = {",
        *table,
        "};",
        "inline gyrodrift::GyroMonitorSettings<float> monitor_settings() noexcept {",
        "  gyrodrift::GyroMonitorSettings<float> s;",
        f"  s.sample_rate_hz = {float_literal(rate)};",
        "  s.octaves = kMonitorOctaves;",
        f"  s.alarms.arw_factor = {float_literal(m.arw_factor)};",
        f"  s.alarms.bias_instability_factor = {float_literal(m.bias_instability_factor)};",
        f"  s.alarms.rate_random_walk_factor = {float_literal(m.rate_random_walk_factor)};",
        f"  s.alarms.false_alarm_probability = {float_literal(m.false_alarm_probability)};",
        f"  s.alarms.stuck_samples = {n['stuck_samples']}U;",
        f"  s.alarms.saturated_samples = {n['saturated_samples']}U;",
        f"  s.reidentify = {'true' if m.reidentify else 'false'};",
        f"  s.drift.block_samples = {n['block_samples']}U;",
        f"  s.drift.retune_blocks = {n['retune_blocks']}U;",
        f"  s.drift.min_samples = {n['min_samples']}ULL;",
        f"  s.drift.memory_blocks = {float_literal(n['memory_blocks'])};",
        f"  s.drift.max_step = {float_literal(m.max_step)};",
        f"  s.drift.max_rel_stderr = {float_literal(m.identified_max_rel_stderr)};",
        f"  s.drift.adapt_ar = {'true' if m.reidentify_ar else 'false'};",
        f"  s.identifier = gyrodrift::DriftIdentifierKind::{m.identifier};",
        f"  s.lag.fit_delay_samples = {n['fit_delay_samples']}U;",
        f"  s.lag.restart_after_fit = {'true' if m.restart_after_fit else 'false'};",
        "  return s;",
        "}",
        "// Starts the monitor on the processor (after construction, before the first step).",
        "inline bool start_monitor(Processor& p) noexcept {",
        "  const std::array<bool, 3> on{kMonitorChannels[0], kMonitorChannels[1], "
        "kMonitorChannels[2]};",
        "  return p.configure_monitor(monitor_settings(), kMonitorReferences, on) == "
        "gyrodrift::GyroMonitorStatus::ok;",
        "}",
    ]


def _processor_type_lines(window: int, wavelet_channels: int, chan_taps: list[str],
                          monitor_octaves: int = 0, monitor_slots: int = 0,
                          monitor_reidentify: bool = True,
                          monitor_identifier: str = "recursive") -> list[str]:
    """The Processor type and make_wavelet: the FIR stage on channels 0..k-1, or none; the
    gyro monitor's capacity (octaves 0: none), its monitors (one per monitored gyro), whether
    they hold the re-identification (its state only when it is configured on) and which one
    (the recursive estimator shared in turns, or the lag-statistics identifier)."""
    octaves = [f"inline constexpr std::size_t kMonitorOctaves = {monitor_octaves};"]
    if monitor_octaves:
        identifier = ("gyrodrift::LagDriftIdentifier<float, kMonitorSlots>"
                      if monitor_identifier == "lag" else
                      "gyrodrift::SharedDriftIdentifier<float, kMonitorSlots>")
        octaves.append(f"inline constexpr std::size_t kMonitorSlots = {monitor_slots};")
        octaves.append("inline constexpr bool kMonitorReidentify = "
                       f"{'true' if monitor_reidentify else 'false'};")
        octaves.append(f"using MonitorIdentifier = {identifier};")
    if not wavelet_channels:
        return [
            *octaves,
            "inline constexpr std::size_t kWaveletChannels = 1;",
            "using Wavelet = gyrodrift::NoWavelet<float>;",
            "using Processor = gyrodrift::ImuProcessor<float, Wavelet, gyrodrift::kImuChannels, "
            "kMonitorOctaves, kMonitorSlots, kMonitorReidentify, MonitorIdentifier>;"
            if monitor_octaves else "using Processor = gyrodrift::ImuProcessor<float>;",
            "inline Wavelet make_wavelet(std::size_t) noexcept { return Wavelet{}; }",
        ]
    processor = ("using Processor = gyrodrift::ImuProcessor<float, Wavelet, kWaveletChannels, "
                 "kMonitorOctaves, kMonitorSlots, kMonitorReidentify, MonitorIdentifier>;"
                 if monitor_octaves else
                 "using Processor = gyrodrift::ImuProcessor<float, Wavelet, kWaveletChannels>;")
    return [
        *octaves,
        f"inline constexpr std::size_t kWaveletWindow = {window};",
        f"// the wavelet stage exists on channels 0..{wavelet_channels - 1} only",
        f"inline constexpr std::size_t kWaveletChannels = {wavelet_channels};",
        "using Wavelet = gyrodrift::FirPrefilter<float, kWaveletWindow>;",
        processor,
        "",
        "// Each wavelet channel's taps in flash (nullptr: the channel has no wavelet stage).",
        "inline constexpr const float* kWaveletTaps[kWaveletChannels] = {"
        + ", ".join(chan_taps[c] for c in range(wavelet_channels)) + "};",
        "// Builds channel c's stage in place: Processor p(kImuConfig, make_wavelet);",
        "inline Wavelet make_wavelet(std::size_t c) noexcept {",
        "  return Wavelet(kWaveletTaps[c]);",
        "}",
    ]


def emit_cpp(cfg: ProcessorConfig, namespace: str = "gyrodrift_config", source: str = "") -> str:
    """The C++17 header text for `cfg` (see the module docstring).

    Examples
    --------
    >>> from gyrodrift.imu.config import default_config
    >>> header = emit_cpp(default_config())
    >>> header.splitlines()[0]
    '// Generated by `gyrodrift config emit-cpp`: do not edit.'
    >>> "#pragma once" in header and "namespace gyrodrift_config" in header
    True
    """
    ns = _ident(namespace)
    window, wavelet_channels, tables, chan_taps = _wavelet_tables(cfg)
    out = [
        "// Generated by `gyrodrift config emit-cpp`" + (f" from {source}" if source else "")
        + ": do not edit.",
        "// Processor configuration (schema gyrodrift.processor, version 1) as constexpr float",
        "// values; forced wavelet stages as flash FIR tables"
        " (gyrodrift/filters/fir_prefilter.hpp).",
        "#pragma once",
        "#include <array>",
        "#include <cstddef>",
        "#include <cstdint>",
        "#include <limits>",
        "",
        "#include <gyrodrift/filters/fir_prefilter.hpp>",
        "#include <gyrodrift/imu/imu_processor.hpp>",
        "",
        f"namespace {ns} {{",
        "",
        f"inline constexpr float kSampleRateHz = {float_literal(cfg.timing.sample_rate_hz)};",
        f"inline constexpr float kLoopRateHz = {float_literal(cfg.timing.loop_hz)};",
        "",
        *_tap_table_lines(tables),
        "// kNaN: parameters of stages a channel does not have",
        "inline constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();",
        "// ImuChannelConfig fields: filter, filter2, steady_state, bias,",
        "// model {a1, a2, sigma2, mean}, q, r, p0, saturation, stuck_samples",
        "inline constexpr gyrodrift::ImuConfig<float> kImuConfig{",
        "    {{",
        *[_channel_initializer(cc) for cc in cfg.channels],
        "    }},",
        f"    {cfg.timing.period_us}U,  // period_us",
        f"    {cfg.timing.tolerance_us}U,  // time_tolerance_us",
        "};",
        "",
        *_processor_type_lines(window, wavelet_channels, chan_taps, _monitor_octaves(cfg),
                               len(cfg.monitored_channels()), bool(cfg.monitor.reidentify),
                               cfg.monitor.identifier),
        "",
        *_monitor_lines(cfg),
        "",
        f"}}  // namespace {ns}",
        "",
    ]
    return "\n".join(out)


def _cpp_name(f: Field) -> str:
    words = f"{f.section}_{f.name}".split("_")
    return "k" + "".join(w[:1].upper() + w[1:] for w in words)


def _cpp_double(x: float | None, missing: float) -> str:
    v = missing if x is None else float(x)
    if math.isinf(v):
        return "kInf" if v > 0 else "-kInf"
    return repr(v)


def _cpp_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


#: The FieldSpec type of the schema header (C++ lines).
_FIELD_SPEC_STRUCT = (
    "enum class FieldKind : std::uint8_t { number, integer, boolean, string };",
    "",
    "// One field of the file: its table (\"timing\", \"channel\" or a stage type), its name",
    "// (the key, plus _rad_s / _m_s2 where channel_unit), its kind, whether it is required,",
    "// its default (number or text) when it has one (absent and no default: derived, see",
    "// help), its bounds (open or closed; +-kInf: none), finite-only, power of two, the",
    "// accepted strings ('|'-separated), the bounds in words (both readers' error text), its",
    "// unit and its help text.",
    "struct FieldSpec {",
    "  const char* section;",
    "  const char* name;",
    "  bool channel_unit;",
    "  FieldKind kind;",
    "  bool required;",
    "  bool has_default;",
    "  double default_value;",
    "  const char* default_text;",
    "  double lo;",
    "  bool lo_open;",
    "  double hi;",
    "  bool hi_open;",
    "  bool finite;",
    "  bool power_of_two;",
    "  bool float32;  // the processors hold it as a float32: it must fit one",
    "  const char* choices;",
    "  const char* bounds_text;",
    "  const char* unit;",
    "  const char* help;",
    "};",
    "",
)


def emit_schema_header() -> str:
    """The C++ header ``include/gyrodrift/imu/config_schema.hpp``: the configuration's fields
    (gyrodrift.imu.schema) with their defaults and bounds, the defaults derived from them, and
    the shipped default configuration's canonical text. Written by ``scripts/gen-config-schema``;
    a test regenerates it and fails on any difference.

    Examples
    --------
    >>> text = emit_schema_header()
    >>> text.splitlines()[0].startswith("// Generated from python/gyrodrift/imu/schema.py")
    True
    >>> "inline constexpr FieldSpec kChannelStuckSamples{" in text
    True
    """
    from gyrodrift.imu.config import default_config, dumps_config

    fields = []
    for f in FIELDS:
        kind = {"float": "number", "int": "integer", "bool": "boolean", "str": "string"}[f.kind]
        has_default = not f.required and f.default is not None
        dflt = f.default if has_default and f.kind in ("float", "int", "bool") else 0.0
        text_default = f.default if has_default and f.kind == "str" else ""
        fields.append(
            f"inline constexpr FieldSpec {_cpp_name(f)}{{\n"
            f"    {_cpp_string(f.section)}, {_cpp_string(f.name)}, "
            f"{'true' if f.unit == 'channel' else 'false'}, FieldKind::{kind},\n"
            f"    {'true' if f.required else 'false'}, {'true' if has_default else 'false'}, "
            f"{_cpp_double(float(dflt), 0.0)}, {_cpp_string(text_default)},\n"
            f"    {_cpp_double(f.lo, -math.inf)}, {'true' if f.lo_open else 'false'}, "
            f"{_cpp_double(f.hi, math.inf)}, {'true' if f.hi_open else 'false'}, "
            f"{'true' if f.finite else 'false'}, {'true' if f.power_of_two else 'false'}, "
            f"{'true' if f.float32 else 'false'},\n"
            f"    {_cpp_string('|'.join(f.choices))}, {_cpp_string(f.bounds_text())}, "
            f"{_cpp_string(f.unit)},\n    {_cpp_string(f.help)}}};")
    rate = DEFAULT_SAMPLE_RATE_HZ
    demo = ", ".join(f"{k} = {v!r}" for k, v in DEMO_AR2.items())
    toml = dumps_config(default_config())
    assert ")gyrodrift\"" not in toml
    out = [
        "// Generated from python/gyrodrift/imu/schema.py by scripts/gen-config-schema: "
        "do not edit.",
        "// The processor configuration's fields (keys, units, defaults, bounds) are written once,",
        "// in that Python table; the C++ defaults (imu_processor.hpp), the loop's configuration",
        "// reader and its built-in default configuration follow from this header.",
        "#pragma once",
        "#include <cstddef>",
        "#include <cstdint>",
        "#include <limits>",
        "",
        "namespace gyrodrift::config_schema {",
        "",
        *_FIELD_SPEC_STRUCT,
        "inline constexpr double kInf = std::numeric_limits<double>::infinity();",
        "",
        *fields,
        "",
        "inline constexpr const FieldSpec* kFields[] = {",
        *[f"    &{_cpp_name(f)}," for f in FIELDS],
        "};",
        f"inline constexpr std::size_t kFieldCount = {len(FIELDS)};",
        "",
        f"inline constexpr const char* kSchema = {_cpp_string(SCHEMA)};",
        f"inline constexpr int kVersion = {VERSION};",
        "inline constexpr const char* kChannelNames[] = {"
        + ", ".join(_cpp_string(c) for c in CHANNEL_NAMES) + "};",
        f"inline constexpr int kMaxStages = {MAX_STAGES};",
        "",
        "// The shipped default configuration's sample rate and the timing derived from it.",
        f"inline constexpr double kDefaultSampleRateHz = {rate!r};",
        f"inline constexpr std::uint32_t kDefaultPeriodUs = {default_period_us(rate)}U;",
        "inline constexpr std::uint32_t kDefaultTimeToleranceUs = "
        f"{default_time_tolerance_us(rate)}U;",
        "",
        "// The shipped default configuration's bad-value detection on the gyros (rad/s) and",
        "// the accelerometers (m/s^2).",
        f"inline constexpr double kDefaultGyroSaturationRadS = {DEFAULT_GYRO_SATURATION_RAD_S!r};",
        f"inline constexpr double kDefaultAccelSaturationMS2 = {DEFAULT_ACCEL_SATURATION_M_S2!r};",
        f"inline constexpr std::uint32_t kDefaultGyroStuckSamples = {DEFAULT_GYRO_STUCK_SAMPLES}U;",
        "",
        "// The real-time prefilter of the 2014 paper: the wavelet stage's defaults.",
        f"inline constexpr const char* kPrefilterWavelet = {_cpp_string(PREFILTER_WAVELET)};",
        f"inline constexpr std::size_t kPrefilterWindow = {PREFILTER_WINDOW};",
        f"inline constexpr int kPrefilterLevel = {PREFILTER_LEVEL};",
        "",
        "// The demonstration AR(2)-Kalman model of the default configuration (sigma2 = q).",
        "struct DemoAr2 {",
        f"  static constexpr double {demo}, sigma2 = {DEMO_AR2['q']!r};",
        "};",
        "",
        "// The shipped default configuration (`gyrodrift config write-default`), canonical text.",
        'inline constexpr const char kDefaultConfigToml[] = R"gyrodrift(' + toml
        + ')gyrodrift";',
        "",
        "}  // namespace gyrodrift::config_schema",
        "",
    ]
    return "\n".join(out)
