# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Horizontal-parallax-only views and cross-talk between views
#
# Most light-field panels one can buy are lenticular: cylindrical lenslets that separate
# the views along x only. Each view then fills a vertical *strip* of the pupil, and its
# beam is astigmatic: along x it focuses on the display's central depth plane (CDP) and
# carries the rendered point's parallax; along y it keeps the divergence of the pixel
# itself (`lfjax.display.lenticular`). This notebook asks, with the orientation bands of
# the VSOTF (`lfjax.vision.orientation`), whether such a display drives accommodation and
# through which structure, against a full-parallax n×n grid of the same view pitch; then
# how leakage of the neighbouring views' content changes the answer.
#
# The size is set by `LFJAX_NOTEBOOK_SIZE`: `small` (the committed outputs: two eyes, 1×3
# strips against 3×3, three depths) or `tiny` (what `tests/studies/test_hpo.py` runs: one
# eye, 1×2 against 2×2, three states; numbers meaningless). The population answer:
# `benchmarks/studies/hpo_crosstalk.py` (RESULTS §27), whose committed results close the
# notebook.

# %%
import json
import os
from pathlib import Path

import numpy as np
from IPython.display import Image, Markdown, display

import lfjax
from lfjax.display.lenticular import lenticular_phone, strip_display
from lfjax.model.strips import strip_layout
from lfjax.vision.orientation import orientation_through_focus

SIZE = os.environ.get("LFJAX_NOTEBOOK_SIZE", "small")
if SIZE == "tiny":
    N, EYES, ACC, WAVELENGTHS = 2, lfjax.average_eye(3.0), [1.5, 2.0, 2.5], [550.0]
else:
    N, EYES, ACC, WAVELENGTHS = 3, lfjax.sample_eyes(0, 2, 3.0), list(np.arange(0.75, 3.26, 0.25)), [500.0, 550.0, 600.0]
DEPTHS = [1.0, 2.0, 3.0]
SPECTRUM = lfjax.make_spectrum(WAVELENGTHS)
SAMPLING = lfjax.Sampling(0.7)
phone = lenticular_phone()
print(f"lenticular phone: CDP {float(phone.cdp_D):.2f} D along x, panel {float(phone.panel_D):.2f} D "
      f"along y: the views' y defocus Δ = {float(phone.y_defocus_D):.3f} D")

# %% [markdown]
# ## HPO strips against the n×n grid
#
# Three displays of the same view pitch: 1×N strips with no astigmatism (the idealised
# 1-D light field, Δ = 0), the same strips with the lenticular phone's Δ, and the N×N grid.
# For each, the predicted accommodation (the VSOTF's peak) of the whole plane, of vertical
# structure (the x band) and of horizontal structure (the y band).

# %%
strips = strip_layout(N, 3.0)
cases = {
    f"1x{N} HPO (Δ = 0)": (strips, strip_display(strips)),
    f"1x{N} lenticular phone": (strips, strip_display(strips, y_defocus_D=phone.y_defocus_D)),
    f"{N}x{N}": (lfjax.grid_layout(N, 3.0), None),
}
results = {name: orientation_through_focus(EYES, layout, lfjax.States.grid(ACC, DEPTHS),
                                           lfjax.Viewing(display=optics), spectrum=SPECTRUM,
                                           sampling=SAMPLING)
           for name, (layout, optics) in cases.items()}
rows = ["| display | band | " + " | ".join(f"depth {d:g} D" for d in DEPTHS) + " |",
        "|---|---|" + "---|" * len(DEPTHS)]
for name, r in results.items():
    for band in ("whole", "x", "y"):
        rows.append(f"| {name} | {band} | " + " | ".join(f"{v:.2f}" for v in r.peak_D(band).mean(0)) + " |")
display(Markdown("Predicted accommodation (D), mean of eyes:\n\n" + "\n".join(rows)))

# %%
import matplotlib.pyplot as plt

fig, axes = plt.subplots(1, len(results), figsize=(4 * len(results), 3.2), sharey=True)
for ax, (name, r) in zip(axes, results.items()):
    for band, colour in (("whole", "k"), ("x", "tab:blue"), ("y", "tab:orange")):
        ax.plot(r.accommodation_D, np.asarray(r.vsotf[("whole", "x", "y").index(band)])[:, -1].mean(0),
                color=colour, label=band)
    ax.axvline(DEPTHS[-1], color="0.6", ls=":")
    ax.set_title(f"{name}, depth {DEPTHS[-1]:g} D", fontsize=9)
    ax.set_xlabel("accommodation (D)")
axes[0].set_ylabel("VSOTF")
axes[0].legend()
fig.tight_layout()
plt.show()

# %% [markdown]
# ## Leakage
#
# Each view carries a copy of its neighbours' content with weight w, displaced by their
# parallax. The x band of the strips, their only depth cue, against w:

# %%
for w in (0.0, 0.5, 1.0):
    r = orientation_through_focus(EYES, strips, lfjax.States.grid(ACC, DEPTHS),
                                  lfjax.Viewing(display=strip_display(strips, leakage_weight=w)),
                                  spectrum=SPECTRUM, sampling=SAMPLING)
    peaks = ", ".join(f"{v:.2f}" for v in r.peak_D("x").mean(0))
    cutoffs = ", ".join(f"{v:.1f}" for v in r.cutoff_cpd("x").mean(0))
    print(f"w = {w:g}: x-band peaks {peaks} D, x cut-off at the peak {cutoffs} cpd")

# %% [markdown]
# ## The population answer (committed results)

# %%
folder = Path(lfjax.__file__).resolve().parents[1] / "benchmarks" / "studies" / "hpo_crosstalk"
study = json.loads((folder / "hpo.json").read_text())
lines = ["| layout | gain, whole | gain, x band | gain, y band |", "|---|---|---|---|"]
for name, row in study["rows"].items():
    if "gain_whole" in row:
        lines.append(f"| {name} | {np.mean(row['gain_whole']):.3f} | {np.mean(row['gain_x']):.3f} "
                     f"| {np.mean(row['gain_y']):.3f} |")
display(Markdown(f"{study['config']['n_eyes']} eyes, depths 0–4 D, CDP 2 D:\n\n" + "\n".join(lines)))
display(Image(filename=str(folder / "hpo_crosstalk.png")))
