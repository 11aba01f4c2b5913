# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Reproducing Miyanishi, Sahin & Gotchev with lfjax
#
# This notebook runs the paper's study through the Python API — the same steps as
# `lfjax reproduce` — at the `--quick` size so that it runs in a few minutes on a laptop:
# 2 virtual eyes plus the average eye, rendered depths CDP − 2, CDP and CDP + 2 D,
# 0.5 D accommodation grid, 400–700 nm in 30 nm steps, no modelling alternatives. Set
# `QUICK = False` for the full study, `lfjax reproduce`'s defaults: 3 mm pupil, CDP at 2 D,
# natural view and 2×2, 3×3, 4×4 viewpoints, rendered depths CDP − 2 … + 2 D in 0.5 D steps,
# 0.2 D accommodation grid, 10 virtual eyes plus the average eye, and over 400–700 nm each
# layout's wavelengths planned so that no accommodation peak moves by more than 0.01 D and
# no cut-off frequency by more than 0.25 cpd (`accuracy="claims"`; `accuracy="vsotf"` is
# the earlier fixed grid).
#
# The tables and figures below are the quick study's: two eyes are too few for the claims'
# statistics, so read them as what the API returns, not as the paper's numbers
# (the guide "The paper's study" gives the full run's).
#
# `notebooks/reproduce_paper.py` is the same notebook as a plain script (jupytext percent
# format); `tests/cli/test_cli.py` executes the `.ipynb` and checks that the two agree.

# %%
import io
import os

import numpy as np
from IPython.display import Image, display

import lfjax
from lfjax import reproduce
from lfjax.cli import enable_compilation_cache
from lfjax.vision.images import retinal_image, snellen_e

# Optional: keep JAX compilations on disk (as the command line does), so a second session
# starts faster.
enable_compilation_cache()

QUICK = True
config = reproduce.StudyConfig.quick() if QUICK else reproduce.StudyConfig()
if os.environ.get("LFJAX_NOTEBOOK_SIZE") == "tiny":
    # what tests/cli/test_cli.py runs: one wavelength; numbers meaningless
    config = config.replace(wavelengths_nm=(550.0, 550.0, 1.0))
config


def show(fig, dpi=80):
    """Display a matplotlib Figure as a PNG (works with any matplotlib backend)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    display(Image(buffer.getvalue()))


# %% [markdown]
# ## The study
#
# `run_study` makes one `lfjax.vision.focus.through_focus` call per layout with every eye
# (the virtual eyes and the average eye in one batch). The result is a labelled
# `xarray.Dataset`: VSOTF and Strehl ratio through focus, radial MTFs, predicted
# accommodation and cut-off frequencies, with units and the model options in its attributes.

# %%
ds = reproduce.run_study(config)
print(ds)

# %% [markdown]
# ## The paper's findings as checkable claims

# %%
claims = reproduce.evaluate_claims(ds)
for claim in claims:
    print(f"({claim.id}) {claim.verdict:5s}  {claim.finding}")
    print(f"          {claim.result}")

# %% [markdown]
# ## Tables
#
# Mean accommodation error of the aberrated eyes and the average eye's error (D), and the
# cut-off frequencies at MTF 0.05 (cpd).

# %%
summary = reproduce.summary_table(ds)
summary[summary.metric == "vsotf"][
    ["layout", "depth_rel_cdp_D", "mean_error_D", "sd_error_D", "average_eye_error_D"]
]

# %%
reproduce.cutoff_table(ds)[
    ["layout", "depth_rel_cdp_D", "mean_cutoff_cpd", "sd_cutoff_cpd", "average_eye_cutoff_cpd"]
]

# %% [markdown]
# ## Figures 3–11

# %%
examples = reproduce.compute_examples(ds, config)
figures = reproduce.all_figures(ds, examples)
for key, fig in figures.items():
    print(key, reproduce.FIGURES[key])
    show(fig)

# %% [markdown]
# ## A retinal image through the API
#
# The average eye looking at a point rendered 1 D in front of the CDP by 3×3 viewpoints:
# polychromatic OTFs with the eye focused on the rendered depth and on the CDP, then a
# 10 arcmin Snellen E convolved with each.

# %%
layout = lfjax.model.layouts.grid_layout(3, config.pupil_diameter_mm)
depth = config.cdp_D + 1.0
stack = lfjax.polychromatic_otf(lfjax.average_eye(), [depth, config.cdp_D], layout=layout,
                                depths_D=[depth],
                                spectrum=lfjax.make_spectrum(config.wavelength_grid_nm),
                                sampling=reproduce.study_sampling(ds, "3x3"))
letter = snellen_e(10.0, pixel_arcmin=0.25)
seen = np.asarray(retinal_image(letter, 0.25, stack.otf[0, 0], stack.freq_step_cpd))
print("letter", letter.shape, "retinal images", seen.shape,
      "contrast (max - min):", np.round(seen.max(axis=(1, 2)) - seen.min(axis=(1, 2)), 3))

# %%
from matplotlib.figure import Figure  # noqa: E402

fig = Figure(figsize=(7, 2.6), layout="constrained")
axes = fig.subplots(1, 3)
titles = ["scene", f"focused at {depth:g} D", f"focused at CDP {config.cdp_D:g} D"]
for ax, image, title in zip(axes, [np.asarray(letter), *seen], titles):
    ax.imshow(image, origin="lower", cmap="gray", vmin=0, vmax=1)
    ax.set_title(title, fontsize=9)
    ax.set_axis_off()
show(fig)
