"""What a careful user would write instead of lfjax (issue #5): the ISETBio-style pipeline.

Plain numpy/scipy, float64, one monochromatic PSF at a time — the way an ISETBio-based
light-field study is built (the paper's own study customised ISETBio's ``wvfCompute``):

for each eye, layout, rendered depth, accommodation state, wavelength and subaperture:
  1. pupil function on its own grid (N × N samples at a fixed spacing dx, so the PSF
     sampling λ/(N·dx) differs by wavelength): circ(pupil) × circ(subaperture) (hard
     edges, as ISETBio) × Stiles–Crawford 10^(−ρ r²) × exp(−i 2π W/λ), W = the eye's
     Zernike wavefront + defocus (accommodation − CDP + LCA) + accommodation SA;
  2. PSF = |FFT|² (``scipy.fft``, all cores), scaled to the energy the pupil transmits;
  3. resampled (cubic spline, ``scipy.ndimage.map_coordinates``) onto a common angular
     grid, displaced in the same step by the rendered depth's view shift
     Δθ_n = (D_r − D_CDP)(p_n, q_n) — recomputed for every depth, nothing reused;
then Σ_n Σ_λ V(λ)·PSF → OTF (FFT, OTF(0) = 1) → VSOTF = Σ NCSF·Re OTF / Σ NCSF·Re OTF_DL
(Watson & Ahumada 2005 NCSF with the oblique effect, full frequency plane; OTF_DL: the same
layout, zero monochromatic aberrations, focused and rendered at the CDP, SA and LCA kept —
the paper's reference). Predicted accommodation = the state of largest VSOTF.

The one concession to speed a careful user makes: the Zernike basis on the (fixed) pupil
grid is computed once and reused (ISETBio recomputes it for every call).

Model constants (LCA, SCE ρ(λ), V(λ) weights, accommodation SA) are taken from lfjax so
the two pipelines model the same eye; everything numerical is written here from scratch.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
from scipy.ndimage import map_coordinates

ARCMIN_PER_RAD = 180.0 * 60.0 / math.pi


# ----------------------------------------------------------------------------- Zernike (own)


def ansi_nm(j: int) -> tuple[int, int]:
    n = int(math.ceil((-3.0 + math.sqrt(9.0 + 8.0 * j)) / 2.0))
    return n, 2 * j - n * (n + 2)


def zernike_ansi(j: int, rho: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """OSA/ANSI RMS-normalised Zernike Z_j (not masked), polar form."""
    n, m = ansi_nm(j)
    ma = abs(m)
    radial = np.zeros_like(rho)
    for s in range((n - ma) // 2 + 1):
        c = (-1) ** s * math.factorial(n - s) / (
            math.factorial(s) * math.factorial((n + ma) // 2 - s) * math.factorial((n - ma) // 2 - s)
        )
        radial = radial + c * rho ** (n - 2 * s)
    norm = math.sqrt(2.0 * (n + 1) / (1.0 + (m == 0)))
    ang = np.cos(m * theta) if m >= 0 else np.sin(ma * theta)
    return norm * radial * ang


# ----------------------------------------------------------------------------- configuration


@dataclass
class NaiveConfig:
    pupil_diameter_mm: float = 3.0
    measured_pupil_mm: float = 3.0
    cdp_D: float = 2.0
    n_pupil_grid: int = 384          # N: samples of the pupil-plane grid (FFT size)
    dx_mm: float = 0.01833           # pupil sample spacing (same at every wavelength)
    common_pixel_arcmin: float = 60.0 / 144
    common_n: int = 144              # common angular grid, zero angle at index n//2
    spline_order: int = 3
    timers: dict = field(default_factory=lambda: {"pupil": 0.0, "fft": 0.0, "resample": 0.0,
                                                  "otf+metric": 0.0})
    n_psf: int = 0

    @property
    def freq_step_cpd(self) -> float:
        return 60.0 / (self.common_pixel_arcmin * self.common_n)


class PupilGrid:
    """Fixed pupil grid with the Zernike bases cached (eye radius, pupil radius)."""

    def __init__(self, cfg: NaiveConfig, n_modes: int):
        n, dx = cfg.n_pupil_grid, cfg.dx_mm
        x = (np.arange(n) - n // 2) * dx
        self.xx, self.yy = np.meshgrid(x, x)  # [y, x]
        self.r2 = self.xx**2 + self.yy**2
        r_meas = 0.5 * cfg.measured_pupil_mm
        r_pup = 0.5 * cfg.pupil_diameter_mm
        rho_m = np.sqrt(self.r2) / r_meas
        th = np.arctan2(self.yy, self.xx)
        self.pupil = self.r2 <= r_pup**2
        # basis only where the pupil is open (the rest never enters the field)
        idx = self.pupil
        self.basis = np.stack([zernike_ansi(j, rho_m[idx], th[idx]) for j in range(n_modes)])
        rho_p = np.sqrt(self.r2[idx]) / r_pup
        self.z20 = zernike_ansi(4, rho_p, th[idx])
        self.z40 = zernike_ansi(12, rho_p, th[idx])


def elemental_psf(cfg: NaiveConfig, grid: PupilGrid, coeffs_um, wavelength_nm, defocus_D, c40_um,
                  rho_sce, centre_mm, diameter_mm):
    """One monochromatic subaperture PSF on its own grid: (density per arcmin², pixel arcmin)."""
    t0 = time.perf_counter()
    idx = grid.pupil
    sub = (grid.xx[idx] - centre_mm[0]) ** 2 + (grid.yy[idx] - centre_mm[1]) ** 2 <= (0.5 * diameter_mm) ** 2
    c20 = defocus_D * cfg.pupil_diameter_mm**2 / (16.0 * math.sqrt(3.0))
    w = coeffs_um @ grid.basis + c20 * grid.z20 + c40_um * grid.z40  # µm on open samples
    amp = sub * 10.0 ** (-rho_sce * grid.r2[idx])
    field_ = np.zeros(grid.r2.shape, np.complex128)
    field_[idx] = amp * np.exp(-2j * np.pi * w / (wavelength_nm * 1e-3))
    energy = np.sum(amp**2) * cfg.dx_mm**2  # mm², transmitted
    t1 = time.perf_counter()
    spec = scipy.fft.fftshift(scipy.fft.fft2(scipy.fft.ifftshift(field_), workers=os.cpu_count()))
    psf = spec.real**2 + spec.imag**2
    t2 = time.perf_counter()
    pixel = wavelength_nm * 1e-6 / (cfg.n_pupil_grid * cfg.dx_mm) * ARCMIN_PER_RAD
    density = psf * (energy / psf.sum()) / pixel**2
    cfg.timers["pupil"] += t1 - t0
    cfg.timers["fft"] += t2 - t1
    cfg.n_psf += 1
    return density, pixel


def resample(cfg: NaiveConfig, density, pixel_arcmin, shift_arcmin):
    """Cubic-spline resampling onto the common grid, displaced by ``shift_arcmin`` (x, y)."""
    t0 = time.perf_counter()
    k = (np.arange(cfg.common_n) - cfg.common_n // 2) * cfg.common_pixel_arcmin
    n = density.shape[0]
    cx = (k - shift_arcmin[0]) / pixel_arcmin + n // 2
    cy = (k - shift_arcmin[1]) / pixel_arcmin + n // 2
    yy, xx = np.meshgrid(cy, cx, indexing="ij")
    out = map_coordinates(density, [yy, xx], order=cfg.spline_order, mode="constant", cval=0.0)
    cfg.timers["resample"] += time.perf_counter() - t0
    return out * cfg.common_pixel_arcmin**2  # samples (energy per common pixel)


def polychromatic_psf(cfg, grid, coeffs_um, accommodation_D, depth_D, layout, spectrum):
    """Σ_n Σ_λ w_λ PSF_{λ,n}(θ − Δθ_n) on the common grid (energy units)."""
    wl, wts, lca, rho, c40 = spectrum
    total = np.zeros((cfg.common_n, cfg.common_n))
    centres, diameters = layout
    for i in range(len(wl)):
        for c, d in zip(centres, diameters):
            dens, pix = elemental_psf(cfg, grid, coeffs_um, wl[i],
                                      accommodation_D - cfg.cdp_D + lca[i],
                                      c40(accommodation_D), rho[i], c, d)
            shift = (depth_D - cfg.cdp_D) * np.asarray(c) * 1e-3 * ARCMIN_PER_RAD  # arcmin
            total += wts[i] * resample(cfg, dens, pix, shift)
    return total


def ncsf_full_plane(cfg: NaiveConfig):
    """Watson & Ahumada (2005) NCSF with the oblique effect on the full FFT-order plane."""
    f1 = np.fft.fftfreq(cfg.common_n, 1.0 / cfg.common_n) * cfg.freq_step_cpd
    fx, fy = np.meshgrid(f1, f1)
    f = np.hypot(fx, fy)
    base = 373.08 * (1.0 / np.cosh((f / 4.1726) ** 0.7786) - 0.8493 / np.cosh(f / 1.3625))
    with np.errstate(invalid="ignore", divide="ignore"):
        sin2 = np.where(f > 0, (2 * fx * fy / np.where(f > 0, f * f, 1.0)) ** 2, 0.0)
    oblique = np.where(f <= 3.481, 1.0, 1.0 - (1.0 - np.exp(-(f - 3.481) / 13.57149)) * sin2)
    return base * oblique


def otf_of(cfg: NaiveConfig, psf):
    otf = scipy.fft.fft2(scipy.fft.ifftshift(psf), workers=os.cpu_count())
    return otf / otf[0, 0]


def through_focus_naive(cfg, coeffs_um, n_modes, layout, depths_D, accommodation_D, spectrum,
                        window_D=None):
    """VSOTF (n_depth, n_acc) and predicted accommodation (n_depth,) — nothing reused.

    ``window_D``: compute only the states within ±window_D of each rendered depth (the
    others are NaN), as the paper's study does."""
    grid = PupilGrid(cfg, n_modes)
    ncsf = ncsf_full_plane(cfg)
    # reference: aberration-free, focused and rendered at the CDP, same layout
    ref_psf = polychromatic_psf(cfg, grid, np.zeros(n_modes), cfg.cdp_D, cfg.cdp_D, layout, spectrum)
    t0 = time.perf_counter()
    ref = np.sum(ncsf * otf_of(cfg, ref_psf).real)
    cfg.timers["otf+metric"] += time.perf_counter() - t0
    vs = np.zeros((len(depths_D), len(accommodation_D)))
    for a, depth in enumerate(depths_D):
        for b, acc in enumerate(accommodation_D):
            if window_D is not None and abs(acc - depth) > window_D + 1e-9:
                vs[a, b] = np.nan
                continue
            psf = polychromatic_psf(cfg, grid, coeffs_um, acc, depth, layout, spectrum)
            t0 = time.perf_counter()
            vs[a, b] = np.sum(ncsf * otf_of(cfg, psf).real) / ref
            cfg.timers["otf+metric"] += time.perf_counter() - t0
    return vs, np.asarray(accommodation_D)[np.nanargmax(vs, axis=1)]


__all__ = ["NaiveConfig", "PupilGrid", "through_focus_naive", "zernike_ansi", "elemental_psf"]
