"""The documentation site, the notebooks as committed, and the project's citations.

The site (``mkdocs.yml``, ``docs/``) is built once per session in strict mode, so a broken
link, an anchor that does not exist, a cross-reference to an object missing from the API
reference or a docstring the parser misreads fails here; the built pages are then read for
what a reader would see wrong (raw reStructuredText, empty descriptions, summaries cut
mid-sentence, equations or assets that need the network, guides' names without their API
link). The API reference must hold a page for every public module and every name ``lfjax``
exports; the face's main calls carry docstring examples, run here; every page the package
names exists; no file of the project may cite a file outside it; the notebooks are committed
with their outputs and the paper notebook's text states the defaults.
"""

from __future__ import annotations

import importlib.util
import os
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

import lfjax
from lfjax.reproduce.config import StudyConfig

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "api"


def _mkdocs_missing() -> str | None:
    for module in ("mkdocs", "material", "mkdocstrings_handlers.python", "mkdocs_jupyter",
                   "latex2mathml", "black", "bs4"):
        try:
            if importlib.util.find_spec(module) is None:
                return module
        except ModuleNotFoundError:
            return module
    return None


@pytest.fixture(scope="session")
def site(tmp_path_factory):
    """The site, built once per test session in strict mode (about 30 s on two cores)."""
    missing = _mkdocs_missing()
    if missing is not None:
        pytest.skip(f"{missing} is not installed: pip install -e '.[docs]' to build the site")
    out = tmp_path_factory.mktemp("site") / "site"
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=300,
    )
    return proc, out


def test_site_builds_strict(site):
    proc, site = site
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"mkdocs build --strict failed:\n{log[-6000:]}"
    # The pages that come from outside docs/ are there, with their content: the benchmark
    # results' summary links every topic page, each page is built, and the figures the
    # scripts write beside themselves are served.
    results = (site / "benchmarks" / "RESULTS" / "index.html").read_text(encoding="utf-8")
    assert "Polychromatic OTFs per second" in results
    table = results.split("<article", 1)[1].split("</article>", 1)[0]  # the page, not the nav
    pages = sorted((ROOT / "benchmarks" / "results").glob("*.md"))
    assert len(pages) >= 20, [p.name for p in pages]
    for page in pages:
        assert f'href="../results/{page.stem}/' in table, f"the summary does not link {page.name}"
        assert (site / "benchmarks" / "results" / page.stem / "index.html").is_file(), page.name
    first = (site / "benchmarks" / "results" / "01-polychromatic-otfs" / "index.html")
    assert "Each floor is one jitted batched call" in first.read_text(encoding="utf-8")
    assert (site / "benchmarks" / "speed" / "speed_accuracy.png").is_file()
    notebook = (site / "notebooks" / "display_effects" / "index.html").read_text(encoding="utf-8")
    assert "data:image/png;base64" in notebook  # committed outputs rendered
    api = (site / "api" / "vision" / "index.html").read_text(encoding="utf-8")
    assert 'id="lfjax.vision.focus.through_focus"' in api
    # Every notebook page shows its committed outputs, the paper's notebook its figures.
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        page = (site / "notebooks" / notebook.stem / "index.html").read_text(encoding="utf-8")
        assert "data:image/png;base64" in page, f"{notebook.name}: no figure on its page"
    paper = (site / "notebooks" / "reproduce_paper" / "index.html").read_text(encoding="utf-8")
    assert paper.count("data:image/png;base64") >= 10  # Figs. 3-11 and the retinal images


# ------------------------------------------------------------------ what the built pages show

# Sphinx roles and directives that Markdown does not know: shown raw if they reach the page.
RAW_REST = re.compile(
    r"(?<!\w):(?:py:)?(?:mod|class|func|meth|attr|data|obj|exc|math|ref|doc):(?!\w)"
    r"|^\s*\.\. (?:math|note|warning|code-block|autofunction|seealso|versionadded)::",
    re.M,
)
SUMMARY_SECTIONS = {"Classes:", "Functions:", "Methods:", "Attributes:", "Modules:"}
# A summary ends where a sentence can end: . ! ? or : (introducing what the docstring shows
# next), possibly followed by a closing bracket or quote.
SENTENCE_END = re.compile(r"[.!?:…][\"')\]]*$")
TEX = re.compile(r"\$\$|\\\[|\\\(|\\begin\{|\\frac\b|\\mathrm\b")
SECTION_HEADERS = ("Parameters", "Attributes", "Returns", "Yields", "Raises", "Other Parameters")


