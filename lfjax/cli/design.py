"""``lfjax design``: a buildable lenslet display fitted to a panel and eyes
(:func:`lfjax.design.fit_design`, :func:`lfjax.design.save_design`)."""

from __future__ import annotations

import argparse
import sys
import shutil
import time

from lfjax.base.errors import ParameterError
from lfjax.base.files import check_output_folder, check_writable
from lfjax.base.sampling import Sampling
from lfjax.cli import cache, common, flags
from lfjax.design import (
    REPORT_ACCURACIES,
    REPORT_COUNTS,
    SCREEN_MARGIN,
    DesignConstraints,
    DesignTarget,
    FitSettings,
    ReportSettings,
    check_design,
    design_cdp_D,
    design_panel,
    fit_design,
    save_design,
)
from lfjax.design.lenticular import check_lenticular_design, fit_lenticular_design, lenticular_target
from lfjax.design.resume import counts_folder
from lfjax.display.aberrations import LENS_FORMS
from lfjax.display.lenslets import DIFFRACTION_MODES
from lfjax.display.panel import PRESETS
from lfjax.layout_opt import EyeDraw

COMMAND = "design"


def add_parser(sub) -> None:
    des = sub.add_parser(
        COMMAND,
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
            "depth range is refused before anything runs. A plan comes first: each count's\n"
            "sampling, estimated time and peak memory; then a line per solver step and report.\n"
            "The fit's gradient takes the training eyes one at a time (memory does not grow\n"
            "with --train-eyes).\n\n"
            "Outputs in DIR: design.json (every count's build specification: pixel pitch,\n"
            "lenslet pitch, aperture, focal length, gap, distance, with units; derived CDP,\n"
            "Fresnel number, pixel and lenslet angles, eye box; held-out scores; the chosen\n"
            "count) and design.png (the chosen lenslet array and its views in the pupil; only\n"
            "when some count was built: --views 1 alone is refused before it has a panel, so\n"
            "design.json is then written alone), written together or not at all (a failed or\n"
            "interrupted run leaves DIR as it was). Each count's status is ok, refused (not buildable, or no light\n"
            "field) or fails (its display's accommodation RMSE above the objective's tolerance,\n"
            "0.25 D); only an ok count is chosen, and the command exits with status 1 when none\n"
            "is. Each finished count is kept in .DIR.design-counts beside DIR until the outputs\n"
            "are written: the same command after a failure or Ctrl-C resumes from them.\n"
            "Units: mm, dioptres (D), arcmin, cycles per degree (cpd), nm.\n\n"
            "--lenticular: design a horizontal-parallax-only (lenticular) panel instead\n"
            "(lfjax.design.lenticular; default panel phone). Its views are 1xN vertical strips\n"
            "(--views gives N) behind cylindrical lenticules, each an astigmatic beam: along x\n"
            "it focuses on the CDP, along y on the pixel plane (the y defocus). There is no\n"
            "gradient fit: per N the strips tile the pupil, fill 1, and the gap is the longest\n"
            "the eye box and the f-number range allow (it only shrinks the pixel's angle and\n"
            "the y defocus); each N is scored by orientation (whole VSOTF, vertical structure\n"
            "along x, horizontal structure along y): the predicted accommodation and its gain,\n"
            "the VSOTF at each eye's peak, the display's accommodation RMSE and the perceivable\n"
            "resolution along x and y. --steps, --distance-range and --lens-form are refused\n"
            "with it; --train-eyes is used only with --test-eyes 0."
        ),
    )
    des.add_argument("--lenticular", action="store_true",
                     help="design a horizontal-parallax-only lenticular panel (1xN strips; "
                          "lfjax.design.lenticular) instead of NxN lenslets")
    des.add_argument("--panel", choices=tuple(PRESETS), default=None,
                     help="starting panel preset (default near-eye; phone with --lenticular: a "
                          "near-eye lenticular's y focus, at the panel 3 cm away, is beyond any "
                          "accommodation)")
    des.add_argument("--pixel-pitch", metavar="MM", type=flags.finite_float, default=None,
                     help="override the preset's pixel pitch, mm")
    des.add_argument("--pixel-count", metavar=("W", "H"), nargs=2, type=flags.positive_int,
                     default=None, help="override the preset's pixel count (horizontal, vertical)")
    des.add_argument("--distance", metavar="MM", type=flags.finite_float, default=None,
                     help="viewing distance, eye pupil to lenslets, mm (default the preset's)")
    des.add_argument("--distance-range", metavar=("LO", "HI"), nargs=2, type=flags.finite_float,
                     default=None, help="fit the viewing distance too, within LO ... HI mm")
    flags.add_depths(des, None, 3, "rendered depth range in D, 0 <= LOW < HIGH")
    des.add_argument("--cdp", metavar="D", type=flags.finite_float, default=None,
                     help="central depth plane, D, within the depth range (default: the "
                          "range's dioptric middle)")
    des.add_argument("--views", metavar="N", nargs="+", type=flags.positive_int,
                     default=[1, 2, 3, 4],
                     help="views-per-side counts to design, 1 ... 8 (default 1 2 3 4)")
    des.add_argument("--min-eye-box", metavar="MM", type=flags.finite_float, default=10.0,
                     help="smallest eye box (viewing zone) allowed, mm (default 10)")
    des.add_argument("--min-fill", metavar="F", type=flags.finite_float, default=0.5,
                     help="smallest lenslet fill, aperture/pitch in (0, 1] (default 0.5)")
    des.add_argument("--f-number", metavar=("LO", "HI"), nargs=2, type=flags.finite_float,
                     default=(1.0, 8.0), help="lenslet f-number range (default 1 8)")
    des.add_argument("--lens-form", choices=LENS_FORMS, default=None,
                     help="the lenslets' form: each view then carries its lenslet's spherical "
                          "aberration (lfjax.display.aberrations; default: aberration-free lenslets)")
    des.add_argument("--refractive-index", metavar="N", type=flags.finite_float, default=1.5,
                     help="the lenslets' refractive index with --lens-form, in (1, 4] (default 1.5)")
    des.add_argument("--diffraction", choices=DIFFRACTION_MODES, default="fresnel",
                     help="lenslet diffraction in the model (default fresnel)")
    flags.add_eyes(des, 10, 20, "held-out eyes, >= 0 (default 20; 0: report on the training eyes)")
    flags.add_fit_setting(
        des, 10, "L-BFGS-B steps per count, >= 0 (default 10)",
        wavelengths_help="the fit's wavelengths, nm, increasing, 400-700 (default 550)",
        report_help="setting of the held-out report: fast (11 wavelengths, 400-700 nm in 30 nm "
                    "steps, peaks at the grid vertex; default), full (31 wavelengths, refined "
                    "peaks; several times slower) or fit (the fit's own wavelengths)",
        freq_step_help="frequency step, cpd (default: the planner's aliasing guard)",
        report_choices=REPORT_ACCURACIES, report_default="fast")
    des.add_argument("--report-counts", choices=REPORT_COUNTS, default="chosen",
                     help="which fitted counts the held-out report scores: chosen (default: in "
                          "order of training loss until one passes, and any within "
                          f"{100 * SCREEN_MARGIN:.0f}%% of it; "  # argparse formats help: %% is %
                          "the rest are listed as not reported) or "
                          "all (every count; several times slower)")
    flags.add_out(des, "lfjax-design", "output folder; must be new or empty unless --force "
                                        "(default ./lfjax-design)")
    flags.add_force(des, "write into a non-empty DIR")
    flags.add_no_progress(des, "print the plan only, no progress per step and per count")


