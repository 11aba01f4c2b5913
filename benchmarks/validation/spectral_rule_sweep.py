"""The sweep at its defaults before and after per-layout spectral rules: wavelengths and
modelled work per layout.

Before: every (pupil, layout) shared one uniform grid, the finest of the layouts' planned
steps (``lfjax.sweep.compute.sweep_spectrum``). After: each sums its own planned rule
(``sweep_spectra``: a uniform step or the Gauss rule in V(λ), whichever meets the targets
with fewer wavelengths). Both are planned and prepared on the same eyes; the work per eye
is the sweep guard's model (``SweepEstimate``: FFT work of grid and peak states, which its
time estimate scales), so the ratio is the arithmetic saved, not a timing.

With ``--time`` also the chunk function itself, before and after side by side in one
process: one warm chunk of ``chunk_size`` eyes per layout, best of ``--repeat`` (compilation
excluded), the two spectra alternating so that load on a shared machine hits both alike.

Run:  .venv/bin/python benchmarks/validation/spectral_rule_sweep.py [--time] [--repeat 2]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from lfjax.sweep.compute import (ChunkEvaluator, build_tasks, population, spectral_plans,
                                 sweep_spectrum)
from lfjax.sweep.config import SweepConfig
from lfjax.sweep.guard import estimate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--time", action="store_true", help="also time one chunk per layout")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    print("command: .venv/bin/python benchmarks/validation/spectral_rule_sweep.py"
          + (f" --time --repeat {args.repeat}" if args.time else ""), flush=True)
    defaults = SweepConfig()
    # the defaults; as many eyes as one chunk (the guard's model is per eye)
    config = dataclasses.replace(defaults, n_eyes=int(defaults.chunk_size))
    eyes, _ = population(config)
    t0 = time.perf_counter()
    before_tasks = build_tasks(config, eyes, sweep_spectrum(config))
    before = estimate(config, before_tasks)
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
    per_1000 = 1000 / 60 / before.n_eyes  # the estimate counts every eye, the average's too
    print(f"| all | | | | **{total_a / total_b:.2f}** ({before.seconds * per_1000:.0f}"
          f" -> {after.seconds * per_1000:.0f} min per 1,000 eyes, the guard's "
          f"model) |", flush=True)
    assert np.isfinite(total_a / total_b)
    if args.time:
        _time(config, eyes, before_tasks, after_tasks, args.repeat)


def _time(config, eyes, before_tasks, after_tasks, repeat: int) -> None:
    """Seconds per eye of one warm chunk per layout, before and after, side by side."""
    evaluator = ChunkEvaluator(config, eyes.measured_pupil_mm)
    z = np.asarray(eyes.zernike_um)[: int(config.chunk_size)]
    print(f"\nchunk of {z.shape[0]} eyes, peaks {config.peak_method!r}, best of {repeat} "
          f"(compilation excluded), s per eye:")
    print("| layout | before | after | after / before |")
    print("| --- | --- | --- | --- |")
    total = [0.0, 0.0]
    for tb, ta in zip(before_tasks, after_tasks):
        evaluator.evaluate(tb, z)  # compile both first
        evaluator.evaluate(ta, z)
        best = [float("inf"), float("inf")]
        for _ in range(repeat):
            for i, task in enumerate((tb, ta)):
                t0 = time.perf_counter()
                evaluator.evaluate(task, z)
                best[i] = min(best[i], time.perf_counter() - t0)
        sb, sa = best[0] / z.shape[0], best[1] / z.shape[0]
        total[0] += sb
        total[1] += sa
        print(f"| {ta.layout_label} | {sb:.3f} | {sa:.3f} | {sa / sb:.2f} |", flush=True)
    print(f"| all | {total[0]:.2f} ({total[0] * 1000 / 60:.0f} min / 1,000 eyes) | {total[1]:.2f} "
          f"({total[1] * 1000 / 60:.0f} min) | **{total[1] / total[0]:.2f}** |", flush=True)


if __name__ == "__main__":
    main()
