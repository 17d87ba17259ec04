"""The wheel installs gyrodrift-loop (issue 12): `pip wheel .` builds a wheel whose scripts
directory holds the loop program, and a replay from a fresh virtual environment holding only
that wheel (no source tree, no build tree, no PYTHONPATH) finds the loop and passes.

The fresh venv has no site packages of the system; its dependencies (numpy, scipy, python-can,
...) come from the shared test venv through a .pth file appended AFTER the venv's own
site-packages, and the test checks that `gyrodrift` and `gyrodrift-loop` resolve to the venv's
copies (this machine has no network to install the dependencies from an index). One test: the
wheel build compiles the whole extension (minutes; scikit-build-core keeps its build tree under
build/, so a rebuild is incremental).
"""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_wheel_contains_loop_and_replays_from_a_clean_venv(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "GYRODRIFT_LOOP", "GYRODRIFT_CPP_BUILD_DIR")}
    env.setdefault("CMAKE_BUILD_PARALLEL_LEVEL", "2")
    dist = tmp_path / "dist"
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "--no-build-isolation",
         "-w", str(dist), "-q"],
        capture_output=True, text=True, env=env, timeout=1800, check=False)
    assert build.returncode == 0, build.stderr[-4000:]
    wheels = list(dist.glob("gyrodrift-*.whl"))
    assert len(wheels) == 1
    names = zipfile.ZipFile(wheels[0]).namelist()
    loop = [n for n in names if n.endswith(".data/scripts/gyrodrift-loop")]
    assert loop, "gyrodrift-loop is not in the wheel's scripts directory"

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(system_site_packages=False, with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_path("
                                "'purelib'))"], capture_output=True, text=True,
                               check=True).stdout.strip())
    # Install first: with the .pth in place pip would see the shared venv's gyrodrift as
    # "already satisfied".
    inst = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "--no-index",
         str(wheels[0]), "-q"], capture_output=True, text=True, env=env, timeout=600,
        check=False)
    assert inst.returncode == 0, inst.stderr[-3000:]
    assert (env_dir / "bin" / "gyrodrift-loop").is_file()
    (site / "zz_shared_deps.pth").write_text(sysconfig.get_path("purelib") + "\n")
    clean = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "LANG": "C.UTF-8"}
    where = subprocess.run(
        [str(py), "-c", "import gyrodrift, gyrodrift._core; "
         "from gyrodrift.replay.harness import find_loop_binary; "
         "print(gyrodrift.__file__); print(find_loop_binary())"],
        capture_output=True, text=True, env=clean, cwd=tmp_path, timeout=120, check=False)
    assert where.returncode == 0, where.stderr[-3000:]
    pkg, found = where.stdout.split()
    assert pkg.startswith(str(env_dir)) and found == str(env_dir / "bin" / "gyrodrift-loop")
    rep = subprocess.run(
        [str(env_dir / "bin" / "gyrodrift"), "replay", "--fast", "--no-rt", "--duration-s", "1",
         "--fault-drop", "0.02", "--out-dir", str(tmp_path / "rep")],
        capture_output=True, text=True, env=clean, cwd=tmp_path, timeout=600, check=False)
    assert rep.returncode == 0, rep.stdout[-3000:] + rep.stderr[-3000:]
    assert "PASS" in rep.stdout