def _inputs(args):
    """The checked inputs both kinds of design share: (output folder, CDP D, panel,
    constraints, sampling or None). Raises ValueError naming the flag."""
    # writable, with room for design.json, design.png and the kept counts: now, not after
    # the work
    out = check_output_folder(args.out, args.force, need_bytes=DESIGN_OUTPUT_BYTES)
    # the finished counts are kept beside it (counts_folder), in its parent even when out
    # exists (a mount point): that folder must take them too, or the first count is lost
    check_writable(counts_folder(out), parameter="out_dir", shown=out)
    cdp = design_cdp_D(args.depths, args.cdp)
    panel = design_panel(args.panel, cdp, distance_mm=args.distance,
                         pixel_pitch_mm=args.pixel_pitch, pixel_count=args.pixel_count,
                         diffraction=args.diffraction)
    constraints = DesignConstraints(
        min_eye_box_mm=args.min_eye_box, min_fill=args.min_fill,
        min_f_number=args.f_number[0], max_f_number=args.f_number[1],
        distance_range_mm=None if args.distance_range is None else tuple(args.distance_range),
        lens_form=args.lens_form, refractive_index=args.refractive_index)
    sampling = None if args.freq_step is None else Sampling(args.freq_step)
    return out, cdp, panel, constraints, sampling


