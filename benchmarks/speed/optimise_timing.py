"""Where a layout fit's time goes, and the README's default fit end to end.

Run:  .venv/bin/python benchmarks/speed/optimise_timing.py              (both parts)
      .venv/bin/python benchmarks/speed/optimise_timing.py --steps-only (part 1)

1. Cost of one solver step (the objective and its gradient, ``layout_value_and_grad``) for
   the 2×2 lattice on 10 training eyes, rendered depths 0–4 D (5), CDP 2 D, 3 mm pupil, one
   setting changed at a time, side by side in one process: the diameter cap (it sizes the
   FFT windows), the number of wavelengths, the objective (correct-focus VSOTF against the
   accommodation-aware objective, whose predicted peaks need a through-focus grid) and the
   peak grid's step. For each: building the problem (planning, reference), the first call
   (compilation) and the mean of three calls after it.
2. ``lfjax optimise --views 4 --train-eyes 10 --test-eyes N`` with every other flag at its
   default, run twice in this process (the second from a warm compilation cache): the fit's
   time, the held-out report's time at the full accuracy, and the result.

Prints the command line and the machine with the numbers; benchmarks/RESULTS.md keeps them.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import jax
import numpy as np

import lfjax.layout_opt as lo
from lfjax import cli
from lfjax.model.eyes import sample_eyes


def step_costs(n_eyes: int = 10) -> list[dict]:
    eyes = sample_eyes(0, n_eyes)
    depths = lo.depth_grid(0.0, 4.0, 5)
    cap = lo.default_max_diameter_mm("square", 4, 3.0)
    cases = [
        ("depth_of_field, cap 3.0 mm (the pupil), 3 wavelengths", "depth_of_field", 3.0, (450.0, 550.0, 650.0), 0.25),
        ("depth_of_field, cap 1.8 mm, 3 wavelengths", "depth_of_field", cap, (450.0, 550.0, 650.0), 0.25),
        ("accommodation_aware, cap 1.8 mm, 3 wavelengths", None, cap, (450.0, 550.0, 650.0), 0.25),
        ("accommodation_aware, cap 1.8 mm, 550 nm (default)", None, cap, (550.0,), 0.25),
        ("accommodation_aware, cap 1.8 mm, 550 nm, 0.5 D peak grid", None, cap, (550.0,), 0.5),
        ("accommodation_aware, cap 3.0 mm, 550 nm", None, 3.0, (550.0,), 0.25),
    ]
    rows = []
    for label, objective, cap_mm, wavelengths, step in cases:
        constraints = lo.Constraints(3.0, cap_mm, 0.5)
        t0 = time.perf_counter()
        problem = lo.make_problem(eyes, depths, constraints, objective or lo.DEFAULT_OBJECTIVE,
                                  wavelengths_nm=wavelengths,
                                  setting=lo.ProblemSetting(peak_step_D=step))
        t1 = time.perf_counter()
        start = lo.as_free(lo.initial_lattice("square", 4, constraints))
        jax.block_until_ready(lo.layout_value_and_grad(start, problem))
        t2 = time.perf_counter()
        for _ in range(3):
            jax.block_until_ready(lo.layout_value_and_grad(start, problem))
        t3 = time.perf_counter()
        row = dict(case=label, n_fft=problem.config.n_fft, freq_step_cpd=problem.config.freq_step_cpd,
                   peak_states=int(problem.peak_grid.states_D.size), problem_s=t1 - t0,
                   first_call_s=t2 - t1, step_s=(t3 - t2) / 3)
        rows.append(row)
        print(f"{label:58s} n_fft {row['n_fft']:4d}  states {row['peak_states']:2d}  problem "
              f"{row['problem_s']:5.1f} s  first {row['first_call_s']:6.1f} s  step {row['step_s']:6.2f} s",
              flush=True)
    return rows


def default_fit(test_eyes: int, out: str) -> None:
    for run in ("cold or warm cache (first run in this process)", "warm cache (second run)"):
        folder = f"{out}-{run.split()[0]}"
        t0 = time.perf_counter()
        code = cli.main(["optimise", "--views", "4", "--train-eyes", "10", "--test-eyes",
                         str(test_eyes), "--out", folder, "--force", "--no-progress"])
        print(f"[{run}] exit {code}, whole command {time.perf_counter() - t0:.1f} s", flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps-only", action="store_true")
    parser.add_argument("--fit-only", action="store_true")
    parser.add_argument("--test-eyes", type=int, default=200)
    parser.add_argument("--out", default="/tmp/lfjax-optimise-timing")
    args = parser.parse_args(argv)
    print("$ python " + " ".join([os.path.relpath(__file__), *sys.argv[1:]]))
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores visible, affinity "
          f"{len(os.sched_getaffinity(0))} cores; jax {jax.__version__} {jax.devices()}", flush=True)
    if not args.fit_only:
        step_costs()
    if not args.steps_only:
        default_fit(args.test_eyes, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
