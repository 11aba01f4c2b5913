"""Through-focus image quality and predicted accommodation (Miyanishi et al. §3).

One jitted call evaluates VSOTF, Strehl ratio and radial MTF for eyes × rendered depths ×
accommodation states of one layout. Elemental OTFs are computed once per eye and reused
for every rendered depth; only OTFs' metrics leave the jitted region, so memory stays at
one eye's OTF stack (eyes are mapped in chunks).
"""

from __future__ import annotations

from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .eyes import Eyes
from .layouts import Layout, open_pupil
from .metrics import ncsf_half_plane, psf_peak, radial_mtf, vsotf_numerator, cutoff_frequency
from .optics import (
    sa_parameters,
    validate_states,
    _elemental_otfs,
    _field_check,
    _render,
    _validate_coefficients,
    validate_pupil,
)
from .options import ModelOptions
from .sampling import Sampling, wavelength_bands
from .spectral import Spectrum, make_spectrum


class ThroughFocus(eqx.Module):
    """Through-focus metrics with their axes.

    Attributes
    ----------
    vsotf, strehl : (n_eyes, n_depth, n_acc) unitless; NaN where ``allowed`` is False
    radial_mtf : (n_eyes, n_depth, n_acc, n_freq) meridian-averaged MTF
    radial_freq_cpd : (n_freq,) cpd
    accommodation_D : (n_depth, n_acc) absolute accommodation states 1/z_acc, D
    allowed : (n_depth, n_acc) bool, False where the state is beyond the hyperopic limit
        (accommodation < 0 D); such states are not computed
    depths_D : (n_depth,) rendered depths, D
    cdp_D : float, D
    layout_name : str
    """

    vsotf: jnp.ndarray
    strehl: jnp.ndarray
    radial_mtf: jnp.ndarray
    radial_freq_cpd: jnp.ndarray
    accommodation_D: jnp.ndarray
    allowed: jnp.ndarray
    depths_D: jnp.ndarray
    cdp_D: float = eqx.field(static=True)
    layout_name: str = eqx.field(static=True, default="custom")

    def metric(self, name: str):
        if name not in ("vsotf", "strehl"):
            raise ValueError(f"metric must be 'vsotf' or 'strehl', got {name!r}")
        return getattr(self, name)

    def peak_index(self, metric: str = "vsotf"):
        """Index of the grid peak along accommodation among allowed states, (n_eyes, n_depth)."""
        values = np.where(np.asarray(self.allowed)[None], np.asarray(self.metric(metric)), -np.inf)
        return np.argmax(values, axis=-1)

    def predicted_accommodation_D(self, metric: str = "vsotf"):
        """Grid peak: the allowed accommodation state (D, absolute, exact grid value)."""
        idx = self.peak_index(metric)
        acc = np.broadcast_to(
            np.asarray(self.accommodation_D, float)[None], idx.shape + self.accommodation_D.shape[-1:]
        )
        return np.take_along_axis(acc, idx[..., None], axis=-1)[..., 0]

    @property
    def relative_accommodation_D(self):
        """Accommodation relative to each rendered depth, (n_depth, n_acc), D."""
        return self.accommodation_D - self.depths_D[:, None]

    def accommodation_error_D(self, metric: str = "vsotf"):
        """Predicted accommodation minus rendered depth, D (negative: focused farther)."""
        return self.predicted_accommodation_D(metric) - np.asarray(self.depths_D, float)[None, :]

    def mtf_at_peak(self, metric: str = "vsotf"):
        """Radial MTF at the predicted accommodation, (n_eyes, n_depth, n_freq)."""
        idx = jnp.asarray(self.peak_index(metric))
        return jnp.take_along_axis(self.radial_mtf, idx[..., None, None], axis=2)[:, :, 0]

    def cutoff_cpd(self, metric: str = "vsotf", threshold: float = 0.05):
        """Cut-off frequency (cpd) of the MTF at the predicted accommodation."""
        return cutoff_frequency(self.mtf_at_peak(metric), self.radial_freq_cpd, threshold)


