"""Command line: ``lfjax reproduce`` (the paper's study: results, tables, figures, report)
``lfjax optimise`` (fit a subaperture layout to virtual eyes, report it on held-out eyes),
``lfjax sweep`` (a population sweep into a resumable Zarr store), ``lfjax sweep-report``
(its distributions, percentiles and what ten eyes cannot tell) and ``lfjax design`` (a
buildable lenslet display fitted to a panel and eyes, :mod:`lfjax.design.fit`).

Usage errors print one line and exit with status 2; failures during the run print one line
and exit with status 1, leaving no partial output.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import signal
import sys
import time
from pathlib import Path

import jax
import numpy as np

from lfjax import layout_opt as lo
from lfjax.model import layout_plots
from lfjax.planner.cache import enable_plan_cache
from lfjax._version import __version__
from lfjax.design.fit import DesignConstraints, fit_design, save_design
from lfjax.display.lenslets import DisplayOptics, display_optics_at
from lfjax.display.spectra import DISPLAY_NAMES, display_spectrum
from lfjax.model.eyes import sample_eyes
from lfjax.model.layout_files import jsonable
from lfjax.layout_opt import (
    DEFAULT_OBJECTIVE,
    OBJECTIVES,
    Constraints,
    Objective,
    default_max_diameter_mm,
    depth_grid,
    feasible_start,
    free_params,
    initial_lattice,
    lattice_sites,
    to_box,
)
from lfjax.display.panel import PRESETS
from lfjax.reproduce import OutputError, StudyConfig, check_output_dir, check_population, reproduce
from lfjax.reproduce.config import ACCURACY_PLANS
from lfjax.base.sampling import Sampling
from lfjax.sweep import (
    StoreMismatchError,
    SweepConfigError,
    SweepTooLargeError,
    load_config,
    plan_sweep,
    run_sweep,
)
from lfjax.sweep.config import config_template
from lfjax.sweep.report import default_out_dir, sweep_report
from lfjax.sweep.store import StoreLockedError, is_disk_full, is_store, verify_store

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


PLAN_FOLDER = "lfjax-plans"
"""Sub-folder of the compilation cache where the planner's plans are kept
(:mod:`lfjax.planner.cache`)."""


def enable_compilation_cache(folder: Path | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache in ``folder`` (returns it, or None when
    the folder cannot be created), and keep the planner's plans in its ``lfjax-plans``
    sub-folder. A second run then skips most compilation and all planning."""
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
    # the planner's sampling plans beside the programs: a warm run re-plans nothing
    enable_plan_cache(folder / PLAN_FOLDER)
    return folder


def _whole_number(text: str, lowest: int, below: int | None = None, allowed: str = "") -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < lowest or (below is not None and value >= below):
        raise argparse.ArgumentTypeError(f"must be {allowed or f'>= {lowest}'}, got {value}")
    return value


def _positive_int(text: str) -> int:
    return _whole_number(text, 1)


def _seed(text: str) -> int:
    return _whole_number(text, 0, 2**32, "in 0 … 4294967295")


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def _count(text: str) -> int:
    """Whole number >= 0."""
    return _whole_number(text, 0)


def _objective(text: str):
    """A name, or comma-separated name=weight pairs."""
    if "=" not in text:
        if text != DEFAULT_OBJECTIVE and text not in OBJECTIVES:
            raise argparse.ArgumentTypeError(
                f"choose from {DEFAULT_OBJECTIVE}, {', '.join(OBJECTIVES)} or weights like "
                f"image_at_peak=1,resolution=0.01; got {text!r}")
        return Objective.parse(text)
    weights = {}
    for part in text.split(","):
        name, _, weight = part.partition("=")
        try:
            weights[name.strip()] = _finite_float(weight)
        except argparse.ArgumentTypeError as err:
            raise argparse.ArgumentTypeError(f"weight of {name.strip()!r}: {err}") from None
    try:
        return Objective.parse(weights)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def build_parser() -> argparse.ArgumentParser:
    parser = _OneLineParser(
        prog=PROG,
        description="lfjax: wave-optics model of aberrated human eyes viewing a light-field "
                    "display (Miyanishi, Sahin & Gotchev).",
    )

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
            "400-700 nm, each layout's wavelength step planned so that no peak moves by\n"
            "more than 0.01 D and no cut-off by more than 0.25 cpd (--accuracy),\n"
            "reference wavelength 550 nm; N seeded virtual eyes\n"
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
    rep.add_argument("--accuracy", choices=ACCURACY_PLANS, default=None,
                     help="how the spectrum is sampled: 'claims' (default) plans each "
                          "layout's wavelength step for peaks to 0.01 D and cut-offs to "
                          "0.25 cpd; 'vsotf' uses 10 nm steps (lfjax 0.3's plan, made for a "
                          "VSOTF error of 1e-3). --quick: 30 nm steps")
    rep.add_argument("--no-alternatives", action="store_true",
                     help="skip the reruns under alternative modelling choices (Stiles-"
                          "Crawford form, accommodation spherical aberration, LCA constant)")
    rep.add_argument("--force", action="store_true",
                     help="replace DIR if it is a non-empty folder written by an earlier "
                          "'lfjax reproduce' (other non-empty folders are never replaced)")
    rep.add_argument("--no-progress", action="store_true",
                     help="do not show the progress bar (on stderr)")
    rep.add_argument("--population", metavar="STORE", default=None,
                     help="a population sweep store (lfjax sweep): REPORT.md adds 'What ten "
                          "eyes cannot tell', how often random samples of N eyes from it "
                          "reproduce each claim, and ten_eyes.csv")
    rep.add_argument("--display-effects", action="store_true",
                     help="add the section 'Beyond the ideal display': lenslet diffraction, "
                          "pixels and an OLED-like spectrum switched on one by one for 2x2, "
                          "3x3 and 4x4 (on the average eye and the first --display-eyes "
                          "eyes), and the 2x2 lenslet-size sweep; display_effects.csv, "
                          "display_lenslet_sweep.csv and two figures")
    rep.add_argument("--display-eyes", metavar="N", type=_count, default=2,
                     help="virtual eyes (besides the average eye) in the display-effects "
                          "section, 0 ... --eyes (default: 2; each costs minutes)")
    _add_optimise_parser(sub)
    _add_sweep_parser(sub)
    _add_sweep_report_parser(sub)
    _add_design_parser(sub)
    return parser


