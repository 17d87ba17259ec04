"""Six-channel IMU processor (gyro x y z rad/s, accel x y z m/s^2): configuration, health flags
and the C++ processor (include/gyrodrift/imu/imu_processor.hpp) over whole records.

`gyrodrift.reference.imu.process_imu` is the numpy reference of the same processor.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.imu.contract import CHANNELS, contract
from gyrodrift.imu.schema import CHANNEL_NAMES, PAPER_WAVELET, field_spec

if TYPE_CHECKING:
    from gyrodrift.imu.config import ProcessorConfig

__all__ = [
    "FILTERS",
    "ImuChannelConfig",
    "ImuConfig",
    "ImuProcessor",
    "ImuResult",
    "WaveletSettings",
]

FILTERS = ("pass_through", "bias_removal", "ar2_kalman", "wavelet")

@dataclass(frozen=True)
class WaveletSettings:
    """Real-time wavelet stage of the wavelet channels (paper 004 sec. 2.2): one setting for
    all of them, or per channel (ImuChannelConfig.wavelet). window: a power of two in
    16..4096 (the configuration format's windows; the C++ stage takes any of them). threshold:
    the detail handling (forced, soft, hard), as in the configuration file. Defaults: the 2014
    paper's stage (gyrodrift.imu.schema.PAPER_WAVELET, db4, N = 256, level 5, forced).

    Examples
    --------
    >>> WaveletSettings(level=4)  # one setting for the processor's wavelet channels
    WaveletSettings(wavelet='db4', window=256, level=4, threshold='forced')
    >>> WaveletSettings(wavelet="db8", threshold="soft")
    WaveletSettings(wavelet='db8', window=256, level=5, threshold='soft')
    """

    wavelet: str = PAPER_WAVELET["wavelet"]
    window: int = PAPER_WAVELET["window"]
    level: int = PAPER_WAVELET["level"]
    threshold: str = PAPER_WAVELET["threshold"]


def _check_wavelet(key: str, ws: WaveletSettings) -> None:
    """One-line ValueError naming `key`.window / `key`.level, in the configuration reader's
    words, for a window outside the format or a level too deep for it."""
    from gyrodrift.imu.config import max_wavelet_level

    n = ws.window
    if not (isinstance(n, (int, np.integer)) and 16 <= n <= 4096 and n & (n - 1) == 0):
        raise GyrodriftValueError(f"{key}.window: expected a power of two in 16..4096, got {n}")
    if ws.wavelet in ("db4", "db8"):
        jmax = max_wavelet_level(n, ws.wavelet)
        if not 1 <= ws.level <= jmax:
            raise GyrodriftValueError(
                f"{key}.level: expected 1..{jmax} for {ws.wavelet} with window {n}, "
                f"got {ws.level}"
            )


@dataclass
class ImuChannelConfig:
    """One channel's chain: `filter` then `filter2` (pass_through: no second stage); a chain
    without a bias_removal stage subtracts `bias` after its last stage (imu/imu_processor.hpp).

    ar2_kalman needs a1, a2, sigma2, mean (the AR(2) model, units of the channel), q and r
    (units^2) and p0 (P_0 = p0 I). saturation: ``|x| >= saturation`` marks the value bad.
    stuck_samples: the N-th identical value in a row is stuck (0 = off).

    Examples
    --------
    >>> ch = ImuChannelConfig(filter="bias_removal", bias=0.01)
    >>> ch.filter, ch.bias
    ('bias_removal', 0.01)
    """

    filter: str = "pass_through"
    bias: float = 0.0
    filter2: str = "pass_through"
    steady_state: bool = field_spec("ar2_kalman", "steady_state").default
    wavelet: WaveletSettings | None = None  # this channel's wavelet stage (None: the shared one)
    # the model and variances: NaN until given (the schema requires them for ar2_kalman)
    a1: float = math.nan
    a2: float = math.nan
    sigma2: float = math.nan
    mean: float = math.nan
    q: float = math.nan
    r: float = math.nan
    p0: float = field_spec("ar2_kalman", "p0").default
    saturation: float = field_spec("channel", "saturation").default
    stuck_samples: int = field_spec("channel", "stuck_samples").default

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
    # nominal sample period and timestamp tolerance (0: check off); defaults from the contract
    period_us: int = field(default_factory=lambda: contract()["default_period_us"])
    time_tolerance_us: int = field(
        default_factory=lambda: contract()["default_time_tolerance_us"]
    )

    def validate(self) -> None:
        if len(self.channels) != CHANNELS:
            raise GyrodriftValueError(
                f"channels: expected {CHANNELS} channel configs, got {len(self.channels)}"
            )
        for i, ch in enumerate(self.channels):
            for name in ("filter", "filter2"):
                if getattr(ch, name) not in FILTERS:
                    raise GyrodriftValueError(
                        f"channels[{i}].{name}: expected one of {FILTERS}, "
                        f"got {getattr(ch, name)!r}"
                    )
            if ch.stuck_samples < 0:
                raise GyrodriftValueError(f"channels[{i}].stuck_samples must be >= 0")
        if not 0 <= self.period_us < 2**32 or not 0 <= self.time_tolerance_us < 2**32:
            raise GyrodriftValueError("period_us and time_tolerance_us must fit in u32")

    @classmethod
    def from_processor_config(
        cls, config: ProcessorConfig | str | os.PathLike[str], float32: bool = False
    ) -> ImuConfig:
        """The processor of a configuration file (gyrodrift.imu.config; a path is read).

        float32: round every parameter to float32 first, as the float loop and firmware store
        them (the reference processor then runs the same model in double).
        """
        from gyrodrift.imu.config import (
            Ar2KalmanStage,
            BiasRemoval,
            ProcessorConfig,
            WaveletStage,
            load_config,
        )

        if not isinstance(config, ProcessorConfig):
            config = load_config(config)

        def num(x: float) -> float:
            return float(np.float32(x)) if float32 else float(x)

        channels = []
        for cc in config.channels:
            types = [st.type for st in cc.stages]
            ch = ImuChannelConfig(
                filter=types[0],
                filter2=types[1] if len(types) > 1 else "pass_through",
                saturation=num(cc.saturation),
                stuck_samples=cc.stuck_samples,
            )
            for st in cc.stages:
                if isinstance(st, BiasRemoval):
                    ch.bias = num(st.bias)
                elif isinstance(st, WaveletStage):
                    ch.wavelet = WaveletSettings(st.wavelet, st.window, st.level, st.threshold)
                elif isinstance(st, Ar2KalmanStage):
                    ch.a1, ch.a2, ch.mean = num(st.a1), num(st.a2), num(st.mean)
                    ch.sigma2, ch.q, ch.r = num(st.sigma2_value), num(st.q), num(st.r)
                    ch.p0, ch.steady_state = num(st.p0), st.steady_state
            channels.append(ch)
        return cls(
            channels=channels,
            period_us=config.timing.period_us,
            time_tolerance_us=config.timing.tolerance_us,
        )


@dataclass
class ImuResult:
    """Outputs for every input row: rejected rows (flags & FLAG_REJECTED) are NaN.

    Examples
    --------
    >>> proc = ImuProcessor(ImuConfig(channels=[ImuChannelConfig() for _ in range(6)]))
    >>> out = proc.process(np.array([0, 1, 1]), np.array([0, 2500, 2500]), np.ones((3, 6)))
    >>> from gyrodrift.imu import contract as imu
    >>> bool(out.flags[2] & imu.FLAG_DUPLICATE), out.accepted, out.health["samples_in"]
    (True, array([ True,  True, False]), 3)
    """

    values: np.ndarray  # (n, 6)
    flags: np.ndarray  # (n,) uint16
    health: dict[str, int]

    @property
    def accepted(self) -> np.ndarray:
        return (self.flags & contract()["flags"]["rejected"]) == 0


def _as_inputs(
    seq: npt.ArrayLike, t_us: npt.ArrayLike, values: npt.ArrayLike, dtype: npt.DTypeLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    raw = np.asarray(values)
    # Refuse what a cast would silently mangle (complex: imaginary part dropped; strings:
    # parsed), as the other array APIs do (gyrodrift.filters.ar2, gyrodrift.filters.wavelet).
    if raw.dtype.kind not in "fiu":
        raise GyrodriftTypeError(
            f"values: expected a real numeric array (float or integer), got dtype {raw.dtype}"
        )
    v = np.ascontiguousarray(raw, dtype=dtype)
    if v.ndim != 2 or v.shape[1] != CHANNELS:
        raise GyrodriftValueError(f"values: expected shape (n, 6), got {v.shape}")
    s = np.asarray(seq)
    t = np.asarray(t_us)
    if s.shape != (v.shape[0],) or t.shape != (v.shape[0],):
        raise GyrodriftValueError(
            f"seq and t_us: expected shape ({v.shape[0]},), got {s.shape} and {t.shape}"
        )
    if not np.issubdtype(s.dtype, np.integer) or not np.issubdtype(t.dtype, np.integer):
        raise GyrodriftTypeError(f"seq and t_us: expected integer arrays, got {s.dtype} and "
                                 f"{t.dtype}")
    if s.size and (s.min() < 0 or s.max() > 0xFFFF):
        raise GyrodriftValueError("seq: values must be in 0..65535")
    if t.size and np.issubdtype(t.dtype, np.signedinteger) and t.min() < 0:
        raise GyrodriftValueError("t_us: timestamps must be >= 0")
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
        config: ImuConfig | ProcessorConfig | str | os.PathLike[str],
        dtype: npt.DTypeLike = np.float64,
        wavelet: WaveletSettings | None = None,
    ) -> None:
        lib = core("imu")
        if not isinstance(config, ImuConfig):  # a configuration file or ProcessorConfig
            config = ImuConfig.from_processor_config(config)
        config.validate()
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.dtype(np.float64), np.dtype(np.float32)):
            raise GyrodriftTypeError(f"dtype: expected float64 or float32, got {self.dtype}")
        cls = lib.ImuProcessor if self.dtype == np.float64 else lib.ImuProcessorF32
        self._proc = cls(settings=self._settings(lib, config, wavelet))
        if self._proc.status != "ok":
            bad = self._proc.bad_channel
            where = f"channels.{CHANNEL_NAMES[bad]}: " if 0 <= bad < len(CHANNEL_NAMES) else ""
            raise GyrodriftValueError(f"{where}invalid IMU processor configuration in "
                                      f"{self.dtype.name}: {self._proc.status}")
        self.config = config

    @staticmethod
    def _settings(lib: Any, config: ImuConfig, wavelet: WaveletSettings | None) -> Any:
        """The binding's configuration object (_core.ImuProcessorSettings), built by keyword.
        A channel whose chain uses the wavelet stage takes its own WaveletSettings, else the
        shared `wavelet`; the others get none. A value the binding refuses is a
        GyrodriftValueError (GyrodriftTypeError for a wrong type) naming the channel."""
        channels = []
        for i, c in enumerate(config.channels):
            uses = "wavelet" in (c.filter, c.filter2)
            ws = (c.wavelet or wavelet) if uses else None
            if uses and ws is None:
                raise GyrodriftValueError(
                    f"channels[{i}] uses the wavelet stage: pass wavelet=WaveletSettings()"
                )
            if ws is not None:
                _check_wavelet(f"channels[{i}].wavelet", ws)
            try:
                stage = None if ws is None else lib.ImuWaveletSettings(
                    wavelet=ws.wavelet, window=ws.window, level=ws.level, threshold=ws.threshold
                )
                settings = lib.ImuChannelSettings(
                    filter=c.filter,
                    filter2=c.filter2,
                    steady_state=bool(c.steady_state),
                    bias=c.bias,
                    a1=c.a1,
                    a2=c.a2,
                    sigma2=c.sigma2,
                    mean=c.mean,
                    q=c.q,
                    r=c.r,
                    p0=c.p0,
                    saturation=c.saturation,
                    stuck_samples=c.stuck_samples,
                    wavelet=stage,
                )
            except ValueError as e:  # the binding's message names the field
                raise GyrodriftValueError(
                    f"invalid IMU processor configuration: channels[{i}]: {e}"
                ) from None
            except TypeError as e:
                raise GyrodriftTypeError(
                    f"invalid IMU processor configuration: channels[{i}]: {e}"
                ) from None
            channels.append(settings)
        return lib.ImuProcessorSettings(
            channels=channels,
            period_us=config.period_us,
            time_tolerance_us=config.time_tolerance_us,
        )

    def process(self, seq: npt.ArrayLike, t_us: npt.ArrayLike, values: npt.ArrayLike) -> ImuResult:
        s, t, v = _as_inputs(seq, t_us, values, self.dtype)
        out, flags = self._proc.process(s, t, v)
        return ImuResult(values=out, flags=flags, health=dict(self._proc.health()))

    @property
    def health(self) -> dict[str, int]:
        return dict(self._proc.health())

    def reset(self) -> None:
        self._proc.reset()
