"""The processor configuration is written once (gyrodrift.imu.schema): every other side
follows from that table or is held to it here.

- the generated C++ header include/gyrodrift/imu/config_schema.hpp equals what the generator
  writes from the table now (scripts/gen-config-schema regenerates it);
- a corpus generated from the table, one file per field and bound (just inside, just outside,
  the wrong type, a missing required field), gets the same verdict and names the same key in
  the Python reader and in the loop's reader (gyrodrift-loop --config FILE --check-config).
"""

from __future__ import annotations

import math
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from gyrodrift.imu.config import ConfigError, default_config, dumps_config, parse_config
from gyrodrift.imu.firmware_header import emit_schema_header
from gyrodrift.imu.schema import FIELDS, FLOAT32_MIN_NORMAL, Field

ROOT = Path(__file__).resolve().parents[1]
HEADER = ROOT / "include" / "gyrodrift" / "imu" / "config_schema.hpp"


def test_committed_schema_header_is_generated() -> None:
    assert HEADER.read_text() == emit_schema_header(), (
        "include/gyrodrift/imu/config_schema.hpp differs from the schema: run "
        "scripts/gen-config-schema and commit the result")


def _location(f: Field) -> tuple[str, str]:
    """(table header line in the default text, key) where the field `f` of gx lives."""
    if f.section == "timing":
        return "[timing]", f.name
    if f.section == "channel":
        return "[channels.gx]", f.key("gx")
    if f.section == "bias_removal":
        return "[channels.ax]", f.key("ax")
    if f.section == "monitor":
        return "[monitor]", f.name
    return "[channels.gx]", f.key("gx")


def _set(text: str, f: Field, value: str | None) -> tuple[str, str]:
    """The default configuration's text with field `f` (of gx's chain, or ax's bias stage) set
    to `value` (None: removed); returns (text, the key an error must name)."""
    table, key = _location(f)
    if table == "[monitor]" and table not in text:  # the default text leaves it out (off)
        at = text.index("[channels.gx]")
        text = text[:at] + "[monitor]\n\n" + text[at:]
    if f.section in ("wavelet", "ar2_kalman"):
        stage = 0 if f.section == "wavelet" else 1
        full = f"channels.gx.stages[{stage}].{key}"
        start = text.index(f'type = "{f.section}"')
    elif f.section == "bias_removal":
        full = f"channels.ax.stages[0].{key}"
        start = text.index('type = "bias_removal"')
    else:
        full = f"{table.strip('[]')}.{key}"
        start = text.index(table)
    end = text.index("\n\n", start)
    block = text[start:end].splitlines()
    lines = [ln for ln in block if not ln.startswith(f"{key} =")]
    if value is not None:
        lines.append(f"{key} = {value}")
    return text[:start] + "\n".join(lines) + text[end:], full


def _literal(f: Field, x: float) -> str:
    if f.kind == "int":
        return str(int(x))
    return "inf" if math.isinf(x) else repr(float(x))


def corpus() -> Iterator[tuple[str, str, str | None]]:
    """(case name, file text, key of the expected error or None: valid)."""
    base = dumps_config(default_config())
    for f in FIELDS:
        if f.section == "wavelet" and f.name == "level":
            continue  # its upper bound depends on the window: tests/test_config_windows.py
        if f.required:
            yield (f"{f.section}.{f.name} missing", *_set(base, f, None))
        wrong = '"text"' if f.kind != "str" else "1"
        yield (f"{f.section}.{f.name} wrong type", *_set(base, f, wrong))
        if f.choices:
            for c in f.choices:
                text, _ = _set(base, f, f'"{c}"')
                yield (f"{f.section}.{f.name} = {c}", text, None)
            yield (f"{f.section}.{f.name} unknown choice", *_set(base, f, '"nope"'))
        for bound, open_, side in ((f.lo, f.lo_open, -1), (f.hi, f.hi_open, +1)):
            if bound is None or (f.name in ("a1", "a2")):
                continue
            if f.kind == "int":
                step: float = 1
            elif f.float32:  # a step the float32 rounding keeps
                step = max(abs(bound) * 1e-6, FLOAT32_MIN_NORMAL)
            else:
                step = max(abs(bound) * 1e-9, 1e-300)
            inside = bound - side * step if open_ else bound
            outside = bound if open_ else bound + side * step
            if not f.power_of_two:
                text, _ = _set(base, f, _literal(f, inside))
                yield (f"{f.section}.{f.name} at {inside!r}", text, None)
            yield (f"{f.section}.{f.name} beyond {bound!r}", *_set(base, f, _literal(f, outside)))
        if f.kind == "float" and f.finite:
            yield (f"{f.section}.{f.name} = nan", *_set(base, f, "nan"))
        if f.float32:  # valid doubles that are no float32: underflow, overflow
            for x in ("1e-50", "-1e-45", "1e39", "-3.5e38"):
                yield (f"{f.section}.{f.name} = {x} (no float32)", *_set(base, f, x))