def _check_states(accommodation_D, depths_D) -> None:
    acc = np.asarray(accommodation_D, float)
    depth = np.asarray(depths_D, float)
    if acc.ndim != 1 or acc.size < 1:
        raise ValueError(f"accommodation_D must be a 1-D grid of >= 1 states, got shape {acc.shape}")
    if depth.ndim != 1 or depth.size < 1:
        raise ValueError(f"depths_D must be a 1-D array of >= 1 depths, got shape {depth.shape}")
    if not np.all(np.isfinite(acc)) or not np.all(np.isfinite(depth)):
        raise ValueError("accommodation_D and depths_D must be finite")
    if np.any(acc < 0):
        raise ValueError(
            "accommodation_D must be >= 0 D (hyperopic limit: an eye cannot focus beyond "
            f"infinity); got states down to {acc.min():g} D. Drop them, e.g. with "
            "relative_accommodation_grid(..., hyperopic_limit=True)"
        )
    if np.any(depth < 0):
        raise ValueError(
            f"depths_D must be >= 0 D (0 D is optical infinity); got {depth[depth < 0].tolist()}"
        )


def relative_accommodation_grid(depths_D, offsets_D, hyperopic_limit: bool = True):
    """Absolute accommodation grid covering ``depth + offset`` for every depth (host).

    Returns (accommodation_D (n_acc,), index (n_depth, n_offsets)) where
    ``accommodation_D[index[d, k]] == depths_D[d] + offsets_D[k]``; entries excluded by the
    hyperopic limit (negative accommodation) have index −1. Values are rounded to 1e-9 D
    so shared states are computed once.
    """
    depths = np.atleast_1d(np.asarray(depths_D, float))
    offsets = np.atleast_1d(np.asarray(offsets_D, float))
    states = np.round(depths[:, None] + offsets[None, :], 9)
    allowed = states >= 0 if hyperopic_limit else np.ones_like(states, bool)
    if not np.any(allowed):
        raise ValueError("the accommodation grid excludes every allowed state (all < 0 D)")
    grid = np.unique(states[allowed])
    index = np.where(allowed, np.searchsorted(grid, states), -1)
    return grid, index


def _reference_normalisers(
    n_modes, measured_pupil_mm, pupil_diameter_mm, cdp_D, ref_centres_mm, ref_diameters_mm,
    spectrum, ref_bands, sampling, sa_params, ncsf_model,
):
    """VSOTF denominator and PSF peak of the reference: aberration-free, accommodated and
    rendered on the CDP, accommodation SA and LCA kept."""
    df = sampling.freq_step_cpd
    ref_n_fft = max(b[2] for b in ref_bands)
    cdp = jnp.reshape(cdp_D, (1,))
    ref_elemental = _elemental_otfs(
        jnp.zeros((n_modes,), pupil_diameter_mm.dtype), measured_pupil_mm, pupil_diameter_mm,
        cdp_D, cdp, ref_centres_mm, ref_diameters_mm, spectrum, ref_bands, sampling, sa_params,
    )
    ref_otf = _render(ref_elemental, ref_centres_mm, cdp_D, cdp, ref_n_fft, df)[0, 0]
    ref_vs = vsotf_numerator(ref_otf, ncsf_half_plane(ref_n_fft, df, ncsf_model))
    return ref_vs, psf_peak(ref_otf, ref_n_fft, df)


@partial(
    jax.jit,
    static_argnames=("measured_pupil_mm", "bands", "ref_bands", "sampling", "ncsf_model", "eye_chunk"),
)
def _through_focus_core(
    zernike_um, measured_pupil_mm, pupil_diameter_mm, cdp_D, accommodation_D, depths_D,
    pair_index, centres_mm, diameters_mm, ref_centres_mm, ref_diameters_mm, spectrum, bands,
    ref_bands, sampling, sa_params, ncsf_model, eye_chunk,
):
    df = sampling.freq_step_cpd
    n_fft = max(b[2] for b in bands)
    ref_vs, ref_peak = _reference_normalisers(
        zernike_um.shape[-1], measured_pupil_mm, pupil_diameter_mm, cdp_D, ref_centres_mm,
        ref_diameters_mm, spectrum, ref_bands, sampling, sa_params, ncsf_model,
    )
    weighted_ncsf = ncsf_half_plane(n_fft, df, ncsf_model)

    def one_eye(coefficients):
        elemental = _elemental_otfs(
            coefficients, measured_pupil_mm, pupil_diameter_mm, cdp_D, accommodation_D,
            centres_mm, diameters_mm, spectrum, bands, sampling, sa_params,
        )
        otf = _render(elemental, centres_mm, cdp_D, depths_D, n_fft, df)
        # keep only the (depth, state) pairs asked for: (n_depth, n_k, L, L//2+1)
        otf = jnp.take_along_axis(otf, pair_index[:, :, None, None], axis=1)
        vs = vsotf_numerator(otf, weighted_ncsf) / ref_vs
        sr = psf_peak(otf, n_fft, df) / ref_peak
        mtf, _ = radial_mtf(otf, n_fft, df)
        return vs, sr, mtf

    return jax.lax.map(one_eye, zernike_um, batch_size=eye_chunk)


