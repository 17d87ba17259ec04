"""The user's manual: the README and the documentation site.

- The site builds with warnings as errors (``bash scripts/docs``: the tutorials run, every
  cross-reference resolves), and the configuration turns a broken reference into a failure.
- Every name in every public ``__all__`` is in the API reference; every subcommand and every
  flag is in the command line reference.
- Headless Chromium opens the built index, a tutorial and an API page (title, figure) and the
  search page finds a name; a screenshot is kept under docs/_build/screenshots.
- The README is short, its commands and its Python example run as written.
- No user page names internal work items, sessions or the team.
"""

from __future__ import annotations

import html as html_lib
import importlib
import inspect
import os
import pkgutil
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import gyrodrift
import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
HTML = DOCS / "_build" / "html"
README = ROOT / "README.md"


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["GYRODRIFT_DOCS_PYTHON"] = sys.executable
    env["MPLBACKEND"] = "Agg"
    # The package this test imports (a development tree or the installed copy) is the one the
    # documentation describes.
    pkg_parent = str(Path(gyrodrift.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join(
        [pkg_parent, *[p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]])
    return env


@pytest.fixture(scope="module")
def site() -> Path:
    """The site built by ``bash scripts/docs`` (incremental: only what changed is redone).

    The tests that read the site share one xdist group (one worker builds it once); the file
    lock keeps any other process building into the same docs/_build (a second test run in this
    tree) from interleaving with this build."""
    from filelock import FileLock

    (DOCS / "_build").mkdir(exist_ok=True)
    with FileLock(DOCS / "_build" / "build.lock"):
        r = subprocess.run(["bash", str(ROOT / "scripts" / "docs")], cwd=ROOT, env=_env(),
                           capture_output=True, text=True, timeout=1800, check=False)
    assert r.returncode == 0, f"docs build failed:\n{r.stdout[-4000:]}\n{r.stderr[-6000:]}"
    assert (HTML / "index.html").is_file()
    return HTML


# ------------------------------------------------------------------ the build and its checks


def _tiny_build(tmp_path: Path, page: str) -> subprocess.CompletedProcess[str]:
    """Build one page with the site's own configuration (its warning rules), without the
    tutorials, the C++ reference and the generated pages."""
    src = tmp_path / "src"
    src.mkdir(parents=True)
    (src / "conf.py").write_text(textwrap.dedent(f"""
        __file__ = {str(DOCS / "conf.py")!r}
        exec(compile(open(__file__).read(), __file__, "exec"))
        extensions = [e for e in extensions
                      if e not in ("sphinx_gallery.gen_gallery", "breathe", "gyrodrift_docs")]
        exclude_patterns = ["_build"]
        """))
    (src / "index.md").write_text(page)
    (src / "other.md").write_text("# Other\n\n## A heading\n\nText.\n")
    return subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-q", str(src),
         str(tmp_path / "out")], env=_env(), capture_output=True, text=True, timeout=300,
        check=False)


GOOD_PAGE = """# Index

```{py:function} demo_function(x)
A documented function.
```

See {py:func}`demo_function` and [the other page](other.md#a-heading).

```{toctree}
other
```
"""


def test_site_configuration_fails_on_a_broken_reference(tmp_path: Path) -> None:
    """The good page builds; a page with a missing name, a link to a missing page and a link
    to a missing heading does not, and each of the three is reported as a warning (any one
    of which fails a -W build; one build checks all three, the tiny builds cost seconds each)."""
    good = _tiny_build(tmp_path / "good", GOOD_PAGE)
    assert good.returncode == 0, good.stderr[-3000:]
    bad = _tiny_build(tmp_path / "bad", GOOD_PAGE.replace("`demo_function`", "`no_such_function`")
                      + "\nSee [a missing page](missing.md#x) and [a missing heading]"
                        "(other.md#nowhere).\n")
    assert bad.returncode != 0
    warnings = [ln for ln in bad.stderr.splitlines() if "WARNING" in ln or "ERROR" in ln]
    for needle in ("no_such_function", "missing", "nowhere"):
        assert any(needle in ln for ln in warnings), (needle, bad.stderr[-3000:])


