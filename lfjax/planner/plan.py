"""Sampling planner: the cheapest sampling that meets an accuracy target, with its reasons.

"Model no more than a scene needs." In lfjax's FFT path one number, the frequency step df
(cpd), fixes the numerics: the PSF field is 60/df arcmin (the blur must fit or it wraps)
and the pupil is sampled at λ·df per wavelength (d/(λ·df) samples across a subaperture of
diameter d). The matrix Fourier transform path (``Sampling(transform="mft")``) separates
the two: df sets the field, ``mft_pupil_samples`` the pupil sampling. The planner also
chooses the wavelength step and the Zernike order the eyes need.

How each choice is made (all on the host, in numpy; 1–30 s per plan):

* **Field (frequency step).** Hard limit: the pipeline's aliasing guard
  (:func:`lfjax.kernel.optics.field_radius_arcmin`, geometric blur + display shifts + diffraction
  + the eyes' ray angles). Within it, the PSF that wraps back into the field is *measured*
  on a proxy (below): the largest ratio of wrapped intensity to the PSF's peak must stay
  within ``psf_tolerance``.
* **Pupil sampling.** The VSOTF error of the discretised, soft-edged aperture is *measured*
  on the proxy, at every (depth, state) pair of the scene: the candidate's distance from
  one converged proxy value (Richardson, order 2, from a half and a quarter of the largest
  admissible step, or a quarter and an eighth for tight targets), × ``ESTIMATE_SAFETY``.
* **Wavelength step** (when only a range is given): proxy through-focus curves at each
  candidate step against a 5 nm reference; the step must keep the VSOTF error within its
  share of the tolerance and leave every proxy peak where it was.
* **Zernike order**: the eyes' wavefront RMS above the kept order, converted to a VSOTF
  change by the Maréchal approximation (2πσ/λ)².
* **Targets in the question's units** (``peak_tolerance_D``, ``cutoff_tolerance_cpd``):
  a through-focus peak's error is the shift of the vertex of the parabola through the
  proxy's highest sample and its neighbours, candidate against converged (the VSOTF error's
  slope over the curve's curvature, to first order); a cut-off's error is the shift of the
  proxy's radial-MTF threshold crossing at every state near each depth's peak (the MTF
  error over the MTF's slope). Half of each target goes to the wavelength step, the rest
  to the frequency step.
* **FFT or MFT** (``transform="auto"``, opt-in): each at its own cheapest
  accuracy-meeting sampling, each measured on a proxy that follows that path exactly; the
  cheaper by a cost model calibrated on this machine.

The proxy is the scene as the paper's ideal display makes it, for an aberration-free eye,
in numpy: each view's aperture (lfjax's logistic, area-exact edge, Stiles–Crawford
apodisation) is transformed with the local defocus of the accommodation state plus LCA and
the accommodation spherical aberration, and enters with its display shift and the tilt of
the defocus over it as one phase ramp. Views congruent under the square's mirrors and
quarter turns share one transform (their VSOTF terms are equal, their PSFs mapped copies).
For the aberration-free eye the proxy's VSOTF equals the pipeline's to < 1e-6 at any step
(tests/test_planner.py), so its error estimates are the pipeline's own; the proxy thins a
spectrum to at most 7 wavelengths. The real eyes' aberrations enter through the field
guard (their ray angles); see benchmarks/RESULTS.md §6–7 for plans measured with real eyes.

Steps are taken from fixed ladders (df = 2^(k/8) cpd; pupil samples 16, 20, 24, 32, …), so
"one step cheaper" is well defined: :attr:`Plan.cheaper` lists it for every dimension.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.fft as sfft

from lfjax.display.lenslets import DisplayOptics
from lfjax.model.layouts import Layout, open_pupil
from lfjax.kernel.metrics import half_plane_weights_np, ncsf, radial_bins
from lfjax.kernel.optics import field_radius_arcmin, pupil_window_size, sa_parameters
from lfjax.model.options import ModelOptions
from lfjax.base.sampling import EDGE_EXTENT_SCALES, EYE_BLOCK, Sampling, next_fast_size, wavelength_bands
from lfjax.model.spectral import Spectrum, make_spectrum
from lfjax.base.units import ARCMIN_PER_RADIAN, DEGREES_PER_RADIAN
from lfjax.base.zernike import n_modes_for_order, nm_from_ansi, zernike_basis

STEPS_PER_OCTAVE = 8
"""Frequency-step ladder: df = 2^(k/8) cpd (9 % apart; one step ≈ 19 % of FFT work)."""

MFT_PUPIL_LADDER = (16, 20, 24, 28, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 256)
"""Pupil samples across the MFT window the planner chooses from."""

ESTIMATE_SAFETY = 1.05
"""Factor on the proxy's VSOTF error estimates (calibration against the pipeline:
benchmarks/planner_validation.py)."""

WAVELENGTH_STEPS_NM = (50.0, 30.0, 25.0, 20.0, 10.0, 5.0)
"""Wavelength steps the planner chooses from (coarsest first)."""

SPECTRAL_REFERENCE_STEP_NM = 5.0
"""Wavelength step of the proxy's converged spectrum, against which candidate steps are
measured. The V(λ)-weighted sum is a trapezoid rule on an integrand that vanishes at both
ends of 400–700 nm, so it converges fast: on the study's eleven eyes 20 and 25 nm agree with
5 nm to 8e-4 D in peaks and 0.06 cpd in natural-view cut-offs (benchmarks/RESULTS.md §18).
(It was 2.5 nm; the 121-wavelength proxy cost 5–10 s per plan.)"""

# Cost model: seconds per eye = FFT flops / R_fft + matrix-product flops / R_mm + pupil
# samples evaluated × t_pupil. Calibrated by least squares on four warm pipeline runs on
# the 2-core reference machine (2×2 and 4×4, FFT and MFT, 31 λ, 21 states, 3 eyes; fit within
# 8 %); small transforms run well below the rate of large FFTs on this machine. Only the ratio
# of the two paths matters for the choice, and benchmarks/speed_accuracy.py re-measures it.
_FFT_FLOPS_PER_S = 4.1e9
_MATMUL_FLOPS_PER_S = 92e9
_PUPIL_S_PER_SAMPLE = 17e-9

_PROXY_WAVELENGTHS = 7
"""Most wavelengths the proxy evaluates; a longer spectrum is thinned, each kept wavelength
taking the V(λ) weight of its nearest neighbours (a cost bound on planning; the validation
scenes use 3 wavelengths, so this thinning is not what they test)."""


class _Estimates:
    """Proxy error estimates per candidate against one converged proxy value (cached).

    The converged VSOTF is Richardson-extrapolated (order 2: soft-edge errors fall ∝ step²)
    from the proxy at a half and a quarter of ``df_reference``; if the estimated residual
    of that extrapolation (a tenth of its correction) is not well below the tolerance, from
    a quarter and an eighth instead. Each candidate's error is its distance from it.
    (Comparing each candidate with its own half step instead was noisy by 30–70 %: the
    soft-edge error depends on where the edge falls between samples at both steps.)
    """

    def __init__(self, proxy, pairs, df_reference: float, tolerance: float):
        self.proxy, self.pairs, self.cache = proxy, pairs, {}
        self.df_reference, self.tolerance = df_reference, tolerance
        self._converged = None

    @property
    def converged(self) -> np.ndarray:
        if self._converged is None:
            coarse = self.proxy.vsotf(self.df_reference / 2.0, self.pairs)
            fine = self.proxy.vsotf(self.df_reference / 4.0, self.pairs)
            correction = (fine - coarse) / 3.0
            if 0.1 * float(np.max(np.abs(correction))) > 0.02 * self.tolerance:
                coarse, fine = fine, self.proxy.vsotf(self.df_reference / 8.0, self.pairs)
                correction = (fine - coarse) / 3.0
            self._converged = fine + correction
        return self._converged

    def _error(self, values) -> float:
        return ESTIMATE_SAFETY * float(np.max(np.abs(values - self.converged)))

    def values(self, df: float) -> np.ndarray:
        """Proxy VSOTF of the FFT path at frequency step df, per pair."""
        key = ("values", round(df, 12))
        if key not in self.cache:
            self.cache[key] = self.proxy.vsotf(df, self.pairs)
        return self.cache[key]

    def vsotf(self, df: float) -> float:
        """VSOTF error of the FFT path at frequency step df."""
        return self._error(self.values(df))

    def peak_shift(self, df: float) -> float:
        """Largest through-focus peak shift (D) of the FFT path at step df against the
        converged curves (× the estimates' safety factor)."""
        return ESTIMATE_SAFETY * _peak_shift_D(self.values(df), self.converged, self.pairs)

    def cutoff_shift(self, df: float, threshold: float) -> float:
        """Largest cut-off shift (cpd) of the FFT path at step df, at each depth's converged
        peak state, against a quarter of the reference step (× the safety factor)."""
        key = ("cutoff", round(df, 12), threshold)
        if key not in self.cache:
            states = _peak_states(self.converged, self.pairs)
            fine = ("cutoff-ref", threshold)
            if fine not in self.cache:
                self.cache[fine] = self.proxy.cutoffs(self.df_reference / 4.0, states, threshold)
            self.cache[key] = ESTIMATE_SAFETY * float(np.max(np.abs(
                self.proxy.cutoffs(df, states, threshold) - self.cache[fine])))
        return self.cache[key]

    def psf(self, df: float) -> tuple[float, float]:
        """(wrapped PSF / peak of the FFT path's field 60/df arcmin, VSOTF error of
        truncating the PSF there instead — the MFT path's field error)."""
        key = ("psf", round(df, 12))
        if key not in self.cache:
            _, wrapped, truncation = self.proxy.vsotf(df / 2.0, self.pairs, with_psf=True)
            self.cache[key] = (float(wrapped.max()), ESTIMATE_SAFETY * truncation)
        return self.cache[key]

    def mft(self, df: float, samples: int) -> float:
        """VSOTF error of the MFT path with ``samples`` pupil samples at step df (one df
        per plan), truncation at the field edge included."""
        key = ("mft", samples)
        if key not in self.cache:
            self.cache[key] = self._error(
                self.proxy.vsotf(df, self.pairs, transform="mft", mft_samples=samples))
        return self.cache[key]


def ladder_floor(x: float) -> float:
    """Largest ladder step 2^(k/8) ≤ x."""
    k = math.floor(STEPS_PER_OCTAVE * math.log2(x) + 1e-9)
    return 2.0 ** (k / STEPS_PER_OCTAVE)


def ladder_up(x: float) -> float:
    """The next ladder step above ``x`` (one step cheaper)."""
    return ladder_floor(x) * 2.0 ** (1.0 / STEPS_PER_OCTAVE)


@dataclass(frozen=True)
class Plan:
    """A chosen sampling with its estimated errors, cost and reasons.

    Attributes
    ----------
    sampling : Sampling to pass to the pipeline (frequency step, transform, pupil samples).
    wavelengths_nm : (n_λ,) wavelengths to use, nm (``spectrum()`` builds them).
    max_zernike_order : radial order of the eyes' Zernike terms to keep (None: all).
    blur_radius_arcmin : largest PSF radius the field must hold (the guard), arcmin.
    guard_freq_step_cpd : largest frequency step the aliasing guard accepts, cpd.
    errors : estimated VSOTF errors by source ("pupil", "spectral", "zernike", "total")
        and "psf_wrap" (wrapped intensity / PSF peak), from the proxy; with the targets in
        the question's units also the proxy's peak shifts in D ("spectral_peak_D", and
        "peak_D" for the whole plan) and cut-off shifts in cpd ("spectral_cutoff_cpd",
        "cutoff_cpd").
    cost_s : modelled seconds per eye for "fft" and "mft" at their own plans.
    cheaper : the sampling one ladder step cheaper in each dimension, with the reason it
        was rejected, e.g. {"field": (Sampling, "…"), "pupil": (Sampling, "…")}.
    bands : wavelength bands and FFT sizes ((start, stop, n_fft), …).
    fft_work : relative FFT work per eye and state, Σ n_λ·n_sub·n_fft²·log2(n_fft).
    reasons : one-line explanations.
    """

    sampling: Sampling
    wavelengths_nm: tuple
    max_zernike_order: int | None
    blur_radius_arcmin: float
    guard_freq_step_cpd: float
    errors: dict
    cost_s: dict
    cheaper: dict
    bands: tuple
    fft_work: float
    options: ModelOptions = ModelOptions()
    reasons: list = field(default_factory=list)
    spectral_weights: tuple | None = None

    def spectrum(self) -> Spectrum:
        """The planned spectrum (V(λ) weights, or the ``spectral_weights`` planned for; LCA
        and SCE of the plan's options)."""
        weights = None if self.spectral_weights is None else np.asarray(self.spectral_weights)
        return make_spectrum(np.asarray(self.wavelengths_nm), self.options, weights=weights)

    def truncate(self, zernike_um):
        """Eye coefficients (…, n_modes) cut to the planned Zernike order."""
        if self.max_zernike_order is None:
            return zernike_um
        n = min(n_modes_for_order(self.max_zernike_order), np.shape(zernike_um)[-1])
        return zernike_um[..., :n]

    def summary(self) -> str:
        """Printable explanation of the choice."""
        s = self.sampling
        wl = np.asarray(self.wavelengths_nm)
        step = f"{wl[1] - wl[0]:g} nm steps" if wl.size > 1 else "one wavelength"
        transform = (
            f"MFT with {s.mft_pupil_samples} pupil samples" if s.transform == "mft"
            else "FFT (pupil sampled at λ·df)"
        )
        e = self.errors
        lines = [
            f"freq_step_cpd = {s.freq_step_cpd:.4g} cpd (PSF field {s.field_arcmin:.1f} arcmin; "
            f"guard allows ≤ {self.guard_freq_step_cpd:.4g})",
            f"transform: {transform}; aperture edge {s.edge_width_samples:g} samples",
            f"wavelengths: {wl[0]:g}–{wl[-1]:g} nm, {step} ({wl.size})",
            "Zernike order: " + ("all" if self.max_zernike_order is None else str(self.max_zernike_order)),
            f"estimated VSOTF error: {e.get('total', float('nan')):.2g} (pupil "
            f"{e.get('pupil', float('nan')):.2g}, spectral {e.get('spectral', float('nan')):.2g}, "
            f"Zernike {e.get('zernike', float('nan')):.2g}); wrapped PSF / peak "
            f"{e.get('psf_wrap', float('nan')):.2g}",
            "modelled time per eye: " + ", ".join(f"{k} {v:.3g} s" for k, v in self.cost_s.items()),
            "wavelength bands (start, stop, n_fft): " + ", ".join(map(str, self.bands)),
        ]
        lines += [f"- {r}" for r in self.reasons]
        for dim, (_, why) in self.cheaper.items():
            lines.append(f"- one step cheaper in {dim}: {why}")
        return "\n".join(lines)


# ----------------------------------------------------------------------------- scene


# The square's symmetries as maps of (x, y): identity first, then mirrors and quarter turns.
_SQUARE_SYMMETRIES = [np.array(m, float) for m in (
    [[1, 0], [0, 1]], [[-1, 0], [0, 1]], [[1, 0], [0, -1]], [[-1, 0], [0, -1]],
    [[0, 1], [1, 0]], [[0, -1], [1, 0]], [[0, 1], [-1, 0]], [[0, -1], [-1, 0]],
)]


def _map_psf(psf: np.ndarray, m: np.ndarray) -> np.ndarray:
    """PSF(s) (…, n, n) [y, x] with zero angle at index n//2, mapped by the symmetry ``m``:
    out(θ) = psf(m⁻¹θ), exactly on the grid (indices wrap like the periodic field)."""
    n = psf.shape[-1]
    k = np.arange(n) - n // 2
    ky, kx = np.meshgrid(k, k, indexing="ij")
    inv = np.rint(np.linalg.inv(m)).astype(int)
    sx = inv[0, 0] * kx + inv[0, 1] * ky
    sy = inv[1, 0] * kx + inv[1, 1] * ky
    return psf[..., (sy + n // 2) % n, (sx + n // 2) % n]


@dataclass(frozen=True)
class _Scene:
    layout: Layout
    pupil_mm: float
    cdp_D: float
    pair_acc: np.ndarray  # (n_pairs,) absolute accommodation of every evaluated pair, D
    pair_depth: np.ndarray  # (n_pairs,) rendered depth, D
    options: ModelOptions
    display: object = None  # lfjax.display.lenslets.DisplayOptics or None (the ideal display)

    @property
    def diffracts(self) -> bool:
        return self.display is not None and self.display.diffracts

    @property
    def window_mm(self) -> float:
        """The static window the pipeline sizes its transforms for (the pupil when lenslet
        diffraction spreads the beams)."""
        return self.pupil_mm if self.diffracts else float(self.layout.window_diameter_mm)

    @property
    def accommodation(self) -> np.ndarray:
        return np.unique(self.pair_acc)

    def view_groups(self) -> list[tuple[tuple[np.ndarray, float], list[np.ndarray]]]:
        """Views grouped by congruence under the square's symmetries: [((centre mm,
        diameter mm) of the group's representative, [2×2 integer matrix M per member]), …],
        each member's centre being M·(representative's centre).

        A member's whole configuration (clipped aperture, SCE, defocus, accommodation SA,
        display shift, all radial or ∝ the centre) is the representative's mapped by M, so
        its PSF is the representative's mapped by M, and — the NCSF being invariant under
        these mirrors and quarter turns — its VSOTF term equals the representative's.
        Views related only by other rotations (a hexagon's 60°) form groups of their own.
        """
        centres = np.asarray(self.layout.centres_mm, float).reshape(-1, 2)
        diam = np.asarray(self.layout.diameters_mm, float).reshape(-1)
        tol = 1e-9 * max(self.pupil_mm, 1.0)
        groups: list = []
        for c, d in zip(centres, diam):
            for (rep, rep_d), maps in groups:
                if abs(rep_d - d) > tol:
                    continue
                m = next((m for m in _SQUARE_SYMMETRIES if np.allclose(m @ rep, c, atol=tol)), None)
                if m is not None:
                    maps.append(m)
                    break
            else:
                groups.append(((c, float(d)), [_SQUARE_SYMMETRIES[0]]))
        return groups

    @property
    def largest_diameter_mm(self) -> float:
        """Largest beam in the pupil, mm (the pupil when diffraction spreads the beams)."""
        if self.diffracts:
            return self.pupil_mm
        d = np.minimum(np.asarray(self.layout.diameters_mm, float), self.pupil_mm)
        return float(d.max())

    @property
    def smallest_diameter_mm(self) -> float:
        d = np.minimum(np.asarray(self.layout.diameters_mm, float), self.pupil_mm)
        return float(d.min())


def _scene_pairs(depths, accommodation_D, window_D):
    depths = np.atleast_1d(np.asarray(depths, float))
    if accommodation_D is not None:
        grid = np.atleast_1d(np.asarray(accommodation_D, float))
        if grid.size == 2 and window_D is None:  # (lowest, highest) absolute range
            grid = np.linspace(grid[0], grid[1], max(int(round(abs(grid[1] - grid[0]) / 0.2)) + 1, 2))
        acc, dep = np.meshgrid(grid, depths)
        keep = np.ones(acc.shape, bool) if window_D is None else np.abs(acc - dep) <= window_D + 1e-9
        if not np.all(keep.any(axis=1)):
            raise ValueError(f"accommodation_window_D={window_D} leaves no state for some depths")
        return acc[keep], dep[keep]
    w = 1.0 if window_D is None else float(window_D)
    offsets = np.linspace(-w, w, 2 * max(int(math.ceil(w / 0.1)), 1) + 1)
    acc = depths[:, None] + offsets[None, :]
    dep = np.broadcast_to(depths[:, None], acc.shape)
    keep = acc >= -1e-9  # hyperopic limit
    return np.clip(acc[keep], 0.0, None), dep[keep]


def _subsample_spectrum(spectrum: Spectrum, n_max: int = _PROXY_WAVELENGTHS):
    """At most ``n_max`` wavelengths, each carrying the weight of its nearest neighbours."""
    wl = np.asarray(spectrum.wavelengths_nm, float)
    w = np.asarray(spectrum.weights, float)
    keep = np.unique(np.round(np.linspace(0, wl.size - 1, min(n_max, wl.size))).astype(int))
    nearest = np.argmin(np.abs(wl[:, None] - wl[keep][None, :]), axis=1)
    weights = np.bincount(nearest, weights=w, minlength=keep.size)
    return (wl[keep], weights / weights.sum(), np.asarray(spectrum.lca_D, float)[keep],
            np.asarray(spectrum.sce_rho_per_mm2, float)[keep])


# ----------------------------------------------------------------------------- proxy


def _aperture_otfs(view, pupil_mm, defocus_D, sa_c40_um, sa_radius_mm, wavelength_nm, rho,
                   dx_mm, n_fft, edge_samples, mft_samples: int | None = None,
                   df_cpd: float | None = None, display=None):
    """Half-plane OTFs (n_states, L, L//2+1), lag step dx, of one view — subaperture
    ``view`` = (centre mm, diameter mm) clipped by the pupil — at each local defocus (D) and
    accommodation SA c(4,0) (µm): the pipeline's aperture (optics._pupil_parts) on one
    window, complex64 FFTs. OTF(0) is the transmitted energy (mm²), as in the pipeline.

    With ``mft_samples``: the pipeline's MFT path instead — ``mft_samples``² pupil samples,
    the PSF's point samples on the n_fft angles of a field 60/``df_cpd`` arcmin (truncated,
    not wrapped), and its OTF at step ``df_cpd``.

    With ``display`` (:class:`lfjax.display.lenslets.DisplayOptics`): square subapertures and lenslet
    diffraction as the pipeline models them (the window is then the whole pupil and the
    view's beam its Fresnel pattern, :func:`_fresnel_np`)."""
    centre, d_mm = view
    if mft_samples is not None:
        n_pupil = mft_samples
    else:
        n_pupil = min(n_fft, pupil_window_size(n_fft, Sampling(1.0, edge_width_samples=edge_samples)))
    diffracts = display is not None and display.diffracts
    shape = "circle" if display is None else display.aperture
    k = (np.arange(n_pupil) - n_pupil // 2) * dx_mm
    window_centre = np.zeros(2) if diffracts else np.asarray(centre, float)
    xl, yl = np.meshgrid(k + window_centre[0] - centre[0], k + window_centre[1] - centre[1])
    r2_local = xl * xl + yl * yl  # about the view's centre
    r2 = (xl + centre[0]) ** 2 + (yl + centre[1]) ** 2
    edge = edge_samples * dx_mm

    def edge_distance(r2_, radius):  # optics.disk_edge_distance (area-exact logistic edge)
        return np.sqrt(max(radius**2 - (math.pi**2 / 3.0) * edge * edge, 0.0)) - np.sqrt(r2_)

    def logistic(x):
        return 0.5 * (1.0 + np.tanh(0.5 * x))  # overflow-free

    if shape == "square":
        sub_inside = np.minimum(0.5 * d_mm - np.abs(xl), 0.5 * d_mm - np.abs(yl))
    else:
        sub_inside = edge_distance(r2_local, 0.5 * d_mm)
    sce = 10.0 ** (-rho * r2)
    if diffracts:
        source = logistic(sub_inside / edge)
        z_mm = float(display.fresnel_distance_mm)
        beam = _fresnel_np(source.astype(complex), dx_mm, wavelength_nm * 1e-6, z_mm, pupil_mm)
        intensity = np.abs(beam) ** 2
        if display.diffraction == "modulus":
            beam = np.sqrt(intensity)
        pupil_cover = logistic(edge_distance(r2, 0.5 * pupil_mm) / edge)
        amp = pupil_cover * sce * beam
        # the edge's energy still on the beam's scale (optics._pupil_parts)
        spread = wavelength_nm * 1e-6 * z_mm / (math.pi * edge * d_mm)
        kept = 1.0 / math.sqrt(1.0 + spread * spread)
        energy = float(np.sum(pupil_cover * sce * sce * (intensity + kept * source * (1.0 - source)))
                       * dx_mm * dx_mm)
    else:
        cover = logistic(np.minimum(edge_distance(r2, 0.5 * pupil_mm), sub_inside) / edge)
        amp = cover * sce
        energy = float(np.sum(cover * sce * sce) * dx_mm * dx_mm)
    # Global defocus = local defocus + a tilt; the tilt is the view's shift (in the ramp).
    # D times r² (mm²) / 2 is µm; SA on pupil coordinates: c40·√5(6ρ⁴ − 6ρ² + 1).
    rho2 = r2 / sa_radius_mm**2
    z40 = math.sqrt(5.0) * (6.0 * rho2 * rho2 - 6.0 * rho2 + 1.0)
    w_um = (0.5 * np.asarray(defocus_D, float)[:, None, None] * r2_local[None]
            + np.asarray(sa_c40_um, float)[:, None, None] * z40[None])
    phase = ((-2.0 * np.pi / (wavelength_nm * 1e-3)) * w_um).astype(np.float32)
    field_ = amp.astype(np.complex64)[None] * np.exp(1j * phase).astype(np.complex64)
    if mft_samples is not None:  # as optics._elemental_otfs_band's MFT branch
        wl_mm = wavelength_nm * 1e-6
        pixel_rad = 1.0 / (n_fft * df_cpd * DEGREES_PER_RADIAN)
        theta = np.fft.fftfreq(n_fft, 1.0 / n_fft) * pixel_rad
        kernel = np.exp((-2j * np.pi / wl_mm) * theta[:, None] * k[None, :]).astype(np.complex64)
        spec = kernel @ field_ @ kernel.T
        psf = (spec.real**2 + spec.imag**2).astype(np.float32)
        otf = sfft.rfft2(psf, workers=-1) * (dx_mm**4 * pixel_rad**2 / wl_mm**2)
    else:
        spec = sfft.fft2(field_, s=(n_fft, n_fft), workers=-1)
        psf = (spec.real**2 + spec.imag**2).astype(np.float32)
        otf = sfft.rfft2(psf, workers=-1) * (dx_mm * dx_mm / n_fft**2)
    otf[:, 0, 0] = energy
    return otf


def _fresnel_np(field, dx_mm, wavelength_mm, distance_mm, extent_mm):
    """numpy twin of :func:`lfjax.display.lenslets.fresnel_propagate` (the same kernel sampling:
    impulse response in the far field, analytic transfer function in the near field)."""
    n = field.shape[-1]
    n_pad = next_fast_size(2 * n)
    lam_z = wavelength_mm * distance_mm
    if lam_z >= 2.0 * extent_mm * dx_mm:
        k = np.fft.fftfreq(n_pad, 1.0 / n_pad)
        h = np.where(np.abs(k * dx_mm) < extent_mm, np.exp(1j * np.pi * (k * dx_mm) ** 2 / lam_z), 0.0)
        transfer = np.fft.fft(h) * dx_mm * np.exp(-0.25j * np.pi) / np.sqrt(lam_z)
    else:
        f = np.fft.fftfreq(n_pad) / dx_mm
        transfer = np.exp(-1j * np.pi * lam_z * f * f)
    padded = np.zeros((n_pad, n_pad), complex)
    padded[:n, :n] = field
    out = np.fft.ifft2(np.fft.fft2(padded) * transfer[:, None] * transfer[None, :])
    return out[:n, :n]


def _view_ramps(shifts_rad, fx_cpr, fy_cpr):
    """Σ over views of exp(−2πi f·shift) per pair: shifts (n_pairs, n_views, 2) rad →
    (n_pairs, n_y, n_x), separable per view."""
    ex = np.exp(-2j * np.pi * shifts_rad[..., 0, None] * fx_cpr).astype(np.complex64)
    ey = np.exp(-2j * np.pi * shifts_rad[..., 1, None] * fy_cpr).astype(np.complex64)
    return np.einsum("pny,pnx->pyx", ey, ex)


def _ncsf_half(n_fft: int, step_cpd: float, model: str) -> np.ndarray:
    """NCSF on the half plane (n_fft, n_fft//2+1) at step ``step_cpd`` cpd times the
    Hermitian multiplicity, in numpy (as metrics.ncsf_half_plane on the host)."""
    fy = np.fft.fftfreq(n_fft, 1.0 / n_fft) * step_cpd
    fx = np.fft.rfftfreq(n_fft, 1.0 / n_fft) * step_cpd
    weights = np.asarray(ncsf(fx[None, :], fy[:, None], model), float)
    return weights * half_plane_weights_np(n_fft)[None, :]


class _Proxy:
    """Aberration-free proxy of a scene on one candidate sampling (see module docstring).

    Views congruent under the square's symmetries form a group (the corner, edge and inner
    views of a grid); each group's representative is transformed once per wavelength and
    state, and its members contribute its VSOTF term and its mapped PSF (view_groups).
    """

    def __init__(self, scene: _Scene, spectrum: Spectrum, edge_samples: float, n_wavelengths=None):
        self.scene = scene
        sub = _subsample_spectrum(spectrum, n_wavelengths or _PROXY_WAVELENGTHS)
        self.wl, self.weights, self.lca, self.rho = sub
        self.edge = edge_samples
        self.groups = scene.view_groups()
        # accommodation SA: (µm of c(4,0) per D, radius mm) as the pipeline applies it
        self.sa = tuple(float(x) for x in np.asarray(sa_parameters(scene.options, scene.pupil_mm)))

    def _sums(self, pairs, dx_of, n_fft: int, step_of, keep_otf: bool = False,
              mft_samples: int | None = None, n_fft_of=None):
        """NCSF-weighted sums of Re OTF per pair, the reference's sum, and (optionally) per
        view group the representative's rendered polychromatic OTFs (n_pairs, L, L//2+1),
        unnormalised.

        Per wavelength the pupil is sampled at ``dx_of(λ)`` mm, so lag k is the frequency
        k·``step_of(λ)`` cpd (the FFT path: λ·df and df, one grid for all wavelengths).
        With ``mft_samples`` the pipeline's MFT path, on ``n_fft_of(λ)`` angles per
        wavelength (its wavelength bands).
        """
        acc, dep = pairs
        scene = self.scene
        states, state_of_pair = np.unique(acc, return_inverse=True)
        # The reference is the ideal display's (pipeline.reference_normalisers): with
        # display effects it is transformed on its own (diffraction off, the shape kept).
        reference_otfs = reference_display = None
        if scene.display is not None and scene.display.diffracts:
            reference_otfs = True
            reference_display = DisplayOptics("off", scene.display.aperture)
        num = np.zeros(acc.size)
        den = 0.0
        energy_views = energy_reference = 0.0  # transmitted energies (differ with diffraction)
        rendered = [np.zeros((acc.size, n_fft, n_fft // 2 + 1), np.complex64) for _ in self.groups] \
            if keep_otf else None
        for lam, w, lca, rho in zip(self.wl, self.weights, self.lca, self.rho):
            dx, step = dx_of(lam), step_of(lam)
            if n_fft_of is not None:
                n_fft = n_fft_of(lam)
            wts = _ncsf_half(n_fft, step, scene.options.ncsf) * step**2
            fy = np.fft.fftfreq(n_fft, 1.0 / n_fft) * step * DEGREES_PER_RADIAN
            fx = np.fft.rfftfreq(n_fft, 1.0 / n_fft) * step * DEGREES_PER_RADIAN
            pixel = 1.0
            if scene.display is not None:  # one emitter's transfer function (display.pixel_transfer)
                a = float(scene.display.pixel_width_arcmin) / ARCMIN_PER_RADIAN
                pixel = (np.sinc(a * fy)[:, None] * np.sinc(a * fx)[None, :]).astype(np.complex64)
            # state 0: the paper's reference, the same views focused and rendered at the CDP
            all_acc = np.concatenate([[scene.cdp_D], states])
            for g, ((centre, d_mm), maps) in enumerate(self.groups):
                otfs = _aperture_otfs((centre, d_mm), scene.pupil_mm, all_acc - scene.cdp_D + lca,
                                      self.sa[0] * all_acc, self.sa[1], lam, rho, dx, n_fft, self.edge,
                                      mft_samples, step, scene.display)
                if reference_otfs is not None:  # the ideal display's (diffraction off)
                    ref_otf = _aperture_otfs((centre, d_mm), scene.pupil_mm, [lca], [self.sa[0] * scene.cdp_D],
                                             self.sa[1], lam, rho, dx, n_fft, self.edge, mft_samples,
                                             step, reference_display)[0]
                else:
                    ref_otf = otfs[0]
                # A view at c is displaced by (depth − CDP)·c on the display and by
                # −(accommodation − CDP + LCA)·c by the tilt of the defocus over it (the
                # pipeline's phase −2πW/λ moves the PSF against the wavefront slope).
                # Every member contributes the representative's term (view_groups).
                ref = ref_otf * _view_ramps(-lca * centre[None, None] * 1e-3, fx, fy)[0]
                den += len(maps) * w * float(np.sum(ref.real * wts))
                shifts = (dep - acc - lca)[:, None, None] * centre[None, None] * 1e-3
                part = otfs[1:][state_of_pair] * _view_ramps(shifts, fx, fy) * pixel
                num += len(maps) * w * np.einsum("pyx,yx->p", part.real, wts)
                energy_views += len(maps) * w * float(otfs[-1, 0, 0].real)
                energy_reference += len(maps) * w * float(ref_otf[0, 0].real)
                if keep_otf:
                    rendered[g] += w * part
        if reference_otfs is not None:
            # The pipeline normalises the rendered and the reference OTFs each by its own
            # energy; without diffraction the two energies are equal (the views are the same
            # apertures), with it part of each beam misses the pupil.
            num *= energy_reference / energy_views
        return num, den, rendered

    def vsotf(self, df_cpd: float, pairs, transform: str = "fft", mft_samples: int = 64,
              with_psf: bool = False):
        """Proxy VSOTF per pair; with ``with_psf`` also, for a field of 60/(2·df) arcmin
        (FFT path), the PSF intensity it would wrap back relative to the PSF's peak, and the
        VSOTF error of truncating the PSF there instead (the MFT path)."""
        scene = self.scene
        if with_psf:  # the reference rides along as the last pair (for the truncated VSOTF)
            pairs = (np.append(pairs[0], scene.cdp_D), np.append(pairs[1], scene.cdp_D))
        if transform == "fft":
            n_fft = Sampling(df_cpd, edge_width_samples=self.edge).window_size(
                scene.largest_diameter_mm, float(self.wl.min()), scene.pupil_mm)
            df_rad = df_cpd * DEGREES_PER_RADIAN
            num, den, rendered = self._sums(
                pairs, lambda lam: lam * 1e-6 * df_rad, n_fft, lambda lam: df_cpd, with_psf)
        else:
            # MFT exactly as the pipeline: one pupil grid for all wavelengths, the PSF's
            # point samples on each wavelength band's angles (truncated at the field edge),
            # its OTF at step df — so the field, pupil and quadrature errors are all there.
            span = scene.largest_diameter_mm
            dx_mft = span / (mft_samples - 2.0 * EDGE_EXTENT_SCALES * self.edge - 2.0)
            sampling = Sampling(df_cpd, edge_width_samples=self.edge, transform="mft",
                                mft_pupil_samples=mft_samples)
            bands = wavelength_bands(self.wl, scene.window_mm, scene.pupil_mm, sampling)
            band_n = {float(w): n for a, b, n in bands for w in self.wl[a:b]}
            num, den, rendered = self._sums(
                pairs, lambda lam: dx_mft, 0, lambda lam: df_cpd, False, mft_samples,
                lambda lam: band_n[float(lam)])
        vs = num / den
        if not with_psf:
            return vs
        psf = self._psf(rendered, n_fft)
        energy = psf.sum(axis=(-2, -1))
        h = n_fft // 2
        folded = psf + np.roll(psf, h, -1) + np.roll(psf, h, -2) + np.roll(np.roll(psf, h, -1), h, -2)
        c = slice(n_fft // 2 - h // 2, n_fft // 2 - h // 2 + h)
        wrapped = (folded - psf)[:, c, c].max(axis=(-2, -1)) / psf.max(axis=(-2, -1))
        # Truncated vs periodised field at step df: OTFs from the cropped PSFs, the zero
        # frequency kept at the whole energy (as the pipeline's MFT path sets it).
        wts = _ncsf_half(h, 2.0 * df_cpd, scene.options.ncsf)

        def vsotf_of(crop):
            otf = sfft.rfft2(np.fft.ifftshift(crop, axes=(-2, -1)), workers=-1)
            otf[:, 0, 0] = energy
            sums = np.einsum("pyx,yx->p", otf.real, wts)
            return sums[:-1] / sums[-1]

        truncation = np.abs(vsotf_of(psf[:, c, c]) - vsotf_of(folded[:, c, c]))
        return vs[:-1], wrapped[:-1], float(truncation.max())


    def _psf(self, rendered, n_fft: int) -> np.ndarray:
        """The scene's PSF per pair (n_pairs, n_fft, n_fft), zero angle at the centre, from
        each view group's rendered OTFs: every member adds the representative's PSF mapped
        by its symmetry."""
        psf = 0.0
        for (_, maps), otf_g in zip(self.groups, rendered):
            psf_g = np.fft.fftshift(sfft.irfft2(otf_g, s=(n_fft, n_fft), workers=-1), axes=(-2, -1))
            psf = psf + sum(_map_psf(psf_g, m) for m in maps)
        return psf

    def cutoffs(self, df_cpd: float, pairs, threshold: float) -> np.ndarray:
        """Cut-off frequency (cpd) of the radial MTF per pair, FFT path at step df: the
        frequency where the meridian-averaged MTF first falls to ``threshold``, linearly
        interpolated, as :func:`lfjax.kernel.metrics.cutoff_frequency` reads the pipeline's."""
        return self.vsotf_and_cutoffs(df_cpd, pairs, threshold)[1]

    def vsotf_and_cutoffs(self, df_cpd: float, pairs, threshold: float):
        """(VSOTF, cut-off frequency in cpd) per pair of the FFT path at step df, from one
        set of transforms."""
        n_fft = Sampling(df_cpd, edge_width_samples=self.edge).window_size(
            self.scene.largest_diameter_mm, float(self.wl.min()), self.scene.pupil_mm)
        df_rad = df_cpd * DEGREES_PER_RADIAN
        num, den, rendered = self._sums(pairs, lambda lam: lam * 1e-6 * df_rad, n_fft,
                                        lambda lam: df_cpd, keep_otf=True)
        psf = self._psf(rendered, n_fft)
        otf = sfft.rfft2(np.fft.ifftshift(psf, axes=(-2, -1)), workers=-1)
        modulus = np.abs(otf) / np.abs(otf[:, :1, :1])
        index, weights, k = radial_bins(n_fft)
        radial = np.sum(modulus.reshape(modulus.shape[0], -1)[:, index] * weights, axis=-1)
        return num / den, _first_crossing(radial, k * df_cpd, threshold)


def _first_crossing(radial: np.ndarray, frequencies_cpd: np.ndarray, threshold: float) -> np.ndarray:
    """numpy twin of :func:`lfjax.kernel.metrics.cutoff_frequency` (…, n_freq) → (…,) cpd."""
    below = radial[..., 1:] <= threshold
    idx = np.argmax(below, axis=-1) + 1
    hi = np.take_along_axis(radial, idx[..., None], -1)[..., 0]
    lo = np.take_along_axis(radial, (idx - 1)[..., None], -1)[..., 0]
    frac = np.clip((lo - threshold) / np.where(lo - hi > 0, lo - hi, 1.0), 0.0, 1.0)
    crossing = frequencies_cpd[idx - 1] + frac * (frequencies_cpd[idx] - frequencies_cpd[idx - 1])
    return np.where(below.any(axis=-1), crossing, frequencies_cpd[-1])


def _vertex_peaks(values, pairs) -> np.ndarray:
    """Per depth (sorted): the vertex (D) of the parabola through the largest value and its
    two neighbours in accommodation — how the pipeline's continuous peaks start — or NaN
    where the largest value is at an end of the depth's states. The difference of two
    curves' vertices is their VSOTF difference propagated through the curve's curvature
    (first order: δa = −δV′/V″)."""
    acc, dep = (np.asarray(x, float) for x in pairs)
    values = np.asarray(values, float)
    out = []
    for d in np.unique(dep):
        sel = np.nonzero(dep == d)[0]
        sel = sel[np.argsort(acc[sel])]
        a, v = acc[sel], values[sel]
        i = int(np.argmax(v))
        if i == 0 or i == a.size - 1:
            out.append(np.nan)
            continue
        x0, x1, x2 = a[i - 1:i + 2]
        y0, y1, y2 = v[i - 1:i + 2]
        num = (x1 - x0) ** 2 * (y1 - y2) - (x1 - x2) ** 2 * (y1 - y0)
        den = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0)
        out.append(x1 - 0.5 * num / den if den != 0 else np.nan)
    return np.asarray(out)


def _peak_shift_D(values, reference, pairs) -> float:
    """Largest shift (D) of the proxy's through-focus peak vertices from the reference's;
    inf where one curve has its peak at an end of its states and the other not, or where
    the two pick different grid peaks by more than one state."""
    a, b = _vertex_peaks(values, pairs), _vertex_peaks(reference, pairs)
    if np.any(np.isnan(a) != np.isnan(b)):
        return float("inf")
    both = np.isfinite(a)
    grid_a, grid_b = np.asarray(_peaks(values, pairs)), np.asarray(_peaks(reference, pairs))
    shift = np.where(both, np.abs(a - b), np.abs(grid_a - grid_b))
    return float(np.max(shift)) if shift.size else 0.0


# ----------------------------------------------------------------------------- cost


def _fft_work(bands, n_sub: int) -> float:
    """Relative FFT work per eye and state: per wavelength one complex fft2 of the pupil field
    per view (5 n² log2 n), per band one real rfft2 of the band's summed PSFs (2.5 n² log2 n)."""
    return float(sum(n_sub * n**2 * math.log2(n) * (5.0 * (b - a) + 2.5) for a, b, n in bands))


def _cost_s(bands, n_sub: int, n_states: int, n_modes: int, sampling: Sampling) -> float:
    """Modelled seconds per eye: transforms + pupil evaluation, per band (see module). Each
    wavelength pays its pupil field and its transform to the PSF; each band one rfft2 of its
    summed PSFs (optics._elemental_otfs_band)."""
    total = 0.0
    for start, stop, n in bands:
        n_wl = stop - start
        log = math.log2(n)
        otf_fft = 2.5 * n * n * log / _FFT_FLOPS_PER_S  # once per band
        if sampling.transform == "mft":
            m = sampling.mft_pupil_samples
            per_wavelength = 8.0 * n * m * (m + n) / _MATMUL_FLOPS_PER_S
            pupil = m * m
        else:
            per_wavelength = 5.0 * n * n * log / _FFT_FLOPS_PER_S
            pupil = pupil_window_size(n, sampling) ** 2
        per_wavelength += pupil * _PUPIL_S_PER_SAMPLE
        total += n_sub * n_states * (n_wl * per_wavelength + otf_fft)
    return total


# ----------------------------------------------------------------------------- planner


def _order_rms_um(zernike_um, measured_pupil_mm: float, pupil_mm: float) -> dict[int, float]:
    """Largest (over eyes) wavefront RMS of each radial order inside the calculation pupil, µm."""
    z = np.asarray(zernike_um, float).reshape(-1, np.shape(zernike_um)[-1])
    n = 48
    t = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    xx, yy = np.meshgrid(t, t)
    inside = xx * xx + yy * yy <= 1.0
    scale = pupil_mm / measured_pupil_mm
    basis = np.asarray(zernike_basis(z.shape[1], xx * scale, yy * scale))[:, inside]
    orders = np.array([nm_from_ansi(j)[0] for j in range(z.shape[1])])
    out = {}
    for order in np.unique(orders):
        largest = 0.0
        # blocks of eyes: each eye's wavefront takes 1804 floats here, so the whole
        # population at once would need 14 KB per eye (14 GB for a million)
        for first in range(0, z.shape[0], EYE_BLOCK):
            w = z[first:first + EYE_BLOCK, orders == order] @ basis[orders == order]
            w = w - w.mean(axis=1, keepdims=True)
            largest = max(largest, float(np.sqrt((w * w).mean(axis=1)).max()))
        out[int(order)] = largest
    return out


def _validate(vsotf_tolerance, psf_tolerance, margin, pupil_diameter_mm, wavelength_step_nm,
              peak_tolerance_D=None, cutoff_tolerance_cpd=None, cutoff_threshold=0.05):
    if vsotf_tolerance is None and peak_tolerance_D is None and cutoff_tolerance_cpd is None:
        raise ValueError("give an accuracy target: vsotf_tolerance, peak_tolerance_D or "
                         "cutoff_tolerance_cpd")
    if vsotf_tolerance is not None and not (0 < vsotf_tolerance < 0.5):
        raise ValueError(f"vsotf_tolerance must be in (0, 0.5), got {vsotf_tolerance}")
    if peak_tolerance_D is not None and not (0 < peak_tolerance_D <= 0.5):
        raise ValueError(f"peak_tolerance_D must be in (0, 0.5] D, got {peak_tolerance_D}")
    if cutoff_tolerance_cpd is not None and not (0 < cutoff_tolerance_cpd <= 10):
        raise ValueError(f"cutoff_tolerance_cpd must be in (0, 10] cpd, got {cutoff_tolerance_cpd}")
    if not (0 < cutoff_threshold < 1):
        raise ValueError(f"cutoff_threshold must be in (0, 1), got {cutoff_threshold}")
    if not (0 < psf_tolerance < 1):
        raise ValueError(f"psf_tolerance must be in (0, 1) (fraction of the PSF peak), got {psf_tolerance}")
    if not (margin >= 1):
        raise ValueError(f"margin must be >= 1, got {margin}")
    if not (0 < pupil_diameter_mm <= 10):
        raise ValueError(f"pupil_diameter_mm must be in (0, 10] mm, got {pupil_diameter_mm}")
    if wavelength_step_nm is not None and not (0 < wavelength_step_nm <= 100):
        raise ValueError(f"wavelength_step_nm must be in (0, 100] nm, got {wavelength_step_nm}")


def plan_sampling(
    layout: Layout | None = None,
    pupil_diameter_mm: float = 3.0,
    cdp_D: float = 2.0,
    depths_D=(2.0,),
    accommodation_window_D: float | None = 1.0,
    wavelengths_nm=None,
    eyes_zernike_um=None,
    measured_pupil_mm: float = 3.0,
    options: ModelOptions = ModelOptions(),
    margin: float = 1.05,
    min_samples_per_subaperture: int = 8,
    wrap_tolerance: float = 1e-3,
    edge_width_samples: float = 0.25,
    freq_step_cpd: float | None = None,
    *,
    accommodation_D=None,
    wavelength_range_nm: tuple[float, float] = (400.0, 700.0),
    wavelength_step_nm: float | None = None,
    vsotf_tolerance: float | None = 1e-3,
    psf_tolerance: float = 2e-3,
    peak_tolerance_D: float | None = None,
    cutoff_tolerance_cpd: float | None = None,
    cutoff_threshold: float = 0.05,
    transform: str = "fft",
    mft_pupil_samples: int | None = None,
    max_zernike_order: int | None = None,
    estimate_accuracy: bool = True,
    pairs: tuple | None = None,
    display=None,
    spectral_weights=None,
) -> Plan:
    """Choose the cheapest sampling that meets an accuracy target for a scene, and say why.

    Scene
    -----
    layout : subapertures (default open pupil); pupil_diameter_mm (mm); cdp_D (D)
    depths_D : rendered depths, D
    accommodation_D : absolute accommodation states (array, D) or a (lowest, highest) range
        in D (0.2 D steps); with ``accommodation_window_D`` only states within that many
        dioptres of a depth count (as :func:`lfjax.vision.focus.through_focus`). Without
        ``accommodation_D``: states depth ± ``accommodation_window_D`` (hyperopic limit 0 D).
    wavelengths_nm : the spectrum to use as given; else the planner chooses the step over
        ``wavelength_range_nm`` (or uses ``wavelength_step_nm``)
    eyes_zernike_um : (n_eyes, n_modes) eyes on ``measured_pupil_mm`` (their ray angles
        widen the field; their RMS per order sets the Zernike order)
    options : ModelOptions (LCA, SCE, NCSF and VSOTF reference as the study uses them)

    Accuracy target (in the units of the question; any combination, each one a bound)
    ---------------
    vsotf_tolerance : largest VSOTF error (absolute) against a converged sampling; None:
        no VSOTF target (then every Zernike order is kept)
    peak_tolerance_D : largest shift of a through-focus peak, D: the proxy's VSOTF error
        propagated through each curve's curvature (the vertex of the parabola through the
        peak and its neighbours, candidate against converged); half of it for the
        wavelength step, half for the frequency step
    cutoff_tolerance_cpd : largest shift of a cut-off frequency, cpd (the proxy's radial MTF
        at each depth's peak state falling to ``cutoff_threshold``; the MTF's error read
        through its slope); split as the peak target
    psf_tolerance : largest PSF intensity wrapped back into the field, relative to its peak
    Without ``peak_tolerance_D`` the wavelength step must also leave every proxy
    through-focus grid peak where it was.

    Overrides (each fixes one choice; the rest is still planned)
    ---------
    freq_step_cpd : frequency step, cpd (raises if the aliasing guard would refuse it)
    transform : "fft" (default), "mft", or "auto" (the cheaper by the cost model). The MFT
        proxy is the pipeline's MFT path (tested); forced MFT plans met a 1e-3 target on an
        open pupil, 2×2 and 4×4 with one pupil step cheaper failing (RESULTS §7). "auto" is
        opt-in because its cost model rests on four calibration runs on one machine.
    mft_pupil_samples, wavelength_step_nm, max_zernike_order, edge_width_samples

    estimate_accuracy : False skips the proxy (the field guard alone picks the step, in a
        few milliseconds; errors are reported as NaN)
    pairs : (accommodation_D, depths_D) arrays of the exact pairs to plan for, D; replaces
        the pairs ``depths_D``/``accommodation_D``/``accommodation_window_D`` describe
    display : :class:`lfjax.display.lenslets.DisplayOptics` of a real display (lenslet diffraction,
        pixels): the field guard adds their blur and the proxy models them as the pipeline
    spectral_weights : weights of ``wavelengths_nm`` when they are not V(λ)'s (a display's
        spectrum, :mod:`lfjax.display.spectra`): the guard then leaves out the wavelengths
        this spectrum weighs least, not V(λ)'s

    Guard parameters: margin (field safety factor ≥ 1), wrap_tolerance (spectral weight
    allowed to wrap), min_samples_per_subaperture (floor on pupil samples).
    """
    _validate(vsotf_tolerance, psf_tolerance, margin, pupil_diameter_mm, wavelength_step_nm,
              peak_tolerance_D, cutoff_tolerance_cpd, cutoff_threshold)
    if transform not in ("auto", "fft", "mft"):
        raise ValueError(f"transform must be 'auto', 'fft' or 'mft', got {transform!r}")
    if transform != "fft" and vsotf_tolerance is None and estimate_accuracy:
        raise ValueError(f"transform={transform!r} plans the MFT's pupil samples for a VSOTF "
                         "target: give vsotf_tolerance (the D / cpd targets plan the FFT path)")
    layout = open_pupil(pupil_diameter_mm) if layout is None else layout
    if pairs is None:
        pair_acc, pair_depth = _scene_pairs(depths_D, accommodation_D, accommodation_window_D)
    else:
        pair_acc, pair_depth = (np.asarray(x, float).reshape(-1) for x in pairs)
    if np.any(pair_acc < -1e-9) or np.any(pair_depth < 0):
        raise ValueError("accommodation and depths must be >= 0 D")
    scene = _Scene(layout, float(pupil_diameter_mm), float(cdp_D), pair_acc, pair_depth, options,
                   display)
    window_mm = scene.window_mm
    reasons: list[str] = []

    # --- spectrum
    if wavelengths_nm is not None:
        wl = np.atleast_1d(np.asarray(wavelengths_nm, float))
        step_choice = None
    else:
        lo, hi = map(float, wavelength_range_nm)
        if not (hi > lo):
            raise ValueError(f"wavelength_range_nm must be increasing, got {wavelength_range_nm}")
        step_choice = wavelength_step_nm
        wl = None
    # Without a VSOTF target the VSOTF budget is unbounded: the D/cpd targets decide.
    budget = math.inf if vsotf_tolerance is None else float(vsotf_tolerance)

    # --- Zernike order
    errors: dict[str, float] = {}
    order_kept = max_zernike_order
    if eyes_zernike_um is not None and vsotf_tolerance is None and order_kept is None:
        errors["zernike"] = 0.0
        reasons.append("Zernike: every order kept (no VSOTF target to spend on truncation)")
    elif eyes_zernike_um is not None:
        rms = _order_rms_um(eyes_zernike_um, measured_pupil_mm, pupil_diameter_mm)
        orders = sorted(o for o in rms if o >= 2)
        if order_kept is None:
            order_kept = orders[-1] if orders else None
            for keep in orders:
                rest = math.sqrt(sum(rms[o] ** 2 for o in orders if o > keep))
                if (2 * math.pi * rest / 0.555) ** 2 <= 0.1 * vsotf_tolerance:
                    order_kept = keep
                    break
        rest = math.sqrt(sum(rms[o] ** 2 for o in rms if order_kept is not None and o > order_kept))
        errors["zernike"] = (2 * math.pi * rest / 0.555) ** 2
        reasons.append(
            f"Zernike: order ≤ {order_kept} kept; RMS above it {rest * 1e3:.2g} nm → VSOTF change "
            f"≈ (2πσ/λ)² = {errors['zernike']:.2g} (budget 10 % of the tolerance)"
        )
    else:
        errors["zernike"] = 0.0
    budget -= errors["zernike"]

    # --- field guard (hard): the pipeline's own rule
    guard_wl = wl if wl is not None else np.arange(wavelength_range_nm[0], wavelength_range_nm[1] + 1e-6, 5.0)
    if spectral_weights is not None and wl is None:
        raise ValueError("spectral_weights needs wavelengths_nm (the wavelengths they weigh)")
    guard_spectrum = make_spectrum(guard_wl, options, weights=spectral_weights)
    radius = field_radius_arcmin(
        eyes_zernike_um, measured_pupil_mm, pupil_diameter_mm, cdp_D, scene.accommodation,
        pair_acc, pair_depth, layout, guard_spectrum, wrap_tolerance, display,
    )
    df_guard = 30.0 / (radius * margin)
    reasons.append(
        f"field guard: blur reaches {radius:.1f} arcmin (defocus, LCA, display shifts, "
        f"diffraction, eyes' ray angles); ×{margin} margin → df ≤ {df_guard:.3g} cpd"
    )
    d_min = scene.smallest_diameter_mm
    df_floor_samples = d_min / (float(guard_wl.max()) * 1e-6 * min_samples_per_subaperture) / DEGREES_PER_RADIAN
    df_top = ladder_floor(min(df_guard, df_floor_samples))

    # --- wavelength step
    if wl is None:
        spec_proxy_df = ladder_floor(min(df_top, d_min / (float(guard_wl.max()) * 1e-6 * 24) / DEGREES_PER_RADIAN))
        peak = _peak_neighbourhood(scene.pair_depth)
        lo, hi = map(float, wavelength_range_nm)

        def proxy_spectrum(step):
            grid = np.arange(lo, hi + 1e-6, step)
            return _Proxy(scene, make_spectrum(grid, options), edge_width_samples,
                          n_wavelengths=grid.size)

        def curves(proxy_step):
            if cutoff_tolerance_cpd is None:
                return proxy_step.vsotf(spec_proxy_df, peak), None
            return proxy_step.vsotf_and_cutoffs(spec_proxy_df, peak, cutoff_threshold)

        ref, ref_cut = curves(proxy_spectrum(SPECTRAL_REFERENCE_STEP_NM))
        ref_peak = _peaks(ref, peak)
        # Cut-offs at each depth's peak state and its neighbours 0.1 D away, not the peak
        # alone: a real eye's aberrations blur it like a little defocus, and a blurred MTF
        # crosses the threshold with a shallower slope, where a spectral error moves it
        # more. Farther out the defocused MTF oscillates about the threshold and its first
        # crossing jumps between lobes: no predicted accommodation sits there.
        near_peak = np.abs(peak[0] - np.asarray(ref_peak)[
            np.searchsorted(np.unique(peak[1]), peak[1])]) <= 0.1 + 1e-9
        candidates = [step_choice] if step_choice is not None else [
            s for s in WAVELENGTH_STEPS_NM if abs((hi - lo) / s - round((hi - lo) / s)) < 1e-9
            and s > SPECTRAL_REFERENCE_STEP_NM]
        chosen = None
        for step in candidates:
            v, cuts = curves(proxy_spectrum(step))
            err = float(np.max(np.abs(v - ref)))
            same_peak = _peaks(v, peak) == ref_peak
            shift = _peak_shift_D(v, ref, peak)
            cut = (float(np.max(np.abs(cuts - ref_cut)[near_peak])) if cuts is not None
                   else float("nan"))
            ok = err <= 0.5 * budget
            ok &= shift <= 0.5 * peak_tolerance_D if peak_tolerance_D is not None else same_peak
            ok &= cutoff_tolerance_cpd is None or cut <= 0.5 * cutoff_tolerance_cpd
            if step_choice is not None or ok:
                chosen, errors["spectral"] = step, err
                errors["spectral_peak_D"], errors["spectral_cutoff_cpd"] = shift, cut
                reasons.append(
                    f"wavelength step {step:g} nm against {SPECTRAL_REFERENCE_STEP_NM:g} nm on the proxy: VSOTF error "
                    f"{err:.2g} (budget {0.5 * budget:.2g}), peaks "
                    + (f"moved ≤ {shift:.2g} D (budget {0.5 * peak_tolerance_D:.2g})"
                       if peak_tolerance_D is not None else
                       ('unchanged' if same_peak else 'MOVED'))
                    + (f", cut-offs moved ≤ {cut:.2g} cpd (budget {0.5 * cutoff_tolerance_cpd:.2g})"
                       if cutoff_tolerance_cpd is not None else "")
                    + (" (user's step)" if step_choice is not None else "")
                )
                break
        if chosen is None:  # no coarser step meets the targets: the reference's own step
            chosen = SPECTRAL_REFERENCE_STEP_NM
            errors["spectral"] = 0.0
            errors["spectral_peak_D"] = errors["spectral_cutoff_cpd"] = 0.0
            reasons.append(f"wavelength step {chosen:g} nm: the reference step (no coarser "
                           f"candidate met the targets)")
        wl = np.arange(lo, hi + 1e-6, chosen)
        # The guard ran on a 5 nm grid; on the chosen, coarser grid each wavelength carries
        # more of the weight, so the blue and red ends may no longer be light enough to let
        # wrap. The field must hold the spectrum the pipeline will sum.
        radius = max(radius, field_radius_arcmin(
            eyes_zernike_um, measured_pupil_mm, pupil_diameter_mm, cdp_D, scene.accommodation,
            pair_acc, pair_depth, layout, make_spectrum(wl, options), wrap_tolerance, display,
        ))
        if 30.0 / (radius * margin) < df_guard:
            df_guard = 30.0 / (radius * margin)
            df_top = ladder_floor(min(df_guard, df_floor_samples))
            reasons.append(f"field guard on the chosen {chosen:g} nm grid: blur reaches "
                           f"{radius:.1f} arcmin → df ≤ {df_guard:.3g} cpd")
    else:
        errors["spectral"] = float("nan")
        if wl.size > 1 and np.any(np.diff(wl) > 20.0):
            reasons.append("warning: wavelength steps over 20 nm under-sample LCA blur (Ravikumar et al. 2008; "
                           "benchmarks/speed_accuracy.py: 50 nm moves a prediction by 0.2 D)")
    if np.isfinite(errors["spectral"]):
        budget -= errors["spectral"]
    spectrum = make_spectrum(wl, options, weights=spectral_weights)
    weights_kept = None if spectral_weights is None else tuple(float(w) for w in spectral_weights)
    if not estimate_accuracy:
        df = float(freq_step_cpd) if freq_step_cpd is not None else df_top
        if df > df_guard * margin:
            raise ValueError(
                f"freq_step_cpd={df} aliases: the scene's blur ({radius:.1f} arcmin) needs "
                f"freq_step_cpd <= {df_guard * margin:.3g} cpd")
        sampling = Sampling(df, edge_width_samples=edge_width_samples)
        bands = wavelength_bands(wl, window_mm, pupil_diameter_mm, sampling)
        reasons.append(f"field guard only (estimate_accuracy=False): df {df:.4g} cpd")
        errors.update(pupil=float("nan"), psf_wrap=float("nan"), total=float("nan"))
        return Plan(sampling, tuple(float(x) for x in wl), order_kept, float(radius),
                    float(df_guard), errors, {}, {}, bands, _fft_work(bands, layout.n_subapertures),
                    options, reasons, weights_kept)

    # --- frequency step (field + pupil sampling for the FFT path; field only for MFT)
    proxy = _Proxy(scene, spectrum, edge_width_samples)
    pairs = (scene.pair_acc, scene.pair_depth)  # all of them: the error peaks anywhere
    cheaper: dict = {}
    if freq_step_cpd is not None:
        if freq_step_cpd > df_guard * margin:
            raise ValueError(
                f"freq_step_cpd={freq_step_cpd} aliases: the scene's blur ({radius:.1f} arcmin) "
                f"needs freq_step_cpd <= {df_guard * margin:.3g} cpd"
            )
        df_candidates = [float(freq_step_cpd)]
    else:
        df_candidates = [df_top / 2.0 ** (k / STEPS_PER_OCTAVE) for k in range(0, 24)]
    fft_plan = None
    mft_field = None
    estimates = _Estimates(proxy, pairs, df_candidates[0],
                           budget if math.isfinite(budget) else 1e-3)
    # what the wavelength step left of the D / cpd targets (all of them for a given spectrum)
    peak_budget = cutoff_budget = None
    if peak_tolerance_D is not None:
        peak_budget = peak_tolerance_D - np.nan_to_num(errors.get("spectral_peak_D", 0.0))
    if cutoff_tolerance_cpd is not None:
        cutoff_budget = cutoff_tolerance_cpd - np.nan_to_num(errors.get("spectral_cutoff_cpd", 0.0))
    found_at = None
    for i, df in enumerate(df_candidates):
        if fft_plan is not None and (mft_field is not None or transform == "fft" or i > found_at + 3):
            break
        e_pupil = estimates.vsotf(df)
        meets = e_pupil <= budget
        if meets and peak_budget is not None:
            meets = estimates.peak_shift(df) <= peak_budget
        if meets and cutoff_budget is not None:
            meets = estimates.cutoff_shift(df, cutoff_threshold) <= cutoff_budget
        want_fft = fft_plan is None and (meets or freq_step_cpd is not None)
        want_mft = transform != "fft" and mft_field is None
        if not (want_fft or want_mft):
            continue  # the PSF on twice the field is the costly part: only where it decides
        wrapped, truncation = estimates.psf(df)
        psf_ok = wrapped <= psf_tolerance
        # MFT truncates the PSF at the field edge: it may need a finer step than the FFT
        if want_mft and ((psf_ok and truncation <= 0.25 * budget) or freq_step_cpd is not None):
            mft_field = (df, wrapped, truncation)
        if want_fft and (psf_ok or freq_step_cpd is not None):
            fft_plan, found_at = (df, e_pupil, wrapped), i
    if fft_plan is None:
        raise ValueError(
            f"no frequency step down to {df_candidates[-1]:.3g} cpd meets vsotf_tolerance="
            f"{vsotf_tolerance:g} and psf_tolerance={psf_tolerance:g}; loosen the target"
        )
    df_fft, e_pupil_fft, wrap_fft = fft_plan

    # --- MFT: field step from the PSF criterion, pupil samples from the VSOTF budget
    n_modes = np.shape(eyes_zernike_um)[-1] if eyes_zernike_um is not None else 15
    if order_kept is not None:
        n_modes = min(n_modes, n_modes_for_order(order_kept))
    n_states = scene.accommodation.size
    fft_sampling = Sampling(df_fft, edge_width_samples=edge_width_samples)
    fft_bands = wavelength_bands(wl, window_mm, pupil_diameter_mm, fft_sampling)
    cost = {"fft": _cost_s(fft_bands, layout.n_subapertures, n_states, n_modes, fft_sampling)}
    mft_plan = None
    if transform in ("auto", "mft") and mft_field is not None:
        df_mft = mft_field[0]
        mft_budget = budget  # the MFT proxy truncates the PSF itself: its error includes the field's
        if mft_pupil_samples is not None:
            ladder = [mft_pupil_samples]
        else:
            # start just below the samples the FFT plan puts across the largest view
            fft_samples = scene.largest_diameter_mm / (float(wl.max()) * 1e-6 * df_fft * DEGREES_PER_RADIAN)
            start = max([i for i, m in enumerate(MFT_PUPIL_LADDER) if m <= 0.6 * fft_samples], default=0)
            while start > 0 and estimates.mft(df_mft, MFT_PUPIL_LADDER[start]) <= mft_budget:
                start -= 1
            ladder = list(MFT_PUPIL_LADDER[start:])
        for m in ladder:
            e = estimates.mft(df_mft, m)
            if e <= mft_budget or mft_pupil_samples is not None:
                s = Sampling(df_mft, edge_width_samples=edge_width_samples, transform="mft",
                             mft_pupil_samples=m)
                bands = wavelength_bands(wl, window_mm, pupil_diameter_mm, s)
                mft_plan = (s, e, mft_field[1], bands)
                cost["mft"] = _cost_s(bands, layout.n_subapertures, n_states, n_modes, s)
                break
    use_mft = mft_plan is not None and (
        transform == "mft" or (transform == "auto" and cost["mft"] < cost["fft"])
    )
    if use_mft:
        sampling, errors["pupil"], errors["psf_wrap"], bands = mft_plan
        reasons.append(
            f"MFT: {sampling.mft_pupil_samples} pupil samples (VSOTF error {errors['pupil']:.2g}), "
            f"df {sampling.freq_step_cpd:.4g} cpd; modelled {cost['mft']:.3g} s vs FFT {cost['fft']:.3g} s per eye"
        )
        m = sampling.mft_pupil_samples
        cheaper_m = max([x for x in MFT_PUPIL_LADDER if x < m], default=None)
        if cheaper_m is not None:
            e = estimates.mft(sampling.freq_step_cpd, cheaper_m)
            cheaper["pupil"] = (dataclasses.replace(sampling, mft_pupil_samples=cheaper_m),
                                f"{cheaper_m} MFT pupil samples: VSOTF error {e:.2g} > budget {budget:.2g}")
    else:
        sampling, errors["pupil"], errors["psf_wrap"], bands = fft_sampling, e_pupil_fft, wrap_fft, fft_bands
        reasons.append(
            f"FFT: df {df_fft:.4g} cpd → {d_min / (float(wl.max()) * 1e-6 * df_fft * DEGREES_PER_RADIAN):.1f} "
            f"pupil samples across the smallest subaperture ({d_min:.3g} mm) at {wl.max():g} nm; "
            f"proxy VSOTF error {e_pupil_fft:.2g} (budget {budget:.2g}), wrapped PSF/peak "
            f"{wrap_fft:.2g} (tolerance {psf_tolerance:g})"
            + (f"; MFT would cost {cost['mft']:.3g} s vs {cost['fft']:.3g} s per eye (modelled)"
               if "mft" in cost else "")
        )
    # --- one step cheaper, per dimension, and why it fails
    if freq_step_cpd is None:
        up = ladder_up(sampling.freq_step_cpd)
        if up > df_guard:
            cheaper["field"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                f"df {up:.4g} cpd: refused by the aliasing guard (needs ≤ {df_guard:.4g})")
        else:
            e, (wrapped_up, _) = estimates.vsotf(up), estimates.psf(up)
            if not use_mft:
                if e > budget:
                    cheaper["pupil"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                        f"df {up:.4g} cpd: VSOTF error {e:.2g} > budget {budget:.2g}")
                elif peak_budget is not None and estimates.peak_shift(up) > peak_budget:
                    cheaper["pupil"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                        f"df {up:.4g} cpd: peaks shift {estimates.peak_shift(up):.2g} D "
                                        f"> {peak_budget:.2g} D")
                elif (cutoff_budget is not None
                      and estimates.cutoff_shift(up, cutoff_threshold) > cutoff_budget):
                    cheaper["pupil"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                        f"df {up:.4g} cpd: cut-offs shift "
                                        f"{estimates.cutoff_shift(up, cutoff_threshold):.2g} cpd "
                                        f"> {cutoff_budget:.2g} cpd")
            if wrapped_up > psf_tolerance:
                cheaper["field"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                    f"df {up:.4g} cpd: wrapped PSF/peak {wrapped_up:.2g} > {psf_tolerance:g}")
    if peak_tolerance_D is not None and not use_mft:
        errors["peak_D"] = np.nan_to_num(errors.get("spectral_peak_D", 0.0)) + \
            estimates.peak_shift(sampling.freq_step_cpd)
        reasons.append(f"peaks: proxy shift ≤ {errors['peak_D']:.2g} D (target {peak_tolerance_D:g} D)")
    if cutoff_tolerance_cpd is not None and not use_mft:
        errors["cutoff_cpd"] = np.nan_to_num(errors.get("spectral_cutoff_cpd", 0.0)) + \
            estimates.cutoff_shift(sampling.freq_step_cpd, cutoff_threshold)
        reasons.append(f"cut-offs: proxy shift ≤ {errors['cutoff_cpd']:.2g} cpd "
                       f"(target {cutoff_tolerance_cpd:g} cpd)")
    errors["total"] = errors["pupil"] + errors["zernike"] + (
        errors["spectral"] if np.isfinite(errors["spectral"]) else 0.0)
    return Plan(
        sampling, tuple(float(x) for x in wl), order_kept, float(radius), float(df_guard), errors,
        cost, cheaper, bands, _fft_work(bands, layout.n_subapertures), options, reasons,
        weights_kept,
    )


PEAK_NEIGHBOURHOOD_D = np.round(np.arange(-3, 4) * 0.1, 9)
"""States (D from each rendered depth) where the wavelength step's proxy reads peaks and
cut-offs: fine enough for a parabola vertex whatever the scene's accommodation grid (on a
0.5 D grid the scene's own states near a depth would be one), wide enough to hold the
aberration-free proxy's peak."""


def _peak_neighbourhood(pair_depth) -> tuple[np.ndarray, np.ndarray]:
    """(accommodation, depth) pairs: every rendered depth ± :data:`PEAK_NEIGHBOURHOOD_D`,
    states ≥ 0 D (the hyperopic limit)."""
    depths = np.unique(np.asarray(pair_depth, float))
    acc = depths[:, None] + PEAK_NEIGHBOURHOOD_D[None, :]
    dep = np.broadcast_to(depths[:, None], acc.shape)
    keep = acc >= -1e-9
    return np.clip(acc[keep], 0.0, None), dep[keep]


def _peak_states(values, pairs) -> tuple[np.ndarray, np.ndarray]:
    """(accommodation, depth) of each depth's largest value: one pair per depth."""
    acc, dep = pairs
    depths = np.unique(dep)
    return np.asarray(_peaks(values, pairs)), depths


def _peaks(values, pairs) -> tuple:
    """Index of the largest value per depth (proxy through-focus peaks)."""
    acc, dep = pairs
    out = []
    for d in np.unique(dep):
        sel = np.nonzero(dep == d)[0]
        out.append(float(acc[sel[np.argmax(values[sel])]]))
    return tuple(out)


__all__ = ["Plan", "plan_sampling", "ladder_floor", "ladder_up", "STEPS_PER_OCTAVE",
           "MFT_PUPIL_LADDER", "WAVELENGTH_STEPS_NM"]
