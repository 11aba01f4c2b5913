"""Through-focus by orientation: which structure (vertical or horizontal) drives the peak.

A horizontal-parallax-only display renders depth along x only, so vertical structure
(modulated along x, frequencies on the f_x axis) and horizontal structure (modulated along
y, frequencies on the f_y axis) may peak at different accommodations. The VSOTF is split
by two orientation windows that sum to one on the frequency plane,

    w_x(f) = cos²φ,  w_y(f) = sin²φ,  φ the angle of (f_x, f_y) from the f_x axis,

(w = ½ each at f = 0): VSOTF_b = Σ NCSF·w_b·Re OTF / Σ NCSF·w_b·Re OTF_ref, against the
pipeline's reference (:func:`lfjax.kernel.pipeline.reference_otf`). The NCSF numerators of
the two bands add to the whole VSOTF's, so the whole is their NCSF-weighted mean; its
oblique effect (the NCSF is lower on the diagonals) is kept inside each band. The MTF along
each axis (|OTF| on f_y = 0 and on f_x = 0) gives each orientation's cut-off.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.kernel.metrics import cutoff_frequency, half_plane_frequencies, ncsf_half_plane, vsotf_numerator
from lfjax.kernel.pipeline import eye_coefficients, reference_otf, rendered_otfs
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout
from lfjax.model.options import ModelOptions
from lfjax.vision.prepare import States, prepare
from lfjax.vision.viewing import Viewing

BANDS = ("whole", "x", "y")
"""The VSOTF bands: the whole plane, vertical structure (f_x axis, cos²φ), horizontal
structure (f_y axis, sin²φ)."""


def orientation_windows(n_fft: int, freq_step_cpd: float):
    """(w_x, w_y) on the half plane (L, L//2+1): cos²φ and sin²φ of the frequency's angle
    from the f_x axis, ½ each at f = 0; they sum to one everywhere."""
    fx, fy = half_plane_frequencies(n_fft, freq_step_cpd)
    f2 = fx * fx + fy * fy
    safe = jnp.where(f2 > 0, f2, 1.0)
    wx = jnp.where(f2 > 0, fx * fx / safe, 0.5)
    return wx, 1.0 - wx


class OrientationFocus(eqx.Module):
    """Through-focus by orientation band.

    Attributes
    ----------
    vsotf : (3, n_eyes, n_depth, n_acc) VSOTF of the bands :data:`BANDS` (whole, x, y)
    mtf_x, mtf_y : (n_eyes, n_depth, n_acc, n_freq) |OTF| along the f_x axis (vertical
        structure) and the f_y axis (horizontal structure)
    freq_cpd : (n_freq,) cpd
    accommodation_D : (n_acc,) the shared absolute accommodation grid, D
    depths_D : (n_depth,) rendered depths, D
    """

    vsotf: jnp.ndarray
    mtf_x: jnp.ndarray
    mtf_y: jnp.ndarray
    freq_cpd: np.ndarray
    accommodation_D: np.ndarray
    depths_D: np.ndarray

    def peak_D(self, band: str = "whole") -> np.ndarray:
        """Predicted accommodation of a band, (n_eyes, n_depth) D: the grid maximum refined
        by the parabola through it and its neighbours (the grid's value at its ends)."""
        v = np.asarray(self.vsotf[BANDS.index(band)], float)
        acc = np.asarray(self.accommodation_D, float)
        i = np.argmax(v, axis=-1)
        inner = np.clip(i, 1, acc.size - 2)
        y0, y1, y2 = (np.take_along_axis(v, (inner + k)[..., None], -1)[..., 0] for k in (-1, 0, 1))
        curvature = y0 - 2 * y1 + y2
        step = acc[1] - acc[0] if acc.size > 1 else 0.0
        offset = np.where(curvature < 0, 0.5 * (y0 - y2) / np.where(curvature < 0, curvature, -1), 0.0)
        refined = acc[inner] + np.clip(offset, -0.5, 0.5) * step
        at_end = (i == 0) | (i == acc.size - 1)
        return np.where(at_end, acc[i], refined)

    def peak_index(self, band: str = "whole") -> np.ndarray:
        return np.argmax(np.asarray(self.vsotf[BANDS.index(band)]), axis=-1)

    def value_at_peak(self, band: str = "whole", at: str | None = None) -> np.ndarray:
        """VSOTF of ``band`` at the grid peak of band ``at`` (default the same), (n_eyes, n_depth)."""
        i = self.peak_index(band if at is None else at)
        return np.take_along_axis(np.asarray(self.vsotf[BANDS.index(band)]), i[..., None], -1)[..., 0]

    def cutoff_cpd(self, axis: str, at: str = "whole", threshold: float = 0.05) -> np.ndarray:
        """Cut-off (cpd) of the MTF along ``axis`` ("x" or "y") at the grid peak of band
        ``at``, where it first falls to ``threshold``, (n_eyes, n_depth)."""
        mtf = np.asarray(self.mtf_x if axis == "x" else self.mtf_y)
        i = self.peak_index(at)
        at_peak = np.take_along_axis(mtf, i[..., None, None], 2)[:, :, 0]
        return np.asarray(cutoff_frequency(jnp.asarray(at_peak), jnp.asarray(self.freq_cpd), threshold))


@eqx.filter_jit
def _band_metrics(eyes, scene, spectrum, accommodation, config):
    n_fft, df = config.n_fft, config.freq_step_cpd
    ref = reference_otf(scene, spectrum, accommodation, config)
    ref_n = ref.shape[-2]
    ref_ncsf = ncsf_half_plane(ref_n, df, config.ncsf)
    ref_wx, ref_wy = orientation_windows(ref_n, df)
    ncsf = ncsf_half_plane(n_fft, df, config.ncsf)
    wx, wy = orientation_windows(n_fft, df)
    weights = jnp.stack([ncsf, ncsf * wx, ncsf * wy])  # (3, L, L//2+1)
    den = jnp.stack([vsotf_numerator(ref, ref_ncsf), vsotf_numerator(ref, ref_ncsf * ref_wx),
                     vsotf_numerator(ref, ref_ncsf * ref_wy)])
    n_half = n_fft // 2 + 1

    def one_eye(zernike_um):
        otf = rendered_otfs(zernike_um, eyes.measured_pupil_mm, scene, spectrum, accommodation,
                            config.bands, config.sampling)
        num = jnp.stack([vsotf_numerator(otf, w) for w in weights])
        return num / den[:, None, None], jnp.abs(otf[..., 0, :n_half]), jnp.abs(otf[..., :n_half, 0])

    return jax.lax.map(one_eye, eye_coefficients(eyes, config), batch_size=config.eye_chunk)


def orientation_through_focus(eyes: Eyes, layout: Layout | None, states: States,
                              viewing: Viewing = Viewing(),  # noqa: B008 - frozen, checked
                              *, spectrum=None, sampling=None,
                              options: ModelOptions = ModelOptions(),
                              eye_chunk: int | None = None) -> OrientationFocus:
    """VSOTF of the whole plane and of each orientation band, and the MTF along each axis,
    for ``eyes`` × the ``states``' depths × their one absolute grid (a
    :meth:`~lfjax.vision.prepare.States.grid` without a window: every state for every
    depth); the other arguments as :func:`lfjax.vision.focus.through_focus`'s (the
    ``viewing``'s display: e.g. a strip display,
    :func:`lfjax.display.lenticular.strip_display`). Inputs are checked before any work."""
    if not isinstance(states, States) or states.kind != "grid" or not np.all(states.allowed):
        raise ParameterError("states", "{states} must be lfjax.States.grid(accommodation_D, "
                             "depths_D) without a window (every state for every depth)")
    prepared = prepare(eyes, layout, states, viewing, spectrum=spectrum, options=options,
                       sampling=sampling, eye_chunk=eye_chunk)
    vsotf, mtf_x, mtf_y = _band_metrics(eyes, prepared.scene, prepared.spectrum,
                                        prepared.accommodation(options), prepared.config)
    n_half = prepared.config.n_fft // 2 + 1
    return OrientationFocus(
        jnp.moveaxis(vsotf, 1, 0), mtf_x, mtf_y,
        np.arange(n_half) * prepared.config.freq_step_cpd,
        np.asarray(states.states_D, float)[states.index[0]], np.asarray(states.depths_D, float))


__all__ = ["BANDS", "orientation_windows", "OrientationFocus", "orientation_through_focus"]
