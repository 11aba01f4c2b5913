# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Optimising the subaperture layout of a light-field display
#
# A light-field display sends each view through its own subaperture of the eye's pupil.
# Where the subapertures sit and how large they are sets the depth of field, the
# accommodation the display drives and the resolution the eye sees. `lfjax.layout_opt`
# fits a layout to a population of virtual eyes with the differentiable pipeline and
# reports it on held-out eyes; this notebook walks through it with the public API.
#
# The default objective is *accommodation-aware*: the eye focuses where its image is best,
# so a layout is scored by the image at each eye's own predicted accommodation (the global
# peak of its through-focus VSOTF, searched between the rendered depth and the display's
# CDP) while the display's accommodation error is held within 0.25 D. Image quality alone
# is won by removing the light field: the views collapse into one pinhole, sharp at every
# depth, on which every eye focuses at the CDP.
#
# The size is set by `LFJAX_NOTEBOOK_SIZE`: `small` (the committed outputs: 4 training
# eyes, 8 held-out eyes scored at the full accuracy — 31 wavelengths, refined peaks) or
# `tiny` (what `tests/layout_opt/test_layout_opt.py` runs: seconds, numbers meaningless). Larger
# studies: `benchmarks/studies/layout_optimisation.py` and `lfjax optimise --help`.
#
# `notebooks/optimise_layout.py` is this notebook as a plain script (jupytext percent
# format); the test checks that the two agree.

# %%
import io
import os
import time

import numpy as np
from IPython.display import Image, display

import lfjax
from lfjax import layout_opt as lo
from lfjax.model import layout_plots
from lfjax.cli import enable_compilation_cache

# Optional: keep JAX compilations on disk (as the command line does), so a second session
# starts faster.
enable_compilation_cache()

SIZE = os.environ.get("LFJAX_NOTEBOOK_SIZE", "small")
if SIZE == "tiny":
    # one held-out eye as one training eye (one chunk shape), one step; the front's one
    # tolerance is the default 0.25 D, so its fit is the fit above (one compiled objective)
    setup = dict(n_train=1, n_test=1, depths_D=[1.0, 3.0], sampling=lfjax.Sampling(2.0),
                 steps=1, scan_mm=[0.75, 1.5], report=None, front=[0.25])
else:
    setup = dict(n_train=4, n_test=8, depths_D=np.linspace(0.0, 4.0, 5), sampling=None,
                 steps=20, scan_mm=[0.5, 0.75, 1.0, 1.25, 1.5], report="full",
                 front=[0.1, 0.3, 1.0])


