"""`lfjax.reproduce` and `lfjax.sweep` import their parts in one direction:
config ← study ← settling ← alternatives/report/figures ← run ← face, and config ← compute ← … ← report.

Parsed with ``ast`` (nothing is imported or run). The rules for the whole package (layers,
no circle, no deferred imports) are in ``tests/test_import_layers.py``; these are the finer
orders inside the two application packages.
"""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LFJAX = ROOT / "lfjax"
PACKAGE = LFJAX / "reproduce"

LAYERS = {
    "config": 0,
    "study": 1,
    "examples": 2,
    "settling": 2,
    "alternatives": 3,
    "report": 3,
    "figures": 3,
    "run": 4,
    "__init__": 5,
}
"""Each part may import only parts of a strictly lower layer (lower: closer to the data)."""


def _imported_modules(path: Path, package: str, top_level_only: bool = False) -> set[str]:
    """Absolute names of every module ``path`` imports, at any depth (lazy imports too), or
    at module level only.

    ``package`` is the package ``path`` belongs to (for relative imports)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found = set()
    for node in (tree.body if top_level_only else ast.walk(tree)):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = parts[: len(parts) - node.level + 1]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = node.module
            found.add(prefix)
            # `from pkg import name` may import the submodule pkg.name
            found.update(f"{prefix}.{alias.name}" for alias in node.names)
    return found


def _part_graph() -> dict[str, set[str]]:
    """{part: parts of lfjax.reproduce it imports} for every module of the package."""
    graph = {}
    for path in sorted(PACKAGE.glob("*.py")):
        names = _imported_modules(path, "lfjax.reproduce")
        graph[path.stem] = {
            n.split(".")[2] for n in names
            if n.startswith("lfjax.reproduce.") and n.split(".")[2] in LAYERS
        } - {path.stem}
    return graph


def test_every_part_has_a_layer():
    parts = {p.stem for p in PACKAGE.glob("*.py")}
    assert parts == set(LAYERS), (
        f"give each module of lfjax/reproduce a layer in LAYERS: {sorted(parts ^ set(LAYERS))}"
    )


def test_parts_import_only_lower_layers():
    wrong = [f"{part} (layer {LAYERS[part]}) imports {dep} (layer {LAYERS[dep]})"
             for part, deps in _part_graph().items() for dep in sorted(deps)
             if LAYERS[dep] >= LAYERS[part]]
    assert not wrong, "; ".join(wrong)


def test_part_graph_is_acyclic():
    graph = _part_graph()
    state: dict[str, str] = {}

    def visit(node, path):
        state[node] = "open"
        for dep in sorted(graph.get(node, ())):
            if state.get(dep) == "open":
                raise AssertionError("import cycle: " + " -> ".join([*path, node, dep]))
            if dep not in state:
                visit(dep, [*path, node])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [])


def test_library_does_not_import_the_reproduction():
    """Only the command line (the top) imports lfjax.reproduce; the library it builds on
    never does, so no cycle can close through a module outside the package."""
    importers = sorted({
        path.relative_to(LFJAX).parts[0] for path in LFJAX.rglob("*.py")
        if PACKAGE not in path.parents
        and any(n == "lfjax.reproduce" or n.startswith("lfjax.reproduce.")
                for n in _imported_modules(path, "lfjax"))
    })
    assert importers == ["cli"]


def test_the_check_sees_a_cycle(tmp_path):
    """The parser resolves relative imports, lazy ones included (guards the guard)."""
    module = tmp_path / "claims.py"
    module.write_text("def f():\n    from . import report\n    from .study import x\n")
    names = _imported_modules(module, "lfjax.reproduce")
    assert {"lfjax.reproduce.report", "lfjax.reproduce.study"} <= names
    assert "lfjax.model.eyes" in _imported_modules(PACKAGE / "config.py", "lfjax.reproduce")


SWEEP = LFJAX / "sweep"
SWEEP_LAYERS = {"config_keys": 0, "target": 0, "distributed": 0, "config": 1,
                "config_files": 2, "compute": 3, "store_checks": 3, "store_lock": 3, "guard": 4,
                "store": 4, "run": 5, "ten_eyes": 5, "report": 6, "__init__": 7}
"""lfjax.sweep: config_keys / target / distributed ← config ← config_files ← compute /
store_checks / store_lock ← guard / store ← run / ten_eyes ← report ← entry."""


def test_sweep_parts_import_only_lower_layers():
    parts = {p.stem for p in SWEEP.glob("*.py")}
    assert parts == set(SWEEP_LAYERS), sorted(parts ^ set(SWEEP_LAYERS))
    wrong = []
    for path in sorted(SWEEP.glob("*.py")):
        deps = {n.split(".")[2] for n in _imported_modules(path, "lfjax.sweep")
                if n.startswith("lfjax.sweep.") and n.split(".")[2] in SWEEP_LAYERS}
        wrong += [f"{path.stem} imports {d}" for d in sorted(deps - {path.stem})
                  if SWEEP_LAYERS[d] >= SWEEP_LAYERS[path.stem]]
    assert not wrong, "; ".join(wrong)


def test_the_sweep_never_imports_the_reproduction():
    """lfjax.reproduce reads sweep stores (--population); the sweep reads the paper's claims
    from lfjax.vision.claims, below both, and never imports lfjax.reproduce (a circle)."""
    for path in SWEEP.glob("*.py"):
        names = _imported_modules(path, "lfjax.sweep")
        assert not any(n.startswith("lfjax.reproduce") for n in names), path


LAYOUT_OPT = LFJAX / "layout_opt"
LAYOUT_OPT_ORDER = ("_eye_draw", "_params", "_feasible", "_problem", "_objectives", "_evaluation", "_solver",
                    "_files", "_run", "__init__")
"""lfjax.layout_opt: each private part imports only the parts before it; the face imports all."""


def test_layout_opt_parts_import_only_earlier_parts():
    parts = {p.stem for p in LAYOUT_OPT.glob("*.py")}
    assert parts == set(LAYOUT_OPT_ORDER), sorted(parts ^ set(LAYOUT_OPT_ORDER))
    rank = {name: k for k, name in enumerate(LAYOUT_OPT_ORDER)}
    wrong = []
    for path in sorted(LAYOUT_OPT.glob("*.py")):
        package = "lfjax.layout_opt"
        deps = {n.split(".")[2] for n in _imported_modules(path, package)
                if n.startswith(package + ".") and n.split(".")[2] in rank}
        wrong += [f"{path.stem} imports {d}" for d in sorted(deps - {path.stem})
                  if rank[d] >= rank[path.stem]]
    assert not wrong, "; ".join(wrong)
