"""MkDocs hook: render equations to MathML at build time, so that they need no network.

pymdownx.arithmatex (``generic: true``) wraps ``$$…$$`` blocks in ``<div class="arithmatex">``
with ``\\[…\\]`` and ``$…$`` in ``<span class="arithmatex">`` with ``\\(…\\)``, for a script to
typeset in the browser. Here each becomes MathML (latex2mathml), which browsers render
natively: no script, no CDN, the page works offline. The docstrings' ``.. math::`` directives
reach arithmatex through docs/_hooks/sphinx_roles.py, so one path serves the whole site. A
formula latex2mathml cannot read fails the build, naming the page.
"""

from __future__ import annotations

import html
import re

from latex2mathml.converter import convert

ARITHMATEX = re.compile(
    r'<(?P<tag>div|span) class="arithmatex">\s*'
    r"(?:\\\[(?P<block>.*?)\\\]|\\\((?P<inline>.*?)\\\))\s*</(?P=tag)>",
    re.S,
)


def to_mathml(page_html: str, where: str = "?") -> str:
    def render(match: re.Match) -> str:
        block = match.group("block") is not None
        tex = html.unescape(match.group("block") if block else match.group("inline")).strip()
        try:
            mathml = convert(tex, display="block" if block else "inline")
        except Exception as error:  # latex2mathml raises its own types, and IndexError
            raise ValueError(f"{where}: cannot render the formula {tex!r}: {error}") from error
        return (f'<div class="math">{mathml}</div>' if block
                else f'<span class="math">{mathml}</span>')

    return ARITHMATEX.sub(render, page_html)


def on_page_content(html_text: str, page, config, files) -> str:  # noqa: ARG001
    return to_mathml(html_text, page.file.src_uri)
