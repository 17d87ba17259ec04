"""The processor configuration file (version 1): one file from identification to firmware.

One TOML file describes the six-channel processor (gx gy gz in rad/s, ax ay az in m/s^2):
per channel a chain of one or two stages from pass_through, bias_removal, wavelet and
ar2_kalman, plus saturation and stuck detection, and the timing (sample rate, timestamp
tolerance, loop rate). ``gyrodrift-loop --config``, ``gyrodrift replay --config``, the Python
``ImuProcessor``, the numpy reference processor and ``gyrodrift config emit-cpp`` read it;
``gyrodrift fit`` writes it. The format is documented in README.md (section "Processor
configuration file"); ``gyrodrift config write-default`` writes a full example.

Every problem is a :class:`ConfigError` whose one-line message starts with the key
(``channels.gx.stages[1].a1: ...``).

Example
-------
>>> cfg = default_config()
>>> parse_config(dumps_config(cfg)) == cfg
True
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Union

from gyrodrift.errors import GyrodriftValueError
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
    "PassThrough",
    "ProcessorConfig",
    "Stage",
    "Timing",
    "WaveletStage",
    "config_from_dict",
    "default_config",
    "dumps_config",
    "load_config",
    "max_wavelet_level",
    "parse_config",
    "write_config",
]

SCHEMA = "gyrodrift.processor"
VERSION = 1
CHANNEL_NAMES = ("gx", "gy", "gz", "ax", "ay", "az")
WAVELETS = {"db4": 8, "db8": 16}  # name -> filter length
THRESHOLDS = ("forced", "soft", "hard")
MAX_STAGES = 2

# Unit suffix of each channel kind, and suffixes that name a unit the processor refuses.
_GYRO_SUFFIX = "_rad_s"
_ACCEL_SUFFIX = "_m_s2"
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
        super().__init__(f"{key}: {message}" if key else message)


def _unit_suffix(channel: str) -> str:
    return _GYRO_SUFFIX if channel.startswith("g") else _ACCEL_SUFFIX


def _units(channel: str) -> str:
    return "rad/s" if channel.startswith("g") else "m/s^2"


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

    bias: float = 0.0
    type: str = field(default="bias_removal", init=False)


@dataclass(frozen=True)
class WaveletStage:
    """Real-time sliding-window wavelet prefilter (paper 004 sec. 2.2).

    Examples
    --------
    >>> WaveletStage(wavelet="db8", level=4)
    WaveletStage(wavelet='db8', window=256, level=4, threshold='forced', type='wavelet')
    """

    wavelet: str = "db4"
    window: int = 256
    level: int = 5
    threshold: str = "forced"
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
    sigma2: float | None = None  # None: = q
    p0: float = 1.0
    steady_state: bool = False
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
    saturation: float = math.inf
    stuck_samples: int = 0

    @property
    def units(self) -> str:
        return _units(self.name)

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

    sample_rate_hz: float = 400.0
    time_tolerance_us: int | None = None
    loop_rate_hz: float | None = None

    @property
    def period_us(self) -> int:
        return math.floor(1e6 / self.sample_rate_hz + 0.5)

    @property
    def tolerance_us(self) -> int:
        if self.time_tolerance_us is not None:
            return self.time_tolerance_us
        return math.floor(1e6 / self.sample_rate_hz / 2.0 + 0.5)  # C++ lround

    @property
    def loop_hz(self) -> float:
        return self.sample_rate_hz if self.loop_rate_hz is None else self.loop_rate_hz


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

    def uses(self, stage_type: str) -> bool:
        return any(s.type == stage_type for c in self.channels for s in c.stages)

    def as_dict(self) -> dict[str, Any]:
        """The file's content as plain JSON-ready values (unit suffixes on the keys)."""
        return _to_dict(self)


# ----------------------------------------------------------------------------- validation


def max_wavelet_level(window: int, wavelet: str) -> int:
    """pywt.dwt_max_level(2N, filter length): the deepest level of the extended window.

    Examples
    --------
    >>> max_wavelet_level(256, "db4"), max_wavelet_level(256, "db8")
    (6, 5)
    """
    flen = WAVELETS[wavelet] - 1
    level = 0
    while level < 8 and (flen << (level + 1)) <= 2 * window:
        level += 1
    return level


