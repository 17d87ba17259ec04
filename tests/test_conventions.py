"""Issue 9 conventions (CONTRIBUTING.md): every subcommand's flags come from one table, and the
oracles in gyrodrift.reference stay independent of the production code."""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

import pytest
from gyrodrift.cli import SUBCOMMAND_MODULES, build_parser

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "gyrodrift"

# ------------------------------------------------------------------ command-line flag table
# The CONTRIBUTING.md flag table: one name per concept, the same in every subcommand.
SHARED_FLAGS = {
    "--rate-hz", "--duration-s", "-o", "--output", "--out-dir", "--png", "--csv", "--json",
    "--progress", "--ci", "--seed", "--column", "--units", "--drop-nan", "--ar2", "--kalman-q",
    "--kalman-r", "--steady-state", "--wavelet", "--window", "--level", "--threshold",
    "--quant-arcsec", "--arw-deg-rt-h", "--bias-inst-deg-h", "--rrw-deg-h-rt-h", "--ramp-deg-h2",
    "--bias-deg-h", "--ar2-sigma2", "--ar2-mean", "--config", "--format", "-h", "--help",
    "--force-rate",
}
# Flags that name one subcommand's own concept (no other subcommand has the concept).
OWN_FLAGS: dict[str, set[str]] = {
    "demo": {"--method", "--float32"},
    "replay": {"--transport", "--device", "--speed", "--fast", "--baud", "--can-bitrate",
               "--no-link-pacing", "--loop-rate-hz", "--loop-binary", "--no-rt", "--drop",
               "--corrupt", "--duplicate", "--reorder", "--delay", "--delay-s", "--can-signals"},
    "simulate": {"--n"},
    "filter": {"--method", "--core", "--ar-method"},
    "allan": {"--taus", "--per-decade", "--noise-id", "--can-signals", "--deviation",
              "--fit-range", "--terms", "--no-select"},
    "fit": {"--criterion"},
    "identify": {"--method", "--model", "--max-model", "--bootstrap", "--fit-range", "--terms",
                 "--no-select"},
    "psd": {"--nperseg", "--bins-per-decade"},
    "compare": set(),
    "wavelet-response": {"--n-freqs"},
    "config": {"--emit-cpp", "--namespace"},
    "characterize": {"--columns", "--time-column", "--topic", "--gyro-units", "--accel-units",
                     "--method", "--terms", "--taus", "--kalibr", "--kalibr-axis", "--html",
                     "--self-check"},
    "fleet": {"--columns", "--time-column", "--topic", "--gyro-units", "--accel-units",
              "--method", "--terms", "--taus", "--workers", "--scheduler", "--force", "--spec",
              "--memory-budget-mib"},
    "align": {"--scenario", "--runs", "--coarse-s", "--states", "--kf-noise", "--gyro-lsb-arcsec",
              "--dither-arcsec", "--mechanism", "--real", "--segment-s", "--no-plots"},
}
# Spellings the table replaced; a reappearance fails with a pointer to the right name.
RETIRED = {"--rate": "--rate-hz", "--duration": "--duration-s", "--seconds": "--duration-s",
           "--minutes": "--duration-s", "--out": "--out-dir or -o/--output",
           "--q": "--kalman-q or --quant-arcsec", "--r": "--kalman-r", "--gyro-ar2": "--ar2",
           "--gyro-q": "--kalman-q", "--gyro-r": "--kalman-r", "--sample-rate-hz": "--rate-hz",
           "--segment-min": "--segment-s", "--arw": "--arw-deg-rt-h", "--bi": "--bias-inst-deg-h"}
# Minutes of work on real inputs (replay: a record's length in real time): --progress
LONG_COMMANDS = {"allan", "compare", "align", "replay"}


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_every_subcommand_is_walked() -> None:
    names = set(_subparsers())
    assert names == set(OWN_FLAGS), "add the new subcommand's own flags to OWN_FLAGS"
    assert len(names) == len(SUBCOMMAND_MODULES)


