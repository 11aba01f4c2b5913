"""Wave optics of the eye: generalised pupil functions, elemental OTFs, polychromatic OTFs.

Conventions (docs/design.md#conventions): pupil function ``A · exp(−i 2π W / λ)``; PSF = |forward DFT|²
(a positive x-tilt c(1,1) moves the PSF towards −x); OTF = forward DFT of the PSF. Arrays
are ``[y, x]``; OTFs are in FFT order (index 0 is zero frequency, ``k·df`` with k from
``fftfreq``). The PSF is never re-centred: light-field displacements are signal.

The expensive part is computed once per eye: for every wavelength λ, accommodation state
a and subaperture n the elemental OTF on a window sized to that subaperture; every
rendered depth is then a phase ramp and a sum (docs/design.md#why-it-is-fast).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.ad_checkpoint import checkpoint_name

from lfjax.base.types import FULL, is_concrete
from lfjax.base.apertures import aperture_edge_distance, disk_edge_distance, fresnel_propagate, safe_sqrt
from lfjax.base.apertures import soft_disk as soft_disk
from lfjax.model.layouts import Layout
from lfjax.base.sampling import (
    EDGE_EXTENT_SCALES,
    Sampling,
    blur_radius_arcmin,
    check_field,
    eye_slope_rad,
)
from lfjax.base.sampling import frequencies_cpd as frequencies_cpd
from lfjax.base.sampling import half_frequencies_cpd as half_frequencies_cpd
from lfjax.kernel.scene import Accommodation, Scene
from lfjax.kernel.scene import sa_c40_um as sa_c40_um
from lfjax.kernel.scene import sa_parameters as sa_parameters
from lfjax.model.spectral import Spectrum
from lfjax.base.units import DEGREES_PER_RADIAN, check_dioptres, dioptres_to_c20_um
from lfjax.base.zernike import monomial_coefficients, nm_from_ansi, powers_of, wavefront_on_grid, wavefront_um

# ----------------------------------------------------------------------------- core


def _window_coordinates(centre_mm, n_samples: int, dx_mm, n_samples_x: int | None = None):
    """Pupil coordinates (mm) of an n_samples (y) × ``n_samples_x`` (x, default n_samples)
    window centred on ``centre_mm``, [y, x]."""
    n_x = n_samples if n_samples_x is None else n_samples_x
    x = centre_mm[0] + (jnp.arange(n_x, dtype=dx_mm.dtype) - (n_x // 2)) * dx_mm
    y = centre_mm[1] + (jnp.arange(n_samples, dtype=dx_mm.dtype) - (n_samples // 2)) * dx_mm
    return jnp.meshgrid(x, y)  # [y, x]


def _pupil_parts(
    pupil_diameter_mm, centre_mm, diameter_mm, dx_mm, sce_rho, n_pupil: int,
    edge_width_samples: float, wavelength_mm=None, display=None, n_pupil_x: int | None = None,
):
    """Amplitude (real, or complex with lenslet diffraction) and transmitted energy (mm²)
    of one subaperture window (n_pupil × ``n_pupil_x`` samples, [y, x])."""
    shape = "circle" if display is None else display.aperture
    diffracts = display is not None and display.diffracts
    xx, yy = _window_coordinates(_window_centres_mm(centre_mm, display), n_pupil, dx_mm, n_pupil_x)
    r2 = xx * xx + yy * yy
    edge = edge_width_samples * dx_mm
    r_pupil = 0.5 * pupil_diameter_mm
    pupil_inside = disk_edge_distance(r2, r_pupil, edge)
    sub_inside = aperture_edge_distance(xx - centre_mm[0], yy - centre_mm[1], diameter_mm, edge, shape)
    # 10^(−ρ r²) = 10^(−ρ x²)·10^(−ρ y²): two 1-D exponentials instead of one per sample
    sce = jnp.outer(jnp.exp(-math.log(10.0) * sce_rho * yy[:, 0] ** 2),
                    jnp.exp(-math.log(10.0) * sce_rho * xx[0] ** 2))
    if diffracts:
        source = jax.nn.sigmoid(sub_inside / edge)
        aperture_field = source.astype(jnp.result_type(complex))
        if display.aberration is not None:
            # the lenslet's wavefront error multiplies its magnified aperture before the
            # Fresnel propagation (lfjax.display.aberrations)
            w_lens = display.aberration.wavefront_um(xx - centre_mm[0], yy - centre_mm[1],
                                                     0.5 * diameter_mm, shape)
            lens_phase = (-2.0 * jnp.pi / (wavelength_mm * 1e3)) * w_lens
            aperture_field = aperture_field * jax.lax.complex(jnp.cos(lens_phase), jnp.sin(lens_phase))
        beam = fresnel_propagate(
            aperture_field, dx_mm, wavelength_mm,
            display.fresnel_distance_mm, pupil_diameter_mm, along_y=not display.strips,
        )
        intensity = jnp.real(beam) ** 2 + jnp.imag(beam) ** 2
        if display.diffraction == "modulus":  # the paper's Eq. 2: |Fr[...]| only
            beam = safe_sqrt(intensity)
        coverage = jax.nn.sigmoid(pupil_inside / edge)
        amp = coverage * sce * beam
        # The zero-frequency term, as in the geometric branch, counts the soft edge's
        # coverage, not coverage²; but the edge's missing energy σ(1−σ) lives on the
        # sub-sample scale s of the edge, which diffraction spreads over λz/(πs): only the
        # part still on the beam's own scale (diameter d) is counted, a fraction
        # 1/√(1 + (λz/(π s d))²). Measured (2×2, 550 nm, VSOTF at df 1.2 against 0.25 cpd):
        # 3.4e-3 / 1.1e-3 / 1.0e-3 at 300 / 30 / 0.3 mm, against 5.5e-3 / 1.7e-2 / 1.6e-2
        # counting none of it and 1.0e-2 / 6.7e-4 / 9.7e-4 counting all of it.
        spread = wavelength_mm * display.fresnel_distance_mm / (jnp.pi * edge * diameter_mm)
        kept = jax.lax.rsqrt(1.0 + spread * spread)
        intensity_e = intensity + kept * source * (1.0 - source)
        energy = jnp.sum(coverage * sce * sce * intensity_e) * dx_mm * dx_mm
    else:
        # Intersection of pupil and subaperture: one edge at the nearer boundary (a product
        # of two sigmoids would double the edge where the boundaries coincide, as for the
        # open pupil).
        coverage = jax.nn.sigmoid(jnp.minimum(pupil_inside, sub_inside) / edge)
        amp = coverage * sce
        # A partly covered sample transmits energy ∝ its coverage, not coverage²: Σ|field|²
        # under-counts the edge by ~s·perimeter, a bias the OTF's zero-frequency term must
        # not carry (it would lift the whole normalised MTF by ~2s/R).
        energy = jnp.sum(coverage * sce * sce) * dx_mm * dx_mm
    return amp, energy


SEPARABLE_MAX_ORDER = 10
"""Largest radial order whose wavefront is evaluated in monomial (separable) form: in
float32 it stays within 4e-5 µm of the float64 polynomials up to order 10 (0.1 µm per
mode), and loses precision to cancellation beyond (7.6e-4 µm at order 12)."""


def _monomials_mm(coefficients_um, radius_mm, n_modes: int):
    """Σ_j c_j Z_j(x/r, y/r) as monomial coefficients in x and y in mm, (N+1, N+1)."""
    m = monomial_coefficients(n_modes)
    scale = powers_of(jnp.reshape(1.0 / radius_mm, (1,)).astype(coefficients_um.dtype), m.shape[-1])[:, 0]
    return (jnp.tensordot(coefficients_um, jnp.asarray(m, coefficients_um.dtype), 1, precision=FULL)
            * jnp.outer(scale, scale))


def _pad_monomials(a, size: int):
    pad = size - a.shape[-1]
    return jnp.pad(a, [(0, 0)] * (a.ndim - 2) + [(0, pad), (0, pad)]) if pad else a


def _window_centres_mm(centres_mm, display):
    """Centre of each view's sample window, mm: the view's own, or the pupil's for diffracted
    beams (they spread over the whole pupil)."""
    if display is not None and display.diffracts:
        return jnp.zeros_like(centres_mm)
    return centres_mm


def _shift_matrices(centre_mm, size: int):
    """B (…, N+1, N+1) with B[p', p] = C(p', p)·c^(p'−p) (p' ≥ p): the coefficients of a
    polynomial in x become those of the same polynomial in u = x − c as Bᵀ·(…)."""
    exponent = np.subtract.outer(np.arange(size), np.arange(size))
    binomial = np.array([[math.comb(i, j) if i >= j else 0 for j in range(size)] for i in range(size)])
    c_pow = jnp.moveaxis(powers_of(centre_mm, size), -2, -1)  # (…, N+1)
    return jnp.asarray(binomial, centre_mm.dtype) * c_pow[..., np.clip(exponent, 0, None)]


def _state_wavefronts_um(eye_um, c20_um, c40_um, window_centres_mm, offsets_mm, pupil_diameter_mm,
                         sa_radius_mm, measured_pupil_mm, offsets_x_mm=None):
    """Total wavefront (µm) of every (state, view): eye + defocus c20·Z(2,0) on the
    calculation pupil + SA c40·Z(4,0) on its own radius, (n_acc, n_sub, n, n).

    ``eye_um`` is the eye's coefficient vector (n_modes,); the views' windows are sampled at
    ``window_centres_mm`` (n_sub, 2) + ``offsets_mm`` (n,) along y and ``offsets_x_mm``
    (n_x,) along x (default ``offsets_mm``): (n_acc, n_sub, n, n_x). Every term is a
    polynomial in x and y, so one monomial matrix per state, moved to each window's centre
    (a binomial shift of the small matrix), and two thin matrix products with the
    offsets' powers give the wavefront (:func:`lfjax.base.zernike.wavefront_on_grid`). The
    reverse pass then costs small matrix products rather than N² polynomial terms per
    sample, and the centres' derivatives flow through the small matrices only, so the
    sample-sized cotangent has one consumer (RESULTS §8)."""
    real = offsets_mm.dtype
    offsets_x_mm = offsets_mm if offsets_x_mm is None else offsets_x_mm
    n_modes = eye_um.shape[-1]
    eye_order = nm_from_ansi(n_modes - 1)[0]
    r_pupil = 0.5 * pupil_diameter_mm
    defocus = _monomials_mm(jnp.zeros((5,), real).at[4].set(1.0), r_pupil, 5)
    sa = _monomials_mm(jnp.zeros((13,), real).at[12].set(1.0), sa_radius_mm, 13)
    separable_eye = eye_order <= SEPARABLE_MAX_ORDER
    size = max(5, eye_order + 1) if separable_eye else 5
    per_state = (c20_um[:, None, None] * _pad_monomials(defocus, size)
                 + c40_um[:, None, None] * _pad_monomials(sa, size))
    if separable_eye:
        eye = _monomials_mm(eye_um, 0.5 * measured_pupil_mm, n_modes)
        per_state = per_state + _pad_monomials(eye, size)[None]
    shift_x = _shift_matrices(window_centres_mm[:, 0], size)  # (n_sub, N+1, N+1)
    shift_y = _shift_matrices(window_centres_mm[:, 1], size)
    # (n_acc, n_sub, N+1, N+1)
    local = jnp.einsum("nip,aij,njq->anpq", shift_x, per_state, shift_y, precision=FULL)
    w = wavefront_on_grid(local, offsets_x_mm, offsets_mm)
    if not separable_eye:  # high orders: the polynomials themselves (no cancellation)
        r_meas = 0.5 * measured_pupil_mm
        w_eye = jax.vmap(lambda c: wavefront_um(
            eye_um, (c[0] + offsets_x_mm)[None, :] / r_meas, (c[1] + offsets_mm)[:, None] / r_meas
        ))(window_centres_mm)
        w = w + w_eye[None]
    return w.astype(real)


def _lenslet_wavefronts_um(display, diameters_mm, offsets_mm, offsets_x_mm=None):
    """Each view's lenslet wavefront (µm) on its own window (n_sub, n, n_x), [y, x]."""
    offsets_x_mm = offsets_mm if offsets_x_mm is None else offsets_x_mm
    return jax.vmap(lambda d: display.aberration.wavefront_um(
        offsets_x_mm[None, :], offsets_mm[:, None], 0.5 * d, display.aperture))(diameters_mm)


