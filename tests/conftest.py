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
