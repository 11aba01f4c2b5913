"""The planner's proxy: the scene's optics for an aberration-free eye, in numpy.

The proxy is the scene as the paper's ideal display makes it (or a real display's, with
lenslet diffraction and pixels), for an aberration-free eye: each view's aperture (lfjax's
logistic, area-exact edge, Stiles–Crawford apodisation) is transformed with the local
defocus of the accommodation state plus LCA and the accommodation spherical aberration,
and enters with its display shift and the tilt of the defocus over it as one phase ramp.
Views congruent under the square's mirrors and quarter turns share one transform (their
VSOTF terms are equal, their PSFs mapped copies: :meth:`~lfjax.planner.scene.PlanScene.view_groups`).
For the aberration-free eye the proxy's VSOTF equals the pipeline's to < 1e-6 at any step
(tests/planner/test_plan.py), so its error estimates are the pipeline's own; the proxy thins a
spectrum to at most :data:`PROXY_WAVELENGTHS` wavelengths.

It runs in float64 numpy on the host and compiles nothing. It shares the metrics' NCSF on
the half plane, their radial bins and their cut-off rule (:mod:`lfjax.kernel.metrics`, on
numpy arrays); the apertures' Fresnel propagator it cannot share (``_fresnel_np`` says why).

:class:`Estimates` turns proxy runs into the plan's error estimates: VSOTF errors against a
converged (Richardson-extrapolated) proxy value, through-focus peak shifts (D) and cut-off
shifts (cpd), the wrapped PSF.
"""

from __future__ import annotations

import math

import numpy as np

from lfjax.base.sampling import EDGE_EXTENT_SCALES, Sampling, next_fast_size, wavelength_bands
from lfjax.base.units import DEGREES_PER_RADIAN
from lfjax.display.lenslets import DisplayOptics
from lfjax.base.parabola import parabola_vertex
from lfjax.kernel.metrics import cutoff_frequency, ncsf_half_plane, radial_bins
from lfjax.kernel.optics import pupil_window_size, sa_parameters
from lfjax.model.spectral import Spectrum
from lfjax.planner.scene import PlanScene, map_psf

ESTIMATE_SAFETY = 1.05
"""Factor on the proxy's VSOTF error estimates (calibration against the pipeline:
benchmarks/validation/planner_validation.py)."""

PROXY_WAVELENGTHS = 7
"""Most wavelengths the proxy evaluates; a longer spectrum is thinned, each kept wavelength
taking the V(λ) weight of its nearest neighbours (a cost bound on planning; the validation
scenes use 3 wavelengths, so this thinning is not what they test)."""



def _sfft():
    """:mod:`scipy.fft`, imported when the proxy first transforms: 0.4 s that a run whose
    plans all come from the plan cache need not pay."""
    import scipy.fft

    return scipy.fft

def _subsample_spectrum(spectrum: Spectrum, n_max: int = PROXY_WAVELENGTHS):
    """At most ``n_max`` wavelengths, each carrying the weight of its nearest neighbours."""
    wl = np.asarray(spectrum.wavelengths_nm, float)
    w = np.asarray(spectrum.weights, float)
    keep = np.unique(np.round(np.linspace(0, wl.size - 1, min(n_max, wl.size))).astype(int))
    nearest = np.argmin(np.abs(wl[:, None] - wl[keep][None, :]), axis=1)
    weights = np.bincount(nearest, weights=w, minlength=keep.size)
    return (wl[keep], weights / weights.sum(), np.asarray(spectrum.lca_D, float)[keep],
            np.asarray(spectrum.sce_rho_per_mm2, float)[keep])


def _aperture_otfs(view, pupil_mm, wavefront, wavelength_nm, rho, dx_mm, n_fft, edge_samples,
                   mft_samples: int | None = None, df_cpd: float | None = None, display=None):
    """Half-plane OTFs (n_states, L, L//2+1), lag step dx, of one view — subaperture
    ``view`` = (centre mm, diameter mm) clipped by the pupil — at each state's
    ``wavefront`` = (local defocus (n_states,) D, accommodation SA c(4,0) (n_states,) µm,
    the radius (mm) the SA's pupil coordinates are normalised by): the pipeline's aperture
    (optics._pupil_parts) on one window, complex64 FFTs. OTF(0) is the transmitted energy
    (mm²), as in the pipeline.

    With ``mft_samples``: the pipeline's MFT path instead — ``mft_samples``² pupil samples,
    the PSF's point samples on the n_fft angles of a field 60/``df_cpd`` arcmin (truncated,
    not wrapped), and its OTF at step ``df_cpd``.

    With ``display`` (:class:`lfjax.display.lenslets.DisplayOptics`): square subapertures and lenslet
    diffraction as the pipeline models them (the window is then the whole pupil and the
    view's beam its Fresnel pattern, :func:`_fresnel_np`)."""
    centre, d_mm = view
    defocus_D, sa_c40_um, sa_radius_mm = wavefront
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
        otf = _sfft().rfft2(psf, workers=-1) * (dx_mm**4 * pixel_rad**2 / wl_mm**2)
    else:
        spec = _sfft().fft2(field_, s=(n_fft, n_fft), workers=-1)
        psf = (spec.real**2 + spec.imag**2).astype(np.float32)
        otf = _sfft().rfft2(psf, workers=-1) * (dx_mm * dx_mm / n_fft**2)
    otf[:, 0, 0] = energy
    return otf