@pytest.mark.xdist_group("docs_site")
def test_site_builds_with_warnings_as_errors(site: Path) -> None:
    for page in ("index.html", "cli.html", "api/index.html", "cpp/index.html",
                 "auto_tutorials/index.html", "changelog.html", "contributing.html"):
        assert (site / page).is_file(), page
    # the contributing page includes CONTRIBUTING.md
    assert "Where a new piece goes" in (site / "contributing.html").read_text()


# ------------------------------------------------------------------ API and CLI references


def _public_modules() -> list[str]:
    names = ["gyrodrift"]
    for info in pkgutil.walk_packages([os.path.dirname(gyrodrift.__file__)], "gyrodrift."):
        parts = info.name.split(".")
        if parts[-1] == "__main__" or any(p.startswith("_") for p in parts[1:]):
            continue
        names.append(info.name)
    return sorted(set(names))


def _ids(text: str) -> set[str]:
    return set(re.findall(r'\bid="([^"]+)"', text))


@pytest.mark.xdist_group("docs_site")
def test_every_public_name_is_in_the_api_reference(site: Path) -> None:
    """Each public module has a page listing every name of its ``__all__``, and each name is
    documented (an anchor ``module.name`` holding the same object) on some API page."""
    pages = {p.stem: p.read_text() for p in (site / "api").glob("gyrodrift*.html")}
    documented: dict[str, object] = {}
    for text in pages.values():
        for ident in _ids(text):
            if ident.startswith("gyrodrift.") and ident.count(".") >= 1:
                documented[ident] = None
    missing = []
    for modname in _public_modules():
        assert modname in pages, f"no API page for {modname}"
        mod = importlib.import_module(modname)
        listed = {html_lib.unescape(m) for m in
                  re.findall(r'<span class="pre">([^<]+)</span>', pages[modname])}
        for name in mod.__all__:
            obj = getattr(mod, name)
            if name not in listed:
                missing.append(f"{modname}: {name} not in its table")
                continue
            # where it is documented: an anchor whose import path gives the same object
            owners = [i for i in documented if i.rsplit(".", 1)[-1] == name]
            ok = False
            for ident in owners:
                owner_mod, _, attr = ident.rpartition(".")
                try:
                    ok = getattr(importlib.import_module(owner_mod), attr) is obj or (
                        not callable(obj) and getattr(importlib.import_module(owner_mod),
                                                      attr) == obj)
                except ImportError:
                    continue
                if ok:
                    break
            if not ok:
                missing.append(f"{modname}.{name} documented nowhere")
    assert not missing, missing


def _docutils_messages(text: str) -> list[str]:
    """docutils' warnings and errors on reST text (Sphinx's cross-reference roles and the
    directives numpydoc emits are accepted as they are; Sphinx resolves them)."""
    import io

    import docutils.core
    from docutils import nodes
    from docutils.parsers.rst import Directive, directives, roles

    def literal_role(name: str, rawtext: str, text: str, lineno: int, inliner: object,
                     options: object = None, content: object = None,
                     ) -> tuple[list[nodes.Node], list[nodes.system_message]]:
        return [nodes.literal(rawtext, text)], []

    for role in ("func", "class", "mod", "meth", "attr", "data", "obj", "exc", "doc", "ref",
                 "math", "term"):
        roles.register_local_role(role, literal_role)
        roles.register_local_role(f"py:{role}", literal_role)

    class AnyOptions(dict):  # type: ignore[type-arg]
        def __missing__(self, key: str) -> object:
            return directives.unchanged

    class Ignored(Directive):
        has_content = True
        optional_arguments = 10
        final_argument_whitespace = True
        option_spec = AnyOptions()

        def run(self) -> list[nodes.Node]:
            return []

    for name in ("seealso", "only", "autosummary", "versionadded", "versionchanged",
                 "deprecated"):
        directives.register_directive(name, Ignored)
    stream = io.StringIO()
    docutils.core.publish_doctree(text, settings_overrides={
        "report_level": 2, "halt_level": 5, "warning_stream": stream})
    return [ln for ln in stream.getvalue().splitlines()
            if "(WARNING/" in ln or "(ERROR/" in ln or "(SEVERE/" in ln]


