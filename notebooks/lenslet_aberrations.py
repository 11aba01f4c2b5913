# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lenslet aberrations
#
# A lenslet is a lens: it has spherical aberration from its focal length, aperture, index and
# shape, and for a point seen off the display's normal also astigmatism, field curvature and
# coma. Each view carries its lenslet's wavefront error, magnified onto the view in the pupil
# (`lfjax.display.aberrations`; the model and its checks against exact ray traces:
# RESULTS §28). This notebook takes the near-eye preset's own plano-convex lenslets and asks
# how much their aberration moves the predicted accommodation and the perceivable resolution.
#
# The size is set by `LFJAX_NOTEBOOK_SIZE`: `small` (the committed outputs: two eyes, the CDP
# and ±1 D) or `tiny` (what `tests/display/test_aberrations.py` runs: the average eye, the
# CDP, a coarse grid; numbers meaningless). The population answer:
# `benchmarks/studies/lenslet_aberrations.py`, whose committed results close the notebook.

# %%
import os
from pathlib import Path

import numpy as np
from IPython.display import Image, Markdown, display

import lfjax
from lfjax.display.aberrations import LensletAberration, panel_aberration
from lfjax.display.panel import near_eye_microdisplay
from lfjax.vision.resolution import perceivable_cutoff_at_peak

SIZE = os.environ.get("LFJAX_NOTEBOOK_SIZE", "small")
panel = near_eye_microdisplay()
cdp = float(panel.cdp_D)
if SIZE == "tiny":
    EYES, DEPTHS, OFFSETS = lfjax.average_eye(panel.pupil_diameter_mm), [cdp], [-0.5, 0.0, 0.5]
    SAMPLING = lfjax.Sampling(0.5)  # coarse (the aliasing guard's limit): the test only runs the cells
else:
    EYES, DEPTHS, OFFSETS = lfjax.sample_eyes(0, 2), [cdp - 1.0, cdp, cdp + 1.0], np.arange(-1.5, 1.501, 0.25)
    SAMPLING = None  # planned for the most aberrated case
FIELDS_DEG = (0.0, 10.0)
print(f"near-eye preset: {panel.n_views_per_side()}x{panel.n_views_per_side()} views, lenslets "
      f"f = {float(panel.focal_length_mm):.3f} mm, aperture {float(panel.aperture_mm):.3f} mm, "
      f"CDP {cdp:.2f} D")
for theta in FIELDS_DEG:
    ab = panel_aberration(panel, field_angle_deg=theta)
    print(f"plano-convex n = 1.5, {theta:g}° off axis: W040 {float(ab.spherical_um):.3f}, "
          f"W131 {float(ab.coma_um):.3f}, W222 {float(ab.astigmatism_um):.3f}, "
          f"W220 {float(ab.field_curvature_um):.3f} µm at the view's rim")

# %% [markdown]
# ## The wavefront over one view
#
# On axis only the spherical term is left; 10° off axis astigmatism and field curvature
# dominate (coma's mean tilt is removed: every view of the point shifts alike, a distortion
# the renderer calibrates out).

# %%
import matplotlib.pyplot as plt

u = np.linspace(-1.0, 1.0, 101)
uu, vv = np.meshgrid(u, u)
inside = uu**2 + vv**2 <= 1.0
fig, axes = plt.subplots(1, len(FIELDS_DEG), figsize=(4.2 * len(FIELDS_DEG), 3.4))
for ax, theta in zip(axes, FIELDS_DEG):
    w = np.asarray(panel_aberration(panel, field_angle_deg=theta).wavefront_um(uu, vv, 1.0))
    im = ax.imshow(np.where(inside, w, np.nan), extent=(-1, 1, -1, 1), origin="lower", cmap="RdBu_r")
    ax.set_title(f"{theta:g}° off axis", fontsize=9)
    ax.set_xlabel("x / view radius")
    fig.colorbar(im, ax=ax, label="µm")
axes[0].set_ylabel("y / view radius")
fig.tight_layout()
plt.show()

# %% [markdown]
# ## Through focus, with and without the lenslets' aberration
#
# The preset's views, lenslet diffraction and emitters, 550 nm; one sampling for all cases,
# planned for the most aberrated one, so that the cases differ only in the aberration (its
# coefficients are data: one compiled program serves the three).

# %%
layout = panel.layout()
spectrum = lfjax.make_spectrum([550.0])
cases = {"no aberration": LensletAberration()}  # zeros: the aberration-free beam, bit for bit
cases.update({f"plano-convex, {t:g}°": panel_aberration(panel, field_angle_deg=t) for t in FIELDS_DEG})
sampling, rows = SAMPLING, ["| lenslets | " + " | ".join(f"depth {d:.2f} D" for d in DEPTHS) + " |",
                        "|---|" + "---|" * len(DEPTHS)]
for name in reversed(list(cases)):  # the most aberrated first: its sampling holds the others
    display_optics = panel.optics().with_aberration(cases[name])
    tf = lfjax.through_focus(EYES, layout, lfjax.States.around(DEPTHS, OFFSETS),
                             lfjax.Viewing(pupil_diameter_mm=panel.pupil_diameter_mm, cdp_D=cdp, display=display_optics),
                             spectrum=spectrum, sampling=sampling,
                             peaks=lfjax.PeakOptions(metrics=("vsotf",)))
    sampling = tf.sampling
    acc = np.asarray(tf.continuous_accommodation_D()).mean(0)
    cut = np.asarray(perceivable_cutoff_at_peak(tf, panel), float).mean(0)
    rows.insert(2, f"| {name} | " + " | ".join(f"{a:.2f} D, {c:.2f} cpd" for a, c in zip(acc, cut)) + " |")
display(Markdown("Predicted accommodation and perceivable cut-off (mean of the eyes):\n\n" + "\n".join(rows)))

# %% [markdown]
# ## The population answer (committed results)

# %%
folder = Path(lfjax.__file__).resolve().parents[1] / "benchmarks" / "studies" / "lenslet_aberrations"
report = (folder / "REPORT.md").read_text()
thresholds = report[report.index("| panel | scan |"):].split("\n\n")[0]
display(Markdown("Where the population's median moves (from `REPORT.md`):\n\n" + thresholds))
display(Image(filename=str(folder / "lenslet_aberrations.png")))