@pytest.mark.parametrize("name", sorted(OWN_FLAGS))
def test_flags_come_from_the_table(name: str) -> None:
    p = _subparsers()[name]
    allowed = SHARED_FLAGS | OWN_FLAGS[name]
    for action in p._actions:
        for flag in action.option_strings:
            assert flag not in RETIRED, f"{name} {flag}: use {RETIRED[flag]} (CONTRIBUTING.md)"
            assert flag in allowed, f"{name} {flag} is not in the flag table (CONTRIBUTING.md)"
        if action.option_strings and action.help is not argparse.SUPPRESS:
            assert action.help, f"{name} {action.option_strings[0]} has no help"
            # full sentences, not cut: ends in a word, a unit or a closing bracket
            assert not action.help.rstrip().endswith((",", " and", " or", " the")), \
                f"{name} {action.option_strings[0]}: help cut: {action.help!r}"


@pytest.mark.parametrize("name", sorted(OWN_FLAGS))
def test_every_subcommand_has_json(name: str) -> None:
    p = _subparsers()[name]
    flags = {f for a in p._actions for f in a.option_strings}
    assert "--json" in flags
    if name in LONG_COMMANDS:
        action = next(a for a in p._actions if "--progress" in a.option_strings)
        assert tuple(action.choices) == ("auto", "always", "never") and action.default == "auto"


def test_ci_default_is_one_sigma() -> None:
    from gyrodrift.stability.allan import ONE_SIGMA_CI

    action = next(a for a in _subparsers()["allan"]._actions if "--ci" in a.option_strings)
    assert action.default == ONE_SIGMA_CI


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    import gyrodrift

    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"gyrodrift {gyrodrift.__version__}"


# ------------------------------------------------------------------ import direction
# Production modules the references may use: neutral helpers that hold no algorithm under test
# (constants and the Earth model, errors, attitude algebra, configuration records, the record
# types a reference consumes).
REFERENCE_MAY_IMPORT = {
    "gyrodrift.nav.earth", "gyrodrift.errors", "gyrodrift.nav.attitude",
    "gyrodrift.nav.align_config",
    "gyrodrift.imu.processor",  # configuration types the reference processor consumes
    "gyrodrift.imu.contract",  # the processor contract: flag bits, health counter names
    "gyrodrift.units",  # unit constants
    "gyrodrift.defaults",  # shared defaults (the paper's prefilter parameters, sample rate)
    "gyrodrift.imu.config",  # the processor configuration file (records and reader, no algorithm)
}
# Single names the references may take from a production module: the model record, its error
# and input checks; not the fits and filters under test.
REFERENCE_MAY_IMPORT_NAMES = {
    "gyrodrift.filters.ar2.MIN_SAMPLES", "gyrodrift.filters.ar2.Ar2FitError",
    "gyrodrift.filters.ar2.Ar2Model",
    "gyrodrift.filters.ar2.is_stationary", "gyrodrift.filters.ar2.normalise_method",
}