def pupil_window_size(n_fft: int, sampling: Sampling) -> int:
    """Pupil samples actually evaluated in a window of ``n_fft`` (the aperture and its edge).

    ``n_fft`` holds twice the aperture (autocorrelation support), so the aperture plus its
    logistic edge fits in about half of it; the rest is zero padding inside the FFT.
    """
    margin = int(math.ceil(2 * EDGE_EXTENT_SCALES * sampling.edge_width_samples)) + 2
    size = (n_fft - 1) // 2 + margin
    return min(n_fft, size + size % 2)


def _embed_half_plane(otf_half, n_fft: int):
    """Zero-pad a band-limited half-plane OTF (…, Lg, Lgx//2+1) onto a larger (…, L, L//2+1)."""
    n_small = otf_half.shape[-2]
    if n_small == n_fft and otf_half.shape[-1] == n_fft // 2 + 1:
        return otf_half
    h = n_small // 2
    top, bottom = otf_half[..., :h, :], otf_half[..., h:, :]
    zeros = jnp.zeros(otf_half.shape[:-2] + (n_fft - n_small, otf_half.shape[-1]), otf_half.dtype)
    rows = jnp.concatenate([top, zeros, bottom], axis=-2)
    pad = [(0, 0)] * (rows.ndim - 1) + [(0, n_fft // 2 + 1 - otf_half.shape[-1])]
    return jnp.pad(rows, pad)


def elemental_otfs(zernike_um, measured_pupil_mm: float, scene: Scene, spectrum: Spectrum,
                   accommodation: Accommodation, bands, sampling: Sampling, view_energy=None):
    """Spectrally weighted elemental OTFs of one eye (stages 1–5 of
    docs/design.md#the-model-stage-by-stage).

    ``zernike_um`` (n_modes,) µm on ``measured_pupil_mm``; the subapertures, the calculation
    pupil, the CDP and the display's optics come from ``scene``, the states and their
    spherical aberration from ``accommodation``. ``bands`` = ((start, stop, n_fft), …) from
    :func:`lfjax.base.sampling.wavelength_bands`: each band of wavelengths is transformed on its
    own window and embedded in the largest. A band (start, stop, n_fft, n_fft_x) transforms
    windows narrower along x (strips: :meth:`lfjax.kernel.pipeline.PipelineConfig.build`):
    n_fft rows × n_fft_x columns, the same angular field, so the same OTF on fewer samples. Returns complex (n_states, n_sub, L, L//2+1),
    the half plane f_x ≥ 0 of Σ_λ w_λ OTF_{λ,n,a}, each OTF carrying the energy its pupil
    transmits (OTF(0) = ∫|P|² dA in mm²) or, with ``spectrum.unit_sum`` = 1, that energy
    divided by the energy all subapertures transmit at λ (each wavelength's PSF summed over
    the views then has unit volume, as ISETBio normalises; the views keep their ratios).

    ``view_energy``: per band, the energy (mm²) all views of the whole layout transmit at
    each of its wavelengths (:func:`view_energy_totals`), for a ``scene`` that holds only
    some of the layout's views (:func:`lfjax.kernel.pipeline.rendered_otfs` streams them one
    at a time); None: ``scene``'s views are the whole layout.
    """
    n_fft = max(b[2] for b in bands)
    if scene.display is not None:  # the views' common astigmatism (lfjax.display.lenticular)
        zernike_um = scene.display.beam_wavefront_um(zernike_um, measured_pupil_mm)
    total = None
    for i, band in enumerate(bands):
        start, stop, band_fft = band[:3]
        part = _elemental_otfs_band(zernike_um, measured_pupil_mm, scene, spectrum.band(start, stop),
                                    accommodation, band_fft, sampling,
                                    band[3] if len(band) > 3 else None,
                                    None if view_energy is None else view_energy[i])
        part = _embed_half_plane(part, n_fft)
        total = part if total is None else total + part
    return total


# Working memory one call of the kernel may hold for the states it transforms together, in
# bytes. Each (state, view) pair keeps, per wavelength, its PSF accumulator, its padded
# complex field and transform, and the squared modulus: about KERNEL_BYTES_PER_SAMPLE bytes
# per frequency sample (float32). Above the budget the states go through in chunks, one
# after the other, so that a scene with many states, views and a large window (lenslet
# diffraction at 4×4 asked for several GiB) needs the budget, not the product. The answer
# does not change: each state is transformed on its own either way.
KERNEL_WORKSPACE_BYTES = 768 * 2**20
KERNEL_BYTES_PER_SAMPLE = 40


def state_chunk(n_states: int, n_views: int, n_fft: int,
                workspace_bytes: int | None = None) -> int:
    """Accommodation states transformed together by the kernel: all of them when their
    working memory (``KERNEL_BYTES_PER_SAMPLE`` × n_views × n_fft² bytes per state) fits
    ``workspace_bytes`` (default :data:`KERNEL_WORKSPACE_BYTES`), else the fewest equal
    chunks that fit (at least one state per chunk)."""
    budget = KERNEL_WORKSPACE_BYTES if workspace_bytes is None else int(workspace_bytes)
    per_state = KERNEL_BYTES_PER_SAMPLE * max(n_views, 1) * n_fft * n_fft
    fits = max(1, budget // per_state)
    if fits >= n_states:
        return max(n_states, 1)
    n_chunks = -(-n_states // fits)
    return -(-n_states // n_chunks)  # equal chunks: the least padding


def _elemental_otfs_band(zernike_um, measured_pupil_mm: float, scene: Scene, spectrum: Spectrum,
                         accommodation: Accommodation, n_fft: int, sampling: Sampling,
                         n_fft_x: int | None = None, energy_total=None):
    """One band of :func:`elemental_otfs`, the states in chunks of :func:`state_chunk`
    (``lax.map``) when they do not fit the kernel's working memory together."""
    states_D = accommodation.states_D
    n_states, n_views = states_D.shape[0], scene.centres_mm.shape[0]
    chunk = state_chunk(n_states, n_views, math.isqrt(n_fft * (n_fft if n_fft_x is None else n_fft_x)))

    def states_band(states):
        return _elemental_otfs_states(zernike_um, measured_pupil_mm, scene, spectrum, accommodation,
                                      states, n_fft, sampling, n_fft_x, energy_total)

    if chunk >= n_states:
        return states_band(states_D)
    n_chunks = -(-n_states // chunk)
    # the last chunk is filled up with copies of the last state, computed and dropped
    padded = jnp.concatenate([states_D, jnp.broadcast_to(states_D[-1:], (n_chunks * chunk - n_states,))])
    otf = jax.lax.map(states_band, padded.reshape(n_chunks, chunk))
    return otf.reshape((n_chunks * chunk,) + otf.shape[2:])[:n_states]


def _window_x(n_fft: int, n_fft_x: int | None, n_pupil: int, sampling: Sampling) -> tuple[int, int]:
    """(FFT columns, pupil columns) of a band's window: a strip band's narrower ones along
    x (FFT transform only), else the square window's."""
    n_fft_x = n_fft if (n_fft_x is None or sampling.transform == "mft") else int(n_fft_x)
    return n_fft_x, (n_pupil if n_fft_x == n_fft else pupil_window_size(n_fft_x, sampling))


def view_energy_totals(scene: Scene, spectrum: Spectrum, bands, sampling: Sampling) -> tuple:
    """Per band of ``bands``, the energy (mm², (n_wavelengths_in_band,)) all of ``scene``'s
    views transmit at each wavelength, summed over the views on the FFT path's pupil grids:
    what ``spectrum.unit_sum`` divides each wavelength's weight by in :func:`elemental_otfs`,
    computed once for a layout whose views are then transformed one at a time."""
    if sampling.transform != "fft":
        raise ValueError("view_energy_totals follows the FFT path's pupil grids; the MFT's "
                         "grid spans the largest view, so its views cannot be taken one at a time")
    real = jnp.result_type(float)
    df_rad = sampling.freq_step_cpd * DEGREES_PER_RADIAN
    totals = []
    for band in bands:
        start, stop, band_fft = band[:3]
        n_pupil = pupil_window_size(band_fft, sampling)
        _, n_pupil_x = _window_x(band_fft, band[3] if len(band) > 3 else None, n_pupil, sampling)
        part = spectrum.band(start, stop)

        def one_wavelength(xs, n_pupil=n_pupil, n_pupil_x=n_pupil_x):
            wl_nm, rho = xs
            wl_mm = wl_nm * 1e-6
            dx = (wl_mm * df_rad).astype(real)
            energy = jax.vmap(lambda c, d: _pupil_parts(
                scene.pupil_diameter_mm, c, d, dx, rho, n_pupil, sampling.edge_width_samples,
                wl_mm, scene.display, n_pupil_x)[1])(scene.centres_mm, scene.diameters_mm)
            return jnp.sum(energy)

        totals.append(jax.lax.map(one_wavelength, (part.wavelengths_nm, part.sce_rho_per_mm2)))
    return tuple(totals)


def _elemental_otfs_states(zernike_um, measured_pupil_mm: float, scene: Scene, spectrum: Spectrum,
                           accommodation: Accommodation, accommodation_D, n_fft: int,
                           sampling: Sampling, n_fft_x: int | None = None, energy_total=None):
    """One band of :func:`elemental_otfs` for the accommodation states ``accommodation_D``
    (n_states,) D: every wavelength's PSFs lie on the same angular grid (the pupil step is
    λ·Δf), so the band's weighted PSFs are summed first and transformed once (the transform
    is linear); the zero-frequency term is set from the summed analytic energies (a finite
    pupil sum under-counts the soft edge).

    ``n_fft_x`` (FFT transform only; default ``n_fft``): columns of a window narrower along
    x. The pupil step λ·Δf and so the angular field are those of the square window; the PSF
    is sampled more coarsely along x, which loses nothing while the columns hold twice the
    aperture (the OTF's support), and the half-plane OTF (n_fft, n_fft_x//2+1) is embedded
    in the square one by zeros beyond its support. Returns (n_states, n_sub, n_fft,
    n_fft_x//2+1)."""
    pupil_diameter_mm, cdp_D = scene.pupil_diameter_mm, scene.cdp_D
    centres_mm, diameters_mm, display = scene.centres_mm, scene.diameters_mm, scene.display
    df_rad = sampling.freq_step_cpd * DEGREES_PER_RADIAN
    real = jnp.result_type(float)
    use_mft = sampling.transform == "mft"
    if use_mft:
        n_pupil = int(sampling.mft_pupil_samples)
        # one λ-independent pupil grid holding the largest subaperture and its edge (the
        # pupil when diffracted beams fill it)
        span = jnp.max(jnp.minimum(diameters_mm, pupil_diameter_mm))
        if display is not None and display.fills_pupil:
            span = pupil_diameter_mm
        dx_mft = (span / (n_pupil - 2.0 * EDGE_EXTENT_SCALES * sampling.edge_width_samples - 2.0)).astype(real)
        k_theta = np.fft.fftfreq(n_fft, 1.0 / n_fft)
        pixel_rad = 1.0 / (n_fft * df_rad)
        local = (jnp.arange(n_pupil, dtype=real) - n_pupil // 2) * dx_mft
    else:
        n_pupil = pupil_window_size(n_fft, sampling)
    n_fft_x, n_pupil_x = _window_x(n_fft, n_fft_x, n_pupil, sampling)
    c40 = (accommodation.sa_c40_um_per_D * accommodation_D).astype(real)

    def one_wavelength(carry, xs):
        psf_total, energy_total = carry
        wl_nm, weight, lca_D, rho, views_energy = xs
        wl_mm = wl_nm * 1e-6
        dx = dx_mft if use_mft else (wl_mm * df_rad).astype(real)
        parts = jax.vmap(
            lambda c, d: _pupil_parts(
                pupil_diameter_mm, c, d, dx, rho, n_pupil, sampling.edge_width_samples,
                wl_mm, display, n_pupil_x,
            )
        )(centres_mm, diameters_mm)
        amp, energy = parts  # (n_sub, n_pupil, n_pupil_x) and (n_sub,)
        # ModelOptions.wavelength_normalisation as data: unit_sum = 1 divides by the energy
        # all views transmit at this wavelength, 0 leaves the weight as it is
        if views_energy is None:
            views_energy = jnp.sum(energy)
        weight = weight * jnp.power(views_energy, -spectrum.unit_sum)
        c20 = dioptres_to_c20_um(accommodation_D - cdp_D + lca_D, pupil_diameter_mm)
        offsets = (jnp.arange(n_pupil, dtype=real) - n_pupil // 2) * dx
        offsets_x = offsets if n_pupil_x == n_pupil else (jnp.arange(n_pupil_x, dtype=real) - n_pupil_x // 2) * dx
        w = _state_wavefronts_um(zernike_um, c20, c40, _window_centres_mm(centres_mm, display),
                                 offsets, pupil_diameter_mm, accommodation.sa_radius_mm, measured_pupil_mm,
                                 offsets_x)
        if display is not None and display.aberration is not None and not display.diffracts:
            # geometric views: each window is centred on its view, so the lenslet's wavefront
            # (lfjax.display.aberrations) is a function of the offsets and the view's size
            w = w + _lenslet_wavefronts_um(display, diameters_mm, offsets, offsets_x)[None]
        phase = (-2.0 * jnp.pi / (wl_nm * 1e-3)) * w
        if jnp.iscomplexobj(amp):  # lenslet diffraction: a complex beam in the pupil
            field = amp[None] * jax.lax.complex(jnp.cos(phase), jnp.sin(phase))
        else:
            field = jax.lax.complex(amp[None] * jnp.cos(phase), amp[None] * jnp.sin(phase))
        if use_mft:
            # Matrix Fourier transform onto the common angular grid (FFT order): point
            # samples of the PSF, truncated (not wrapped) at the field edge.
            theta = jnp.asarray(k_theta, real) * pixel_rad
            kernel = jnp.exp((-2j * jnp.pi / wl_mm) * theta[:, None] * local[None, :])
            spectrum_2d = jnp.einsum("jy,...yx,mx->...jm", kernel, field, kernel, precision=FULL)
            scale = dx**4 * pixel_rad**2 / wl_mm**2
        else:
            # The aperture fills only the central n_pupil samples; an explicit pad then one
            # fft2 is faster on CPU than two padded 1-D passes (measured).
            field = jnp.pad(field, ((0, 0), (0, 0), (0, n_fft - n_pupil), (0, n_fft_x - n_pupil_x)))
            spectrum_2d = jnp.fft.fft2(field)
            scale = dx * dx / (n_fft * n_fft_x)
        # Named so that the reverse pass keeps the transform (saved, 2 floats a sample)
        # instead of recomputing it; checkpoint_name takes real arrays only.
        re = checkpoint_name(jnp.real(spectrum_2d), "pupil_spectrum")
        im = checkpoint_name(jnp.imag(spectrum_2d), "pupil_spectrum")
        psf = re * re + im * im
        return (psf_total + (weight * scale) * psf, energy_total + weight * energy), None

    n_acc, n_sub = accommodation_D.shape[0], centres_mm.shape[0]
    init = (jnp.zeros((n_acc, n_sub, n_fft, n_fft_x), real), jnp.zeros((n_sub,), real))
    xs = (spectrum.wavelengths_nm, spectrum.weights, spectrum.lca_D, spectrum.sce_rho_per_mm2,
          energy_total)
    # Reverse mode keeps each wavelength's pupil spectrum and recomputes the cheap pupil
    # fields instead of stacking every intermediate over the scan (jax.checkpoint): 1.6x
    # faster than stacking, 1.13x faster than recomputing the transform too; the forward
    # is unchanged (benchmarks/speed/bench_gradient.py, RESULTS.md §8).
    keep_spectrum = jax.checkpoint_policies.save_only_these_names("pupil_spectrum")
    one_wavelength = jax.checkpoint(one_wavelength, prevent_cse=False, policy=keep_spectrum)
    (psf_band, energy_band), _ = jax.lax.scan(one_wavelength, init, xs)
    # The PSF is real: its OTF is Hermitian and the half plane (rfft2) holds it all.
    otf = jnp.fft.rfft2(psf_band)
    return otf.at[..., 0, 0].set(jnp.broadcast_to(energy_band, otf.shape[:-2]).astype(otf.dtype))


# ----------------------------------------------------------------------------- validation


_is_concrete = is_concrete


def validate_pupil(pupil_diameter_mm, measured_pupil_mm: float) -> None:
    """Calculation pupil must be > 0 and no larger than the measured pupil."""
    if not _is_concrete(pupil_diameter_mm):
        return
    d = float(pupil_diameter_mm)
    if not (d > 0 and math.isfinite(d)):
        raise ValueError(f"pupil_diameter_mm must be > 0 mm, got {d}")
    if d > measured_pupil_mm + 1e-9:
        raise ValueError(
            f"pupil_diameter_mm={d:g} exceeds the measured pupil of the eyes "
            f"({measured_pupil_mm:g} mm): allowed range (0, {measured_pupil_mm:g}] mm; "
            "use eye statistics measured on a larger pupil"
        )


def validate_states(accommodation_D=None, depths_D=None, cdp_D=None) -> None:
    """Accommodation, rendered depths and CDP must be finite and in the model's range
    [0, :data:`~lfjax.base.units.MAX_DIOPTRES_D`] D (0 D = infinity;
    :func:`~lfjax.base.units.check_dioptres`).

    Checked on the host for concrete values; traced values pass through (differentiable
    paths such as :func:`lfjax.vision.focus.metrics_at`).
    """
    for name, value, what, noun in (
        ("accommodation_D", accommodation_D, "an eye cannot focus beyond infinity",
         "accommodation state"),
        ("depths_D", depths_D, "a rendered point cannot lie beyond infinity", "rendered depth"),
        ("cdp_D", cdp_D, "the display's image plane cannot lie beyond infinity", "CDP"),
    ):
        if value is None or not _is_concrete(value):
            continue
        v = np.asarray(value, float)
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} must be finite, got {v.ravel().tolist()}")
        if np.any(v < 0):
            raise ValueError(f"{name} must be >= 0 D ({what}); got {v[v < 0].tolist()}")
        check_dioptres(name, v, noun)


def validate_coefficients(zernike_um) -> None:
    """Concrete Zernike coefficients must be finite (traced ones pass through)."""
    # numpy, not jnp: under an outer jit a jnp reduction of a concrete array is a tracer
    if _is_concrete(zernike_um) and not np.all(np.isfinite(np.asarray(zernike_um))):
        raise ValueError("zernike_um contains non-finite values (NaN or inf)")


def field_radius_arcmin(
    eyes_zernike_um, measured_pupil_mm: float, pupil_diameter_mm: float, cdp_D: float,
    accommodation_D, pair_accommodation_D, pair_depths_D, layout: Layout, spectrum: Spectrum,
    wrap_tolerance: float = 1e-3, display=None,
) -> float:
    """Largest PSF radius (arcmin) the field must hold for these states (host, numpy).

    Geometric blur of every accommodation state (incl. LCA) and display shift of every
    (accommodation, depth) pair, plus diffraction and the eyes' largest ray angle
    (:func:`lfjax.base.sampling.blur_radius_arcmin`), and the blur a real display adds
    (``display``: lenslet diffraction, pixels). Wavelengths carrying in total less than
    ``wrap_tolerance`` of the spectral weight, the most blurred first, are left out: their
    error in the OTF is bounded by their weight. The pipeline's aliasing guard and
    :func:`lfjax.planner.plan.plan_sampling` both use this function.
    """
    acc = np.asarray(accommodation_D, float).reshape(-1)
    pair_acc = np.asarray(pair_accommodation_D, float).reshape(-1)
    pair_depth = np.asarray(pair_depths_D, float).reshape(-1)
    lca_all = np.asarray(spectrum.lca_D, float)
    weights = np.asarray(spectrum.weights, float)
    order = np.argsort(-np.abs(lca_all))  # most chromatic defocus first
    excluded = np.cumsum(weights[order]) < wrap_tolerance * weights.sum()
    lca = lca_all[order[~excluded]]
    defocus = (acc[:, None] - float(cdp_D) + lca[None, :]).ravel()
    mismatch = (pair_acc[:, None] - pair_depth[:, None] + lca[None, :]).ravel()
    slope = 0.0
    if eyes_zernike_um is not None:
        slope = eye_slope_rad(np.asarray(eyes_zernike_um), measured_pupil_mm, float(pupil_diameter_mm))
    return blur_radius_arcmin(
        float(pupil_diameter_mm), np.asarray(layout.centres_mm), np.asarray(layout.diameters_mm),
        defocus, mismatch, float(np.max(np.asarray(spectrum.wavelengths_nm))), slope, display,
    )


def field_check(
    eyes_zernike, measured_pupil_mm, pupil_diameter_mm, cdp_D, accommodation_D, depths_D,
    layout: Layout, spectrum: Spectrum, sampling: Sampling, pairs=None,
    wrap_tolerance: float = 1e-3, display=None,
) -> None:
    """Raise if the PSF field cannot hold the blur (host check on concrete inputs).

    ``pairs`` = (accommodation, depth) arrays restricts the check to the pairs computed.
    """
    if not _is_concrete(
        eyes_zernike, pupil_diameter_mm, cdp_D, accommodation_D, depths_D, layout, spectrum, display
    ):
        return  # under tracing the caller has checked the concrete sampling already
    acc = np.asarray(accommodation_D, float).reshape(-1)
    depth = np.asarray(depths_D, float).reshape(-1)
    if pairs is None:
        pairs = (np.repeat(acc, depth.size), np.tile(depth, acc.size))
    radius = field_radius_arcmin(
        eyes_zernike, measured_pupil_mm, pupil_diameter_mm, cdp_D, acc, pairs[0], pairs[1],
        layout, spectrum, wrap_tolerance, display,
    )
    check_field(sampling, radius, "the blur of the requested defocus, LCA and display shifts")


# ----------------------------------------------------------------------------- public


def full_plane(otf_half, n_fft: int):
    """Full FFT-order (…, L, L) OTF from its half plane (…, L, L//2+1) by Hermitian symmetry.

    OTF(−f) = conj(OTF(f)): column −k_x is the conjugate of column k_x with rows reflected.
    """
    n_negative = n_fft - otf_half.shape[-1]
    cols = otf_half[..., 1 : 1 + n_negative][..., ::-1]
    reflected = jnp.roll(jnp.flip(cols, axis=-2), 1, axis=-2)
    return jnp.concatenate([otf_half, jnp.conj(reflected)], axis=-1)


def psf_from_otf(otf_half, n_fft: int, freq_step_cpd: float):
    """PSF density (per arcmin²) from a half-plane OTF, centred (zero angle at index L//2).

    Integrates to OTF(0) over the field 60/df arcmin; pixel 60/(df·L) arcmin.
    """
    psf = jnp.fft.irfft2(otf_half, s=(n_fft, n_fft)) * (n_fft * n_fft) * (freq_step_cpd / 60.0) ** 2
    return jnp.fft.fftshift(psf, axes=(-2, -1))


__all__ = [
    "elemental_otfs",
    "view_energy_totals",
    "pupil_window_size",
    "full_plane",
    "psf_from_otf",
    "validate_pupil",
    "validate_states",
    "validate_coefficients",
    "field_radius_arcmin",
    "field_check",
]
