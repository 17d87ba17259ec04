"""Shared pytest fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = REPO_ROOT.parent / "shared" / "data"


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
