"""Numerical sampling: one common frequency grid for every wavelength, and its guards.

The OTF of every (wavelength, subaperture, accommodation) is sampled on the same grid
``f = k · df`` (cpd, k an integer in FFT order). Per wavelength the pupil is sampled at
``dx(λ) = λ · df`` (mm, with df in cycles/radian), so the FFT of the pupil lands every
wavelength on that grid without interpolation. The PSF implied by the grid is periodic
with period (field) ``1/df`` = 60/df arcmin: the whole blur must fit inside it or it wraps.

A window holding a subaperture of diameter d at the shortest wavelength needs
``L ≥ 2 d / (λ_min df)`` samples (the autocorrelation support) plus the soft edges; an
n×n layout therefore needs windows about n times smaller than the open pupil.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.units import ARCMIN_PER_RADIAN, DEGREES_PER_RADIAN
from lfjax.base.zernike import zernike_basis_host

EDGE_EXTENT_SCALES = 6.0
"""Logistic edge profile is taken to extend this many scale lengths (e^-6 ≈ 0.25 %)."""


def next_fast_size(n: int) -> int:
    """Smallest even 2^a·3^b·5^c ≥ n (fast FFT sizes)."""
    n = max(int(n), 2)
    best = None
    p2 = 1
    while p2 < 2 * n:
        p3 = p2
        while p3 < 2 * n:
            p5 = p3
            while p5 < 2 * n:
                if p5 >= n and p5 % 2 == 0 and (best is None or p5 < best):
                    best = p5
                p5 *= 5
            p3 *= 3
        p2 *= 2
    return best


@dataclass(frozen=True)
class Sampling:
    """Frequency-grid sampling shared by all wavelengths (static under ``jit``).

    Attributes
    ----------
    freq_step_cpd : float, cpd
        Frequency step df. The PSF field (period) is 60/df arcmin.
    n_fft : int or None
        FFT size of the open-pupil window. ``None`` (default): the smallest fast size that
        holds the OTF support at the shortest wavelength. Subaperture windows scale with
        their diameter.
    edge_width_samples : float
        Scale of the logistic aperture edge, in pupil samples (anti-aliasing; keeps apertures
        differentiable in centre and diameter). The MTF bias of a soft edge is ∝ this scale
        over the pupil samples; 0.25 is on the speed/accuracy Pareto front
        (benchmarks/speed/speed_accuracy.png: VSOTF error 1.6e-4 against 4.3e-3 at 0.5).
    transform : "fft" or "mft"
        ``"fft"`` (default): pupil sampled at λ·df per wavelength, zero-padded FFT; the
        PSF is exactly periodic (wraps). ``"mft"``: one pupil grid of ``mft_pupil_samples``
        across the largest subaperture for every wavelength, matrix Fourier transform onto
        the common angular grid; the PSF is truncated at the field edge instead of wrapped.
    mft_pupil_samples : int
        Pupil samples across the MFT window (phase and edge resolution).
    """

    freq_step_cpd: float = 1.0
    n_fft: int | None = None
    edge_width_samples: float = 0.25
    transform: str = "fft"
    mft_pupil_samples: int = 64

    def __post_init__(self):
        if not (self.freq_step_cpd > 0 and math.isfinite(self.freq_step_cpd)):
            raise ParameterError("freq_step_cpd", "{freq_step_cpd} must be > 0 cpd, got {got}",
                                 got=self.freq_step_cpd)
        if self.n_fft is not None and (int(self.n_fft) != self.n_fft or self.n_fft < 8):
            raise ValueError(f"n_fft must be an integer >= 8, got {self.n_fft}")
        if self.transform not in ("fft", "mft"):
            raise ValueError(f"transform must be 'fft' or 'mft', got {self.transform!r}")
        if int(self.mft_pupil_samples) != self.mft_pupil_samples or self.mft_pupil_samples < 16:
            raise ValueError(f"mft_pupil_samples must be an integer >= 16, got {self.mft_pupil_samples}")
        if not (0.05 <= self.edge_width_samples <= 4.0):
            raise ValueError(
                f"edge_width_samples must be in 0.05–4 pupil samples, got {self.edge_width_samples}"
            )

    @property
    def field_arcmin(self) -> float:
        """Period of the PSF, arcmin."""
        return 60.0 / self.freq_step_cpd

    def freq_step_cycles_per_radian(self) -> float:
        return self.freq_step_cpd * DEGREES_PER_RADIAN

    def window_size(
        self, window_diameter_mm: float, min_wavelength_nm: float, pupil_diameter_mm: float
    ) -> int:
        """FFT size for a window holding ``window_diameter_mm`` at the shortest wavelength."""
        samples = window_diameter_mm / (min_wavelength_nm * 1e-6 * self.freq_step_cycles_per_radian())
        needed = 2.0 * (samples + 2.0 * EDGE_EXTENT_SCALES * self.edge_width_samples) + 1.0
        if self.n_fft is None:
            return next_fast_size(int(math.ceil(needed)))
        if window_diameter_mm >= pupil_diameter_mm - 1e-12:
            size = int(self.n_fft)
        else:  # subapertures scale the user's open-pupil size by their diameter
            size = next_fast_size(int(math.ceil(self.n_fft * window_diameter_mm / pupil_diameter_mm)))
        if size < needed - 4.0 * EDGE_EXTENT_SCALES * self.edge_width_samples:
            raise ValueError(
                f"n_fft={self.n_fft} cannot hold the OTF of a {window_diameter_mm:g} mm aperture at "
                f"{min_wavelength_nm:g} nm with freq_step_cpd={self.freq_step_cpd:g}: need n_fft >= "
                f"{int(math.ceil(needed))} (or a larger freq_step_cpd)"
            )
        return size

    def pixel_arcmin(self, n_fft: int) -> float:
        """Angular pixel of the PSF on a window of ``n_fft`` samples, arcmin."""
        return self.field_arcmin / n_fft


def wavelength_bands(
    wavelengths_nm, window_diameter_mm: float, pupil_diameter_mm: float, sampling: Sampling,
    max_bands: int = 3,
) -> tuple[tuple[int, int, int], ...]:
    """Split increasing wavelengths into ≤ ``max_bands`` contiguous bands with their FFT size.

    The OTF support shrinks as 1/λ, so long wavelengths need smaller windows. Returns
    ``((start, stop, n_fft), ...)`` (slices of the wavelength axis) minimising Σ n_λ·n_fft²;
    each band's OTF is embedded exactly (zero padding in frequency) into the largest.
    A user-fixed ``sampling.n_fft`` gives one band.
    """
    wl = np.asarray(wavelengths_nm, float).reshape(-1)
    sizes = [sampling.window_size(window_diameter_mm, w, pupil_diameter_mm) for w in wl]
    n = wl.size
    if sampling.n_fft is not None or n == 1 or max_bands <= 1:
        return ((0, n, max(sizes)),)
    best, best_cost = None, None
    # wavelengths increase, so each band's size is that of its first (shortest) wavelength
    cuts_options = [()]
    if max_bands >= 2:
        cuts_options += [(i,) for i in range(1, n)]
    if max_bands >= 3:
        cuts_options += [(i, j) for i in range(1, n) for j in range(i + 1, n)]
    for cuts in cuts_options:
        edges = (0,) + cuts + (n,)
        bands = tuple((a, b, max(sizes[a:b])) for a, b in zip(edges[:-1], edges[1:]))
        cost = sum((b - a) * size**2 * math.log2(size) for a, b, size in bands)
        if best_cost is None or cost < best_cost * (1 - 1e-9):
            best, best_cost = bands, cost
    return best


def blur_radius_arcmin(
    pupil_diameter_mm: float,
    centres_mm: np.ndarray,
    diameters_mm: np.ndarray,
    relative_defocus_D: np.ndarray,
    lf_mismatch_D: np.ndarray,
    max_wavelength_nm: float,
    aberration_slope_rad: float = 0.0,
    display=None,
) -> float:
    """Largest distance (arcmin) from the origin that the rendered PSF reaches.

    Geometric optics plus diffraction: subaperture n at defocus D (eye relative to the
    CDP, incl. LCA) images to a disc of radius |D| d_n/2 centred at −(D − D_lf) p_n, where
    D_lf = (depth − CDP) is the display's shift; three Airy radii of the smallest
    subaperture are added, and the eye's largest aberration ray angle.

    A real display (``display``, :class:`lfjax.display.lenslets.DisplayOptics`) adds: with lenslet
    diffraction, beams that may fill the pupil (defocus blur over the pupil, not the
    subaperture) — their angular spread needs nothing more, because Fresnel propagation
    multiplies the aperture's angular spectrum by a unit-modulus factor, so a diffracted
    beam holds the angles the geometric subaperture's Airy term already bounds; finite
    pixels, half the emitter's diagonal.
    """
    centres = np.asarray(centres_mm, float).reshape(-1, 2)
    diam = np.minimum(np.asarray(diameters_mm, float).reshape(-1), pupil_diameter_mm)
    dist = np.minimum(np.hypot(centres[:, 0], centres[:, 1]), 0.5 * pupil_diameter_mm)
    d = np.abs(np.asarray(relative_defocus_D, float)).max(initial=0.0)
    mism = np.abs(np.asarray(lf_mismatch_D, float)).max(initial=0.0)
    beam = diam
    extra = 0.0
    if display is not None:
        if display.fills_pupil:  # diffracted beams, or strips spanning the pupil along y
            beam = np.full_like(diam, pupil_diameter_mm)
        extra = float(display.pixel_width_arcmin) / math.sqrt(2.0) / ARCMIN_PER_RADIAN
        # a lenticular beam's own defocus along y (lfjax.display.lenticular) adds to the eye's
        y_defocus = 0.0 if display.y_defocus_D is None else float(display.y_defocus_D)
        if y_defocus:
            d = max(d, np.abs(np.asarray(relative_defocus_D, float) + y_defocus).max(initial=0.0))
        # the lenslets' own aberration (lfjax.display.aberrations): its largest ray angle
        extra += float(display.aberration_slope_rad(diam))
    geometric = (mism * dist + d * 0.5 * beam).max() * 1e-3  # rad (D in 1/m, mm → m)
    airy = 3.0 * 1.22 * max_wavelength_nm * 1e-6 / diam.min()
    return (geometric + airy + aberration_slope_rad + extra) * ARCMIN_PER_RADIAN


class AliasingError(ValueError):
    """The frequency sampling's PSF field cannot hold the blur: the PSF would wrap.

    Attributes
    ----------
    freq_step_cpd : the step that was refused, cpd
    max_freq_step_cpd : the largest step whose field holds the blur, cpd (what to use)
    radius_arcmin : the blur's radius, arcmin
    """

    def __init__(self, message: str, freq_step_cpd: float, max_freq_step_cpd: float,
                 radius_arcmin: float):
        super().__init__(message)
        self.freq_step_cpd = float(freq_step_cpd)
        self.max_freq_step_cpd = float(max_freq_step_cpd)
        self.radius_arcmin = float(radius_arcmin)


def finer_step(err: AliasingError, current: float) -> float:
    """Next frequency step (cpd) to try after an aliasing error: the largest safe step it
    carries, rounded down to 0.05 cpd (or 90 % of ``current`` if that rounding would not
    shrink it). The study and the sweep both retry with it."""
    step = math.floor(err.max_freq_step_cpd * 20.0 + 1e-9) / 20.0
    return step if 0 < step < current else round(current * 0.9, 6)


def check_field(sampling: Sampling, radius_arcmin: float, what: str) -> None:
    """Raise :class:`AliasingError` if the PSF of radius ``radius_arcmin`` would wrap in the
    periodic field."""
    half = 0.5 * sampling.field_arcmin
    if radius_arcmin > half:
        max_df = 30.0 / radius_arcmin
        raise AliasingError(
            f"sampling too coarse for the requested defocus (aliasing): freq_step_cpd="
            f"{sampling.freq_step_cpd:g} gives a PSF field of ±{half:.1f} arcmin but {what} "
            f"reaches {radius_arcmin:.1f} arcmin; use freq_step_cpd <= {max_df:.3g}",
            sampling.freq_step_cpd, max_df, radius_arcmin,
        )


def frequencies_cpd(n_fft: int, freq_step_cpd: float):
    """Frequencies (cpd) of an FFT-order axis of ``n_fft`` samples."""
    return jnp.asarray(np.fft.fftfreq(n_fft, 1.0 / n_fft) * freq_step_cpd)


def half_frequencies_cpd(n_fft: int, freq_step_cpd: float):
    """Frequencies (cpd) of the non-negative half axis (rfft layout, n_fft//2 + 1 samples)."""
    return jnp.asarray(np.fft.rfftfreq(n_fft, 1.0 / n_fft) * freq_step_cpd)


EYE_BLOCK = 1024
"""Eyes whose wavefronts the host-side guards evaluate at once (memory ∝ the block)."""


def eye_slope_rad(zernike_um: np.ndarray, measured_pupil_mm: float, pupil_diameter_mm: float) -> float:
    """Largest wavefront slope (ray angle, rad) of eyes inside the calculation pupil (host)."""
    z = np.asarray(zernike_um, float).reshape(-1, np.shape(zernike_um)[-1]).copy()
    z[:, :3] = 0.0  # tilt is a uniform shift, accounted by the user's choice of eye data
    n = 48
    r_cal = 0.5 * pupil_diameter_mm
    r_meas = 0.5 * measured_pupil_mm
    t = np.linspace(-r_cal, r_cal, n)
    xx, yy = np.meshgrid(t, t)
    inside = xx**2 + yy**2 <= r_cal**2
    basis = zernike_basis_host(z.shape[1], xx / r_meas, yy / r_meas)
    h = t[1] - t[0]
    slope = 0.0
    # blocks of eyes: the wavefronts and their gradients take ~90 KB per eye, so a whole
    # population at once would grow with it (9 GB for 100,000 eyes)
    for first in range(0, z.shape[0], EYE_BLOCK):
        w = np.tensordot(z[first:first + EYE_BLOCK], basis, axes=([1], [0]))  # µm
        gy, gx = np.gradient(w, h, axis=(1, 2))
        slope = max(slope, float(np.hypot(gx, gy)[:, inside].max(initial=0.0)))  # µm/mm
    return slope * 1e-3  # rad


__all__ = [
    "AliasingError",
    "Sampling",
    "next_fast_size",
    "wavelength_bands",
    "blur_radius_arcmin",
    "check_field",
    "finer_step",
    "eye_slope_rad",
    "frequencies_cpd",
    "half_frequencies_cpd",
]
