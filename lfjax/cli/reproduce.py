"""``lfjax reproduce``: the paper's study (:func:`lfjax.reproduce.reproduce`)."""

from __future__ import annotations

import argparse
import time

from lfjax.cli import cache, common, flags
from lfjax.reproduce import OutputError, StudyConfig, check_reproduce, reproduce
from lfjax.reproduce.config import ACCURACY_PLANS

COMMAND = "reproduce"
DEFAULT_OUT = "lfjax-results"


def add_parser(sub) -> None:
    rep = sub.add_parser(
        COMMAND,
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
    flags.add_out(rep, DEFAULT_OUT, f"output folder; must be new or empty unless --force "
                                     f"(default: ./{DEFAULT_OUT})")
    rep.add_argument("--eyes", metavar="N", type=flags.positive_int, default=None,
                     help="number of virtual eyes drawn from the Thibos et al. (2002) "
                          "statistics, >= 1; the average eye is always added "
                          "(default: 10, or 2 with --quick)")
    flags.add_seed(rep, "seed of the random eye draw, integer 0 ... 2^32-1 (default: 0); "
                         "same seed, same eyes")
    rep.add_argument("--quick", action="store_true",
                     help="small version for testing: 2 eyes + average eye, depths CDP-2, "
                          "CDP, CDP+2 D, accommodation in 0.5 D steps, 30 nm wavelength "
                          "steps, no modelling-choice alternatives; its numbers are not the "
                          "paper's")
    rep.add_argument("--accuracy", choices=ACCURACY_PLANS, default=None,
                     help="how the spectrum is sampled: 'claims' (default) plans each "
                          "layout's wavelengths (a uniform step or a Gauss rule in V(lambda), "
                          "whichever needs fewer) for peaks to 0.01 D and cut-offs to "
                          "0.25 cpd; 'vsotf' uses 10 nm steps (the uniform plan made for "
                          "a VSOTF error of 1e-3). --quick: 30 nm steps")
    rep.add_argument("--settle-verdicts", action="store_true",
                     help="with --accuracy claims: compute again at the reference spectrum "
                          "(--accuracy vsotf's steps) the layouts a verdict turns on when the "
                          "planned spectrum's error could change it, so that every verdict is "
                          "the reference's (such verdicts are otherwise marked unsettled)")
    rep.add_argument("--no-alternatives", action="store_true",
                     help="skip the reruns under alternative modelling choices (Stiles-"
                          "Crawford form, accommodation spherical aberration, LCA constant)")
    flags.add_force(rep, "replace DIR if it is a non-empty folder written by an earlier "
                          "'lfjax reproduce' (other non-empty folders are never replaced)")
    flags.add_no_progress(rep)
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
    rep.add_argument("--display-eyes", metavar="N", type=flags.count, default=2,
                     help="virtual eyes (besides the average eye) in the display-effects "
                          "section, 0 ... --eyes (default: 2; each costs minutes)")


def run(args) -> int:
    prog = f"{common.PROG} {COMMAND}"
    display_eyes = args.display_eyes if args.display_effects else None
    try:
        eyes = {} if args.eyes is None else {"n_eyes": args.eyes}
        config = (StudyConfig.quick if args.quick else StudyConfig)(seed=args.seed, **eyes)
        if args.no_alternatives:
            config = config.replace(alternatives=False)
        if args.accuracy is not None:
            config = config.replace(accuracy=args.accuracy)
        if args.settle_verdicts:
            config = config.replace(settle_verdicts=True)
        check_reproduce(args.out, config, force=args.force, population_store=args.population,
                        display_effects_eyes=display_eyes)
    except ValueError as err:
        return common.refuse(prog, err, COMMAND)
    cache.enable_compilation_cache()
    result, status = common.guarded(
        prog, COMMAND,
        lambda: reproduce(args.out, config, force=args.force, progress=not args.no_progress,
                          population_store=args.population, display_effects_eyes=display_eyes),
        note="; nothing written",  # outputs are staged: whole or not at all
        refused=(OutputError,))  # the folder, checked again as the run starts
    if status is not None:
        return status
    verdicts = ", ".join(f"{c.id} {c.verdict}" for c in result["claims"])
    print(f"{prog}: claims: {verdicts}")
    print(f"{prog}: wrote {len(result['files'])} files to {result['out']} in "
          f"{time.perf_counter() - args.t_start:.1f} s")
    return 0
