"""Griffe extension: render lfjax's docstring house style faithfully in the API reference.

lfjax's docstrings are numpydoc-like with two habits that a strict numpydoc parser misreads:

* an entry's description is written on its name line — ``depths_D : (n_depth,) rendered
  depths, D`` — so that units and shapes sit next to the name. Read literally, that line is
  a *type*; it is turned into the entry's description (the type shown is the annotation);
* a closing paragraph follows the last section after a blank line, without a header. It is
  given a ``Notes`` header instead of being read as more parameters.

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
ENTRY = re.compile(
    r"^(?P<names>\*{0,2}[A-Za-z_]\w*(?:\s*,\s*\*{0,2}[A-Za-z_]\w*)*)\s*(?::\s*(?P<rest>.*))?$"
)
UNDERLINE = re.compile(r"^\s*-{3,}\s*$")


def _public(path: str) -> bool:
    return path.startswith("lfjax") and not any(
        part.startswith("_") for part in path.split(".")[1:]
    )


def normalise_sections(text: str) -> str:
    """House style → numpydoc (see the module docstring)."""
    lines = text.split("\n")
    out: list[str] = []
    in_section = False

    def is_header(k: int) -> bool:
        return k + 1 < len(lines) and bool(lines[k].strip()) and bool(UNDERLINE.match(lines[k + 1]))

    i = 0
    while i < len(lines):
        line = lines[i]
        if is_header(i):
            in_section = line.strip() in SECTIONS
            out += [line, lines[i + 1]]
            i += 2
            continue
        if in_section and not line.strip():
            out.append(line)
            i += 1
            nxt = lines[i] if i < len(lines) else ""
            if nxt.strip() and not nxt.startswith(" ") and not is_header(i) and not ENTRY.match(nxt):
                out += ["Notes", "-----"]
                in_section = False
            continue
        if in_section and not line.startswith(" "):
            m = ENTRY.match(line)
            if m and (m.group("rest") or "," in m.group("names")):
                # The entry's own description lines follow, indented.
                j = i + 1
                while j < len(lines) and lines[j].startswith(" ") and lines[j].strip():
                    j += 1
                body = lines[i + 1:j]
                if m.group("rest"):
                    # The name line's text reads as the first line of the description; a
                    # line break keeps it apart from the indented text that follows.
                    body = ["    " + m.group("rest") + ("<br>" if body else "")] + body
                # One entry per name: "spectrum, options : ..." documents both.
                for name in re.split(r"\s*,\s*", m.group("names")):
                    out += [name] + body
                i = j
                continue
        out.append(line)
        i += 1
    return "\n".join(out)


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

        value = normalise_sections(obj.docstring.value)
        obj.docstring.value = ROLE.sub(link, value)
