"""MkDocs hook: the command-line reference page (``cli.md``), generated from the parsers.

``lfjax.cli.build_parser()`` is the parser the ``lfjax`` console script runs; this hook walks
it at build time and writes one section per subcommand — its description, usage and a table
of every argument with its default — so the page cannot drift from the code: a new flag
appears on the next build, a removed one disappears.
"""

from __future__ import annotations

import argparse
import html
import os

from mkdocs.structure.files import File, Files

SRC_URI = "cli.md"


def _cell(text: str) -> str:
    return html.escape(" ".join(str(text).split())).replace("|", "&#124;")


def _default(action: argparse.Action) -> str:
    if action.default in (None, argparse.SUPPRESS) or isinstance(action, (
            argparse._StoreTrueAction, argparse._StoreFalseAction, argparse._HelpAction,
            argparse._VersionAction)):
        return ""
    value = action.default
    if isinstance(value, (list, tuple)):
        value = " ".join(map(str, value))
    return f"`{value}`"


def _arguments_table(parser: argparse.ArgumentParser) -> list[str]:
    rows = ["| argument | default | meaning |", "| --- | --- | --- |"]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            continue
        if action.option_strings:
            name = ", ".join(action.option_strings)
            if action.nargs != 0:
                metavar = action.metavar or (action.dest.upper())
                if isinstance(metavar, tuple):
                    metavar = " ".join(metavar)
                name += f" {metavar}"
        else:
            name = action.metavar or action.dest
        if action.choices is not None and not isinstance(action.choices, dict):
            choices = ", ".join(f"`{c}`" for c in action.choices)
            helptext = f"{action.help or ''} (one of {choices})"
        else:
            helptext = action.help or ""
        if "%(default)" in helptext:
            helptext = helptext % {"default": action.default}
        rows.append(f"| `{_cell(name)}` | {_default(action)} | {_cell(helptext)} |")
    return rows


def cli_reference() -> str:
    """The page's Markdown."""
    from lfjax.cli import SUBCOMMANDS, build_parser

    os.environ.setdefault("COLUMNS", "100")  # argparse wraps usage lines at the terminal width
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = [
        "# Command-line reference",
        "",
        "Generated from the parsers themselves (`lfjax.cli.build_parser`) each time the site is "
        "built, so it lists exactly the flags the installed `lfjax` accepts; `lfjax COMMAND "
        "--help` prints the same. The guides explain when to use each command: "
        "[the paper's study](guides/paper-study.md), "
        "[layout optimisation](guides/layout-optimisation.md), "
        "[population sweeps](guides/population-sweeps.md), "
        "[display design](guides/display-design.md).",
        "",
        "```text",
        parser.format_usage().strip(),
        "```",
        "",
        *_arguments_table(parser),
        "",
    ]
    for name in SUBCOMMANDS:
        command = sub.choices[name]
        out += [f"## `lfjax {name}`", "", "```text", command.format_usage().strip(), "```", ""]
        if command.description:
            out += ["```text", command.description.strip(), "```", ""]
        out += _arguments_table(command) + [""]
        if command.epilog:
            out += ["```text", command.epilog.strip(), "```", ""]
    return "\n".join(out)


def on_files(files: Files, config) -> Files:
    files.append(File.generated(config, SRC_URI, content=cli_reference()))
    return files
