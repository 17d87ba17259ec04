"""The conventions of CONTRIBUTING.md: every subcommand's flags come from one table, one flag
name carries one meaning (the same type, choices and default wherever it appears), one
concept has one flag name, no user-facing text names internal work items, and the oracles in
gyrodrift.reference stay independent of the production code."""

from __future__ import annotations

import argparse
import ast
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from gyrodrift.cli import SUBCOMMAND_MODULES, build_parser

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "gyrodrift"
REPO = PACKAGE.parents[1]

# ------------------------------------------------------------------ command-line flag table
# The CONTRIBUTING.md flag table: one name per concept, the same in every subcommand. Each
# shared flag maps to a pattern its help text must match in every subcommand (the concept,
# said the same way).
SHARED_FLAGS: dict[str, str] = {
    "--rate-hz": r"sample rate", "--duration-s": r"length|duration", "-o": r"", "--output": r"",
    "--out-dir": r"directory", "--png": r"plot", "--csv": r"CSV", "--json": r"JSON",
    "--progress": r"progress", "--ci": r"confidence", "--seed": r"seed",
    "--column": r"column", "--gyro-units": r"units of the gyro data", "--drop-nan": r"NaN",
    "--force-rate": r"--rate-hz", "--ar2": r"AR\(2\)", "--kalman-q": r"process variance",
    "--kalman-r": r"measurement variance", "--steady-state": r"steady-state|constant-gain",
    "--wavelet": r"wavelet", "--window": r"window", "--level": r"level",
    "--threshold": r"threshold",
    "--quant-arcsec": r"quantization", "--arw-deg-rt-h": r"angle random walk",
    "--bias-inst-deg-h": r"bias instability", "--rrw-deg-h-rt-h": r"rate random walk",
    "--ramp-deg-h2": r"rate ramp", "--bias-deg-h": r"bias", "--ar2-sigma2": r"driving-noise",
    "--ar2-mean": r"mean", "--config": r"configuration", "--format": r"format", "-h": r"",
    "--help": r"", "--ar-method": r"AR\(2\) estimator", "--identifier": r"noise identifier",
    "--terms": r"terms", "--taus": r"tau|averaging time", "--fit-range": r"tau",
    "--no-select": r"term",
    "--can-signals": r"signal map|DBC", "--accel-units": r"units of the accelerometer",
    "--column-channels": r"channel of each data column", "--time-column": r"time column",
    "--topic": r"topic", "--time-units": r"units of the time column",
    "--self-check": r"self-check.*does not describe",
}
# Flags that name one subcommand's own concept (no other subcommand has the concept).
OWN_FLAGS: dict[str, set[str]] = {
    "demo": {"--float32"},
    "replay": {"--transport", "--device", "--speed", "--fast", "--baud", "--can-bitrate",
               "--no-link-pacing", "--loop-rate-hz", "--loop-binary", "--no-rt", "--fault-drop",
               "--fault-corrupt", "--fault-duplicate", "--fault-reorder", "--fault-delay",
               "--fault-delay-s", "--target"},
    "simulate": {"--samples"},
    "filter": {"--filter", "--core"},
    "allan": {"--taus-per-decade", "--noise-id", "--deviation", "--curve"},
    "fit": {"--criterion"},
    "monitor": {"--channel", "--learn-s", "--report-every-s", "--fail-on-alarm",
                "--reidentify"},
    "identify": {"--model", "--max-model", "--bootstrap"},
    "psd": {"--nperseg", "--bins-per-decade"},
    "compare": set(),
    "wavelet-response": {"--n-freqs"},
    "config": {"--emit-cpp", "--namespace"},
    "characterize": {"--kalibr", "--kalibr-axis", "--html"},
    "fleet": {"--workers", "--scheduler", "--redo", "--spec", "--memory-budget-mib"},
    "align": {"--scenario", "--runs", "--coarse-s", "--states", "--kf-noise", "--gyro-lsb-arcsec",
              "--dither-arcsec", "--mechanism", "--real", "--segment-s", "--no-plots"},
}
# Spellings the table replaced; a reappearance fails with a pointer to the right name.
RETIRED = {"--rate": "--rate-hz", "--duration": "--duration-s", "--seconds": "--duration-s",
           "--minutes": "--duration-s", "--out": "--out-dir or -o/--output",
           "--q": "--kalman-q or --quant-arcsec", "--r": "--kalman-r", "--gyro-ar2": "--ar2",
           "--gyro-q": "--kalman-q", "--gyro-r": "--kalman-r", "--sample-rate-hz": "--rate-hz",
           "--segment-min": "--segment-s", "--arw": "--arw-deg-rt-h", "--bi": "--bias-inst-deg-h",
           # one name carried three concepts: say which method
           "--method": "--ar-method (AR(2) estimator), --filter (filter kind) or --identifier "
                       "(noise identifier)",
           "--units": "--gyro-units", "--n": "--samples", "--columns": "--column-channels",
           "--per-decade": "--taus-per-decade", "--force": "--redo",
           "--drop": "--fault-drop", "--corrupt": "--fault-corrupt",
           "--duplicate": "--fault-duplicate", "--reorder": "--fault-reorder",
           "--delay": "--fault-delay", "--delay-s": "--fault-delay-s"}
