"""One processor configuration, given to both sides of a replay: the loop program's command
line (cpp/programs/gyrodrift-loop/processing.hpp) and the reference processor's ImuConfig
(gyrodrift.reference.imu.process_imu), so the two run the same chain.

With a configuration file (``ProcessorSettings.from_config``) the loop gets ``--config`` with
the file's canonical text and the reference reads the same configuration."""

from __future__ import annotations

import hashlib
import math
import tempfile
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig

if TYPE_CHECKING:
    from gyrodrift.imu.config import ProcessorConfig

__all__ = [
    "LOOP_FILTERS",
    "ProcessorSettings",
]

LOOP_FILTERS = ("ar2_kalman", "bias_removal", "pass_through")


def _demo_ar2(key: str) -> float:
    """One number of the loop's demonstration AR(2) model (C++ ImuDemoAr2, via _core)."""
    from gyrodrift._native import core

    return float(core("imu").IMU_DEMO_AR2[key])


@dataclass(frozen=True)
class ProcessorSettings:
    """Gyro chain (all three axes) and accelerometer chain (all three axes).

    The AR(2) default (a1=1.0, a2=-0.25: a double root at 0.5, stationary; sigma2, q, r in
    (rad/s)^2) is a demonstration model; identify the real gyro with gyrodrift.fit_ar2.

    Examples
    --------
    >>> p = ProcessorSettings(gyro_filter="bias_removal", gyro_bias=0.01, sample_rate_hz=200.0)
    >>> p.period_us, p.tolerance_us, p.loop_args()[:4]
    (5000, 2500, ['--gyro-filter', 'bias_removal', '--accel-filter', 'pass_through'])
    >>> ProcessorSettings(gyro_filter="median")
    Traceback (most recent call last):
    ...
    gyrodrift.errors.GyrodriftValueError: gyro_filter must be one of (...), got 'median'
    """

    gyro_filter: str = "ar2_kalman"
    accel_filter: str = "pass_through"
    # The demonstration model's numbers live once, in imu/imu_processor.hpp (ImuDemoAr2).
    a1: float = field(default_factory=lambda: _demo_ar2("a1"))
    a2: float = field(default_factory=lambda: _demo_ar2("a2"))
    sigma2: float = field(default_factory=lambda: _demo_ar2("sigma2"))
    mean: float = field(default_factory=lambda: _demo_ar2("mean"))
    q: float = field(default_factory=lambda: _demo_ar2("q"))
    r: float = field(default_factory=lambda: _demo_ar2("r"))
    gyro_bias: float = 0.0
    accel_bias: float = 0.0
    gyro_saturation: float = math.inf
    accel_saturation: float = math.inf
    stuck_samples: int = 0
    sample_rate_hz: float = 400.0
    time_tolerance_us: int = -1  # -1: half a sample period
    config: ProcessorConfig | None = None  # a configuration file's processor (overrides all)

    @classmethod
    def from_config(cls, config: ProcessorConfig | str | Path) -> ProcessorSettings:
        """Settings that run the processor of a configuration file (or ProcessorConfig)."""
        from gyrodrift.imu.config import ProcessorConfig, load_config

        cfg = config if isinstance(config, ProcessorConfig) else load_config(config)
        return cls(sample_rate_hz=cfg.timing.sample_rate_hz,
                   time_tolerance_us=cfg.timing.tolerance_us, config=cfg)

    def with_sample_rate(self, rate_hz: float) -> ProcessorSettings:
        return replace(self, sample_rate_hz=rate_hz)

    def __post_init__(self) -> None:
        for name in ("gyro_filter", "accel_filter"):
            if getattr(self, name) not in LOOP_FILTERS:
                raise GyrodriftValueError(f"{name} must be one of {LOOP_FILTERS}, "
                                          f"got {getattr(self, name)!r}")
        if not (self.sample_rate_hz > 0 and math.isfinite(self.sample_rate_hz)):
            raise GyrodriftValueError(f"sample_rate_hz must be > 0, got {self.sample_rate_hz}")

    @property
    def period_us(self) -> int:
        return round(1e6 / self.sample_rate_hz)

    @property
    def tolerance_us(self) -> int:
        if self.time_tolerance_us >= 0:
            return self.time_tolerance_us
        return math.floor(1e6 / self.sample_rate_hz / 2.0 + 0.5)  # C++ lround

    def loop_args(self) -> list[str]:
        """The gyrodrift-loop options for this configuration (repr() keeps every digit)."""
        if self.config is not None:
            return ["--config", str(self._config_file())]
        def num(x: float) -> str:
            return "inf" if math.isinf(x) else repr(float(x))

        return [
            "--gyro-filter", self.gyro_filter, "--accel-filter", self.accel_filter,
            "--gyro-ar2", ",".join(repr(float(v)) for v in (self.a1, self.a2, self.sigma2,
                                                            self.mean)),
            "--gyro-q", repr(float(self.q)), "--gyro-r", repr(float(self.r)),
            "--gyro-bias", repr(float(self.gyro_bias)),
            "--accel-bias", repr(float(self.accel_bias)),
            "--gyro-saturation", num(self.gyro_saturation),
            "--accel-saturation", num(self.accel_saturation),
            "--stuck-samples", str(int(self.stuck_samples)),
            "--sample-rate-hz", repr(float(self.sample_rate_hz)),
            "--time-tolerance-us", str(self.tolerance_us),
        ]

    def _config_file(self) -> Path:
        """The configuration's canonical text in a content-named temporary file (the loop's
        reader takes the canonical TOML subset, whatever layout the user's file has)."""
        from gyrodrift.imu.config import dumps_config, write_config

        assert self.config is not None
        text = dumps_config(self.config)
        digest = hashlib.sha256(text.encode()).hexdigest()[:16]
        path = Path(tempfile.gettempdir()) / f"gyrodrift-config-{digest}.toml"
        if not path.exists():
            write_config(self.config, path)
        return path

    def imu_config(self) -> ImuConfig:
        """The same chain as an ImuConfig for the reference processor. The loop stores every
        parameter as float32, so the reference gets the float32-rounded values too."""
        if self.config is not None:
            return ImuConfig.from_processor_config(self.config, float32=True)
        def f32(x: float) -> float:
            import numpy as np

            return float(np.float32(x))

        channels = []
        for c in range(6):
            gyro = c < 3
            channels.append(ImuChannelConfig(
                filter=self.gyro_filter if gyro else self.accel_filter,
                bias=f32(self.gyro_bias if gyro else self.accel_bias),
                a1=f32(self.a1), a2=f32(self.a2), sigma2=f32(self.sigma2), mean=f32(self.mean),
                q=f32(self.q), r=f32(self.r), p0=1.0,
                saturation=f32(self.gyro_saturation if gyro else self.accel_saturation),
                stuck_samples=int(self.stuck_samples),
            ))
        return ImuConfig(channels=channels, period_us=self.period_us,
                         time_tolerance_us=self.tolerance_us)

    def to_dict(self) -> dict[str, object]:
        if self.config is not None:
            return {"config": self.config.as_dict()}
        return asdict(self)
