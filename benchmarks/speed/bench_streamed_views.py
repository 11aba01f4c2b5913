"""Views one at a time against all views together: time and peak memory of one eye.

The phone panel's designs (``lfjax design --panel phone``) have large elemental stacks: at
4x4 views the held-out report holds 16 states x 16 views of 1440 x 721 complex samples
(2.1 GB per eye) and the fit's reverse pass kept them for its gradient. Above
``lfjax.kernel.pipeline.ELEMENTAL_STACK_BYTES`` the pipeline transforms the views one at a
time (:func:`lfjax.kernel.pipeline.rendered_otfs`). This script measures, each in a fresh
process (its peak resident memory is that process's), for one eye of the phone preset at
n x n views (default 4):

* ``report``: the held-out report's evaluation (``evaluate_layout`` at the "fast" setting),
  first call (with compilation) and second call;
* ``fit``: the fit's value and gradient (``design_loss_chunked``, one eye), first and second
  call;

with the stack held whole (``together``) and streamed (``streamed``), and the largest
difference between their numbers.

    python benchmarks/speed/bench_streamed_views.py [--views N] [--out FILE.json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

CHILD = r"""
import json, resource, sys, time
import numpy as np
import jax, jax.numpy as jnp
import lfjax.kernel.pipeline as pipeline
mode, task, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
pipeline.ELEMENTAL_STACK_BYTES = 2**62 if mode == "together" else 0
from lfjax.design.box import (design_problem, design_value_and_grad_chunked, panel_from_box,
                              report_problem, start_box, with_display)
from lfjax.design.fit import design_cdp_D, design_panel
from lfjax.design.settings import DesignConstraints
from lfjax.layout_opt import evaluate_layout
from lfjax.model.eyes import sample_eyes
depths = np.linspace(0.0, 3.0, 3)
cdp = design_cdp_D((0.0, 3.0))
panel = design_panel("phone", cdp)
constraints = DesignConstraints()
train, test = sample_eyes(0, 1), sample_eyes(1, 1)
problem = design_problem(panel, n, train, depths, cdp, constraints, planning_eyes=train)
x0 = jnp.asarray(start_box(panel, n, cdp, constraints), jnp.float32)
if task == "report":
    report = report_problem(problem, test, "fast")
    candidate = panel_from_box(np.asarray(x0), panel, n, cdp, constraints)
    run = lambda: evaluate_layout(candidate.layout(n), with_display(report, candidate, constraints))
    numbers = lambda out: [float(v) for v in np.ravel(out["values"]["vsotf"])] + [out["loss"]]
    fft = report.config.n_fft
else:
    run = lambda: jax.block_until_ready(design_value_and_grad_chunked(x0, problem, panel, n, constraints, 1))
    numbers = lambda out: [float(out[0])] + [float(g) for g in np.ravel(out[1])]
    fft = problem.config.n_fft
t0 = time.perf_counter(); out = run(); first = time.perf_counter() - t0
t0 = time.perf_counter(); out = run(); second = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps(dict(mode=mode, task=task, views=n, n_fft=fft, first_s=first, second_s=second,
                      peak_bytes=peak, numbers=numbers(out))))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=4, help="views per side (n x n)")
    ap.add_argument("--out", help="write the rows as JSON here")
    args = ap.parse_args(argv)
    print("command: python " + " ".join([sys.argv[0]] + (argv if argv is not None else sys.argv[1:])),
          flush=True)
    rows = []
    env = dict(os.environ, JAX_PLATFORMS=os.environ.get("JAX_PLATFORMS", "cpu"))
    for task in ("report", "fit"):
        for mode in ("together", "streamed"):
            t0 = time.perf_counter()
            done = subprocess.run([sys.executable, "-c", CHILD, mode, task, str(args.views)],
                                  capture_output=True, text=True, env=env)
            if done.returncode != 0:
                print(done.stderr[-3000:], file=sys.stderr)
                raise SystemExit(f"{task}/{mode} failed (exit {done.returncode})")
            row = json.loads(done.stdout.strip().splitlines()[-1])
            row["process_s"] = time.perf_counter() - t0
            rows.append(row)
            print(f"{task:6s} {mode:9s} {args.views}x{args.views} FFT {row['n_fft']}: first "
                  f"{row['first_s']:.1f} s, second {row['second_s']:.1f} s, peak "
                  f"{row['peak_bytes'] / 2**30:.2f} GiB", flush=True)
    for task in ("report", "fit"):
        a, b = (next(r for r in rows if r["task"] == task and r["mode"] == m)
                for m in ("together", "streamed"))
        x, y = (__import__("numpy").asarray(r["numbers"]) for r in (a, b))
        scale = max(float(abs(x).max()), 1e-30)
        print(f"{task}: streamed/together second call {b['second_s'] / a['second_s']:.2f}x, peak "
              f"{b['peak_bytes'] / a['peak_bytes']:.2f}x; largest difference in its numbers "
              f"{float(abs(x - y).max()):.2e} (largest number {scale:.3g})")
    if args.out:
        with open(args.out, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
