"""What the eye sees and where it focuses: the host-side entry points.

:mod:`~lfjax.vision.focus` (through-focus curves and metrics at chosen states),
:mod:`~lfjax.vision.peaks` (accommodation peaks), :mod:`~lfjax.vision.prepare` (the
preparation seam every entry point and application shares: checks, states, sampling,
configuration, scene), :mod:`~lfjax.vision.psf` (PSFs and
OTF stacks), :mod:`~lfjax.vision.images` (retinal images), :mod:`~lfjax.vision.resolution`
(the perceivable cut-off of a display), :mod:`~lfjax.vision.orientation` (through-focus by
orientation band) and :mod:`~lfjax.vision.claims` (the paper's
findings as checkable criteria).
"""

from lfjax.vision import claims, focus, images, orientation, peaks, prepare, psf, resolution
from lfjax.vision.focus import ThroughFocus, metrics_at, through_focus, through_focus_variants
from lfjax.vision.peaks import Peaks, accommodation_peaks

__all__ = ["claims", "focus", "images", "orientation", "peaks", "prepare", "psf", "resolution",
           "ThroughFocus", "metrics_at", "through_focus", "through_focus_variants", "Peaks",
           "accommodation_peaks"]
