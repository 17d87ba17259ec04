"""Pages of the documentation site generated from the package at every build.

- ``api/<module>.rst``: one page per public module, an autosummary table of every name in its
  ``__all__`` and, for the names the module defines, their full documentation (a re-exported
  name links to the page of the module that defines it). The list of modules and names comes
  from walking the package, so a new module or name cannot be left out.
- ``_generated/config_fields.md``: the configuration file's fields, from
  :mod:`gyrodrift.imu.schema`.
- ``_generated/units.md``: the unit tables, from :mod:`gyrodrift.units`.
- ``_generated/flag_table.md``: the processor's sample flags, from the C++ contract.
- ``cpp/<area>.rst``: the C++ reference of each header area; Doxygen's XML (for breathe) is
  regenerated when a header changes.
"""

from __future__ import annotations

import hashlib
import importlib
import inspect
import math
import os
import pkgutil
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent
API = DOCS / "api"
GENERATED = DOCS / "_generated"
CPP = DOCS / "cpp"
DOXYGEN_OUT = DOCS / "_build" / "doxygen"


# ------------------------------------------------------------------ the public names


def public_modules() -> list[str]:
    """Every public module of the package (no ``_private`` part, no ``__main__``), sorted."""
    import gyrodrift

    names = ["gyrodrift"]
    for info in pkgutil.walk_packages([os.path.dirname(gyrodrift.__file__)], "gyrodrift."):
        parts = info.name.split(".")
        if parts[-1] == "__main__" or any(p.startswith("_") for p in parts[1:]):
            continue
        names.append(info.name)
    return sorted(set(names))


def _kind(obj: Any) -> str:
    if inspect.isclass(obj):
        return "exception" if issubclass(obj, BaseException) else "class"
    if inspect.isroutine(obj) or hasattr(obj, "__wrapped__"):
        return "function"
    return "data"


def public_names() -> dict[str, list[tuple[str, str, str]]]:
    """module -> [(name, kind, canonical module)] for every name in every public ``__all__``.

    The canonical module of a name is where it is documented: the module that defines it when
    that module is public and exports it, else the deepest public module exporting the same
    object.
    """
    modules = {m: importlib.import_module(m) for m in public_modules()}
    missing = sorted(m for m, mod in modules.items() if not hasattr(mod, "__all__"))
    if missing:
        raise RuntimeError(f"public modules without __all__ (the API reference lists what "
                           f"__all__ names): {', '.join(missing)}")
    # Objects fetched once (a module may build an attribute on each access).
    objects = {m: {name: getattr(mod, name) for name in mod.__all__}
               for m, mod in modules.items()}
    exporters: dict[tuple[str, int], list[str]] = {}
    for m, objs in objects.items():
        for name, obj in objs.items():
            exporters.setdefault((name, id(obj)), []).append(m)
    out: dict[str, list[tuple[str, str, str]]] = {}
    for m, objs in objects.items():
        rows = []
        for name, obj in objs.items():
            candidates = exporters[(name, id(obj))]
            defining = getattr(obj, "__module__", None) if _kind(obj) != "data" else None
            if defining in candidates:
                canonical = defining
            else:
                canonical = max(candidates, key=lambda c: (c.count("."), c))
            rows.append((name, _kind(obj), canonical))
        out[m] = rows
    return out


def _title(text: str, char: str = "=") -> str:
    return f"{text}\n{char * len(text)}\n"


