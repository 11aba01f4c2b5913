"""Cheaper settings for the HPO and cross-talk studies, checked against a fine reference.

The HPO study (lfjax.studies.hpo) and its cross-talk scans read, per eye and rendered depth,
the predicted accommodation of each orientation band (whole, x, y), the VSOTF at the peak and
the MTF cut-off along each axis there. Their cost is one pupil transform per accommodation
state × wavelength × view, so the spectrum's samples and the accommodation states are the
levers. For a few eyes and the study's representative cases this prints, per setting, the
largest difference from the reference (10 nm steps over 400–700 nm, 31 wavelengths) of
every quantity the studies read, beside the studies' previous setting (25 nm over 450–650 nm,
9 wavelengths), and the seconds each took (side by side in one process).

Run:  PYTHONPATH=. python benchmarks/validation/hpo_settings.py [--eyes 4] [--out FILE.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

from _common import header  # noqa: E402

from lfjax.base.sampling import AliasingError, Sampling, finer_step  # noqa: E402
from lfjax.display.lenticular import lenticular_phone, strip_display  # noqa: E402
from lfjax.model.eyes import sample_eyes  # noqa: E402
from lfjax.model.layouts import grid_layout, make_layout  # noqa: E402
from lfjax.model.spectral import gauss_spectrum, make_spectrum  # noqa: E402
from lfjax.model.strips import strip_layout  # noqa: E402
from lfjax.vision.orientation import BANDS, orientation_through_focus  # noqa: E402
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

HPO_GRID = tuple(np.round(np.arange(0.0, 4.51, 0.25), 6))


def cases():
    pupil, n = 3.0, 3
    strips = strip_layout(n, pupil)
    phone = lenticular_phone(cdp_D=2.0)
    wide = make_layout(np.asarray(grid_layout(n, pupil).centres_mm), np.full(n * n, 1.5 * pupil / n), pupil,
                       name="3x3 w/p 1.5")
    hpo_depths = (0.0, 1.0, 2.0, 3.0, 4.0)
    xt_depths = (1.0, 2.0, 3.0)
    return [
        ("1x3 HPO", strips, strip_display(strips), hpo_depths),
        ("3x3", grid_layout(n, pupil), None, hpo_depths),
        ("1x3 HPO lenticular phone", strips, strip_display(strips, y_defocus_D=float(phone.y_defocus_D)),
         hpo_depths),
        ("strips leakage 0.5", strips, strip_display(strips, leakage_weight=0.5), xt_depths),
        ("grid width 1.5", wide, strip_display(wide, aperture="circle"), xt_depths),
    ]


def run(eyes, layout, display, depths, grid, spectrum, step=0.75):
    for _ in range(8):
        try:
            t = time.perf_counter()
            r = orientation_through_focus(
                eyes,
                layout,
                States.grid(list(grid), list(depths)),
                Viewing(pupil_diameter_mm=3.0, cdp_D=2.0, display=display),
                spectrum=spectrum,
                sampling=Sampling(step),
                eye_chunk=4,
            )
            jax.block_until_ready(r.vsotf)
            return r, time.perf_counter() - t, step
        except AliasingError as err:
            step = finer_step(err, step)
    raise RuntimeError("no step held the field")


def read(r):
    out = {}
    for band in BANDS:
        out[f"peak_{band}_D"] = np.asarray(r.peak_D(band))
        out[f"vsotf_{band}_at_peak"] = np.asarray(r.value_at_peak(band))
    for axis in ("x", "y"):
        out[f"cutoff_{axis}_cpd"] = np.asarray(r.cutoff_cpd(axis))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--eyes", type=int, default=4)
    p.add_argument("--out", default=None)
    p.add_argument("--part", choices=("spectrum", "states"), default="states",
                   help="spectrum: the spectral samples against 31 wavelengths (HPO cases); "
                        "states: the cross-talk scans' 0.5–3.5 D grid against the HPO study's 0–4.5 D")
    p.add_argument("--cases", nargs="*", default=None, help="names of the cases to run (default: the part's)")
    args = p.parse_args(argv)
    header("HPO and cross-talk studies: cheaper settings against a fine reference")
    eyes = sample_eyes(jax.random.PRNGKey(0), args.eyes, 3.0)
    uniform9 = make_spectrum(list(np.arange(450.0, 651.0, 25.0)))
    if args.part == "spectrum":
        settings = {
            "reference 10 nm 400-700 (31)": (make_spectrum(list(np.arange(400.0, 701.0, 10.0))), None),
            "previous 25 nm 450-650 (9)": (uniform9, None),
            "Gauss V(λ) 4 nodes": (gauss_spectrum(4), None),
            "Gauss V(λ) 5 nodes": (gauss_spectrum(5), None),
            "Gauss V(λ) 7 nodes": (gauss_spectrum(7), None),
        }
        wanted = args.cases or ["1x3 HPO", "3x3", "1x3 HPO lenticular phone"]
    else:
        settings = {
            "reference: 25 nm (9), states 0-4.5 D (19)": (uniform9, None),
            "25 nm (9), states 0.5-3.5 D (13)": (uniform9, "xt"),
        }
        wanted = args.cases or ["strips leakage 0.5", "grid width 1.5"]
    report = {}
    for name, layout, display, depths in cases():
        if name not in wanted:
            continue
        ref = None
        steps = None
        for sname, (spectrum, grid_kind) in settings.items():
            grid = HPO_GRID if grid_kind is None else tuple(np.round(np.arange(0.5, 3.51, 0.25), 6))
            # the reference's step for every setting: differences are the spectrum's and grid's
            r, sec, step = run(eyes, layout, display, depths, grid, spectrum,
                               step=0.75 if steps is None else steps)
            steps = step if steps is None else steps
            got = read(r)
            if ref is None:
                ref = got
                report.setdefault(name, {})[sname] = {"seconds": sec, "freq_step_cpd": step}
                print(f"{name} | {sname}: {sec:.1f} s, step {step:g} cpd", flush=True)
                continue
            diff = {k: float(np.max(np.abs(got[k] - ref[k]))) for k in got}
            report.setdefault(name, {})[sname] = {"seconds": sec, "max_abs_diff": diff}
            print(f"{name} | {sname}: {sec:.1f} s; max |Δ| peaks whole/x/y "
                  f"{diff['peak_whole_D']:.4f}/{diff['peak_x_D']:.4f}/{diff['peak_y_D']:.4f} D, "
                  f"VSOTF at peak {diff['vsotf_whole_at_peak']:.4f}, cut-off x/y "
                  f"{diff['cutoff_x_cpd']:.3f}/{diff['cutoff_y_cpd']:.3f} cpd", flush=True)
    if args.out:
        Path(args.out).write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