def site_problems(site: Path) -> dict[str, list[str]]:
    """What a reader would see wrong on the built pages, by kind:

    * ``rest``: a reStructuredText role or directive shown as text;
    * ``empty``: a table row without its description — a docstring section's entry, or a
      summary row of a member whose own docstring has text; a Returns entry whose prose
      landed in the Type column; a numpydoc section header the parser did not recognise
      (shown as a bare collapsible block);
    * ``cut``: a summary-table description that stops mid-sentence, or any table's
      description cut in two by a line break inside a sentence ("every view must reach into
      the⏎calculation pupil"), or starting with a bare ``()``; a default shown with parts
      missing (``tuple(tolist())``);
    * ``offline``: a script or stylesheet fetched from the network, or an equation left as
      TeX for a script to typeset.
    """
    from bs4 import BeautifulSoup

    found: dict[str, list[str]] = {"rest": [], "empty": [], "cut": [], "offline": []}
    for page in sorted(site.rglob("*.html")):
        where = page.relative_to(site).as_posix()
        raw = page.read_text(encoding="utf-8")
        for tag in re.findall(r"<(?:script|link)\b[^>]*>", raw):
            source = re.search(r'\b(?:src|href)="((?:https?:)?//[^"]*)"', tag)
            loads = tag.startswith("<script") or re.search(r'\brel="[^"]*stylesheet', tag)
            if source and loads:
                found["offline"].append(f"{where}: loads {source.group(1)}")
            if tag.startswith("<script") and re.search(r'\bsrc=""', tag):
                found["offline"].append(f"{where}: a script with an empty source")
        for script in re.findall(r"<script\b[^>]*>((?:(?!</script>).)*)</script>", raw, re.S):
            fetched = re.search(r"import\s*\(?\s*[\"'](https?://[^\"']+)", script)
            if fetched:
                found["offline"].append(f"{where}: imports {fetched.group(1)}")
        # Only the page's own content is read (not the navigation), without the notebooks'
        # inline images: html.parser is pure Python, and this keeps the check to seconds.
        start, end = raw.find("<article"), raw.rfind("</article>")
        if start < 0 or end < 0:
            continue
        content = re.sub(r'data:image/[\w+.-]+;base64,[^"\')\s]+', "data:", raw[start:end + 10])
        body = BeautifulSoup(content, "html.parser").find("article")
        for element in body.select(".arithmatex"):
            found["offline"].append(f"{where}: equation left as TeX: {element.get_text()[:60]!r}")
        ids = {element["id"]: element for element in body.find_all(id=True)}
        documented: dict[str, bool] = {}
        for table in body.find_all("table"):
            _table_problems(ids, documented, table, where, found)
        for details in body.find_all("details"):
            summary = details.find("summary")
            title = summary.get_text().strip() if summary else ""
            if title.startswith(SECTION_HEADERS) and title not in SECTION_HEADERS:
                found["empty"].append(f"{where}: section header not parsed: {title!r}")
        for element in body.find_all(["pre", "code"]):
            element.decompose()  # code may show anything
        text = body.get_text("\n")
        for match in RAW_REST.finditer(text):
            context = text[max(0, match.start() - 40):match.end() + 40].replace("\n", " ")
            found["rest"].append(f"{where}: {context!r}")
        for match in TEX.finditer(text):
            context = text[max(0, match.start() - 20):match.end() + 40].replace("\n", " ")
            found["offline"].append(f"{where}: TeX shown as text: {context!r}")
    return found


def _table_problems(ids: dict, documented: dict, table, where: str,
                    found: dict[str, list[str]]) -> None:
    heads = [th.get_text().strip() for th in table.find_all("th")]
    if "Description" not in heads:
        return
    title = table.find_previous("span", class_="doc-section-title")
    section = title.get_text().strip() if title else "?"
    heading = table.find_previous(class_="doc-heading")
    owner = heading.get("id", "?") if heading else "?"
    for row in table.select("tr.doc-section-item"):
        name = row.find("td").get_text(" ", strip=True)
        if section in ("Returns:", "Yields:") and "Type" in heads:
            # A type, not prose: numpydoc reads an unnamed line of prose as the type.
            shown = row.find_all("td", recursive=False)[heads.index("Type")].get_text(" ", strip=True)
            unquoted = re.sub(r"'[^']*'|\"[^\"]*\"", "", shown)
            if shown.endswith(".") or re.search(r"\b[a-z]{2,}\s+[a-z]{2,}\b", unquoted):
                found["empty"].append(f"{where}: {owner} {section} prose as the type: {shown[:60]!r}")
        description = row.select_one(".doc-md-description")
        text = description.get_text(" ", strip=True) if description else ""
        for broken in _broken_sentences(description) if description else []:
            found["cut"].append(f"{where}: {owner} {section} {name}: {broken}")
        if text.startswith("()"):
            found["cut"].append(f"{where}: {owner} {section} {name}: starts with a bare (): {text[:40]!r}")
        if "Default" in heads:
            shown = row.find_all("td", recursive=False)[heads.index("Default")].get_text("", strip=True)
            if LOSSY_DEFAULT.search(shown):
                found["cut"].append(f"{where}: {owner} {section} {name}: default {shown!r}")
        # A summary row names a member documented on the page, by a link to its heading.
        link = row.find("td").find("a", href=True)
        member = link["href"][1:] if link is not None and link["href"].startswith("#") else None
        # (A docstring's Attributes section links its entries too; it is told apart by
        # the members it names having no docstring of their own.)
        if member is not None and member not in documented:
            documented[member] = _has_own_docstring(ids.get(member))
        is_summary = section in SUMMARY_SECTIONS and member is not None and documented[member]
        if not text:
            if section in SUMMARY_SECTIONS and member is not None and not is_summary:
                continue  # the member has no docstring: nothing to summarise
            found["empty"].append(f"{where}: {owner} {section} {name}: no description")
        elif is_summary:
            first = description.find("p")
            line = (first.get_text(" ", strip=True) if first else text)
            if not SENTENCE_END.search(line):
                found["cut"].append(f"{where}: {owner} {section} {name}: …{line[-60:]!r}")


