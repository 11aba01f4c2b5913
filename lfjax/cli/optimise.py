"""``lfjax optimise``: fit a subaperture layout (:func:`lfjax.layout_opt.optimise_and_save`)."""

from __future__ import annotations

import argparse
import time

from lfjax import layout_opt as lo
from lfjax.base.errors import ParameterError
from lfjax.base.files import check_output_folder
from lfjax.cli import cache, common, flags

COMMAND = "optimise"


def objective(text: str) -> lo.Objective:
    """``--objective``: a name, or comma-separated name=weight pairs."""
    if "=" in text:
        weights = {}
        for part in text.split(","):
            name, _, weight = part.partition("=")
            try:
                weights[name.strip()] = flags.finite_float(weight)
            except argparse.ArgumentTypeError as err:
                raise argparse.ArgumentTypeError(f"weight of {name.strip()!r}: {err}") from None
        text = weights
    try:
        return lo.Objective.parse(text)
    except ParameterError as err:
        raise argparse.ArgumentTypeError(err.naming({"objective": "the objective"})) from None


def add_parser(sub) -> None:
    opt = sub.add_parser(
        COMMAND,
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
            "step); with --front N also front.png and front.json (the trade-off). DIR is\n"
            "checked first (writable, room for the files); they are staged and moved in\n"
            "when all are written: a failure or Ctrl-C leaves none of them.\n"
            "Units: mm in the pupil, dioptres (D), cycles per degree (cpd), nm."
        ),
    )
    opt.add_argument("--objective", type=objective, default=None, metavar="OBJ",
                     help="accommodation_aware (default), image_at_peak, depth_of_field, "
                          "accommodation, resolution, or weights name=w,name=w "
                          "(loss = -w*VSOTF + w*D^2 - w*cpd)")
    opt.add_argument("--accommodation-tolerance", metavar="D", type=flags.finite_float,
                     default=None,
                     help="constrain the training eyes' accommodation RMSE to D dioptres "
                          "(default 0.25 for accommodation_aware, none for the others)")
    opt.add_argument("--front", metavar="N", type=flags.positive_int, default=None,
                     help="also fit N layouts along the trade-off (tolerances 0.1 ... 1 D), "
                          "score them and the tangent 2x2-4x4 grids and natural viewing on the "
                          "held-out eyes, and draw front.png")
    opt.add_argument("--views", metavar="N", type=flags.positive_int, default=4,
                     help="number of views, >= 1 (square lattice: n*n, e.g. 4, 9, 16; hex: any, "
                          "7 and 19 fill rings; default 4)")
    opt.add_argument("--parametrisation", choices=lo.PARAMETRISATIONS, default="lattice",
                     help="lattice: pitch, diameter, rotation; free: every centre and diameter "
                          "(default lattice)")
    opt.add_argument("--lattice", choices=lo.LATTICES, default="square",
                     help="lattice of the start (and of the fit with --parametrisation lattice)")
    flags.add_depths(opt, (0.0, 4.0), 5,
                      "rendered depth range in D, 0 <= LOW < HIGH (default 0 4)")
    opt.add_argument("--cdp", metavar="D", type=flags.finite_float, default=2.0,
                     help="central depth plane of the display, D >= 0 (default 2)")
    opt.add_argument("--pupil", metavar="MM", type=flags.finite_float, default=3.0,
                     help="pupil diameter, mm, in (0, 3] for the 3 mm eye statistics (default 3)")
    opt.add_argument("--max-diameter", metavar="MM", type=flags.finite_float, default=None,
                     help="largest subaperture diameter, mm (default 1.2 x the tangent lattice's, "
                          "at most the pupil: it sizes every FFT window, so smaller is faster)")
    opt.add_argument("--min-diameter", metavar="MM", type=flags.finite_float, default=0.5,
                     help="smallest subaperture diameter, mm (default 0.5)")
    opt.add_argument("--containment", choices=lo.CONTAINMENTS, default="centre",
                     help="centre: |centre| <= pupil radius, the pupil crops the rest "
                          "(default); contained: |centre| + d/2 <= pupil radius")
    opt.add_argument("--non-overlap", action="store_true", help="subapertures must not overlap")
    flags.add_eyes(opt, 10, 50, "held-out eyes, >= 0 (default 50; 0: none). Scored at the full "
                                 "accuracy, each costs about 9 s per layout (start and fit) on 2 "
                                 "busy CPU cores")
    opt.add_argument("--display-distance", metavar="MM", type=flags.finite_float, default=None,
                     help="optimise for a lenslet-array display at MM from the eye: each view "
                          "is its lenslet's Fresnel pattern (default: the paper's ideal display)")
    opt.add_argument("--pixel-arcmin", metavar="A", type=flags.finite_float, default=0.0,
                     help="emitters of this angular width, arcmin (default 0: points)")
    opt.add_argument("--spectrum", metavar="NAME", default=None,
                     help="a display's white (crt, lcd, oled, laser) instead of the V(lambda)-"
                          "weighted --wavelengths")
    opt.add_argument("--solver", choices=lo.METHODS, default="lbfgsb",
                     help="lbfgsb: jaxopt L-BFGS-B in box coordinates (default); bfgs: "
                          "optimistix BFGS in unconstrained coordinates, which reach a bound "
                          "only asymptotically (prefer lbfgsb when the start or the optimum "
                          "sits on one, e.g. tangent discs with --non-overlap)")
    flags.add_fit_setting(
        opt, 30, "solver steps, >= 0 (default 30)",
        wavelengths_help="the fit's wavelengths, nm, increasing, 400-700 (default 550, the LCA "
                         "reference; the held-out report uses 31 wavelengths)",
        report_help="setting of the held-out report: full (31 wavelengths, refined peaks; "
                    "default) or fit (the training setting, much faster)",
        freq_step_help="frequency step, cpd (default: the planner's aliasing guard for every "
                       "feasible layout)")
    flags.add_out(opt, "lfjax-layout", "output folder; must be new or empty unless --force "
                                        "(default: ./lfjax-layout)")
    flags.add_force(opt, "write into a non-empty DIR (files of the same names are replaced)")
    flags.add_no_progress(opt)


