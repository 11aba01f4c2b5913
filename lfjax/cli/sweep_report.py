"""``lfjax sweep-report``: a sweep store's distributions and what ten eyes cannot tell
(:func:`lfjax.sweep.report.sweep_report`)."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from lfjax.cli import common, flags
from lfjax.base.errors import FlatCurveWarning
from lfjax.sweep.report import default_out_dir, sweep_report

COMMAND = "sweep-report"


def add_parser(sub) -> None:
    rp = sub.add_parser(
        COMMAND,
        help="pictures, percentiles and a summary of a sweep store; what ten eyes cannot tell",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Report on a population sweep store (lfjax sweep), counting only the eyes of\n"
            "complete chunks; the Thibos average eye is left out of every population\n"
            "statistic. Only a store that 'lfjax sweep STORE --verify' passes is read: a\n"
            "damaged one is refused (exit 2, nothing written), naming each damaged chunk\n"
            "and the command that recomputes it. Outputs in DIR: accommodation_error.png (VSOTF accommodation error,\n"
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
    flags.add_out(rp, None, "output folder (default: STORE's name with -report, beside it); "
                             "files of the same names in it are replaced")
    rp.add_argument("--draws", metavar="N", type=flags.positive_int, default=1000,
                    help="samples of 10 eyes drawn for the ten-eye table, >= 1 (default 1000)")
    flags.add_seed(rp, "seed of the samples (default 0)")
    flags.add_no_progress(rp, "do not show the progress bar of the draws (on stderr)")


def run(args) -> int:
    prog = f"{common.PROG} {COMMAND}"
    out = Path(args.out) if args.out else default_out_dir(args.store)
    def work():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", FlatCurveWarning)
            files = sweep_report(args.store, out, draws=args.draws, seed=args.seed,
                                 progress=not args.no_progress)
        for warning in caught:
            if issubclass(warning.category, FlatCurveWarning):
                print(f"{prog}: warning: {warning.message}", file=sys.stderr)
            else:
                warnings.showwarning(warning.message, warning.category, warning.filename,
                                     warning.lineno)
        return files

    files, status = common.guarded(prog, COMMAND, work)
    if status is not None:
        return status
    print(f"{prog}: wrote {len(files)} files to {out}: "
          + ", ".join(sorted(p.name for p in files.values())))
    return 0
