# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # The rest of the scene: its blur, its colour cue and retinal images
#
# With the CDP at 2 D and the eye focused on a point rendered at 4 D, what does a point
# rendered at 0 D look like — is its blur the blur of natural viewing, and does it keep the
# chromatic fringes of natural defocus (red sharper for farther points, blue for nearer)?
# This notebook asks `lfjax.vision.scene_blur` for the average eye and draws the retinal
# image of a scene at three depths with `lfjax.vision.scene_images`; the population answer
# is on results page 29 (`benchmarks/studies/scene_blur.py`).
#
# The size is set by `LFJAX_NOTEBOOK_SIZE`: `small` (the committed outputs: OLED primaries,
# the paper's 2×2 and 3×3 layouts, a 128×128 scene) or `tiny` (what
# `tests/vision/test_scene_blur.py` runs: laser primaries, one wavelength per primary, the
# 2×2 layout, a 32×32 scene, the accommodation set instead of predicted; numbers
# meaningless).
#
# `notebooks/scene_blur.py` is this notebook as a plain script (jupytext percent format);
# the test checks that the two agree.

# %%
import os

import matplotlib.pyplot as plt
import numpy as np

from lfjax.model.eyes import average_eye
from lfjax.model.layouts import grid_layout
from lfjax.vision.images import psf_on_grid
from lfjax.vision.scene_blur import rest_of_scene
from lfjax.vision.scene_images import (LayeredScene, demo_scene, predicted_accommodation,
                                       retinal_scene)

SIZE = os.environ.get("LFJAX_NOTEBOOK_SIZE", "small")
tiny = SIZE == "tiny"
primaries = "laser" if tiny else "oled"
layouts = {"2x2": grid_layout(2)} if tiny else {"2x2": grid_layout(2), "3x3": grid_layout(3)}
n_pixels = 32 if tiny else 128
eye = average_eye(3.0)
print(SIZE, primaries, list(layouts), n_pixels)

# %% [markdown]
# ## A point at 0 D while the eye fixates a point rendered at 4 D
#
# The eye's predicted accommodation for the fixated point through each layout (CDP 2 D),
# then the point at 0 D through the display and as a real point at 0 D, at that same
# accommodation. The equivalent defocus is the natural defocus whose MTFs (all three
# primaries) best match the display's; the true defocus is 0 − a.

# %%
grid = np.round(np.arange(-5.5, -1.0, 0.5 if tiny else 0.1), 6)
rows = []
for name, layout in layouts.items():
    a = 3.9 if tiny else predicted_accommodation(eye, layout, 4.0, primaries, cdp_D=2.0)
    r = rest_of_scene(eye, layout, a, [0.0], primaries, cdp_D=2.0, grid_defocus_D=grid)
    rows.append((name, a, r))
    print(f"{name}: accommodation {a:.2f} D, true defocus {r['true_defocus_D'][0]:+.2f} D, "
          f"equivalent {r['equivalent_defocus_D'][0]:+.2f} D, MTF ratio display/natural "
          f"{r['mtf_ratio'][0]:.2f}, colour cue natural {r['cue_natural'][0]:+.2f}, "
          f"display {r['cue_display'][0]:+.2f}")

# %%
fig, ax = plt.subplots(len(rows), 2, figsize=(6, 3 * len(rows)), squeeze=False)
for k, (name, a, r) in enumerate(rows):
    for j, (what, otf) in enumerate((("display", r["display_otf"]), ("natural", r["natural_otf"]))):
        psf = np.asarray(psf_on_grid(otf[:, 0], r["freq_step_cpd"], 0.5, 81))  # (3, 81, 81)
        rgb = np.moveaxis(psf / psf.max(axis=(1, 2), keepdims=True), 0, -1)
        ax[k, j].imshow(rgb, origin="lower", extent=[-20.25, 20.25, -20.25, 20.25])
        ax[k, j].set_title(f"{name} {what}", fontsize=9)
ax[-1, 0].set_xlabel("arcmin")
fig.tight_layout()

# %% [markdown]
# ## Retinal images of a scene at three depths
#
# A block at 4 D, a grating at 2 D and a checkerboard at 0.5 D; the eye fixates the grating
# (2 D, the CDP) at its predicted accommodation through the 2×2 display; the same
# accommodation for natural viewing and each layout. Each layer is blurred by its own PSF per
# primary and the layers are composited front to back with occlusion.

# %%
image, depth = demo_scene(n_pixels)
a = 1.95 if tiny else predicted_accommodation(eye, grid_layout(2), 2.0, primaries, cdp_D=2.0)
panels = [("scene", image)]
for name, display in [("natural", "natural")] + list(layouts.items()):
    out = retinal_scene(eye, LayeredScene.from_depth_map(image, depth, 0.75), display=display,
                        primaries=primaries, accommodation_D=a)
    panels.append((name, np.asarray(out["retina"])))
fig, ax = plt.subplots(1, len(panels), figsize=(3 * len(panels), 3.2))
for k, (name, im) in enumerate(panels):
    ax[k].imshow(np.clip(np.moveaxis(im, 0, -1), 0, 1), origin="lower")
    ax[k].set_title(name, fontsize=9)
    ax[k].set_xticks([]), ax[k].set_yticks([])
fig.tight_layout()
print(f"accommodation {a:.2f} D; layers at {out['depths_D']} D")
