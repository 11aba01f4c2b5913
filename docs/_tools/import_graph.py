"""Draw the package's import graph by folder into docs/img/import-graph.svg.

    python docs/_tools/import_graph.py

The graph and the folder table are those of ``tests/test_import_layers.py`` (parsed with
``ast``, nothing imported), so the drawing shows what the test checks. One box per folder of
``lfjax/`` (each a layer); rows run bottom-up by rank, and every arrow points from an
importer to what it imports, so every arrow points down. Only the edges no longer path implies
are drawn (the transitive reduction): an import of a module that the importer also reaches
through another of its imports is left out, which keeps the picture readable. The script refuses to draw a graph with
a circle. Graphviz is not needed (matplotlib only).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "img" / "import-graph.svg"


def _rules():
    spec = importlib.util.spec_from_file_location("import_layers", ROOT / "tests" / "test_import_layers.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _node(name: str) -> str:
    return "lfjax.base" if name == "lfjax._version" else ".".join(name.split(".")[:2])


def _reduce(edges: set[tuple[str, str]]) -> set[tuple[str, str]]:
    """The edges of an acyclic graph that no longer path between their ends implies."""
    succ: dict[str, set[str]] = {}
    for a, b in edges:
        succ.setdefault(a, set()).add(b)

    def reachable(start: str, skip: tuple[str, str]) -> set[str]:
        seen, todo = set(), [start]
        while todo:
            n = todo.pop()
            for m in succ.get(n, ()):
                if (n, m) != skip and m not in seen:
                    seen.add(m)
                    todo.append(m)
        return seen

    return {(a, b) for a, b in edges if b not in reachable(a, (a, b))}


def main() -> Path:
    rules = _rules()
    g = rules.graph()
    cycle = rules.find_cycle({m: {d for d in deps if not m.startswith(d + ".")} for m, deps in g.items()})
    if cycle:
        sys.exit("import cycle: " + " -> ".join(cycle))
    edges = {(_node(m), _node(d)) for m, deps in g.items() for d in deps}
    edges = {(a, b) for a, b in edges if a != b and not b.startswith(a + ".")}
    edges = _reduce(edges)
    nodes = sorted({_node(m) for m in g}, key=lambda n: (rules.layer_of(n), n))
    rows: dict[int, list[str]] = {}
    for n in nodes:
        rows.setdefault(rules.layer_of(n), []).append(n)

    width = max(len(r) for r in rows.values())
    fig, ax = plt.subplots(figsize=(1.9 * width + 3.2, 1.25 * len(rows) + 0.6))
    pos = {}
    for layer, names in rows.items():
        offset = (width - len(names)) / 2
        for i, n in enumerate(names):
            pos[n] = (offset + i + 0.5, layer)
    for a, b in sorted(edges):
        (xa, ya), (xb, yb) = pos[a], pos[b]
        same = ya == yb
        ax.add_patch(FancyArrowPatch(
            (xa, ya), (xb, yb), arrowstyle="-|>", mutation_scale=7, lw=0.5,
            color="tab:orange" if same else "0.55", alpha=0.8 if same else 0.35,
            connectionstyle="arc3,rad=0.35" if same else "arc3,rad=0.0",
            shrinkA=11, shrinkB=11, zorder=1))
    for n, (x, y) in pos.items():
        label = n.removeprefix("lfjax.") if n != "lfjax" else "lfjax (face)"
        if n != "lfjax":
            label += "/"
        ax.add_patch(FancyBboxPatch((x - 0.43, y - 0.16), 0.86, 0.32,
                                    boxstyle="round,pad=0.02", fc="white", ec="0.3", lw=0.8, zorder=2))
        ax.text(x, y, label, ha="center", va="center", fontsize=7.5, zorder=3)
    for layer in rows:
        ax.text(-0.15, layer, f"{layer}  {rules.LAYER_NAMES[layer]}", ha="right", va="center",
                fontsize=8, color="0.25")
    ax.set_xlim(-3.2, width + 0.1)
    ax.set_ylim(-0.6, max(rows) + 0.6)
    ax.axis("off")
    ax.set_title("lfjax folders, bottom-up: every arrow goes from an importer down to a folder "
                 "it imports; no circle", fontsize=9)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, bbox_inches="tight", metadata={"Date": None})
    return OUT


if __name__ == "__main__":
    print(main())
