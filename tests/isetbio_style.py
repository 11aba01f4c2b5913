"""The strongest baseline a careful ISETBio user would write (issue #11), in numpy.

An independent implementation, like ``reference.py`` beside it: ``test_isetbio_style.py``
checks it (sampling, diffraction-limited MTF, the sign of the view shifts) and the baseline
benchmark ``benchmarks/baselines/bench_naive.py`` times lfjax against it, importing it from
here. It lives with the tests so that the suite needs nothing from ``benchmarks/`` and the
benchmark races the copy the suite keeps correct.

Part 1 — ISETBio's wavefront → PSF path, re-implemented from reading its MATLAB source
(no code copied). Files read, in ``isetbio/isetbio`` at b9ca6a78 (the last commit before
the wavefront code moved to ISETCam in 58a590b8, "Moved wavefront functions into the
ISETCam repo"; ISETBio now calls ISETCam's copy, whose sampling code is the same):

* ``isettools/wavefront/wvf/wvfCreate.m`` — defaults: 'spatial samples' = 201,
  'ref pupil plane size' = 16.212 mm, 'measured wl' = 550 nm, 'sample interval domain' =
  'psf', 'calc pupil size' = 3 mm, 'measured pupil' = 8 mm.
* ``isettools/wavefront/wvf/wvfGet.m`` — 'pupil plane size' (at a calc wavelength λ):
  ref pupil plane size × λ / measured wl in the default 'psf' domain (the ref size at every
  λ in the 'pupil' domain); 'ref psf arcmin per pixel' = measured wl / ref pupil plane size
  (rad; ×180·60/3.1416 in this copy, /π in ISETCam's); 'psf arcmin per sample' /
  'psf angle per sample' (λ) = that reference value at EVERY λ in the 'psf' domain
  (λ / ref pupil plane size in the 'pupil' domain); 'middle row' = floor(N/2) + 1.
* ``isettools/wavefront/wvf/wvfComputePupilFunction.m`` — per calc wavelength, an N × N
  grid at spacing (pupil plane size)/N, position ((1:N) − (floor(N/2)+1))·spacing, y
  negated ("flip y"); amplitude 10^(−ρ(λ)·r²) (Stiles–Crawford, centred); Zernike
  wavefront on ρ = r / (measured pupil radius), ANSI/OSA; LCA and focus correction added to
  the defocus coefficient (custom LCA allowed); phase exp(−i 2π W/λ); HARD pupil edge
  (zero where r > calc pupil radius).
* ``isettools/wavefront/wvf/wvfComputePSF.m`` — PSF = |fftshift(fft2(ifftshift(pupil)))|²,
  then scaled to unit sum, per wavelength.
  In ``ISET/isetcam`` (read through the code index, one stored version each):
  ``opticalimage/wavefront/wvfCompute.m`` calls wvfComputePupilFunction then
  wvfComputePSF (an aperture function optional), and ``opticalimage/wavefront/wvfGet.m``
  and ``wvfCreate.m`` keep the same defaults and 'psf'-domain rules.

So at ISETBio's defaults the PSF sample is 550e-6/16.212 rad = 0.1166 arcmin at every
wavelength (the PUPIL spacing 16.212·(λ/550)/201 mm is what scales with λ: 58.7 µm at
400 nm, 102.7 µm at 700 nm), the PSF field is 201 × 0.1166 = 23.4 arcmin, and all
wavelengths share one angular grid — no resampling is needed to sum them. (Only the
non-default 'pupil' domain gives λ-dependent PSF samples, λ/16.212 rad.) The PSF is
aliasing-free while the aperture's autocorrelation fits the grid, pupil plane size(λ_min)
≥ 2 × aperture width.

Part 2 — the study pipeline built on it (``through_focus_isetbio``). The model is lfjax's
(the same as ``benchmarks/baselines/naive_pipeline.py``): eye wavefront (Zernike, ρ on the
measured pupil) + defocus c(2,0) = (accommodation − CDP + LCA(λ)) over the calculation
pupil + accommodation SA on c(4,0); amplitude = hard calc pupil × hard subaperture ×
10^(−ρ(λ) r²); weights V(λ).
What is computed once and reused:

1. for each (eye, accommodation state, λ, subaperture): the pupil function on ISETBio's
   grid for λ, |FFT|², scaled as ISETBio does to unit sum and then multiplied by the energy
   the apodised subaperture transmits Σ|P|²·dx² (lfjax's default convention: each
   elemental PSF carries its energy). Cached, as a careful user would (ISETBio itself
   recomputes them per call): the grid and its defocus and SA polynomials per λ, the
   eye's wavefront per (eye, λ) (accommodation only moves c(2,0) and c(4,0)), each view's
   SCE-apodised hard aperture per (layout, λ), and the zero-filled FFT input buffer;
2. Σ_λ w_λ·PSF_λ per (state, subaperture) — directly, because in the 'psf' domain every λ
   is on the same angular grid (an ISETBio 'pupil'-domain user would have to resample
   here), and because the view's displacement (D_d − D_CDP)·(p_n, q_n) is the same at
   every λ; then ONE real FFT per (state, subaperture) gives its OTF;
3. per rendered depth: OTF = Σ_n OTF_n · exp(−i 2π f·Δθ_n) — the shift as a Fourier phase
   ramp, not interpolation: the PSF is band-limited and Nyquist-sampled on this grid, so
   the ramp is an exact (periodic) sub-pixel shift, costs one complex multiply-add per
   frequency (separable ramps), and is needed in the Fourier domain anyway for the metric;
   spline interpolation would add its own error and cost a resampling per view and depth;
4. VSOTF = Σ NCSF·Re OTF / OTF(0) ÷ the same for the paper's reference (aberration-free,
   focused and rendered at the CDP, same layout, SA and LCA kept), on the OTF's own grid:
   true DFT frequencies k / (N · PSF sample) (ISETBio's 'otf support' is off by N/(N−1)
   for odd N; docs/design.md#conventions), Watson–Ahumada NCSF from ``lfjax.kernel.metrics`` (numpy path).

Orientation: ISETBio negates y in the pupil, so its PSF rows run towards −θ_y; the y phase
ramp carries the opposite sign (checked by ``test_isetbio_style.py``: an aberration-
free eye accommodated on the rendered depth brings every view onto the same point). The
flip mirrors the OTF in f_y, which leaves VSOTF unchanged (the NCSF is even in f_y).

Accuracy knobs (both are wvfSet parameters): the field N·λ_m/P, the frequency step
P/(N·λ_m) and the samples across a hard-edged subaperture N·d·λ_m/(P·λ) are all set by
N / P (N = spatial samples, P = ref pupil plane size), while the cost grows as N² log N —
so at a given accuracy the smallest P that keeps the views and their autocorrelation inside
the grid (``min_ref_pupil_plane_mm``) is the cheapest setting.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
from reference import zernike_j as zernike_ansi  # OSA/ANSI RMS-normalised Z_j, not masked

ARCMIN_PER_RAD = 180.0 * 60.0 / math.pi


@dataclass(frozen=True)
class WvfSampling:
    """ISETBio's spatial sampling ('psf' sample interval domain), defaults of wvfCreate."""

    n_samples: int = 201                 # 'spatial samples'
    ref_pupil_plane_mm: float = 16.212   # 'ref pupil plane size' (at the measured wl)
    measured_wl_nm: float = 550.0        # 'measured wl'

    def pupil_plane_mm(self, wavelength_nm: float) -> float:
        """'pupil plane size' at λ ('psf' domain): scales with λ."""
        return self.ref_pupil_plane_mm * wavelength_nm / self.measured_wl_nm

    def pupil_dx_mm(self, wavelength_nm: float) -> float:
        return self.pupil_plane_mm(wavelength_nm) / self.n_samples

    @property
    def psf_arcmin_per_sample(self) -> float:
        """'psf angle per sample' (arcmin), the same at every λ in the 'psf' domain."""
        return self.measured_wl_nm * 1e-6 / self.ref_pupil_plane_mm * ARCMIN_PER_RAD

    @property
    def field_arcmin(self) -> float:
        return self.n_samples * self.psf_arcmin_per_sample

    @property
    def freq_step_cpd(self) -> float:
        return 60.0 / self.field_arcmin

    def label(self) -> str:
        return f"N = {self.n_samples}, P = {self.ref_pupil_plane_mm:g} mm"


