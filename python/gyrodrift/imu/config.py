"""The processor configuration file (version 1): one file from identification to firmware.

One TOML file describes the six-channel processor (gx gy gz in rad/s, ax ay az in m/s^2):
per channel a chain of one or two stages from pass_through, bias_removal, wavelet and
ar2_kalman, plus saturation and stuck detection, and the timing (sample rate, timestamp
tolerance, loop rate). ``gyrodrift-loop --config``, ``gyrodrift replay --config``, the Python
``ImuProcessor``, the numpy reference processor and ``gyrodrift config emit-cpp`` read it;
``gyrodrift fit`` writes it. The format is documented in the configuration file format guide
of the documentation (docs/guides/configuration-file.md); ``gyrodrift config write-default``
writes a full example.

Every problem is a :class:`ConfigError` whose one-line message starts with the key
(``channels.gx.stages[1].a1: ...``).

Examples
--------
>>> cfg = default_config()
>>> parse_config(dumps_config(cfg)) == cfg
True
"""

from __future__ import annotations

import datetime
import math
import os
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Union

import numpy as np

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.imu.schema import (
    CHANNEL_NAMES,
    DEFAULT_ACCEL_SATURATION_M_S2,
    DEFAULT_GYRO_SATURATION_RAD_S,
    DEFAULT_GYRO_STUCK_SAMPLES,
    DEFAULT_SAMPLE_RATE_HZ,
    DEMO_AR2,
    FIELDS,
    MAX_STAGES,
    PAPER_WAVELET,
    REQUIRED,
    SCHEMA,
    STAGE_TYPES,
    U32_MAX,
    VERSION,
    Field,
    channel_unit,
    channel_unit_suffix,
    default_period_us,
    default_time_tolerance_us,
    field_spec,
    max_wavelet_level,
    to_float32,
)
from gyrodrift.io.atomic import atomic_write_text

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = [
    "CHANNEL_NAMES",
    "SCHEMA",
    "VERSION",
    "Ar2KalmanStage",
    "BiasRemoval",
    "ChannelConfig",
    "ConfigError",
    "MonitorConfig",
    "PassThrough",
    "ProcessorConfig",
    "Stage",
    "Timing",
    "WaveletStage",
    "config_from_dict",
    "default_config",
    "drift_filter_config",
    "dumps_config",
    "load_config",
    "max_wavelet_level",
    "parse_config",
    "pass_through_config",
    "write_config",
]

# Suffixes that name a unit the processor refuses (a key with one gets a wrong-units error).
_OTHER_SUFFIXES = (
    "_deg_s", "_deg_h", "_rad_h", "_mrad_s", "_g", "_mg", "_ug", "_ft_s2", "_rad_s", "_m_s2",
)


class ConfigError(GyrodriftValueError):
    """A configuration problem: a one-line message that starts with the offending key
    (`.key`). A GyrodriftValueError (so also a ValueError).

    Examples
    --------
    >>> try:
    ...     parse_config('schema = "gyrodrift.processor"\\nversion = 2\\n')
    ... except ConfigError as exc:
    ...     print(exc.key, "|", exc, "|", isinstance(exc, ValueError))
    version | version: this gyrodrift reads version 1, got 2 | True
    """

    def __init__(self, key: str, message: str) -> None:
        self.key = key
        text = f"{key}: {message}" if key else message
        # one line: control characters (of a quoted key, of a parser's message) escaped
        super().__init__("".join(c if c >= " " and c != "\x7f" else f"\\x{ord(c):02x}"
                                 for c in text))


@dataclass(frozen=True)
class PassThrough:
    """y = x (only as the single stage of a chain).

    Examples
    --------
    >>> ChannelConfig("ax", (PassThrough(),)).stages[0].type
    'pass_through'
    """

    type: str = field(default="pass_through", init=False)


@dataclass(frozen=True)
class BiasRemoval:
    """y = x - bias (bias in channel units).

    Examples
    --------
    >>> BiasRemoval(bias=0.002).bias  # subtracted from every sample, channel units
    0.002
    """

    bias: float = 0.0  # required in a file; 0.0 here: a stage built in code subtracts nothing
    type: str = field(default="bias_removal", init=False)


@dataclass(frozen=True)
class WaveletStage:
    """Real-time sliding-window wavelet prefilter (paper 004 sec. 2.2).

    Examples
    --------
    >>> WaveletStage(wavelet="db8", level=4)
    WaveletStage(wavelet='db8', window=256, level=4, threshold='forced', type='wavelet')
    """

    wavelet: str = PAPER_WAVELET["wavelet"]
    window: int = PAPER_WAVELET["window"]
    level: int = PAPER_WAVELET["level"]
    threshold: str = field_spec("wavelet", "threshold").default
    type: str = field(default="wavelet", init=False)