def _imports(path: Path) -> set[str]:
    """Every gyrodrift name a module imports: `import a.b` -> a.b, `from a import x` -> a.x
    (relative imports resolved)."""
    tree = ast.parse(path.read_text(), str(path))
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    pkg_parts = list(rel.parts[:-1])
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg_parts[: len(pkg_parts) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            names |= {f"{mod}.{a.name}" for a in node.names}
    return {n for n in names if n.startswith("gyrodrift.")}


def _modules(under: Path) -> list[Path]:
    return sorted(p for p in under.rglob("*.py") if "__pycache__" not in p.parts)


# The one production module whose job is to run an oracle: the replay harness checks every
# output of the loop program against the reference processor (README, replay harness). It
# takes the oracle's result; it shares no helper with it.
ORACLE_USERS = {"replay/harness.py": {"gyrodrift.reference.imu.process_imu"}}


def test_production_never_imports_the_reference() -> None:
    bad = []
    for path in _modules(PACKAGE):
        rel = path.relative_to(PACKAGE)
        if "reference" in rel.parts:
            continue
        hits = {n for n in _imports(path) if n.startswith("gyrodrift.reference")}
        hits -= ORACLE_USERS.get(rel.as_posix(), set())
        if hits:
            bad.append(f"{path.relative_to(PACKAGE)}: {sorted(hits)}")
    assert not bad, "production imports the oracles:\n" + "\n".join(bad)


def test_reference_imports_only_neutral_production_helpers() -> None:
    bad = []
    for path in _modules(PACKAGE / "reference"):
        for name in _imports(path):
            if name.startswith("gyrodrift.reference") or name in REFERENCE_MAY_IMPORT_NAMES:
                continue
            if any(name == m or name.startswith(m + ".") for m in REFERENCE_MAY_IMPORT):
                continue
            bad.append(f"{path.relative_to(PACKAGE)}: {name}")
    assert not bad, "the oracles import production code:\n" + "\n".join(bad)


def test_alignment_references_live_under_reference() -> None:
    import gyrodrift.nav as align
    import gyrodrift.reference as ref

    for name in ("Strapdown", "InertialCoarseAlign", "FineAlignKF", "run_alignment_reference"):
        assert getattr(ref, name).__module__.startswith("gyrodrift.reference.align"), name
        assert not hasattr(align, name), name
    assert not (PACKAGE / "align" / "earth.py").exists()
    assert not (PACKAGE / "align" / "prefilter.py").exists()


# ------------------------------------------------------------------ errors
# Built-in exceptions a production module may still raise on purpose: OSError on the user's
# paths and devices (the command line reports it like a GyrodriftError), AttributeError from a
# module's __getattr__ and KeyError from a lookup by name (the protocols Python expects),
# ImportError for a missing extension or optional dependency, AssertionError for an internal
# invariant (a bug, not a user error).
BUILTIN_RAISES_ALLOWED = {"OSError", "FileNotFoundError", "AttributeError", "KeyError",
                          "ImportError", "AssertionError"}


def test_production_raises_gyrodrift_errors() -> None:
    """Every ValueError/TypeError the package raises on purpose is a GyrodriftValueError /
    GyrodriftTypeError, and nothing else built in is raised but the few above
    (CONTRIBUTING.md: one base class, catchable as GyrodriftError)."""
    import builtins

    bad = []
    for path in _modules(PACKAGE):
        rel = path.relative_to(PACKAGE)
        if "reference" in rel.parts:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call)
                    and isinstance(node.exc.func, ast.Name)
                    and isinstance(getattr(builtins, node.exc.func.id, None), type)
                    and node.exc.func.id not in BUILTIN_RAISES_ALLOWED):
                bad.append(f"{rel}:{node.lineno}: raise {node.exc.func.id}")
    assert not bad, "use gyrodrift.errors:\n" + "\n".join(bad)


def test_production_exception_classes_derive_from_gyrodrift_error() -> None:
    """Every exception class a production module defines is a GyrodriftError (so one
    `except GyrodriftError` catches them all, and `except ValueError` still works)."""
    import importlib
    import inspect

    from gyrodrift.errors import GyrodriftError

    bad = []
    for path in _modules(PACKAGE):
        rel = path.relative_to(PACKAGE)
        if "reference" in rel.parts or rel.name == "__main__.py":
            continue
        name = ".".join(("gyrodrift", *rel.with_suffix("").parts)).removesuffix(".__init__")
        mod = importlib.import_module(name)
        for cname, cls in inspect.getmembers(mod, inspect.isclass):
            if (cls.__module__ == name and issubclass(cls, BaseException)
                    and not issubclass(cls, GyrodriftError)):
                bad.append(f"{name}.{cname}")
    assert not bad, f"exception classes outside gyrodrift.errors' hierarchy: {bad}"


def test_replay_codecs_imu_raise_gyrodrift_errors() -> None:
    """The replay, codecs and processor-contract areas: catchable as GyrodriftError and still
    as ValueError / TypeError / RuntimeError by existing callers."""
    import numpy as np
    from gyrodrift.codecs import FrameError, encode_frames
    from gyrodrift.errors import GyrodriftError, GyrodriftTypeError, GyrodriftValueError
    from gyrodrift.imu.processor import ImuConfig, ImuProcessor
    from gyrodrift.replay import FaultSpec, ReplayError, log_format

    with pytest.raises(GyrodriftValueError, match="within"):
        FaultSpec(drop=2.0)
    with pytest.raises(GyrodriftValueError, match="shape"):
        encode_frames(np.zeros(3, np.uint16), np.zeros(3, np.uint64), np.zeros((3, 5)))
    with pytest.raises(GyrodriftValueError, match="suffix"):
        log_format("record.xyz")
    with pytest.raises(GyrodriftTypeError, match="dtype"):
        ImuProcessor(ImuConfig(), dtype=np.int32)
    assert issubclass(FrameError, GyrodriftValueError)
    assert issubclass(ReplayError, GyrodriftError) and issubclass(ReplayError, RuntimeError)
