"""Conventions and mathematics that know nothing of eyes or displays.

Units and angular conversions (:mod:`~lfjax.base.units`), Zernike polynomials
(:mod:`~lfjax.base.zernike`), the Fourier sampling grids and their aliasing guards
(:mod:`~lfjax.base.sampling`), the host grids of depths, accommodation states and wavelengths
(:mod:`~lfjax.base.grids`), pupil apertures and the Fresnel propagator
(:mod:`~lfjax.base.apertures`), array type aliases (:mod:`~lfjax.base.types`) and the
host-side helpers for atomic files and plain-text tables (:mod:`~lfjax.base.files`,
:mod:`~lfjax.base.tables`), the error a refused parameter raises
(:mod:`~lfjax.base.errors`), and compiled programs kept across processes
(:mod:`~lfjax.base.programs`). Nothing here imports any other part of lfjax.
"""

from lfjax.base import (
    apertures,
    errors,
    files,
    grids,
    programs,
    sampling,
    tables,
    types,
    units,
    zernike,
)

__all__ = ["apertures", "errors", "files", "grids", "programs", "sampling", "tables", "types",
           "units", "zernike"]
