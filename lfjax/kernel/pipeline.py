"""The pipeline as one pure function: eyes × scene × spectrum × accommodation → metrics.

Four pytrees carry the physics as arrays (every float a sweep or a fit varies is a leaf, so
``jax.jit``, ``jax.vmap`` and ``jax.grad`` can wrap the pipeline from outside without
recompiling per value):

* :class:`lfjax.model.eyes.Eyes` — Zernike coefficients (µm), batch axis first;
* :class:`Scene` — what the display shows and through which pupil: subaperture centres and
  diameters (mm), the central depth plane (D), rendered depths (D), the calculation pupil
  (mm), and optionally the display's own optics (:class:`lfjax.display.lenslets.DisplayOptics`:
  lenslet diffraction, finite pixels);
* :class:`lfjax.model.spectral.Spectrum` — wavelengths (nm), weights, LCA (D), Stiles–Crawford ρ;
* :class:`Accommodation` — the accommodation states (D) and which state each
  (depth, k) pair uses, with the accommodation-dependent spherical aberration.

One hashable, static :class:`PipelineConfig` holds everything that sets array shapes or
selects code: the frequency sampling and its wavelength bands, the NCSF model, the VSOTF
reference and the eye chunk. :func:`retinal_metrics` is the paper's chain on one screen;
:func:`lfjax.vision.focus.through_focus`, :func:`lfjax.vision.focus.metrics_at`,
:func:`lfjax.vision.psf.polychromatic_otf`, the peak finder and the layout optimiser all call it
(or :func:`otf_stack`, its first half).

Bad values are refused twice: on the host with a message naming the parameter (the public
wrappers, before any tracing) and, for traced values, with ``eqx.error_if`` inside the
pipeline, so a NaN never leaves it silently.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from lfjax.display.lenslets import DisplayOptics, pixel_transfer
from lfjax.model.eyes import Eyes
from lfjax.kernel.metrics import ncsf_half_plane, psf_peak, radial_mtf, vsotf_numerator
from lfjax.kernel.optics import elemental_otfs, view_energy_totals
from lfjax.model.options import ModelOptions
from lfjax.base.sampling import Sampling, frequencies_cpd, half_frequencies_cpd, wavelength_bands
from lfjax.kernel.scene import Accommodation, Scene
from lfjax.model.spectral import Spectrum
from lfjax.base.units import DEGREES_PER_RADIAN


@dataclass(frozen=True)
class PipelineConfig:
    """Static configuration: shapes and code paths (hashable; changing it recompiles).

    Attributes
    ----------
    sampling : frequency step, transform and aperture edge
    bands : ((start, stop, n_fft), …) wavelength bands of the scene's layout; a band
        (start, stop, n_fft, n_fft_x) has windows n_fft_x < n_fft columns wide (strips)
    reference_bands : the same for the VSOTF/Strehl reference aperture
    ncsf : NCSF model name (:mod:`lfjax.kernel.metrics`)
    vsotf_reference : "paper" (same layout, aberration-free) or "open_pupil"
    zero_piston_tilt : drop j = 0, 1, 2 from the eyes' coefficients
    eye_chunk : eyes evaluated together inside the map over eyes (None: one at a time)
    traced_checks : check traced inputs inside the program with ``eqx.error_if`` (default).
        False only where every input was checked on the host first (the public wrappers on
        concrete values do): ``eqx.error_if`` is a host callback, and JAX's persistent
        compilation cache does not store programs with host callbacks, so a checked program
        is recompiled by every new process.
    """

    sampling: Sampling
    bands: tuple
    reference_bands: tuple
    ncsf: str = "watson_ahumada_2005"
    vsotf_reference: str = "paper"
    zero_piston_tilt: bool = True
    eye_chunk: int | None = None
    traced_checks: bool = True

    @property
    def n_fft(self) -> int:
        return max(b[2] for b in self.bands)

    @property
    def freq_step_cpd(self) -> float:
        return self.sampling.freq_step_cpd

    @classmethod
    def build(
        cls, wavelengths_nm, window_diameter_mm: float, pupil_diameter_mm: float,
        sampling: Sampling, options: ModelOptions = ModelOptions(), eye_chunk: int | None = None,
        traced_checks: bool = True, display: DisplayOptics | None = None,
        widest_view_mm: float | None = None,
    ) -> PipelineConfig:
        """Bands for a spectrum (nm) and a layout whose largest window is
        ``window_diameter_mm`` (mm), on a calculation pupil of ``pupil_diameter_mm`` (mm);
        everything here is concrete host data. With lenslet diffraction (``display``) every
        view's window is the pupil; the reference (an ideal display) keeps the layout's.

        ``widest_view_mm`` (mm, host; None: unknown): the widest view of the layout. Where
        the display's views are narrower along x than their window along y
        (:meth:`~lfjax.display.lenslets.DisplayOptics.window_x_mm`: strips, as wide as the
        widest strip and as tall as the pupil) their bands carry a narrower FFT along x
        (``(start, stop, n_fft, n_fft_x)``): the same OTF on the columns its support needs,
        a third of the transforms for 1×3 strips. Not with the MFT or a user-fixed ``n_fft``."""
        wl = np.asarray(wavelengths_nm, float)
        pupil = float(pupil_diameter_mm)
        reference_window = window_diameter_mm if options.vsotf_reference == "paper" else pupil
        if display is not None and display.diffracts:
            window_diameter_mm = pupil
        window_x = (None if display is None or widest_view_mm is None
                    else display.window_x_mm(widest_view_mm, pupil))
        bands = wavelength_bands(wl, float(window_diameter_mm), pupil, sampling)
        reference_bands = wavelength_bands(wl, float(reference_window), pupil, sampling)
        if window_x is not None and sampling.transform == "fft" and sampling.n_fft is None:
            bands = _narrow_bands(bands, wl, window_x, pupil, sampling)
            if options.vsotf_reference == "paper":  # the reference keeps the strips' shape
                reference_bands = _narrow_bands(reference_bands, wl, window_x, pupil, sampling)
        return cls(
            sampling,
            bands,
            reference_bands,
            options.ncsf, options.vsotf_reference, options.zero_piston_tilt,
            None if eye_chunk is None else int(eye_chunk), bool(traced_checks),
        )

    def replace(self, **changes) -> PipelineConfig:
        return dataclasses.replace(self, **changes)


def _narrow_bands(bands, wavelengths_nm, window_x_mm: float, pupil_diameter_mm: float,
                  sampling: Sampling) -> tuple:
    """``bands`` with each band's FFT columns sized for a window ``window_x_mm`` wide along x
    (its shortest wavelength's, as :meth:`Sampling.window_size` sizes any window); bands it
    would not narrow stay (start, stop, n_fft)."""
    out = []
    for start, stop, n_fft, *_ in bands:
        n_x = sampling.window_size(min(window_x_mm, pupil_diameter_mm), float(wavelengths_nm[start]),
                                   pupil_diameter_mm)
        out.append((start, stop, n_fft, n_x) if n_x < n_fft else (start, stop, n_fft))
    return tuple(out)


def transform_units(bands) -> float:
    """Cost of one view's transforms at one accommodation state over ``bands`` ((start, stop,
    n_fft[, n_fft_x]) of :class:`PipelineConfig`): Σ (stop − start)·n_fft·n_fft_x·log2 n_fft
    (n_fft_x = n_fft for a square window), the unit the sweep's and the design's estimates
    time. A strip's band on a narrow window (n_fft_x < n_fft) costs n_fft_x/n_fft of a square
    one's."""
    total = 0.0
    for start, stop, size, *narrow in bands:
        size_x = narrow[0] if narrow else size
        total += (stop - start) * size * size_x * math.log2(max(size, 2))
    return float(total)


