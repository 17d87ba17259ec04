"""Every file the package writes goes through the one output rule (gyrodrift.io.atomic,
docs/guides/output-files.md): a static check of python/gyrodrift. A call that writes a file
(``Path.write_text``/``write_bytes``, ``open``/``os.fdopen``/``Path.open`` for writing,
``numpy.save``, ``savefig``, ``open_memmap`` for writing) must sit inside a
``with atomic_output(...)`` block, or be one of the listed writes into files the package
made for itself (temporary files and directories), each with its reason. Before, the CAN
decode table, the firmware check's budget.json and the firmware build's config.toml were
written in place with ``write_text``."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "gyrodrift"

#: (module, function) -> why its write need not go through atomic_output.
ALLOWED: dict[tuple[str, str], str] = {
    ("io/atomic.py", "_write_through"): "the rule itself: copies the finished output into a "
                                        "device or FIFO",
    ("io/imu_log.py", "_write_samples"): "called with the temporary file of write_samples' "
                                          "atomic_output",
    ("io/imu_data.py", "spool"): "spool files in the caller's temporary directory",
    ("io/spool.py", "append"): "a normalized record's samples in its own temporary directory",
    ("papers/table1.py", "_write_report"): "the temporary files of atomic_output entered "
                                           "through an ExitStack",
    ("stability/gmwm.py", "_spool_replicate"): "a bootstrap replicate in a temporary "
                                               "directory the bootstrap made and removes",
    ("papers/table1.py", "_spool"): "a filtered record in a temporary directory the "
                                    "comparison made and removes",
    ("replay/firmware.py", "cached_firmware"): "image.json inside a fresh mkdtemp directory, "
                                               "renamed into place whole",
    ("replay/harness.py", "start"): "the decode table in a mkstemp file for the loop "
                                    "process, removed afterwards",
    ("workflows/characterize.py", "plot_sensor"): "renders into an in-memory buffer",
    ("workflows/fleet.py", "_start_peak_window"): "/proc/self/clear_refs, a kernel control "
                                                  "file",
    ("workflows/fleet.py", "_boxplot"): "renders into an in-memory buffer",
}


def _is_write_call(node: ast.Call) -> bool:
    f = node.func
    name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
    if name in ("write_text", "write_bytes", "savefig", "tofile"):
        return True
    if name == "save" and isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) \
            and f.value.id == "np":
        return True
    mode = None
    if name in ("open", "fdopen", "open_memmap"):
        args = [a for a in node.args[1:2]] + [k.value for k in node.keywords
                                               if k.arg == "mode"]
        if name == "open" and isinstance(f, ast.Attribute) and f.attr == "open" \
                and not (isinstance(f.value, ast.Name) and f.value.id == "os"):
            args = node.args[:1] + [k.value for k in node.keywords if k.arg == "mode"]
        for a in args:
            if isinstance(a, ast.Constant) and isinstance(a.value, str):
                mode = a.value
        return mode is not None and any(c in mode for c in "wax+")
    return False


def _inside_atomic(stack: list[ast.AST]) -> bool:
    for node in stack:
        if isinstance(node, (ast.With, ast.AsyncWith)):
            for item in node.items:
                e = item.context_expr
                if isinstance(e, ast.Call):
                    fn = e.func
                    nm = fn.attr if isinstance(fn, ast.Attribute) else getattr(fn, "id", "")
                    if nm == "atomic_output":
                        return True
    return False


def _writes_outside_the_rule(used: set[tuple[str, str]] | None = None) -> list[str]:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"))

        def visit(node: ast.AST, stack: list[ast.AST], func: str, rel: str = rel) -> None:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                func = node.name
            if isinstance(node, ast.Call) and _is_write_call(node) \
                    and not _inside_atomic(stack):
                if (rel, func) in ALLOWED:
                    if used is not None:
                        used.add((rel, func))
                else:
                    found.append(f"{rel}:{node.lineno} ({func}): {ast.unparse(node)[:80]}")
            for child in ast.iter_child_nodes(node):
                visit(child, [*stack, node], func)

        visit(tree, [], "<module>")
    return found


def test_every_file_write_goes_through_the_output_rule() -> None:
    used: set[tuple[str, str]] = set()
    assert _writes_outside_the_rule(used) == []
    assert set(ALLOWED) - used == set(), "allowed writes that no longer exist"


def test_the_check_sees_a_write_in_place() -> None:
    """The check itself: a write_text outside atomic_output is found, one inside is not."""
    bad = ast.parse("def f(p):\n    p.write_text('x')\n").body[0].body[0].value
    assert isinstance(bad, ast.Call) and _is_write_call(bad)
    tree = ast.parse("with atomic_output(p) as tmp:\n    tmp.write_text('x')\n")
    with_node = tree.body[0]
    call = with_node.body[0].value
    assert _is_write_call(call) and _inside_atomic([tree, with_node])
    assert _is_write_call(ast.parse("open(p, 'w')").body[0].value)
    assert not _is_write_call(ast.parse("open(p, 'rb')").body[0].value)
    assert _is_write_call(ast.parse("p.open('w', newline='')").body[0].value)
