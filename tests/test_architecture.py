"""The package's architecture holds: areas import only the areas below them (the order is
written once, in pyproject.toml [tool.importlinter], and checked by import-linter), no import
circles between modules, the command line is imported by nothing in the library, no private
name is imported across modules, library modules neither parse arguments nor print, and the
library never imports the root package (whose ``__init__`` re-exports from every area)."""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import grimp
import gyrodrift
import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGE = Path(gyrodrift.__file__).resolve().parent
# The top of the architecture: the command line and the module that runs it.
FRONT_ENDS = ("gyrodrift.cli", "gyrodrift.__main__")


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _library_modules() -> list[tuple[str, Path]]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        name = _module_name(path)
        if name != "gyrodrift" and not name.startswith(FRONT_ENDS):
            out.append((name, path))
    return out


def _lint_imports(cwd: Path, pythonpath: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(pythonpath)}
    script = ("import sys; from importlinter.cli import lint_imports; "
              "sys.exit(lint_imports(config_filename='pyproject.toml'))")
    return subprocess.run([sys.executable, "-c", script], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def test_areas_import_only_the_areas_below_them() -> None:
    res = _lint_imports(REPO, PACKAGE.parent)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "1 kept, 0 broken" in res.stdout


def test_the_layer_contract_fails_on_an_upward_import(tmp_path: Path) -> None:
    # The same contract on a copy of the package with one upward import added (an algorithm
    # that imports the command line) must fail and name the import.
    copy = tmp_path / "src" / "gyrodrift"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("*.so", "__pycache__"))
    edf = copy / "stability" / "edf.py"
    edf.write_text(edf.read_text() + "\nfrom gyrodrift.cli import common  # noqa\n")
    shutil.copy(REPO / "pyproject.toml", tmp_path / "pyproject.toml")
    res = _lint_imports(tmp_path, tmp_path / "src")
    assert res.returncode != 0
    assert "gyrodrift.stability.edf -> gyrodrift.cli.common" in res.stdout


def test_no_import_circles() -> None:
    graph = grimp.build_graph("gyrodrift", exclude_type_checking_imports=True)
    circles = []
    for module in sorted(graph.modules):
        for imported in graph.find_modules_directly_imported_by(module):
            if imported != module and graph.chain_exists(importer=imported, imported=module):
                circles.append(f"{module} -> {imported} -> ... -> {module}")
    assert not circles, "\n".join(circles)


def _imports(tree: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    return [n for n in ast.walk(tree) if isinstance(n, ast.Import | ast.ImportFrom)]


def _is_module(name: str) -> bool:
    return (PACKAGE / f"{name}.py").is_file() or (PACKAGE / name / "__init__.py").is_file()


def test_library_imports_neither_the_root_package_nor_the_command_line() -> None:
    bad = []
    for name, path in _library_modules():
        for node in _imports(ast.parse(path.read_text())):
            targets = ([a.name for a in node.names] if isinstance(node, ast.Import)
                       else [node.module or ""])
            if isinstance(node, ast.ImportFrom) and node.module == "gyrodrift":
                # `from gyrodrift import units` names a submodule, not the root's re-exports
                targets = [f"gyrodrift.{a.name}" if _is_module(a.name) else "gyrodrift"
                           for a in node.names]
            for t in targets:
                if t == "gyrodrift" or t.startswith(FRONT_ENDS):
                    bad.append(f"{name}:{node.lineno} imports {t}")
    assert not bad, "\n".join(bad)


def test_no_private_name_is_imported_across_modules() -> None:
    bad = []
    for name, path in [*_library_modules(), *((n, p) for n, p in _all_modules()
                                             if n.startswith(FRONT_ENDS))]:
        for node in _imports(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("gyrodrift"):
                private = [a.name for a in node.names
                           if a.name.startswith("_") and not a.name.endswith("__")]
                if private:
                    bad.append(f"{name}:{node.lineno} takes {private} from {node.module}")
    assert not bad, "\n".join(bad)


def _all_modules() -> list[tuple[str, Path]]:
    return [(_module_name(p), p) for p in sorted(PACKAGE.rglob("*.py"))]


def test_library_modules_neither_parse_arguments_nor_print() -> None:
    bad = []
    for name, path in _library_modules():
        tree = ast.parse(path.read_text())
        for node in _imports(tree):
            mods = ([a.name for a in node.names] if isinstance(node, ast.Import)
                    else [node.module or ""])
            if "argparse" in mods:
                bad.append(f"{name}:{node.lineno} imports argparse")
        for node in ast.walk(tree):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                    and node.func.id == "print"):
                bad.append(f"{name}:{node.lineno} prints")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("check", ["root", "private", "print"])
def test_the_ast_checks_fail_on_a_bad_module(tmp_path: Path, check: str,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    # Each AST check above, run on a package holding one offending module, reports it.
    pkg = tmp_path / "gyrodrift"
    (pkg / "stability").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "stability" / "__init__.py").write_text("")
    body = {"root": "import gyrodrift\n",
            "private": "from gyrodrift.io.records import _hidden\n",
            "print": "def f():\n    print('x')\n"}[check]
    (pkg / "stability" / "bad.py").write_text(body)
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", pkg)
    test = {"root": test_library_imports_neither_the_root_package_nor_the_command_line,
            "private": test_no_private_name_is_imported_across_modules,
            "print": test_library_modules_neither_parse_arguments_nor_print}[check]
    with pytest.raises(AssertionError, match=r"gyrodrift\.stability\.bad"):
        test()