def min_ref_pupil_plane_mm(centres_mm, diameters_mm, pupil_diameter_mm: float,
                           min_wavelength_nm: float, measured_wl_nm: float = 550.0,
                           margin: float = 1.03) -> float:
    """Smallest 'ref pupil plane size' whose grid holds every subaperture at the shortest λ
    and keeps its autocorrelation (2 × its width) unwrapped, times ``margin``."""
    c = np.abs(np.asarray(centres_mm, float).reshape(-1, 2))
    d = np.minimum(np.asarray(diameters_mm, float).reshape(-1), pupil_diameter_mm)
    r_pupil = 0.5 * pupil_diameter_mm
    reach = np.minimum(c.max(axis=1) + 0.5 * d, r_pupil)     # farthest sample from the centre
    need = max(2.0 * d.max(), 2.0 * reach.max())             # at λ_min, mm
    return margin * need * measured_wl_nm / min_wavelength_nm


class _Grid:
    """ISETBio's pupil grid for one wavelength: the open (calc-pupil) samples and their
    defocus / SA polynomials, cached; the eye's wavefront cached per eye."""

    def __init__(self, s: WvfSampling, wavelength_nm: float, pupil_diameter_mm: float,
                 measured_pupil_mm: float, sa_radius_mm: float):
        n = s.n_samples
        self.n = n
        self.dx = s.pupil_dx_mm(wavelength_nm)
        pos = (np.arange(n) - n // 2) * self.dx          # (1:N) − (floor(N/2)+1), 0-based
        xx, yy = np.meshgrid(pos, -pos)                  # ISETBio: y negated
        r2 = xx * xx + yy * yy
        r_pupil = 0.5 * pupil_diameter_mm
        open_ = r2 <= r_pupil * r_pupil                  # hard edge at the calc pupil
        rows, cols = np.nonzero(open_)
        # positions in the ifftshift-ed array (index N//2 → 0): the FFT input directly
        self.flat = ((rows - n // 2) % n) * n + (cols - n // 2) % n
        self.x, self.y, self.r2 = xx[open_], yy[open_], r2[open_]
        r = np.sqrt(self.r2)
        self.th = np.arctan2(self.y, self.x)
        self.rho_m = r / (0.5 * measured_pupil_mm)
        self.z20 = zernike_ansi(4, r / r_pupil, self.th)
        self.z40 = zernike_ansi(12, r / sa_radius_mm, self.th)
        self._apertures = {}
        self._w_eye = {}

    def eye_wavefront(self, coeffs_um):
        """The eye's Zernike wavefront (µm) on the open samples (modes with c = 0 skipped, as
        ISETBio does), cached per eye: accommodation only moves c(2,0) and c(4,0)."""
        c = np.asarray(coeffs_um, float)
        key = c.tobytes()
        if key not in self._w_eye:
            if len(self._w_eye) >= 4:
                self._w_eye.clear()
            w = np.zeros_like(self.r2)
            for j in np.nonzero(c)[0]:
                w += c[j] * zernike_ansi(int(j), self.rho_m, self.th)
            self._w_eye[key] = w
        return self._w_eye[key]

    def apertures(self, centres_mm, diameters_mm, sce_rho: float, real=np.float64):
        """State-independent part, cached per layout and λ: for each subaperture the open
        samples it covers (indices into the open-sample list and into the FFT input) and
        its amplitude there (hard edge × 10^(−ρ r²))."""
        key = (np.asarray(centres_mm).tobytes(), np.asarray(diameters_mm).tobytes(), float(sce_rho),
               np.dtype(real).str)
        if key not in self._apertures:
            sce = (10.0 ** (-sce_rho * self.r2)).astype(real)
            subs = []
            for c, d in zip(np.asarray(centres_mm), np.asarray(diameters_mm)):
                idx = np.nonzero((self.x - c[0]) ** 2 + (self.y - c[1]) ** 2 <= (0.5 * d) ** 2)[0]
                subs.append((idx, self.flat[idx], sce[idx]))
            self._apertures[key] = subs
        return self._apertures[key]


@dataclass
class IsetbioStats:
    timers: dict = field(default_factory=lambda: {"pupil": 0.0, "psf fft": 0.0, "otf fft": 0.0,
                                                  "depths+metric": 0.0})
    n_psf: int = 0          # monochromatic subaperture PSFs (pupil function + fft2)
    n_otf: int = 0          # polychromatic elemental OTFs (rfft2 per state × subaperture)
    n_pairs: int = 0        # (depth, state) pairs evaluated


class IsetbioPipeline:
    """Grids cached per wavelength for one sampling and pupil; one reusable FFT input buffer
    per number of views (zero except where the last call wrote, which the next call clears)."""

    def __init__(self, s: WvfSampling, wavelengths_nm, pupil_diameter_mm=3.0,
                 measured_pupil_mm=3.0, sa_radius_mm=None, workers=None, dtype=np.float64):
        self.s = s
        self.pupil_diameter_mm = float(pupil_diameter_mm)
        self.workers = os.cpu_count() if workers is None else workers
        self.real = np.dtype(dtype)           # float64 as ISETBio (MATLAB double); float32 option
        self.complex = np.result_type(self.real, np.complex64)
        sa_r = 0.5 * pupil_diameter_mm if sa_radius_mm is None else sa_radius_mm
        self.grids = [_Grid(s, float(w), pupil_diameter_mm, measured_pupil_mm, sa_r)
                      for w in np.asarray(wavelengths_nm, float)]
        self._buffers = {}
        n = s.n_samples
        pix_rad = s.psf_arcmin_per_sample / ARCMIN_PER_RAD
        self._kx = np.fft.rfftfreq(n, 1.0 / n)            # OTF column index (f_x = k/(N·pix))
        self._ky = np.fft.fftfreq(n, 1.0 / n)             # OTF row index
        self._pix_rad = pix_rad
        from lfjax.kernel.metrics import ncsf_watson_ahumada_2005  # numpy in → numpy out

        df = s.freq_step_cpd
        fx, fy = np.meshgrid(self._kx * df, self._ky * df)
        mult = np.full(self._kx.size, 2.0)
        mult[0] = 1.0
        if n % 2 == 0:
            mult[-1] = 1.0
        self.ncsf = ncsf_watson_ahumada_2005(fx, fy) * mult[None, :]

    # ------------------------------------------------------------------ elemental part
    def elemental_psfs(self, coeffs_um, defocus_D, c40_um, spectrum, centres_mm, diameters_mm,
                       stats: IsetbioStats):
        """Σ_λ w_λ PSF_λ,n on ISETBio's common angular grid (ifftshift-ed: angle 0 at index
        0), each PSF scaled to the energy its subaperture transmits: (n_sub, N, N)."""
        wl, wts, lca, rho = spectrum[:4]
        n = self.s.n_samples
        n_sub = len(diameters_mm)
        total = np.zeros((n_sub, n, n), self.real)
        c20_per_D = self.pupil_diameter_mm**2 / (16.0 * math.sqrt(3.0))
        for i, g in enumerate(self.grids):
            t0 = time.perf_counter()
            subs = g.apertures(centres_mm, diameters_mm, rho[i], self.real)
            fld, written = self._buffer(n_sub)
            w = (g.eye_wavefront(coeffs_um) + (defocus_D + lca[i]) * c20_per_D * g.z20
                 + c40_um * g.z40)                                       # µm, open samples
            arg = (2.0 * np.pi / (wl[i] * 1e-3)) * w
            phase = np.empty(arg.shape, self.complex)                   # exp(−i 2π W/λ)
            phase.real = np.cos(arg)
            phase.imag = -np.sin(arg)
            for k, (idx, flat, amp) in enumerate(subs):
                if written[k] is not None and written[k] is not flat:
                    fld[k, written[k]] = 0.0                             # previous λ / layout
                fld[k, flat] = amp * phase[idx]
                written[k] = flat
            t1 = time.perf_counter()
            spec = scipy.fft.fft2(fld.reshape(n_sub, n, n), workers=self.workers)
            psf = spec.real**2
            psf += spec.imag**2
            # ISETBio scales each PSF to unit sum (Σ|FFT|² = N²·Σ|P|², Parseval); lfjax's
            # convention then gives it the energy its subaperture transmits, Σ|P|²·dx²:
            # together a factor dx²/N², no reduction needed.
            psf *= wts[i] * g.dx**2 / (n * n)
            total += psf
            stats.timers["pupil"] += t1 - t0
            stats.timers["psf fft"] += time.perf_counter() - t1
            stats.n_psf += n_sub
        return total

    def _buffer(self, n_sub: int):
        if n_sub not in self._buffers:
            n = self.s.n_samples
            self._buffers[n_sub] = (np.zeros((n_sub, n * n), self.complex), [None] * n_sub)
        return self._buffers[n_sub]

    def elemental_otfs(self, psf_sum, stats: IsetbioStats):
        t0 = time.perf_counter()
        otf = scipy.fft.rfft2(psf_sum, workers=self.workers)
        stats.timers["otf fft"] += time.perf_counter() - t0
        stats.n_otf += psf_sum.shape[0]
        return otf

    # ------------------------------------------------------------------ per depth
    def shifted_sum(self, otfs, shifts_rad):
        """Σ_n OTF_n shifted by Δθ_n = (x, y) rad (physical angles; ISETBio's flipped rows)."""
        total = np.zeros(otfs.shape[1:], otfs.dtype)
        n = self.s.n_samples
        for o, (sx, sy) in zip(otfs, shifts_rad):
            rx = np.exp((-2j * np.pi / n) * self._kx * (sx / self._pix_rad)).astype(otfs.dtype)
            # rows run towards −θ_y (ISETBio's flipped y): opposite sign
            ry = np.exp((+2j * np.pi / n) * self._ky * (sy / self._pix_rad)).astype(otfs.dtype)
            ramp = np.outer(ry, rx)
            ramp *= o
            total += ramp
        return total

    def metric_numerator(self, otf):
        return float(np.sum(self.ncsf * otf.real) / otf[0, 0].real)


def through_focus_isetbio(pipe: IsetbioPipeline, coeffs_um, layout, depths_D, accommodation_D,
                          spectrum, cdp_D=2.0, window_D=None, stats: IsetbioStats | None = None):
    """VSOTF (n_depth, n_acc) and predicted accommodation (n_depth,), ISETBio-style.

    ``spectrum`` = (wavelengths nm, weights, LCA D, SCE ρ mm⁻², c40(accommodation) µm) as in
    ``benchmarks/baselines/naive_pipeline.py``; ``layout`` = (centres mm (n_sub, 2), diameters
    mm (n_sub,)).
    Elemental PSFs are computed once per (state, λ, subaperture) and re-used for every
    depth within ``window_D`` of the state (all depths when None).
    """
    stats = IsetbioStats() if stats is None else stats
    centres, diameters = (np.asarray(a, float) for a in layout)
    c40 = spectrum[4]
    depths = np.asarray(depths_D, float)
    acc = np.asarray(accommodation_D, float)
    # reference: aberration-free, accommodated and rendered at the CDP
    ref_psf = pipe.elemental_psfs(np.zeros(1), 0.0, c40(cdp_D),
                                  spectrum, centres, diameters, stats)
    ref_otfs = pipe.elemental_otfs(ref_psf, stats)
    t0 = time.perf_counter()
    ref = pipe.metric_numerator(np.sum(ref_otfs, axis=0))
    stats.timers["depths+metric"] += time.perf_counter() - t0
    vs = np.full((depths.size, acc.size), np.nan)
    for b, a in enumerate(acc):
        todo = [k for k, d in enumerate(depths) if window_D is None or abs(a - d) <= window_D + 1e-9]
        if not todo:
            continue
        psf = pipe.elemental_psfs(coeffs_um, a - cdp_D, c40(a), spectrum, centres, diameters, stats)
        otfs = pipe.elemental_otfs(psf, stats)
        t0 = time.perf_counter()
        for k in todo:
            shifts = (depths[k] - cdp_D) * centres * 1e-3                     # rad (D × mm)
            vs[k, b] = pipe.metric_numerator(pipe.shifted_sum(otfs, shifts)) / ref
            stats.n_pairs += 1
        stats.timers["depths+metric"] += time.perf_counter() - t0
    pred = acc[np.nanargmax(vs, axis=1)]
    return vs, pred, stats


def monochromatic_psf(s: WvfSampling, coeffs_um, wavelength_nm, pupil_diameter_mm=3.0,
                      measured_pupil_mm=3.0, centre_mm=(0.0, 0.0), diameter_mm=None,
                      defocus_D=0.0, sce_rho=0.0):
    """One ISETBio-style PSF, centred (angle 0 at index N//2, rows towards −θ_y), unit sum;
    returns (psf, arcmin per sample). For tests and inspection."""
    coeffs = np.asarray(coeffs_um, float)
    pipe = IsetbioPipeline(s, [wavelength_nm], pupil_diameter_mm, measured_pupil_mm)
    d = pupil_diameter_mm if diameter_mm is None else diameter_mm
    spec = (np.array([wavelength_nm]), np.array([1.0]), np.array([0.0]), np.array([sce_rho]))
    psf = pipe.elemental_psfs(coeffs, defocus_D, 0.0, spec, np.array([centre_mm]), np.array([d]),
                              IsetbioStats())[0]
    psf = np.fft.fftshift(psf)
    return psf / psf.sum(), s.psf_arcmin_per_sample


__all__ = [
    "IsetbioPipeline",
    "IsetbioStats",
    "WvfSampling",
    "min_ref_pupil_plane_mm",
    "monochromatic_psf",
    "through_focus_isetbio",
]
