"""The pipeline as one pure function: eyes × scene × spectrum × accommodation → metrics.

Four pytrees carry the physics as arrays (every float a sweep or a fit varies is a leaf, so
``jax.jit``, ``jax.vmap`` and ``jax.grad`` can wrap the pipeline from outside without
recompiling per value):

* :class:`lfjax.eyes.Eyes` — Zernike coefficients (µm), batch axis first;
* :class:`Scene` — what the display shows and through which pupil: subaperture centres and
  diameters (mm), the central depth plane (D), rendered depths (D), the calculation pupil
  (mm), and optionally the display's own optics (:class:`lfjax.display.DisplayOptics`:
  lenslet diffraction, finite pixels);
* :class:`lfjax.spectral.Spectrum` — wavelengths (nm), weights, LCA (D), Stiles–Crawford ρ;
* :class:`Accommodation` — the accommodation states (D) and which state each
  (depth, k) pair uses, with the accommodation-dependent spherical aberration.

One hashable, static :class:`PipelineConfig` holds everything that sets array shapes or
selects code: the frequency sampling and its wavelength bands, the NCSF model, the VSOTF
reference and the eye chunk. :func:`retinal_metrics` is the paper's chain on one screen;
:func:`lfjax.through_focus.through_focus`, :func:`lfjax.through_focus.metrics_at`,
:func:`lfjax.optics.polychromatic_otf`, the peak finder and the layout optimiser all call it
(or :func:`otf_stack`, its first half).

Bad values are refused twice: on the host with a message naming the parameter (the public
wrappers, before any tracing) and, for traced values, with ``eqx.error_if`` inside the
pipeline, so a NaN never leaves it silently.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ._types import as_index_array, as_real_array as _real
from .display import DisplayOptics, pixel_transfer
from .eyes import Eyes
from .layouts import Layout
from .metrics import ncsf_half_plane, psf_peak, radial_mtf, vsotf_numerator
from .optics import _elemental_otfs, half_frequencies_cpd, frequencies_cpd, sa_parameters
from .options import ModelOptions
from .sampling import Sampling, wavelength_bands
from .spectral import Spectrum
from .units import DEGREES_PER_RADIAN


class Scene(eqx.Module):
    """The display scene seen through the eye's pupil (all leaves are arrays).

    Attributes
    ----------
    centres_mm : (n_sub, 2) subaperture centres (x, y) in the pupil plane, mm
    diameters_mm : (n_sub,) subaperture diameters, mm (cropped by the pupil)
    cdp_D : () central depth plane of the display, D
    depths_D : (n_depth,) rendered depths, D (0 D = infinity)
    pupil_diameter_mm : () calculation pupil, mm
    display : :class:`lfjax.display.DisplayOptics` or None (the paper's ideal display:
        geometric circular subapertures, point emitters)
    """

    centres_mm: Float[Array, "n_sub 2"] = eqx.field(converter=_real)
    diameters_mm: Float[Array, " n_sub"] = eqx.field(converter=_real)
    cdp_D: Float[Array, ""] = eqx.field(converter=_real)
    depths_D: Float[Array, " n_depth"] = eqx.field(converter=_real)
    pupil_diameter_mm: Float[Array, ""] = eqx.field(converter=_real)
    display: DisplayOptics | None = None

    def __check_init__(self):
        if self.centres_mm.ndim < 2 or self.centres_mm.shape[-1] != 2:
            raise ValueError(f"Scene.centres_mm must have shape (n_sub, 2), got {self.centres_mm.shape}")
        if self.diameters_mm.shape[-1:] != self.centres_mm.shape[-2:-1]:
            raise ValueError(
                f"Scene.diameters_mm must have shape ({self.centres_mm.shape[-2]},), "
                f"got {self.diameters_mm.shape}"
            )

    @classmethod
    def from_layout(cls, layout: Layout, depths_D, cdp_D, pupil_diameter_mm,
                    display: DisplayOptics | None = None) -> Scene:
        """Scene of a :class:`~lfjax.layouts.Layout` rendering ``depths_D`` (D)."""
        return cls(layout.centres_mm, layout.diameters_mm, cdp_D, jnp.atleast_1d(_real(depths_D)),
                   pupil_diameter_mm, display)

    @property
    def n_depths(self) -> int:
        return int(self.depths_D.shape[-1])


class Accommodation(eqx.Module):
    """Accommodation states and how the eye changes with them.

    Elemental OTFs are computed once per entry of ``states_D`` and shared by every rendered
    depth that uses it (``pair_index``).

    Attributes
    ----------
    states_D : (n_states,) absolute accommodation 1/z_acc, D
    pair_index : (n_depth, n_k) int, the state of each (rendered depth, k) pair
    sa_c40_um_per_D : () change of c(4,0) per dioptre of accommodation on the Zernike
        pupil of radius ``sa_radius_mm``, µm/D (Cheng et al. 2004, as ``ModelOptions`` reads it)
    sa_radius_mm : () radius of that Zernike pupil, mm
    """

    states_D: Float[Array, " n_states"] = eqx.field(converter=_real)
    pair_index: Int[Array, "n_depth n_k"] = eqx.field(converter=as_index_array)
    sa_c40_um_per_D: Float[Array, ""] = eqx.field(converter=_real)
    sa_radius_mm: Float[Array, ""] = eqx.field(converter=_real)

    def __check_init__(self):
        if self.pair_index.ndim < 2:
            raise ValueError(
                f"Accommodation.pair_index must have shape (n_depth, n_k), got {self.pair_index.shape}"
            )

    @classmethod
    def per_depth(cls, accommodation_D, options: ModelOptions, pupil_diameter_mm) -> Accommodation:
        """States given per rendered depth, (n_depth, n_k) in D: each pair computed on its own."""
        acc = _real(accommodation_D)
        if acc.ndim != 2:
            raise ValueError(f"accommodation_D must have shape (n_depth, n_k), got {acc.shape}")
        index = jnp.arange(acc.size, dtype=jnp.int32).reshape(acc.shape)
        return cls.shared(acc.reshape(-1), index, options, pupil_diameter_mm)

    @classmethod
    def shared(cls, states_D, pair_index, options: ModelOptions, pupil_diameter_mm) -> Accommodation:
        """States ``states_D`` (D) shared by depths through ``pair_index`` (n_depth, n_k)."""
        sa = sa_parameters(options, _real(pupil_diameter_mm))
        return cls(states_D, pair_index, sa[0], sa[1])


@dataclass(frozen=True)
class PipelineConfig:
    """Static configuration: shapes and code paths (hashable; changing it recompiles).

    Attributes
    ----------
    sampling : frequency step, transform and aperture edge
    bands : ((start, stop, n_fft), …) wavelength bands of the scene's layout
    reference_bands : the same for the VSOTF/Strehl reference aperture
    ncsf : NCSF model name (:mod:`lfjax.metrics`)
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
    ) -> PipelineConfig:
        """Bands for a spectrum (nm) and a layout whose largest window is
        ``window_diameter_mm`` (mm), on a calculation pupil of ``pupil_diameter_mm`` (mm);
        everything here is concrete host data. With lenslet diffraction (``display``) every
        view's window is the pupil; the reference (an ideal display) keeps the layout's."""
        wl = np.asarray(wavelengths_nm, float)
        pupil = float(pupil_diameter_mm)
        reference_window = window_diameter_mm if options.vsotf_reference == "paper" else pupil
        if display is not None and display.diffracts:
            window_diameter_mm = pupil
        return cls(
            sampling,
            wavelength_bands(wl, float(window_diameter_mm), pupil, sampling),
            wavelength_bands(wl, float(reference_window), pupil, sampling),
            options.ncsf, options.vsotf_reference, options.zero_piston_tilt,
            None if eye_chunk is None else int(eye_chunk), bool(traced_checks),
        )

    def replace(self, **changes) -> PipelineConfig:
        return dataclasses.replace(self, **changes)


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