# Not apertures.fresnel_propagate: that is float32 JAX compiled per size; the proxy is float64 NumPy
def _fresnel_np(field, dx_mm, wavelength_mm, distance_mm, extent_mm):
    """numpy twin of :func:`lfjax.base.apertures.fresnel_propagate` (the same kernel sampling:
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


class Proxy:
    """Aberration-free proxy of a scene on one candidate sampling (see module docstring).

    Views congruent under the square's symmetries form a group (the corner, edge and inner
    views of a grid); each group's representative is transformed once per wavelength and
    state, and its members contribute its VSOTF term and its mapped PSF (view_groups).
    """

    def __init__(self, scene: PlanScene, spectrum: Spectrum, edge_samples: float, n_wavelengths=None):
        self.scene = scene
        sub = _subsample_spectrum(spectrum, n_wavelengths or PROXY_WAVELENGTHS)
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
            wts = ncsf_half_plane(n_fft, step, scene.options.ncsf, host=True) * step**2
            fy = np.fft.fftfreq(n_fft, 1.0 / n_fft) * step * DEGREES_PER_RADIAN
            fx = np.fft.rfftfreq(n_fft, 1.0 / n_fft) * step * DEGREES_PER_RADIAN
            pixel = 1.0
            if scene.display is not None:  # one emitter's transfer function (display.pixel_transfer)
                a = float(scene.display.pixel_width_rad)
                b = float(scene.display.pixel_height_rad)  # a lenticular view's differs
                pixel = (np.sinc(b * fy)[:, None] * np.sinc(a * fx)[None, :]).astype(np.complex64)
            # state 0: the paper's reference, the same views focused and rendered at the CDP
            all_acc = np.concatenate([[scene.cdp_D], states])
            for g, ((centre, d_mm), maps) in enumerate(self.groups):
                otfs = _aperture_otfs((centre, d_mm), scene.pupil_mm,
                                      (all_acc - scene.cdp_D + lca, self.sa[0] * all_acc, self.sa[1]),
                                      lam, rho, dx, n_fft, self.edge, mft_samples, step,
                                      scene.display)
                if reference_otfs is not None:  # the ideal display's (diffraction off)
                    ref_otf = _aperture_otfs((centre, d_mm), scene.pupil_mm,
                                             ([lca], [self.sa[0] * scene.cdp_D], self.sa[1]),
                                             lam, rho, dx, n_fft, self.edge, mft_samples, step,
                                             reference_display)[0]
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
        wts = ncsf_half_plane(h, 2.0 * df_cpd, scene.options.ncsf, host=True)

        def vsotf_of(crop):
            otf = _sfft().rfft2(np.fft.ifftshift(crop, axes=(-2, -1)), workers=-1)
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
            psf_g = np.fft.fftshift(_sfft().irfft2(otf_g, s=(n_fft, n_fft), workers=-1), axes=(-2, -1))
            psf = psf + sum(map_psf(psf_g, m) for m in maps)
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
        otf = _sfft().rfft2(np.fft.ifftshift(psf, axes=(-2, -1)), workers=-1)
        modulus = np.abs(otf) / np.abs(otf[:, :1, :1])
        index, weights, k = radial_bins(n_fft)
        radial = np.sum(modulus.reshape(modulus.shape[0], -1)[:, index] * weights, axis=-1)
        return num / den, cutoff_frequency(radial, k * df_cpd, threshold)


def vertex_peaks(values, pairs) -> np.ndarray:
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
        out.append(float(parabola_vertex(a, v, np.asarray(i))))
    return np.asarray(out)


def peak_shift_D(values, reference, pairs) -> float:
    """Largest shift (D) of the proxy's through-focus peak vertices from the reference's;
    inf where one curve has its peak at an end of its states and the other not, or where
    the two pick different grid peaks by more than one state."""
    a, b = vertex_peaks(values, pairs), vertex_peaks(reference, pairs)
    if np.any(np.isnan(a) != np.isnan(b)):
        return float("inf")
    both = np.isfinite(a)
    grid_a, grid_b = np.asarray(grid_peaks(values, pairs)), np.asarray(grid_peaks(reference, pairs))
    shift = np.where(both, np.abs(a - b), np.abs(grid_a - grid_b))
    return float(np.max(shift)) if shift.size else 0.0


class Estimates:
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
        return ESTIMATE_SAFETY * peak_shift_D(self.values(df), self.converged, self.pairs)

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


def _peak_states(values, pairs) -> tuple[np.ndarray, np.ndarray]:
    """(accommodation, depth) of each depth's largest value: one pair per depth."""
    acc, dep = pairs
    depths = np.unique(dep)
    return np.asarray(grid_peaks(values, pairs)), depths


def grid_peaks(values, pairs) -> tuple:
    """Index of the largest value per depth (proxy through-focus peaks)."""
    acc, dep = pairs
    out = []
    for d in np.unique(dep):
        sel = np.nonzero(dep == d)[0]
        out.append(float(acc[sel[np.argmax(values[sel])]]))
    return tuple(out)


__all__ = ["Proxy", "Estimates", "PROXY_WAVELENGTHS", "ESTIMATE_SAFETY", "grid_peaks",
           "peak_shift_D", "vertex_peaks"]