@dataclass(frozen=True)
class Ar2KalmanStage:
    """AR(2)-Kalman filter (paper 000 sec. 2.2); mean in channel units, sigma2/q/r in units^2.

    Examples
    --------
    >>> st = Ar2KalmanStage(a1=0.5, a2=0.1, mean=0.0, q=1e-10, r=1e-8, steady_state=True)
    >>> st.sigma2_value, st.type  # sigma2 defaults to q
    (1e-10, 'ar2_kalman')
    """

    a1: float
    a2: float
    mean: float
    q: float
    r: float
    sigma2: float | None = field_spec("ar2_kalman", "sigma2").default  # None: = q
    p0: float = field_spec("ar2_kalman", "p0").default
    steady_state: bool = field_spec("ar2_kalman", "steady_state").default
    type: str = field(default="ar2_kalman", init=False)

    @property
    def sigma2_value(self) -> float:
        return self.q if self.sigma2 is None else self.sigma2


Stage = Union[PassThrough, BiasRemoval, WaveletStage, Ar2KalmanStage]  # noqa: UP007 (3.10)


@dataclass(frozen=True)
class ChannelConfig:
    """One channel: its chain and its bad-value detection (saturation in channel units).

    Examples
    --------
    >>> ch = ChannelConfig("gz", (BiasRemoval(bias=1e-4),), saturation=8.0)
    >>> ch.units, ch.is_gyro
    ('rad/s', True)
    """

    name: str
    stages: tuple[Stage, ...]
    saturation: float = field_spec("channel", "saturation").default
    stuck_samples: int = field_spec("channel", "stuck_samples").default

    @property
    def units(self) -> str:
        return channel_unit(self.name)

    @property
    def is_gyro(self) -> bool:
        return self.name.startswith("g")


@dataclass(frozen=True)
class Timing:
    """Sample rate, timestamp tolerance (None: half a period; 0: off) and loop rate (None: =
    sample rate).

    Examples
    --------
    >>> t = Timing(sample_rate_hz=400.0)
    >>> t.period_us, t.tolerance_us, t.loop_hz  # tolerance: half a period; loop: the sample rate
    (2500, 1250, 400.0)
    """

    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ
    time_tolerance_us: int | None = field_spec("timing", "time_tolerance_us").default
    loop_rate_hz: float | None = field_spec("timing", "loop_rate_hz").default

    @property
    def period_us(self) -> int:
        return default_period_us(self.sample_rate_hz)

    @property
    def tolerance_us(self) -> int:
        if self.time_tolerance_us is not None:
            return self.time_tolerance_us
        return default_time_tolerance_us(self.sample_rate_hz)

    @property
    def loop_hz(self) -> float:
        return self.sample_rate_hz if self.loop_rate_hz is None else self.loop_rate_hz


def _monitor_default(name: str) -> Any:
    return field_spec("monitor", name).default


@dataclass(frozen=True)
class MonitorConfig:
    """The gyro monitor (the ``[monitor]`` table; off by default): streaming Allan statistics,
    health alarms and the online re-identification on every gyro channel whose first stage is
    ar2_kalman. Durations in seconds, converted to samples at the sample rate
    (:meth:`samples`).

    Examples
    --------
    >>> m = MonitorConfig(enabled=True, reidentify=True)
    >>> m.octaves, m.report_interval_s, m.samples(400.0)["block_samples"]
    (16, 10.0, 400)
    """

    enabled: bool = _monitor_default("enabled")
    octaves: int = _monitor_default("octaves")
    report_interval_s: float = _monitor_default("report_interval_s")
    coverage: float = _monitor_default("coverage")
    arw_factor: float = _monitor_default("arw_factor")
    bias_instability_factor: float = _monitor_default("bias_instability_factor")
    rate_random_walk_factor: float = _monitor_default("rate_random_walk_factor")
    false_alarm_probability: float = _monitor_default("false_alarm_probability")
    stuck_alarm_s: float = _monitor_default("stuck_alarm_s")
    saturated_alarm_s: float = _monitor_default("saturated_alarm_s")
    reidentify: bool = _monitor_default("reidentify")
    reidentify_ar: bool = _monitor_default("reidentify_ar")
    block_s: float = _monitor_default("block_s")
    retune_s: float = _monitor_default("retune_s")
    min_learn_s: float = _monitor_default("min_learn_s")
    memory_s: float = _monitor_default("memory_s")
    max_step: float = _monitor_default("max_step")
    identified_max_rel_stderr: float = _monitor_default("identified_max_rel_stderr")
    identifier: str = _monitor_default("identifier")
    fit_delay_s: float = _monitor_default("fit_delay_s")
    restart_after_fit: bool = _monitor_default("restart_after_fit")

    def samples(self, sample_rate_hz: float) -> dict[str, int | float]:
        """The durations at `sample_rate_hz` as the processor holds them (the C++ reader's
        rounding: lround of seconds times rate): stuck_samples, saturated_samples,
        block_samples (at least MIN_BLOCK_SAMPLES), retune_blocks (whole blocks, at least
        one), retune_samples (their product: one gyro's retune cadence, both identifiers),
        min_samples, memory_blocks (a float: 0, or at least one block), report_samples,
        fit_delay_samples (at least one).

        Examples
        --------
        >>> d = MonitorConfig(block_s=0.5, retune_s=30.0, fit_delay_s=10.0).samples(400.0)
        >>> d["block_samples"], d["retune_blocks"], d["retune_samples"], d["report_samples"]
        (200, 60, 12000, 4000)
        >>> d["fit_delay_samples"]
        4000
        """
        block = max(MIN_BLOCK_SAMPLES, _lround(self.block_s * sample_rate_hz))
        retune_blocks = max(1, _lround(self.retune_s / self.block_s))
        memory = self.memory_s / self.block_s
        return {
            "stuck_samples": _lround(self.stuck_alarm_s * sample_rate_hz),
            "saturated_samples": _lround(self.saturated_alarm_s * sample_rate_hz),
            "block_samples": block,
            "retune_blocks": retune_blocks,
            "retune_samples": retune_blocks * block,
            "min_samples": _lround(self.min_learn_s * sample_rate_hz),
            "memory_blocks": max(1.0, memory) if memory > 0.0 else 0.0,
            "report_samples": max(1, _lround(self.report_interval_s * sample_rate_hz)),
            "fit_delay_samples": max(1, _lround(self.fit_delay_s * sample_rate_hz)),
        }

    def check_fit_delay(self, sample_rate_hz: float, gyros: int) -> None:
        """Raise ConfigError (key ``monitor.fit_delay_s``) when the lag identifier's fits of
        `gyros` watched gyros do not fit one retune interval: each gyro's fit is applied
        fit_delay_s after it starts, before the next gyro's starts, so gyros x
        fit_delay_samples must be at most retune_samples (:meth:`samples`). Nothing to check
        for the recursive identifier.

        Examples
        --------
        >>> MonitorConfig(identifier="lag").check_fit_delay(400.0, 3)  # 3 x 15 s <= 60 s
        >>> MonitorConfig(identifier="lag", fit_delay_s=30.0).check_fit_delay(400.0, 3)
        Traceback (most recent call last):
        ...
        gyrodrift.imu.config.ConfigError: monitor.fit_delay_s: 3 gyros x 12000 samples ...
        """
        if self.identifier != "lag":
            return
        n = self.samples(sample_rate_hz)
        fit_delay, cadence = int(n["fit_delay_samples"]), int(n["retune_samples"])
        if fit_delay > U32_MAX:
            raise ConfigError("monitor.fit_delay_s",
                              f"more than {U32_MAX} samples at {sample_rate_hz!r} Hz")
        if gyros * fit_delay > cadence:
            raise ConfigError(
                "monitor.fit_delay_s",
                f"{gyros} {'gyro' if gyros == 1 else 'gyros'} x {fit_delay} samples exceed "
                f"retune_s = {cadence} samples at {sample_rate_hz!r} Hz: the lag identifier "
                "needs watched gyros x fit_delay_s <= retune_s (each gyro's fit is applied "
                "before the next one's starts)")


