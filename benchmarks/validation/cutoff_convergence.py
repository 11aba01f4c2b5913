"""How far the frequency step moves a cut-off frequency, on the study's eyes.

The radial MTF is a ring average on the frequency grid (rings of width df), and the cut-off
its first crossing of the threshold, linearly interpolated. For an aberrated eye's
anisotropic MTF near 0.05 both depend on df. This script evaluates the natural view (the
paper's eleven eyes at the CDP, VSOTF-predicted accommodation, `lfjax reproduce`'s spectrum
at each plan's wavelength step) at several frequency steps and prints each eye's cut-off
against the finest step's. The wavelength step is held fixed, so only df moves.

Run:  PYTHONPATH=. .venv/bin/python benchmarks/validation/cutoff_convergence.py [--layout natural]
      [--steps 1.1892 1.0905 0.6 0.3] [--wavelength-step 20]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layout", default="natural")
    parser.add_argument("--steps", type=float, nargs="+", default=[1.1892, 1.0905, 0.6, 0.3],
                        help="frequency steps (cpd); the last is the reference")
    parser.add_argument("--wavelength-step", type=float, default=20.0)
    args = parser.parse_args(argv)
    print("$", " ".join(["python", *sys.argv]))

    from lfjax.model.layouts import paper_layouts
    from lfjax.reproduce.config import StudyConfig, study_eyes
    from lfjax.base.sampling import Sampling
    from lfjax.model.spectral import make_spectrum
    from lfjax.vision.focus import through_focus

    config = StudyConfig()
    eyes, labels = study_eyes(config)
    layout = paper_layouts(config.pupil_diameter_mm)[args.layout]
    depths = np.array([config.cdp_D]) if args.layout == "natural" else config.depths_D
    spectrum = make_spectrum(np.arange(400.0, 700.0 + 1e-6, args.wavelength_step),
                             config.options)
    cutoffs, peaks = {}, {}
    for df in args.steps:
        tf = through_focus(
            eyes,
            layout,
            States.grid(config.accommodation_D, depths_D=depths, window_D=config.window_D),
            Viewing(pupil_diameter_mm=config.pupil_diameter_mm, cdp_D=config.cdp_D),
            spectrum=spectrum,
            sampling=Sampling(df),
            options=config.options,
            check_aliasing=False,
        )
        cutoffs[df] = np.asarray(tf.cutoff_cpd("vsotf", config.cutoff_threshold), float)
        peaks[df] = np.asarray(tf.peak_index("vsotf"))
    ref = args.steps[-1]
    print(f"layout {args.layout}, {args.wavelength_step:g} nm; cut-off (cpd) minus the cut-off "
          f"at df {ref:g} cpd, per eye ({', '.join(labels)}); same grid peak: whether each "
          f"eye's predicted accommodation is the reference's")
    for df in args.steps[:-1]:
        diff = (cutoffs[df] - cutoffs[ref]).ravel()
        same = bool(np.all(peaks[df] == peaks[ref]))
        print(f"df {df:g}: max |diff| {np.max(np.abs(diff)):.3f} cpd, "
              f"rms {np.sqrt(np.mean(diff ** 2)):.3f} cpd, same grid peak: {same}; "
              + " ".join(f"{d:+.2f}" for d in diff))
    return 0


if __name__ == "__main__":
    sys.exit(main())