def _add_sweep_report_parser(sub) -> None:
    rp = sub.add_parser(
        "sweep-report",
        help="pictures, percentiles and a summary of a sweep store; what ten eyes cannot tell",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Report on a population sweep store (lfjax sweep), counting only the eyes of\n"
            "complete chunks; the Thibos average eye is left out of every population\n"
            "statistic. Outputs in DIR: accommodation_error.png (VSOTF accommodation error,\n"
            "D, per layout against rendered depth - CDP: median and 25-75 %, 5-95 % bands),\n"
            "cutoff_frequency.png (cpd, the same way), layouts.png (subapertures in each\n"
            "pupil), percentiles.csv (5/25/50/75/95 %, mean and n per pupil x layout x depth\n"
            "of grid and continuous accommodation error, cut-off frequency, VSOTF peak),\n"
            "summary.md, and - with more than 10 virtual eyes, the average eye and natural\n"
            "view plus two of 2x2, 3x3, 4x4 - ten_eyes.md / ten_eyes.csv: how often a random\n"
            "sample of 10 eyes reproduces each of the paper's claims (95 % Wilson interval)."
        ),
    )
    rp.add_argument("store", metavar="STORE", help="sweep store (a Zarr folder)")
    rp.add_argument("--out", metavar="DIR", default=None,
                    help="output folder (default: STORE's name with -report, beside it); "
                         "files of the same names in it are replaced")
    rp.add_argument("--draws", metavar="N", type=_positive_int, default=1000,
                    help="samples of 10 eyes drawn for the ten-eye table, >= 1 (default 1000)")
    rp.add_argument("--seed", metavar="S", type=_seed, default=0,
                    help="seed of the samples (default 0)")
    rp.add_argument("--no-progress", action="store_true",
                    help="do not show the progress bar of the draws (on stderr)")


def _add_sweep_parser(sub) -> None:
    sw = sub.add_parser(
        "sweep",
        help="population sweep from a TOML config into a resumable Zarr store",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Compute through-focus VSOTF and Strehl ratio, grid and continuous predicted\n"
            "accommodation and MTF cut-off frequencies for a population of virtual eyes\n"
            "(Thibos et al. 2002) x pupils x layouts x rendered depths, as described by\n"
            "CONFIG (TOML; see the README's 'Population sweeps' for every key and its unit).\n"
            "The whole config is validated first and every problem listed.\n\n"
            "Results go to STORE, a Zarr store of one xarray Dataset (open it with\n"
            "lfjax.sweep.open_store or xarray.open_zarr), written one chunk of eyes at a time;\n"
            "an interrupted sweep continues with --resume and recomputes no finished chunk.\n"
            "The plan (sizes, estimated time, memory, store size) is printed first, and a\n"
            "sweep that cannot fit this machine is refused before anything is written.\n"
            "One writer per STORE: STORE.lock names it (host, PID, start).\n"
            "The eye axis is sharded over all local JAX devices (run.chunk_size must be a\n"
            "multiple of their number). Several processes or hosts: start one process per\n"
            "host with --distributed (jax.distributed.initialize; the coordinator is found\n"
            "from the cluster environment, or give --coordinator, --num-processes and\n"
            "--process-id); each computes its share of the chunks into the shared STORE."
        ),
    )
    sw.add_argument("config", metavar="CONFIG.toml",
                    help="sweep configuration (TOML); with --template the file to write; with "
                         "--verify the STORE to check")
    sw.add_argument("--dry-run", action="store_true",
                    help="print the plan (eyes, layouts, depths, states, wavelengths, sampling, "
                         "estimated time, memory and store size), check it fits, write nothing")
    sw.add_argument("--verify", action="store_true",
                    help="check STORE (given in place of CONFIG.toml): read every finished chunk "
                         "back and compare it with its checksum; exit 1 if any is corrupt "
                         "(--resume recomputes those)")
    sw.add_argument("--template", action="store_true",
                    help="write CONFIG.toml: a commented config with every key and its default")
    sw.add_argument("--out", metavar="STORE", default=None,
                    help="Zarr store to write (default: CONFIG's name with .zarr, in the "
                         "current folder); must not exist unless --resume")
    sw.add_argument("--resume", action="store_true",
                    help="complete an existing STORE made by the same config (finished chunks "
                         "are skipped, those whose data fail their checksum recomputed; a store "
                         "of another config is refused, listing the differences)")
    sw.add_argument("--max-chunks", metavar="N", type=_positive_int, default=None,
                    help="stop after computing N chunks (continue later with --resume)")
    sw.add_argument("--no-progress", action="store_true",
                    help="do not show the progress bar (on stderr)")
    sw.add_argument("--distributed", action="store_true",
                    help="call jax.distributed.initialize first (one process per host)")
    sw.add_argument("--coordinator", metavar="HOST:PORT", default=None,
                    help="with --distributed: address of process 0's coordinator service")
    sw.add_argument("--num-processes", metavar="N", type=_positive_int, default=None,
                    help="with --distributed: total number of processes")
    sw.add_argument("--process-id", metavar="I", type=_count, default=None,
                    help="with --distributed: this process's index, 0 ... N-1")