def ar2_is_stationary(a1: float, a2: float) -> bool:
    """Both roots of z^2 - a1 z - a2 inside the unit circle (the stationarity triangle)."""
    return abs(a2) < 1.0 and a1 + a2 < 1.0 and a2 - a1 < 1.0


def _finite(key: str, v: float) -> None:
    if not math.isfinite(v):
        raise ConfigError(key, f"must be finite, got {v!r}")


def _check_stage(key: str, ch: str, s: Stage) -> None:
    u = _unit_suffix(ch)
    if isinstance(s, BiasRemoval):
        _finite(f"{key}.bias{u}", s.bias)
    elif isinstance(s, WaveletStage):
        if s.wavelet not in WAVELETS:
            raise ConfigError(
                f"{key}.wavelet", f"expected one of {sorted(WAVELETS)}, got {s.wavelet!r}"
            )
        n = s.window
        if not (16 <= n <= 4096 and n & (n - 1) == 0):
            raise ConfigError(f"{key}.window", f"expected a power of two in 16..4096, got {n}")
        jmax = max_wavelet_level(n, s.wavelet)
        if not 1 <= s.level <= jmax:
            raise ConfigError(
                f"{key}.level", f"expected 1..{jmax} for {s.wavelet} with window {n}, got {s.level}"
            )
        if s.threshold not in THRESHOLDS:
            raise ConfigError(
                f"{key}.threshold", f"expected one of {THRESHOLDS}, got {s.threshold!r}"
            )
    elif isinstance(s, Ar2KalmanStage):
        for name in ("a1", "a2", "q", "r", "p0"):
            _finite(f"{key}.{name}", getattr(s, name))
        _finite(f"{key}.mean{u}", s.mean)
        if s.sigma2 is not None:
            _finite(f"{key}.sigma2", s.sigma2)
            if s.sigma2 < 0:
                raise ConfigError(f"{key}.sigma2", f"a variance must be >= 0, got {s.sigma2!r}")
        if not ar2_is_stationary(s.a1, s.a2):
            raise ConfigError(
                f"{key}.a1",
                f"AR(2) model is not stationary (a1={s.a1!r}, a2={s.a2!r}; needs |a2| < 1, "
                "a1 + a2 < 1, a2 - a1 < 1)",
            )
        if s.q < 0:
            raise ConfigError(f"{key}.q", f"a variance must be >= 0, got {s.q!r}")
        if not s.r > 0:
            raise ConfigError(f"{key}.r", f"must be > 0, got {s.r!r}")
        if s.p0 < 0:
            raise ConfigError(f"{key}.p0", f"must be >= 0, got {s.p0!r}")
    elif not isinstance(s, PassThrough):
        raise ConfigError(f"{key}.type", f"unknown stage {s!r}")


def validate(cfg: ProcessorConfig) -> None:
    """Raise ConfigError (key named) if `cfg` is not a valid configuration."""
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
        sat_key = f"{key}.saturation{_unit_suffix(ch)}"
        if math.isnan(cc.saturation) or not cc.saturation > 0:
            raise ConfigError(sat_key, f"must be > 0 (or inf: off), got {cc.saturation!r}")
        if not 0 <= cc.stuck_samples < 2**32:
            raise ConfigError(f"{key}.stuck_samples", f"expected 0..2^32-1, got {cc.stuck_samples}")
    t = cfg.timing
    if not (math.isfinite(t.sample_rate_hz) and 1.0 <= t.sample_rate_hz <= 1e5):
        raise ConfigError(
            "timing.sample_rate_hz", f"expected 1..100000 Hz, got {t.sample_rate_hz!r}"
        )
    if t.time_tolerance_us is not None and not 0 <= t.time_tolerance_us < 2**32:
        raise ConfigError(
            "timing.time_tolerance_us", f"expected 0..2^32-1, got {t.time_tolerance_us}"
        )
    if t.loop_rate_hz is not None and not (
        math.isfinite(t.loop_rate_hz) and 1.0 <= t.loop_rate_hz <= 2000.0
    ):
        raise ConfigError("timing.loop_rate_hz", f"expected 1..2000 Hz, got {t.loop_rate_hz!r}")


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
        if kind == "float":
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
        for name in self.data:
            if name in self.used:
                continue
            key = self._k(name)
            if channel is not None:
                want = _unit_suffix(channel)
                for suf in _OTHER_SUFFIXES:
                    if name.endswith(suf) and suf != want:
                        base = name[: -len(suf)]
                        kind = "gyro" if channel.startswith("g") else "n accelerometer"
                        raise ConfigError(
                            key,
                            f"wrong units for a {kind} channel ({_units(channel)}): "
                            f"use {base}{want}",
                        )
            raise ConfigError(key, "unknown key")