def write_if_changed(path: Path, text: str) -> None:
    """Write only when the text differs, so Sphinx rereads only the pages that changed."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def generate_api() -> None:
    names = public_names()
    keep = set()
    for m, rows in names.items():
        lines = [".. Generated from the package by docs/_ext/gyrodrift_docs.py; do not edit.\n",
                 _title(f"``{m}``"),
                 f".. automodule:: {m}\n   :no-members:\n",
                 ".. rubric:: Names\n",
                 ".. autosummary::\n   :nosignatures:\n"]
        for name, _, canon in rows:
            # Relative to the page's module where possible (autosummary resolves it there).
            if canon == m:
                lines.append(f"   {name}")
            elif canon.startswith(m + "."):
                lines.append(f"   ~{canon[len(m) + 1:]}.{name}")
            else:
                lines.append(f"   ~{canon}.{name}")
        lines.append("")
        own = [(name, kind) for name, kind, canon in rows if canon == m]
        if own:
            lines.append(".. rubric:: Reference\n")
            lines.append(f".. currentmodule:: {m}\n")
        for name, kind in own:
            if kind in ("class", "exception"):
                lines.append(f".. auto{kind}:: {name}\n   :members:\n")
            else:
                lines.append(f".. auto{kind}:: {name}\n")
        path = API / f"{m}.rst"
        keep.add(path.name)
        write_if_changed(path, "\n".join(lines))
    for old in API.glob("gyrodrift*.rst"):
        if old.name not in keep:
            old.unlink()


# ------------------------------------------------------------------ tables from the code


def _md_escape(text: str) -> str:
    return str(text).replace("|", "\\|")


def _default_text(default: Any) -> str:
    from gyrodrift.imu.schema import REQUIRED

    if default is REQUIRED:
        return "required"
    if default is None:
        return "derived (see the description)"
    if isinstance(default, bool):
        return "true" if default else "false"
    if isinstance(default, float) and math.isinf(default):
        return "inf"
    if isinstance(default, str):
        return f'"{default}"'
    return repr(default)


def generate_config_fields() -> None:
    from gyrodrift.imu import schema

    lines = ["<!-- Generated from gyrodrift.imu.schema by docs/_ext/gyrodrift_docs.py. -->", ""]
    for section in schema.SECTIONS:
        lines += [f"### `{section}`", "",
                  "| key | type | unit | default | accepted values | meaning |",
                  "| --- | --- | --- | --- | --- | --- |"]
        for f in schema.FIELDS:
            if f.section != section:
                continue
            if f.unit == "channel":
                key = f"`{f.key('gx')}` (gyros), `{f.key('ax')}` (accelerometers)"
                unit = "rad/s or m/s^2"
            else:
                key = f"`{f.name}`"
                unit = {"channel^2": "(rad/s)^2 or (m/s^2)^2"}.get(f.unit, f.unit or "-")
            lines.append(f"| {key} | {f.kind} | {_md_escape(unit)} | "
                         f"{_md_escape(_default_text(f.default))} | "
                         f"{_md_escape(f.bounds_text())} | {_md_escape(f.help)} |")
        lines.append("")
    write_if_changed(GENERATED / "config_fields.md", "\n".join(lines))


def generate_units() -> None:
    from gyrodrift import units

    lines = ["<!-- Generated from gyrodrift.units by docs/_ext/gyrodrift_docs.py. -->", "",
             "| sensor | term | SI unit | IEEE 952 display unit | display value of 1 SI unit |",
             "| --- | --- | --- | --- | --- |"]
    for sensor, terms in units.TERM_UNITS.items():
        for term, u in terms.items():
            lines.append(f"| {sensor} | {term} | {_md_escape(u.si)} | {_md_escape(u.ieee)} | "
                         f"{u.ieee_factor:.6g} |")
    lines += ["", "| input unit (`--gyro-units`) | kind | factor to rad/s (rad) | "
              "factor to deg/h (deg) |", "| --- | --- | --- | --- |"]
    for name, u in units.RATE_UNITS.items():
        lines.append(f"| `{name}` | rate | {u.to_rad_s:.10g} | {u.to_deg_h:.10g} |")
    for name, u in units.INCREMENT_UNITS.items():
        lines.append(f"| `{name}` | angle increment per sample | {u.to_rad_s:.10g} | "
                     f"{u.to_deg_h:.10g} |")
    lines += ["", "| input unit (`--accel-units`) | kind | factor to m/s^2 (m/s) |",
              "| --- | --- | --- |"]
    for name, f in units.ACCEL_UNITS.items():
        lines.append(f"| `{name}` | acceleration | {f:.10g} |")
    for name, f in units.ACCEL_INCREMENT_UNITS.items():
        lines.append(f"| `{name}` | velocity increment per sample | {f:.10g} |")
    lines.append("")
    write_if_changed(GENERATED / "units.md", "\n".join(lines))


# ------------------------------------------------------------------ C++ reference

CPP_AREAS = {
    "filters": "Filters: AR(2) models and Kalman filters, lifting wavelets, the real-time "
               "prefilter, the drift likelihood",
    "stability": "Stability: the Allan deviation family kernels",
    "codecs": "Codecs: serial frame, CAN frames and signals, SLCAN",
    "imu": "IMU processor and its configuration schema",
    "nav": "Navigation: Earth model, attitude, strapdown, alignment",
}

# The headers' comments are plain ``//`` lines; Doxygen reads the ones that start a line as
# documentation (a comment before a declaration documents it).
DOXYFILE = """
PROJECT_NAME = gyrodrift
OUTPUT_DIRECTORY = {out}
INPUT = {inc}
RECURSIVE = YES
FILE_PATTERNS = *.hpp
EXCLUDE_PATTERNS = */lifting_coefficients_*.hpp
EXCLUDE_SYMBOLS = detail *_detail *::detail::* *_detail::*
INPUT_FILTER = "sed -e 's@^\\([[:space:]]*\\)//\\([^/]\\)@\\1///\\2@'"
FILTER_SOURCE_FILES = NO
AUTOLINK_SUPPORT = NO
SHOW_INCLUDE_FILES = NO
HAVE_DOT = NO
INCLUDE_GRAPH = NO
INCLUDED_BY_GRAPH = NO
XML_PROGRAMLISTING = NO
SOURCE_BROWSER = NO
GENERATE_XML = YES
GENERATE_HTML = NO
GENERATE_LATEX = NO
EXTRACT_ALL = YES
EXTRACT_PRIVATE = NO
EXTRACT_STATIC = YES
EXTRACT_ANON_NSPACES = NO
HIDE_UNDOC_MEMBERS = NO
MACRO_EXPANSION = YES
ENABLE_PREPROCESSING = YES
STRIP_FROM_PATH = {inc}
QUIET = YES
WARNINGS = NO
WARN_IF_UNDOCUMENTED = NO
"""


def run_doxygen() -> None:
    """Doxygen's XML of include/gyrodrift, redone when a header (or this file) changes."""
    inc = ROOT / "include"
    digest = hashlib.sha256(Path(__file__).read_bytes())
    for h in sorted(inc.rglob("*.hpp")):
        digest.update(str(h.relative_to(inc)).encode())
        digest.update(h.read_bytes())
    stamp = DOXYGEN_OUT / "stamp"
    if stamp.exists() and stamp.read_text() == digest.hexdigest() and (
            DOXYGEN_OUT / "xml" / "index.xml").exists():
        return
    doxygen = shutil.which("doxygen")
    if doxygen is None:
        raise RuntimeError("doxygen is not installed (Debian package doxygen; scripts/setup)")
    if DOXYGEN_OUT.exists():
        shutil.rmtree(DOXYGEN_OUT)
    DOXYGEN_OUT.mkdir(parents=True)
    config = DOXYFILE.format(out=DOXYGEN_OUT, inc=inc / "gyrodrift")
    with open(DOXYGEN_OUT / "doxygen.log", "wb") as log:  # its notes on the comments' markup
        subprocess.run([doxygen, "-"], input=config.encode(), check=True, cwd=ROOT,
                       stdout=log, stderr=log)
    # A class's "#include <...>" line links to its header's file page, which the site does not
    # have (each header is a section of its area's page): keep the line, drop the link.
    for xml in (DOXYGEN_OUT / "xml").glob("*.xml"):
        text = xml.read_text()
        new = re.sub(r'<includes refid="[^"]*" ', "<includes ", text)
        if new != text:
            xml.write_text(new)
    stamp.write_text(digest.hexdigest())


