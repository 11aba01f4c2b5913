"""MkDocs hook: serve project files that live outside ``docs/`` from their own paths.

The notebooks (``notebooks/*.ipynb``, rendered by mkdocs-jupyter with their committed
outputs) and the benchmarks' results (``benchmarks/RESULTS.md``, its summary table, and
``benchmarks/results/*.md``, one page per topic, with the figures, tables and reports the
scripts write beside themselves in ``benchmarks/{speed,baselines,validation,studies}/``) are
read where they are, so the site cannot drift from them: there is no copy to forget. Each
file keeps its project path as its site path, so the relative links between the results
pages, to the figures, and the guides' links to ``../benchmarks/...`` resolve as they do on
GitHub.
"""

from __future__ import annotations

import re
from pathlib import Path

from mkdocs.plugins import event_priority
from mkdocs.structure.files import File, Files

# (folder, glob patterns): what the site shows from outside docs/.
MOUNTS = {
    "notebooks": ("*.ipynb",),
    "benchmarks": ("RESULTS.md", "results/*.md", "**/*.png", "**/*.csv", "**/*.json",
                   "**/*.toml", "studies/display_effects/REPORT.md", "studies/sweep_1000/*.md"),
}


@event_priority(100)  # before mkdocs-jupyter's on_files, which turns .ipynb into pages
def on_files(files: Files, config) -> Files:
    root = Path(config.config_file_path).parent
    for folder, patterns in MOUNTS.items():
        seen: set[Path] = set()
        for pattern in patterns:
            for path in sorted((root / folder).glob(pattern)):
                if path in seen or not path.is_file():
                    continue
                seen.add(path)
                src_uri = path.relative_to(root).as_posix()
                # src_dir is the project root: the file is read in place, and plugins that rebuild
                # File objects (mkdocs-jupyter) keep finding it.
                files.append(File(src_uri, str(root), config.site_dir, config.use_directory_urls))
    return files


def on_page_markdown(markdown: str, page, config, files) -> str:
    """Make links that work on GitHub work on the site too.

    In the project, ``docs/guides/x.md`` reaches ``benchmarks/`` as ``../../benchmarks/``
    and ``benchmarks/results/x.md`` reaches ``docs/design.md`` as ``../../docs/design.md``.
    On the site, ``docs/`` is the root and the mounted folders sit beside its pages, so each
    such link loses one level (or its ``docs/``)."""
    markdown = _blank_line_before_lists(markdown)
    depth = page.file.src_uri.count("/")
    up = "../" * depth
    if page.file.src_uri.split("/", 1)[0] in MOUNTS:
        return markdown.replace("](" + up + "docs/", "](" + up)
    for folder in MOUNTS:
        markdown = markdown.replace("](" + up + "../" + folder + "/", "](" + up + folder + "/")
    return markdown


LIST_ITEM = re.compile(r"^\s{0,3}(?:[*+-]|\d+[.)])\s+\S")
FENCE = re.compile(r"^\s*(```|~~~)")


def _blank_line_before_lists(markdown: str) -> str:
    """GitHub starts a list right after a paragraph line; Python-Markdown needs a blank line
    first. Insert one (outside code fences) so the files read the same in both places."""
    out: list[str] = []
    in_fence = False
    previous = ""
    for line in markdown.split("\n"):
        if FENCE.match(line):
            in_fence = not in_fence
        elif (not in_fence and LIST_ITEM.match(line) and previous.strip()
              and not LIST_ITEM.match(previous) and not previous.startswith((" ", "\t", "|", "#"))):
            out.append("")
        out.append(line)
        previous = line
    return "\n".join(out)