#: The fewest samples in one update block of the re-identification.
MIN_BLOCK_SAMPLES = 8


def _lround(x: float) -> int:
    """C's lround (half away from zero) of a non-negative number."""
    return math.floor(x + 0.5)


@dataclass(frozen=True)
class ProcessorConfig:
    """The whole processor: six channels in the order gx gy gz ax ay az.

    Examples
    --------
    >>> cfg = default_config()
    >>> [c.name for c in cfg.channels], cfg.uses("wavelet")
    (['gx', 'gy', 'gz', 'ax', 'ay', 'az'], True)
    >>> cfg2 = cfg.with_channel("gz", ChannelConfig("gz", (PassThrough(),)))
    >>> cfg2.channel("gz").stages, cfg.channel("gz").stages[0].type
    ((PassThrough(type='pass_through'),), 'wavelet')
    """

    channels: tuple[ChannelConfig, ...]
    timing: Timing = Timing()
    meta: tuple[tuple[str, Any], ...] = ()
    monitor: MonitorConfig = MonitorConfig()

    def __post_init__(self) -> None:
        validate(self)

    def channel(self, name: str) -> ChannelConfig:
        """The channel called `name` (gx gy gz ax ay az)."""
        return self.channels[CHANNEL_NAMES.index(name)]

    def with_channel(self, name: str, channel: ChannelConfig) -> ProcessorConfig:
        """A copy with one channel replaced."""
        chans = list(self.channels)
        chans[CHANNEL_NAMES.index(name)] = replace(channel, name=name)
        return replace(self, channels=tuple(chans))

    def with_timing(self, **changes: Any) -> ProcessorConfig:
        """A copy with timing fields replaced (sample_rate_hz, time_tolerance_us,
        loop_rate_hz; None: derived).

        Examples
        --------
        >>> cfg = default_config().with_timing(sample_rate_hz=200.0, time_tolerance_us=None)
        >>> cfg.timing.period_us, cfg.timing.tolerance_us, cfg.timing.loop_hz
        (5000, 2500, 400.0)
        """
        return replace(self, timing=replace(self.timing, **changes))

    def uses(self, stage_type: str) -> bool:
        return any(s.type == stage_type for c in self.channels for s in c.stages)

    def with_monitor(self, **changes: Any) -> ProcessorConfig:
        """A copy with monitor fields replaced.

        Examples
        --------
        >>> cfg = drift_filter_config("gz", a1=0.6, a2=0.2, mean=0.0, q=1e-10, r=1e-8,
        ...                           sample_rate_hz=100.0).with_monitor(enabled=True)
        >>> cfg.monitor.enabled, cfg.monitored_channels()
        (True, ('gz',))
        """
        return replace(self, monitor=replace(self.monitor, **changes))

    def monitored_channels(self) -> tuple[str, ...]:
        """The gyro channels the monitor watches (when enabled): those whose first stage is
        ar2_kalman (its model is the monitor's reference and the re-identification's start)."""
        return tuple(c.name for c in self.channels
                     if c.is_gyro and isinstance(c.stages[0], Ar2KalmanStage))

    def as_dict(self) -> dict[str, Any]:
        """The file's content as plain JSON-ready values (unit suffixes on the keys)."""
        return _to_dict(self)