def test_docstrings_are_valid_numpydoc_and_rest() -> None:
    """Every public module's docstring and the docstring of every name a public module defines
    and exports, as numpydoc renders it, is valid reST: no "unexpected indentation", no
    ``|x|`` read as a substitution, no ``C_`` read as a link target. The site build (-W) fails
    on the same; this finds it in seconds, without building the site."""
    import warnings

    from numpydoc.docscrape_sphinx import SphinxDocString

    problems = []
    for modname in _public_modules():
        mod = importlib.import_module(modname)
        objects = [(modname, mod)] + [
            (f"{modname}.{n}", getattr(mod, n)) for n in mod.__all__
            if getattr(getattr(mod, n), "__module__", None) == modname]
        for qualname, obj in objects:
            if not (inspect.ismodule(obj) or inspect.isclass(obj) or inspect.isroutine(obj)):
                continue
            doc = inspect.getdoc(obj)
            if not doc:
                continue
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # a module's own section titles
                text = str(SphinxDocString(doc, config={"show_class_members": False}))
            problems += [f"{qualname}: {m}" for m in _docutils_messages(text)]
    assert not problems, "\n".join(problems)


@pytest.mark.xdist_group("docs_site")
def test_every_subcommand_and_flag_is_in_the_cli_reference(site: Path) -> None:
    import argparse

    from gyrodrift.cli import build_parser

    text = (site / "cli.html").read_text()
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert sub.choices, "no subcommands"
    starts = {name: text.find(f'id="gyrodrift-{name}"') for name in sub.choices}
    missing = [name for name, i in starts.items() if i < 0]
    assert not missing, f"subcommands without a section: {missing}"
    order = [*sorted(starts.values()), len(text)]
    problems = []
    for name, p in sub.choices.items():
        i = starts[name]
        section = text[i:order[order.index(i) + 1]]
        entries = set()
        for kbd in re.findall(r"<kbd>(.*?)</kbd>", section):
            entries.update(s.strip() for s in html_lib.unescape(kbd).split(","))
        for action in p._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            names = action.option_strings or [action.metavar or action.dest]
            problems += [f"{name} {n}" for n in names if n not in entries]
    assert not problems, f"not in the command line reference: {problems}"


@pytest.mark.xdist_group("docs_site")
def test_every_header_is_in_the_cpp_reference(site: Path) -> None:
    """Each header of every folder of include/gyrodrift (generated coefficient tables aside)
    has its section on its area's page, with at least one documented declaration."""
    inc = ROOT / "include" / "gyrodrift"
    missing = []
    for header in sorted(inc.glob("*/*.hpp")):
        if header.name.startswith("lifting_coefficients_"):
            continue
        area = header.parent.name
        page = site / "cpp" / f"{area}.html"
        text = page.read_text() if page.is_file() else ""
        start = text.find(f"<h2>&lt;gyrodrift/{area}/{header.name}&gt;")
        if start < 0:
            missing.append(f"{area}/{header.name}")
            continue
        end = text.find("<h2>", start + 4)
        if 'class="sig sig-object cpp"' not in text[start:end if end > 0 else len(text)]:
            missing.append(f"{area}/{header.name} (no declaration)")
    assert not missing, missing


# ------------------------------------------------------------------ in a browser


def _chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "Debian chromium is not installed (scripts/setup installs it)"
    return exe


