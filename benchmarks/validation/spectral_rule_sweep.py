"""The sweep at its defaults before and after per-layout spectral rules: wavelengths and
modelled work per layout.

Before: every (pupil, layout) shared one uniform grid, the finest of the layouts' planned
steps (``lfjax.sweep.compute.sweep_spectrum``). After: each sums its own planned rule
(``sweep_spectra``: a uniform step or the Gauss rule in V(λ), whichever meets the targets
with fewer wavelengths). Both are planned and prepared on the same eyes; the work per eye
is the sweep guard's model (``SweepEstimate``: FFT work of grid and peak states, which its
time estimate scales), so the ratio is the arithmetic saved, not a timing.

Run:  .venv/bin/python benchmarks/validation/spectral_rule_sweep.py
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from lfjax.sweep.compute import build_tasks, population, spectral_plans, sweep_spectrum
from lfjax.sweep.config import SweepConfig
from lfjax.sweep.guard import estimate


def main() -> None:
    print("command: .venv/bin/python benchmarks/validation/spectral_rule_sweep.py", flush=True)
    config = dataclasses.replace(SweepConfig(), n_eyes=2)  # the defaults; eyes only for the guard
    eyes, _ = population(config)
    t0 = time.perf_counter()
    before = estimate(config, build_tasks(config, eyes, sweep_spectrum(config)))
    after_tasks = build_tasks(config, eyes)
    after = estimate(config, after_tasks)
    plans = spectral_plans(config)
    print(f"defaults: {config.wavelengths_nm[0]:g}-{config.wavelengths_nm[1]:g} nm planned for "
          f"peaks {config.peak_tolerance_D:g} D, cut-offs {config.cutoff_tolerance_cpd:g} cpd; "
          f"layouts {', '.join(config.layouts)} ({time.perf_counter() - t0:.0f} s to plan)")
    print("| layout | before: wavelengths | after: rule | after: wavelengths | work per eye after / before |")
    print("| --- | --- | --- | --- | --- |")
    total_b = total_a = 0.0
    for tb, ta in zip(before.tasks, after.tasks):
        task = next(t for t in after_tasks if t.layout_label == ta.layout)
        plan = plans[task.key]
        n_b, n_a = tb.bands[-1][1], ta.bands[-1][1]
        rule = (f"Gauss in V(λ), {n_a} nodes" if plan.spectral_rule == "gauss"
                else f"uniform {plan.wavelengths_nm[1] - plan.wavelengths_nm[0]:g} nm")
        total_b += tb.units_per_eye
        total_a += ta.units_per_eye
        print(f"| {ta.layout} | {n_b} | {rule} | {n_a} | {ta.units_per_eye / tb.units_per_eye:.2f} |")
    print(f"| all | | | | **{total_a / total_b:.2f}** ({before.seconds / config.n_eyes * 1000 / 60:.0f}"
          f" -> {after.seconds / config.n_eyes * 1000 / 60:.0f} min per 1,000 eyes, the guard's "
          f"model) |", flush=True)
    assert np.isfinite(total_a / total_b)


if __name__ == "__main__":
    main()
