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

ARCMIN_PER_RADIAN: float = 180.0 * 60.0 / math.pi
"""Visual angle: arcmin in one radian."""

DEGREES_PER_RADIAN: float = 180.0 / math.pi

RETINAL_UM_PER_ARCMIN: float = 4.85
"""Approximate retinal distance per arcmin of visual angle (µm), for display only.

Taken from a posterior nodal distance of 16.7 mm (0.291 mm per degree). No lfjax result
depends on it: all computations are in visual angle.
"""


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
    "dioptres_to_c20_um",
    "c20_um_to_dioptres",
    "cpd_to_cycles_per_radian",
    "radians_to_arcmin",
    "arcmin_to_radians",
    "nm_to_mm",
    "field_arcmin_from_freq_step",
]