def cpp_areas() -> dict[str, str]:
    """Every header area (a folder of include/gyrodrift) -> its page title: a new area gets a
    page without an edit here (titled by its name until CPP_AREAS gives it one)."""
    inc = ROOT / "include" / "gyrodrift"
    return {d.name: CPP_AREAS.get(d.name, f"{d.name.capitalize()} headers")
            for d in sorted(inc.iterdir()) if d.is_dir() and any(d.glob("*.hpp"))}


def generate_cpp_pages() -> None:
    inc = ROOT / "include" / "gyrodrift"
    areas = cpp_areas()
    for area, title in areas.items():
        lines = [".. Generated from include/gyrodrift by docs/_ext/gyrodrift_docs.py.\n",
                 _title(title),
                 f"Umbrella header: ``#include <gyrodrift/{area}.hpp>``.\n"]
        for h in sorted((inc / area).glob("*.hpp")):
            if h.name.startswith("lifting_coefficients_"):
                continue
            lines += [_title(f"<gyrodrift/{area}/{h.name}>", "-"),
                      f".. doxygenfile:: {h.name}\n   :project: gyrodrift\n"]
        write_if_changed(CPP / f"{area}.rst", "\n".join(lines))
    for old in CPP.glob("*.rst"):
        if old.stem not in areas:
            old.unlink()


