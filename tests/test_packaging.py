"""Packaging: the Python package as users get it, and the C++ core as CMake consumers get it.

Python side: the `gyrodrift` console script (or, in a development tree where the package is not
installed, the declared entry point) runs `--help` and every subcommand's `--help`; the
compiled `gyrodrift._core` and `gyrodrift.reference` import; an installed package contains
every module and data file of python/gyrodrift (catches files a wheel would silently drop).

C++ side: a tiny external CMake project in a temporary directory consumes the INTERFACE target
`gyrodrift::gyrodrift`, once through add_subdirectory() and once through find_package() after
`cmake --install` into a temporary prefix, includes every public header, builds and runs.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.machinery
import importlib.metadata
import shutil
import subprocess
import sys
from pathlib import Path

import gyrodrift
import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # pytest depends on tomli before 3.11
    import tomli as tomllib

REPO_ROOT = Path(__file__).resolve().parent.parent
SOURCE_PKG = REPO_ROOT / "python" / "gyrodrift"
PUBLIC_HEADERS = sorted((REPO_ROOT / "include" / "gyrodrift").rglob("*.hpp"))


def _run(cmd: list[str], cwd: Path | None = None, timeout: float = 600) -> str:
    proc = subprocess.run(
        cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout, check=False
    )
    assert proc.returncode == 0, f"{' '.join(cmd)} failed ({proc.returncode}):\n" + (
        proc.stdout[-3000:] + proc.stderr[-3000:]
    )
    return proc.stdout


def _installed() -> bool:
    """True when `gyrodrift` is imported from an installed distribution, not from python/."""
    pkg_dir = Path(gyrodrift.__file__).resolve().parent
    return pkg_dir != SOURCE_PKG.resolve()


def _subcommands() -> list[str]:
    """Subcommand names as registered by the modules in gyrodrift.cli.SUBCOMMAND_MODULES."""
    from gyrodrift.cli import SUBCOMMAND_MODULES, build_parser

    parser = build_parser()
    names = [
        name
        for action in parser._actions
        if isinstance(action, argparse._SubParsersAction)
        for name in action.choices
    ]
    assert len(names) >= len(SUBCOMMAND_MODULES), (names, SUBCOMMAND_MODULES)
    return names


# --- Python package ------------------------------------------------------------------------


def test_entry_point_declared_and_resolves() -> None:
    scripts = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["gyrodrift"] == "gyrodrift.cli:main"
    module_name, func_name = scripts["gyrodrift"].split(":")
    assert callable(getattr(importlib.import_module(module_name), func_name))
    if _installed():
        eps = importlib.metadata.entry_points(group="console_scripts", name="gyrodrift")
        assert [ep.value for ep in eps] == ["gyrodrift.cli:main"]


def test_console_script_help() -> None:
    if _installed():
        script = Path(sys.executable).parent / "gyrodrift"
        script_path = str(script) if script.exists() else shutil.which("gyrodrift")
        assert script_path, "installed package but no `gyrodrift` console script"
        cmd = [script_path]
    else:  # development tree: the same entry function through `python -m gyrodrift`
        cmd = [sys.executable, "-m", "gyrodrift"]
    out = _run([*cmd, "--help"])
    assert "usage: gyrodrift" in out
    for name in _subcommands():
        assert name in out, f"subcommand {name} missing from --help"


@pytest.mark.parametrize("name", _subcommands())
def test_subcommand_help(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    from gyrodrift.cli import main

    with pytest.raises(SystemExit) as exc:  # argparse exits 0 after printing help
        main([name, "--help"])
    assert exc.value.code == 0
    assert f"gyrodrift {name}" in capsys.readouterr().out


def test_no_command_prints_help_and_exit_2() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "gyrodrift"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 2 and "usage: gyrodrift" in proc.stdout


def test_core_extension_imports() -> None:
    core = importlib.import_module("gyrodrift._core")
    assert core.__version__ == gyrodrift.__version__
    suffixes = tuple(importlib.machinery.EXTENSION_SUFFIXES)
    assert str(core.__file__).endswith(suffixes)
    if _installed():  # the wheel puts it inside the package
        assert Path(core.__file__).resolve().parent == Path(gyrodrift.__file__).resolve().parent


def test_reference_package_exists() -> None:
    ref = importlib.import_module("gyrodrift.reference")
    assert ref.__file__ is not None and Path(ref.__file__).name == "__init__.py"
    assert ref.__doc__ and "reference" in ref.__doc__.lower()


def test_version_matches_project_metadata() -> None:
    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]
    assert gyrodrift.__version__ == project["version"]
    if _installed():
        assert importlib.metadata.version("gyrodrift") == project["version"]


def _package_source_files() -> set[str]:
    """Files a wheel built from python/gyrodrift must carry: like scikit-build-core, every file
    not ignored by git (tracked or not); without git, every file outside __pycache__."""
    git = shutil.which("git")
    if git and (REPO_ROOT / ".git").exists():
        out = _run(
            [
                git,
                "ls-files",
                "--cached",
                "--others",
                "--exclude-standard",
                "--",
                "python/gyrodrift",
            ],
            cwd=REPO_ROOT,
        )
        return {
            Path(line).relative_to("python/gyrodrift").as_posix()
            for line in out.splitlines()
            if line and (REPO_ROOT / line).is_file()
        }
    return {
        p.relative_to(SOURCE_PKG).as_posix()
        for p in SOURCE_PKG.rglob("*")
        if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc"
    }


def test_installed_package_is_complete() -> None:
    """Every source module and data file of python/gyrodrift is importable from where the
    package actually lives (identical set of files when installed)."""
    source_files = _package_source_files()
    assert "simulation/records.py" in source_files and "reference/__init__.py" in source_files
    pkg_dir = Path(gyrodrift.__file__).resolve().parent
    present = {f for f in source_files if (pkg_dir / f).is_file()}
    assert present == source_files, f"missing from {pkg_dir}: {sorted(source_files - present)}"
    for rel in sorted(source_files):
        if rel.endswith(".py") and not rel.endswith("__main__.py"):
            module = "gyrodrift." + rel[:-3].replace("/", ".").removesuffix(".__init__")
            importlib.import_module(module.removesuffix(".__init__"))


# --- C++ CMake consumers -------------------------------------------------------------------

CONSUMER_MAIN = """
// Includes every public header through the consumer's include path and uses Eigen through the
// imported dependency: proves gyrodrift::gyrodrift carries include dirs, Eigen and C++17.
{includes}
#include <cstdio>
int main() {{
  Eigen::Matrix2f a = Eigen::Matrix2f::Identity();
  std::printf("consumer ok %.1f\\n", static_cast<double>(a.trace()));
  return 0;
}}
"""


def _consumer_project(root: Path, cmake_body: str) -> Path:
    src = root / "consumer"
    src.mkdir(parents=True)
    includes = "\n".join(
        f"#include <{h.relative_to(REPO_ROOT / 'include').as_posix()}>" for h in PUBLIC_HEADERS
    )
    (src / "main.cpp").write_text(CONSUMER_MAIN.format(includes=includes))
    (src / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.18)\nproject(consumer LANGUAGES CXX)\n"
        + cmake_body
        + "add_executable(consumer main.cpp)\n"
        "target_link_libraries(consumer PRIVATE gyrodrift::gyrodrift)\n"
    )
    return src


def _build_and_run(src: Path, build: Path, extra: list[str]) -> None:
    cmake = shutil.which("cmake")
    assert cmake, "cmake not found"
    _run([cmake, "-S", str(src), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release", *extra])
    _run([cmake, "--build", str(build), "-j", "2"])
    out = _run([str(build / "consumer")])
    assert out.strip() == "consumer ok 2.0"


def test_cmake_consumer_add_subdirectory(tmp_path: Path) -> None:
    assert PUBLIC_HEADERS
    src = _consumer_project(
        tmp_path, f'add_subdirectory("{REPO_ROOT.as_posix()}" gyrodrift-build)\n'
    )
    _build_and_run(src, tmp_path / "build", [])


def test_cmake_consumer_find_package_after_install(tmp_path: Path) -> None:
    cmake = shutil.which("cmake")
    assert cmake, "cmake not found"
    prefix = tmp_path / "prefix"
    lib_build = tmp_path / "gyrodrift-build"
    _run(
        [
            cmake,
            "-S",
            str(REPO_ROOT),
            "-B",
            str(lib_build),
            "-DGYRODRIFT_BUILD_PYTHON=OFF",
            "-DGYRODRIFT_BUILD_TESTS=OFF",
            "-DGYRODRIFT_BUILD_PROGRAMS=OFF",
        ]
    )
    _run([cmake, "--install", str(lib_build), "--prefix", str(prefix)])
    for header in PUBLIC_HEADERS:
        rel = header.relative_to(REPO_ROOT / "include")
        assert (prefix / "include" / rel).is_file(), rel
    configs = list(prefix.rglob("gyrodriftConfig.cmake"))
    assert len(configs) == 1
    src = _consumer_project(tmp_path, "find_package(gyrodrift 0.1 CONFIG REQUIRED)\n")
    _build_and_run(src, tmp_path / "build", [f"-DCMAKE_PREFIX_PATH={prefix}"])