# Minutes of work on real inputs (replay: a record's length in real time): --progress
LONG_COMMANDS = {"allan", "compare", "align", "replay"}


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _options(p: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in p._actions if a.option_strings]


def test_every_subcommand_is_walked() -> None:
    names = set(_subparsers())
    assert names == set(OWN_FLAGS), "add the new subcommand's own flags to OWN_FLAGS"
    assert len(names) == len(SUBCOMMAND_MODULES)


@pytest.mark.parametrize("name", sorted(OWN_FLAGS))
def test_flags_come_from_the_table(name: str) -> None:
    p = _subparsers()[name]
    allowed = set(SHARED_FLAGS) | OWN_FLAGS[name]
    for action in p._actions:
        for flag in action.option_strings:
            assert flag not in RETIRED, f"{name} {flag}: use {RETIRED[flag]} (CONTRIBUTING.md)"
            assert flag in allowed, f"{name} {flag} is not in the flag table (CONTRIBUTING.md)"
        if action.option_strings and action.help is not argparse.SUPPRESS:
            assert action.help, f"{name} {action.option_strings[0]} has no help"
            # full sentences, not cut: ends in a word, a unit or a closing bracket
            assert not action.help.rstrip().endswith((",", " and", " or", " the")), \
                f"{name} {action.option_strings[0]}: help cut: {action.help!r}"


def test_own_flags_are_own() -> None:
    """A flag listed as one subcommand's own appears in that subcommand only, and is not in
    the shared table too."""
    seen: dict[str, set[str]] = {}
    for name, p in _subparsers().items():
        for a in _options(p):
            for flag in a.option_strings:
                seen.setdefault(flag, set()).add(name)
    for name, flags in OWN_FLAGS.items():
        for flag in flags:
            assert flag not in SHARED_FLAGS, f"{flag}: in SHARED_FLAGS and OWN_FLAGS[{name!r}]"
            assert seen.get(flag, set()) <= {name}, \
                f"{flag} is {name}'s own but also in {sorted(seen[flag] - {name})}: share it"


# ------------------------------------------------------------------ one meaning per flag name
# The value a subcommand uses when an option is not given, where the parser's default is a
# placeholder: `identify` defaults its identifier-specific options to None so that it can
# refuse one given to an identifier that ignores it, and fills them in from this table.
def _effective_defaults() -> dict[str, dict[str, Any]]:
    from gyrodrift.cli.identify import IDENTIFIER_OPTIONS

    return {"identify": {dest: default for dest, (_, default) in IDENTIFIER_OPTIONS.items()}}