def _eye_coefficients(eyes: Eyes, config: PipelineConfig):
    z = eyes.zernike_um
    return z.at[..., :3].set(0.0) if config.zero_piston_tilt else z


def elemental_otfs(zernike_um, measured_pupil_mm: float, scene: Scene, spectrum: Spectrum,
                   accommodation: Accommodation, bands, sampling: Sampling):
    """Spectrally weighted elemental OTFs of one eye, (n_states, n_sub, L, L//2+1), each
    carrying the energy its pupil transmits (stages 1–5 of docs/design.md#the-model-stage-by-stage)."""
    return _elemental_otfs(
        zernike_um, measured_pupil_mm, scene.pupil_diameter_mm, scene.cdp_D, accommodation.states_D,
        scene.centres_mm, scene.diameters_mm, spectrum, bands, sampling,
        jnp.stack([accommodation.sa_c40_um_per_D, accommodation.sa_radius_mm]), scene.display,
    )


def render(elemental, scene: Scene, pair_index, n_fft: int, freq_step_cpd: float):
    """Rendered polychromatic OTFs of every (depth, k) pair, (n_depth, n_k, L, L//2+1), OTF(0) = 1.

    View n of depth d is displaced by Δθ_n = (D_d − D_CDP)·(p_n, q_n) (rad; D in 1/m, p in
    m), applied as the phase ramp exp(−2πi f·Δθ_n); pair (d, k) sums the views' elemental
    OTFs of state ``pair_index[d, k]`` (stages 6–7). Finite pixels (``scene.display``)
    blur every view alike: the sum is multiplied by the emitter's transfer function.
    """
    fy_rad = frequencies_cpd(n_fft, freq_step_cpd) * DEGREES_PER_RADIAN
    fx_rad = half_frequencies_cpd(n_fft, freq_step_cpd) * DEGREES_PER_RADIAN
    shift_rad = (scene.depths_D - scene.cdp_D)[:, None, None] * scene.centres_mm[None] * 1e-3
    ramp_x = jnp.exp(-2j * jnp.pi * shift_rad[..., 0:1] * fx_rad)  # (n_depth, n_sub, Lx)
    ramp_y = jnp.exp(-2j * jnp.pi * shift_rad[..., 1:2] * fy_rad)  # (n_depth, n_sub, L)

    def add_view(total, view):
        elemental_n, ry, rx = view  # (n_states, L, Lx), (n_depth, L), (n_depth, Lx)
        ramp = ry[:, None, :, None] * rx[:, None, None, :]
        return total + ramp * elemental_n[pair_index], None

    # A scan over views keeps memory at one (n_depth, n_k, L, Lx) block; an einsum over the
    # view axis lowers to tiny per-pixel matmuls, slow on CPU.
    init = jnp.zeros(pair_index.shape + elemental.shape[2:], elemental.dtype)
    otf, _ = jax.lax.scan(
        add_view, init,
        (jnp.moveaxis(elemental, 1, 0), jnp.moveaxis(ramp_y, 1, 0), jnp.moveaxis(ramp_x, 1, 0)),
    )
    energy = jnp.real(jnp.sum(elemental[:, :, 0, 0], axis=1))[pair_index]
    if scene.display is not None:
        otf = otf * pixel_transfer(fx_rad, fy_rad, scene.display)
    return otf / energy[..., None, None]