# Text that ends a sentence, or a fragment that may stand before a line break (a type, a
# unit list), and a default rendered without its receiver: ``tuple(tolist())``.
BREAK_ENDS = re.compile(r"[.!?:;…\"')\]]\s*$")
LOSSY_DEFAULT = re.compile(r"\w\(\w+\(\)\)")


def _broken_sentences(description) -> list[str]:
    """Line breaks (``<br>``) inside a description where a sentence goes on: the text before
    does not end one and the text after starts in lower case."""
    out = []
    def text(node) -> str:
        return node.get_text() if hasattr(node, "get_text") else str(node)

    for br in description.find_all("br"):
        before = next((t for t in (text(n).strip() for n in br.previous_siblings) if t), "")
        after = next((t for t in (text(n).strip() for n in br.next_siblings) if t), "")
        if before and after and not BREAK_ENDS.search(before) and after[0].islower():
            out.append(f"broken at a line break: …{before[-40:]!r}⏎{after[:30]!r}")
    return out


def _has_own_docstring(target) -> bool:
    contents = target.find_next_sibling("div", class_="doc-contents") if target else None
    if contents is None:
        return False

    def own(element) -> bool:  # not inside a member documented within this one
        for parent in element.parents:
            if parent is contents:
                return True
            if "doc-children" in (parent.get("class") or []):
                return False
        return False

    return any("doc-class-bases" not in (element.get("class") or []) and own(element)
               for element in contents.find_all(["p", "table", "details"]))


def test_pages_render_what_the_docstrings_say(site):
    proc, site = site
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    found = site_problems(site)
    report = "\n".join(f"{kind}: {line}" for kind, lines in found.items() for line in lines[:15])
    assert not any(found.values()), "the built site shows what its sources do not say:\n" + report
    # The equations are there, as MathML (the VSOTF's definition on the kernel's page).
    kernel = (site / "api" / "kernel" / "index.html").read_text(encoding="utf-8")
    assert kernel.count("<math") >= 2 and "VSOTF" in kernel
    panel = (site / "api" / "display" / "index.html").read_text(encoding="utf-8")
    attributes = panel.split('id="lfjax.display.panel.Panel"', 1)[1].split("Methods:", 1)[0]
    assert "pixel_pitch_mm" in attributes and "pixel pitch p of the panel" in attributes


SAMPLE_PAGE = """<html><head>{head}</head><body><article>
<h3 id="m.f" class="doc doc-heading">f</h3><div class="doc doc-contents"><p>Has text.</p></div>
<p><span class="doc-section-title">Functions:</span></p>
<table><thead><tr><th>Name</th><th>Description</th></tr></thead><tbody>
<tr class="doc-section-item"><td><code><a href="#m.f">f</a></code></td>
<td><div class="doc-md-description">{summary}</div></td></tr></tbody></table>
<p>{text}</p></article></body></html>"""


@pytest.mark.parametrize("kind, page", [
    ("rest", dict(text="the layers: :mod:`lfjax.base` first")),
    ("rest", dict(text=".. math:: a = b")),
    ("cut", dict(summary="<p>A sentence cut at the</p>")),
    ("cut", dict(summary="<p>every view must reach into the<br>calculation pupil.</p>")),
    ("cut", dict(summary="<p>() pixel pitch p of the panel, mm.</p>")),
    ("empty", dict(summary="")),
    ("offline", dict(head='<script src="https://unpkg.com/mathjax@3/es5/tex-mml-chtml.js">'
                          "</script>")),
    ("offline", dict(text='<span class="arithmatex">\\(x^2\\)</span>')),
    ("offline", dict(head='<script src=""> </script>')),
    ("offline", dict(head='<script type="module">const m = (await import("https://cdn.example/m.mjs"));'
                          "</script>")),
    ("offline", dict(text="$$ \\frac{a}{b} $$")),
    ("empty", dict(text="</p><details><summary>Attributes (lengths in mm)</summary>x</details><p>")),
    ("empty", dict(text='</p><p><span class="doc-section-title">Returns:</span></p><table><thead>'
                        "<tr><th>Type</th><th>Description</th></tr></thead><tbody>"
                        '<tr class="doc-section-item"><td>the peaks, in D.</td><td>'
                        '<div class="doc-md-description"><p>x</p></div></td></tr></tbody>'
                        "</table><p>")),
])
def test_site_checks_see_what_they_must(tmp_path, kind, page):
    """Each check fires on a page with its fault, and only that check."""
    pytest.importorskip("bs4")
    values = dict(head="", summary="<p>A whole sentence.</p>", text="Plain text.") | page
    (tmp_path / "index.html").write_text(SAMPLE_PAGE.format(**values), encoding="utf-8")
    found = site_problems(tmp_path)
    assert found[kind], found
    assert not any(lines for other, lines in found.items() if other != kind), found
    values = dict(head="", summary="<p>A whole sentence.</p>", text="Plain text.")
    (tmp_path / "index.html").write_text(SAMPLE_PAGE.format(**values), encoding="utf-8")
    assert not any(site_problems(tmp_path).values())