def _add_optimise_parser(sub) -> None:
    opt = sub.add_parser(
        "optimise",
        help="fit a subaperture layout to virtual eyes; layout.json and figures",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Fit the subaperture layout of a light-field display to a training population of\n"
            "virtual eyes (Thibos et al. 2002; seed S) and report it on a held-out population\n"
            "(seed S+1). The default objective, accommodation_aware, maximises the image at\n"
            "each eye's own predicted accommodation (mean VSOTF at the global peak of its\n"
            "through-focus curve, searched between the rendered depth and the CDP) subject to\n"
            "the display's accommodation error (RMSE of each eye's error less its own error on\n"
            "the CDP) within --accommodation-tolerance (0.25 D), by a quadratic\n"
            "penalty: a layout whose views collapse into one pinhole lets every eye focus on\n"
            "the CDP and scores far worse than the paper's tangent grid. Named alternatives\n"
            "(unconstrained unless --accommodation-tolerance is given): image_at_peak;\n"
            "depth_of_field = mean VSOTF at the correct accommodation (maximised);\n"
            "accommodation = mean squared error (D^2) of the predicted accommodation\n"
            "(minimised); resolution = smooth MTF cut-off at MTF 0.05, cpd (maximised); or\n"
            "weights, e.g. image_at_peak=1,resolution=0.01. VSOTF is scored against the\n"
            "natural open pupil. The fit runs on a cheap setting (550 nm, 0.25 D peak grid,\n"
            "grid-parabola peaks); the held-out report on the full one (31 wavelengths\n"
            "400-700 nm, planned sampling, refined peaks), and says how long each took.\n"
            "The start is the tangent lattice (the paper's n x n grids for square), moved\n"
            "into the constraints (and 2 % inside them for --solver bfgs).\n\n"
            "Outputs in DIR: layout.json (centres_mm, diameters_mm, pupil_diameter_mm, name,\n"
            "objective with before/after values, provenance), layouts.png (before/after),\n"
            "through_focus.png (population-mean VSOTF before/after), history.png (loss per\n"
            "step); with --front N also front.png and front.json (the trade-off).\n"
            "Units: mm in the pupil, dioptres (D), cycles per degree (cpd), nm."
        ),
    )
    opt.add_argument("--objective", type=_objective, default=None, metavar="OBJ",
                     help="accommodation_aware (default), image_at_peak, depth_of_field, "
                          "accommodation, resolution, or weights name=w,name=w "
                          "(loss = -w*VSOTF + w*D^2 - w*cpd)")
    opt.add_argument("--accommodation-tolerance", metavar="D", type=_finite_float, default=None,
                     help="constrain the training eyes' accommodation RMSE to D dioptres "
                          "(default 0.25 for accommodation_aware, none for the others)")
    opt.add_argument("--front", metavar="N", type=_positive_int, default=None,
                     help="also fit N layouts along the trade-off (tolerances 0.1 ... 1 D), "
                          "score them and the tangent 2x2-4x4 grids and natural viewing on the "
                          "held-out eyes, and draw front.png")
    opt.add_argument("--report-accuracy", choices=("full", "fit"), default="full",
                     help="setting of the held-out report: full (31 wavelengths, refined peaks; "
                          "default) or fit (the training setting, much faster)")
    opt.add_argument("--views", metavar="N", type=_positive_int, default=4,
                     help="number of views, >= 1 (square lattice: n*n, e.g. 4, 9, 16; hex: any, "
                          "7 and 19 fill rings; default 4)")
    opt.add_argument("--parametrisation", choices=("lattice", "free"), default="lattice",
                     help="lattice: pitch, diameter, rotation; free: every centre and diameter "
                          "(default lattice)")
    opt.add_argument("--lattice", choices=("square", "hex"), default="square",
                     help="lattice of the start (and of the fit with --parametrisation lattice)")
    opt.add_argument("--depths", metavar=("LOW", "HIGH"), nargs=2, type=_finite_float,
                     default=(0.0, 4.0),
                     help="rendered depth range in D, 0 <= LOW < HIGH (default 0 4)")
    opt.add_argument("--n-depths", metavar="K", type=_positive_int, default=5,
                     help="rendered depths evenly spanning the range, >= 2 (default 5)")
    opt.add_argument("--cdp", metavar="D", type=_finite_float, default=2.0,
                     help="central depth plane of the display, D >= 0 (default 2)")
    opt.add_argument("--pupil", metavar="MM", type=_finite_float, default=3.0,
                     help="pupil diameter, mm, in (0, 3] for the 3 mm eye statistics (default 3)")
    opt.add_argument("--max-diameter", metavar="MM", type=_finite_float, default=None,
                     help="largest subaperture diameter, mm (default 1.2 x the tangent lattice's, "
                          "at most the pupil: it sizes every FFT window, so smaller is faster)")
    opt.add_argument("--min-diameter", metavar="MM", type=_finite_float, default=0.5,
                     help="smallest subaperture diameter, mm (default 0.5)")
    opt.add_argument("--containment", choices=("centre", "contained"), default="centre",
                     help="centre: |centre| <= pupil radius, the pupil crops the rest "
                          "(default); contained: |centre| + d/2 <= pupil radius")
    opt.add_argument("--non-overlap", action="store_true", help="subapertures must not overlap")
    opt.add_argument("--train-eyes", metavar="N", type=_positive_int, default=10,
                     help="training eyes, >= 1 (default 10)")
    opt.add_argument("--test-eyes", metavar="N", type=_count, default=50,
                     help="held-out eyes, >= 0 (default 50; 0: none). Scored at the full accuracy, "
                          "each costs about 9 s per layout (start and fit) on 2 busy CPU cores")
    opt.add_argument("--seed", metavar="S", type=_seed, default=0,
                     help="training eyes from seed S, held-out eyes from S+1 (default 0)")
    opt.add_argument("--wavelengths", metavar="NM", nargs="+", type=_finite_float,
                     default=[550.0],
                     help="the fit's wavelengths, nm, increasing, 400-700 (default 550, the LCA "
                          "reference; the held-out report uses 31 wavelengths)")
    opt.add_argument("--display-distance", metavar="MM", type=_finite_float, default=None,
                     help="optimise for a lenslet-array display at MM from the eye: each view "
                          "is its lenslet's Fresnel pattern (default: the paper's ideal display)")
    opt.add_argument("--pixel-arcmin", metavar="A", type=_finite_float, default=0.0,
                     help="emitters of this angular width, arcmin (default 0: points)")
    opt.add_argument("--spectrum", metavar="NAME", default=None,
                     help="a display's white (crt, lcd, oled, laser) instead of the V(lambda)-"
                          "weighted --wavelengths")
    opt.add_argument("--freq-step", metavar="CPD", type=_finite_float, default=None,
                     help="frequency step, cpd (default: the planner's aliasing guard for every "
                          "feasible layout)")
    opt.add_argument("--solver", choices=("lbfgsb", "bfgs"), default="lbfgsb",
                     help="lbfgsb: jaxopt L-BFGS-B in box coordinates (default); bfgs: "
                          "optimistix BFGS in unconstrained coordinates, which reach a bound "
                          "only asymptotically (prefer lbfgsb when the start or the optimum "
                          "sits on one, e.g. tangent discs with --non-overlap)")
    opt.add_argument("--steps", metavar="N", type=_count, default=30,
                     help="solver steps, >= 0 (default 30)")
    opt.add_argument("--out", metavar="DIR", default="lfjax-layout",
                     help="output folder; must be new or empty unless --force "
                          "(default: ./lfjax-layout)")
    opt.add_argument("--force", action="store_true",
                     help="write into a non-empty DIR (files of the same names are replaced)")
    opt.add_argument("--no-progress", action="store_true",
                     help="do not show the progress bar (on stderr)")