# ----------------------------------------------------------------------------- validation


def ar2_is_stationary(a1: float, a2: float) -> bool:
    """Both roots of z^2 - a1 z - a2 inside the unit circle (the stationarity triangle).

    Examples
    --------
    >>> ar2_is_stationary(1.0, -0.25), ar2_is_stationary(1.3, -0.25)
    (True, False)
    """
    return abs(a2) < 1.0 and a1 + a2 < 1.0 and a2 - a1 < 1.0


#: The float32 processor's stationarity bound (include/gyrodrift/filters/ar2_model.hpp:
#: ar2_is_stationary, 1 - 64 machine epsilons).
_F32_ONE = np.float32(1.0) - np.float32(64.0) * np.finfo(np.float32).eps


def _ar2_is_stationary_f32(a1: float, a2: float) -> bool:
    """The float32 processor's own stationarity test, in float32 arithmetic as it runs it."""
    x1, x2 = np.float32(a1), np.float32(a2)
    return bool(-_F32_ONE < x2 < _F32_ONE and x1 + x2 < _F32_ONE and x2 - x1 < _F32_ONE)


def _check_field(key: str, spec: Field, value: Any) -> None:
    """The field's own bounds (gyrodrift.imu.schema), in the words both readers use."""
    if value is None and spec.default is None:
        return
    if (spec.float32 and isinstance(value, (int, float)) and not isinstance(value, bool)
            and to_float32(float(value)) is None):
        raise ConfigError(key, f"{float(value)!r} does not fit a float32, the processor's "
                               f"scalar (a magnitude {FLOAT32_RANGE_TEXT}, or 0)")
    if not spec.accepts(value):
        raise ConfigError(key, f"expected {spec.bounds_text()}, got {value!r}")


def _stage_values(s: Stage) -> dict[str, Any]:
    """The stage's fields by schema name (sigma2 as given: None when it follows q)."""
    return {f.name: getattr(s, f.name) for f in FIELDS if f.section == s.type}


def _check_stage(key: str, ch: str, s: Stage) -> None:
    if not isinstance(s, (PassThrough, BiasRemoval, WaveletStage, Ar2KalmanStage)):
        raise ConfigError(f"{key}.type", f"unknown stage {s!r}")
    for f in FIELDS:
        if f.section != s.type:
            continue
        if isinstance(s, WaveletStage) and f.name == "level":
            # the deepest level depends on the wavelet and the window (checked before it)
            jmax = max_wavelet_level(s.window, s.wavelet)
            if not (isinstance(s.level, int) and 1 <= s.level <= jmax):
                raise ConfigError(
                    f"{key}.level", f"expected 1..{jmax} for {s.wavelet} with window "
                    f"{s.window}, got {s.level}"
                )
            continue
        _check_field(f"{key}.{f.key(ch)}", f, getattr(s, f.name))
    if isinstance(s, Ar2KalmanStage) and not ar2_is_stationary(s.a1, s.a2):
        raise ConfigError(
            f"{key}.a1",
            f"AR(2) model is not stationary (a1={s.a1!r}, a2={s.a2!r}; needs |a2| < 1, "
            "a1 + a2 < 1, a2 - a1 < 1)",
        )
    if isinstance(s, Ar2KalmanStage) and not _ar2_is_stationary_f32(s.a1, s.a2):
        raise ConfigError(
            f"{key}.a1",
            f"AR(2) model is not stationary in float32, the processor's scalar (a1={s.a1!r}, "
            f"a2={s.a2!r}; in float32 |a2|, a1 + a2 and a2 - a1 must stay below "
            f"1 - 64 eps = {float(_F32_ONE)!r})",
        )


def validate(cfg: ProcessorConfig) -> None:
    """Raise ConfigError (key named) if `cfg` is not a valid configuration.

    Examples
    --------
    >>> validate(default_config())  # valid: returns None
    """
    if len(cfg.channels) != len(CHANNEL_NAMES):
        raise ConfigError("channels", f"expected the six channels {CHANNEL_NAMES}")
    for ch, cc in zip(CHANNEL_NAMES, cfg.channels, strict=True):
        key = f"channels.{ch}"
        if cc.name != ch:
            raise ConfigError(key, f"channel named {cc.name!r} in the place of {ch!r}")
        if not 1 <= len(cc.stages) <= MAX_STAGES:
            raise ConfigError(
                f"{key}.stages", f"expected 1..{MAX_STAGES} stages, got {len(cc.stages)}"
            )
        types = [s.type for s in cc.stages]
        if "pass_through" in types and len(types) > 1:
            raise ConfigError(f"{key}.stages", "pass_through must be the only stage of a chain")
        if len(set(types)) != len(types):
            raise ConfigError(f"{key}.stages", f"at most one stage of each type, got {types}")
        for i, s in enumerate(cc.stages):
            _check_stage(f"{key}.stages[{i}]", ch, s)
        for f in FIELDS:
            if f.section == "channel":
                _check_field(f"{key}.{f.key(ch)}", f, getattr(cc, f.name))
    for f in FIELDS:
        if f.section == "timing":
            _check_field(f"timing.{f.key('')}", f, getattr(cfg.timing, f.name))
    _check_monitor(cfg)
    loop = field_spec("timing", "loop_rate_hz")
    if cfg.timing.loop_rate_hz is None and not loop.accepts(cfg.timing.sample_rate_hz):
        # valid for the format, not for the loop program: its cycle runs at most at 2000 Hz
        raise ConfigError("timing.loop_rate_hz", f"absent, so the sample rate "
                          f"{cfg.timing.sample_rate_hz!r} Hz, outside the loop's "
                          f"{loop.bounds_text()}: give it")


