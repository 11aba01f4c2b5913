"""Command line: ``lfjax reproduce`` (the paper's study: results, tables, figures, report).

Usage errors print one line and exit with status 2; failures during the run print one line
and exit with status 1, leaving no partial output.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

PROG = "lfjax"
DEFAULT_OUT = "lfjax-results"


class _OneLineParser(argparse.ArgumentParser):
    """ArgumentParser whose errors are a single line (no usage block)."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def compilation_cache_dir() -> Path:
    """Folder of the persistent JAX compilation cache used by the command line.

    ``$LFJAX_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/lfjax/jax`` (default
    ``~/.cache/lfjax/jax``).
    """
    explicit = os.environ.get("LFJAX_CACHE_DIR")
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "lfjax" / "jax"


def enable_compilation_cache(folder: Path | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache in ``folder`` (returns it, or None when
    the folder cannot be created). A second run then skips most compilation."""
    import jax

    folder = compilation_cache_dir() if folder is None else Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    if not os.access(folder, os.W_OK):
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return folder


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if not (0 <= value < 2**32):
        raise argparse.ArgumentTypeError(f"must be in 0 … 4294967295, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = _OneLineParser(
        prog=PROG,
        description="lfjax: wave-optics model of aberrated human eyes viewing a light-field "
                    "display (Miyanishi, Sahin & Gotchev).",
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"lfjax {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_OneLineParser)
    rep = sub.add_parser(
        "reproduce",
        help="reproduce the paper's study: results file, CSV tables, Figs. 3-11, REPORT.md",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Reproduce the simulation study of Miyanishi, Sahin & Gotchev.\n\n"
            "Default (the paper's experiment): 3 mm pupil; display central depth plane (CDP)\n"
            "at 2 D; natural view and 2x2, 3x3, 4x4 viewpoints in the pupil; points rendered\n"
            "at -2 ... +2 D from the CDP in 0.5 D steps (0 ... 4 D absolute); accommodation\n"
            "through focus on a 0 ... 5 D grid in 0.2 D steps (each depth within +-2 D);\n"
            "400-700 nm in 10 nm steps, reference wavelength 550 nm; N seeded virtual eyes\n"
            "(Thibos et al. 2002) plus the average eye; accommodation predicted by the\n"
            "peaks of VSOTF and of the Strehl ratio; radial MTFs and cut-off frequencies\n"
            "(MTF 0.05). The paper's findings are checked as claims in REPORT.md, also\n"
            "under alternative modelling choices (on a reduced set of depths and\n"
            "wavelengths).\n\n"
            "Outputs in DIR: results.nc and examples.nc (netCDF, labelled, with units and\n"
            "model options), accommodation_predictions.csv, accommodation_summary.csv,\n"
            "cutoff_frequencies.csv, claims.csv, alternatives.csv, fig03...fig11 PNGs and\n"
            "REPORT.md. They are written to a temporary folder and moved into place at the\n"
            "end. Units: depths and accommodation in dioptres (D = 1/m), frequencies in\n"
            "cycles per degree (cpd), angles in arcmin, wavelengths in nm.\n\n"
            "JAX compilations are cached in $LFJAX_CACHE_DIR (default ~/.cache/lfjax/jax),\n"
            "so later runs start faster."
        ),
    )
    rep.add_argument("--out", metavar="DIR", default=DEFAULT_OUT,
                     help=f"output folder; must be new or empty unless --force "
                          f"(default: ./{DEFAULT_OUT})")
    rep.add_argument("--eyes", metavar="N", type=_positive_int, default=None,
                     help="number of virtual eyes drawn from the Thibos et al. (2002) "
                          "statistics, >= 1; the average eye is always added "
                          "(default: 10, or 2 with --quick)")
    rep.add_argument("--seed", metavar="S", type=_seed, default=0,
                     help="seed of the random eye draw, integer 0 ... 2^32-1 (default: 0); "
                          "same seed, same eyes")
    rep.add_argument("--quick", action="store_true",
                     help="small version for testing: 2 eyes + average eye, depths CDP-2, "
                          "CDP, CDP+2 D, accommodation in 0.5 D steps, 30 nm wavelength "
                          "steps, no modelling-choice alternatives; its numbers are not the "
                          "paper's")
    rep.add_argument("--no-alternatives", action="store_true",
                     help="skip the reruns under alternative modelling choices (Stiles-"
                          "Crawford form, accommodation spherical aberration, LCA constant)")
    rep.add_argument("--force", action="store_true",
                     help="replace DIR if it is a non-empty folder written by an earlier "
                          "'lfjax reproduce' (other non-empty folders are never replaced)")
    rep.add_argument("--no-progress", action="store_true",
                     help="do not show the progress bar (on stderr)")
    return parser


def _reproduce(args, t_start: float) -> int:
    from .reproduce import OutputError, StudyConfig, check_output_dir, reproduce

    prog = f"{PROG} reproduce"
    try:
        check_output_dir(args.out, args.force)
        if args.quick:
            config = StudyConfig.quick(n_eyes=args.eyes or 2, seed=args.seed)
        else:
            config = StudyConfig(n_eyes=args.eyes or 10, seed=args.seed)
        if args.no_alternatives:
            config = config.replace(alternatives=False)
    except (OutputError, ValueError) as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    enable_compilation_cache()
    try:
        result = reproduce(args.out, config, force=args.force, progress=not args.no_progress)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; nothing written", file=sys.stderr)
        return 130
    except OutputError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # one line, no traceback; nothing half-written
        message = " ".join(str(err).split()) or type(err).__name__
        print(f"{prog}: error: {type(err).__name__}: {message}; nothing written",
              file=sys.stderr)
        if os.environ.get("LFJAX_DEBUG"):
            raise
        return 1
    verdicts = ", ".join(f"{c.id} {c.verdict}" for c in result["claims"])
    print(f"{prog}: claims: {verdicts}")
    print(f"{prog}: wrote {len(result['files'])} files to {result['out']} in "
          f"{time.perf_counter() - t_start:.1f} s")
    return 0


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
    if args.command == "reproduce":
        return _reproduce(args, t_start)
    return 2  # pragma: no cover - argparse rejects unknown commands


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