def _reproduce(args, t_start: float) -> int:
    prog = f"{PROG} reproduce"
    try:
        check_output_dir(args.out, args.force)
        if args.quick:
            config = StudyConfig.quick(n_eyes=args.eyes or 2, seed=args.seed)
        else:
            config = StudyConfig(n_eyes=args.eyes or 10, seed=args.seed)
        if args.no_alternatives:
            config = config.replace(alternatives=False)
        if args.accuracy is not None:
            config = config.replace(accuracy=args.accuracy)
        if args.population is not None:
            check_population(args.population, config)
        if args.display_effects and args.display_eyes > config.n_eyes:
            raise ValueError(f"--display-eyes must be in 0 ... {config.n_eyes} (the study's eyes), "
                             f"got {args.display_eyes}")
    except (OutputError, ValueError) as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    enable_compilation_cache()
    try:
        result = reproduce(args.out, config, force=args.force, progress=not args.no_progress,
                           population_store=args.population,
                           display_effects_eyes=args.display_eyes if args.display_effects else None)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; nothing written", file=sys.stderr)
        return 130
    except OutputError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # one line, no traceback; nothing half-written
        return _unexpected_error(prog, err, "; nothing written")
    verdicts = ", ".join(f"{c.id} {c.verdict}" for c in result["claims"])
    print(f"{prog}: claims: {verdicts}")
    print(f"{prog}: wrote {len(result['files'])} files to {result['out']} in "
          f"{time.perf_counter() - t_start:.1f} s")
    return 0