def _check_monitor(cfg: ProcessorConfig) -> None:
    """The monitor's fields, then their relations to each other and to the processor."""
    m = cfg.monitor
    for f in FIELDS:
        if f.section == "monitor":
            _check_field(f"monitor.{f.key('')}", f, getattr(m, f.name))
    rate = cfg.timing.sample_rate_hz
    n = m.samples(rate)
    if n["block_samples"] > U32_MAX:
        raise ConfigError("monitor.block_s", f"more than {U32_MAX} samples at {rate!r} Hz")
    for name in ("stuck_alarm_s", "saturated_alarm_s"):
        if n[name.replace("_alarm_s", "_samples")] > U32_MAX:
            raise ConfigError(f"monitor.{name}", f"more than {U32_MAX} samples at {rate!r} Hz")
    if m.enabled and not cfg.monitored_channels():
        raise ConfigError("monitor.enabled", "no gyro channel has ar2_kalman as its first "
                                             "stage (the drift model the monitor starts from)")
    # the gyros the processor watches, or the one `gyrodrift monitor` runs when it is off
    m.check_fit_delay(rate, len(cfg.monitored_channels()) if m.enabled else 1)


# ----------------------------------------------------------------------------- reading


class _Table:
    """A TOML table read key by key; unread keys are reported as unknown."""

    def __init__(self, key: str, data: Any) -> None:
        if not isinstance(data, Mapping):
            raise ConfigError(key, f"expected a table, got {type(data).__name__}")
        self.key = key
        self.data = dict(data)
        self.used: set[str] = set()

    def _k(self, name: str) -> str:
        return f"{self.key}.{name}" if self.key else name

    def has(self, name: str) -> bool:
        return name in self.data

    def get(self, name: str, kind: str, default: Any = ..., unit_hint: str | None = None) -> Any:
        key = self._k(name)
        if name not in self.data:
            if default is ...:
                raise ConfigError(key, "missing value")
            return default
        self.used.add(name)
        v = self.data[name]
        if kind != "any" and isinstance(v, (Mapping, list)):
            words = {"float": "a number", "int": "an integer", "bool": "true or false",
                     "str": "a string"}[kind]
            raise ConfigError(key, f"expected {words}, got {_kind_words(v)}")
        if kind == "float":
            if v is None and isinstance(default, float) and math.isinf(default):
                # JSON has no infinity: `config show --json` writes an unlimited value (the
                # field's default, inf) as null, and reading that document back restores it
                return default
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ConfigError(key, f"expected a number, got {v!r}")
            return float(v)
        if kind == "int":
            if isinstance(v, bool) or not isinstance(v, int):
                raise ConfigError(key, f"expected an integer, got {v!r}")
            return int(v)
        if kind == "bool":
            if not isinstance(v, bool):
                raise ConfigError(key, f"expected true or false, got {v!r}")
            return v
        if kind == "str":
            if not isinstance(v, str):
                raise ConfigError(key, f"expected a string, got {v!r}")
            return v
        return v

    def finish(self, channel: str | None = None) -> None:
        for name in sorted(self.data):  # key order: both readers name the same first key
            if name in self.used:
                continue
            key = self._k(name)
            if channel is not None:
                want = channel_unit_suffix(channel)
                for suf in _OTHER_SUFFIXES:
                    if name.endswith(suf) and suf != want:
                        raise _wrong_units(key, name[: -len(suf)], channel)
            raise ConfigError(key, "unknown key")


def _read_fields(t: _Table, section: str, ch: str = "") -> dict[str, Any]:
    """The values of one section's fields (gyrodrift.imu.schema) from table `t`, by field name:
    a missing required field is an error, a missing optional one takes its default."""
    out = {}
    for f in FIELDS:
        if f.section != section:
            continue
        if f.unit == "channel":
            _wrong_unit_key(t, f.name, ch)
        out[f.name] = t.get(f.key(ch), f.kind, ... if f.default is REQUIRED else f.default)
    return out


_STAGE_CLASSES: dict[str, type[Stage]] = {
    "pass_through": PassThrough, "bias_removal": BiasRemoval, "wavelet": WaveletStage,
    "ar2_kalman": Ar2KalmanStage,
}


def _read_stage(key: str, ch: str, data: Any) -> Stage:
    t = _Table(key, data)
    kind = t.get("type", "str")
    if kind not in _STAGE_CLASSES:
        raise ConfigError(f"{key}.type", f"expected one of {', '.join(STAGE_TYPES)}, got {kind!r}")
    stage = _STAGE_CLASSES[kind](**_read_fields(t, kind, ch))
    t.finish(ch)
    return stage