def relations() -> Iterator[tuple[str, str, str | None]]:
    """Cases of relations between fields, where both readers must agree too."""
    base = dumps_config(default_config())
    fast = base.replace("sample_rate_hz = 400.0", "sample_rate_hz = 5000.0").replace(
        "time_tolerance_us = 1250\n", "")
    yield ("fast record, loop rate absent", fast.replace("loop_rate_hz = 400.0\n", ""),
           "timing.loop_rate_hz")
    yield ("fast record, loop rate given", fast, None)
    # the lag identifier: watched gyros x fit_delay_s <= retune_s, in samples
    yield from _fit_delay_relations()


def _fit_delay_relations() -> Iterator[tuple[str, str, str | None]]:
    from gyrodrift.imu.config import Ar2KalmanStage, ChannelConfig

    cfg = default_config()
    for ch in ("gx", "gy", "gz"):  # three watched gyros: ar2_kalman first
        stage = Ar2KalmanStage(a1=0.5, a2=0.1, mean=0.0, q=1e-9, r=1e-7, steady_state=True)
        cfg = cfg.with_channel(ch, ChannelConfig(ch, (stage,)))
    three = dumps_config(cfg.with_monitor(enabled=True, reidentify=True, identifier="lag",
                                          retune_s=60.0, fit_delay_s=20.0))
    assert "fit_delay_s = 20.0\n" in three and "retune_s = 60.0\n" in three
    yield ("lag, three gyros x 20 s in 60 s", three, None)
    yield ("lag, three gyros x 20 s in 59 s", three.replace("retune_s = 60.0", "retune_s = 59.0"),
           "monitor.fit_delay_s")
    yield ("lag, off: one gyro x 20 s in 59 s",
           three.replace("retune_s = 60.0", "retune_s = 59.0").replace("enabled = true",
                                                                         "enabled = false"), None)
    yield ("lag, off: one gyro x 20 s in 19 s",
           three.replace("retune_s = 60.0", "retune_s = 19.0").replace("enabled = true",
                                                                         "enabled = false"),
           "monitor.fit_delay_s")
    yield ("recursive: fit_delay_s not related",
           three.replace('identifier = "lag"', 'identifier = "recursive"').replace(
               "retune_s = 60.0", "retune_s = 19.0"), None)
    # in samples: at 100.4 Hz a block of 1 s is 100 samples (cadence 6000), 20 s 2008 samples
    odd = three.replace("sample_rate_hz = 400.0", "sample_rate_hz = 100.4").replace(
        "time_tolerance_us = 1250\n", "").replace("loop_rate_hz = 400.0\n", "")
    yield ("lag, three gyros x 2008 samples in 6000", odd, "monitor.fit_delay_s")
    yield ("lag, three gyros x 1958 samples in 6000", odd.replace("fit_delay_s = 20.0",
                                                                  "fit_delay_s = 19.5"), None)
    # the default fit_delay_s: three gyros within the default retune_s at any sample rate
    dflt = three.replace("fit_delay_s = 20.0\n", "").replace("retune_s = 60.0\n", "")
    for rate in ("1.0", "7.3", "100.4", "333.3", "999.9", "1000.0"):
        text = dflt.replace("sample_rate_hz = 400.0", f"sample_rate_hz = {rate}").replace(
            "time_tolerance_us = 1250\n", "").replace("loop_rate_hz = 400.0\n", "")
        yield (f"lag, three gyros, default fit delay at {rate} Hz", text, None)
    # more samples than the target's counter holds
    big = three.replace("sample_rate_hz = 400.0", "sample_rate_hz = 100000.0").replace(
        "time_tolerance_us = 1250\n", "").replace("enabled = true", "enabled = false")
    yield ("lag, fit delay beyond 32 bits", big.replace("retune_s = 60.0", "retune_s = 86400.0")
           .replace("fit_delay_s = 20.0", "fit_delay_s = 50000.0"), "monitor.fit_delay_s")


CASES = list(corpus()) + list(relations())


def test_corpus_covers_every_field() -> None:
    named = {c[0].split(" ")[0] for c in CASES}
    assert named >= {f"{f.section}.{f.name}" for f in FIELDS if f.name != "level"}


