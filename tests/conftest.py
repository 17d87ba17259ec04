"""Shared pytest fixtures."""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = REPO_ROOT.parent / "shared" / "data"

# A run started with SIGINT ignored (a background command of a shell without job control, such
# as `nohup pytest &` in a script) passes that on to every program the tests start, and Python
# then installs no Ctrl-C handler in them: the Ctrl-C tests would fail. Restore Python's own.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture()
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


@pytest.fixture(scope="session")
def cpp_build_dir() -> Path:
    """The CMake build with the C++ programs (scripts/test sets GYRODRIFT_CPP_BUILD_DIR)."""
    value = os.environ.get("GYRODRIFT_CPP_BUILD_DIR")
    if not value:
        raise RuntimeError(
            "GYRODRIFT_CPP_BUILD_DIR is not set: run the suite through scripts/test, or "
            "eval the last line of scripts/dev-build NAME first"
        )
    path = Path(value)
    if not path.is_dir():
        raise RuntimeError(f"GYRODRIFT_CPP_BUILD_DIR={path} does not exist")
    return path


@pytest.fixture(scope="session")
def pass_through_config(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., Path]:
    """A processor configuration file with pass-through on every channel (outputs = inputs,
    bit-exact float32), for the tests that start gyrodrift-loop directly: the loop takes its
    processor and its rates only from a configuration. ``pass_through_config(sample_rate_hz,
    loop_rate_hz)`` returns the file's path (written once per pair of rates)."""
    from gyrodrift.imu.config import (
        CHANNEL_NAMES,
        ChannelConfig,
        PassThrough,
        ProcessorConfig,
        Timing,
        write_config,
    )

    made: dict[tuple[float, float], Path] = {}

    def make(sample_rate_hz: float = 1000.0, loop_rate_hz: float = 1000.0) -> Path:
        key = (sample_rate_hz, loop_rate_hz)
        if key not in made:
            cfg = ProcessorConfig(
                channels=tuple(ChannelConfig(ch, (PassThrough(),)) for ch in CHANNEL_NAMES),
                timing=Timing(sample_rate_hz, loop_rate_hz=loop_rate_hz),
                meta=(("written_by", "tests/conftest.py pass_through_config"),))
            name = f"pass_through_{sample_rate_hz:g}hz_loop_{loop_rate_hz:g}hz.toml"
            made[key] = write_config(cfg, tmp_path_factory.mktemp("config") / name)
        return made[key]

    return make


def skip_unless_ci(reason: str) -> None:
    """An optional input is missing: skip on a developer machine, fail in CI.

    CI (CI=true) runs scripts/test, which builds every C++ variant, with shared/ beside the
    checkout, so there a missing input is a broken set-up, never a reason to skip.
    """
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        pytest.fail(f"required in CI: {reason}")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def lasergyro_path() -> Path:
    """The shared real ring-laser-gyro record (PSINS lasergyro.imu; see shared/data/README.md)."""
    path = SHARED_DATA / "lasergyro.imu"
    if not path.is_file():
        skip_unless_ci(f"shared real-data record {path} not present")
    return path
