"""The package's public surface (issue 9): `__all__` everywhere public, `help(gyrodrift)` lists
the API, and `import gyrodrift` does not pull in the replay area's dependencies."""

from __future__ import annotations

import importlib
import os
import pkgutil
import pydoc
import subprocess
import sys

import gyrodrift
import pytest


def test_import_gyrodrift_does_not_import_replay_dependencies() -> None:
    # A fresh interpreter: this test process may already hold them.
    code = ("import sys, gyrodrift\n"
            "heavy = {'can', 'cantools', 'serial', 'dask', 'rosbags', 'matplotlib'}\n"
            "print(sorted(heavy & set(sys.modules)))\n"
            "gyrodrift.fit_ar2, gyrodrift.simulate, gyrodrift.oadev\n"
            "print(sorted(heavy & set(sys.modules)))\n"
            "gyrodrift.ReplayOptions\n"
            "print(sorted({'can', 'cantools', 'serial'} & set(sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=os.environ.copy(), check=True).stdout.splitlines()
    assert out == ["[]", "[]", "['can', 'cantools', 'serial']"]


def test_help_lists_the_api() -> None:
    text = pydoc.render_doc(gyrodrift, renderer=pydoc.plaintext)
    for name in ("fit_ar2", "kalman_filter", "simulate", "RealtimeWavelet", "forced_fir_taps",
                 "oadev", "welch_psd", "load_record", "ImuProcessor", "run_alignment",
                 "GyrodriftError", "run_replay", "read_imu_log"):
        assert name in gyrodrift.__all__, name
        assert f"\n    {name}" in text or f" {name}(" in text or f"class {name}" in text, name
    for name in gyrodrift.__all__:
        assert getattr(gyrodrift, name) is not None, name


def _public_modules() -> list[str]:
    names = []
    for info in pkgutil.walk_packages(gyrodrift.__path__, "gyrodrift."):
        parts = info.name.split(".")
        if any(p.startswith("_") for p in parts[1:]) or parts[-1] == "__main__":
            continue
        names.append(info.name)
    return sorted(set(names))


@pytest.mark.parametrize("name", _public_modules())
def test_every_public_module_has_all(name: str) -> None:
    mod = importlib.import_module(name)
    assert hasattr(mod, "__all__"), f"{name} has no __all__"
    for item in mod.__all__:
        assert hasattr(mod, item), f"{name}.__all__ names {item!r}, which it does not define"