# ------------------------------------------------------------------ Sphinx hooks

_ALIASES: dict[str, str] = {}


def _aliases() -> dict[str, str]:
    """Every public spelling of a name -> where it is documented: ``gyrodrift.oadev`` ->
    ``gyrodrift.stability.allan.oadev``; an unqualified name that is unique among the public
    names (``CliError``) -> its documented name."""
    if not _ALIASES:
        short: dict[str, set[str]] = {}
        for m, rows in public_names().items():
            for name, _, canon in rows:
                _ALIASES[f"{m}.{name}"] = f"{canon}.{name}"
                short.setdefault(name, set()).add(f"{canon}.{name}")
        for name, targets in short.items():
            if len(targets) == 1:
                _ALIASES.setdefault(name, next(iter(targets)))
    return _ALIASES


def _resolve_alias(app: Any, env: Any, node: Any, contnode: Any) -> Any:
    """A Python reference to a re-exported spelling resolves to the documented object; any
    other missing reference stays missing (and fails the build)."""
    if node.get("refdomain") != "py":
        return None
    target = node.get("reftarget", "")
    canon = _aliases().get(target)
    if canon is None or canon == target:
        return None
    domain = env.get_domain("py")
    builder = app.builder
    node = node.deepcopy()
    node["reftarget"] = canon
    for role in (node.get("reftype"), "obj"):
        found = domain.resolve_xref(env, node["refdoc"], builder, role, canon, node, contnode)
        if found is not None:
            return found
    return None



def _generate(app: Any) -> None:
    generate_api()
    generate_config_fields()
    generate_units()
    run_doxygen()
    generate_cpp_pages()


def _drop_type_docstring(app: Any, what: str, name: str, obj: Any, options: Any,
                         lines: list[str]) -> None:
    """A constant without a ``#:`` comment would show its type's docstring (a numpy dtype's,
    a dict's): its module's docstring describes it instead."""
    if what in ("data", "attribute") and not (inspect.isclass(obj) or inspect.isroutine(obj)):
        own = inspect.getdoc(obj)
        if own is not None and own == inspect.getdoc(type(obj)):
            lines[:] = []


def _always_reread(app: Any, env: Any, added: set[str], changed: set[str],
                   removed: set[str]) -> list[str]:
    """The command line page is generated from the argument parsers, not from its source
    file: an incremental build would keep a stale page after a new subcommand or flag."""
    return [d for d in ALWAYS_REREAD if d in env.found_docs]


#: Pages whose content comes from code rather than from their source file.
ALWAYS_REREAD = ("cli",)


def setup(app: Any) -> dict[str, Any]:
    # Before sphinx-gallery (priority 500) and before Sphinx reads the sources.
    app.connect("config-inited", lambda app, config: _generate(app), priority=400)
    app.connect("env-get-outdated", _always_reread)
    app.connect("missing-reference", _resolve_alias)
    app.connect("autodoc-process-docstring", _drop_type_docstring, priority=100)
    return {"parallel_read_safe": True, "parallel_write_safe": True, "version": "1"}