def _public_modules() -> list[str]:
    names = []
    for info in pkgutil.walk_packages(lfjax.__path__, "lfjax."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            names.append(info.name)
    return sorted(names)


def test_api_reference_has_every_public_module_and_export():
    documented = set()
    for page in API.glob("*.md"):
        documented |= set(re.findall(r"^::: (lfjax[\w.]*)", page.read_text(encoding="utf-8"), re.M))
    missing = [m for m in _public_modules() if m not in documented]
    assert not missing, f"public modules without an API page (add '::: name' to docs/api/): {missing}"
    top = (API / "lfjax.md").read_text(encoding="utf-8")
    exports = [
        name for name in dir(lfjax)
        if not name.startswith("_")
        and getattr(getattr(lfjax, name), "__module__", "").startswith("lfjax")
        and not isinstance(getattr(lfjax, name), type(lfjax))
    ]
    assert exports, "lfjax exports no names: the check would be empty"
    missing = [n for n in exports if f"`lfjax.{n}`" not in top]
    assert not missing, f"names exported by lfjax but absent from docs/api/lfjax.md: {missing}"


# A citation of a file that is not in the project: the design notes the project was started
# from, or the folder beside it. Spelled in pieces so that this file does not match itself.
OUTSIDE = re.compile(
    r"DESIGN" r"(\.md|\s*§|\s+\d|\s+sections?\b)" r"|\.\./" r"shared\b"
)
SCANNED = ("lfjax", "tests", "benchmarks", "notebooks", "docs", ".ci")
SCANNED_FILES = ("README.md", "pyproject.toml", "mkdocs.yml")
TEXT_SUFFIXES = {".py", ".md", ".ipynb", ".toml", ".yml", ".yaml", ".txt", ".csv", ".json", ""}


def _project_text_files():
    for name in SCANNED_FILES:
        yield ROOT / name
    for folder in SCANNED:
        for path in (ROOT / folder).rglob("*"):
            parts = set(path.relative_to(ROOT).parts)
            if parts & {"__pycache__", "_cache", ".cache"} or not path.is_file():
                continue
            if path.suffix in TEXT_SUFFIXES:
                yield path


def test_no_citation_of_files_outside_the_project():
    hits = []
    n_files = 0
    for path in _project_text_files():
        n_files += 1
        text = path.read_text(encoding="utf-8", errors="replace")
        for number, line in enumerate(text.splitlines(), 1):
            if OUTSIDE.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()[:120]}")
    assert n_files > 50, f"only {n_files} files scanned: the scan is not looking at the project"
    assert not hits, "cite docs/design.md#section instead:\n" + "\n".join(hits)


def test_citation_pattern_catches_what_it_must():
    for bad in ("see DESIGN" ".md §2b", "(DESIGN" " §3)", "DESIGN" " 2.6 invariant",
                "../" "shared/data/x.json"):
        assert OUTSIDE.search(bad), bad
    for good in ("docs/design.md#modelling-choices", "a shared store", "DESIGNS"):
        assert not OUTSIDE.search(good), good