# Fields of a flag that may differ between the subcommands that have it, each with the reason.
# Everything not listed here must be equal wherever the flag appears. An entry that no longer
# differs is stale and fails too (keep the table true).
SAME_FLAG_EXCEPTIONS: dict[tuple[str, str], str] = {
    # Commands that read a record take its rate from the file (no default); the ones that
    # make a record (demo 100 Hz, simulate, align, wavelet-response 400 Hz) have their own.
    ("--rate-hz", "default"): "the length of the record a command makes, or none",
    ("--duration-s", "default"): "the length of the record each generator makes",
    # Each command seeds its own random process (demo 2006, align 2014, compare the library's
    # fixed seed, the others 0), so that its documented output is reproducible.
    ("--seed", "default"): "each command seeds its own random process",
    ("--out-dir", "default"): "each command's own report directory (or required)",
    # psd and wavelet-response: the plot is the main output, so it has a default file.
    ("--png", "default"): "a default file where the plot is the main output",
    # `simulate --format` writes an IMU log (a .csv output is a rate record, not a log);
    # `replay --format` reads one (its IMU .csv too), named like simulate's.
    ("--format", "choices"): "simulate writes bin/candump/asc/blf; replay also reads csv",
    ("--format", "dest"): "replay's is named fmt",
    # `replay`'s processor options are the processor's, in rad/s with the demonstration
    # processor's values; demo/filter/simulate work on a deg/h record and default to the fit
    # (or to no AR(2) component).
    # filter's wavelet options default per filter kind (db8 offline denoiser of the 2006
    # paper, level 5 or 4 for wpacket); wavelet-response shows the forced real-time
    # prefilter of paper 004 (db4, J = 5).
    ("--wavelet", "default"): "filter: per filter kind; wavelet-response: the prefilter's",
    ("--level", "default"): "filter: per filter kind; wavelet-response: the prefilter's",
    # characterize/fleet need a fitted model per channel (Kalibr export, fleet summary): the
    # slope read-offs give none (gyrodrift.stability.MODEL_IDENTIFIERS).
    ("--identifier", "choices"): "characterize/fleet: the identifiers that give a model",
    ("-o", "required"): "simulate and filter must write a file; fit and config may",
    ("--output", "required"): "simulate and filter must write a file; fit and config may",
    ("--out-dir", "required"): "fleet writes only there",
}


def _signature(sub: str, a: argparse.Action) -> dict[str, Any]:
    default = _effective_defaults().get(sub, {}).get(a.dest, a.default)
    return {"action": type(a).__name__, "type": getattr(a.type, "__name__", a.type),
            "choices": None if a.choices is None else tuple(a.choices), "default": default,
            "nargs": a.nargs, "dest": a.dest, "required": a.required}


def _flag_uses() -> dict[str, dict[str, argparse.Action]]:
    uses: dict[str, dict[str, argparse.Action]] = {}
    for name, p in _subparsers().items():
        for a in _options(p):
            for flag in a.option_strings:
                uses.setdefault(flag, {})[name] = a
    return uses


def test_one_flag_name_one_meaning() -> None:
    """A flag in two or more subcommands is one concept: the same kind of option, type,
    choices, default and destination everywhere (SAME_FLAG_EXCEPTIONS: the listed reasons),
    and its help says the concept the table gives it."""
    bad, used = [], set()
    for flag, subs in sorted(_flag_uses().items()):
        if flag in ("-h", "--help"):
            continue
        pattern = SHARED_FLAGS.get(flag, "")
        for sub, a in subs.items():
            if pattern and not re.search(pattern, a.help or "", re.IGNORECASE):
                bad.append(f"{sub} {flag}: help {a.help!r} does not say /{pattern}/")
        if len(subs) < 2:
            continue
        sigs = {sub: _signature(sub, a) for sub, a in subs.items()}
        for field in next(iter(sigs.values())):
            values = {sub: sig[field] for sub, sig in sigs.items()}
            if len({repr(v) for v in values.values()}) > 1:
                if (flag, field) in SAME_FLAG_EXCEPTIONS:
                    used.add((flag, field))
                else:
                    bad.append(f"{flag}: {field} differs: {values}")
    stale = set(SAME_FLAG_EXCEPTIONS) - used
    assert not bad, "one flag name, several meanings (CONTRIBUTING.md):\n" + "\n".join(bad)
    assert not stale, f"SAME_FLAG_EXCEPTIONS entries that no longer differ: {sorted(stale)}"