def run(args) -> int:
    prog = f"{common.PROG} {COMMAND}"
    if args.panel is None:
        args.panel = "phone" if args.lenticular else "near-eye"
    if args.lenticular:
        return _run_lenticular(args, prog)
    try:
        out, cdp, panel, constraints, sampling = _inputs(args)
        target = DesignTarget(tuple(args.depths), args.n_depths, cdp, tuple(args.views),
                              tuple(args.wavelengths))
        fit = FitSettings(steps=args.steps)
        report = ReportSettings(args.report_accuracy, args.report_counts)
        draw = EyeDraw(args.seed, args.train_eyes, args.test_eyes)
        check_design(panel, target)
    except ValueError as err:
        return common.refuse(prog, err, COMMAND)

    def design(kept):
        return fit_design(panel, target, draw.train(), draw.test(), constraints=constraints,
                          fit=fit, report=report, sampling=sampling,
                          progress=_printer(args.no_progress), counts_dir=kept)

    return _design_and_write(args, prog, out, draw, design, "views-per-side count",
                             lambda f: f"{f.n_per_side}x{f.n_per_side}")


STEPS_DEFAULT = 10
"""--steps' default (a lenticular design refuses any other value: it has no fit)."""


def _run_lenticular(args, prog: str) -> int:
    """``lfjax design --lenticular``: :func:`lfjax.design.lenticular.fit_lenticular_design`."""
    try:
        if args.report_counts != "chosen":
            raise ParameterError("report_counts", "{report_counts} ranks fitted NxN counts by "
                                 "their training loss; a {lenticular} design has no fit and "
                                 "scores every count: leave {report_counts} out")
        if args.steps != STEPS_DEFAULT:
            raise ParameterError("steps", "{steps} sets the gradient fit of NxN designs; a "
                                 "{lenticular} design is set in closed form and has no steps: leave "
                                 "{steps} out")
        out, cdp, panel, constraints, sampling = _inputs(args)
        target = lenticular_target(tuple(args.depths), args.n_depths, cdp, tuple(args.views),
                                   tuple(args.wavelengths))
        report = ReportSettings(args.report_accuracy)
        check_lenticular_design(panel, target, constraints)
        draw = EyeDraw(args.seed, args.train_eyes, args.test_eyes)
    except ValueError as err:
        return common.refuse(prog, err, COMMAND)

    def design(kept):
        return fit_lenticular_design(panel, target, draw.report(), held_out=draw.held_out,
                                     constraints=constraints, report=report, sampling=sampling,
                                     progress=_printer(args.no_progress), counts_dir=kept)

    return _design_and_write(args, prog, out, draw, design, "view count", lambda f: f"1x{f.n_views}")


def _design_and_write(args, prog: str, out, draw, design, what: str, label) -> int:
    """Both kinds' run after their checks: ``design(counts_dir)`` (the finished counts kept
    beside ``out`` until the files are written: a failed run resumes from them), its files
    (:func:`lfjax.design.save_design`), its summary; exit 1 when no count qualifies
    (``what`` names a count, ``label(fit)`` each one)."""
    cache.enable_compilation_cache()
    kept = counts_folder(out)

    def work():
        result = design(kept)
        result.provenance.update(draw.provenance(), panel_preset=args.panel)
        files = save_design(result, out, command=common.command_line(args.argv), force=args.force)
        shutil.rmtree(kept, ignore_errors=True)  # written: the kept counts are not needed
        return result, files

    done, status = common.guarded(prog, COMMAND, work, note=lambda: _kept_note(kept), fold=True)
    if status is not None:
        return status
    result, files = done
    print(result.summary())
    print(f"{prog}: wrote {len(files)} files to {out} in "
          f"{time.perf_counter() - args.t_start:.1f} s")
    if result.best is None:  # the report is written, but nothing may be built from it
        reasons = "; ".join(f"{label(f)} {f.status}" for f in result.fits)
        print(f"{prog}: error: no {what} qualifies: {reasons}", file=sys.stderr)
        return 1
    return 0


DESIGN_OUTPUT_BYTES = 16 * 2**20
"""Room ``lfjax design`` asks of its output folder's disk before any work, bytes: design.png
(about 0.1 MB), design.json and the kept counts (tens of kB each), with a wide margin."""


def _kept_note(kept) -> str:
    """What an interrupted or failed run says of the counts it finished."""
    if not kept.is_dir() or not any(kept.glob("*.json")):  # count-N or lenticular-N
        return "; nothing written"
    return (f"; nothing written to --out, the finished counts are kept in {kept}: the same "
            f"command resumes from them")


def _printer(plan_only: bool):
    """What :func:`lfjax.design.fit_design` says: the plan (sampling, estimated time and
    memory of every count) always, before any work, and the progress unless ``plan_only``."""
    def say(line: str) -> None:
        if not plan_only or line.startswith("plan:"):
            print(line, flush=True)
    return say
