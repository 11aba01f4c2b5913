# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Designing a light-field display from a panel
#
# A display maker does not choose "a subaperture layout". They choose a panel (pixel pitch
# and count), a lenslet array (pitch, fill, focal length), the gap between them and a
# viewing distance. This notebook walks through one design with `lfjax.display.panel` and
# `lfjax.design.fit`: the quantities a panel implies for the eye, what more views per pupil
# cost in resolution, a fit of the lenslet array to a few eyes, the buildable
# specification it writes and its drawing.
#
# The size is set by `LFJAX_NOTEBOOK_SIZE`: `small` (the committed outputs: 2 training and
# 4 held-out eyes, 2×2 and 3×3, two solver steps, the fit setting's single wavelength) or
# `tiny` (what `tests/design/test_design_fit.py` runs: one eye each, 2×2 only, one step, lenslet
# diffraction off and a coarse fixed frequency step; numbers meaningless). The population
# trade-off is `benchmarks/studies/spatio_angular_tradeoff.py` (RESULTS §15).
#
# `notebooks/display_design.py` is this notebook as a plain script (jupytext percent
# format); the test checks that the two agree.

# %%
import dataclasses
import json
import os
from pathlib import Path

import numpy as np
from IPython.display import Image, display

import lfjax
from lfjax.design import (DesignConstraints, DesignTarget, FitSettings, ReportSettings, fit_design,
                          panel_specification, save_design)
from lfjax.model.eyes import sample_eyes
from lfjax.display.panel import near_eye_microdisplay, sampling_limit_cpd
from lfjax.base.sampling import Sampling
from lfjax.studies.tradeoff import panel_for_views

SIZE = os.environ.get("LFJAX_NOTEBOOK_SIZE", "small")
panel = near_eye_microdisplay()
if SIZE == "tiny":
    panel = dataclasses.replace(panel, diffraction="off")
    target_kwargs, fit_kwargs, sampling = dict(views_per_side=(2,)), dict(steps=1), Sampling(2.0)
    n_train, n_test = 1, 1
else:
    target_kwargs, fit_kwargs, sampling = dict(views_per_side=(1, 2, 3)), dict(steps=2), None
    n_train, n_test = 2, 4
print(SIZE, lfjax.__version__)

# %% [markdown]
# ## The panel and what it implies
#
# The preset is a 0.7-inch 1920×1080 OLED microdisplay (8.1 µm pixels) behind 1 mm
# lenslets of 3.3 mm focal length, 30 mm from the eye, with the gap set for a central depth
# plane (CDP) at 1.5 D. Everything below follows from those numbers by thin-lens geometry
# (`lfjax.display.panel`'s module documentation derives each one):
#
# * the magnification M = 1 + z_m·V from the lenslet plane to the pupil, so the views are
#   M·Δu apart in the pupil and M·a wide — a 3 mm pupil holds D/(M·Δu) of them across;
# * the Fresnel number of one view, which says whether a view is a geometric disc (≫ 1)
#   or a diffraction pattern spread over the pupil (≲ 1);
# * the pixel's angle on the CDP, p/(z_0·M), and the lenslet pitch's angle Δu/z_m: the two
#   samplings of the image, whose Nyquist frequencies bound what the eye can resolve;
# * the eye box Δu·(1 + z_m/z_0), the zone from which every lenslet shows its own pixels.

# %%
spec = panel_specification(panel)
for key in ("cdp_D", "magnification", "views_across_pupil", "views_per_side", "view_pitch_mm",
            "view_diameter_mm", "fresnel_number", "pixel_arcmin", "pixel_nyquist_cpd",
            "lenslet_arcmin", "nyquist_cpd", "eye_box_mm", "depth_step_D", "f_number"):
    entry = spec["derived"][key]
    print(f"{key:20s} {entry['value']:10.4g}  {entry['unit']}")

# %% [markdown]
# ## What the sampling lets through at each rendered depth
#
# A pattern rendered on the CDP is sampled by the pixels; one on the lenslet plane by the
# lenslets; in between and beyond, by both in proportion (`sampling_limit_cpd`, after
# Hoshino et al. 1998 and Zwicker et al. 2006). The perceivable resolution of an eye is the
# lower of its optical cut-off at its predicted accommodation and this limit.

