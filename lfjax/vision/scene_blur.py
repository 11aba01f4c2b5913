"""The blur of the rest of the scene: points at other depths than the one the eye focuses on,
seen through a light-field display and in natural viewing, per display primary.

The eye is accommodated at ``a`` (D), usually its predicted accommodation for a fixated
rendered depth. A point at depth ``d`` (D) is then seen

* **through the display** as the sum of its views' PSFs, each the eye's PSF through one
  subaperture at accommodation ``a`` for light diverging from the CDP, displaced by the
  parallax ``(d − CDP)·u`` of its view at pupil position ``u`` (docs/design.md, stages 5–7):
  :func:`lfjax.vision.psf.polychromatic_otf` with ``depths_D=[d]``. The subaperture's own
  defocus ``(a − CDP)`` over its offset part of the pupil adds a tilt ``−(a − CDP)·u``, so
  each view lands at ``(d − a)·u``, exactly where the same pupil zone images a real point
  at ``d``: the views sample natural defocus at n×n points of the pupil, each with the
  blur of its subaperture focused at the CDP;
* **in natural viewing** as a real point at ``d`` through the open pupil: the eye's own
  aberrations, the accommodation's spherical aberration at ``a``, the Stiles–Crawford
  apodisation and the chromatic defocus of every wavelength, with defocus ``a − d``
  (the model's sign: positive is myopic, the point farther than focus). It is the open
  pupil with its "CDP" at ``d`` (:func:`natural_otfs`).

Both are computed per primary of the display (:func:`lfjax.display.spectra.display_spectrum`
with channel ``"red"``, ``"green"``, ``"blue"``), so the chromatic defocus of the eye
(LCA: the eye has more power at short wavelengths, so blue comes to focus for objects
*nearer* than the green accommodation and red for objects *farther*) shows as a signed
difference between the red and blue blur (:func:`chromatic_cue`): for a point farther than
focus red is sharper than blue, for a nearer one blue is sharper (Cholewiak, Love & Banks,
J. Vis. 2018).

Measures (:func:`blur_measures`):

* ``equivalent_defocus_D`` — the signed natural defocus ``δ = d_nat − a`` (D; positive: a
  point nearer than focus) whose NCSF-weighted MTFs of the three primaries best match the
  display's (least squares, the primaries weighted equally so that the blue channel, which
  carries the chromatic sign but little luminance, counts), to be read against the true
  ``d − a``. The sign comes from the chromatic defocus and the eye's odd aberrations: the
  MTF of an aberration-free eye is the same at ±δ, so a monochromatic match could not sign
  it. For natural viewing it is the true defocus (the measure's zero, tested).
* ``mtf_ratio`` — Σ NCSF·MTF of the display over the same for natural viewing of the same
  point (1: as sharp as nature; > 1: the display shows the out-of-focus point too sharp);
  ``mtf_rms`` — the NCSF-weighted RMS difference of the two MTFs (0: identical blur);
  ``match_rms`` — the same at the equivalent defocus (how well *any* natural blur matches).

Everything is per eye; :mod:`lfjax.studies.scene_blur` maps it over layouts, panels, depths
and a population.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.sampling import Sampling
from lfjax.display.lenslets import DisplayOptics
from lfjax.display.spectra import DisplayPrimaries, display_spectrum
from lfjax.kernel.metrics import ncsf_half_plane
from lfjax.kernel.pipeline import PipelineConfig, otf_stack
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout, open_pupil
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import Spectrum
from lfjax.vision.prepare import States, default_sampling, prepare
from lfjax.vision.psf import polychromatic_otf
from lfjax.vision.viewing import Viewing

PRIMARIES = ("red", "green", "blue")
"""The display channels, in the order of every ``n_channel`` axis here."""

DEFAULT_DEFOCUS_GRID_D = np.round(np.arange(-4.0, 4.0 + 1e-9, 0.05), 6)
"""Signed natural defocus δ (D) searched by :func:`equivalent_defocus` (then refined)."""


def channel_spectra(primaries: DisplayPrimaries | str = "oled",
                    options: ModelOptions = ModelOptions(),
                    channels: tuple[str, ...] = PRIMARIES) -> tuple[Spectrum, ...]:
    """The model spectrum of each primary alone (V(λ)-weighted emission), in ``channels`` order."""
    return tuple(display_spectrum(primaries, c, options) for c in channels)


def single_eye(eye: Eyes) -> Eyes:
    """``eye`` if it is an :class:`~lfjax.model.eyes.Eyes` of one eye, else a clear error."""
    if not isinstance(eye, Eyes):
        raise TypeError(f"eye must be an lfjax Eyes of one eye, got {type(eye).__name__}")
    if eye.n_eyes != 1:
        raise ParameterError("eye", "{eye} must hold one eye (eyes[i:i+1]), got {got} eyes",
                             got=eye.n_eyes)
    return eye


def _check_depths(name: str, depths) -> np.ndarray:
    d = np.atleast_1d(np.asarray(depths, float))
    if d.ndim != 1 or d.size < 1:
        raise ParameterError(name, "{" + name + "} must be a 1-D list of depths (D), got shape {got}",
                             got=d.shape)
    if not np.all(np.isfinite(d)) or np.any(d < 0) or np.any(d > 10):
        raise ParameterError(name, "{" + name + "} must be finite depths in [0, 10] D, got {got}",
                             got=d.tolist())
    return d


def common_sampling(eye: Eyes, layouts, accommodation_D: float, depths_D, spectra,
                    *, pupil_diameter_mm: float = 3.0, cdp_D: float = 2.0,
                    options: ModelOptions = ModelOptions(),
                    display: DisplayOptics | None = None,
                    natural_defocus_D=None) -> Sampling:
    """One frequency sampling for the display's and natural viewing's OTFs of a scene, so
    that their MTFs compare sample by sample: the planner's field guard of every layout
    rendering ``depths_D`` at ``accommodation_D`` and of the open pupil defocused by up to
    the largest ``|a − d|`` (or ``natural_defocus_D``), the finest step of them all."""
    depths = _check_depths("depths_D", depths_D)
    a = float(accommodation_D)
    steps = []
    wide = max(spectra, key=lambda s: float(np.ptp(np.asarray(s.wavelengths_nm))) if
               s.n_wavelengths > 1 else 0.0)
    for layout in layouts:
        if layout is None:
            continue
        states = States.every([a], depths)
        steps.append(
            default_sampling(
                eye,
                layout,
                states,
                Viewing(pupil_diameter_mm=pupil_diameter_mm, cdp_D=cdp_D, display=display),
                spectrum=wide,
                options=options,
            )
        )
    deltas = depths - a if natural_defocus_D is None else np.asarray(natural_defocus_D, float)
    objects = np.clip(a + deltas, 0.0, 10.0)
    worst = float(objects[np.argmax(np.abs(objects - a))])
    steps.append(
        default_sampling(
            eye,
            open_pupil(pupil_diameter_mm),
            States.every([a], [worst]),
            Viewing(pupil_diameter_mm=pupil_diameter_mm, cdp_D=worst),
            spectrum=wide,
            options=options,
        )
    )
    return with_channels_n_fft(min(steps, key=lambda s: s.freq_step_cpd), spectra,
                               pupil_diameter_mm, options)


def with_channels_n_fft(sampling: Sampling, spectra, pupil_diameter_mm: float,
                        options: ModelOptions = ModelOptions()) -> Sampling:
    """``sampling`` with one FFT size for every channel's spectrum (``spectra``) on the open
    pupil of ``pupil_diameter_mm`` (mm): the largest any of them needs, or the sampling's own
    ``n_fft`` if larger. The OTF grid grows at short wavelengths (the pupil's support in
    cycles per degree is d/λ), so the bluest channel's size is used by all, and the
    channels' OTFs stack on one grid."""
    n_fft = max(PipelineConfig.build(s.wavelengths_nm, pupil_diameter_mm, pupil_diameter_mm,
                                     sampling, options).n_fft for s in spectra)
    return dataclasses.replace(sampling, n_fft=max(n_fft, sampling.n_fft or 0))