def _read_stage(key: str, ch: str, data: Any) -> Stage:
    t = _Table(key, data)
    kind = t.get("type", "str")
    u = _unit_suffix(ch)
    stage: Stage
    if kind == "pass_through":
        stage = PassThrough()
    elif kind == "bias_removal":
        _wrong_unit_key(t, "bias", ch)
        stage = BiasRemoval(bias=t.get(f"bias{u}", "float"))
    elif kind == "wavelet":
        stage = WaveletStage(
            wavelet=t.get("wavelet", "str"),
            window=t.get("window", "int"),
            level=t.get("level", "int"),
            threshold=t.get("threshold", "str", "forced"),
        )
    elif kind == "ar2_kalman":
        sigma2 = t.get("sigma2", "float", None)
        stage = Ar2KalmanStage(
            a1=t.get("a1", "float"),
            a2=t.get("a2", "float"),
            mean=t.get(f"mean{u}", "float", ...) if not _wrong_unit_key(t, "mean", ch) else 0.0,
            q=t.get("q", "float"),
            r=t.get("r", "float"),
            sigma2=sigma2,
            p0=t.get("p0", "float", 1.0),
            steady_state=t.get("steady_state", "bool", False),
        )
    else:
        raise ConfigError(
            f"{key}.type",
            f"expected one of pass_through, bias_removal, wavelet, ar2_kalman, got {kind!r}",
        )
    t.finish(ch)
    return stage


def _wrong_unit_key(t: _Table, base: str, ch: str) -> bool:
    """If `base` is given with another unit's suffix (and not with this channel's), raise the
    wrong-units error for that key (rather than 'missing value'). Returns False otherwise."""
    want = _unit_suffix(ch)
    if f"{base}{want}" in t.data:
        return False
    for suf in _OTHER_SUFFIXES:
        if suf != want and f"{base}{suf}" in t.data:
            kind = "gyro" if ch.startswith("g") else "n accelerometer"
            raise ConfigError(
                t._k(f"{base}{suf}"),
                f"wrong units for a {kind} channel ({_units(ch)}): use {base}{want}",
            )
    return False


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
        for k, v in meta.items():
            if not isinstance(v, (str, int, float, bool)):
                raise ConfigError(f"meta.{k}", "expected a string, number or boolean")
        meta_items = tuple(meta.items())
    tt = _Table("timing", top.get("timing", "any"))
    timing = Timing(
        sample_rate_hz=tt.get("sample_rate_hz", "float"),
        time_tolerance_us=tt.get("time_tolerance_us", "int", None),
        loop_rate_hz=tt.get("loop_rate_hz", "float", None),
    )
    tt.finish()
    ct = _Table("channels", top.get("channels", "any"))
    channels = []
    for ch in CHANNEL_NAMES:
        key = f"channels.{ch}"
        c = _Table(key, ct.get(ch, "any"))
        u = _unit_suffix(ch)
        _wrong_unit_key(c, "saturation", ch)
        sat = c.get(f"saturation{u}", "float", math.inf)
        stuck = c.get("stuck_samples", "int", 0)
        raw = c.get("stages", "any")
        if not isinstance(raw, list):
            raise ConfigError(f"{key}.stages", "expected an array of tables ([[...stages]])")
        stages = tuple(_read_stage(f"{key}.stages[{i}]", ch, s) for i, s in enumerate(raw))
        c.finish(ch)
        channels.append(ChannelConfig(name=ch, stages=stages, saturation=sat, stuck_samples=stuck))
    ct.finish()
    top.finish()
    return ProcessorConfig(channels=tuple(channels), timing=timing, meta=meta_items)


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
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(source, f"not valid TOML: {exc}") from None
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


