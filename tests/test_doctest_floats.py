"""No docstring example expects a float to its last digits.

The examples run as doctests on every machine (tests/test_api.py). A computed float printed
with all its digits depends on the last bits of a sum or of a library routine, which differ
between machines (a fresh machine failed on ``...7761489e-06`` vs ``...7761487e-06``). This
scan reads every docstring of the package and fails on an expected output holding a float
literal of 12 or more significant digits, also when an ellipsis cuts it
(``9.9339075777614...e-06``): such an example must round or format what it prints.

Nor does an example expect numpy 2's repr of a numpy scalar (``np.float32(9.8)``,
``np.True_``): numpy 1 prints the same value as ``9.8`` and ``True``. tests/test_api.py runs
the examples with the installed numpy's own print options, so an example printing a numpy
scalar the numpy 1 way fails there; together the two checks leave examples that print
Python values, the same under every supported numpy.
"""

from __future__ import annotations

import ast
import doctest
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "python" / "gyrodrift"
#: Significant digits from which an expected float is refused (a float64 carries 15-17).
MAX_DIGITS = 12
# A decimal literal with a fraction or an exponent; an ellipsis may follow the digits.
_FLOAT = re.compile(r"(?<![\w.])[-+]?(?P<mant>\d+\.\d*|\.\d+)(?:\.\.\.)?(?:[eE][-+]?\d+)?")


# numpy 2's repr of a numpy scalar: np.float32(9.8), np.int64(3), np.str_('a'), np.True_.
_NUMPY_SCALAR = re.compile(
    r"\bnp\.(?:(?:float|int|uint|complex|bool|str|bytes|longdouble|clongdouble|datetime64"
    r"|timedelta64|void)\w*\(|True_|False_)")


def long_floats(text: str) -> list[str]:
    """The float literals in `text` with MAX_DIGITS or more significant digits (an
    ellipsis-cut one included)."""
    out = []
    for m in _FLOAT.finditer(text):
        digits = m.group("mant").replace(".", "").lstrip("0")
        if len(digits) >= MAX_DIGITS:
            out.append(m.group(0))
    return out


def _expected_outputs() -> list[tuple[str, str, str]]:
    """(where, example source, expected output) of every docstring example in the package."""
    parser = doctest.DocTestParser()
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if not isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef
                              | ast.AsyncFunctionDef):
                continue
            doc = ast.get_docstring(node, clean=True)
            if not doc or ">>>" not in doc:
                continue
            where = f"{path.relative_to(PACKAGE.parent)}:{getattr(node, 'lineno', 1)}"
            for ex in parser.get_examples(doc):
                found.append((where, ex.source.strip(), ex.want))
    return found


def test_the_scan_finds_the_examples() -> None:
    examples = _expected_outputs()
    assert len(examples) > 500  # every module has examples; the scan must see them
    assert any("kalibr_yaml" in src for _, src, _ in examples)


def test_no_expected_output_holds_a_float_to_its_last_digits() -> None:
    bad = [f"{where}: {src[:60]!r} expects {', '.join(long_floats(want))}"
           for where, src, want in _expected_outputs() if long_floats(want)]
    assert not bad, ("examples that print a computed float with all its digits (round or "
                     "format it):\n" + "\n".join(bad))


def test_the_scan_catches_the_case_that_failed() -> None:
    """The example that failed on a fresh machine, and its ellipsis form, are caught;
    rounded and formatted values are not."""
    assert long_floats("gyroscope_noise_density: 9.933907577761489e-06  # rad/s")
    assert long_floats("gyroscope_noise_density: 9.9339075777614...e-06  # rad/s")
    assert not long_floats("('9.934e-06', 'rad/s/sqrt(Hz)') (1.414214, 6) 0.1 100.0 1e-07")
    assert not long_floats("update_rate: 100.0\nseed 20261121, 4096 samples")


def test_no_expected_output_holds_a_numpy_2_scalar_repr() -> None:
    bad = [f"{where}: {src[:60]!r} expects {_NUMPY_SCALAR.findall(want)}"
           for where, src, want in _expected_outputs() if _NUMPY_SCALAR.search(want)]
    assert not bad, ("examples that expect numpy 2's repr of a numpy scalar (print a Python "
                     "value: float(), bool(), str(), .tolist()):\n" + "\n".join(bad))


def test_the_numpy_scalar_scan_catches_numpy_2_reprs() -> None:
    for text in ("np.float32(9.8)", "(1, np.int64(3))", "np.True_", "[np.str_('acf')]",
                 "np.uint16(65535)", "np.bool(False)"):
        assert _NUMPY_SCALAR.search(text), text
    for text in ("9.8", "array([1, 2], dtype=uint16)", "dtype('float32')", "True",
                 "np.random.default_rng(0)"):
        assert not _NUMPY_SCALAR.search(text), text
