"""Display studies: the ideal display against a real one.

:mod:`~lfjax.studies.display_effects` (lenslet diffraction, pixels and real spectra on the
paper's layouts), :mod:`~lfjax.studies.array_views` (a whole lenslet array against the
idealised views) and :mod:`~lfjax.studies.tradeoff` (the spatio-angular trade-off of a panel).
"""

from lfjax.studies import array_views, display_effects, tradeoff

__all__ = ["array_views", "display_effects", "tradeoff"]
