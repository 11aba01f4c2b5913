"""Every module of ``lfjax/`` with logic has tests that say so
(docs/design.md#where-each-capability-lives).

Parsed with ``ast`` (nothing is imported or run). The rule:

* A module **has logic** when it defines at least one function or method (at module level
  or in a class body) whose body, its docstring aside, is more than one trivial statement
  (``pass``, ``...``, or ``return`` of a name, an attribute or a constant). A module of
  re-exports, constants, type aliases or field-only classes (dataclasses, named tuples,
  enums) has none; neither has a ``__main__.py`` whose only code is a guarded call.
* Such a module ``lfjax/<folder>/<module>.py`` is **covered** when
  ``tests/<folder>/test_<name>.py`` or ``tests/<folder>/test_<folder>_<name>.py`` exists,
  ``<name>`` being the module's name without a leading underscore (``_problem.py`` →
  ``test_problem.py``) and, for a package's ``__init__.py``, the folder's name
  (``layout_opt/__init__.py`` → ``tests/layout_opt/test_layout_opt.py``); the second form is
  for a name two folders share (``display/lenticular.py``, ``design/lenticular.py``: test
  file names are unique across folders, tests/test_import_layers.py).
* Otherwise some test file's module docstring must name it on a line of the one fixed form
  ``Covers: lfjax.layout_opt._problem, lfjax.layout_opt._run`` (full dotted module names,
  separated by commas; several such lines may follow one another). Write it only in a file
  whose tests do exercise that module's logic. The modules at the top of ``lfjax/``
  (``lfjax/__init__.py``, ``lfjax/_version.py``), and any in a folder two levels down, have
  no folder of tests of their own and always need the line.

A ``Covers:`` line that names no module of ``lfjax/`` (a module renamed, split or removed)
fails too, so the lines follow the package when it moves.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LFJAX = ROOT / "lfjax"
TESTS = ROOT / "tests"

COVERS = re.compile(r"^\s*Covers:\s*(.+?)\s*$")
"""The one form of a coverage line in a test file's module docstring."""


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _trivial(statement: ast.stmt) -> bool:
    """``pass``, ``...`` (or any bare constant) and ``return`` of a name, attribute or
    constant: statements that hold no logic of their own."""
    if isinstance(statement, ast.Pass):
        return True
    if isinstance(statement, ast.Expr) and isinstance(statement.value, ast.Constant):
        return True
    return isinstance(statement, ast.Return) and (
        statement.value is None
        or isinstance(statement.value, (ast.Name, ast.Attribute, ast.Constant)))


def _has_body(function: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    body = list(function.body)
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str):
        body = body[1:]  # the docstring
    return len(body) > 1 or (len(body) == 1 and not _trivial(body[0]))


def has_logic(source: str) -> bool:
    """Whether a module's source defines a function or method with a non-trivial body
    (the rule in this file's docstring)."""
    tree = ast.parse(source)
    functions = (ast.FunctionDef, ast.AsyncFunctionDef)
    for node in tree.body:
        if isinstance(node, functions) and _has_body(node):
            return True
        if isinstance(node, ast.ClassDef):
            # Methods of nested classes count as the outer class's.
            if any(isinstance(n, functions) and _has_body(n) for n in ast.walk(node)):
                return True
    return False


def mirror_files(path: Path) -> list[Path]:
    """The test files named after the module at ``path`` (either form is enough); none for
    a module at the top of ``lfjax/``."""
    rel = path.relative_to(LFJAX)
    if len(rel.parts) != 2:
        return []
    folder, file = rel.parts
    name = folder if file == "__init__.py" else Path(file).stem.lstrip("_")
    return [TESTS / folder / f"test_{name}.py", TESTS / folder / f"test_{folder}_{name}.py"]


def covers_lines(docstring: str | None) -> list[str]:
    """The module names of the ``Covers:`` lines of a test file's docstring."""
    names = []
    for line in (docstring or "").splitlines():
        match = COVERS.match(line)
        if match:
            names += [n.strip() for n in match.group(1).split(",") if n.strip()]
    return names


def covered_by_docstrings() -> dict[str, list[str]]:
    """{module name: [test files whose docstring's Covers: lines name it]}."""
    out: dict[str, list[str]] = {}
    for path in sorted(TESTS.rglob("test_*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
        for name in covers_lines(doc):
            out.setdefault(name, []).append(str(path.relative_to(ROOT)))
    return out


def modules_with_logic() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(LFJAX.rglob("*.py"))
            if has_logic(p.read_text(encoding="utf-8"))}


def test_every_module_with_logic_has_its_tests():
    covered = covered_by_docstrings()
    taken = {p.name for p in TESTS.rglob("test_*.py")}
    missing = []
    for name, path in modules_with_logic().items():
        mirrors = mirror_files(path)
        if name in covered or any(m.exists() for m in mirrors):
            continue
        # A plain name another folder's tests already use is taken (names are unique).
        free = [m for m in mirrors if m.name not in taken] or mirrors[1:]
        add = f"add {free[0].relative_to(ROOT)}, or " if free else ""
        missing.append(f"  {path.relative_to(ROOT)}: {add}put the line "
                       f"'Covers: {name}' in the docstring of the test file that exercises it")
    assert not missing, (
        f"{len(missing)} module(s) with logic have no tests named after them "
        "(tests/test_module_tests.py states the rule):\n" + "\n".join(missing))


def test_covers_lines_name_modules_that_exist():
    known = {module_name(p) for p in LFJAX.rglob("*.py")}
    stale = [f"  {file}: 'Covers: {name}' names no module of lfjax/ (renamed, split or "
             "removed? name the modules that now hold what it tests)"
             for name, files in covered_by_docstrings().items() if name not in known
             for file in files]
    assert not stale, "\n".join(stale)


def test_the_rule_tells_logic_from_faces():
    """The classifier on small sources, so that the rule cannot pass by seeing nothing."""
    assert not has_logic('"""A face."""\nfrom a import b\n__all__ = ["b"]\nX = 1.0\n')
    assert not has_logic("import sys\nfrom m import main\n"
                         "if __name__ == '__main__':\n    sys.exit(main())\n")
    assert not has_logic("class Options(NamedTuple):\n    '''Doc.'''\n    a: int = 1\n")
    assert not has_logic("def f():\n    '''Doc.'''\n    ...\n")
    assert not has_logic("class P(Protocol):\n    def f(self) -> int:\n        return x\n")
    assert has_logic("def f(x):\n    return 2 * x\n")
    assert has_logic("class A:\n    def __check_init__(self):\n        check(self.a)\n")
    assert has_logic("class A:\n    class B:\n        def f(self):\n"
                     "            y = 1\n            return y\n")
    assert covers_lines("Title.\n\nCovers: lfjax.a._b, lfjax.c\nCovers: lfjax.d\n") == [
        "lfjax.a._b", "lfjax.c", "lfjax.d"]
    assert [p.name for p in mirror_files(LFJAX / "layout_opt" / "_problem.py")] == [
        "test_problem.py", "test_layout_opt_problem.py"]
    assert [p.name for p in mirror_files(LFJAX / "sweep" / "__init__.py")] == [
        "test_sweep.py", "test_sweep_sweep.py"]
    assert mirror_files(LFJAX / "_version.py") == []
    logic = modules_with_logic()
    assert "lfjax.kernel.pipeline" in logic and "lfjax.kernel" not in logic
