"""Six-channel IMU processor (gyro x y z rad/s, accel x y z m/s^2): configuration, health flags
and the C++ processor (include/gyrodrift/imu_processor.hpp) over whole records.

`gyrodrift.reference.imu.process_imu` is the numpy reference of the same processor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from gyrodrift import _native

__all__ = [
    "CHANNELS",
    "FILTERS",
    "FLAG_CONFIG_ERROR",
    "FLAG_DUPLICATE",
    "FLAG_FILTER_FAULT",
    "FLAG_NAMES",
    "FLAG_NON_FINITE",
    "FLAG_OUT_OF_ORDER",
    "FLAG_REJECTED",
    "FLAG_RESYNC",
    "FLAG_SATURATED",
    "FLAG_SEQ_GAP",
    "FLAG_STUCK",
    "FLAG_TIME_JUMP",
    "HEALTH_KEYS",
    "RESYNC_AFTER",
    "ImuChannelConfig",
    "ImuConfig",
    "ImuProcessor",
    "ImuResult",
    "WaveletSettings",
    "describe_flags",
]

CHANNELS = 6
FILTERS = ("pass_through", "bias_removal", "ar2_kalman", "wavelet")

# Per-sample health flags (u16 `flags` of output frames), as in imu_processor.hpp.
FLAG_NON_FINITE = 1 << 0
FLAG_SATURATED = 1 << 1
FLAG_STUCK = 1 << 2
FLAG_SEQ_GAP = 1 << 3
FLAG_DUPLICATE = 1 << 4
FLAG_OUT_OF_ORDER = 1 << 5
FLAG_TIME_JUMP = 1 << 6
FLAG_FILTER_FAULT = 1 << 7
FLAG_RESYNC = 1 << 8
FLAG_CONFIG_ERROR = 1 << 14
FLAG_REJECTED = 1 << 15
FLAG_NAMES = {
    FLAG_NON_FINITE: "non_finite",
    FLAG_SATURATED: "saturated",
    FLAG_STUCK: "stuck",
    FLAG_SEQ_GAP: "seq_gap",
    FLAG_DUPLICATE: "duplicate",
    FLAG_OUT_OF_ORDER: "out_of_order",
    FLAG_TIME_JUMP: "time_jump",
    FLAG_FILTER_FAULT: "filter_fault",
    FLAG_RESYNC: "resync",
    FLAG_CONFIG_ERROR: "config_error",
    FLAG_REJECTED: "rejected",
}
RESYNC_AFTER = 8  # the 8th consecutive would-be rejection is accepted as a source restart

HEALTH_KEYS = (
    "samples_in",
    "samples_accepted",
    "duplicates",
    "out_of_order",
    "config_rejected",
    "seq_gaps",
    "missing_samples",
    "seq_resyncs",
    "time_jumps",
    "non_finite_samples",
    "non_finite_values",
    "saturated_values",
    "stuck_values",
    "filter_faults",
)


def describe_flags(flags: int) -> list[str]:
    """Names of the bits set in a flags word."""
    return [name for bit, name in FLAG_NAMES.items() if flags & bit]


@dataclass
class ImuChannelConfig:
    """One channel's chain: y = stage(x) - bias (see imu_processor.hpp).

    ar2_kalman needs a1, a2, sigma2, mean (the AR(2) model, units of the channel), q and r
    (units^2) and p0 (P_0 = p0 I). saturation: |x| >= saturation marks the value bad.
    stuck_samples: the N-th identical value in a row is stuck (0 = off).

    Examples
    --------
    >>> ch = ImuChannelConfig(filter="bias_removal", bias=0.01)
    >>> ch.filter, ch.bias
    ('bias_removal', 0.01)
    """

    filter: str = "pass_through"
    bias: float = 0.0
    a1: float = math.nan
    a2: float = math.nan
    sigma2: float = math.nan
    mean: float = math.nan
    q: float = math.nan
    r: float = math.nan
    p0: float = 1.0
    saturation: float = math.inf
    stuck_samples: int = 0

    @classmethod
    def ar2_kalman(
        cls, model: Any, q: float | None = None, r: float | None = None, **kw: Any
    ) -> ImuChannelConfig:
        """From a gyrodrift.Ar2Model (q defaults to model.sigma2, r to model.r)."""
        q_val = float(model.sigma2) if q is None else float(q)
        r_val = float(getattr(model, "r", math.nan)) if r is None else float(r)
        return cls(
            filter="ar2_kalman",
            a1=float(model.a1),
            a2=float(model.a2),
            sigma2=float(model.sigma2),
            mean=float(model.mean),
            q=q_val,
            r=r_val,
            **kw,
        )


@dataclass(frozen=True)
class WaveletSettings:
    """Real-time wavelet stage of the wavelet channels (paper 004 sec. 2.2): one setting for
    all of them. The C++ processor is built with a 256-sample window."""

    wavelet: str = "db8"
    window: int = 256
    level: int = 5
    mode: str = "forced"


def _default_channels() -> list[ImuChannelConfig]:
    return [ImuChannelConfig(filter="ar2_kalman") for _ in range(3)] + [
        ImuChannelConfig() for _ in range(3)
    ]


@dataclass
class ImuConfig:
    """Processor configuration. Gyros default to ar2_kalman (a model must be supplied).

    Examples
    --------
    >>> cfg = ImuConfig(channels=[ImuChannelConfig() for _ in range(6)])
    >>> cfg.validate()
    >>> cfg.period_us
    2500
    """

    channels: list[ImuChannelConfig] = field(default_factory=_default_channels)
    period_us: int = 2500  # nominal sample period (400 Hz)
    time_tolerance_us: int = 1250  # 0: timestamp check off

    def validate(self) -> None:
        if len(self.channels) != CHANNELS:
            raise ValueError(
                f"channels: expected {CHANNELS} channel configs, got {len(self.channels)}"
            )
        for i, ch in enumerate(self.channels):
            if ch.filter not in FILTERS:
                raise ValueError(
                    f"channels[{i}].filter: expected one of {FILTERS}, got {ch.filter!r}"
                )
            if ch.stuck_samples < 0:
                raise ValueError(f"channels[{i}].stuck_samples must be >= 0")
        if not 0 <= self.period_us < 2**32 or not 0 <= self.time_tolerance_us < 2**32:
            raise ValueError("period_us and time_tolerance_us must fit in u32")


@dataclass
class ImuResult:
    """Outputs for every input row: rejected rows (flags & FLAG_REJECTED) are NaN."""

    values: np.ndarray  # (n, 6)
    flags: np.ndarray  # (n,) uint16
    health: dict[str, int]

    @property
    def accepted(self) -> np.ndarray:
        return (self.flags & FLAG_REJECTED) == 0


def _as_inputs(
    seq: npt.ArrayLike, t_us: npt.ArrayLike, values: npt.ArrayLike, dtype: npt.DTypeLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v = np.ascontiguousarray(values, dtype=dtype)
    if v.ndim != 2 or v.shape[1] != CHANNELS:
        raise ValueError(f"values: expected shape (n, 6), got {v.shape}")
    s = np.asarray(seq)
    t = np.asarray(t_us)
    if s.shape != (v.shape[0],) or t.shape != (v.shape[0],):
        raise ValueError(
            f"seq and t_us: expected shape ({v.shape[0]},), got {s.shape} and {t.shape}"
        )
    if not np.issubdtype(s.dtype, np.integer) or not np.issubdtype(t.dtype, np.integer):
        raise TypeError(f"seq and t_us: expected integer arrays, got {s.dtype} and {t.dtype}")
    if s.size and (s.min() < 0 or s.max() > 0xFFFF):
        raise ValueError("seq: values must be in 0..65535")
    if t.size and np.issubdtype(t.dtype, np.signedinteger) and t.min() < 0:
        raise ValueError("t_us: timestamps must be >= 0")
    return (
        np.ascontiguousarray(s, dtype=np.uint16),
        np.ascontiguousarray(t, dtype=np.uint64),
        v,
    )


class ImuProcessor:
    """The C++ ImuProcessor (float64 or float32) over whole records, stateful across calls.

    Examples
    --------
    >>> cfg = ImuConfig(channels=[ImuChannelConfig() for _ in range(6)])  # pass-through
    >>> proc = ImuProcessor(cfg)
    >>> out = proc.process(np.arange(3), np.arange(3) * 2500, np.ones((3, 6)))
    >>> out.values.shape, bool(out.accepted.all())
    ((3, 6), True)
    """

    def __init__(
        self,
        config: ImuConfig,
        dtype: npt.DTypeLike = np.float64,
        wavelet: WaveletSettings | None = None,
    ) -> None:
        _core = _native.core("imu", "ImuProcessor")

        config.validate()
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.dtype(np.float64), np.dtype(np.float32)):
            raise TypeError(f"dtype: expected float64 or float32, got {self.dtype}")
        f64 = self.dtype == np.float64
        ch = config.channels
        extra: tuple[object, ...] = ()
        if any(c.filter == "wavelet" for c in ch):
            if wavelet is None:
                raise ValueError("a channel uses the wavelet stage: pass wavelet=WaveletSettings()")
            if wavelet.window != 256:
                raise ValueError(
                    f"wavelet.window: the C++ stage has 256 samples, got {wavelet.window}"
                )
            cls = _core.ImuProcessorWavelet if f64 else _core.ImuProcessorWaveletF32
            extra = (wavelet.wavelet, wavelet.level, wavelet.mode)
        else:
            cls = _core.ImuProcessor if f64 else _core.ImuProcessorF32
        self._proc = cls(
            [FILTERS.index(c.filter) for c in ch],
            [c.bias for c in ch],
            [c.a1 for c in ch],
            [c.a2 for c in ch],
            [c.sigma2 for c in ch],
            [c.mean for c in ch],
            [c.q for c in ch],
            [c.r for c in ch],
            [c.p0 for c in ch],
            [c.saturation for c in ch],
            [c.stuck_samples for c in ch],
            config.period_us,
            config.time_tolerance_us,
            *extra,
        )
        if self._proc.status != "ok":
            where = f" (channel {self._proc.bad_channel})" if self._proc.bad_channel >= 0 else ""
            raise ValueError(f"invalid IMU processor configuration: {self._proc.status}{where}")
        self.config = config

    def process(self, seq: npt.ArrayLike, t_us: npt.ArrayLike, values: npt.ArrayLike) -> ImuResult:
        s, t, v = _as_inputs(seq, t_us, values, self.dtype)
        out, flags = self._proc.process(s, t, v)
        return ImuResult(values=out, flags=flags, health=dict(self._proc.health()))

    @property
    def health(self) -> dict[str, int]:
        return dict(self._proc.health())

    def reset(self) -> None:
        self._proc.reset()
