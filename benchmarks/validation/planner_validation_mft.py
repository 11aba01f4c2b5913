"""Planner validation for the matrix Fourier transform path (issue #5, RESULTS §7).

For three small scenes (aberration-free eye, 450/550/650 nm, accommodation 0–4 D / 0.2 D in
a window around each depth) the planner is forced to the MFT path (``transform="mft"``);
its plan and each rejected cheaper neighbour are run through lfjax.vision.focus and
measured against a converged run: Richardson (order 2) from the FFT plan's df/2 and df/4.

Run:  .venv/bin/python benchmarks/validation/planner_validation_mft.py [tolerance, default 1e-3]
"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

from _common import header  # noqa: E402

import lfjax
from lfjax.planner import Overrides, PlanScene, Targets, plan_sampling
from lfjax.vision.focus import through_focus
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

WL = [450.0, 550.0, 650.0]
SPECTRUM = lfjax.make_spectrum(WL)
ACC = np.round(np.arange(0, 4.01, 0.2), 9)
SCENES = {
    "open": (lfjax.open_pupil(3.0), [2.0], 3.0, 1.0),
    "2x2": (lfjax.grid_layout(2, 3.0), [1.0, 2.0, 3.0], 3.0, 1.0),
    "4x4": (lfjax.grid_layout(4, 3.0), [1.5, 2.5], 3.0, 0.6),
}


def vsotf(eye, layout, depths, window, sampling, pupil):
    tf = through_focus(
        eye,
        layout,
        States.grid(ACC, depths_D=depths, window_D=window),
        Viewing(pupil_diameter_mm=pupil),
        spectrum=SPECTRUM,
        sampling=sampling,
        check_aliasing=False,
    )
    return np.asarray(tf.vsotf), np.asarray(tf.allowed)


def main():
    tol = float(sys.argv[1]) if len(sys.argv) > 1 else 1e-3
    header(f"planner_validation_mft: forced MFT plans for VSOTF error <= {tol:g} (issue #5)")
    for name, (layout, depths, pupil, window) in SCENES.items():
        eye = lfjax.model.eyes.aberration_free_eye(measured_pupil_mm=3.0)
        scene = PlanScene(layout, pupil, 2.0, depths_D=depths, accommodation_D=ACC,
                          accommodation_window_D=window, wavelengths_nm=WL)
        plan = plan_sampling(scene, Targets(vsotf=tol), overrides=Overrides(transform="mft"))
        df_fft = plan_sampling(scene, Targets(vsotf=tol)).sampling.freq_step_cpd
        half, allowed = vsotf(eye, layout, depths, window, lfjax.Sampling(df_fft / 2), pupil)
        quarter, _ = vsotf(eye, layout, depths, window, lfjax.Sampling(df_fft / 4), pupil)
        ref = quarter + (quarter - half) / 3
        mask = np.broadcast_to(allowed[None], ref.shape)

        def error(sampling):
            return np.abs(vsotf(eye, layout, depths, window, sampling, pupil)[0] - ref)[mask].max()

        s = plan.sampling
        print(f"== {name}: MFT {s.mft_pupil_samples} samples at df {s.freq_step_cpd:.4g} cpd; "
              f"estimate {plan.errors['pupil']:.2e}, measured {error(s):.2e}", flush=True)
        for dim, (cheaper, why) in plan.cheaper.items():
            print(f"   one step cheaper ({dim}): {why} | measured {error(cheaper):.2e}", flush=True)


if __name__ == "__main__":
    main()
