"""Griffe extension: render lfjax's docstring house style faithfully in the API reference.

lfjax's docstrings are numpydoc-like with two habits that a strict numpydoc parser misreads:

* an entry's description is written on its name line — ``depths_D : (n_depth,) rendered
  depths, D`` — so that units and shapes sit next to the name. Read literally, that line is
  a *type*; it is turned into the entry's description (the type shown is the annotation);
* a closing paragraph follows the last section after a blank line, without a header. It is
  given a ``Notes`` header instead of being read as more parameters;
* a section header may carry a note in parentheses — ``Attributes (lengths in mm)`` — which
  numpydoc does not recognise: the header becomes ``Attributes`` and the note a paragraph
  before it;
* a ``Returns``/``Yields`` entry is either ``name : description`` or a line of prose; numpydoc
  reads both as a *type*, so each becomes a description (the type shown is the annotation).

The summary tables of the API pages show the first *line* of each docstring; the first
paragraph is reflowed so that its first line is its first sentence, whole.

``.. math::`` directives and ``:math:`` roles become ``$$…$$`` and ``$…$`` for
pymdownx.arithmatex (docs/_hooks/mathml.py renders them to MathML at build time).

Objects are named with Sphinx roles (``:func:`through_focus```,
``:class:`~lfjax.vision.peaks.Peaks```). Markdown has no roles, so each becomes a cross-reference
when the name resolves to a public lfjax object (relative names are resolved in the
docstring's own scope, as Python would), and a code span otherwise (``xarray.Dataset``,
``jax.jit``). A reference that resolves but is missing from the reference pages fails the
strict build, as a broken link should.
"""

from __future__ import annotations

