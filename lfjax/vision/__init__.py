"""What the eye sees and where it focuses: the host-side entry points.

:mod:`~lfjax.vision.focus` (through-focus curves and metrics at chosen states),
:mod:`~lfjax.vision.peaks` (accommodation peaks), :mod:`~lfjax.vision.prepare` (the
preparation seam every entry point and application shares: checks, states, sampling,
configuration, scene), :mod:`~lfjax.vision.psf` (PSFs and
OTF stacks), :mod:`~lfjax.vision.images` (retinal images), :mod:`~lfjax.vision.resolution`
(the perceivable cut-off of a display), :mod:`~lfjax.vision.orientation` (through-focus by
orientation band), :mod:`~lfjax.vision.claims` (the paper's
findings as checkable criteria: the registry of the claims declared in
:mod:`~lfjax.vision.claims_accommodation` and :mod:`~lfjax.vision.claims_resolution`, built
from :mod:`~lfjax.vision.claim_core`) and :mod:`~lfjax.vision.claim_margins` (how far a
planned spectrum's numbers may move, for the verdicts it could change).
"""

from lfjax.vision import claim_core, claim_margins, claims, claims_accommodation, claims_resolution, focus, images, orientation, peaks, prepare, psf, resolution
from lfjax.vision.focus import ThroughFocus, metrics_at, through_focus, through_focus_variants
from lfjax.vision.peaks import Peaks, accommodation_peaks

__all__ = ["claim_core", "claim_margins", "claims", "claims_accommodation", "claims_resolution", "focus", "images", "orientation", "peaks", "prepare", "psf", "resolution",
           "ThroughFocus", "metrics_at", "through_focus", "through_focus_variants", "Peaks",
           "accommodation_peaks"]