class RetinalMetrics(eqx.Module):
    """Image quality of each (eye, rendered depth, k) pair.

    Attributes
    ----------
    vsotf : (…, n_depth, n_k) visual Strehl ratio from the OTF, unitless
    strehl : (…, n_depth, n_k) PSF peak over the reference's, unitless
    radial_mtf : (…, n_depth, n_k, L//2+1) meridian-averaged MTF at f = k·df
    """

    vsotf: Float[Array, "*n_eyes n_depth n_k"]
    strehl: Float[Array, "*n_eyes n_depth n_k"]
    radial_mtf: Float[Array, "*n_eyes n_depth n_k n_freq"]


# ----------------------------------------------------------------------------- stages


def checked_inputs(eyes: Eyes, scene: Scene, accommodation: Accommodation):
    """Traced-value checks (``eqx.error_if``); concrete values were checked on the host."""
    z = eqx.error_if(eyes.zernike_um, ~jnp.all(jnp.isfinite(eyes.zernike_um)),
                     "zernike_um contains non-finite values (NaN or inf)")
    # 0.1 % beyond the measured pupil is let through: finite differences at the boundary
    # step there, and the Zernike fit extrapolates negligibly that far.
    pupil = eqx.error_if(
        scene.pupil_diameter_mm,
        ~((scene.pupil_diameter_mm > 0) & (scene.pupil_diameter_mm <= eyes.measured_pupil_mm * 1.001)),
        f"pupil_diameter_mm must be in (0, {eyes.measured_pupil_mm:g}] mm (the eyes' measured pupil)",
    )
    diameters = eqx.error_if(scene.diameters_mm, ~jnp.all(scene.diameters_mm > 0),
                             "diameters_mm must be > 0 mm")
    centres = eqx.error_if(scene.centres_mm, ~jnp.all(jnp.isfinite(scene.centres_mm)),
                           "centres_mm must be finite")
    depths = eqx.error_if(scene.depths_D, ~jnp.all(jnp.isfinite(scene.depths_D) & (scene.depths_D >= 0)),
                          "depths_D must be finite and >= 0 D (0 D is optical infinity)")
    cdp = eqx.error_if(scene.cdp_D, ~(jnp.isfinite(scene.cdp_D) & (scene.cdp_D >= 0)),
                       "cdp_D must be finite and >= 0 D")
    states = eqx.error_if(
        accommodation.states_D, ~jnp.all(jnp.isfinite(accommodation.states_D)),
        "accommodation_D must be finite",
    )
    display = None if scene.display is None else scene.display.checked()
    return (
        eqx.tree_at(lambda e: e.zernike_um, eyes, z),
        Scene(centres, diameters, cdp, depths, pupil, display),
        eqx.tree_at(lambda a: a.states_D, accommodation, states),
    )