import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:mod|class|func|meth|attr|data|obj|exc):`(~?)([^`]+)`")
SECTIONS = {"Parameters", "Attributes", "Returns", "Yields", "Raises", "Other Parameters"}
NOTED_HEADER = re.compile(r"^(?P<indent>\s*)(?P<name>[A-Z][A-Za-z ]*?)\s+\((?P<note>.+)\)\s*$")
MATH_ROLE = re.compile(r":math:`([^`]+)`")
MATH_DIRECTIVE = re.compile(r"^(?P<indent>\s*)\.\. math::\s*(?P<first>.*)$")
# A Returns line that is a type (``StackResult``, ``jax.Array``, ``tuple[Peaks, Array]``), not
# prose.
TYPE_LINE = re.compile(r"^[A-Za-z_][\w.]*(\[[\w., |\[\]]*\])?(\s*\|\s*[A-Za-z_][\w.]*)*$")
# The end of a sentence: . ! or ? before a space and a capital, an opening parenthesis, a
# quote or a code span — unless it closes an abbreviation.
SENTENCE_END = re.compile(
    r"(?<!\be\.g)(?<!\bi\.e)(?<!\bal)(?<!\bcf)(?<!\bvs)(?<!\bFig)(?<!\bEq)(?<!\bSec)"
    r"[.!?](?=\s+[A-Z(`\"'*\[])"
)
ENTRY = re.compile(
    r"^(?P<names>\*{0,2}[A-Za-z_]\w*(?:\s*,\s*\*{0,2}[A-Za-z_]\w*)*)\s*(?::\s*(?P<rest>.*))?$"
)
UNDERLINE = re.compile(r"^\s*-{3,}\s*$")


def _public(path: str) -> bool:
    return path.startswith("lfjax") and not any(
        part.startswith("_") for part in path.split(".")[1:]
    )



# A leading array shape, ``()`` or ``(n_depth, n_acc)`` (a comma or nothing inside).
SHAPE = re.compile(r"^\((?P<shape>(?:[\w…. *+-]+,\s*)+[\w…. *+-]*|)\)(?=\s|$)")
# Where a name line's text may end without ending a sentence: a type or its qualifier.
TYPE_TAIL = re.compile(r"(?:\boptional|\bkeyword-only|[\w\]]\s*\|\s*None)$")


def _first_line(text: str, body: list[str]) -> list[str]:
    """The description lines of an entry whose name line carries ``text``.

    A leading shape is written as one (``()`` alone read as stray punctuation). The text reads
    as the description's first line; a line break keeps it apart from the indented text that
    follows (``float, D, optional`` above its explanation), unless that text goes on with the
    same sentence (it starts in lower case and ``text`` ends without a stop), where a break
    would cut the sentence in two."""
    text = text.strip()
    shape = SHAPE.match(text)
    if shape:
        rest = text[shape.end():].strip()
        text = f"shape `({shape.group('shape')})`" + (f": {rest}" if rest else "")
    if not body:
        return ["    " + text]
    nxt = body[0].strip()
    goes_on = (bool(nxt) and (nxt[0].islower() or nxt[0] in "(`:[0123456789≤≥<>=±−-")
               and not re.search(r"[.:;!?]$", text) and not TYPE_TAIL.search(text))
    if goes_on:
        return ["    " + text + " " + nxt] + body[1:]
    return ["    " + text + "<br>"] + body


def normalise_sections(text: str) -> str:
    """House style → numpydoc (see the module docstring)."""
    lines = text.split("\n")
    out: list[str] = []
    section = None  # the current numpydoc section's name, None outside one

    def is_header(k: int) -> bool:
        return k + 1 < len(lines) and bool(lines[k].strip()) and bool(UNDERLINE.match(lines[k + 1]))

    i = 0
    while i < len(lines):
        line = lines[i]
        if is_header(i):
            noted = NOTED_HEADER.match(line)
            if noted and noted.group("name") in SECTIONS:
                # "Attributes (lengths in mm)": the note becomes a paragraph before the header.
                indent, name = noted.group("indent"), noted.group("name")
                note = noted.group("note").strip()
                out += [indent + f"{note[0].upper()}{note[1:]}.", "", indent + name,
                        indent + "-" * len(name)]
                section = name
            else:
                section = line.strip() if line.strip() in SECTIONS else None
                out += [line, lines[i + 1]]
            i += 2
            continue
        if section and not line.strip():
            out.append(line)
            i += 1
            nxt = lines[i] if i < len(lines) else ""
            if (nxt.strip() and not nxt.startswith(" ") and not is_header(i)
                    and (section in ("Returns", "Yields") or not ENTRY.match(nxt))):
                out += ["Notes", "-----"]
                section = None
            continue
        if section and not line.startswith(" "):
            j = i + 1  # the entry's own description lines follow, indented
            while j < len(lines) and lines[j].startswith(" ") and lines[j].strip():
                j += 1
            body = lines[i + 1:j]
            m = ENTRY.match(line)
            if section in ("Returns", "Yields"):
                if m and m.group("rest") and " : " in line and TYPE_LINE.match(m.group("rest").strip()):
                    head, text = line, ""  # numpydoc's own "name : type"
                elif m and m.group("rest") is not None and " : " in line:
                    # "name : description": numpydoc's "name :" takes the annotation as type.
                    head, text = m.group("names") + " :", m.group("rest")
                elif TYPE_LINE.match(line.strip()):
                    head, text = line, ""
                else:  # prose: no name, the annotation as type
                    head, text = ":", line.strip()
                    # Prose wrapped without indentation continues the same entry.
                    while (j < len(lines) and lines[j].strip() and not lines[j].startswith(" ")
                           and not is_header(j) and " : " not in lines[j]):
                        text += " " + lines[j].strip()
                        j += 1
                    k = j
                    while k < len(lines) and lines[k].startswith(" ") and lines[k].strip():
                        k += 1
                    body, j = lines[j:k], k
                if text:
                    body = _first_line(text, body)
                out += [head] + body
                i = j
                continue
            if m and (m.group("rest") or "," in m.group("names")):
                if m.group("rest"):
                    body = _first_line(m.group("rest"), body)
                # One entry per name: "spectrum, options : ..." documents both.
                for name in re.split(r"\s*,\s*", m.group("names")):
                    out += [name] + body
                i = j
                continue
        out.append(line)
        i += 1
    return "\n".join(out)


def math_to_arithmatex(text: str) -> str:
    """``.. math::`` directives → ``$$`` blocks, ``:math:`x``` roles → ``$x$``."""
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        m = MATH_DIRECTIVE.match(lines[i])
        if not m:
            out.append(lines[i])
            i += 1
            continue
        indent = m.group("indent")
        body = [m.group("first").strip()] if m.group("first").strip() else []
        i += 1
        # The equation: the lines indented deeper than the directive (blank lines inside).
        while i < len(lines) and (not lines[i].strip() or
                                  len(lines[i]) - len(lines[i].lstrip()) > len(indent)):
            if lines[i].strip():
                body.append(lines[i].strip())
            elif body and i + 1 < len(lines) and not lines[i + 1].startswith(indent + " "):
                break
            i += 1
        if out and out[-1].strip():
            out.append("")
        out += [indent + "$$", *(indent + b for b in body), indent + "$$", ""]
        while i < len(lines) and not lines[i].strip():
            i += 1
    return MATH_ROLE.sub(lambda r: f"${r.group(1)}$", "\n".join(out))


def first_sentence_first(text: str) -> str:
    """Reflow the docstring's first paragraph so that its first line is its first sentence.

    mkdocstrings' summary tables show a docstring's first line; a sentence wrapped at the
    source's line width would be cut there. Markdown joins the lines of a paragraph, so the
    rendered docstring is unchanged."""
    lines = text.split("\n")
    end = 0
    while end < len(lines) and lines[end].strip() and not (
            end + 1 < len(lines) and UNDERLINE.match(lines[end + 1])):
        end += 1
    first = lines[:end]
    if len(first) < 2 or any(ln.lstrip().startswith(("|", "- ", "* ", ">>>", "..", "$$"))
                             for ln in first):
        return text
    joined = " ".join(ln.strip() for ln in first)
    m = SENTENCE_END.search(joined)
    head, rest = (joined[:m.end()], joined[m.end():].strip()) if m else (joined, "")
    return "\n".join([head, *([rest] if rest else []), *lines[end:]])


class SphinxRoles(griffe.Extension):
    def on_object(self, *, obj: griffe.Object, **kwargs) -> None:  # noqa: ARG002
        if obj.docstring is None:
            return
        scope = obj if obj.is_module or obj.is_class else obj.parent

        def link(match: re.Match) -> str:
            short, name = match.group(1) == "~", match.group(2).strip()
            shown = name.rsplit(".", 1)[-1] if short else name
            target = name
            if not name.startswith("lfjax"):
                try:
                    target = scope.resolve(name) if scope is not None else name
                except Exception:  # not a name in scope: an external object
                    target = name
            if _public(target):
                return f"[`{shown}`][{target}]"
            return f"`{shown}`"

        value = math_to_arithmatex(normalise_sections(obj.docstring.value))
        obj.docstring.value = first_sentence_first(ROLE.sub(link, value))

    def on_package(self, *, pkg: griffe.Module, **kwargs) -> None:
        # griffe calls on_object for every object but the package itself.
        self.on_object(obj=pkg, **kwargs)
        # Dataclasses' __init__ are made by griffe's own extension, on this same event,
        # before this one: every object is there now.
        for obj in _walk(pkg):
            if obj.is_class:
                _field_help(obj)
            if obj.is_function:
                for parameter in obj.parameters:
                    if _lossy(parameter.default):
                        parameter.default = str(parameter.default)
            elif obj.is_attribute:
                if _lossy(obj.value):
                    obj.value = str(obj.value)
                if obj.annotation is None:
                    obj.annotation = _literal_type(obj.value)


def _walk(obj, seen=None):
    seen = set() if seen is None else seen
    for member in list(obj.members.values()):
        if member.is_alias or id(member) in seen:
            continue
        seen.add(id(member))
        yield member
        if member.is_module or member.is_class:
            yield from _walk(member, seen)


def _lossy(value) -> bool:
    """An expression the API pages would render with parts missing: an attribute of a call
    (``tuple(grid(-2, 2, 0.5).tolist())`` showed as ``tuple(tolist())``)."""
    if not isinstance(value, griffe.Expr):
        return False
    return any(isinstance(e, griffe.ExprAttribute) and not isinstance(e.values[0], griffe.ExprName)
               for e in value.iterate(flat=False) if isinstance(e, griffe.Expr))


def _literal_type(value) -> str | None:
    """The type of a constant written as a literal (``DECIMALS = 9``: ``int``), for a module
    or class attribute without an annotation; None for anything else."""
    import ast

    if value is None:
        return None
    try:
        literal = ast.literal_eval(str(value))
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        return None
    if isinstance(literal, (tuple, list, set, frozenset)):
        kinds = sorted({type(v).__name__ for v in literal})
        inner = kinds[0] if len(kinds) == 1 else " | ".join(kinds)
        name = type(literal).__name__
        return f"{name}[{inner}, ...]" if name == "tuple" and kinds else (
            f"{name}[{inner}]" if kinds else name)
    if isinstance(literal, dict):
        return "dict"
    return type(literal).__name__


def _field_help(cls) -> None:
    """Dataclass fields that declare their help in their metadata (a
    :class:`lfjax.sweep.config_keys.Key`: the TOML key, its help, unit and rules) get it as
    their docstring, as a reader of the class's source sees it."""
    import dataclasses
    import importlib

    if not any(isinstance(m, griffe.Attribute) and "metadata" in str(m.value)
               for m in cls.members.values() if not m.is_alias):
        return
    try:
        module = importlib.import_module(cls.module.path)
        fields = dataclasses.fields(getattr(module, cls.name))
    except (ImportError, AttributeError, TypeError):
        return
    # The module's completed declarations (name and unit filled in from the field), if any.
    completed = {getattr(k, "field", None): k for k in getattr(module, "KEYS", ())}
    for f in fields:
        member = cls.members.get(f.name)
        if member is None or member.is_alias or member.docstring is not None:
            continue
        for declared in f.metadata.values():
            declared = completed.get(f.name, declared)
            text = getattr(declared, "help", None)
            if not isinstance(text, str):
                continue
            section, name = getattr(declared, "section", ""), getattr(declared, "name", "")
            where = f"[{section}] {name or f.name}" if section else None
            unit = getattr(declared, "unit", "")
            rules = declared.rules() if callable(getattr(declared, "rules", None)) else ""
            line = (f"`{where}` in the TOML file: " if where else "") + text
            line += f"; {rules}" if rules else (f" ({unit})" if unit else "")
            member.docstring = griffe.Docstring(line.rstrip(".") + ".", parent=member)
            break