def _concepts() -> list[tuple[str, Callable[[argparse.Action], bool], str, dict[str, Any]]]:
    """Known concepts: how to recognise an option of the concept in any subcommand, the one
    flag name it must have, and the values (choices, default, type) the library defines once."""
    from gyrodrift.cli.common import DEFAULT_FIT_TERMS
    from gyrodrift.filters.ar2 import AR2_METHODS, DEFAULT_AR2_METHOD
    from gyrodrift.stability import DEFAULT_IDENTIFIER, NOISE_IDENTIFIERS
    from gyrodrift.stability.allan import ONE_SIGMA_CI
    from gyrodrift.units import (
        ACCEL_INPUT_UNITS,
        DEFAULT_ACCEL_UNITS,
        DEFAULT_GYRO_UNITS,
        GYRO_INPUT_UNITS,
        RATE_UNITS,
    )

    def choices(a: argparse.Action) -> set[Any]:
        return set(a.choices or ())

    def text(a: argparse.Action) -> str:
        return (a.help or "").lower()

    return [
        ("sample rate", lambda a: a.dest.endswith("rate_hz") or "sample rate" in text(a),
         "--rate-hz", {"type": float}),
        ("gyro units", lambda a: bool(choices(a) & set(RATE_UNITS)), "--gyro-units",
         {"choices": GYRO_INPUT_UNITS, "default": DEFAULT_GYRO_UNITS}),
        ("accelerometer units", lambda a: "m/s^2" in choices(a), "--accel-units",
         {"choices": ACCEL_INPUT_UNITS, "default": DEFAULT_ACCEL_UNITS}),
        ("noise identifier", lambda a: "allan-nnls" in choices(a), "--identifier",
         {"default": DEFAULT_IDENTIFIER, "choices_within": NOISE_IDENTIFIERS}),
        ("AR(2) estimator", lambda a: "burg" in choices(a), "--ar-method",
         {"choices": AR2_METHODS, "default": DEFAULT_AR2_METHOD}),
        ("filter kind", lambda a: {"kalman", "wavelet"} <= choices(a), "--filter", {}),
        ("random seed", lambda a: "seed" in a.dest, "--seed", {"type": int}),
        ("confidence level", lambda a: a.dest == "ci" or "confidence" in text(a), "--ci",
         {"default": ONE_SIGMA_CI, "type": float}),
        ("IEEE 952 terms", lambda a: a.dest == "terms", "--terms",
         {"default": DEFAULT_FIT_TERMS}),
        ("fault probability", lambda a: text(a).startswith(("fault", "probability that")),
         "--fault-", {}),
        ("per decade", lambda a: "per-decade" in a.option_strings[-1], "", {}),
    ]


# Options a concept recogniser catches that are another concept.
CONCEPT_EXCEPTIONS = {
    ("sample rate", "--loop-rate-hz"): "the loop program's cycle rate, not the record's",
    ("per decade", "--taus-per-decade"): "averaging times per decade (allan)",
    ("per decade", "--bins-per-decade"): "PSD plot bins per decade (psd)",
}


