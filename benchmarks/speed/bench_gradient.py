"""Cost of a gradient of the pipeline against one forward evaluation, both jitted.

Scene (issue #10): 2 seeded eyes, 2×2 views, CDP 2 D, rendered depths 1 and 3 D, one
accommodation state per depth, 11 wavelengths (450–650 nm), the planner's guard sampling.
Objective: mean VSOTF (and Strehl) over eyes and depths. Gradients with respect to

* the eyes' Zernike coefficients (what a population fit varies),
* the layout (subaperture centres and diameters: the layout optimiser),
* the accommodation states (peak finding).

Forward and gradient are timed side by side (interleaved, minimum of repeats), after
compilation (timed separately). The ratio is the figure of merit (goal ≤ 3×).

    python benchmarks/speed/bench_gradient.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import lfjax
from lfjax.kernel.pipeline import Accommodation, PipelineConfig, Scene, retinal_metrics

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

from _common import header, interleaved_min, timed_first, fmt_s, markdown_table  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    header("gradient cost against the forward pass (jitted both)")
    options = lfjax.ModelOptions()
    spectrum = lfjax.make_spectrum(np.linspace(450.0, 650.0, 11), options)
    eyes = lfjax.sample_eyes(0, 2)
    layout = lfjax.grid_layout(2, 3.0)
    depths = np.array([1.0, 3.0])
    acc = np.array([[1.0], [3.0]])
    plan = lfjax.plan_sampling(lfjax.PlanScene(
        layout=layout, depths_D=depths, accommodation_D=acc.ravel(), accommodation_window_D=None,
        pairs=(acc.ravel(), depths), wavelengths_nm=spectrum.wavelengths_nm, eyes=eyes),
        estimate_accuracy=False)
    config = PipelineConfig.build(spectrum.wavelengths_nm, layout.window_diameter_mm, 3.0,
                                  plan.sampling, options)
    print(f"sampling: {plan.sampling.freq_step_cpd:.3g} cpd, bands {config.bands}")
    params = dict(z=eyes.zernike_um, centres=layout.centres_mm, diameters=layout.diameters_mm,
                  acc=jnp.asarray(acc))

    def objective(p):
        scene = Scene(p["centres"], p["diameters"], 2.0, depths, 3.0)
        accommodation = Accommodation.per_depth(p["acc"], options, 3.0)
        m = retinal_metrics(lfjax.Eyes(p["z"], 3.0), scene, spectrum, accommodation, config)
        return jnp.mean(m.vsotf) + jnp.mean(m.strehl)

    forward = jax.jit(objective)
    gradient = jax.jit(jax.grad(objective))
    value_and_grad = jax.jit(jax.value_and_grad(objective))
    rows = []
    compile_f, _, _ = timed_first(forward, params)
    compile_g, _, _ = timed_first(gradient, params)
    compile_vg, _, _ = timed_first(value_and_grad, params)
    times = interleaved_min({"forward": lambda: forward(params), "grad": lambda: gradient(params),
                             "value_and_grad": lambda: value_and_grad(params)}, args.repeats)
    for name, compile_s in (("forward", compile_f), ("grad", compile_g),
                            ("value_and_grad", compile_vg)):
        rows.append({"call": name, "compile": fmt_s(compile_s), "steady": fmt_s(times[name]),
                     "× forward": f"{times[name] / times['forward']:.2f}"})
    print(markdown_table(rows, ["call", "compile", "steady", "× forward"]))


if __name__ == "__main__":
    main()
