"""The processor configuration's fields, written once.

Every field of the configuration file (its key, type, unit, default, bounds and help text) is
declared here and nowhere else. The Python reader, validator and writer
(:mod:`gyrodrift.imu.config`), the documentation of the format, and the C++ side follow from
this table: ``include/gyrodrift/imu/config_schema.hpp`` is generated from it
(:func:`gyrodrift.imu.firmware_header.emit_schema_header`, ``scripts/gen-config-schema``) and
holds the C++ defaults, the bounds the loop's reader checks and the shipped default
configuration; a test regenerates it and fails on any difference.

"No value" has one spelling: a field whose default is ``None`` may be left out, and its value
is then derived as its help text says (the timestamp tolerance is half a sample period, the
loop rate is the sample rate, sigma2 is q). Fields whose default is :data:`REQUIRED` must be
given.

Units: ``"channel"`` is the channel's own unit (rad/s for the gyros gx gy gz, m/s^2 for the
accelerometers ax ay az) and the key carries its suffix (``saturation_rad_s``,
``saturation_m_s2``); ``"channel^2"`` is its square (a variance).

Examples
--------
>>> f = field_spec("timing", "sample_rate_hz")
>>> f.unit, f.required, f.lo, f.hi
('Hz', True, 1.0, 100000.0)
>>> field_spec("channel", "saturation").key("gx"), field_spec("channel", "saturation").default
('saturation_rad_s', inf)
>>> [f.name for f in FIELDS if f.section == "ar2_kalman"]
['a1', 'a2', 'mean', 'sigma2', 'q', 'r', 'p0', 'steady_state']
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Any

from gyrodrift.defaults import (
    DEFAULT_SAMPLE_RATE_HZ,
    PREFILTER_LEVEL,
    PREFILTER_THRESHOLD,
    PREFILTER_WAVELET,
    PREFILTER_WINDOW,
)

__all__ = [
    "CHANNEL_NAMES",
    "DEFAULT_ACCEL_SATURATION_M_S2",
    "DEFAULT_GYRO_SATURATION_RAD_S",
    "DEFAULT_GYRO_STUCK_SAMPLES",
    "DEFAULT_SAMPLE_RATE_HZ",
    "DEMO_AR2",
    "FIELDS",
    "FLOAT32_INPUT_LIMIT",
    "FLOAT32_MAX",
    "FLOAT32_MIN_NORMAL",
    "IDENTIFIERS",
    "MAX_STAGES",
    "MAX_VARIANCE",
    "MONITOR_MAX_OCTAVES",
    "PAPER_WAVELET",
    "REQUIRED",
    "SCHEMA",
    "SECTIONS",
    "STAGE_TYPES",
    "THRESHOLDS",
    "U32_MAX",
    "VERSION",
    "WAVELETS",
    "Field",
    "channel_unit",
    "channel_unit_suffix",
    "default_period_us",
    "default_time_tolerance_us",
    "field_spec",
    "max_wavelet_level",
    "to_float32",
]

SCHEMA = "gyrodrift.processor"
VERSION = 1
#: The six channels in order: gyro x y z (rad/s), accelerometer x y z (m/s^2).
CHANNEL_NAMES = ("gx", "gy", "gz", "ax", "ay", "az")
#: Stage types of a channel's chain (one or two stages; pass_through only alone).
STAGE_TYPES = ("pass_through", "bias_removal", "wavelet", "ar2_kalman")
MAX_STAGES = 2
#: Wavelets of the real-time stage -> filter length.
WAVELETS = {"db4": 8, "db8": 16}
THRESHOLDS = ("forced", "soft", "hard")
#: Where the fields live: the timing table, each channel's table, each stage type's table, and
#: the gyro monitor's table.
SECTIONS = ("timing", "channel", "bias_removal", "wavelet", "ar2_kalman", "monitor")
#: The most octaves of the monitor's streaming Allan curve (the loop program's capacity).
MONITOR_MAX_OCTAVES = 24
#: The monitor's re-identification methods (``[monitor] identifier``): the recursive estimator
#: and the whole-record lag statistics with their fit.
IDENTIFIERS = ("recursive", "lag")


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


#: The default of a field that must be given.
REQUIRED: Any = _Required()

U32_MAX = 2**32 - 1
#: The largest finite and the smallest normal float32 magnitudes.
FLOAT32_MAX = 3.4028234663852886e38
FLOAT32_MIN_NORMAL = 1.1754943508222875e-38
#: The float32 filters' input limit (include/gyrodrift/filters/input_range.hpp: max / 2^24):
#: the bound of a model mean.
FLOAT32_INPUT_LIMIT = FLOAT32_MAX / 2.0**24
#: The largest variance (q, r, sigma2, p0) a float32 filter's covariance recursion holds
#: without overflow for every stationary model (a standard deviation of 1e15 channel units).
MAX_VARIANCE = 1e30


def to_float32(x: float) -> float | None:
    """`x` rounded to the nearest float32 (as the C++ cast does), or None when a nonzero
    value does not fit one: it overflows, or it rounds to zero or to a subnormal number (the
    processors built on float32 flush those, and a variance of 0 is not the one written).

    Examples
    --------
    >>> f32_of_tenth = struct.unpack("<f", struct.pack("<f", 0.1))[0]
    >>> to_float32(0.1) == f32_of_tenth, to_float32(0.0), to_float32(float("inf"))
    (True, 0.0, inf)
    >>> to_float32(1e-50), to_float32(1e39), to_float32(0.999999999)
    (None, None, 1.0)
    """
    if x == 0.0 or math.isinf(x) or math.isnan(x):
        return float(x)
    try:
        y = float(struct.unpack("f", struct.pack("f", x))[0])
    except OverflowError:
        return None
    if math.isinf(y) or abs(y) < FLOAT32_MIN_NORMAL:
        return None
    return y


@dataclass(frozen=True)
class Field:
    """One configuration field.

    ``lo``/``hi`` bound the value (None: unbounded); ``lo_open``/``hi_open`` make a bound
    strict. ``choices`` lists the accepted strings. ``finite`` refuses NaN and +-inf (a float
    field that is not finite-only says so by its bounds, e.g. saturation accepts inf).
    ``float32``: the processors hold the value as a float32 (the firmware's scalar), so the
    value must fit one (:func:`to_float32`) and its bounds hold for the rounded value
    (against the bounds rounded to float32).

    Examples
    --------
    >>> f = field_spec("ar2_kalman", "r")
    >>> f.kind, f.unit, f.lo, f.lo_open, f.bounds_text()
    ('float', 'channel^2', 0.0, True, '> 0 and <= 1e+30')
    """

    section: str
    name: str
    kind: str  # "float", "int", "bool", "str"
    unit: str  # "Hz", "us", "samples", "channel", "channel^2", "" (dimensionless)
    default: Any
    help: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    finite: bool = True
    choices: tuple[str, ...] = ()
    power_of_two: bool = False
    float32: bool = False

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def key(self, channel: str) -> str:
        """The key in the file: the name with the channel unit's suffix where it has one."""
        if self.unit == "channel":
            return self.name + channel_unit_suffix(channel)
        return self.name

    def bounds_text(self) -> str:
        """The accepted values in words (the same text in every error of both readers).

        Examples
        --------
        >>> field_spec("timing", "loop_rate_hz").bounds_text()
        '1..2000 Hz'
        >>> field_spec("channel", "saturation").bounds_text()
        '> 0 (or inf: off)'
        """
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.power_of_two:
            return f"a power of two in {_num(self.lo)}..{_num(self.hi)}"
        unit = f" {self.unit}" if self.unit in ("Hz", "us") else ""
        if self.lo is not None and self.hi is not None and not (self.lo_open or self.hi_open):
            return f"{_num(self.lo)}..{_num(self.hi)}{unit}"
        parts = []
        if self.lo is not None:
            parts.append(f"{'>' if self.lo_open else '>='} {_num(self.lo)}")
        if self.hi is not None:
            parts.append(f"{'<' if self.hi_open else '<='} {_num(self.hi)}")
        text = " and ".join(parts) if parts else "finite"
        if not self.finite:
            text += " (or inf: off)"
        return text + unit

    def accepts(self, value: Any) -> bool:
        """Whether a value of the right type lies within the bounds (relations between fields,
        such as AR(2) stationarity or the wavelet level for its window, are checked apart).

        Examples
        --------
        >>> s = field_spec("channel", "stuck_samples")
        >>> s.accepts(0), s.accepts(-1), s.accepts(2**32)
        (True, False, False)
        """
        if self.choices:
            return value in self.choices
        if self.kind == "bool":
            return isinstance(value, bool)
        if self.kind == "str":
            return isinstance(value, str)
        v = float(value)
        if math.isnan(v) or (self.finite and math.isinf(v)):
            return False
        lo, hi = self.lo, self.hi
        if self.float32:  # the bounds hold for the values the processor holds
            rounded = to_float32(v)
            if rounded is None:
                return False
            v = rounded
            lo = None if lo is None else to_float32(lo)
            hi = None if hi is None else to_float32(hi)
        if lo is not None and (v <= lo if self.lo_open else v < lo):
            return False
        if hi is not None and (v >= hi if self.hi_open else v > hi):
            return False
        if self.power_of_two:
            n = int(value)
            return n > 0 and n & (n - 1) == 0
        return True


def _num(x: float | None) -> str:
    if x is None:
        return ""
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e16 else repr(float(x))


def channel_unit(channel: str) -> str:
    """rad/s for a gyro channel, m/s^2 for an accelerometer channel.

    Examples
    --------
    >>> channel_unit("gz"), channel_unit("ax")
    ('rad/s', 'm/s^2')
    """
    return "rad/s" if channel.startswith("g") else "m/s^2"


def channel_unit_suffix(channel: str) -> str:
    """The key suffix of a channel's unit.

    Examples
    --------
    >>> channel_unit_suffix("gx"), channel_unit_suffix("az")
    ('_rad_s', '_m_s2')
    """
    return "_rad_s" if channel.startswith("g") else "_m_s2"


#: Every field, by section, in the order the canonical file writes them.
FIELDS: tuple[Field, ...] = (
    Field("timing", "sample_rate_hz", "float", "Hz", REQUIRED,
          "IMU sample rate: the nominal period of the timestamps is 1e6 / rate us",
          lo=1.0, hi=1e5),
    Field("timing", "time_tolerance_us", "int", "us", None,
          "timestamp check: |dt - k period| above it is a time jump (absent: half a sample "
          "period; 0: check off)", lo=0, hi=U32_MAX),
    Field("timing", "loop_rate_hz", "float", "Hz", None,
          "rate of the loop program's cycle (absent: the sample rate)", lo=1.0, hi=2000.0),
    Field("channel", "saturation", "float", "channel", math.inf,
          "|x| >= saturation marks a value saturated (inf: off)", lo=0.0, lo_open=True,
          finite=False, float32=True),
    Field("channel", "stuck_samples", "int", "samples", 0,
          "the N-th identical value in a row marks the channel stuck (0: off)",
          lo=0, hi=U32_MAX),
    Field("bias_removal", "bias", "float", "channel", REQUIRED,
          "subtracted from every sample", float32=True),
    Field("wavelet", "wavelet", "str", "", REQUIRED,
          "wavelet of the real-time sliding-window prefilter", choices=tuple(WAVELETS)),
    Field("wavelet", "window", "int", "samples", REQUIRED,
          "sliding window length N", lo=16, hi=4096, power_of_two=True),
    Field("wavelet", "level", "int", "", REQUIRED,
          "decomposition level J (at most the deepest level of the extended window 2N)",
          lo=1, hi=8),
    Field("wavelet", "threshold", "str", "", PREFILTER_THRESHOLD,
          "detail handling: forced (all details zeroed), soft or hard", choices=THRESHOLDS),
    Field("ar2_kalman", "a1", "float", "", REQUIRED,
          "AR(2) coefficient of x[k-1] (the model must be stationary)", float32=True),
    Field("ar2_kalman", "a2", "float", "", REQUIRED, "AR(2) coefficient of x[k-2]",
          float32=True),
    Field("ar2_kalman", "mean", "float", "channel", REQUIRED,
          "model mean (constant drift; within the float32 filters' input range)",
          lo=-FLOAT32_INPUT_LIMIT, hi=FLOAT32_INPUT_LIMIT, float32=True),
    Field("ar2_kalman", "sigma2", "float", "channel^2", None,
          "AR(2) driving-noise variance (absent: q)", lo=0.0, hi=MAX_VARIANCE, float32=True),
    Field("ar2_kalman", "q", "float", "channel^2", REQUIRED,
          "Kalman process-noise variance", lo=0.0, hi=MAX_VARIANCE, float32=True),
    Field("ar2_kalman", "r", "float", "channel^2", REQUIRED,
          "Kalman measurement-noise variance", lo=0.0, lo_open=True, hi=MAX_VARIANCE, float32=True),
    Field("ar2_kalman", "p0", "float", "channel^2", 1.0,
          "initial state covariance P_0 = p0 I", lo=0.0, hi=MAX_VARIANCE, float32=True),
    Field("ar2_kalman", "steady_state", "bool", "", False,
          "constant (DARE steady-state) Kalman gain instead of the time-varying one"),
    Field("monitor", "enabled", "bool", "", False,
          "run the gyro monitor (streaming Allan statistics, health alarms, online "
          "re-identification) on every gyro channel whose first stage is ar2_kalman (its model "
          "is the reference and the fallback)"),
    Field("monitor", "octaves", "int", "", 16,
          "octaves of the streaming Allan curve: tau = 2^k / sample rate, k = 0 .. octaves - 1",
          lo=2, hi=MONITOR_MAX_OCTAVES),
    Field("monitor", "report_interval_s", "float", "s", 10.0,
          "interval of the monitor's reports (noise estimates, model in use, alarms)",
          lo=0.0, lo_open=True, hi=86400.0),
    Field("monitor", "coverage", "float", "", math.erf(1.0 / math.sqrt(2.0)),
          "coverage of the noise estimates' intervals (default: one sigma)",
          lo=0.0, hi=1.0, lo_open=True, hi_open=True, float32=True),
    Field("monitor", "arw_factor", "float", "", 2.0,
          "alarm when the angle random walk N is up by more than this factor",
          lo=1.0, lo_open=True, hi=1000.0, float32=True),
    Field("monitor", "bias_instability_factor", "float", "", 2.0,
          "alarm when the bias instability B is up by more than this factor",
          lo=1.0, lo_open=True, hi=1000.0, float32=True),
    Field("monitor", "rate_random_walk_factor", "float", "", 2.0,
          "alarm when the rate random walk K is up by more than this factor",
          lo=1.0, lo_open=True, hi=1000.0, float32=True),
    Field("monitor", "false_alarm_probability", "float", "", 1e-6,
          "false-alarm probability of one check of one octave (the chi-square bound)",
          lo=0.0, lo_open=True, hi=0.5, float32=True),
    Field("monitor", "stuck_alarm_s", "float", "s", 1.0,
          "a channel stuck this long without a break raises the stuck alarm (0: off)",
          lo=0.0, hi=86400.0),
    Field("monitor", "saturated_alarm_s", "float", "s", 1.0,
          "a channel saturated this long without a break raises the saturated alarm (0: off)",
          lo=0.0, hi=86400.0),
    Field("monitor", "reidentify", "bool", "", False,
          "re-identify the drift model online and retune the steady-state AR(2)-Kalman gain"),
    Field("monitor", "identifier", "str", "", "recursive",
          "the re-identification's method: recursive (a recursive estimator updated every "
          "block, with an optional forgetting memory, memory_s: follows a change, but does not "
          "settle on the offline maximum-likelihood fit on every record) or lag (whole-record "
          "lag statistics per gyro and their maximum-likelihood fit every retune_s: converges "
          "to the offline fit of the samples seen; restart_after_fit to follow a change)",
          choices=IDENTIFIERS),
    Field("monitor", "reidentify_ar", "bool", "", True,
          "both identifiers: re-identify the drift's AR coefficients a1, a2 too (false: hold "
          "them at the configured model and fit q and r only, which follows a change of the "
          "noise levels in a shorter memory)"),
    Field("monitor", "block_s", "float", "s", 1.0,
          "recursive identifier: samples per update of the re-identified parameters, in "
          "seconds (at least 8 samples); both identifiers: the unit retune_s is rounded to",
          lo=0.0, lo_open=True, hi=3600.0),
    Field("monitor", "retune_s", "float", "s", 60.0,
          "both identifiers: time between gain retunes of one gyro (rounded to whole blocks, "
          "at least one)", lo=0.0, lo_open=True, hi=86400.0),
    Field("monitor", "min_learn_s", "float", "s", 600.0,
          "both identifiers: no retune before this much accepted data (lag: data in the "
          "gyro's statistics)", lo=0.0, hi=1e7),
    Field("monitor", "memory_s", "float", "s", 0.0,
          "recursive identifier: forgetting horizon of the re-identification (0: none, for a "
          "stationary sensor: the estimate settles near the maximum-likelihood fit of "
          "everything seen; else at least one block, to track a change)", lo=0.0, hi=1e7),
    Field("monitor", "max_step", "float", "", 0.1,
          "both identifiers: largest change of one parameter per update (log q, log r; the AR "
          "part; lag: per retune)", lo=0.0, lo_open=True, hi=10.0, float32=True),
    Field("monitor", "identified_max_rel_stderr", "float", "", 0.5,
          "both identifiers: retune only when the relative standard errors of q and r are at "
          "most this (the drift/noise split is identified)", lo=0.0, lo_open=True, hi=10.0,
          float32=True),
    Field("monitor", "fit_delay_s", "float", "s", 15.0,
          "lag identifier: time from a fit's start to the retune that applies it; the target "
          "runs the fit in the background and must finish it within this time, while the "
          "gyro's statistics pause. With n watched gyros n x fit_delay_s must be at most "
          "retune_s (in samples). Default: a fit takes under a second of a 168 MHz "
          "Cortex-M4F beside a 400 Hz loop (3e7 to 1e8 instructions), so 15 s leaves a wide "
          "margin, and three gyros then take their turns within the default retune_s, with "
          "room for the rounding to whole samples", lo=0.0, lo_open=True, hi=86400.0),
    Field("monitor", "restart_after_fit", "bool", "", False,
          "lag identifier: each fit uses only the samples since that gyro's previous fit, to "
          "follow a change of the noise (false: everything since the start, converging on a "
          "stationary sensor)"),
)


def field_spec(section: str, name: str) -> Field:
    """The field `name` of `section`.

    Examples
    --------
    >>> field_spec("ar2_kalman", "p0").default
    1.0
    """
    for f in FIELDS:
        if f.section == section and f.name == name:
            return f
    raise KeyError(f"{section}.{name}")


#: The wavelet stage the 2014 paper puts before SINS alignment: db4, N = 256, level 5, all
#: details zeroed (forced). The defaults of a wavelet stage built in code.
PAPER_WAVELET: dict[str, Any] = {"wavelet": PREFILTER_WAVELET, "window": PREFILTER_WINDOW,
                                  "level": PREFILTER_LEVEL, "threshold": PREFILTER_THRESHOLD}
#: The shipped default's bad-value detection: gyro and accelerometer saturation (rad/s,
#: m/s^2) and the gyros' stuck count.
DEFAULT_GYRO_SATURATION_RAD_S = 8.0
DEFAULT_ACCEL_SATURATION_M_S2 = 160.0
DEFAULT_GYRO_STUCK_SAMPLES = 50

#: The demonstration AR(2)-Kalman model of the shipped default configuration (a1, a2: a
#: double root at 0.5, stationary; mean in rad/s; q and r in (rad/s)^2; sigma2 = q). Identify
#: the real gyro's with ``gyrodrift fit``.
DEMO_AR2 = {"a1": 1.0, "a2": -0.25, "mean": 0.0, "q": 1e-10, "r": 1e-8}


def default_period_us(sample_rate_hz: float) -> int:
    """The nominal sample period, rounded to whole microseconds as the C++ side does (lround).

    Examples
    --------
    >>> default_period_us(400.0), default_period_us(300.0)
    (2500, 3333)
    """
    return math.floor(1e6 / sample_rate_hz + 0.5)


def default_time_tolerance_us(sample_rate_hz: float) -> int:
    """The timestamp tolerance when the file gives none: half a sample period (C++ lround).

    Examples
    --------
    >>> default_time_tolerance_us(400.0)
    1250
    """
    return math.floor(1e6 / sample_rate_hz / 2.0 + 0.5)


def max_wavelet_level(window: int, wavelet: str) -> int:
    """pywt.dwt_max_level(2N, filter length): the deepest level of the extended window.

    Examples
    --------
    >>> max_wavelet_level(256, "db4"), max_wavelet_level(256, "db8")
    (6, 5)
    """
    flen = WAVELETS[wavelet] - 1
    level = 0
    hi = field_spec("wavelet", "level").hi
    assert hi is not None
    while level < hi and (flen << (level + 1)) <= 2 * window:
        level += 1
    return level