def _sphinx_roles():
    if importlib.util.find_spec("griffe") is None:
        pytest.skip("griffe is not installed: pip install -e '.[docs]'")
    spec = importlib.util.spec_from_file_location(
        "_lfjax_docs_sphinx_roles", ROOT / "docs" / "_hooks" / "sphinx_roles.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_docstring_house_style_becomes_numpydoc():
    """The API reference reads ``name : description`` lines as descriptions and a closing
    paragraph as Notes, not as more parameters."""
    normalise = _sphinx_roles().normalise_sections
    doc = ("Summary.\n\nParameters\n----------\ndepths_D : (n_depth,) rendered depths, D\n"
           "window_D : float, D, optional\n    Half-width.\nname, source : str\n\n"
           "The closing paragraph, not a parameter.")
    out = normalise(doc).split("\n")
    assert out[4:6] == ["depths_D", "    shape `(n_depth,)`: rendered depths, D"]
    assert out[6:9] == ["window_D", "    float, D, optional<br>", "    Half-width."]
    assert out[9:13] == ["name", "    str", "source", "    str"]
    assert out[14:17] == ["Notes", "-----", "The closing paragraph, not a parameter."]
    # A sentence that goes on below its name line is not cut by a line break; a scalar's
    # shape is written as one.
    doc = ("S.\n\nParameters\n----------\nviews : (n,) every view must reach into the\n"
           "    calculation pupil. More.\npitch_mm : () pixel pitch, mm\n")
    out = normalise(doc).split("\n")
    assert out[4:6] == ["views", "    shape `(n,)`: every view must reach into the calculation pupil. More."]
    assert out[6:8] == ["pitch_mm", "    shape `()`: pixel pitch, mm"]


# ------------------------------------------------------------------ pages the package points to

# A project file named in a message, a help text or a docstring: docs/…md(#anchor),
# benchmarks/…md, README.md; or a README section by name ("the README's 'X'").
PAGE_REFERENCE = re.compile(
    r"(?P<path>(?:docs|benchmarks)/[\w/.-]+?\.md|README\.md)(?:#(?P<anchor>[\w-]+))?"
)
README_SECTION = re.compile(r"README'?s? '(?P<section>[^']+)'")


def _anchors(markdown: str) -> set[str]:
    """The anchors of a Markdown page's headings, as the site (toc's slugify) makes them."""
    anchors = set()
    for title in re.findall(r"^#{1,6}\s+(.+?)\s*#*\s*$", markdown, re.M):
        explicit = re.search(r"\{#([\w-]+)\}\s*$", title)  # attr_list: "## Title {#id}"
        if explicit:
            anchors.add(explicit.group(1))
            continue
        text = re.sub(r"[`*_\[\]]|\(.*?\)", "", title) if "](" in title else re.sub(r"[`*_]", "", title)
        slug = re.sub(r"[^\w\s-]", "", text.lower()).strip()
        anchors.add(re.sub(r"[-\s]+", "-", slug))
    return anchors


def page_reference_problems(text: str, where: str) -> list[str]:
    problems = []
    for match in PAGE_REFERENCE.finditer(text):
        path = ROOT / match.group("path")
        if not path.is_file():
            problems.append(f"{where}: {match.group(0)} does not exist")
        elif match.group("anchor") and match.group("anchor") not in _anchors(path.read_text(
                encoding="utf-8")):
            problems.append(f"{where}: {match.group(0)}: no such heading")
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for match in README_SECTION.finditer(text):
        if not re.search(rf"^#+\s+{re.escape(match.group('section'))}\s*$", readme, re.M):
            problems.append(f"{where}: the README has no section {match.group('section')!r}")
    return problems


def test_help_texts_messages_and_docstrings_point_to_pages_that_exist():
    from lfjax.cli import SUBCOMMANDS, build_parser

    problems = []
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    for name in SUBCOMMANDS:
        problems += page_reference_problems(sub.choices[name].format_help(), f"lfjax {name} --help")
    n_refs = 0
    for path in sorted((ROOT / "lfjax").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        n_refs += len(PAGE_REFERENCE.findall(text))
        problems += page_reference_problems(text, str(path.relative_to(ROOT)))
    assert n_refs > 10, "the package names almost no page: the scan is not reading it"
    assert not problems, "\n".join(problems)


def test_page_reference_check_sees_a_dead_reference():
    assert page_reference_problems("see docs/guides/no-such-guide.md", "x")
    assert page_reference_problems("docs/design.md#no-such-heading", "x")
    assert page_reference_problems("see the README's 'No such section' for keys", "x")
    assert not page_reference_problems("docs/design.md#layers and benchmarks/RESULTS.md", "x")


# ------------------------------------------------------------------ docstring examples

# The modules of the package's face whose docstrings carry runnable examples, and the calls
# that must have one (through-focus, metrics at a point, peaks through through_focus's
# PeakOptions, planning, eyes, layouts, the panel, the option objects).
EXAMPLE_MODULES = ("lfjax.vision.focus", "lfjax.planner.plan", "lfjax.model.eyes",
                   "lfjax.model.layouts", "lfjax.display.panel", "lfjax.vision.viewing",
                   "lfjax.vision.peak_options", "lfjax.binocular.viewer")
MUST_HAVE_EXAMPLES = ("through_focus", "metrics_at", "plan_sampling", "sample_eyes",
                      "average_eye", "grid_layout", "Panel", "Viewing", "PeakOptions")


def _docstring_examples():
    import doctest
    import importlib

    finder = doctest.DocTestFinder(exclude_empty=True)
    tests = []
    for name in EXAMPLE_MODULES:
        module = importlib.import_module(name)
        tests += [t for t in finder.find(module) if t.examples and t.name.startswith(name)]
    return tests


def test_the_main_calls_have_examples():
    named = {t.name.rsplit(".", 1)[-1] for t in _docstring_examples()}
    missing = [name for name in MUST_HAVE_EXAMPLES if name not in named]
    assert not missing, f"no Examples section with >>> lines in the docstrings of {missing}"
    for name in MUST_HAVE_EXAMPLES:
        assert getattr(lfjax, name).__doc__.count("Examples\n    --------") == 1, name


def test_docstring_examples_run():
    """Every >>> example in the face's modules runs and prints what its docstring says
    (tiny sizes: one eye, one depth, one wavelength; about 30 s, mostly compilation)."""
    import doctest

    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    tests = _docstring_examples()
    assert len(tests) >= len(MUST_HAVE_EXAMPLES)
    for test in tests:
        runner.run(test)
    results = runner.summarize(verbose=False)
    assert results.attempted >= 25, results  # every example was found and run
    assert results.failed == 0, f"{results.failed} docstring examples failed (output above)"


def test_guides_link_the_functions_they_name(site):
    """On the pages outside the API reference, a name like `lfjax.through_focus` (or the
    face's `through_focus`) that is a public object links to its entry
    (docs/_hooks/api_links.py)."""
    from bs4 import BeautifulSoup

    proc, site = site
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    spec = importlib.util.spec_from_file_location(
        "_lfjax_docs_api_links", ROOT / "docs" / "_hooks" / "api_links.py")
    api_links = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(api_links)
    unlinked, linked = [], 0
    pages = [site / "index.html", site / "getting-started" / "index.html",
             site / "faq" / "index.html", site / "glossary" / "index.html",
             *sorted((site / "guides").rglob("index.html"))]
    for page in pages:
        body = BeautifulSoup(page.read_text(encoding="utf-8"), "html.parser").find("article")
        for code in body.find_all("code"):
            name = code.get_text().removesuffix("()")
            if re.fullmatch(r"[A-Za-z]\w*", name) and callable(getattr(lfjax, name, None)):
                name = "lfjax." + name  # a call of the face by its bare name
            if code.find_parent("pre") is not None or not re.fullmatch(r"lfjax(\.\w+)+", name):
                continue
            if api_links.canonical(name) is None:
                continue
            if code.find_parent("a") is None:
                unlinked.append(f"{page.relative_to(site).parent}: {name}")
            else:
                linked += 1
    assert linked > 40, f"only {linked} names linked: the check is not reading the guides"
    assert not unlinked, "names that do not link to their API entry:\n" + "\n".join(unlinked)


# ------------------------------------------------------------------ citation, licence, changelog


def test_citation_licence_and_changelog_agree_with_the_package():
    import tomllib

    yaml = pytest.importorskip("yaml")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert cff["cff-version"].startswith("1.2") and cff["type"] == "software"
    assert cff["version"] == project["version"] and cff["license"] == project["license"]
    paper = cff["preferred-citation"]
    assert "Optical modelling of accommodative light field display" in paper["title"]
    assert [a["family-names"] for a in paper["authors"]] == ["Miyanishi", "Sahin", "Gotchev"]
    assert paper["year"] and paper["journal"] and paper["identifiers"]
    assert cff["repository-code"] == _mkdocs_setting("repo_url")
    licence = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert licence.startswith("MIT License") and project["license"] == "MIT"
    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    for n in range(1, 5):
        assert re.search(rf"^## Round {n}\b", changelog, re.M), f"CHANGELOG.md lacks round {n}"


def _mkdocs_setting(key: str) -> str:
    match = re.search(rf"^{key}:\s*(\S+)", (ROOT / "mkdocs.yml").read_text(encoding="utf-8"), re.M)
    assert match, f"mkdocs.yml sets no {key}"
    return match.group(1)


def test_readme_is_short_names_its_readers_and_says_what_was_measured():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 180, len(readme.splitlines())
    assert "Who it is for" in readme
    assert _mkdocs_setting("site_url").startswith("https://")
    # The optimiser's held-out accommodation error is the guide's measurement, not the
    # training constraint.
    guide = (ROOT / "docs" / "guides" / "layout-optimisation.md").read_text(encoding="utf-8")
    held_out = re.search(r"display's accommodation error, RMSE \| ([\d.]+) D \| ([\d.]+) D", guide)
    assert held_out, "the guide no longer gives the held-out table"
    assert f"{held_out.group(1)} →\n{held_out.group(2)} D" in readme or \
        f"{held_out.group(1)} → {held_out.group(2)} D" in readme, held_out.groups()
    assert "held within 0.25 D" not in readme
    # The main job's times: README and home page cite the same results page.
    index = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    latest = max(int(p.name[:2]) for p in (ROOT / "benchmarks" / "results").glob("[0-9]*-*.md")
                 if re.search(r"`lfjax reproduce`.*warm", p.read_text(encoding="utf-8")))
    for name, text in (("README.md", readme.split("## A tour")[0]), ("docs/index.md", index)):
        cited = {int(n) for n in re.findall(r"results/(\d+)-[\w-]+\.md", text)}
        assert latest in cited, f"{name} does not give the main job's time from §{latest}"


# ------------------------------------------------------------------ notebooks as committed
# Each notebook carries its outputs (the site shows them as they are), and the paper
# notebook's text states the settings the package's defaults use. Executing the notebooks is
# tested beside the code they show (tests/cli/test_cli.py, tests/display/test_lenslets.py,
# tests/design/test_design_fit.py, tests/layout_opt/), at a tiny size; these only read files.

NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


def test_there_are_notebooks():  # the parametrised tests below would pass on none
    assert len(NOTEBOOKS) >= 4, [p.name for p in NOTEBOOKS]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_is_committed_with_its_outputs(path):
    """Every code cell ran, in order, without an error, and the notebook shows a figure."""
    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code, f"{path.name} has no code"
    not_run = [i for i, c in enumerate(code) if c.get("execution_count") is None]
    assert not not_run, f"{path.name}: code cells {not_run} were committed without being run"
    counts = [c.execution_count for c in code]
    assert counts == sorted(counts), f"{path.name}: cells were run out of order ({counts})"
    outputs = [o for c in code for o in c.get("outputs", [])]
    errors = [o.get("ename") for o in outputs if o.output_type == "error"]
    assert not errors, f"{path.name} was committed with errors: {errors}"
    assert any("image/png" in o.get("data", {}) for o in outputs), f"{path.name}: no figure"


def _number(pattern: str, text: str, what: str) -> float:
    match = re.search(pattern, text)
    assert match, f"the notebook no longer states {what} (pattern {pattern!r})"
    return float(match.group(1))


def paper_notebook_settings(text: str) -> tuple[dict, dict]:
    """(quick, full) settings the paper notebook's introduction states, read from its text."""
    quick_text, full_text = re.split(r"Set\s+`QUICK = False`", text, maxsplit=1)
    quick = dict(
        n_eyes=_number(r"(\d+) virtual eyes plus the average eye", quick_text, "the quick eyes"),
        accommodation_step_D=_number(r"([\d.]+) D accommodation grid", quick_text,
                                     "the quick accommodation step"),
        wavelength_step_nm=_number(r"(\d+) nm steps", quick_text, "the quick wavelength step"),
    )
    full = dict(
        n_eyes=_number(r"(\d+) virtual eyes plus the average eye", full_text, "the eyes"),
        pupil_diameter_mm=_number(r"([\d.]+) mm pupil", full_text, "the pupil"),
        cdp_D=_number(r"CDP at ([\d.]+) D", full_text, "the CDP"),
        depth_step_D=_number(r"in ([\d.]+) D steps", full_text, "the depth step"),
        accommodation_step_D=_number(r"([\d.]+) D accommodation grid", full_text,
                                     "the accommodation step"),
        peak_tolerance_D=_number(r"by more than ([\d.]+) D", full_text, "the peak target"),
        cutoff_tolerance_cpd=_number(r"by more than ([\d.]+) cpd", full_text, "the cut-off target"),
    )
    start, stop = re.search(r"(\d+)[–-](\d+) nm", full_text).groups()
    full["wavelength_range_nm"] = (float(start), float(stop))
    full["accuracy"] = re.search(r'`accuracy="(\w+)"`', full_text).group(1)
    # A fixed step is only stated for the quick size; the full study plans its own.
    full["states_a_fixed_step"] = bool(re.search(r"\d+ nm steps", full_text))
    return quick, full


def test_paper_notebook_text_states_the_defaults():
    nb = nbformat.read(ROOT / "notebooks" / "reproduce_paper.ipynb", as_version=4)
    intro = nb.cells[0].source.replace("\n", " ").replace("# ", "")
    quick, full = paper_notebook_settings(intro)
    q, d = StudyConfig.quick(), StudyConfig()
    assert quick == dict(n_eyes=q.n_eyes, accommodation_step_D=q.accommodation_step_D,
                         wavelength_step_nm=q.wavelengths_nm[2])
    depth_steps = {round(b - a, 9) for a, b in zip(d.depth_offsets_D, d.depth_offsets_D[1:])}
    assert full == dict(
        n_eyes=d.n_eyes, pupil_diameter_mm=d.pupil_diameter_mm, cdp_D=d.cdp_D,
        depth_step_D=depth_steps.pop(), accommodation_step_D=d.accommodation_step_D,
        peak_tolerance_D=d.peak_tolerance_D, cutoff_tolerance_cpd=d.cutoff_tolerance_cpd,
        wavelength_range_nm=d.wavelengths_nm[:2], accuracy=d.accuracy,
        states_a_fixed_step=d.accuracy == "vsotf",
    )
    assert not depth_steps, "the default depths are not evenly spaced: the text cannot say one step"
    # The code cell the text describes uses exactly these configurations.
    code = "\n".join(c.source for c in nb.cells if c.cell_type == "code")
    assert "StudyConfig.quick() if QUICK else reproduce.StudyConfig()" in code


def test_the_text_check_reads_a_disagreement():
    """The old introduction (10 nm steps for the full study) fails the check."""
    old = ("at the `--quick` size: 2 virtual eyes plus the average eye, 0.5 D accommodation "
           "grid, 400–700 nm in 30 nm steps. Set `QUICK = False` for the full study: 3 mm "
           "pupil, CDP at 2 D, in 0.5 D steps, 0.2 D accommodation grid, 400–700 nm in 10 nm "
           "steps, 10 virtual eyes plus the average eye, no peak moves by more than 0.01 D, "
           "by more than 0.25 cpd (`accuracy=\"claims\"`)")
    _, full = paper_notebook_settings(old)
    assert full["states_a_fixed_step"] and StudyConfig().accuracy == "claims"


def test_docstring_sections_math_and_summaries_become_what_the_site_renders():
    """Headers with a note, Returns prose, ``.. math::`` and the summary's first line."""
    roles = _sphinx_roles()
    out = roles.normalise_sections(
        "S.\n\nAttributes (lengths in mm)\n----------\nx : () width, mm\n").split("\n")
    assert out[2:7] == ["Lengths in mm.", "", "Attributes", "----------", "x"]
    out = roles.normalise_sections(
        "S.\n\nReturns\n-------\nArray of the scene's shape: the\nimage, cd/m².\n"
        "peak : float\nvalue : (n,) the values, D\n").split("\n")
    assert out[4:10] == [":", "    Array of the scene's shape: the image, cd/m².", "peak : float",
                         "value :", "    shape `(n,)`: the values, D", ""]
    math = roles.math_to_arithmatex("Text.\n\n.. math:: a = \\frac{b}\n      {c}\n\nAfter, :math:`x`.")
    assert math == "Text.\n\n$$\na = \\frac{b}\n{c}\n$$\n\nAfter, $x$."
    first = roles.first_sentence_first("One sentence, e.g. this, that runs\non. Another one\nhere.\n\nMore.")
    assert first == "One sentence, e.g. this, that runs on.\nAnother one here.\n\nMore."


# ------------------------------------------------------------------ figures quoted from results
# Each time or result the README, the home page and the guides quote, with the results page
# and row it comes from: (file, pattern of the quote, results page, pattern of the row). Each
# pattern captures one number; a re-measurement that changes the row fails here until every
# quote follows it.
R35 = "benchmarks/results/35-targets-36-today.md"
R33 = "benchmarks/results/33-verdict-margins.md"
R34 = "benchmarks/results/34-gpu-check-h200.md"
COLD_35 = r"\| `lfjax reproduce` cold \| [^|]+\| \*\*([\d.]+) s\*\*"
WARM_35 = r"\| \*\*warm, median of 3\*\* \| [^|]+\| \*\*([\d.]+) s\*\*"
QUOTED_FIGURES = [
    ("README.md", r"takes\s+([\d.]+) s on two idle CPU cores from empty caches", R35, COLD_35),
    ("README.md", r"from empty caches and ([\d.]+) s warm", R35, WARM_35),
    ("README.md", r"([\d.]+) s and [\d.]+ s there", R33,
     r"\| `lfjax reproduce` cold \| [^|]+\| ([\d.]+) s"),
    ("README.md", r"[\d.]+ s and ([\d.]+) s there", R33,
     r"\| \*\*warm, median of 3\*\* \| [^|]+\| \*\*([\d.]+) s\*\*"),
    ("README.md", r"([\d.]+) s cold and [\d.]+–[\d.]+ s warm on one H200", R34,
     r"\| run 2, cold \| ([\d.]+) s"),
    ("README.md", r"s cold and ([\d.]+)–[\d.]+ s warm on one H200", R34,
     r"\| run 2, warm 1 \| \*\*([\d.]+) s\*\*"),
    ("README.md", r"s cold and [\d.]+–([\d.]+) s warm on one H200", R34,
     r"\| run 2, warm 2 \| ([\d.]+) s"),
    ("README.md", r"10,000-eye sweep takes ([\d.]+) s", R34, r"\| sweep \| 10,000 eyes[^|]+\| \*\*([\d.]+) s\*\*"),
    ("README.md", r"cost ([\d.]+) s per eye on two idle cores", R35, r"\*\*[\d.]+ s: ([\d.]+) s/eye\*\*"),
    ("README.md", r"about (\d+) min per 1,000 eyes\n\(\[§35\]", R35, r"about \*\*(\d+) min per 1,000 eyes\*\*"),
    ("docs/index.md", r"\(([\d.]+) s on two idle CPU cores from an empty compilation cache", R35, COLD_35),
    ("docs/index.md", r"([\d.]+) s\s+warm, the median of three", R35, WARM_35),
    ("docs/guides/paper-study.md", r"whole job takes ([\d.]+) s on 2 idle CPU cores", R35, COLD_35),
    ("docs/guides/paper-study.md", r"and ([\d.]+) s warm\s+\(the median of three", R35, WARM_35),
    ("docs/guides/paper-study.md", r"it takes ([\d.]+)–[\d.]+ s warm", R34, r"\| run 2, warm 1 \| \*\*([\d.]+) s\*\*"),
    ("docs/guides/paper-study.md", r"and ([\d.]+) s cold, nearly all of it compiling", R34, r"\| run 2, cold \| ([\d.]+) s"),
    ("docs/guides/population-sweeps.md", r"today's faster VM ([\d.]+) s per eye", R35,
     r"\*\*[\d.]+ s: ([\d.]+) s/eye\*\*"),
]


def quoted_figure_problems(quotes) -> list[str]:
    problems = []
    for name, quote, page, row in quotes:
        text = (ROOT / name).read_text(encoding="utf-8")
        source = (ROOT / page).read_text(encoding="utf-8")
        said, measured = re.search(quote, text), re.search(row, source)
        if said is None:
            problems.append(f"{name} no longer quotes {quote!r}: update QUOTED_FIGURES")
        elif measured is None:
            problems.append(f"{page} has no row {row!r}")
        elif float(said.group(1)) != float(measured.group(1)):
            problems.append(f"{name} quotes {said.group(0)!r}; {page} says {measured.group(1)}")
        elif Path(page).stem not in text:
            problems.append(f"{name} quotes {said.group(0)!r} without citing {page}")
    return problems


def test_quoted_figures_are_the_results_pages_rows():
    problems = quoted_figure_problems(QUOTED_FIGURES)
    assert not problems, "\n".join(problems)


def test_quoted_figure_check_sees_a_stale_quote():
    """The README's old sweep cost (§25's 1.8 s per eye) against §35's row fails."""
    stale = [("README.md", r"takes\s+([\d.]+) s on two idle CPU cores", R35,
              r"\*\*[\d.]+ s: ([\d.]+) s/eye\*\*")]
    assert quoted_figure_problems(stale)
    assert quoted_figure_problems([("README.md", r"no such quote (\d)", R35, COLD_35)])