def test_one_concept_one_flag_name() -> None:
    """Every option of a known concept, in any subcommand, has the concept's one flag name,
    and the choices and default the library defines once (gyrodrift.units,
    gyrodrift.stability, gyrodrift.filters.ar2): e.g. the noise identifier is --identifier
    with default DEFAULT_IDENTIFIER in identify, characterize and fleet alike."""
    bad, used = [], set()
    for sub, p in _subparsers().items():
        eff = _effective_defaults().get(sub, {})
        for a in _options(p):
            if a.help is argparse.SUPPRESS or "-h" in a.option_strings:
                continue
            flag = a.option_strings[-1]
            for concept, match, want, values in _concepts():
                if not match(a):
                    continue
                if (concept, flag) in CONCEPT_EXCEPTIONS:
                    used.add((concept, flag))
                    continue
                if not want or not flag.startswith(want) or (not want.endswith("-")
                                                            and flag != want):
                    bad.append(f"{sub} {flag}: the {concept} is {want or 'named per what'}")
                    continue
                default = eff.get(a.dest, a.default)
                if "default" in values and default != values["default"]:
                    bad.append(f"{sub} {flag}: default {default!r}, the library's is "
                               f"{values['default']!r}")
                if "choices" in values and tuple(a.choices or ()) != tuple(values["choices"]):
                    bad.append(f"{sub} {flag}: choices {a.choices}, the library's are "
                               f"{values['choices']}")
                if "choices_within" in values and not set(a.choices or ()) <= set(
                        values["choices_within"]):
                    bad.append(f"{sub} {flag}: choices {a.choices} outside "
                               f"{values['choices_within']}")
                if "type" in values and a.type is not values["type"]:
                    bad.append(f"{sub} {flag}: type {a.type}, not {values['type']}")
    assert not bad, "one concept, one flag (CONTRIBUTING.md):\n" + "\n".join(bad)
    stale = set(CONCEPT_EXCEPTIONS) - used
    assert not stale, f"CONCEPT_EXCEPTIONS entries no option needs: {sorted(stale)}"


# ------------------------------------------------------------------ no internal work items
# User-facing text says what it means: no internal work-item numbers ("issue 11", "(#14)",
# "issue-12 schema", "task 3"), no "the formula", no paths of the machine it was
# written on.
WORK_ITEM = re.compile(r"\b(issues?|tasks?|tickets?|sessions?)[- ]?#?\d+|\(#\d+\)|"
                       r"\b(the|this) issue\b|\bthe issue's\b|/work/", re.IGNORECASE)
C_SUFFIXES = {".hpp", ".cpp", ".h", ".c"}


def _work_item_hits(path: Path) -> list[str]:
    return [f"{path.relative_to(REPO)}:{k}: {line.strip()}"
            for k, line in enumerate(path.read_text(errors="replace").splitlines(), 1)
            if WORK_ITEM.search(line)]


def test_work_item_pattern() -> None:
    for text in ("issue 11", "(issue 9)", "issues 5/6", "Issue 12:", "(#14)", "issue-12 schema",
                 "task 3", "the issue's formula", "/work/shared/data/x.imu"):
        assert WORK_ITEM.search(text), text
    for text in ("one task per log", "an issue with the clock", "color: #222;", "#include"):
        assert not WORK_ITEM.search(text), text


def test_no_work_items_in_the_package_sources() -> None:
    bad = [hit for path in _modules(PACKAGE) for hit in _work_item_hits(path)]
    assert not bad, "internal work items in python/gyrodrift:\n" + "\n".join(bad)


def test_no_work_items_in_the_tools() -> None:
    # benchmarks and scripts print the tables the documentation shows, and have --help
    bad = [hit for folder in ("benchmarks", "scripts")
           for path in sorted((REPO / folder).iterdir()) if path.is_file()
           for hit in _work_item_hits(path)]
    assert not bad, "internal work items in benchmarks/ or scripts/:\n" + "\n".join(bad)


def test_no_work_items_in_the_cpp_sources() -> None:
    bad = []
    for folder in ("include", "cpp", "bindings"):
        for path in sorted((REPO / folder).rglob("*")):
            if path.is_file() and path.suffix in C_SUFFIXES:
                bad += _work_item_hits(path)
    assert not bad, "internal work items in the C++ sources:\n" + "\n".join(bad)


@pytest.mark.parametrize("name", sorted(OWN_FLAGS))
def test_no_work_items_in_help(name: str) -> None:
    text = " ".join(_subparsers()[name].format_help().split())  # lines joined: no wrap hides one
    hits = [m.group(0) for m in WORK_ITEM.finditer(text)]
    assert not hits, f"gyrodrift {name} --help names internal work items: {hits}"


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