def _dump_dom(exe: str, url: str, profile: Path) -> str:
    r = subprocess.run(
        [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         f"--user-data-dir={profile}", "--virtual-time-budget=15000", "--dump-dom", url],
        capture_output=True, text=True, timeout=180, check=False)
    assert r.stdout.strip(), (r.returncode, r.stderr[-2000:])
    return r.stdout


PROBE = ("<script>window.addEventListener('load', function () {"
         "var w = Array.from(document.images).map(function (i) { return i.naturalWidth; });"
         "var p = document.createElement('pre'); p.id = 'gd-probe';"
         "p.textContent = 'widths=' + w.join(',') + ';';"
         "document.body.appendChild(p); });</script>")


def _probe_page(exe: str, page: Path, profile: Path) -> tuple[str, list[int]]:
    """The page's DOM after load and the decoded width of each of its images (a copy of the
    page beside it, so its relative links hold, carries a script that records them)."""
    probe = page.with_name("_probe_" + page.name)
    probe.write_text(page.read_text().replace("</body>", PROBE + "</body>"))
    try:
        dom = _dump_dom(exe, probe.as_uri(), profile)
    finally:
        probe.unlink()
    m = re.search(r"widths=([0-9,]*);", dom)
    assert m, dom[-2000:]
    return dom, [int(w) for w in m.group(1).split(",") if w]


@pytest.mark.xdist_group("docs_site")
def test_site_renders_in_headless_chromium(site: Path, tmp_path: Path) -> None:
    exe = _chromium()
    profile = tmp_path / "profile"
    # the index: title, navigation to the tutorials, guides, validation and references
    dom, _ = _probe_page(exe, site / "index.html", profile)
    assert re.search(r"<title>gyrodrift", dom)
    for target in ("auto_tutorials/index.html", "cli.html", "api/index.html"):
        assert target in dom, target
    # a tutorial: its title and its figures, decoded by the browser
    tutorial = site / "auto_tutorials" / "plot_01_filter_a_record.html"
    dom, widths = _probe_page(exe, tutorial, profile)
    assert re.search(r"<title>Filter a gyro record", dom)
    assert len(widths) >= 2 and all(w > 100 for w in widths), widths
    # an API page: title and the documented function
    dom, _ = _probe_page(exe, site / "api" / "gyrodrift.filters.ar2.html", profile)
    assert "<title>gyrodrift.filters.ar2" in dom
    assert 'id="gyrodrift.filters.ar2.kalman_filter"' in dom
    # search runs in the browser (searchindex.js) and finds the page of a name
    dom = _dump_dom(exe, (site / "search.html").as_uri() + "?q=kalman_filter", profile)
    results = re.findall(r'<li[^>]*>\s*<a[^>]+href="([^"]+)"', dom.split('id="search-results"')[-1])
    assert any("gyrodrift.filters.ar2" in href for href in results), results[:10]
    # a screenshot of a tutorial page, kept with the build
    shots = site.parent / "screenshots"
    shots.mkdir(exist_ok=True)
    shot = shots / "tutorial.png"
    shot.unlink(missing_ok=True)
    subprocess.run(
        [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         f"--user-data-dir={profile}", "--window-size=1280,1600", "--hide-scrollbars",
         f"--screenshot={shot}", tutorial.as_uri()],
        capture_output=True, timeout=180, check=False)
    assert shot.is_file() and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert shot.stat().st_size > 20_000  # a rendered page, not a blank one


# ------------------------------------------------------------------ the README


def test_readme_is_short() -> None:
    assert len(README.read_text().splitlines()) <= 200


def _fenced(lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", README.read_text(), re.M | re.S)


def test_readme_links_resolve() -> None:
    text = README.read_text()
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text):
        if "://" in target:
            continue
        assert (ROOT / target).exists(), target


