"""Display studies: the ideal display against a real one.

:mod:`~lfjax.studies.display_effects` (lenslet diffraction, pixels and real spectra on the
paper's layouts), :mod:`~lfjax.studies.array_views` (a whole lenslet array against the
idealised views), :mod:`~lfjax.studies.tradeoff` (the spatio-angular trade-off of a panel)
and :mod:`~lfjax.studies.hpo` (horizontal-parallax-only views and cross-talk).
"""

from lfjax.studies import array_views, display_effects, hpo, tradeoff

__all__ = ["array_views", "display_effects", "hpo", "tradeoff"]
