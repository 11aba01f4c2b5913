"""MkDocs hook: the guides' mentions of lfjax's functions link to their API pages.

A guide names a function as code — `lfjax.through_focus`, `lfjax.sweep.open_store()`, or a
call of the package's face by its bare name, `through_focus` — and this hook turns each such span, outside code blocks and existing links, into a
cross-reference to the object's entry in the API reference. Names are resolved by importing
them, so a face name (``lfjax.through_focus``) reaches the page of the module that defines it
(``lfjax.vision.focus.through_focus``). tests/test_docs.py checks the built guides: every
name that resolves to a public object is a link.
"""

from __future__ import annotations

import html
import importlib
import re

CODE_SPAN = re.compile(
    r"(?<![\[`])`(?P<name>lfjax(?:\.[A-Za-z_]\w*)+|[A-Za-z]\w*)(?P<call>\(\))?`(?!\]|`)")
FENCE = re.compile(r"^\s*(```|~~~)")


def canonical(name: str) -> str | None:
    """The identifier of ``name``'s entry in the API reference, or None when it is not a
    public lfjax object."""
    parts = name.split(".")
    if any(part.startswith("_") for part in parts):
        return None
    for split in range(len(parts), 0, -1):  # the longest importable module prefix
        try:
            obj = importlib.import_module(".".join(parts[:split]))
        except ImportError:
            continue
        owner = obj
        for attr in parts[split:]:
            owner, obj = obj, getattr(obj, attr, None)
            if obj is None:
                return None
        if split == len(parts):
            return obj.__name__  # a module
        module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
        if isinstance(module, str) and isinstance(qualname, str) and module.startswith("lfjax"):
            return f"{module}.{qualname}"
        if hasattr(owner, "__name__") and getattr(owner, "__file__", None):
            return f"{owner.__name__}.{parts[-1]}"  # a module attribute (a constant)
        return None
    return None


def link_names(markdown: str) -> str:
    out, in_fence = [], False
    for line in markdown.split("\n"):
        if FENCE.match(line):
            in_fence = not in_fence
        elif not in_fence:
            def link(match: re.Match) -> str:
                name = match.group("name")
                if "." not in name:  # a bare name: one of the face's calls, or left alone
                    if not callable(getattr(importlib.import_module("lfjax"), name, None)):
                        return match.group(0)
                    name = "lfjax." + name
                target = canonical(name)
                if target is None:
                    return match.group(0)
                shown = html.escape(match.group("name") + (match.group("call") or ""))
                return f'<autoref identifier="{target}" optional><code>{shown}</code></autoref>'
            line = CODE_SPAN.sub(link, line)
        out.append(line)
    return "\n".join(out)


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001
    if page.file.src_uri.startswith("api/"):
        return markdown  # the reference links its own names
    return link_names(markdown)