@pytest.mark.parametrize("name,text,key", CASES, ids=[c[0] for c in CASES])
def test_python_reader_verdict(name: str, text: str, key: str | None) -> None:
    if key is None:
        parse_config(text)
        return
    with pytest.raises(ConfigError) as info:
        parse_config(text)
    assert str(info.value).startswith(key + ":"), (name, str(info.value))


@pytest.fixture(scope="module")
def loop_check(cpp_build_dir: Path) -> Path:
    path = cpp_build_dir / "cpp" / "programs" / "gyrodrift-loop" / "gyrodrift-loop"
    assert path.is_file(), path
    return path


@pytest.mark.parametrize("name,text,key", CASES, ids=[c[0] for c in CASES])
def test_loop_reader_verdict(name: str, text: str, key: str | None, loop_check: Path,
                             tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(text)
    r = subprocess.run([str(loop_check), "--check-config", str(path)], capture_output=True,
                       text=True, timeout=10)
    if key is None:
        assert r.returncode == 0, (name, r.stderr)
    else:
        assert r.returncode == 2, (name, r.stderr)
        assert f"{path}: {key}:" in r.stderr, (name, r.stderr)


# ------------------------------------------------------------------ no second spelling
# A processor default written as a literal outside the schema (and the header generated from
# it): the shipped default configuration's numbers and the fields' defaults, in the places
# they used to be copied to. Comments, docstrings and strings are not code and are skipped.
LITERAL_DEFAULTS = [
    ("sample rate", r"\b(sample_rate_hz|rate_hz|period)\w*\s*[:=][^\n]*?\b400(\.0)?\b"),
    ("sample rate (C++ period)", r"\b(period_us|PeriodUs)\w*\s*=\s*2500"),
    ("timestamp tolerance", r"\b(time_tolerance_us|tolerance_us|ToleranceUs)\w*\s*=\s*1250"),
    ("stuck count", r"\bstuck_samples\s*[:=][^\n]*?\b50\b"),
    ("saturation", r"\bsaturation\w*\s*[:=][^\n]*?\b(8|160)\.0\b"),
    ("demonstration AR(2) model", r"\ba2\s*[:=]\s*-\s*0\.25\b"),
    ("demonstration q, r", r"\b(q|r|sigma2)\s*[:=][^\n]*?\b1e-(8|08|10)\b"),
    ("wavelet stage", r"\bwindow\s*[:=][^\n]*?\b256\b"),
]
# Matches that are not a copy of a default (checked by hand; each says why).
NOT_A_COPY = {
    ("cpp/bench/bench_imu.cpp", "demonstration q, r"): "the benchmark's own AR(2) model (a1 1.6)",
}
SINGLE_SOURCE = {"python/gyrodrift/imu/schema.py", "python/gyrodrift/defaults.py",
                 "include/gyrodrift/imu/config_schema.hpp"}


def _code_only(path: Path) -> str:
    import io
    import re
    import tokenize

    text = path.read_text()
    if path.suffix == ".py":
        out = []
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.type in (tokenize.COMMENT, tokenize.STRING):
                out.append(" ")
            elif tok.type == tokenize.NL or tok.type == tokenize.NEWLINE:
                out.append("\n")
            else:
                out.append(tok.string + " ")
        return re.sub(r" +", " ", "".join(out))
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    text = re.sub(r"//[^\n]*", " ", text)
    text = re.sub(r'R"(\w*)\(.*?\)\1"', '""', text, flags=re.S)
    return re.sub(r'"(\\.|[^"\\\n])*"', '""', text)


def _sources() -> list[Path]:
    files = list((ROOT / "python" / "gyrodrift").rglob("*.py"))
    for sub in ("include", "bindings", "cpp/programs", "cpp/cortex_m", "cpp/bench"):
        files += [p for p in (ROOT / sub).rglob("*") if p.suffix in (".hpp", ".cpp")]
    return [p for p in files if str(p.relative_to(ROOT)) not in SINGLE_SOURCE
            and "generated" not in p.parts]


def test_no_processor_default_is_written_outside_the_schema() -> None:
    import re

    hits = []
    for path in _sources():
        code = _code_only(path)
        for what, pattern in LITERAL_DEFAULTS:
            if (str(path.relative_to(ROOT)), what) in NOT_A_COPY:
                continue
            for m in re.finditer(pattern, code):
                hits.append(f"{path.relative_to(ROOT)}: {what}: {m.group(0)!r}")
    assert not hits, "\n".join(hits)


def test_the_literal_scan_finds_a_copied_default(tmp_path: Path) -> None:
    py = tmp_path / "m.py"
    py.write_text('"""rate_hz = 400.0 in a docstring is fine"""\n'
                  "def f(rate_hz: float = 400.0) -> None: ...\n")
    cpp = tmp_path / "m.hpp"
    cpp.write_text("// stuck_samples = 50 in a comment is fine\n"
                   "std::uint32_t stuck_samples = 50;\n")
    import re

    for path, what in ((py, "sample rate"), (cpp, "stuck count")):
        pattern = dict(LITERAL_DEFAULTS)[what]
        assert len(re.findall(pattern, _code_only(path))) == 1, path


def test_wrong_units_message_reads_as_english() -> None:
    # regression: "wrong units for a n accelerometer channel"
    text = dumps_config(default_config()).replace("bias_m_s2", "bias_rad_s", 1)
    with pytest.raises(ConfigError, match=r"^channels\.ax\.stages\[0\]\.bias_rad_s: wrong units "
                                          r"for an accelerometer channel \(m/s\^2\): use "
                                          r"bias_m_s2$"):
        parse_config(text)


# ------------------------------------------------------------------ the hostile corpus
# tests/data/config_corpus: valid and invalid files (TOML 1.0 forms the format reads, what
# TOML refuses, what the format refuses, encodings, NUL bytes, nesting, duplicate tables,
# float32 limits), each with its expected verdict in expected.json: "ok", the key the error
# must name, or for an error of the whole file its reason ("not valid TOML", "not a UTF-8
# text file", after the file's name). Both readers must give exactly that.
CORPUS = ROOT / "tests" / "data" / "config_corpus"
EXPECTED: dict[str, str] = __import__("json").loads((CORPUS / "expected.json").read_text())
FILE_ERRORS = ("not valid TOML", "not a UTF-8 text file")


def _verdict(path: Path, message: str | None) -> str:
    """'ok', the key named, or the reason of an error of the whole file."""
    if message is None:
        return "ok"
    prefix = f"{path}: "
    assert message.startswith(prefix), message
    rest = message[len(prefix):]
    for reason in FILE_ERRORS:
        if rest.startswith(reason):
            return reason
    assert "\n" not in rest, message  # one line
    return rest.split(": ", 1)[0]


def test_corpus_is_complete() -> None:
    files = {p.name for p in CORPUS.glob("*.toml")}
    assert files == set(EXPECTED)
    verdicts = list(EXPECTED.values())
    assert verdicts.count("ok") >= 15 and verdicts.count("not valid TOML") >= 40
    assert len([v for v in verdicts if v not in ("ok", *FILE_ERRORS)]) >= 30


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_corpus_python_reader(name: str) -> None:
    from gyrodrift.imu.config import load_config

    path = CORPUS / name
    try:
        load_config(path)
        message = None
    except ConfigError as exc:
        message = f"{path}: {exc}" if not str(exc).startswith(str(path)) else str(exc)
    assert _verdict(path, message) == EXPECTED[name], message


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_corpus_loop_reader(name: str, loop_check: Path) -> None:
    path = CORPUS / name
    r = subprocess.run([str(loop_check), "--check-config", str(path)], capture_output=True,
                       text=True, timeout=20)
    if r.returncode == 0:
        assert r.stdout.strip() == f"{path}: ok", r.stdout
        message = None
    else:
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1, r.stderr  # one line, never a trace
        message = lines[0].removeprefix("gyrodrift-loop: error: ")
    assert _verdict(path, message) == EXPECTED[name], message


@pytest.mark.parametrize("name,needle", [
    ("toml_deep_array.toml", "not valid TOML: tables or arrays nested deeper than 128"),
    ("toml_deep_inline_table.toml", "not valid TOML: tables or arrays nested deeper than 128"),
    ("f32_r_underflow.toml", "channels.gx.stages[1].r: 1e-50 does not fit a float32"),
])
def test_config_command_refuses_in_one_line(name: str, needle: str, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    # `config validate` on 5000-deep arrays raised RecursionError; `emit-cpp` wrote r = 0.0f.
    from gyrodrift.cli import main

    path = CORPUS / name
    assert main(["config", "validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gyrodrift config: error: ") and needle in err
    assert err.count("\n") == 1, err
    out = tmp_path / "h.hpp"
    assert main(["config", "emit-cpp", str(path), "-o", str(out)]) == 2
    assert needle in capsys.readouterr().err and not out.exists()
