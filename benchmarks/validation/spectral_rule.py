"""The spectral rule the planner chooses, checked on the pipeline against a 5 nm reference.

For each of the paper's layouts (3 mm pupil, CDP 2 D; natural view at the CDP, the
viewpoint layouts at the study's depths 0–4 D in 0.5 D steps; states 0–5 D in 0.2 D steps
within ±2 D), the planner is asked the study's question (peaks to 0.01 D, cut-offs to
0.25 cpd, ``lfjax.planner.targets.Targets``) twice: with ``spectral_rule="uniform"`` (the step,
as lfjax planned before) and ``"auto"`` (the step or the Gauss rule for V(λ), whichever meets
the targets on the proxy with fewer wavelengths). Both plans' spectra then run through the
pipeline itself (real eyes, not the aberration-free proxy) on the auto plan's frequency
grid, against 400–700 nm in 5 nm steps on the same grid: continuous VSOTF peaks (``local``),
VSOTF over every allowed state, and cut-offs at the reference's grid peak (the same state
for every spectrum, so only the spectrum differs). The wavelength counts before/after are
the arithmetic the rule saves (the transforms scale with them).

Eyes: the study's (``lfjax.reproduce.config.study_eyes``, seed 0): the first
``--eyes`` virtual eyes (default 5) and the average eye.

Run:  .venv/bin/python benchmarks/validation/spectral_rule.py [--eyes N] [natural 2x2 3x3 4x4]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import time

import jax
import numpy as np

import lfjax
from lfjax.model.layouts import paper_layouts
from lfjax.model.spectral import make_spectrum
from lfjax.planner.plan import plan_sampling
from lfjax.planner.targets import Overrides, Targets
from lfjax.planner.scene import PlanScene
from lfjax.reproduce.config import StudyConfig, study_eyes
from lfjax.vision.focus import _cutoff_at_index, through_focus
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

PEAK_TARGET_D = 0.01
CUTOFF_TARGET_CPD = 0.25
LOBE_JUMP_CPD = 1.0  # a cut-off this far off has crossed the threshold on another MTF lobe


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=False).stdout.strip() or "?"
    except OSError:
        return "?"


def compare(name: str, eyes, config: StudyConfig) -> dict:
    layout = paper_layouts(config.pupil_diameter_mm)[name]
    depths = ([config.cdp_D] if name == "natural"
              else [config.cdp_D + d for d in config.depth_offsets_D])
    grid = np.round(np.arange(0.0, config.accommodation_max_D + 1e-9,
                              config.accommodation_step_D), 9)
    scene = PlanScene(layout=layout, pupil_diameter_mm=config.pupil_diameter_mm,
                      cdp_D=config.cdp_D, depths_D=np.asarray(depths), accommodation_D=grid,
                      accommodation_window_D=config.window_D, eyes=eyes,
                      wavelength_range_nm=(400.0, 700.0), options=config.options)
    targets = Targets(vsotf=None, peak_D=PEAK_TARGET_D, cutoff_cpd=CUTOFF_TARGET_CPD,
                      cutoff_threshold=config.cutoff_threshold)
    t0 = time.perf_counter()
    plans = {rule: plan_sampling(scene, targets, estimate_accuracy=False,
                                 overrides=Overrides(spectral_rule=rule))
             for rule in ("uniform", "auto")}
    t_plan = time.perf_counter() - t0
    sampling = plans["auto"].sampling

    def run(spectrum):
        return through_focus(
            eyes,
            layout,
            States.grid(grid, depths_D=depths, window_D=config.window_D),
            Viewing(pupil_diameter_mm=config.pupil_diameter_mm, cdp_D=config.cdp_D),
            spectrum=spectrum,
            sampling=sampling,
            options=config.options,
            peaks=PeakOptions(metrics=("vsotf",), method="local", second_peaks=False),
        )

    t0 = time.perf_counter()
    reference = run(make_spectrum(np.arange(400.0, 701.0, 5.0), config.options))
    index = reference.peak_index("vsotf")
    peaks = reference.continuous_accommodation_D()
    cutoffs = np.asarray(_cutoff_at_index(reference.radial_mtf, index, reference.radial_freq_cpd,
                                          config.cutoff_threshold))
    allowed = np.asarray(reference.allowed)
    print(f"{name}: {eyes.zernike_um.shape[0]} eyes, depths {depths[0]:g}–{depths[-1]:g} D "
          f"({len(depths)}), df {sampling.freq_step_cpd:.4g} cpd; planning {t_plan:.1f} s; "
          f"reference 400-700 nm in 5 nm steps ({time.perf_counter() - t0:.1f} s)", flush=True)
    out = {}
    for rule, plan in plans.items():
        t0 = time.perf_counter()
        tf = run(plan.spectrum())
        dp = float(np.nanmax(np.abs(tf.continuous_accommodation_D() - peaks)))
        dv = float(np.max(np.abs(np.where(allowed[None], np.asarray(tf.vsotf)
                                          - np.asarray(reference.vsotf), 0.0))))
        dc = np.abs(np.asarray(_cutoff_at_index(tf.radial_mtf, index, tf.radial_freq_cpd,
                                                config.cutoff_threshold)) - cutoffs)
        wl = np.asarray(plan.wavelengths_nm)
        label = (f"Gauss-V {wl.size} nodes" if plan.spectral_rule == "gauss"
                 else f"uniform {wl[1] - wl[0]:g} nm")
        within = dp <= PEAK_TARGET_D and dc.max() <= CUTOFF_TARGET_CPD
        print(f"  {rule:7s} -> {label:18s} {wl.size:2d} wavelengths ({wl.min():.0f}-{wl.max():.0f} nm): "
              f"peaks max |d| {dp:.1e} D, VSOTF max |d| {dv:.1e}, cut-offs max |d| "
              f"{dc.max():.3f} cpd (median {np.median(dc):.3f}, {int(np.sum(dc > CUTOFF_TARGET_CPD))}"
              f" of {dc.size} over {CUTOFF_TARGET_CPD:g}, {int(np.sum(dc > LOBE_JUMP_CPD))} lobe "
              f"jumps > {LOBE_JUMP_CPD:g}); {'within' if within else 'OUTSIDE'} the targets "
              f"({time.perf_counter() - t0:.1f} s)", flush=True)
        out[rule] = (label, wl.size, dp, dv, float(dc.max()))
    for r in plans["auto"].reasons:
        if r.startswith("wavelength"):
            print(f"    plan: {r}", flush=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--eyes", type=int, default=5, help="virtual eyes (plus the average eye)")
    parser.add_argument("layouts", nargs="*", default=["natural", "2x2", "3x3", "4x4"])
    args = parser.parse_args()
    print("command: .venv/bin/python benchmarks/validation/spectral_rule.py "
          f"--eyes {args.eyes} " + " ".join(args.layouts))
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__}, {time.strftime('%Y-%m-%d %H:%M %Z')}, commit {_commit()}",
          flush=True)
    config = StudyConfig()
    both, _ = study_eyes(config)
    pick = list(range(args.eyes)) + [config.n_eyes]  # the first virtual eyes and the average
    eyes = lfjax.Eyes(np.asarray(both.zernike_um)[pick], both.measured_pupil_mm)
    t0 = time.perf_counter()
    rows = {name: compare(name, eyes, config) for name in args.layouts}
    print("\nsummary (wavelengths before -> after; max |d| against 5 nm with the planned rule):")
    for name, r in rows.items():
        label, n, dp, dv, dc = r["auto"]
        print(f"  {name:8s} {r['uniform'][0]} ({r['uniform'][1]}) -> {label} ({n}): peaks "
              f"{dp:.1e} D, VSOTF {dv:.1e}, cut-offs {dc:.3f} cpd")
    print(f"total {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