def through_focus(
    eyes: Eyes,
    layout: Layout | None = None,
    depths_D=None,
    accommodation_D=None,
    pupil_diameter_mm: float = 3.0,
    cdp_D: float = 2.0,
    spectrum: Spectrum | None = None,
    sampling: Sampling = Sampling(),
    options: ModelOptions = ModelOptions(),
    accommodation_offsets_D=None,
    window_D: float | None = None,
    eye_chunk: int | None = None,
    check_aliasing: bool = True,
) -> ThroughFocus:
    """VSOTF, Strehl and radial MTF through focus for eyes × depths × accommodation states.

    Parameters
    ----------
    eyes : Eyes (n_eyes batch)
    layout : Layout, default open pupil (natural view)
    depths_D : (n_depth,) rendered depths, D ≥ 0; default [cdp_D]
    accommodation_D : (n_acc,) absolute accommodation states shared by all depths, D ≥ 0
        (hyperopic limit). Mutually exclusive with ``accommodation_offsets_D``.
    accommodation_offsets_D : (n_acc,) states relative to each rendered depth, D (the
        paper's through-focus); states below 0 D absolute are marked not ``allowed``.
        Default when neither is given: offsets −1 … +1 D in 0.2 D steps.
    window_D : float, D, optional
        With ``accommodation_D``: evaluate only states within ±window_D of each rendered
        depth (others are not ``allowed``), e.g. the paper's 0–5 D grid with a ±1 D window.
    pupil_diameter_mm : calculation pupil, mm (≤ eyes.measured_pupil_mm)
    cdp_D : central depth plane of the display, D
    spectrum, sampling, options : see :func:`lfjax.optics.polychromatic_otf`

    Elemental OTFs are computed once per distinct absolute state and reused by every depth.
    The VSOTF/Strehl reference follows ``options.vsotf_reference`` (default: the same layout,
    aberration-free, focused and rendered at the CDP, accommodation SA and LCA kept).
    """
    validate_pupil(pupil_diameter_mm, eyes.measured_pupil_mm)
    validate_states(None, depths_D, cdp_D)
    spectrum = make_spectrum(options=options) if spectrum is None else spectrum
    layout = open_pupil(float(pupil_diameter_mm)) if layout is None else layout
    depths = np.atleast_1d(np.asarray(cdp_D if depths_D is None else depths_D, float))
    if accommodation_D is not None and accommodation_offsets_D is not None:
        raise ValueError("give accommodation_D or accommodation_offsets_D, not both")
    if accommodation_D is not None:
        grid = np.atleast_1d(np.asarray(accommodation_D, float))
        _check_states(grid, depths)
        index = np.broadcast_to(np.arange(grid.size), (depths.size, grid.size))
        allowed = np.ones(index.shape, bool)
        if window_D is not None:
            allowed = np.abs(grid[None, :] - depths[:, None]) <= float(window_D) + 1e-9
            if not np.all(allowed.any(axis=1)):
                raise ValueError(
                    f"window_D={window_D} leaves no accommodation state for some rendered depths"
                )
    else:
        offsets = (
            np.round(np.arange(-5, 6) * 0.2, 9)
            if accommodation_offsets_D is None
            else np.atleast_1d(np.asarray(accommodation_offsets_D, float))
        )
        _check_states(np.abs(offsets), depths)  # finiteness and depth range
        grid, index = relative_accommodation_grid(depths, offsets, hyperopic_limit=True)
        allowed = index >= 0
        index = np.where(allowed, index, 0)
    # true state of every entry, also those beyond the hyperopic limit (not computed)
    if accommodation_D is not None:
        absolute = grid[index]
    else:
        absolute = np.where(allowed, grid[index], depths[:, None] + offsets[None, :])
    # Compute each absolute state once, and only the states some depth uses.
    used = np.zeros(grid.size, bool)
    used[index[allowed]] = True
    remap = np.cumsum(used) - 1
    grid = grid[used]
    index = np.where(allowed, remap[index], 0)
    validate_pupil(pupil_diameter_mm, eyes.measured_pupil_mm)
    _validate_coefficients(eyes.zernike_um)
    if check_aliasing:
        _field_check(
            eyes.zernike_um, eyes.measured_pupil_mm, pupil_diameter_mm, cdp_D, grid, depths,
            layout, spectrum, sampling, pairs=(absolute[allowed], np.broadcast_to(depths[:, None], absolute.shape)[allowed]),
        )
    reference = layout if options.vsotf_reference == "paper" else open_pupil(float(pupil_diameter_mm))
    wl = np.asarray(spectrum.wavelengths_nm)
    bands = wavelength_bands(wl, layout.window_diameter_mm, float(pupil_diameter_mm), sampling)
    ref_bands = wavelength_bands(
        wl, reference.window_diameter_mm, float(pupil_diameter_mm), sampling
    )
    n_fft = max(b[2] for b in bands)
    zernike = eyes.zernike_um
    if options.zero_piston_tilt:
        zernike = zernike.at[:, :3].set(0.0)
    real = jnp.result_type(float)
    vs, sr, mtf = _through_focus_core(
        zernike.astype(real), eyes.measured_pupil_mm, jnp.asarray(pupil_diameter_mm, real),
        jnp.asarray(cdp_D, real), jnp.asarray(grid, real), jnp.asarray(depths, real),
        jnp.asarray(index, jnp.int32),
        layout.centres_mm.astype(real), layout.diameters_mm.astype(real),
        reference.centres_mm.astype(real), reference.diameters_mm.astype(real), spectrum,
        bands, ref_bands, sampling,
        sa_parameters(options, jnp.asarray(pupil_diameter_mm, real)).astype(real), options.ncsf,
        eye_chunk,
    )
    mask = jnp.asarray(allowed)
    # NaN marks states beyond the hyperopic limit (never computed); `allowed` says which.
    vs = jnp.where(mask[None], vs, jnp.nan)
    sr = jnp.where(mask[None], sr, jnp.nan)
    freq = jnp.arange(n_fft // 2 + 1) * sampling.freq_step_cpd
    return ThroughFocus(
        vs, sr, mtf, freq, np.asarray(absolute, float), np.asarray(allowed), np.asarray(depths, float),
        float(cdp_D),
        layout.name,
    )


__all__ = ["ThroughFocus", "through_focus", "relative_accommodation_grid"]


@partial(
    jax.jit,
    static_argnames=("measured_pupil_mm", "bands", "ref_bands", "sampling", "ncsf_model"),
)
def _metrics_at_core(
    zernike_um, measured_pupil_mm, pupil_diameter_mm, cdp_D, accommodation_D, depths_D,
    centres_mm, diameters_mm, ref_centres_mm, ref_diameters_mm, spectrum, bands, ref_bands,
    sampling, sa_params, ncsf_model,
):
    df = sampling.freq_step_cpd
    n_fft = max(b[2] for b in bands)
    ref_vs, ref_peak = _reference_normalisers(
        zernike_um.shape[-1], measured_pupil_mm, pupil_diameter_mm, cdp_D, ref_centres_mm,
        ref_diameters_mm, spectrum, ref_bands, sampling, sa_params, ncsf_model,
    )
    weighted_ncsf = ncsf_half_plane(n_fft, df, ncsf_model)

    def one_depth(coefficients, depth, states):
        elemental = _elemental_otfs(
            coefficients, measured_pupil_mm, pupil_diameter_mm, cdp_D, states,
            centres_mm, diameters_mm, spectrum, bands, sampling, sa_params,
        )
        otf = _render(elemental, centres_mm, cdp_D, depth[None], n_fft, df)[0]
        return (
            vsotf_numerator(otf, weighted_ncsf) / ref_vs,
            psf_peak(otf, n_fft, df) / ref_peak,
        )

    per_eye = jax.vmap(one_depth, in_axes=(None, 0, 0))
    return jax.lax.map(lambda c: per_eye(c, depths_D, accommodation_D), zernike_um)


def metrics_at(
    eyes: Eyes,
    layout: Layout,
    depths_D,
    accommodation_D,
    pupil_diameter_mm=3.0,
    cdp_D=2.0,
    spectrum: Spectrum | None = None,
    sampling: Sampling = Sampling(),
    options: ModelOptions = ModelOptions(),
):
    """VSOTF and Strehl at given (depth, accommodation) pairs — differentiable in everything.

    Unlike :func:`through_focus` (a host-side grid with the hyperopic limit and aliasing
    checks), this is a pure function of arrays, so ``jax.grad`` flows to the eyes' Zernike
    coefficients, ``depths_D``, ``accommodation_D``, ``pupil_diameter_mm``, ``cdp_D`` and
    the layout's centres and diameters: the building block of peak finders and layout
    optimisers. Window sizes are static: they come from ``layout.window_diameter_mm`` and,
    when ``pupil_diameter_mm`` is traced, the eyes' measured pupil.

    Parameters
    ----------
    depths_D : (n_depth,) rendered depths, D
    accommodation_D : (n_depth, n_acc) absolute accommodation states for each depth, D

    Returns
    -------
    (vsotf, strehl), each (n_eyes, n_depth, n_acc).
    """
    spectrum = make_spectrum(options=options) if spectrum is None else spectrum
    concrete = not any(
        isinstance(x, jax.core.Tracer)
        for x in jax.tree_util.tree_leaves((pupil_diameter_mm, cdp_D, depths_D, accommodation_D))
    )
    validate_states(accommodation_D, depths_D, cdp_D)
    _validate_coefficients(eyes.zernike_um)
    if concrete:
        validate_pupil(pupil_diameter_mm, eyes.measured_pupil_mm)
        acc = np.asarray(accommodation_D, float)
        if acc.ndim != 2 or acc.shape[0] != np.size(depths_D):
            raise ValueError(
                f"accommodation_D must have shape (n_depth, n_acc) = ({np.size(depths_D)}, n), "
                f"got {acc.shape}"
            )
        depth = np.asarray(depths_D, float)
        _field_check(
            eyes.zernike_um, eyes.measured_pupil_mm, pupil_diameter_mm, cdp_D, acc.ravel(),
            depth, layout, spectrum, sampling,
            pairs=(acc.ravel(), np.broadcast_to(depth[:, None], acc.shape).ravel()),
        )
    pupil_static = float(pupil_diameter_mm) if concrete else float(eyes.measured_pupil_mm)
    reference = layout
    if options.vsotf_reference == "open_pupil":
        reference = Layout(
            jnp.zeros((1, 2)), jnp.reshape(jnp.asarray(pupil_diameter_mm, float), (1,)),
            pupil_static, "natural",
        )
    wl = np.asarray(spectrum.wavelengths_nm)
    bands = wavelength_bands(wl, layout.window_diameter_mm, pupil_static, sampling)
    ref_bands = wavelength_bands(wl, reference.window_diameter_mm, pupil_static, sampling)
    zernike = eyes.zernike_um
    if options.zero_piston_tilt:
        zernike = zernike.at[:, :3].set(0.0)
    real = jnp.result_type(float)
    return _metrics_at_core(
        zernike.astype(real), eyes.measured_pupil_mm, jnp.asarray(pupil_diameter_mm, real),
        jnp.asarray(cdp_D, real), jnp.asarray(accommodation_D, real),
        jnp.asarray(depths_D, real), layout.centres_mm.astype(real),
        layout.diameters_mm.astype(real), reference.centres_mm.astype(real),
        reference.diameters_mm.astype(real), spectrum, bands, ref_bands, sampling,
        sa_parameters(options, jnp.asarray(pupil_diameter_mm, real)).astype(real), options.ncsf,
    )


__all__ += ["metrics_at"]
