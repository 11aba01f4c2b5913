# ---
# jupyter:
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Beyond the ideal display: lenslet diffraction, pixels and a real spectrum
#
# The paper models an ideal light-field display: every view fills a geometric subaperture
# of the pupil, every emitter is a point, and the light is V(λ)-weighted white. Its own
# limitations section calls display diffraction the most important thing left out. This
# notebook switches the three effects on one by one with `lfjax.studies.display_effects` and asks
# how the predicted accommodation and the MTF cut-off change, and whether lenslet
# diffraction changes the paper's 2×2 conclusion (2×2 views already drive accommodation to
# the rendered depth).
#
# The size is set by `LFJAX_NOTEBOOK_SIZE`: `small` (the committed outputs: the Thibos
# average eye, three layouts, three depths, 50 nm wavelength steps) or `tiny` (what
# `tests/display/test_lenslets.py` runs: 2×2 only, two depths, 1 D states, 150 nm steps, peaks from three states around the
# grid's instead of Newton; numbers meaningless). The full
# study: `benchmarks/studies/display_effects.py` (RESULTS §12) or `lfjax reproduce --display-effects`.
#
# `notebooks/display_effects.py` is this notebook as a plain script (jupytext percent
# format); the test checks that the two agree.

# %%
import os

import numpy as np
from IPython.display import Image, Markdown, display

import lfjax
from lfjax.studies import display_effects as de
from lfjax.display.lenslets import lenslets_for_layout
from lfjax.display.spectra import display_spectrum

SIZE = os.environ.get("LFJAX_NOTEBOOK_SIZE", "small")
if SIZE == "tiny":
    # two depths, 1 D states, 3 wavelengths; the sweep in the study's window, so that its
    # scenes reuse the study's compiled programs
    config = de.DisplayStudyConfig.quick(wavelength_step_nm=150.0, sweep_distances_mm=(400.0,),
                                         peak_method="local", depth_offsets_D=(0.0, 1.0),
                                         accommodation_step_D=1.0, sweep_window_D=1.0)
else:
    config = de.DisplayStudyConfig.quick(layouts=("2x2", "3x3", "4x4"),
                                         sweep_distances_mm=(30.0, 200.0, 400.0, 470.0))
eyes = lfjax.average_eye(config.pupil_diameter_mm)
print(SIZE, config)

# %% [markdown]
# ## The display's optics
#
# A lenslet array at distance z_m from the eye, a pixel panel at the gap z_0 behind it. For
# each layout `lenslets_for_layout` builds the array that puts n×n tangent views in the 3 mm
# pupil with its central depth plane (CDP) at 2 D. Each view is then the Fresnel pattern of
# its lenslet, magnified onto the pupil; the Fresnel number says how far from geometric
# it is (large: the paper's geometric subaperture).

# %%
for n in (2, 3, 4):
    array = lenslets_for_layout(n, 3.0, 2.0, config.display_distance_mm, f_number=config.f_number)
    optics = array.optics(config.pixel_pitch_mm, config.fill_factor)
    print(f"{n}x{n}: lenslet pitch {float(array.pitch_mm):.3f} mm, focal length "
          f"{float(array.focal_length_mm):.2f} mm, magnification {float(array.magnification):.2f}, "
          f"Fresnel number {float(array.fresnel_number(550.0)):.2f} at 550 nm, pixel "
          f"{float(optics.pixel_width_arcmin):.2f} arcmin")

# %% [markdown]
# ## The display's spectrum
#
# An OLED-like white (Gaussian R, G, B primaries, white-balanced to D65) weighted by V(λ),
# on only the wavelengths that carry weight.

# %%
import matplotlib.pyplot as plt

white = config.white_spectrum()
oled = display_spectrum("oled", "white", config.options, step_nm=10.0)
fig, ax = plt.subplots(figsize=(6, 3))
ax.stem(np.asarray(white.wavelengths_nm), np.asarray(white.weights), linefmt="C0-", markerfmt="C0o",
        label=f"V(λ) white ({white.n_wavelengths} λ)")
ax.stem(np.asarray(oled.wavelengths_nm), np.asarray(oled.weights), linefmt="C3-", markerfmt="C3s",
        label=f"OLED white ({oled.n_wavelengths} λ)")
ax.set_xlabel("wavelength (nm)")
ax.set_ylabel("spectral weight")
ax.legend()
fig.tight_layout()
plt.show()

# %% [markdown]
# ## The effects, one by one
#
# Steps are cumulative: ideal → + lenslet diffraction → + pixels → + the display's spectrum.

# %%
study = de.run_display_study(eyes, ["average"], config, progress=False)
sweep = de.lenslet_sweep(eyes, ["average"], config, progress=False)
display(Markdown(de.display_effects_markdown(study, sweep)))

# %%
names = de.save_display_figures(study, sweep, ".")
for name in names:
    display(Image(filename=name))

# %%
print(de.effects_table(study).round(3).to_string(index=False))

# %% [markdown]
# ## What this shows
#
# The table and figures above are the small run's numbers for the average eye only; the
# study on a population and every depth is in `benchmarks/results/12-display-effects.md`.
# Read the lenslet sweep from right to left: as the lenslets shrink the Fresnel number
# falls below 1 and the beams spread over the pupil; the cut-off frequency is what moves
# first, the accommodation prediction much later.
