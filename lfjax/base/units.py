"""Unit conventions and the only unit conversions in lfjax.

Conventions (used everywhere):

* pupil coordinates ``x`` (right), ``y`` (up) in mm, origin at the pupil centre, arrays ``[y, x]``;
* wavefront and Zernike coefficients in µm (OSA/ANSI, RMS-normalised);
* wavelengths in nm;
* depths, accommodation, defocus in dioptres (D = 1/m); 0 D is optical infinity;
* retinal position as visual angle in arcmin; spatial frequency in cycles per degree (cpd).

Sign: positive Zernike defocus c(2,0) means the eye focuses in front of the retina (myopic
relative to the object); the same sign is used for accommodation, LCA and light-field shifts.
"""

from __future__ import annotations

import math

import numpy as np

from lfjax.base.errors import ParameterError

ARCMIN_PER_RADIAN: float = 180.0 * 60.0 / math.pi
"""Visual angle: arcmin in one radian."""

DEGREES_PER_RADIAN: float = 180.0 / math.pi

RETINAL_UM_PER_ARCMIN: float = 4.85
"""Approximate retinal distance per arcmin of visual angle (µm), for display only.

Taken from a posterior nodal distance of 16.7 mm (0.291 mm per degree). No lfjax result
depends on it: all computations are in visual angle.
"""


MAX_DIOPTRES_D: float = 10.0
"""The nearest depth the model describes, D: rendered depths, a display's CDP and
accommodation states lie in [0, MAX_DIOPTRES_D] D (infinity to 10 cm). 10 D is about the
amplitude of accommodation of a young adult (Duane's norms: some 10 D at 20 years), so an
eye focused nearer is no eye the model's population (Thibos et al. 2002, adults) contains;
the accommodation's spherical-aberration slope (Cheng et al. 2004) is a linear fit over
smaller accommodations, and its extrapolation grows with the state. Beyond it the pipeline
still returns numbers, but they describe nothing: :func:`check_dioptres` refuses them."""


def check_dioptres(parameter: str, values, what: str = "depth", *, lowest: float = 0.0,
                   note: str = "") -> np.ndarray:
    """Host check of dioptric values (any shape): finite and in the model's range
    [``lowest``, :data:`MAX_DIOPTRES_D`] D; returns them as a float64 array.

    The one check of that range: every entry point, configuration and constructor that takes
    a depth, a CDP or an accommodation state calls it before any work. A refused value is a
    :class:`~lfjax.base.errors.ParameterError` naming ``parameter``, the range and the values
    outside it; ``what`` says what the values are ("rendered depth", "accommodation state"),
    ``note`` where they came from (appended to the message)."""
    try:
        v = np.asarray(values, float)
    except (TypeError, ValueError):
        raise ParameterError(parameter, "{%s} must be numbers in D, got {got!r}" % parameter,
                             got=values) from None
    extra = f" ({note})" if note else ""
    bad = ~np.isfinite(v)
    if np.any(bad):
        raise ParameterError(parameter, "{%s} must be finite, got {got}{extra}" % parameter,
                             got=v[bad].ravel().tolist()[:5], extra=extra)
    low, high = v < lowest, v > MAX_DIOPTRES_D
    if np.any(low) or np.any(high):
        outside = v[low | high].ravel()
        why = (f"0 D is optical infinity: a {what} cannot lie beyond it" if np.any(low)
               else f"nearer than {100.0 / MAX_DIOPTRES_D:g} cm is beyond the amplitude of "
                    "accommodation the model describes, lfjax.base.units.MAX_DIOPTRES_D")
        raise ParameterError(
            parameter, "{%s}: every %s must lie in the model's range [{lo:g}, {hi:g}] D (%s); "
                       "got {got}{extra}" % (parameter, what, why),
            lo=lowest, hi=MAX_DIOPTRES_D, got=[round(float(x), 9) for x in outside[:5]],
            extra=extra)
    return v


def dioptres_to_c20_um(defocus_D, pupil_diameter_mm):
    """Zernike defocus coefficient c(2,0) in µm for ``defocus_D`` dioptres over a pupil.

    .. math:: c_2^0 = d^2 D / (16\\sqrt{3})

    (Miyanishi et al., ``eq:diopter2um``; ANSI Z80.28). 1 D on a 3 mm pupil is 0.3248 µm.
    """
    return defocus_D * pupil_diameter_mm**2 / (16.0 * math.sqrt(3.0))


def c20_um_to_dioptres(c20_um, pupil_diameter_mm):
    """Inverse of :func:`dioptres_to_c20_um`: dioptres of defocus for c(2,0) in µm."""
    return c20_um * 16.0 * math.sqrt(3.0) / pupil_diameter_mm**2


def cpd_to_cycles_per_radian(freq_cpd):
    """Spatial frequency: cycles/degree → cycles/radian."""
    return freq_cpd * DEGREES_PER_RADIAN


def radians_to_arcmin(angle_rad):
    """Visual angle: radians → arcmin."""
    return angle_rad * ARCMIN_PER_RADIAN


def arcmin_to_radians(angle_arcmin):
    """Visual angle: arcmin → radians."""
    return angle_arcmin / ARCMIN_PER_RADIAN


def nm_to_mm(wavelength_nm):
    """Wavelength: nm → mm (pupil coordinates are in mm)."""
    return wavelength_nm * 1e-6


def field_arcmin_from_freq_step(freq_step_cpd):
    """Angular period (arcmin) of the PSF implied by a frequency step in cpd: 60 / df."""
    return 60.0 / freq_step_cpd


def format_bytes(n: float) -> str:
    """A size in bytes as a short human-readable string (binary units: KiB … TiB)."""
    if not math.isfinite(n):
        return "inf"
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def format_duration(seconds: float) -> str:
    """A duration in seconds as a short human-readable string (s, min, h or days)."""
    if not math.isfinite(seconds):
        return "inf"
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"


__all__ = [
    "format_bytes",
    "format_duration",
    "ARCMIN_PER_RADIAN",
    "DEGREES_PER_RADIAN",
    "RETINAL_UM_PER_ARCMIN",
    "MAX_DIOPTRES_D",
    "check_dioptres",
    "dioptres_to_c20_um",
    "c20_um_to_dioptres",
    "cpd_to_cycles_per_radian",
    "radians_to_arcmin",
    "arcmin_to_radians",
    "nm_to_mm",
    "field_arcmin_from_freq_step",
]