def natural_otfs(eye: Eyes, accommodation_D: float, object_depths_D, spectra,
                 sampling: Sampling, *, pupil_diameter_mm: float = 3.0,
                 options: ModelOptions = ModelOptions()):
    """OTFs of real points at ``object_depths_D`` seen by ``eye`` accommodated at
    ``accommodation_D``, one per spectrum: (n_channel, n_object, L, L//2+1), OTF(0) = 1.

    The open pupil with its CDP at the object (defocus ``a − d``), its accommodation SA at
    ``a``: :func:`lfjax.kernel.pipeline.otf_stack` mapped over the CDP leaf, one compiled
    program for every object depth. A ``sampling`` without ``n_fft`` gets the one FFT size
    of every channel (:func:`with_channels_n_fft`), so that the channels stack."""
    eye = single_eye(eye)
    depths = jnp.asarray(_check_depths("object_depths_D", object_depths_D))
    spectra = tuple(spectra)
    if sampling.n_fft is None:
        sampling = with_channels_n_fft(sampling, spectra, pupil_diameter_mm, options)
    out = []
    for spectrum in spectra:
        prepared = prepare(
            eye,
            None,
            States.every([float(accommodation_D)], [float(depths[0])]),
            Viewing(pupil_diameter_mm=pupil_diameter_mm, cdp_D=float(depths[0])),
            spectrum=spectrum,
            options=options,
            sampling=sampling,
            check_aliasing=False,
            traced_checks=False,
        )
        out.append(_natural_stack(eye, prepared.scene, spectrum, prepared.accommodation(options),
                                  prepared.config, depths))
    return jnp.stack(out)


