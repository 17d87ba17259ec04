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
}
# Flags that name one subcommand's own concept (no other subcommand has the concept).
OWN_FLAGS: dict[str, set[str]] = {
    "demo": {"--method", "--float32"},
    "replay": {"--transport", "--device", "--speed", "--fast", "--baud", "--can-bitrate",
               "--no-link-pacing", "--loop-rate-hz", "--loop-binary", "--no-rt", "--drop",
               "--corrupt", "--duplicate", "--reorder", "--delay", "--delay-s", "--gyro-filter",
               "--accel-filter", "--stuck-samples"},
    "simulate": {"--n"},
    "filter": {"--method", "--core", "--ar-method"},
    "allan": {"--taus", "--per-decade", "--noise-id", "--fit-range", "--terms", "--no-select"},
    "identify": {"--method", "--model", "--max-model", "--bootstrap", "--fit-range", "--terms",
                 "--no-select"},
    "psd": {"--nperseg", "--bins-per-decade"},
    "compare": set(),
    "wavelet-response": {"--n-freqs"},
    "align": {"--scenario", "--runs", "--coarse-s", "--states", "--kf-noise", "--gyro-lsb-arcsec",
              "--dither-arcsec", "--mechanism", "--real", "--segment-s", "--no-plots"},
}
# Spellings the table replaced; a reappearance fails with a pointer to the right name.
RETIRED = {"--rate": "--rate-hz", "--duration": "--duration-s", "--seconds": "--duration-s",
           "--minutes": "--duration-s", "--out": "--out-dir or -o/--output",
           "--q": "--kalman-q or --quant-arcsec", "--r": "--kalman-r", "--gyro-ar2": "--ar2",
           "--gyro-q": "--kalman-q", "--gyro-r": "--kalman-r", "--sample-rate-hz": "--rate-hz",
           "--segment-min": "--segment-s", "--arw": "--arw-deg-rt-h", "--bi": "--bias-inst-deg-h"}
LONG_COMMANDS = {"allan", "compare", "align"}  # minutes of work on real inputs: --progress
# Subcommands that may take longer without a bar of their own: replay runs in real time and
# prints its accounting; its progress is the loop's.


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
    from gyrodrift.allan import ONE_SIGMA_CI

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
    "gyrodrift.earth", "gyrodrift.errors", "gyrodrift.align.attitude", "gyrodrift.align.config",
    "gyrodrift.imu",  # the processor contract: flag bits, channel names, configuration types
}
# Single names the references may take from a production module: the model record, its error
# and input checks; not the fits and filters under test.
REFERENCE_MAY_IMPORT_NAMES = {
    "gyrodrift.ar2.MIN_SAMPLES", "gyrodrift.ar2.Ar2FitError", "gyrodrift.ar2.Ar2Model",
    "gyrodrift.ar2.is_stationary", "gyrodrift.ar2.normalise_method",
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
    import gyrodrift.align as align
    import gyrodrift.reference as ref

    for name in ("Strapdown", "InertialCoarseAlign", "FineAlignKF", "run_alignment_reference"):
        assert getattr(ref, name).__module__.startswith("gyrodrift.reference.align"), name
        assert not hasattr(align, name), name
    assert not (PACKAGE / "align" / "earth.py").exists()
    assert not (PACKAGE / "align" / "prefilter.py").exists()


# ------------------------------------------------------------------ errors
# Areas whose owners are rewriting them in parallel (issues 12 and 13) convert on their side.
ERRORS_PENDING = {"imu.py", "replay", "codecs"}


def test_production_raises_gyrodrift_errors() -> None:
    """Every ValueError/TypeError the package raises on purpose is a GyrodriftValueError /
    GyrodriftTypeError (CONTRIBUTING.md: one base class, catchable as GyrodriftError)."""
    bad = []
    for path in _modules(PACKAGE):
        rel = path.relative_to(PACKAGE)
        if "reference" in rel.parts or rel.parts[0] in ERRORS_PENDING:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call)
                    and isinstance(node.exc.func, ast.Name)
                    and node.exc.func.id in ("ValueError", "TypeError")):
                bad.append(f"{rel}:{node.lineno}: raise {node.exc.func.id}")
    assert not bad, "use gyrodrift.errors:\n" + "\n".join(bad)
