"""The package's public surface (issue 9): `__all__` everywhere public, `help(gyrodrift)` lists
the API, `import gyrodrift` does not pull in the replay area's dependencies, and the docstring
examples run as doctests (every module; every name of the top-level API has one)."""

from __future__ import annotations

import doctest
import importlib
import inspect
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
            "gyrodrift.fit_ar2, gyrodrift.simulation.records, gyrodrift.oadev\n"
            "print(sorted(heavy & set(sys.modules)))\n"
            "gyrodrift.ReplayOptions\n"
            "print(sorted({'can', 'cantools', 'serial'} & set(sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=os.environ.copy(), check=True).stdout.splitlines()
    assert out == ["[]", "[]", "['can', 'cantools', 'serial']"]


def test_import_gyrodrift_does_not_import_the_heavy_scipy_modules() -> None:
    # scipy.stats, scipy.signal (which loads scipy.stats) and the drift models' and GMWM's
    # modules cost ~0.7 s of import; every command line call and each fleet worker paid them
    # (1.15 s for `import gyrodrift` before). They load on first use of a name that needs them.
    code = ("import sys, gyrodrift\n"
            "heavy = {'scipy.stats', 'scipy.signal', 'gyrodrift.filters.drift_model',"
            " 'gyrodrift.stability.gmwm'}\n"
            "print(sorted(heavy & set(sys.modules)))\n"
            "import gyrodrift.workflows._fleet_worker\n"
            "print(sorted(heavy & set(sys.modules)))\n"
            "print(gyrodrift.identify_gmwm.__module__, gyrodrift.fit_drift_model.__module__,"
            " gyrodrift.GmwmResult.__name__)\n"
            "print(sorted(heavy & set(sys.modules)))\n"
            "rec = gyrodrift.simulate(n=64, rate_hz=10.0, n_deg_rt_h=0.01, seed=1)\n"
            "print(rec.rate_deg_h.size)\n"
            "print(float(gyrodrift.welch_psd([0.0, 1.0] * 32, 10.0).psd[1]) > 0)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=os.environ.copy(), check=True).stdout.splitlines()
    assert out == ["[]", "[]", "gyrodrift.stability.gmwm gyrodrift.filters.drift_model GmwmResult",
                   "['gyrodrift.filters.drift_model', 'gyrodrift.stability.gmwm', 'scipy.stats']",
                   "64", "True"]


def test_help_lists_the_api() -> None:
    text = pydoc.render_doc(gyrodrift, renderer=pydoc.plaintext)
    for name in ("fit_ar2", "kalman_filter", "simulate", "RealtimeWavelet", "forced_fir_taps",
                 "oadev", "welch_psd", "load_record", "ImuProcessor", "run_alignment",
                 "GyrodriftError", "run_replay", "read_imu_log"):
        assert name in gyrodrift.__all__, name
        assert f"\n    {name}" in text or f" {name}(" in text or f"class {name}" in text, name
    for name in gyrodrift.__all__:
        assert getattr(gyrodrift, name) is not None, name


def _modules(public_only: bool) -> list[str]:
    names = [] if public_only else ["gyrodrift"]
    # The package's own directory only: __path__ may also list an installed copy (the
    # development-build path extension in gyrodrift/__init__.py).
    for info in pkgutil.walk_packages([os.path.dirname(gyrodrift.__file__)], "gyrodrift."):
        parts = info.name.split(".")
        if parts[-1] == "__main__" or (public_only and any(p.startswith("_") for p in parts[1:])):
            continue
        names.append(info.name)
    return sorted(set(names))


@pytest.mark.parametrize("name", _modules(public_only=True))
def test_every_public_module_has_all(name: str) -> None:
    mod = importlib.import_module(name)
    assert hasattr(mod, "__all__"), f"{name} has no __all__"
    for item in mod.__all__:
        assert hasattr(mod, item), f"{name}.__all__ names {item!r}, which it does not define"


# ------------------------------------------------------------------ doctests


@pytest.mark.parametrize("name", _modules(public_only=False))
def test_docstring_examples_run(name: str) -> None:
    mod = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(
        optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    # The installed numpy's own print options (no legacy mode): an example that prints a
    # numpy scalar fails here under numpy 2 (np.float64(...)), and one that expects numpy 2's
    # scalar repr fails tests/test_doctest_floats.py; so the examples print Python values,
    # the same under every numpy this package supports (pytest --doctest-modules too).
    for test in finder.find(mod, name, globs=vars(mod).copy()):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"


def _documented_names() -> list[tuple[str, str]]:
    """(module, name) for every function and class in the __all__ of every public module
    (gyrodrift itself included). Constants carry no docstring of their own: their module's
    docstring describes them."""
    out = []
    for modname in ["gyrodrift", *_modules(public_only=True)]:
        mod = importlib.import_module(modname)
        for name in mod.__all__:
            obj = getattr(mod, name)
            if inspect.isclass(obj) or inspect.isroutine(obj) or hasattr(obj, "__wrapped__"):
                out.append((modname, name))
    return out


def _examples_section(doc: str) -> str:
    """The text of a numpydoc "Examples" section ('' when there is none)."""
    lines = doc.splitlines()
    for i in range(len(lines) - 1):
        if lines[i].strip() == "Examples" and set(lines[i + 1].strip()) == {"-"}:
            return "\n".join(lines[i + 2:])
    return ""


def test_every_public_name_has_an_example() -> None:
    """Every function and class any public module exports has a numpydoc Examples section
    with a `>>>` line, and test_docstring_examples_run collects it (the docstring of an
    object defined in its own module, found by doctest.DocTestFinder)."""
    names = _documented_names()
    assert len(names) > 300  # the walk reaches the subpackages (reference, replay, codecs, cli)
    missing, uncollected = [], []
    finder = doctest.DocTestFinder(exclude_empty=True)
    collected: dict[str, set[str]] = {}
    for modname, name in names:
        obj = getattr(importlib.import_module(modname), name)
        doc = inspect.getdoc(obj) or ""
        if ">>>" not in _examples_section(doc):
            missing.append(f"{modname}.{name}")
            continue
        home = getattr(inspect.unwrap(obj), "__module__", modname)
        if home not in collected:
            mod = importlib.import_module(home)
            collected[home] = {t.docstring or "" for t in finder.find(mod, home)}
        if inspect.unwrap(obj).__doc__ not in collected[home]:
            uncollected.append(f"{modname}.{name}")
    assert not missing, f"public names without a docstring example ({len(missing)}): {missing}"
    assert not uncollected, f"examples the doctest run does not collect: {uncollected}"


def test_one_core_loader_with_one_message(monkeypatch: pytest.MonkeyPatch) -> None:
    """gyrodrift._native.core() is the only place that imports the extension; a missing
    extension or binding area is one clear ImportError."""
    from gyrodrift import _native

    assert _native.core("ar2").__name__ == "gyrodrift._core"
    with pytest.raises(ImportError, match="built without the 'nope' binding area"):
        _native.core("nope")
    monkeypatch.setitem(sys.modules, "gyrodrift._core", None)  # import now fails
    monkeypatch.delattr(gyrodrift, "_core", raising=False)
    with pytest.raises(ImportError, match="C\\+\\+ extension\\) is not available"):
        _native.core()
    # no other module imports the extension itself
    pkg = os.path.dirname(gyrodrift.__file__)
    offenders = []
    for root, _, files in os.walk(pkg):
        for f in files:
            if f.endswith(".py") and f != "_native.py":
                text = open(os.path.join(root, f), encoding="utf-8").read()
                if "from gyrodrift import _core" in text or "import gyrodrift._core" in text:
                    offenders.append(f)
    assert not offenders
