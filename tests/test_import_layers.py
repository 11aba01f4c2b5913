"""The whole package imports in one direction, with no circle (docs/design.md#layers).

Every module of ``lfjax/`` is parsed with ``ast`` (nothing is imported or run) and its
imports, those inside functions included, are checked against the layer table below:

* a module imports only its own folder or folders of a lower rank (peers do not import
  each other);
* the import graph has no circle (within a layer too);
* an application never imports a private name (or a private module) of another application:
  what two of them share lives below both;
* no module imports another module's private name (``_name``; a dunder such as
  ``__version__`` is public) or reads one as an attribute (``module._name``), and a private
  module (``_params``) is imported only inside its own package: what two modules share is a
  public name of the one that owns it;
* an import inside a function body is allowed only for the heavy optional dependencies in
  ``DEFERRED_OK``, each with its reason.

The graph is also what ``docs/_tools/import_graph.py`` draws into ``docs/img/import-graph.svg``.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LFJAX = ROOT / "lfjax"

LAYERS = {
    "lfjax.base": 0, "lfjax._version": 0,
    "lfjax.model": 1,
    "lfjax.display": 2,
    "lfjax.kernel": 3,
    "lfjax.planner": 4,
    "lfjax.vision": 5,
    "lfjax.layout_opt": 6, "lfjax.sweep": 6, "lfjax.binocular": 6,
    "lfjax.studies": 7, "lfjax.design": 7,
    "lfjax.reproduce": 8,
    "lfjax.cli": 9,
    "lfjax": 10,
}
"""Rank of each folder of ``lfjax/`` (every module in it has its folder's rank): a module
imports only folders of a lower rank, or its own folder. Folders of one rank are peers and
import neither each other nor anything above."""

LAYER_NAMES = {
    0: "conventions and maths", 1: "the model's data", 2: "the display",
    3: "the optics kernel and the pure pipeline", 4: "the planner",
    5: "vision entry points", 6: "applications (layout optimiser, sweep, both eyes)",
    7: "applications built on those (display studies, design)",
    8: "the paper's study", 9: "the command line", 10: "the package's face",
}

APPLICATIONS = ("lfjax.layout_opt", "lfjax.sweep", "lfjax.studies", "lfjax.design",
                "lfjax.reproduce")

DEFERRED_OK = {
    "matplotlib": "plotting is optional and slow to import; only figure-writing calls pay",
    "xarray": "Datasets are built only when a study or a sweep writes them",
    "zarr": "only the sweep's store opens it",
    "pandas": "tables only; slow to import",
    "tqdm": "progress bars only",
    "colour": "colour-science loads its CIE tables on import; read once, then cached",
    "jaxopt": "an optional solver of the layout optimiser",
    "scipy": "the display design's host-side L-BFGS-B only; slow to import",
    "beartype": "shape checks are switched on only in the test suite",
}
"""Top-level packages that may be imported inside a function, and why."""


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(LFJAX.rglob("*.py"))}


def folder_of(name: str) -> str:
    """The folder (``lfjax.<folder>``) a module belongs to; ``lfjax`` for the face."""
    parts = name.split(".")
    return ".".join(parts[:2])


def layer_of(name: str) -> int:
    return LAYERS[folder_of(name)]


def application_of(name: str) -> str | None:
    return next((a for a in APPLICATIONS if name == a or name.startswith(a + ".")), None)


def imports(path: Path, name: str, known: set[str]):
    """(target module, imported names, line, inside a function) for every import of ``path``.

    A ``from pkg import x`` whose ``pkg.x`` is a module counts as importing that module."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    in_function: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            in_function.update(id(n) for n in ast.walk(node) if n is not node)
    found = []
    for node in ast.walk(tree):
        deferred = id(node) in in_function
        if isinstance(node, ast.Import):
            found += [(a.name, (), node.lineno, deferred) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            plain = []
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                if sub in known:
                    found.append((sub, (), node.lineno, deferred))
                else:
                    plain.append(alias.name)
            if plain or not node.names:
                found.append((target, tuple(plain), node.lineno, deferred))
    return found


def graph() -> dict[str, set[str]]:
    """{module: lfjax modules it imports} (a package's import means its ``__init__``)."""
    mods = modules()
    known = set(mods)
    return {
        name: {t for t, _, _, _ in imports(path, name, known) if t in known and t != name}
        for name, path in mods.items()
    }


def test_every_module_has_a_layer():
    missing = [m for m in modules() if not _has_layer(m)]
    assert not missing, f"give these modules a layer in LAYERS: {missing}"


def _has_layer(name: str) -> bool:
    try:
        layer_of(name)
    except KeyError:
        return False
    return True


def test_a_folder_imports_only_folders_below_it():
    wrong = [
        f"{m} (layer {layer_of(m)}: {LAYER_NAMES[layer_of(m)]}) imports {d} "
        f"(layer {layer_of(d)}: {LAYER_NAMES[layer_of(d)]})"
        for m, deps in graph().items() for d in sorted(deps)
        if folder_of(d) != folder_of(m) and layer_of(d) >= layer_of(m)
        # the package's face imports the folders it offers
        and m != "lfjax"
    ]
    assert not wrong, "\n".join(wrong)


def find_cycle(g: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, str] = {}

    def visit(node, path):
        state[node] = "open"
        for dep in sorted(g.get(node, ())):
            if state.get(dep) == "open":
                return [*path, node, dep]
            if dep not in state:
                cycle = visit(dep, [*path, node])
                if cycle:
                    return cycle
        state[node] = "done"
        return None

    for node in sorted(g):
        if node not in state:
            cycle = visit(node, [])
            if cycle:
                return cycle
    return None


def test_import_graph_has_no_cycle():
    g = graph()
    # A module's import of its own package is the package's __init__ being run first, which
    # Python does anyway; the edges that could close a circle are the others.
    g = {m: {d for d in deps if not m.startswith(d + ".")} for m, deps in g.items()}
    cycle = find_cycle(g)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_applications_import_each_other_in_one_direction():
    """Collapsed to one node per application, the graph still has no circle (a circle
    between two packages can hide behind module-level edges that are each acyclic)."""
    g: dict[str, set[str]] = {}
    for m, deps in graph().items():
        a = application_of(m)
        if a is None:
            continue
        g.setdefault(a, set()).update(
            b for b in map(application_of, deps) if b is not None and b != a)
    cycle = find_cycle(g)
    assert cycle is None, "applications import each other in a circle: " + " -> ".join(cycle)


def test_applications_use_no_private_name_of_another():
    mods = modules()
    known = set(mods)
    wrong = []
    for name, path in mods.items():
        mine = application_of(name)
        if mine is None:
            continue
        for target, names, line, _ in imports(path, name, known):
            theirs = application_of(target)
            if theirs is None or theirs == mine:
                continue
            private_module = any(p.startswith("_") and p != "__init__" for p in target.split("."))
            private_names = [n for n in names if n.startswith("_")]
            if private_module or private_names:
                wrong.append(f"{name}:{line} imports {target} {private_names or ''}")
    assert not wrong, "\n".join(wrong)


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_name_uses(path: Path, name: str, known: set[str]) -> list[str]:
    """Every use in ``path`` (module ``name``) of another module's private name: imported
    (``from m import _x``), read as an attribute of an imported module (``m._x``), or a
    private module imported from outside its own package."""
    found = []
    for target, names, line, _ in imports(path, name, known):
        if not target.startswith("lfjax"):
            continue
        parts = target.split(".")
        for depth, part in enumerate(parts):
            if _private(part):
                owner = ".".join(parts[:depth])  # the package the private module belongs to
                if not (name == owner or name.startswith(owner + ".")):
                    found.append(f"{name}:{line} imports the private module {target}")
                break
        if target != name:
            found += [f"{name}:{line} imports {target}.{n}" for n in names if _private(n)]
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    bound: dict[str, str] = {}  # local name → the lfjax module it is bound to
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("lfjax"):
                    bound[alias.asname or alias.name.split(".")[0]] = (
                        alias.name if alias.asname else alias.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                if f"{target}.{alias.name}" in known:
                    bound[alias.asname or alias.name] = f"{target}.{alias.name}"
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and _private(node.attr)):
            continue
        chain, value = [], node.value
        while isinstance(value, ast.Attribute):
            chain.append(value.attr)
            value = value.value
        if isinstance(value, ast.Name) and value.id in bound:
            module = ".".join([bound[value.id], *reversed(chain)])
            if module in known and module != name:
                found.append(f"{name}:{node.lineno} reads {module}.{node.attr}")
    return found


def test_no_module_uses_another_modules_private_name():
    mods = modules()
    known = set(mods)
    wrong = [use for name, path in mods.items() for use in private_name_uses(path, name, known)]
    assert not wrong, "\n".join(wrong)


def test_imports_inside_functions_only_for_heavy_optional_dependencies():
    mods = modules()
    known = set(mods)
    wrong = [
        f"{name}:{line} imports {target} inside a function"
        for name, path in mods.items()
        for target, _, line, deferred in imports(path, name, known)
        if deferred and target.split(".")[0] not in DEFERRED_OK
    ]
    assert not wrong, "\n".join(wrong)


def test_the_checks_see_what_they_must(tmp_path):
    """Guards the guard: a relative import inside a function is found, resolved and marked
    deferred, a submodule imported by name counts as a module, and a circle is found."""
    pkg = tmp_path / "lfjax" / "reproduce"
    pkg.mkdir(parents=True)
    module = pkg / "claims.py"
    module.write_text("from . import report\ndef f():\n    from ..sweep.store import _x\n")
    found = imports(module, "lfjax.reproduce.claims", {"lfjax.reproduce.report", "lfjax.sweep.store"})
    assert ("lfjax.reproduce.report", (), 1, False) in found
    assert ("lfjax.sweep.store", ("_x",), 3, True) in found
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    assert layer_of("lfjax.sweep.store") == LAYERS["lfjax.sweep"]
    other = tmp_path / "lfjax" / "sweep"
    other.mkdir(parents=True)
    (other / "run.py").write_text(
        "from lfjax.vision.focus import _grid, public\n"
        "from lfjax.layout_opt import _params\n"
        "from lfjax import _version\n"
        "from lfjax._version import __version__\n"
        "from lfjax.kernel import optics\n"
        "optics._field_check(optics.public, optics.__name__)\n")
    known = {"lfjax.vision.focus", "lfjax.layout_opt", "lfjax.layout_opt._params", "lfjax._version",
             "lfjax.kernel", "lfjax.kernel.optics"}
    uses = private_name_uses(other / "run.py", "lfjax.sweep.run", known)
    assert uses == ["lfjax.sweep.run:1 imports lfjax.vision.focus._grid",
                    "lfjax.sweep.run:2 imports the private module lfjax.layout_opt._params",
                    "lfjax.sweep.run:6 reads lfjax.kernel.optics._field_check"], uses
    inside = tmp_path / "lfjax" / "layout_opt"
    inside.mkdir(parents=True)
    (inside / "_solver.py").write_text("from lfjax.layout_opt._params import FreeParams\n")
    assert private_name_uses(inside / "_solver.py", "lfjax.layout_opt._solver", known) == []
    assert folder_of("lfjax.kernel.optics") == "lfjax.kernel"
    assert application_of("lfjax.layout_opt._solver") == "lfjax.layout_opt"


def test_the_folders_are_the_layers():
    """``ls lfjax`` is the architecture: every entry is a folder of the table (or the
    package's version and data), and the table names no folder that is not there."""
    entries = {p.name for p in LFJAX.iterdir() if not p.name.startswith("__")}
    folders = {f"lfjax.{n}" for n in entries if (LFJAX / n / "__init__.py").exists()}
    assert folders == {f for f in LAYERS if f.count(".") == 1} - {"lfjax._version"}
    loose = {n for n in entries - {"data", "_version.py", "py.typed"}
             if not (LFJAX / n / "__init__.py").exists()}
    assert not loose, f"modules outside a layer folder: {sorted(loose)}"


PROJECT_WIDE_TESTS = {
    "test_docs.py": "the documentation site, the README's and guides' examples",
    "test_errors.py": "bad input at every public entry point",
    "test_gpu_check.py": "benchmarks/speed/gpu_check.sh, the one-command GPU check, on the CPU",
    "test_import_layers.py": "this file: the layers and the tests' tree",
    "test_isetbio_style.py": "the ISETBio-style baseline kept beside the tests",
    "test_module_tests.py": "every module with logic has tests named after it",
    "test_precision.py": "every matrix product asks for full precision",
    "test_probes_inputs.py": "issue #52's probes: every input checked before work, at every "
                             "entry point",
    "test_probes_images.py": "issue #52's probes of retinal images and the retina command",
    "test_probes_outputs.py": "issue #52's probes of output folders and stores, kept as tests",
    "test_reference_selfcheck.py": "the float64 reference against analytic results",
    "test_shapes.py": "the shape checks of every public numerical entry point",
    "test_transforms.py": "every public numerical function under jit, vmap and grad",
}
"""Test files that check the whole package at once, and so sit at the top of tests/."""


def test_the_tests_mirror_the_package():
    """tests/<folder>/ holds the tests of lfjax/<folder>/ (one file per module or per
    folder); only the project-wide checks above sit at the top."""
    tests = ROOT / "tests"
    folders = {f.split(".")[1] for f in LAYERS if f.count(".") == 1 and f != "lfjax._version"}
    have = {p.name for p in tests.iterdir() if p.is_dir() and any(p.glob("test_*.py"))}
    assert have <= folders, f"test folders with no package folder: {sorted(have - folders)}"
    untested = sorted(folders - have)
    assert not untested, f"package folders without a tests/<folder>/: {untested}"
    top = {p.name for p in tests.glob("test_*.py")}
    assert top == set(PROJECT_WIDE_TESTS), (
        f"unexpected top-level test files {sorted(top - set(PROJECT_WIDE_TESTS))}; "
        f"missing {sorted(set(PROJECT_WIDE_TESTS) - top)}")
    names = [p.name for p in tests.rglob("test_*.py")]
    assert len(names) == len(set(names)), "test file names must be unique across folders"


def test_no_test_file_imports_another():
    """What tests share lives in helpers.py, reference.py or conftest.py: a test file that
    imports another passes or fails by which files its pytest worker happened to collect."""
    tests = ROOT / "tests"
    names = {p.stem for p in tests.rglob("test_*.py")}
    wrong = []
    for path in tests.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            targets = ([a.name for a in node.names] if isinstance(node, ast.Import)
                       else [node.module] if isinstance(node, ast.ImportFrom) and node.module
                       else [])
            wrong += [f"{path.relative_to(ROOT)}:{node.lineno} imports {t}"
                      for t in targets if t.split(".")[0] in names]
    assert not wrong, "\n".join(wrong)