def _stage_items(ch: str, s: Stage) -> list[tuple[str, Any]]:
    u = _unit_suffix(ch)
    items: list[tuple[str, Any]] = [("type", s.type)]
    if isinstance(s, BiasRemoval):
        items.append((f"bias{u}", float(s.bias)))
    elif isinstance(s, WaveletStage):
        items += [("wavelet", s.wavelet), ("window", int(s.window)), ("level", int(s.level)),
                  ("threshold", s.threshold)]
    elif isinstance(s, Ar2KalmanStage):
        items += [("a1", float(s.a1)), ("a2", float(s.a2)), (f"mean{u}", float(s.mean))]
        if s.sigma2 is not None:  # absent: = q (so a written file reads back identical)
            items.append(("sigma2", float(s.sigma2)))
        items += [("q", float(s.q)), ("r", float(s.r)), ("p0", float(s.p0)),
                  ("steady_state", bool(s.steady_state))]
    return items


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
    lines = ["# gyrodrift processor configuration (README: Processor configuration file)",
             f"schema = {_str(SCHEMA)}", f"version = {VERSION}", ""]
    if cfg.meta:
        lines.append("[meta]")
        lines += [f"{k} = {_value(v)}" for k, v in cfg.meta]
        lines.append("")
    t = cfg.timing
    lines += ["[timing]", f"sample_rate_hz = {_num(t.sample_rate_hz)}"]
    if t.time_tolerance_us is not None:
        lines.append(f"time_tolerance_us = {int(t.time_tolerance_us)}")
    if t.loop_rate_hz is not None:
        lines.append(f"loop_rate_hz = {_num(t.loop_rate_hz)}")
    lines.append("")
    for cc in cfg.channels:
        ch = cc.name
        lines += [f"[channels.{ch}]", f"saturation{_unit_suffix(ch)} = {_num(cc.saturation)}",
                  f"stuck_samples = {int(cc.stuck_samples)}", ""]
        for s in cc.stages:
            lines.append(f"[[channels.{ch}.stages]]")
            lines += [f"{k} = {_value(v)}" for k, v in _stage_items(ch, s)]
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


def default_config(
    gyro_model: tuple[float, float, float, float, float] = (1.0, -0.25, 0.0, 1e-10, 1e-8),
) -> ProcessorConfig:
    """The shipped default: gyros wavelet db4 N=256 J=5 forced -> steady-state AR(2)-Kalman
    (a demonstration model (a1, a2, mean_rad_s, q, r): identify yours with ``gyrodrift fit``),
    accelerometers bias removal (bias 0), 400 Hz.

    Examples
    --------
    >>> cfg = default_config()
    >>> [s.type for s in cfg.channel("gx").stages], [s.type for s in cfg.channel("ax").stages]
    (['wavelet', 'ar2_kalman'], ['bias_removal'])
    >>> default_config((0.6, 0.2, 0.0, 1e-9, 1e-7)).channel("gy").stages[1].a1
    0.6
    """
    a1, a2, mean, q, r = gyro_model
    gyro = (
        WaveletStage("db4", 256, 5, "forced"),
        Ar2KalmanStage(a1=a1, a2=a2, mean=mean, q=q, r=r, sigma2=q, steady_state=True),
    )
    chans = [ChannelConfig(name=ch, stages=gyro, saturation=8.0, stuck_samples=50)
             for ch in CHANNEL_NAMES[:3]]
    chans += [ChannelConfig(name=ch, stages=(BiasRemoval(0.0),), saturation=160.0)
              for ch in CHANNEL_NAMES[3:]]
    return ProcessorConfig(
        channels=tuple(chans),
        timing=Timing(sample_rate_hz=400.0, time_tolerance_us=1250, loop_rate_hz=400.0),
        meta=(("written_by", "gyrodrift config write-default"),),
    )