# %%
depths = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
limit = np.asarray(sampling_limit_cpd(panel, depths))
for d, c in zip(depths, limit):
    print(f"rendered at {d:3.1f} D: sampling limit {c:5.2f} cpd")

# %% [markdown]
# ## More views per pupil, coarser pixels
#
# Keep the panel's pixels, distance, CDP and eye box, and put n×n tangent views in the
# pupil (`lfjax.studies.tradeoff.panel_for_views`): the lenslets shrink as 1/n, and so does the gap
# that keeps the eye box, so each pixel subtends an angle n times wider while the lenslet
# sampling gets n times finer. On the CDP the pixels decide; off it, the lenslets. How the
# eyes fare — accommodation error and perceivable resolution over a population — is the
# trade-off benchmark's question.

# %%
print(" n  lenslet mm  gap mm  pixel arcmin  limit on CDP cpd  limit at CDP±1 D cpd  Fresnel N")
for n in range(1, 7):
    p = panel_for_views(panel, n)
    cdp = float(p.cdp_D)
    lim = np.asarray(sampling_limit_cpd(p, [cdp, cdp - 1.0, cdp + 1.0]))
    print(f"{n:2d}  {float(p.lenslet_pitch_mm):10.3f}  {float(p.gap_mm):6.2f}"
          f"  {float(p.pixel_arcmin()):12.2f}  {lim[0]:16.2f}  {min(lim[1], lim[2]):20.2f}"
          f"  {float(p.fresnel_number()):9.3g}")

# %% [markdown]
# ## Fitting the lenslet array to eyes
#
# `fit_design` keeps the panel's pixels and distance and fits, for each views-per-pupil
# count, the lenslet pitch, fill and gap (the focal length follows from the CDP) by
# gradient, with the layout optimiser's accommodation-aware objective: image quality at
# each eye's own predicted accommodation, with the display's accommodation error bounded.
# Every point of its search box is a buildable panel (n views across the pupil, a lenslet
# no smaller than a pixel, an f-number in range, the eye box at least 10 mm). One view
# (1×1) is refused before anything is fitted: it drives no accommodation. The fitted
# design and its starting tangent array are scored on held-out eyes — here every count
# (`report_counts="all"`); by default only the counts the choice needs are, in order of
# their training loss.

# %%
train, test = sample_eyes(0, n_train), sample_eyes(1, n_test)
result = fit_design(panel, DesignTarget((1.0, 2.0), n_depths=3 if SIZE != "tiny" else 2,
                                        **target_kwargs),
                    train, test, constraints=DesignConstraints(), fit=FitSettings(**fit_kwargs),
                    report=ReportSettings("fit", "all"), sampling=sampling)
print(result.summary())

# %% [markdown]
# ## The specification
#
# `save_design` writes `design.json` — every number of every count's design with its unit,
# the scores on the held-out eyes, the notes on where the design leaves the model's
# assumptions — and `design.png`, the drawing of the chosen array.

# %%
out = Path("display_design_out")
files = save_design(result, out, command="notebooks/display_design.ipynb")
record = json.loads((out / "design.json").read_text())
chosen = next(d for d in record["designs"] if d["specification"] is not None
              and d["views_per_side"] == (record["chosen_views_per_side"] or d["views_per_side"]))
print("chosen:", record["chosen_views_per_side"], "views per side")
for key, entry in chosen["specification"]["build"].items():
    value = entry["value"]
    value = f"{value:.5g}" if isinstance(value, float) else value
    print(f"{key:22s} {value}  {entry['unit'] or ''}")
print("notes:", *chosen["notes"], sep="\n  ")

# %% [markdown]
# ## The drawing
#
# Left: a 3×3 patch of the lenslet array over the panel's pixels (every lenslet covers
# tens of them); right: the views the array puts in the design pupil.

# %%
display(Image(filename=str(out / "design.png")))