def eye_coefficients(eyes: Eyes, config: PipelineConfig):
    """The eyes' Zernike coefficients (…, n_modes) µm as the pipeline uses them: piston and
    tilt zeroed when ``config.zero_piston_tilt``."""
    z = eyes.zernike_um
    return z.at[..., :3].set(0.0) if config.zero_piston_tilt else z


ELEMENTAL_STACK_BYTES = 64 * 2**20
"""Largest stack of one eye's elemental OTFs (n_states × n_views half planes) the pipeline
holds at once. Above it :func:`rendered_otfs` transforms the views one at a time and adds
each into the rendered OTFs as it comes (the same transforms, in a different order), so that
a scene with many views, states and a large window (the phone panel's 4×4 design: 2.1 GB of
elemental OTFs per eye) needs one view's states, not the product. It is faster too, the
working set being one view's: 0.36–0.88× the time on 2 CPU cores for stacks of 87 MB to
2.1 GB (RESULTS §36). Below it — twice the 32 MiB L3 cache, under the smallest stack
measured — the whole stack is transformed together, as every paper study, default sweep and
``lfjax optimise`` (stacks of 11–40 MiB) does: they compile as before."""


def streams_views(n_states: int, n_views: int, n_fft: int, sampling: Sampling,
                  stack_bytes: int | None = None) -> bool:
    """Whether :func:`rendered_otfs` takes the views one at a time: more than one view, the
    FFT transform (the MFT's pupil grid spans the largest view, so it needs all of them),
    and an elemental stack (complex half planes) above ``stack_bytes`` (default
    :data:`ELEMENTAL_STACK_BYTES`)."""
    budget = ELEMENTAL_STACK_BYTES if stack_bytes is None else int(stack_bytes)
    complex_bytes = 16 if jax.config.jax_enable_x64 else 8
    stack = n_states * n_views * n_fft * (n_fft // 2 + 1) * complex_bytes
    return n_views > 1 and sampling.transform == "fft" and stack > budget


def held_elemental_planes(n_states: int, n_views: int, n_pairs: int, n_fft: int,
                          sampling: Sampling) -> int:
    """Half planes of one eye's elemental OTFs the pipeline holds at once (for memory
    estimates): the whole stack (n_states × n_views), or, streamed (:func:`streams_views`),
    one view's states and its contribution to the ``n_pairs`` rendered pairs."""
    if streams_views(n_states, n_views, n_fft, sampling):
        return n_states + n_pairs
    return n_states * n_views


def rendered_otfs(zernike_um, measured_pupil_mm: float, scene: Scene, spectrum: Spectrum,
                  accommodation: Accommodation, bands, sampling: Sampling, stack_bytes: int | None = None):
    """One eye's rendered OTFs of every (depth, k) pair, (n_depth, n_k, L, L//2+1) half planes,
    OTF(0) = 1 (stages 1–7): :func:`elemental_otfs` then :func:`render`, or, when the
    elemental stack would exceed ``stack_bytes`` (:func:`streams_views`), one view at a time,
    each view's states transformed and added into the pairs before the next view's. The two
    orders compute the same sums; the streamed one's reverse pass recomputes each view's
    transforms (``jax.checkpoint``) instead of keeping them."""
    n_fft, df = max(b[2] for b in bands), sampling.freq_step_cpd
    n_states, n_views = accommodation.states_D.shape[0], scene.centres_mm.shape[0]
    if not streams_views(n_states, n_views, n_fft, sampling, stack_bytes):
        elemental = elemental_otfs(zernike_um, measured_pupil_mm, scene, spectrum, accommodation,
                                   bands, sampling)
        return render(elemental, scene, accommodation.pair_index, n_fft, df)
    view_energy = view_energy_totals(scene, spectrum, bands, sampling)
    fy_rad, fx_rad, ramp_y, ramp_x = _view_ramps(scene, n_fft, df)
    mixing = None if scene.display is None else scene.display.view_mixing
    ramps = None if mixing is None else ramp_y[..., :, None] * ramp_x[..., None, :]
    pair_index = accommodation.pair_index

    @jax.checkpoint
    def view_contribution(view):
        centre, diameter, ry, rx, k_n = view
        one = Scene(centre[None], diameter[None], scene.cdp_D, scene.depths_D,
                    scene.pupil_diameter_mm, scene.display)
        elemental_n = elemental_otfs(zernike_um, measured_pupil_mm, one, spectrum, accommodation,
                                     bands, sampling, view_energy)[:, 0]  # (n_states, L, Lx)
        if k_n is None:
            ramp = ry[:, None, :, None] * rx[:, None, None, :]
        else:
            ramp = jnp.sum(k_n.astype(ramps.real.dtype)[None, :, None, None] * ramps, axis=1)[:, None]
        return ramp * elemental_n[pair_index], jnp.real(elemental_n[:, 0, 0])

    def add_view(carry, view):
        total, energy = carry
        otf, energy_n = view_contribution(view)
        return (total + otf, energy + energy_n), None

    real = jnp.result_type(float)
    complex_dtype = jnp.result_type(real, jnp.complex64)
    init = (jnp.zeros(pair_index.shape + (n_fft, n_fft // 2 + 1), complex_dtype),
            jnp.zeros((n_states,), real))
    views = (scene.centres_mm, scene.diameters_mm, jnp.moveaxis(ramp_y, 1, 0),
             jnp.moveaxis(ramp_x, 1, 0), mixing)
    (otf, energy), _ = jax.lax.scan(add_view, init, views)
    if scene.display is not None:
        otf = otf * pixel_transfer(fx_rad, fy_rad, scene.display)
    return otf / energy[pair_index][..., None, None]


def _view_ramps(scene: Scene, n_fft: int, freq_step_cpd: float):
    """Frequencies (rad⁻¹: fy (L,), fx (L//2+1,)) and each view's displacement ramps
    exp(−2πi f·Δθ_n) along y (n_depth, n_sub, L) and x (n_depth, n_sub, L//2+1)."""
    fy_rad = frequencies_cpd(n_fft, freq_step_cpd) * DEGREES_PER_RADIAN
    fx_rad = half_frequencies_cpd(n_fft, freq_step_cpd) * DEGREES_PER_RADIAN
    shift_rad = (scene.depths_D - scene.cdp_D)[:, None, None] * scene.centres_mm[None] * 1e-3
    ramp_x = jnp.exp(-2j * jnp.pi * shift_rad[..., 0:1] * fx_rad)  # (n_depth, n_sub, Lx)
    ramp_y = jnp.exp(-2j * jnp.pi * shift_rad[..., 1:2] * fy_rad)  # (n_depth, n_sub, L)
    return fy_rad, fx_rad, ramp_y, ramp_x


def render(elemental, scene: Scene, pair_index, n_fft: int, freq_step_cpd: float):
    """Rendered polychromatic OTFs of every (depth, k) pair, (n_depth, n_k, L, L//2+1), OTF(0) = 1.

    View n of depth d is displaced by Δθ_n = (D_d − D_CDP)·(p_n, q_n) (rad; D in 1/m, p in
    m), applied as the phase ramp exp(−2πi f·Δθ_n); pair (d, k) sums the views' elemental
    OTFs of state ``pair_index[d, k]`` (stages 6–7). Finite pixels (``scene.display``)
    blur every view alike: the sum is multiplied by the emitter's transfer function.
    """
    fy_rad, fx_rad, ramp_y, ramp_x = _view_ramps(scene, n_fft, freq_step_cpd)

    def add_view(total, view):
        elemental_n, ry, rx = view  # (n_states, L, Lx), (n_depth, L), (n_depth, Lx)
        ramp = ry[:, None, :, None] * rx[:, None, None, :]
        return total + ramp * elemental_n[pair_index], None

    # A scan over views keeps memory at one (n_depth, n_k, L, Lx) block; an einsum over the
    # view axis lowers to tiny per-pixel matmuls, slow on CPU.
    init = jnp.zeros(pair_index.shape + elemental.shape[2:], elemental.dtype)
    mixing = None if scene.display is None else scene.display.view_mixing
    if mixing is not None:
        # Leakage (lfjax.display.lenticular): view n carries K[n, m] of view m's content,
        # displaced by view m's shift (the neighbour's parallax at the rendered depth).
        # Every view's ramp, (n_depth, n_sub, L, Lx), weighted and summed per view: with
        # K = I each view's own ramp comes out exactly (1·r + 0 + …), bit for bit.
        ramps = ramp_y[..., :, None] * ramp_x[..., None, :]

        def add_mixed_view(total, view):
            elemental_n, k_n = view
            ramp = jnp.sum(k_n.astype(ramps.real.dtype)[None, :, None, None] * ramps, axis=1)
            return total + ramp[:, None] * elemental_n[pair_index], None

        otf, _ = jax.lax.scan(add_mixed_view, init, (jnp.moveaxis(elemental, 1, 0),
                                                     mixing))
    else:
        otf, _ = jax.lax.scan(
            add_view, init,
            (jnp.moveaxis(elemental, 1, 0), jnp.moveaxis(ramp_y, 1, 0), jnp.moveaxis(ramp_x, 1, 0)),
        )
    energy = jnp.real(jnp.sum(elemental[:, :, 0, 0], axis=1))[pair_index]
    if scene.display is not None:
        otf = otf * pixel_transfer(fx_rad, fy_rad, scene.display)
    return otf / energy[..., None, None]


def reference_otf(scene: Scene, spectrum: Spectrum, accommodation: Accommodation,
                  config: PipelineConfig):
    """The reference's rendered OTF, (L, L//2+1) half plane on its own window (the
    reference :func:`reference_normalisers` describes)."""
    if config.vsotf_reference == "paper":
        centres, diameters = scene.centres_mm, scene.diameters_mm
    else:
        centres = jnp.zeros((1, 2), scene.centres_mm.dtype)
        diameters = jnp.reshape(scene.pupil_diameter_mm, (1,))
    cdp = jnp.reshape(scene.cdp_D, (1,))
    ideal = None
    if scene.display is not None and scene.display.aperture != "circle" and config.vsotf_reference == "paper":
        ideal = DisplayOptics("off", scene.display.aperture)
    reference_scene = Scene(centres, diameters, scene.cdp_D, cdp, scene.pupil_diameter_mm, ideal)
    on_cdp = Accommodation(cdp, jnp.zeros((1, 1), jnp.int32), accommodation.sa_c40_um_per_D,
                           accommodation.sa_radius_mm)
    n_fft = max(b[2] for b in config.reference_bands)
    elemental = elemental_otfs(jnp.zeros((1,), cdp.dtype), 1.0, reference_scene, spectrum, on_cdp,
                               config.reference_bands, config.sampling)
    return render(elemental, reference_scene, on_cdp.pair_index, n_fft, config.freq_step_cpd)[0, 0]


@eqx.filter_jit
def reference_normalisers(scene: Scene, spectrum: Spectrum, accommodation: Accommodation,
                          config: PipelineConfig):
    """VSOTF denominator Σ NCSF·Re OTF_ref and PSF peak (per arcmin²) of the reference eye:
    no monochromatic aberrations, accommodated on the CDP and the point rendered on it,
    accommodation SA and LCA kept, through the same layout or the open pupil, of an ideal
    display (no lenslet diffraction, point emitters; the subapertures keep their shape), so
    VSOTF and Strehl values stay comparable when display effects are switched on. Compiled
    here (``eqx.filter_jit``), for callers that evaluate it once for many calls."""
    n_fft = max(b[2] for b in config.reference_bands)
    otf = reference_otf(scene, spectrum, accommodation, config)
    weighted_ncsf = ncsf_half_plane(n_fft, config.freq_step_cpd, config.ncsf)
    return vsotf_numerator(otf, weighted_ncsf), psf_peak(otf, n_fft, config.freq_step_cpd)


# ----------------------------------------------------------------------------- the pipeline


@eqx.filter_jit
def otf_stack(eyes: Eyes, scene: Scene, spectrum: Spectrum, accommodation: Accommodation,
              config: PipelineConfig):
    """Rendered polychromatic OTFs, (n_eyes, n_depth, n_k, L, L//2+1) half planes, OTF(0) = 1.

    Compiled here (``eqx.filter_jit``: ``config`` static, arrays traced), pure like
    :func:`retinal_metrics`."""
    if config.traced_checks:
        eyes, scene, accommodation = checked_inputs(eyes, scene, accommodation)

    def one_eye(zernike_um):
        return rendered_otfs(zernike_um, eyes.measured_pupil_mm, scene, spectrum, accommodation,
                             config.bands, config.sampling)

    return jax.lax.map(one_eye, eye_coefficients(eyes, config), batch_size=config.eye_chunk)


@eqx.filter_jit
def retinal_metrics(eyes: Eyes, scene: Scene, spectrum: Spectrum, accommodation: Accommodation,
                    config: PipelineConfig, reference=None) -> RetinalMetrics:
    """VSOTF, Strehl ratio and radial MTF of every eye and (rendered depth, k) pair.

    The paper's chain (Miyanishi et al. §2; docs/design.md#the-model-stage-by-stage), one eye at a time:

    1–5. eye wavefront + accommodation (defocus and SA) + LCA, Stiles–Crawford apodised
         subaperture pupils → elemental PSFs → OTFs, weighted by the spectrum and summed
         over wavelength, once per accommodation state;
    6–7. each view displaced by the display for each rendered depth, summed (OTF(0) = 1);
    8.   VSOTF = Σ NCSF·Re OTF / the reference's; Strehl = PSF peak / the reference's;
         radial MTF.

    Compiled here (``eqx.filter_jit``: ``config`` static, arrays traced; inside an outer
    transformation it is inlined). Pure: ``jax.jit``, ``jax.vmap`` and ``jax.grad`` apply
    from outside, in every leaf of
    ``eyes``, ``scene``, ``spectrum`` and ``accommodation``. ``reference`` = the
    :func:`reference_normalisers` of this scene, when the caller evaluates it once for many
    calls (solvers). Returns arrays of shape (n_eyes, n_depth, n_k[, L//2+1]).
    """
    if config.traced_checks:
        eyes, scene, accommodation = checked_inputs(eyes, scene, accommodation)
    n_fft, df = config.n_fft, config.freq_step_cpd
    if reference is None:
        reference = reference_normalisers(scene, spectrum, accommodation, config)
    reference_vsotf, reference_peak = reference
    weighted_ncsf = ncsf_half_plane(n_fft, df, config.ncsf)

    def one_eye(zernike_um):
        otf = rendered_otfs(zernike_um, eyes.measured_pupil_mm, scene, spectrum, accommodation,
                            config.bands, config.sampling)
        return RetinalMetrics(
            vsotf=vsotf_numerator(otf, weighted_ncsf) / reference_vsotf,
            strehl=psf_peak(otf, n_fft, df) / reference_peak,
            radial_mtf=radial_mtf(otf, n_fft, df)[0],
        )

    return jax.lax.map(one_eye, eye_coefficients(eyes, config), batch_size=config.eye_chunk)


def pair_metric(zernike_um, measured_pupil_mm: float, scene: Scene, spectrum: Spectrum,
                accommodation: Accommodation, config: PipelineConfig, reference,
                metric: str = "vsotf"):
    """One eye's VSOTF or Strehl ratio for each (depth, k) pair, (n_depth, n_k).

    The inner function of solvers: only the metric asked for is traced (derivatives of the
    others would be traced and then discarded), and the inputs are not re-checked (the
    caller's grid evaluation checked them). ``zernike_um`` as the pipeline uses it (piston
    and tilt already dropped); ``reference`` from :func:`reference_normalisers`.
    """
    n_fft, df = config.n_fft, config.freq_step_cpd
    otf = rendered_otfs(zernike_um, measured_pupil_mm, scene, spectrum, accommodation,
                        config.bands, config.sampling)
    if metric == "vsotf":
        return vsotf_numerator(otf, ncsf_half_plane(n_fft, df, config.ncsf)) / reference[0]
    return psf_peak(otf, n_fft, df) / reference[1]


@eqx.filter_jit
def vsotf_and_strehl(eyes: Eyes, scene: Scene, spectrum: Spectrum, accommodation: Accommodation,
                     config: PipelineConfig):
    """(vsotf, strehl), each (n_eyes, n_depth, n_k): :func:`retinal_metrics` without the
    radial MTF (compiled; what solvers differentiate)."""
    m = retinal_metrics(eyes, scene, spectrum, accommodation, config)
    return m.vsotf, m.strehl


__all__ = [
    "transform_units",
    "Scene",
    "Accommodation",
    "PipelineConfig",
    "RetinalMetrics",
    "retinal_metrics",
    "rendered_otfs",
    "streams_views",
    "held_elemental_planes",
    "ELEMENTAL_STACK_BYTES",
    "pair_metric",
    "vsotf_and_strehl",
    "otf_stack",
    "reference_normalisers",
    "reference_otf",
    "elemental_otfs",
    "render",
    "checked_inputs",
    "eye_coefficients",
]