def settings(args) -> lo.OptimisationSettings:
    """The library's settings from the parsed flags (checked as they are made)."""
    return lo.OptimisationSettings(
        n_views=args.views, lattice=args.lattice, parametrisation=args.parametrisation,
        objective=args.objective, accommodation_tolerance_D=args.accommodation_tolerance,
        depth_range_D=tuple(args.depths), n_depths=args.n_depths, cdp_D=args.cdp,
        pupil_diameter_mm=args.pupil, max_diameter_mm=args.max_diameter,
        min_diameter_mm=args.min_diameter, containment=args.containment,
        non_overlap=args.non_overlap, train_eyes=args.train_eyes, test_eyes=args.test_eyes,
        seed=args.seed, wavelengths_nm=tuple(args.wavelengths),
        display_distance_mm=args.display_distance, pixel_width_arcmin=args.pixel_arcmin,
        spectrum=args.spectrum, freq_step_cpd=args.freq_step, method=args.solver,
        steps=args.steps, report_accuracy=args.report_accuracy, front=args.front)


def run(args) -> int:
    prog = f"{common.PROG} {COMMAND}"
    try:
        chosen = settings(args)
        # writable, with room for the outputs: refused now, not after the work
        check_output_folder(args.out, args.force, need_bytes=lo.estimated_output_bytes(chosen))
    except ValueError as err:
        return common.refuse(prog, err, COMMAND)
    cache.enable_compilation_cache()
    result, status = common.guarded(
        prog, COMMAND, lambda: lo.optimise_and_save(chosen, args.out, force=args.force,
                                                    progress=not args.no_progress,
                                                    command=common.command_line(args.argv)),
        refused=())
    if status is not None:
        return status
    print(result.summary)
    print(f"{prog}: wrote {len(result.files)} files to {args.out} in "
          f"{time.perf_counter() - args.t_start:.1f} s")
    return 0
