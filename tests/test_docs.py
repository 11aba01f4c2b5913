"""The documentation site and the project's citations.

The site (``mkdocs.yml``, ``docs/``) is built in strict mode, so a broken link, an anchor
that does not exist, a cross-reference to an object missing from the API reference or a
docstring the parser misreads fails here. The API reference must hold a page for every
public module and every name ``lfjax`` exports, and no file of the project may cite a file
outside it.
"""

from __future__ import annotations

import importlib.util
import os
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

import lfjax

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "api"


def _mkdocs_missing() -> str | None:
    for module in ("mkdocs", "material", "mkdocstrings_handlers.python", "mkdocs_jupyter"):
        try:
            if importlib.util.find_spec(module) is None:
                return module
        except ModuleNotFoundError:
            return module
    return None


def test_site_builds_strict(tmp_path):
    missing = _mkdocs_missing()
    if missing is not None:
        pytest.skip(f"{missing} is not installed: pip install -e '.[docs]' to build the site")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=300,
    )
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"mkdocs build --strict failed:\n{log[-6000:]}"
    site = tmp_path / "site"
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
    assert out[4:6] == ["depths_D", "    (n_depth,) rendered depths, D"]
    assert out[6:9] == ["window_D", "    float, D, optional<br>", "    Half-width."]
    assert out[9:13] == ["name", "    str", "source", "    str"]
    assert out[14:17] == ["Notes", "-----", "The closing paragraph, not a parameter."]