def _optimise_setup(args):
    """Everything validated before any computation: (objective, constraints, depths, out)."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not args.force:
        raise ValueError(f"--out {out} is not empty (use --force to write into it)")
    if not (0.0 < args.pupil <= 3.0):
        raise ValueError(f"--pupil must be in (0, 3] mm (the eyes are measured on 3 mm), got {args.pupil:g}")
    if args.depths[0] < 0 or args.depths[1] < 0:
        raise ValueError(f"--depths must be >= 0 D (0 D is optical infinity), got {args.depths[0]:g} "
                         f"{args.depths[1]:g}")
    if not args.depths[1] > args.depths[0]:
        raise ValueError(f"--depths must satisfy LOW < HIGH, got {args.depths[0]:g} {args.depths[1]:g} "
                         f"({'empty' if args.depths[1] == args.depths[0] else 'inverted'} range)")
    if args.n_depths < 2:
        raise ValueError(f"--n-depths must be >= 2 for a depth range, got {args.n_depths}")
    if args.cdp < 0:
        raise ValueError(f"--cdp must be >= 0 D, got {args.cdp:g}")
    if args.freq_step is not None and not args.freq_step > 0:
        raise ValueError(f"--freq-step must be > 0 cpd, got {args.freq_step:g}")
    wl = args.wavelengths
    if any(w < 400 or w > 700 for w in wl) or any(b <= a for a, b in zip(wl, wl[1:])):
        raise ValueError(f"--wavelengths must increase within 400-700 nm, got {wl}")
    if args.accommodation_tolerance is not None and not 0 < args.accommodation_tolerance <= 2:
        raise ValueError(f"--accommodation-tolerance must be in (0, 2] D, got {args.accommodation_tolerance:g}")
    objective = Objective.parse(args.objective)
    if args.accommodation_tolerance is not None:
        objective = Objective.parse(objective, args.accommodation_tolerance)
    if args.front is not None and args.front < 2:
        raise ValueError(f"--front must be >= 2 points, got {args.front}")
    if args.front is not None and args.test_eyes == 0:
        raise ValueError("--front needs held-out eyes (--test-eyes >= 1)")
    try:
        lattice_sites(args.lattice, args.views)
    except ValueError as err:
        raise ValueError(f"--views: {err}") from None
    max_diameter = args.max_diameter
    if max_diameter is None and 0 < args.pupil:
        max_diameter = max(default_max_diameter_mm(args.lattice, args.views, args.pupil),
                           min(args.min_diameter, args.pupil))
    try:
        constraints = Constraints(args.pupil, max_diameter, args.min_diameter,
                                  args.containment, args.non_overlap)
    except ValueError as err:
        msg = str(err).replace("max_diameter_mm", "--max-diameter").replace(
            "min_diameter_mm", "--min-diameter")
        raise ValueError(msg) from None
    depths = depth_grid(args.depths[0], args.depths[1], args.n_depths)
    if not args.pixel_arcmin >= 0:
        raise ValueError(f"--pixel-arcmin must be >= 0 arcmin, got {args.pixel_arcmin:g}")
    if args.display_distance is not None:
        try:
            display_optics_at(args.display_distance, args.cdp)
        except ValueError as err:
            raise ValueError(f"--display-distance: {err}") from None
    if args.spectrum is not None:
        if args.spectrum not in DISPLAY_NAMES:
            raise ValueError(f"--spectrum must be one of {', '.join(DISPLAY_NAMES)}, got {args.spectrum!r}")
    return objective, constraints, depths, out


def _optimise(args, t_start: float) -> int:
    prog = f"{PROG} optimise"
    try:
        objective, constraints, depths, out = _optimise_setup(args)

        # BFGS moves in sigmoid coordinates, which cannot leave a bound: start 2 % inside
        margin = 0.02 if args.solver == "bfgs" else 0.0
        start = initial_lattice(args.lattice, args.views, constraints, margin)
        if args.parametrisation == "free":
            start = feasible_start(free_params(start.centres_mm, start.diameters_mm), constraints,
                                   margin)
        to_box(start, constraints)  # raises if no feasible start exists
    except ValueError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    enable_compilation_cache()
    try:
        result = run_optimise(args, objective, constraints, depths, out, start)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except Exception as err:  # one line, no traceback
        return _unexpected_error(prog, err)
    print(result["summary"])
    print(f"{prog}: wrote {len(result['files'])} files to {out} in "
          f"{time.perf_counter() - t_start:.1f} s")
    return 0


def run_optimise(args, objective, constraints, depths, out: Path, start) -> dict:
    """The optimise command's computation and files (inputs validated by the caller)."""

    train = sample_eyes(args.seed, args.train_eyes)
    test = sample_eyes(args.seed + 1, args.test_eyes) if args.test_eyes > 0 else None
    planning = train if test is None else type(train)(
        np.concatenate([np.asarray(train.zernike_um), np.asarray(test.zernike_um)]),
        train.measured_pupil_mm)
    sampling = None if args.freq_step is None else Sampling(args.freq_step)
    display = spectrum = None
    if args.display_distance is not None or args.pixel_arcmin > 0:
        display = (display_optics_at(args.display_distance, args.cdp, args.pixel_arcmin)
                   if args.display_distance is not None
                   else DisplayOptics(pixel_width_arcmin=args.pixel_arcmin))
    if args.spectrum is not None:
        spectrum = display_spectrum(args.spectrum, "white", lo.ModelOptions(vsotf_reference="open_pupil"))
    problem = lo.make_problem(train, depths, constraints, objective, cdp_D=args.cdp,
                              wavelengths_nm=args.wavelengths, sampling=sampling,
                              planning_eyes=planning, spectrum=spectrum, display=display)
    fit = lo.optimise_layout(start, problem, method=args.solver, max_steps=args.steps,
                             test_eyes=test, progress=not args.no_progress,
                             name=f"optimised-{args.parametrisation}-{args.views}",
                             report_problem=args.report_accuracy)
    shown = test if test is not None else train
    shown = shown[: min(shown.n_eyes, 20)]
    curves = {"before": lo.through_focus_curves(fit.initial_params, problem, eyes=shown),
              "after": lo.through_focus_curves(fit.params, problem, eyes=shown)}
    out.mkdir(parents=True, exist_ok=True)
    files = layout_plots.save_fit_figures(fit, curves, out)

    def brief(ev):
        return None if ev is None else {k: {m: v for m, v in ev[k].items() if m != "values"}
                                        for k in ("before", "after")}

    record_objective = dict(fit.objective.as_dict(), name=fit.objective.name,
                            train=brief(fit.train), test=brief(fit.test), warning=fit.warning)
    provenance = {
        "command": "lfjax " + " ".join(getattr(args, "argv", None) or ["optimise", "..."]),
        "seed_train": args.seed, "n_train_eyes": args.train_eyes,
        "seed_test": args.seed + 1 if test is not None else None, "n_test_eyes": args.test_eyes,
        "depths_D": depths.tolist(), "cdp_D": args.cdp,
        "wavelengths_nm": [float(w) for w in problem.spectrum.wavelengths_nm],
        "report_accuracy": args.report_accuracy,
        "spectrum": args.spectrum or "V(lambda) white",
        "display_distance_mm": args.display_distance, "pixel_arcmin": args.pixel_arcmin,
        "freq_step_cpd": problem.config.freq_step_cpd, "solver": fit.method,
        "steps": fit.n_steps, "converged": fit.converged, "time_s": round(fit.time_s, 2),
        "evaluation_s": round(fit.evaluation_s, 2),
        "constraints": constraints.as_dict(), "model_options": problem.options.as_dict(),
        "history": fit.history.tolist(),
    }
    files.append(lo.save_layout_json(out / "layout.json", fit.layout, constraints.pupil_diameter_mm,
                                     objective=record_objective, provenance=provenance,
                                     parameters=fit.params))
    summary = fit.summary()
    if args.front is not None:
        t_front = time.perf_counter()
        tolerances = np.round(np.geomspace(0.1, 1.0, args.front), 4)
        front = lo.trade_off_front(start, problem, tolerances, test_eyes=test, method=args.solver,
                                   max_steps=args.steps, progress=not args.no_progress,
                                   report_problem=args.report_accuracy)
        fig = layout_plots.fig_front(front, constraints.pupil_diameter_mm)
        fig.savefig(out / "front.png", dpi=110)
        rows = front.table()
        (out / "front.json").write_text(json.dumps(jsonable(
            {"tolerances_D": tolerances, "rows": rows, "time_s": time.perf_counter() - t_front}),
            indent=2) + "\n")
        files += [out / "front.png", out / "front.json"]
        lines = ["trade-off front (held-out): image at the predicted accommodation (VSOTF); "
                 "accommodation RMSE, the display's share and in all (D)"]
        lines += [f"  {r['name']}: {r['image_at_peak']:.4f}; {r['relative_accommodation_rmse_D']:.3f} D, "
                  f"{r['accommodation_rmse_D']:.3f} D" for r in rows]
        summary += "\n" + "\n".join(lines)
    return {"fit": fit, "files": files, "summary": summary}


