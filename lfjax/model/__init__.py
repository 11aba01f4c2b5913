"""The model's data: eyes, modelling options and parameters, spectra and view layouts.

Populations of aberrated eyes (:mod:`~lfjax.model.eyes`), the modelling choices and the
differentiable physical constants (:mod:`~lfjax.model.options`), the eye's spectral
weighting, chromatic aberration and Stiles–Crawford tables (:mod:`~lfjax.model.spectral`),
subaperture layouts (:mod:`~lfjax.model.layouts`; lenticular strips,
:mod:`~lfjax.model.strips`), their JSON files
(:mod:`~lfjax.model.layout_files`) and drawings (:mod:`~lfjax.model.layout_plots`).
Imports only :mod:`lfjax.base`.
"""

from lfjax.model import eyes, layout_files, layout_plots, layouts, options, spectral, strips

__all__ = ["eyes", "layout_files", "layout_plots", "layouts", "options", "spectral", "strips"]