def show(fig):
    """Display a matplotlib Figure (lfjax builds them without pyplot) as a PNG."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90)
    display(Image(buffer.getvalue()))


train = lfjax.sample_eyes(0, setup["n_train"])   # fitted
test = lfjax.sample_eyes(1, setup["n_test"])     # held out: never seen by the fit
print(f"size {SIZE}: {train.n_eyes} training eyes, {test.n_eyes} held-out eyes, "
      f"depths {np.round(setup['depths_D'], 2).tolist()} D, CDP 2 D, 3 mm pupil")

# %% [markdown]
# ## Why the VSOTF reference must not move with the layout
#
# The paper normalises VSOTF by the *same layout* without aberrations. Shrink the
# subapertures and that reference shrinks with them, so the ratio keeps rising: every
# objective would reward vanishingly small subapertures. Scored against the natural open
# pupil, the same scan (2×2 views at 1.5 mm pitch, correct accommodation) has an interior
# optimum. `lfjax.layout_opt` therefore insists on `ModelOptions(vsotf_reference="open_pupil")`.

# %%
scan = {ref: lo.diameter_scan(train, 2, 1.5, setup["scan_mm"], setup["depths_D"], ref,
                              wavelengths_nm=[550.0], sampling=setup["sampling"])
        for ref in ("paper", "open_pupil")}
print("diameter (mm)        " + "  ".join(f"{d:5.2f}" for d in setup["scan_mm"]))
for ref, values in scan.items():
    print(f"mean VSOTF, {ref:10s} " + "  ".join(f"{v:5.3f}" for v in values.mean(axis=1)))
    print(f"worst depth, {ref:9s} " + "  ".join(f"{v:5.3f}" for v in values.min(axis=1)))

# %% [markdown]
# ## What the default objective refuses: four views on one spot
#
# The problem bundles the training eyes, the rendered depths, the spectrum, the
# constraints and the objective (default `"accommodation_aware"`). It is built at the
# cheap *fit* setting: 550 nm, each eye's through-focus VSOTF on a 0.25 D grid over a
# window holding the rendered depth and the CDP, peaks located by the grid parabola.
# Four views stacked on the pupil centre make one pinhole: a sharper image at the eye's
# own peak than the paper's tangent grid, but that peak sits on the CDP whatever the
# rendered depth. The evaluation searches the whole window, so it sees it.

# %%
constraints = lo.Constraints(pupil_diameter_mm=3.0,
                             max_diameter_mm=lo.default_max_diameter_mm("square", 4, 3.0),
                             min_diameter_mm=0.5)
problem = lo.make_problem(train, setup["depths_D"], constraints, sampling=setup["sampling"],
                          planning_eyes=test)
print(f"objective: {problem.objective.name}")
print(f"frequency step {problem.config.freq_step_cpd:.3f} cpd, peak grid "
      f"{problem.peak_grid.states_D.size} states")
tangent = lo.tangent_lattice("square", 4, 3.0)
pinhole = lo.free_params(np.full((4, 2), 1e-8), np.full(4, 0.94))
for name, params in (("tangent 2x2", tangent), ("pinhole", pinhole)):
    ev = lo.evaluate_layout(params, problem)
    print(f"{name:12s} image at the eye's peak {ev['image_at_peak']:.3f}, accommodation RMSE "
          f"{ev['accommodation_rmse_D']:.2f} D (display's share {ev['relative_accommodation_rmse_D']:.2f} D), "
          f"gain {ev['accommodation_gain']:.2f}, loss {ev['loss']:.3f}")

# %% [markdown]
# ## A lattice fit with the default objective
#
# Square lattice (pitch, diameter, rotation), centres inside the pupil, diameters
# 0.5–1.8 mm (1.2 × the tangent diameter: the cap sizes every FFT window). L-BFGS-B
# (jaxopt) moves in box coordinates that always map to feasible layouts. The held-out
# eyes are scored at the full setting (31 wavelengths, refined peaks).

# %%
start = lo.initial_lattice("square", 4, constraints)
t0 = time.perf_counter()
fit = lo.optimise_layout(start, problem, method="lbfgsb", max_steps=setup["steps"],
                         test_eyes=test, progress=False, report_problem=setup["report"])
print(f"fitted and reported in {time.perf_counter() - t0:.1f} s")
print(fit.summary())

# %%
show(layout_plots.fig_layouts({"tangent 2x2": fit.initial_layout, "fitted": fit.layout}, 3.0))
show(layout_plots.fig_history(fit.history, "loss"))

# %% [markdown]
# Through-focus VSOTF of the held-out eyes before and after (fit setting), around each
# rendered depth.

# %%
curves = {"tangent 2x2": lo.through_focus_curves(fit.initial_params, problem, eyes=test),
          "fitted": lo.through_focus_curves(fit.params, problem, eyes=test)}
show(layout_plots.fig_through_focus(curves, setup["depths_D"]))

# %% [markdown]
# ## The trade-off
#
# Accommodation accuracy and image quality pull against each other. One fit per
# tolerance draws the front, with the tangent grids and natural viewing (real points:
# the display's share of the error is zero by definition) on the same held-out eyes.
# Loose tolerances let the views shrink towards one pinhole.

# %%
front = lo.trade_off_front(start, problem, setup["front"], test_eyes=test,
                           max_steps=setup["steps"], progress=False, report_problem=None)
for row in front.table():
    print(f"{row['name']:24s} image {row['image_at_peak']:.3f}, display error "
          f"{row['relative_accommodation_rmse_D']:.3f} D, all {row['accommodation_rmse_D']:.3f} D")
show(layout_plots.fig_front(front, 3.0))

# %% [markdown]
# ## Saving and reading a layout

# %%
path = lo.save_layout_json("layout.json", fit.layout, 3.0,
                           objective=dict(name=fit.objective.name,
                                          held_out=fit.test["after"]["image_at_peak"]),
                           provenance=dict(train_seed=0, test_seed=1), parameters=fit.params)
layout, record = lo.load_layout_json(path)
print(layout.name, np.round(np.asarray(layout.diameters_mm, float), 4).tolist(),
      record["parameters"]["kind"])