def _wrong_unit_key(t: _Table, base: str, ch: str) -> bool:
    """If `base` is given with another unit's suffix (and not with this channel's), raise the
    wrong-units error for that key (rather than 'missing value'). Returns False otherwise."""
    want = channel_unit_suffix(ch)
    if f"{base}{want}" in t.data:
        return False
    for suf in _OTHER_SUFFIXES:
        if suf != want and f"{base}{suf}" in t.data:
            raise _wrong_units(t._k(f"{base}{suf}"), base, ch)
    return False


def _wrong_units(key: str, base: str, channel: str) -> ConfigError:
    """The error of a key written in another unit than its channel's."""
    kind = "a gyro" if channel.startswith("g") else "an accelerometer"
    return ConfigError(key, f"wrong units for {kind} channel ({channel_unit(channel)}): use "
                            f"{base}{channel_unit_suffix(channel)}")


def config_from_dict(data: Mapping[str, Any]) -> ProcessorConfig:
    """Build and validate a configuration from the parsed TOML (or JSON) document.

    Examples
    --------
    >>> import tomllib
    >>> data = tomllib.loads(dumps_config(default_config()))
    >>> list(data)
    ['schema', 'version', 'meta', 'timing', 'channels']
    >>> config_from_dict(data) == default_config()
    True
    """
    top = _Table("", data)
    schema = top.get("schema", "str")
    if schema != SCHEMA:
        raise ConfigError("schema", f"expected {SCHEMA!r}, got {schema!r}")
    version = top.get("version", "int")
    if version != VERSION:
        raise ConfigError("version", f"this gyrodrift reads version {VERSION}, got {version}")
    meta_items: tuple[tuple[str, Any], ...] = ()
    if top.has("meta"):
        meta = top.get("meta", "any")
        if not isinstance(meta, Mapping):
            raise ConfigError("meta", "expected a table")
        for k, v in sorted(meta.items()):
            if not isinstance(v, (str, int, float, bool)):
                raise ConfigError(f"meta.{k}", "expected a string, number or boolean")
        meta_items = tuple(meta.items())
    tt = _Table("timing", top.get("timing", "any"))
    timing = Timing(**_read_fields(tt, "timing"))
    tt.finish()
    ct = _Table("channels", top.get("channels", "any"))
    channels = []
    for ch in CHANNEL_NAMES:
        key = f"channels.{ch}"
        c = _Table(key, ct.get(ch, "any"))
        values = _read_fields(c, "channel", ch)
        raw = c.get("stages", "any")
        if not isinstance(raw, list):
            raise ConfigError(f"{key}.stages", "expected an array of tables ([[...stages]])")
        stages = tuple(_read_stage(f"{key}.stages[{i}]", ch, s) for i, s in enumerate(raw))
        c.finish(ch)
        channels.append(ChannelConfig(name=ch, stages=stages, **values))
    ct.finish()
    monitor = MonitorConfig()
    if top.has("monitor"):
        mt = _Table("monitor", top.get("monitor", "any"))
        monitor = MonitorConfig(**_read_fields(mt, "monitor"))
        mt.finish()
    top.finish()
    return ProcessorConfig(channels=tuple(channels), timing=timing, meta=meta_items,
                           monitor=monitor)


#: Tables and arrays nested deeper than this are refused (both readers; the document is depth
#: 0, [timing] 1, a stage's table 3).
MAX_NESTING = 128
_TOO_DEEP = f"tables or arrays nested deeper than {MAX_NESTING}"
_INT64 = (-(2**63), 2**63 - 1)
_DOUBLE_MIN_NORMAL = 2.2250738585072014e-308
FLOAT32_RANGE_TEXT = "1.1754944e-38..3.4028235e+38"


class _LiteralError(GyrodriftValueError):
    """A float literal outside the normal range of a double (raised while parsing)."""


def _parse_float(literal: str) -> float:
    """tomllib's float hook: the literal's double, refusing one that overflows or whose
    nonzero value rounds to zero or to a subnormal number (the rule of both readers: every
    number read is a normal double, or zero written as zero)."""
    x = float(literal)
    body = literal.lower().lstrip("+-")
    if body in ("inf", "nan"):
        return x
    mantissa = body.split("e")[0]
    nonzero = any(c in "123456789" for c in mantissa)
    if math.isinf(x) or (nonzero and abs(x) < _DOUBLE_MIN_NORMAL):
        raise _LiteralError(f"float {literal} is outside the range of a double (normal "
                            "magnitudes 2.2250738585072014e-308..1.7976931348623157e+308, or 0)")
    return x


def _kind_words(v: Any) -> str:
    return "a table" if isinstance(v, Mapping) else "an array"


def _walk(data: Any, key: str, depth: int) -> Iterator[tuple[str, Any, int]]:
    """(key, value, nesting depth) of every value under `data`, keys sorted; an array of
    tables is walked as tables (key[i]), any other array is a leaf."""
    if isinstance(data, Mapping):
        for k in sorted(data):
            yield from _walk(data[k], f"{key}.{k}" if key else str(k), depth)
        return
    if isinstance(data, list) and all(isinstance(d, Mapping) for d in data):
        for i, d in enumerate(data):
            yield from _walk(d, f"{key}[{i}]", depth)
        return
    yield key, data, depth