def reference_normalisers(scene: Scene, spectrum: Spectrum, accommodation: Accommodation,
                          config: PipelineConfig):
    """VSOTF denominator Σ NCSF·Re OTF_ref and PSF peak (per arcmin²) of the reference eye:
    no monochromatic aberrations, accommodated on the CDP and the point rendered on it,
    accommodation SA and LCA kept, through the same layout or the open pupil, of an ideal
    display (no lenslet diffraction, point emitters; the subapertures keep their shape), so
    VSOTF and Strehl values stay comparable when display effects are switched on."""
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
    otf = render(elemental, reference_scene, on_cdp.pair_index, n_fft, config.freq_step_cpd)[0, 0]
    weighted_ncsf = ncsf_half_plane(n_fft, config.freq_step_cpd, config.ncsf)
    return vsotf_numerator(otf, weighted_ncsf), psf_peak(otf, n_fft, config.freq_step_cpd)


# ----------------------------------------------------------------------------- the pipeline


def otf_stack(eyes: Eyes, scene: Scene, spectrum: Spectrum, accommodation: Accommodation,
              config: PipelineConfig):
    """Rendered polychromatic OTFs, (n_eyes, n_depth, n_k, L, L//2+1) half planes, OTF(0) = 1."""
    if config.traced_checks:
        eyes, scene, accommodation = checked_inputs(eyes, scene, accommodation)

    def one_eye(zernike_um):
        elemental = elemental_otfs(zernike_um, eyes.measured_pupil_mm, scene, spectrum,
                                   accommodation, config.bands, config.sampling)
        return render(elemental, scene, accommodation.pair_index, config.n_fft, config.freq_step_cpd)

    return jax.lax.map(one_eye, _eye_coefficients(eyes, config), batch_size=config.eye_chunk)


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

    Pure: ``jax.jit``, ``jax.vmap`` and ``jax.grad`` apply from outside, in every leaf of
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
        elemental = elemental_otfs(zernike_um, eyes.measured_pupil_mm, scene, spectrum,
                                   accommodation, config.bands, config.sampling)
        otf = render(elemental, scene, accommodation.pair_index, n_fft, df)
        return RetinalMetrics(
            vsotf=vsotf_numerator(otf, weighted_ncsf) / reference_vsotf,
            strehl=psf_peak(otf, n_fft, df) / reference_peak,
            radial_mtf=radial_mtf(otf, n_fft, df)[0],
        )

    return jax.lax.map(one_eye, _eye_coefficients(eyes, config), batch_size=config.eye_chunk)


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
    elemental = elemental_otfs(zernike_um, measured_pupil_mm, scene, spectrum, accommodation,
                               config.bands, config.sampling)
    otf = render(elemental, scene, accommodation.pair_index, n_fft, df)
    if metric == "vsotf":
        return vsotf_numerator(otf, ncsf_half_plane(n_fft, df, config.ncsf)) / reference[0]
    return psf_peak(otf, n_fft, df) / reference[1]


retinal_metrics_jit = eqx.filter_jit(retinal_metrics)
""":func:`retinal_metrics` compiled (``eqx.filter_jit``: static config, arrays traced)."""
otf_stack_jit = eqx.filter_jit(otf_stack)
""":func:`otf_stack` compiled (``eqx.filter_jit``: static config, arrays traced)."""


@eqx.filter_jit
def vsotf_and_strehl(eyes: Eyes, scene: Scene, spectrum: Spectrum, accommodation: Accommodation,
                     config: PipelineConfig):
    """(vsotf, strehl), each (n_eyes, n_depth, n_k): :func:`retinal_metrics` without the
    radial MTF (compiled; what solvers differentiate)."""
    m = retinal_metrics(eyes, scene, spectrum, accommodation, config)
    return m.vsotf, m.strehl


__all__ = [
    "Scene",
    "Accommodation",
    "PipelineConfig",
    "RetinalMetrics",
    "retinal_metrics",
    "pair_metric",
    "retinal_metrics_jit",
    "vsotf_and_strehl",
    "otf_stack",
    "otf_stack_jit",
    "reference_normalisers",
    "elemental_otfs",
    "render",
    "checked_inputs",
]