def _sweep(args, t_start: float) -> int:
    prog = f"{PROG} sweep"
    explicit = [args.coordinator, args.num_processes, args.process_id]
    if any(x is not None for x in explicit) and not args.distributed:
        print(f"{prog}: error: --coordinator, --num-processes and --process-id need "
              f"--distributed", file=sys.stderr)
        return 2
    if args.distributed:
        # before anything touches a JAX device (loading a layout file does)
        kwargs = {k: v for k, v in (("coordinator_address", args.coordinator),
                                    ("num_processes", args.num_processes),
                                    ("process_id", args.process_id)) if v is not None}
        try:
            jax.distributed.initialize(**kwargs)
        except Exception as err:  # noqa: BLE001 - report any start-up failure in one line
            print(f"{prog}: error: jax.distributed.initialize failed: {err}", file=sys.stderr)
            return 2

    if args.verify:
        if not is_store(args.config):
            print(f"{prog}: error: --verify needs a sweep STORE (a folder written by 'lfjax "
                  f"sweep'), got {args.config}", file=sys.stderr)
            return 2
        check = verify_store(args.config)
        print(f"{prog}: {args.config}: {check.summary()}")
        return 0 if check.healthy else 1
    if args.template:
        target = Path(args.config)
        if target.exists():
            print(f"{prog}: error: {target} already exists; --template writes a new file",
                  file=sys.stderr)
            return 2
        target.write_text(config_template())
        print(f"{prog}: wrote {target} (every key with its default; edit, then "
              f"'lfjax sweep {target} --dry-run')")
        return 0
    try:
        config = load_config(args.config)
    except SweepConfigError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else Path(Path(args.config).stem + ".zarr")
    if args.dry_run:
        try:
            *_, est = plan_sweep(config, None if out.exists() else out)
        except SweepTooLargeError as err:
            print(f"{prog}: error: {err}", file=sys.stderr)
            return 2
        except (ValueError, OSError) as err:
            print(f"{prog}: error: {' '.join(str(err).split())}", file=sys.stderr)
            return 2
        print(f"{prog}: plan for {args.config} (dry run: nothing written)")
        print(est.summary(out))
        return 0
    if out.exists() and not args.resume:
        print(f"{prog}: error: --out {out} already exists: pass --resume to complete it, or "
              f"choose another --out", file=sys.stderr)
        return 2
    enable_compilation_cache()

    def terminated(signum, frame):
        # a batch scheduler's SIGTERM (preemption, time limit) ends the run as Ctrl-C does:
        # the lock is released and finished chunks are kept for --resume
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, terminated)
    except ValueError:  # not the main thread: leave signals alone
        previous = None
    try:
        run = run_sweep(config, out, resume=args.resume, progress=not args.no_progress,
                        max_chunks=args.max_chunks,
                        on_plan=lambda est: print(f"{prog}: plan\n{est.summary(out)}",
                                                  flush=True))
    except KeyboardInterrupt:
        if out.exists():
            print(f"{prog}: interrupted; finished chunks are kept in {out} (continue with "
                  f"--resume)", file=sys.stderr)
        else:
            print(f"{prog}: interrupted before any chunk finished; no store was kept",
                  file=sys.stderr)
        return 130
    except (StoreMismatchError, SweepTooLargeError, StoreLockedError) as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # one line, no traceback
        if is_disk_full(err):
            kept = (f"finished chunks are kept in {out}; free space and continue with --resume"
                    if out.exists() else "no chunk had finished, so no store was kept")
            print(f"{prog}: error: the disk is full: {kept}", file=sys.stderr)
            return 1
        notes = " ".join(getattr(err, "__notes__", []))
        return _unexpected_error(prog, err, f" ({notes})" if notes else "")
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    who = f" (process {run.process_index} of {run.process_count})" if run.process_count > 1 else ""
    print(f"{prog}: {run.eyes_computed} eyes in {len(run.computed_chunks)} chunks computed"
          f"{who}, {len(run.skipped_chunks)} chunks already complete; "
          f"{run.eyes_per_second:.2f} eyes/s, peak memory {run.peak_rss_mb:.0f} MiB")
    print(f"{prog}: store {out} ({time.perf_counter() - t_start:.1f} s)")
    return 0


