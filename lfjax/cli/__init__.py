"""The ``lfjax`` command line (:func:`main`): one module per subcommand, each parsing its
flags, calling the library and printing what it did.

``lfjax reproduce`` (:mod:`~lfjax.cli.reproduce`: the paper's study: results, tables,
figures, report), ``lfjax optimise`` (:mod:`~lfjax.cli.optimise`: fit a subaperture layout
to virtual eyes, report it on held-out eyes), ``lfjax sweep`` (:mod:`~lfjax.cli.sweep`: a
population sweep into a resumable Zarr store), ``lfjax sweep-report``
(:mod:`~lfjax.cli.sweep_report`: its distributions, percentiles and what ten eyes cannot
tell) and ``lfjax design`` (:mod:`~lfjax.cli.design`: a buildable lenslet display fitted to
a panel and eyes) and ``lfjax retina`` (:mod:`~lfjax.cli.retina`: the retinal image of a
scene with depth through a display or in natural viewing). What they share: the flags
declared once, their argument types and the parameter↔flag table (:mod:`~lfjax.cli.flags`),
the error and exit conventions and the one guard of every subcommand's work
(:mod:`~lfjax.cli.common`), and the compilation cache (:mod:`~lfjax.cli.cache`).

Usage errors print one line and exit with status 2; failures during the run print one line
and exit with status 1, leaving no partial output. Ctrl-C exits with status 130 within about
2 s (:func:`~lfjax.cli.common.exit_promptly_on_interrupt`), leaving no partial output either.
"""

from __future__ import annotations

import argparse
import sys
import time

from lfjax._version import __version__
from lfjax.cli import common, design, optimise, reproduce, retina, sweep, sweep_report
from lfjax.cli.cache import enable_compilation_cache

SUBCOMMANDS = {module.COMMAND: module for module in (reproduce, optimise, sweep, sweep_report, design,
                                                   retina)}
"""Each subcommand's module: ``add_parser(sub)`` declares its flags, ``run(args)`` runs it."""

GUIDES = {"reproduce": "paper-study.md", "optimise": "layout-optimisation.md",
          "sweep": "population-sweeps.md", "sweep-report": "population-sweeps.md",
          "design": "display-design.md", "retina": "scene-blur.md"}
"""Each subcommand's guide page (``docs/guides/``), named at the end of its ``--help``."""


def build_parser() -> argparse.ArgumentParser:
    parser = common.OneLineParser(
        prog=common.PROG,
        description="lfjax: wave-optics model of aberrated human eyes viewing a light-field "
                    "display (Miyanishi, Sahin & Gotchev).",
    )
    parser.add_argument("--version", action="version", version=f"lfjax {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND",
                                parser_class=common.OneLineParser)
    for name, module in SUBCOMMANDS.items():
        module.add_parser(sub)
        sub.choices[name].epilog = (f"Guide: docs/guides/{GUIDES[name]} (also on the "
                                    "documentation site).")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``lfjax`` console script; returns the exit status."""
    t_start = time.perf_counter()
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help/--version (0) or a usage error (2)
        return int(exc.code or 0)
    if args.command is None:
        parser.print_help()
        return 2
    args.argv = list(sys.argv[1:] if argv is None else argv)
    args.t_start = t_start
    real = argv is None  # the command itself, not a call from Python (a test)
    if real:
        common.exit_promptly_on_interrupt(f"{common.PROG} {args.command}")
    try:
        status = SUBCOMMANDS[args.command].run(args)
    except KeyboardInterrupt:  # a subcommand without its own handling of Ctrl-C
        status = common.interrupted(f"{common.PROG} {args.command}")
    if real and status == 130:
        common.exit_now(status)  # not through interpreter shutdown under running XLA threads
    return status


__all__ = ["main", "build_parser", "enable_compilation_cache", "SUBCOMMANDS", "GUIDES"]
