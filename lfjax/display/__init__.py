"""The display: lenslet optics, the panel as a maker builds it, and its spectra.

:mod:`~lfjax.display.lenslets` holds the display optics the kernel takes (lenslet
diffraction, pixel blur); :mod:`~lfjax.display.aberrations` the lenslets' own wavefront
error each view carries; :mod:`~lfjax.display.panel` derives a layout, a central depth
plane and those optics from a panel's geometry; :mod:`~lfjax.display.spectra` gives the
emission spectra of display primaries; :mod:`~lfjax.display.lenticular` the lenticular
(horizontal-parallax-only) views and the leakage between views. Imports only :mod:`lfjax.base` and :mod:`lfjax.model`.
"""

from lfjax.display import aberrations, lenslets, lenticular, panel, spectra
from lfjax.display.aberrations import LensletAberration, lenslet_aberration, panel_aberration
from lfjax.display.lenslets import DisplayOptics, LensletArray, ideal_display
from lfjax.display.panel import Panel, near_eye_microdisplay, phone_panel
from lfjax.display.spectra import DisplayPrimaries, display_primaries, display_spectrum

__all__ = ["aberrations", "lenslets", "lenticular", "panel", "spectra", "LensletAberration",
           "lenslet_aberration", "panel_aberration", "DisplayOptics", "LensletArray", "ideal_display",
           "Panel", "near_eye_microdisplay", "phone_panel", "DisplayPrimaries",
           "display_primaries", "display_spectrum"]