def _sweep_report(args) -> int:
    prog = f"{PROG} sweep-report"
    if not is_store(args.store):
        print(f"{prog}: error: STORE {args.store} is not an lfjax sweep store (a folder written "
              f"by 'lfjax sweep')", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else default_out_dir(args.store)
    if out.exists() and not out.is_dir():
        print(f"{prog}: error: --out {out} exists and is not a folder", file=sys.stderr)
        return 2
    try:
        files = sweep_report(args.store, out, draws=args.draws, seed=args.seed,
                             progress=not args.no_progress)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except ValueError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    except Exception as err:  # one line, no traceback
        return _unexpected_error(prog, err)
    print(f"{prog}: wrote {len(files)} files to {out}: "
          + ", ".join(sorted(p.name for p in files.values())))
    return 0


# ----------------------------------------------------------------------------- lfjax design


def _add_design_parser(sub) -> None:
    des = sub.add_parser(
        "design",
        help="fit a buildable lenslet display to a panel and virtual eyes; design.json, design.png",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Design a light-field display a maker can build (lfjax.design.fit). Start from a panel\n"
            "(--panel near-eye: a 0.7-inch 1920x1080 OLED microdisplay, 8.1 um pixels, lenslets\n"
            "30 mm from the eye; --panel phone: a 460 ppi phone panel at 350 mm; the pixel pitch\n"
            "and count can be overridden). For each views-per-pupil count (--views, n x n views\n"
            "across the design pupil) fit the lenslet pitch, fill and gap (the focal length\n"
            "follows from the gap and the CDP) and, with --distance-range, the viewing distance,\n"
            "by L-BFGS-B with the layout optimiser's accommodation-aware objective on training\n"
            "eyes (seed S), the panel's lenslet diffraction and pixel blur in the model. Each\n"
            "design keeps an eye box of at least --min-eye-box mm. Report every count on\n"
            "held-out eyes (seed S+1) beside its starting array (lenslets_for_layout's tangent\n"
            "array, f/3): image at each eye's predicted accommodation (VSOTF), the display's\n"
            "accommodation error, and the perceivable resolution (MTF 0.05 cut-off capped at the\n"
            "display's sampling limit, cpd; median and 5-95 %). A design whose views collapse\n"
            "(1x1) or that drives no accommodation is refused with the reason; a CDP outside the\n"
            "depth range is refused before anything runs.\n\n"
            "Outputs in DIR: design.json (every count's build specification: pixel pitch,\n"
            "lenslet pitch, aperture, focal length, gap, distance, with units; derived CDP,\n"
            "Fresnel number, pixel and lenslet angles, eye box; held-out scores; the chosen\n"
            "count) and design.png (the chosen lenslet array and its views in the pupil).\n"
            "Units: mm, dioptres (D), arcmin, cycles per degree (cpd), nm."
        ),
    )
    des.add_argument("--panel", choices=("near-eye", "phone"), default="near-eye",
                     help="starting panel preset (default near-eye)")
    des.add_argument("--pixel-pitch", metavar="MM", type=_finite_float, default=None,
                     help="override the preset's pixel pitch, mm")
    des.add_argument("--pixel-count", metavar=("W", "H"), nargs=2, type=_positive_int, default=None,
                     help="override the preset's pixel count (horizontal, vertical)")
    des.add_argument("--distance", metavar="MM", type=_finite_float, default=None,
                     help="viewing distance, eye pupil to lenslets, mm (default the preset's)")
    des.add_argument("--distance-range", metavar=("LO", "HI"), nargs=2, type=_finite_float,
                     default=None, help="fit the viewing distance too, within LO ... HI mm")
    des.add_argument("--depths", metavar=("LOW", "HIGH"), nargs=2, type=_finite_float,
                     required=True, help="rendered depth range in D, 0 <= LOW < HIGH")
    des.add_argument("--n-depths", metavar="K", type=_positive_int, default=3,
                     help="rendered depths evenly spanning the range, >= 2 (default 3)")
    des.add_argument("--cdp", metavar="D", type=_finite_float, default=None,
                     help="central depth plane, D, within the depth range (default: the "
                          "range's dioptric middle)")
    des.add_argument("--views", metavar="N", nargs="+", type=_positive_int, default=[1, 2, 3, 4],
                     help="views-per-side counts to design, 1 ... 8 (default 1 2 3 4)")
    des.add_argument("--min-eye-box", metavar="MM", type=_finite_float, default=10.0,
                     help="smallest eye box (viewing zone) allowed, mm (default 10)")
    des.add_argument("--min-fill", metavar="F", type=_finite_float, default=0.5,
                     help="smallest lenslet fill, aperture/pitch in (0, 1] (default 0.5)")
    des.add_argument("--f-number", metavar=("LO", "HI"), nargs=2, type=_finite_float,
                     default=(1.0, 8.0), help="lenslet f-number range (default 1 8)")
    des.add_argument("--diffraction", choices=("fresnel", "modulus", "off"), default="fresnel",
                     help="lenslet diffraction in the model (default fresnel)")
    des.add_argument("--train-eyes", metavar="N", type=_positive_int, default=10,
                     help="training eyes, >= 1 (default 10)")
    des.add_argument("--test-eyes", metavar="N", type=_count, default=20,
                     help="held-out eyes, >= 0 (default 20; 0: report on the training eyes)")
    des.add_argument("--seed", metavar="S", type=_seed, default=0,
                     help="training eyes from seed S, held-out eyes from S+1 (default 0)")
    des.add_argument("--wavelengths", metavar="NM", nargs="+", type=_finite_float, default=[550.0],
                     help="the fit's wavelengths, nm, increasing, 400-700 (default 550)")
    des.add_argument("--steps", metavar="N", type=_count, default=10,
                     help="L-BFGS-B steps per count, >= 0 (default 10)")
    des.add_argument("--report-accuracy", choices=("full", "fit"), default="full",
                     help="setting of the held-out report (default full: 31 wavelengths)")
    des.add_argument("--freq-step", metavar="CPD", type=_finite_float, default=None,
                     help="frequency step, cpd (default: the planner's aliasing guard)")
    des.add_argument("--out", metavar="DIR", default="lfjax-design",
                     help="output folder; must be new or empty unless --force (default ./lfjax-design)")
    des.add_argument("--force", action="store_true", help="write into a non-empty DIR")
    des.add_argument("--no-progress", action="store_true", help="print no per-count progress")