def _depth(v: Any) -> int:
    """Nesting depth of tables and arrays under `v` (0 for a scalar), iteratively."""
    best, stack = 0, [(v, 0)]
    while stack:
        x, d = stack.pop()
        best = max(best, d)
        if isinstance(x, Mapping):
            stack += [(y, d + 1) for y in x.values()]
        elif isinstance(x, list):
            stack += [(y, d + 1) for y in x]
    return best


def _check_document(data: Mapping[str, Any], source: str) -> None:
    """What TOML allows but the format does not, the same rules as the loop's reader: integers
    beyond 64 bits and nesting deeper than MAX_NESTING (the file is not valid TOML for either
    reader), then, by key, a value that is not a string, number, boolean or table (arrays,
    dates and times)."""
    if _depth(data) > MAX_NESTING:
        raise ConfigError(source, f"not valid TOML: {_TOO_DEEP}")
    leaves = list(_walk(data, "", 0))
    for _, v, _ in leaves:
        if isinstance(v, int) and not isinstance(v, bool) and not _INT64[0] <= v <= _INT64[1]:
            raise ConfigError(source, f"not valid TOML: integer {v} is not representable in "
                                      "64 bits")
    for key, v, _ in leaves:
        if isinstance(v, (list, datetime.date, datetime.time)):
            raise ConfigError(key, "value not in the supported TOML subset (string, integer, "
                                   "float, inf, nan, true/false, tables)")


def parse_config(text: str, source: str = "<string>") -> ProcessorConfig:
    """Parse TOML text. A TOML syntax error is a ConfigError naming `source`.

    Examples
    --------
    >>> cfg = parse_config(dumps_config(default_config()))
    >>> cfg.timing.sample_rate_hz, cfg.channel("gx").saturation
    (400.0, 8.0)
    >>> parse_config('schema = "gyrodrift.processor"\\nversion = 1\\n', "mine.toml")
    Traceback (most recent call last):
    ...
    gyrodrift.imu.config.ConfigError: timing: missing value
    """
    try:
        data = tomllib.loads(text, parse_float=_parse_float)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(source, f"not valid TOML: {exc}") from None
    except _LiteralError as exc:
        raise ConfigError(source, f"not valid TOML: {exc}") from None
    except RecursionError:
        raise ConfigError(source, f"not valid TOML: {_TOO_DEEP}") from None
    _check_document(data, source)
    return config_from_dict(data)


def load_config(path: str | os.PathLike[str]) -> ProcessorConfig:
    """Read and validate a configuration file.

    Raises ConfigError (key named) for a bad configuration and OSError for an unreadable path.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = write_config(default_config(), Path(d) / "processor.toml")
    ...     print(load_config(path) == default_config())
    True
    """
    p = Path(path)
    try:
        text = p.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError(str(p), "not a UTF-8 text file") from None
    return parse_config(text, str(p))


# ----------------------------------------------------------------------------- writing


def _num(x: float) -> str:
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return repr(float(x))  # shortest round-trip form, always with '.' or 'e'


def _str(s: str) -> str:
    out = s.replace("\\", "\\\\").replace('"', '\\"')
    out = "".join(c if ord(c) >= 0x20 and c != "\x7f" else f"\\u{ord(c):04x}" for c in out)
    return f'"{out}"'


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return _num(v)
    return _str(str(v))


def _field_lines(section: str, obj: Any, ch: str = "") -> list[str]:
    """`key = value` lines of one section's fields, in the schema's order; an optional field
    left at None is not written (absent: derived, so the file reads back identical)."""
    lines = []
    for f in FIELDS:
        if f.section != section:
            continue
        v = getattr(obj, f.name)
        if v is None:
            continue
        v = {"float": float, "int": int, "bool": bool, "str": str}[f.kind](v)
        lines.append(f"{f.key(ch)} = {_value(v)}")
    return lines


def dumps_config(cfg: ProcessorConfig) -> str:
    """The canonical TOML text of `cfg` (the subset the C++ loop reads).

    Examples
    --------
    >>> print("\\n".join(dumps_config(default_config()).splitlines()[1:12]))
    schema = "gyrodrift.processor"
    version = 1
    <BLANKLINE>
    [meta]
    written_by = "gyrodrift config write-default"
    <BLANKLINE>
    [timing]
    sample_rate_hz = 400.0
    time_tolerance_us = 1250
    loop_rate_hz = 400.0
    <BLANKLINE>
    """
    validate(cfg)
    lines = ["# gyrodrift processor configuration "
             "(see the configuration file guide in the documentation)",
             f"schema = {_str(SCHEMA)}", f"version = {VERSION}", ""]
    if cfg.meta:
        lines.append("[meta]")
        lines += [f"{k} = {_value(v)}" for k, v in cfg.meta]
        lines.append("")
    lines += ["[timing]", *_field_lines("timing", cfg.timing), ""]
    if cfg.monitor != MonitorConfig():  # absent: off, every field its default
        lines += ["[monitor]", *_field_lines("monitor", cfg.monitor), ""]
    for cc in cfg.channels:
        ch = cc.name
        lines += [f"[channels.{ch}]", *_field_lines("channel", cc, ch), ""]
        for s in cc.stages:
            lines.append(f"[[channels.{ch}.stages]]")
            lines += [f"type = {_value(s.type)}", *_field_lines(s.type, s, ch)]
            lines.append("")
    return "\n".join(lines)


