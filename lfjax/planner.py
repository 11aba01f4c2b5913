"""Sampling planner: the cheapest sampling a scene needs, with the reasons printed.

"Model no more than a scene needs": the frequency step df fixes everything else in lfjax's
FFT path — the PSF field (60/df arcmin, which must hold the largest blur or it wraps),
the pupil sample spacing per wavelength (λ·df) and the window sizes (the whole OTF
support). The planner takes the largest df whose field holds the scene's blur (defocus of
every accommodation state incl. LCA, light-field displacements, diffraction of the
smallest subaperture, the eyes' own aberrations), checks that the smallest subaperture
still gets enough pupil samples, and reports the cost. Any choice can be overridden.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .layouts import Layout, open_pupil
from .options import ModelOptions
from .sampling import Sampling, blur_radius_arcmin, eye_slope_rad, wavelength_bands
from .spectral import make_spectrum


@dataclass(frozen=True)
class Plan:
    """A chosen sampling with its reasons.

    Attributes
    ----------
    sampling : Sampling to pass to the pipeline.
    blur_radius_arcmin : largest PSF radius the field must hold, arcmin.
    bands : wavelength bands and FFT sizes ((start, stop, n_fft), …).
    fft_work : relative FFT cost per (eye, state): Σ n_λ·n_sub·n_fft²·log2(n_fft).
    reasons : list of one-line explanations.
    """

    sampling: Sampling
    blur_radius_arcmin: float
    bands: tuple
    fft_work: float
    reasons: list = field(default_factory=list)

    def summary(self) -> str:
        """Printable explanation of the choice."""
        lines = [
            f"freq_step_cpd = {self.sampling.freq_step_cpd:.4g} cpd "
            f"(PSF field {self.sampling.field_arcmin:.1f} arcmin)",
            f"largest blur radius {self.blur_radius_arcmin:.1f} arcmin",
            "wavelength bands (start, stop, n_fft): " + ", ".join(map(str, self.bands)),
            f"relative FFT work per eye and state: {self.fft_work:.3g}",
        ]
        return "\n".join(lines + [f"- {r}" for r in self.reasons])


def plan_sampling(
    layout: Layout | None = None,
    pupil_diameter_mm: float = 3.0,
    cdp_D: float = 2.0,
    depths_D=(2.0,),
    accommodation_window_D: float = 1.0,
    wavelengths_nm=None,
    eyes_zernike_um=None,
    measured_pupil_mm: float = 3.0,
    options: ModelOptions = ModelOptions(),
    margin: float = 1.05,
    min_samples_per_subaperture: int = 16,
    wrap_tolerance: float = 1e-3,
    edge_width_samples: float = 0.25,
    freq_step_cpd: float | None = None,
) -> Plan:
    """Choose the frequency step for a scene (and say why).

    Parameters
    ----------
    layout : subapertures (default open pupil)
    pupil_diameter_mm, cdp_D : scene, mm and D
    depths_D : rendered depths, D
    accommodation_window_D : through-focus half-range around each depth, D
    wavelengths_nm : spectrum (default 400–700 nm / 10 nm)
    eyes_zernike_um : (n_eyes, n_modes) eyes whose aberrations add blur (optional)
    margin : field safety factor (≥ 1)
    min_samples_per_subaperture : smallest number of pupil samples across the smallest
        subaperture at the longest wavelength (phase and edge resolution)
    wrap_tolerance : spectral weight allowed to wrap (the most blurred wavelengths)
    freq_step_cpd : override; the plan then only reports (and raises if it aliases)
    """
    if margin < 1:
        raise ValueError(f"margin must be >= 1, got {margin}")
    layout = open_pupil(pupil_diameter_mm) if layout is None else layout
    spectrum = make_spectrum(wavelengths_nm, options)
    wl = np.asarray(spectrum.wavelengths_nm, float)
    weights = np.asarray(spectrum.weights, float)
    lca_all = np.asarray(spectrum.lca_D, float)
    order = np.argsort(-np.abs(lca_all))
    excluded = np.cumsum(weights[order]) < wrap_tolerance * weights.sum()
    lca = lca_all[order[~excluded]]
    depths = np.atleast_1d(np.asarray(depths_D, float))
    offsets = np.linspace(-accommodation_window_D, accommodation_window_D, 21)
    acc = np.clip(depths[:, None] + offsets[None, :], 0.0, None)
    defocus = (acc[..., None] - cdp_D + lca).ravel()
    mismatch = (acc[..., None] - depths[:, None, None] + lca).ravel()
    slope = 0.0
    if eyes_zernike_um is not None:
        slope = eye_slope_rad(np.asarray(eyes_zernike_um), measured_pupil_mm, pupil_diameter_mm)
    radius = blur_radius_arcmin(
        pupil_diameter_mm, np.asarray(layout.centres_mm), np.asarray(layout.diameters_mm),
        defocus, mismatch, float(wl.max()), slope,
    )
    reasons = []
    df_field = 30.0 / (radius * margin)
    reasons.append(
        f"field: blur reaches {radius:.1f} arcmin (defocus up to {np.abs(defocus).max():.2f} D "
        f"incl. LCA, view mismatch up to {np.abs(mismatch).max():.2f} D, eye slope "
        f"{slope * 3437.75:.1f} arcmin); ×{margin} margin → df ≤ {df_field:.3g} cpd"
    )
    d_min = float(np.min(np.minimum(np.asarray(layout.diameters_mm), pupil_diameter_mm)))
    df_samples = d_min / (wl.max() * 1e-6 * min_samples_per_subaperture) / (180.0 / math.pi)
    reasons.append(
        f"pupil sampling: ≥ {min_samples_per_subaperture} samples across the smallest "
        f"subaperture ({d_min:.3g} mm) at {wl.max():g} nm → df ≤ {df_samples:.3g} cpd"
    )
    chosen = min(df_field, df_samples)
    chosen = math.floor(chosen * 100.0) / 100.0  # round down to 0.01 cpd
    if freq_step_cpd is not None:
        if freq_step_cpd > df_field:
            raise ValueError(
                f"freq_step_cpd={freq_step_cpd} aliases: the scene's blur needs "
                f"freq_step_cpd <= {df_field:.3g} cpd"
            )
        reasons.append(f"user override: df = {freq_step_cpd} cpd")
        chosen = float(freq_step_cpd)
    else:
        reasons.append(f"chosen: the largest admissible step, rounded down: {chosen:.2f} cpd")
    sampling = Sampling(chosen, edge_width_samples=edge_width_samples)
    bands = wavelength_bands(wl, layout.window_diameter_mm, pupil_diameter_mm, sampling)
    work = sum(
        (b - a) * layout.n_subapertures * n**2 * math.log2(n) for a, b, n in bands
    )
    if np.any(np.diff(wl) > 20.0):
        reasons.append(
            "warning: wavelength steps over 20 nm under-sample LCA blur (Ravikumar et al. 2008)"
        )
    return Plan(sampling, float(radius), bands, float(work), reasons)


__all__ = ["Plan", "plan_sampling"]