def _design_setup(args):
    """Validated (panel, eyes, fit_design keywords, out) of ``lfjax design``; ValueError
    naming the option otherwise."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not args.force:
        raise ValueError(f"--out {out} is not empty (use --force to write into it)")
    low, high = args.depths
    if low < 0 or not high > low:
        raise ValueError(f"--depths must satisfy 0 <= LOW < HIGH (D), got {low:g} {high:g}")
    if args.n_depths < 2:
        raise ValueError(f"--n-depths must be >= 2 for a depth range, got {args.n_depths}")
    if any(n > 8 for n in args.views):
        raise ValueError(f"--views must be in 1 ... 8, got {args.views}")
    wl = args.wavelengths
    if any(w < 400 or w > 700 for w in wl) or any(b <= a for a, b in zip(wl, wl[1:])):
        raise ValueError(f"--wavelengths must increase within 400-700 nm, got {wl}")
    if args.freq_step is not None and not args.freq_step > 0:
        raise ValueError(f"--freq-step must be > 0 cpd, got {args.freq_step:g}")
    cdp = 0.5 * (low + high) if args.cdp is None else args.cdp
    if not low <= cdp <= high:
        raise ValueError(f"--cdp {cdp:g} D lies outside the depth range [{low:g}, {high:g}] D; choose "
                         f"a CDP within it (default: its middle, {0.5 * (low + high):g} D)")
    preset = {"cdp_D": cdp}
    if args.distance is not None:
        if not args.distance > 0:
            raise ValueError(f"--distance must be > 0 mm, got {args.distance:g}")
        preset["distance_mm"] = args.distance
    try:
        panel = PRESETS[args.panel](**preset)
        changes = {}
        if args.pixel_pitch is not None:
            changes["pixel_pitch_mm"] = args.pixel_pitch
        if args.pixel_count is not None:
            changes["pixel_count"] = tuple(args.pixel_count)
        panel = dataclasses.replace(panel, diffraction=args.diffraction, **changes)
    except ValueError as err:
        raise ValueError(f"--panel {args.panel}: {err}") from None
    try:
        constraints = DesignConstraints(
            min_eye_box_mm=args.min_eye_box, min_fill=args.min_fill, min_f_number=args.f_number[0],
            max_f_number=args.f_number[1],
            distance_range_mm=None if args.distance_range is None else tuple(args.distance_range))
    except ValueError as err:
        raise ValueError(str(err).replace("min_eye_box_mm", "--min-eye-box").replace(
            "min_fill", "--min-fill").replace("distance_range_mm", "--distance-range")) from None
    return panel, constraints, cdp, out


def _design(args, t_start: float) -> int:
    prog = f"{PROG} design"
    try:
        panel, constraints, cdp, out = _design_setup(args)
    except ValueError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return 2
    enable_compilation_cache()
    try:
        result = fit_design(
            panel, depth_range_D=tuple(args.depths), n_depths=args.n_depths, cdp_D=cdp,
            train_eyes=sample_eyes(args.seed, args.train_eyes),
            test_eyes=sample_eyes(args.seed + 1, args.test_eyes) if args.test_eyes > 0 else None,
            views_per_side=tuple(args.views), constraints=constraints,
            wavelengths_nm=tuple(args.wavelengths), steps=args.steps,
            report_accuracy=args.report_accuracy,
            sampling=None if args.freq_step is None else Sampling(args.freq_step),
            progress=not args.no_progress)
        result.provenance["seed_train"] = args.seed
        result.provenance["panel_preset"] = args.panel
        files = save_design(result, out, command="lfjax " + " ".join(args.argv))
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except ValueError as err:
        print(f"{prog}: error: {' '.join(str(err).split())}", file=sys.stderr)
        return 2
    except Exception as err:  # one line, no traceback
        return _unexpected_error(prog, err)
    print(result.summary())
    print(f"{prog}: wrote {len(files)} files to {out} in {time.perf_counter() - t_start:.1f} s")
    return 0



def _unexpected_error(prog: str, err: Exception, suffix: str = "") -> int:
    """An error no check foresaw: one line on stderr, no traceback (``LFJAX_DEBUG=1``
    re-raises it); exit status 1."""
    message = " ".join(str(err).split()) or type(err).__name__
    print(f"{prog}: error: {type(err).__name__}: {message}{suffix}", file=sys.stderr)
    if os.environ.get("LFJAX_DEBUG"):
        raise err
    return 1


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
    if args.command == "optimise":
        args.argv = list(sys.argv[1:] if argv is None else argv)
        return _optimise(args, t_start)
    if args.command == "sweep-report":
        return _sweep_report(args)
    if args.command == "sweep":
        return _sweep(args, t_start)
    if args.command == "design":
        args.argv = list(sys.argv[1:] if argv is None else argv)
        return _design(args, t_start)
    return 2  # pragma: no cover - argparse rejects unknown commands


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