@eqx.filter_jit
def _natural_stack(eye, scene, spectrum, accommodation, config, depths):
    """One compiled program per configuration: the open pupil's OTF with its CDP moved to
    every object depth (the defocus a − d), (n_object, L, L//2+1)."""

    def one(d):
        moved = eqx.tree_at(lambda s: (s.cdp_D, s.depths_D), scene, (d, jnp.reshape(d, (1,))))
        return otf_stack(eye, moved, spectrum, accommodation, config)[0, 0, 0]

    return jax.lax.map(one, depths)


def embed_otf(otf_half, n_fft: int):
    """A half-plane OTF (…, L, L//2+1) on the larger grid (…, n_fft, n_fft//2+1) of the same
    frequency step: zero outside its support. A subaperture's OTF is computed on a grid
    scaled to its window (a 2×2 view's support is half the pupil's), the open pupil's on the
    full one; the MTFs compare only on one grid."""
    L = int(otf_half.shape[-2])
    if L == n_fft:
        return otf_half
    if L > n_fft:
        raise ValueError(f"cannot embed an OTF of size {L} in a smaller grid {n_fft}")
    rows = np.fft.fftfreq(L, 1.0 / L).astype(int) % n_fft
    out = jnp.zeros(otf_half.shape[:-2] + (n_fft, n_fft // 2 + 1), otf_half.dtype)
    return out.at[..., rows, : L // 2 + 1].set(otf_half)


def display_otfs(eye: Eyes, layout: Layout | None, accommodation_D: float, depths_D, spectra,
                 sampling: Sampling, *, pupil_diameter_mm: float = 3.0, cdp_D: float = 2.0,
                 options: ModelOptions = ModelOptions(), display: DisplayOptics | None = None):
    """OTFs of points rendered at ``depths_D`` by ``layout`` (its CDP ``cdp_D``), the eye at
    ``accommodation_D``: (n_channel, n_depth, L, L//2+1). ``layout=None`` is natural viewing
    (:func:`natural_otfs`)."""
    if layout is None:
        return natural_otfs(eye, accommodation_D, depths_D, spectra, sampling,
                            pupil_diameter_mm=pupil_diameter_mm, options=options)
    eye = single_eye(eye)
    depths = _check_depths("depths_D", depths_D)
    out = [
        polychromatic_otf(
            eye,
            [float(accommodation_D)],
            Viewing(pupil_diameter_mm=pupil_diameter_mm, cdp_D=cdp_D, display=display),
            layout=layout,
            depths_D=depths,
            spectrum=spectrum,
            sampling=sampling,
            options=options,
            check_aliasing=False,
        ).otf[0, :, 0]
        for spectrum in spectra
    ]
    return jnp.stack(out)


def ncsf_weights(n_fft: int, freq_step_cpd: float, options: ModelOptions = ModelOptions()):
    """NCSF × half-plane multiplicity on the OTF grid, normalised to sum 1, (L, L//2+1)."""
    w = ncsf_half_plane(n_fft, freq_step_cpd, options.ncsf, host=True)
    return w / w.sum()


def weighted_mtf(otf, weights):
    """Σ NCSF·|OTF| (weights from :func:`ncsf_weights`): 1 for a perfect image, (…)."""
    return jnp.sum(jnp.abs(otf) * weights, axis=(-2, -1))


def chromatic_cue(otf, weights, red: int = 0, blue: int = 2):
    """Signed chromatic blur (m_R − m_B)/(m_R + m_B) with m the NCSF-weighted MTF of a
    channel (axis 0 of ``otf``): > 0 red sharper than blue (a point farther than focus in
    natural viewing), < 0 blue sharper (nearer). Shape: ``otf.shape[1:-2]``."""
    m = weighted_mtf(otf, weights)
    return (m[red] - m[blue]) / (m[red] + m[blue])


def equivalent_defocus(otf, natural_grid_otf, grid_defocus_D, weights):
    """The signed natural defocus whose MTFs best match ``otf``'s, D, and the match's RMS.

    Parameters
    ----------
    otf : (n_channel, n, L, L//2+1) OTFs to match (e.g. the display's at n depths)
    natural_grid_otf : (n_channel, n_grid, L, L//2+1) natural OTFs at ``grid_defocus_D``
    grid_defocus_D : (n_grid,) increasing signed natural defocus δ = d − a, D, evenly spaced
    weights : (L, L//2+1) NCSF weights (:func:`ncsf_weights`)

    Returns
    -------
    (delta_D, rms) each (n,): the minimum of E(δ) = mean over channels of Σ w (|OTF| −
    |OTF_nat(δ)|)² on the grid, refined by the parabola through the grid minimum and its
    neighbours (kept within them); ``rms`` = √E there (interpolated).
    """
    grid = np.asarray(grid_defocus_D, float)
    m = jnp.abs(otf)[:, :, None]  # (c, n, 1, L, Lh)
    g = jnp.abs(natural_grid_otf)[:, None]  # (c, 1, g, L, Lh)
    err = jnp.mean(jnp.sum((m - g) ** 2 * weights, axis=(-2, -1)), axis=0)  # (n, g)
    err = np.asarray(err, float)
    i = np.clip(np.argmin(err, axis=1), 1, grid.size - 2)
    rows = np.arange(err.shape[0])
    e0, e1, e2 = err[rows, i - 1], err[rows, i], err[rows, i + 1]
    curv = e0 - 2 * e1 + e2
    step = grid[1] - grid[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(curv > 0, 0.5 * (e0 - e2) / curv, 0.0)
    t = np.clip(t, -1.0, 1.0)
    delta = grid[i] + t * step
    e_min = np.maximum(e1 - 0.25 * (e0 - e2) * t, 0.0)
    return delta, np.sqrt(e_min)


def blur_measures(display_otf, natural_otf, natural_grid_otf, grid_defocus_D, weights) -> dict:
    """Every measure of the module docstring for n points, as NumPy arrays (n,) (the cue:
    (n,) for the display and for natural viewing)."""
    eq, match = equivalent_defocus(display_otf, natural_grid_otf, grid_defocus_D, weights)
    eq_nat, _ = equivalent_defocus(natural_otf, natural_grid_otf, grid_defocus_D, weights)
    md = weighted_mtf(display_otf, weights)
    mn = weighted_mtf(natural_otf, weights)
    diff = jnp.mean(jnp.sum((jnp.abs(display_otf) - jnp.abs(natural_otf)) ** 2 * weights,
                            axis=(-2, -1)), axis=0)
    return dict(
        equivalent_defocus_D=eq, natural_equivalent_defocus_D=eq_nat, match_rms=match,
        mtf_ratio=np.asarray(jnp.mean(md, axis=0) / jnp.mean(mn, axis=0), float),
        mtf_rms=np.sqrt(np.asarray(diff, float)),
        cue_display=np.asarray(chromatic_cue(display_otf, weights), float),
        cue_natural=np.asarray(chromatic_cue(natural_otf, weights), float),
    )


def rest_of_scene(eye: Eyes, layout: Layout | None, accommodation_D: float, depths_D,
                  primaries: DisplayPrimaries | str = "oled", *, pupil_diameter_mm: float = 3.0,
                  cdp_D: float = 2.0, options: ModelOptions = ModelOptions(),
                  display: DisplayOptics | None = None, sampling: Sampling | None = None,
                  grid_defocus_D=None) -> dict:
    """The display's blur of points at ``depths_D`` against natural viewing, one eye at
    ``accommodation_D`` (D): the measures of :func:`blur_measures` with the true defocus
    ``true_defocus_D = d − a`` and the OTFs (``display_otf``, ``natural_otf``, each
    (3, n_depth, L, L//2+1), with ``freq_step_cpd``)."""
    eye = single_eye(eye)
    depths = _check_depths("depths_D", depths_D)
    a = float(accommodation_D)
    if not (np.isfinite(a) and 0 <= a <= 10):
        raise ParameterError("accommodation_D", "{accommodation_D} must be in [0, 10] D, got {got}",
                             got=accommodation_D)
    spectra = channel_spectra(primaries, options)
    grid = DEFAULT_DEFOCUS_GRID_D if grid_defocus_D is None else np.asarray(grid_defocus_D, float)
    grid = grid[(a + grid >= 0) & (a + grid <= 10)]
    if sampling is None:
        sampling = common_sampling(eye, [layout], a, depths, spectra,
                                   pupil_diameter_mm=pupil_diameter_mm, cdp_D=cdp_D,
                                   options=options, display=display,
                                   natural_defocus_D=np.r_[grid, depths - a])
    dis = display_otfs(eye, layout, a, depths, spectra, sampling,
                       pupil_diameter_mm=pupil_diameter_mm, cdp_D=cdp_D, options=options,
                       display=display)
    nat = natural_otfs(eye, a, depths, spectra, sampling, pupil_diameter_mm=pupil_diameter_mm,
                       options=options)
    nat_grid = natural_otfs(eye, a, a + grid, spectra, sampling,
                            pupil_diameter_mm=pupil_diameter_mm, options=options)
    n_fft = max(int(dis.shape[-2]), int(nat.shape[-2]))
    dis, nat, nat_grid = (embed_otf(o, n_fft) for o in (dis, nat, nat_grid))
    weights = ncsf_weights(n_fft, sampling.freq_step_cpd, options)
    out = blur_measures(dis, nat, nat_grid, grid, weights)
    out.update(true_defocus_D=depths - a, depths_D=depths, accommodation_D=a,
               display_otf=dis, natural_otf=nat, freq_step_cpd=float(sampling.freq_step_cpd))
    return out


__all__ = [
    "PRIMARIES",
    "DEFAULT_DEFOCUS_GRID_D",
    "channel_spectra",
    "single_eye",
    "common_sampling",
    "with_channels_n_fft",
    "natural_otfs",
    "display_otfs",
    "embed_otf",
    "ncsf_weights",
    "weighted_mtf",
    "chromatic_cue",
    "equivalent_defocus",
    "blur_measures",
    "rest_of_scene",
]
