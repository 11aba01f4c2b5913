"""MkDocs hook: the notebook pages reference no network.

mkdocs-jupyter's page template loads MathJax from a URL it leaves empty here
(``<script src="">``, with its configuration script) and imports mermaid from a CDN when a
page has a diagram (no notebook of the project has one). Both are dropped from the built
pages: the site's equations are MathML (docs/_hooks/mathml.py) and the pages work offline.
"""

from __future__ import annotations

import re

EMPTY_SOURCE = re.compile(r'<script src="">\s*</script>')
MATHJAX_CONFIG = re.compile(r'<script type="text/x-mathjax-config">.*?</script>', re.S)
# An inline script that fetches code from the network (the mermaid import).
NETWORK_SCRIPT = re.compile(r"<script\b[^>]*>(?:(?!</script>).)*?https?://(?:(?!</script>).)*?</script>",
                            re.S)


def on_post_page(output: str, page, config) -> str:  # noqa: ARG001
    if not page.file.src_uri.endswith(".ipynb"):
        return output
    for pattern in (EMPTY_SOURCE, MATHJAX_CONFIG, NETWORK_SCRIPT):
        output = pattern.sub("", output)
    return output