def _to_dict(cfg: ProcessorConfig) -> dict[str, Any]:
    return tomllib.loads(dumps_config(cfg))


def write_config(cfg: ProcessorConfig, path: str | os.PathLike[str]) -> Path:
    """Write `cfg` as canonical TOML, atomically; returns the path.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = write_config(default_config(), Path(d) / "processor.toml")
    ...     print(path.name, path.read_text().splitlines()[1])
    processor.toml schema = "gyrodrift.processor"
    """
    return atomic_write_text(path, dumps_config(cfg))


def pass_through_config(sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ) -> ProcessorConfig:
    """Every channel passed through unchanged (no saturation or stuck detection) at
    ``sample_rate_hz``: the processor that only checks the stream (sequence, timestamps, bad
    values), e.g. to test a link.

    Examples
    --------
    >>> cfg = pass_through_config(100.0)
    >>> {s.type for c in cfg.channels for s in c.stages}, cfg.timing.period_us
    ({'pass_through'}, 10000)
    """
    loop_max = field_spec("timing", "loop_rate_hz").hi
    assert loop_max is not None
    return ProcessorConfig(
        channels=tuple(ChannelConfig(name=ch, stages=(PassThrough(),)) for ch in CHANNEL_NAMES),
        timing=Timing(sample_rate_hz=sample_rate_hz, loop_rate_hz=min(sample_rate_hz, loop_max)))


def drift_filter_config(channel: str, *, a1: float, a2: float, mean: float, q: float,
                        r: float, sample_rate_hz: float,
                        meta: tuple[tuple[str, Any], ...] = ()) -> ProcessorConfig:
    """A steady-state AR(2)-Kalman stage (sigma2 = q) on one channel, every other channel
    passed through: what an identified drift model (``gyrodrift fit``) gives the processor.
    Units: the channel's (rad/s for a gyro); q and r its square.

    Examples
    --------
    >>> cfg = drift_filter_config("gz", a1=0.6, a2=0.2, mean=0.0, q=1e-10, r=1e-8,
    ...                           sample_rate_hz=100.0)
    >>> [c.stages[0].type for c in cfg.channels]
    ['pass_through', 'pass_through', 'ar2_kalman', 'pass_through', 'pass_through', 'pass_through']
    """
    stage = Ar2KalmanStage(a1=a1, a2=a2, mean=mean, q=q, r=r, sigma2=q, steady_state=True)
    cfg = pass_through_config(sample_rate_hz).with_channel(channel,
                                                           ChannelConfig(channel, (stage,)))
    return replace(cfg, meta=meta)


def default_config(
    gyro_model: tuple[float, float, float, float, float] | None = None,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
) -> ProcessorConfig:
    """The shipped default: gyros wavelet db4 N=256 J=5 forced -> steady-state AR(2)-Kalman
    (``gyro_model`` = (a1, a2, mean_rad_s, q, r), by default the demonstration model
    gyrodrift.imu.schema.DEMO_AR2: identify yours with ``gyrodrift fit``), accelerometers bias
    removal (bias 0), saturation and stuck detection, at ``sample_rate_hz`` (the timestamp
    tolerance half a period, the loop at the sample rate, at most 2000 Hz).

    Examples
    --------
    >>> cfg = default_config()
    >>> [s.type for s in cfg.channel("gx").stages], [s.type for s in cfg.channel("ax").stages]
    (['wavelet', 'ar2_kalman'], ['bias_removal'])
    >>> default_config((0.6, 0.2, 0.0, 1e-9, 1e-7)).channel("gy").stages[1].a1
    0.6
    """
    d = DEMO_AR2
    a1, a2, mean, q, r = gyro_model or (d["a1"], d["a2"], d["mean"], d["q"], d["r"])
    gyro = (
        WaveletStage(),
        Ar2KalmanStage(a1=a1, a2=a2, mean=mean, q=q, r=r, sigma2=q, steady_state=True),
    )
    chans = [ChannelConfig(name=ch, stages=gyro, saturation=DEFAULT_GYRO_SATURATION_RAD_S,
                           stuck_samples=DEFAULT_GYRO_STUCK_SAMPLES)
             for ch in CHANNEL_NAMES[:3]]
    chans += [ChannelConfig(name=ch, stages=(BiasRemoval(),),
                            saturation=DEFAULT_ACCEL_SATURATION_M_S2)
              for ch in CHANNEL_NAMES[3:]]
    loop_max = field_spec("timing", "loop_rate_hz").hi
    assert loop_max is not None
    timing = Timing(sample_rate_hz=sample_rate_hz,
                    time_tolerance_us=default_time_tolerance_us(sample_rate_hz),
                    loop_rate_hz=min(sample_rate_hz, loop_max))
    return ProcessorConfig(channels=tuple(chans), timing=timing,
                           meta=(("written_by", "gyrodrift config write-default"),))