def test_readme_command_lines_run_as_written(tmp_path: Path) -> None:
    """Every ``gyrodrift ...`` line of the README, in order, in one directory, through bash;
    ``gyrodrift`` is the command line of the package under test."""
    bindir = tmp_path / "bin"
    bindir.mkdir()
    shim = bindir / "gyrodrift"
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m gyrodrift "$@"\n')
    shim.chmod(0o755)
    env = _env()
    env["PATH"] = f"{bindir}{os.pathsep}{env['PATH']}"
    work = tmp_path / "work"
    work.mkdir()
    lines = [ln for block in _fenced("bash") for ln in block.splitlines()
             if ln.startswith("gyrodrift ")]
    assert len(lines) >= 8, lines
    for line in lines:
        r = subprocess.run(["bash", "-c", line], cwd=work, env=env, capture_output=True,
                           text=True, timeout=600, check=False)
        assert r.returncode == 0, f"{line}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
    for out in ("gyro.npy", "filtered.npy", "allan.png", "imu.yaml", "proc.toml",
                "imu_config.hpp", "imu.bin"):
        assert (work / out).is_file(), out


def test_readme_scripts_are_the_documented_ones() -> None:
    """The README's two commands and the docs command, as written, name scripts that exist
    (scripts/test runs this suite; scripts/docs is run by the site fixture above; the demo
    script is run below)."""
    lines = [ln.split("#")[0].strip() for block in _fenced("bash") for ln in block.splitlines()
             if ln.startswith("bash ")]
    assert lines == ["bash scripts/demo", "bash scripts/test", "bash scripts/docs"]
    for ln in lines:
        assert (ROOT / ln.split()[1]).is_file()


def test_readme_demo_runs(tmp_path: Path) -> None:
    """``bash scripts/demo`` as written where the set-up's .venv exists (scripts/test made it);
    in a development tree without one, the command it runs (``gyrodrift demo``)."""
    if (ROOT / ".venv" / "bin" / "gyrodrift").exists():
        cmd = ["bash", "scripts/demo"]
    else:
        cmd = [sys.executable, "-m", "gyrodrift", "demo"]
    r = subprocess.run(cmd, cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=900,
                       check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "AR(2)-Kalman" in r.stdout


def test_readme_python_example_runs(tmp_path: Path) -> None:
    blocks = _fenced("python")
    assert len(blocks) == 1
    code = blocks[0]
    assert len(code.strip().splitlines()) <= 12
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=_env(),
                       capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    assert re.match(r"STD [0-9.]+ -> [0-9.]+ deg/h", r.stdout), r.stdout


# ------------------------------------------------------------------ user pages


INTERNAL = re.compile(
    r"/work/|\bissue[- ]?\d+|\(#\d+\)|\bengineers?\b|\bsessions?\b|\bthe team\b|"
    r"\btried and (?:dropped|not kept)\b|\bnot kept\b|\brun \d+[a-e]?\b(?!\.\d)", re.I)


def test_user_pages_name_no_work_items() -> None:
    pages = [README, *sorted(DOCS.glob("*.md")), *sorted(DOCS.glob("guides/*.md")),
             *sorted(DOCS.glob("validation/*.md")), *sorted(DOCS.glob("tutorials/*.py"))]
    hits = []
    for page in pages:
        for n, line in enumerate(page.read_text().splitlines(), 1):
            m = INTERNAL.search(line)
            if m:
                hits.append(f"{page.relative_to(ROOT)}:{n}: {m.group(0)!r}")
    assert not hits, hits


def test_every_user_page_has_one_title() -> None:
    for page in [*DOCS.glob("guides/*.md"), *DOCS.glob("validation/*.md")]:
        lines = page.read_text().splitlines()
        fence = False
        titles = 0
        for ln in lines:
            if ln.startswith("```"):
                fence = not fence
            elif not fence and ln.startswith("# "):
                titles += 1
        assert lines[0].startswith("# ") and titles == 1, page.name
