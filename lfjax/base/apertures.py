"""Apertures in the pupil plane: the shapes a view can have, soft edges, Fresnel propagation.

:data:`APERTURES` declares every subaperture shape once (:class:`ApertureShape`): a disc, a
square, and the strip of a lenticular view, which spans the pupil's height; what a caller
needs to know of a shape (what its size measures, whether it spans the pupil's height, its
numerical window along x) is read from there, not decided again by name.

Every aperture is anti-aliased (docs/design.md#conventions): a sample on the edge is weighted
by a logistic of its signed distance (mm) inside the edge, whose scale is a fraction of a
pupil sample, so results vary smoothly and differentiably with centres and diameters. The
lenslet diffraction of a real display (:mod:`lfjax.display.lenslets`) is the Fresnel propagation of
such an aperture; both the elemental optics kernel (:mod:`lfjax.kernel.optics`) and the single-PSF
entry point (:mod:`lfjax.vision.psf`) build their pupils from these functions. Pure ``jax.numpy``
on arrays; nothing here knows about eyes, scenes or displays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from lfjax.base.sampling import next_fast_size


@dataclass(frozen=True)
class ApertureShape:
    """One subaperture shape, with what the pipeline, the plots and the displays read of it.

    Attributes
    ----------
    name : the value of ``aperture=`` that selects it (``DisplayOptics``, ``LensletArray``)
    size : what a layout's ``diameters_mm`` (mm) measures for it: ``"diameter"``,
        ``"side"`` or ``"width along x"``
    spans_pupil_height : the view is bounded along x only and the pupil crops it to its
        chord (a lenticular view: its cylindrical lenslet has no power along y, so no edge
        limits the beam there, and lenslet diffraction acts along x only)
    """

    name: str
    size: str
    spans_pupil_height: bool = False

    def window_x_mm(self, widest_mm: float, pupil_diameter_mm: float) -> float | None:
        """Width (mm) of the views' numerical window along x where it is narrower than
        along y, or None (a square window). A shape spanning the pupil's height is as wide
        as its widest view (``widest_mm``, mm; at most the pupil, ``pupil_diameter_mm``)
        and as tall as the pupil; a bounded shape's window is square."""
        if not self.spans_pupil_height:
            return None
        return min(float(widest_mm), float(pupil_diameter_mm))


CIRCLE = ApertureShape("circle", "diameter")
SQUARE = ApertureShape("square", "side")
STRIP = ApertureShape("strip", "width along x", spans_pupil_height=True)
APERTURES = {shape.name: shape for shape in (CIRCLE, SQUARE, STRIP)}
"""Every subaperture shape by name: ``"circle"`` (diameter), ``"square"`` (side, axis
aligned) and ``"strip"`` (width along x, spanning the pupil's height: a lenticular view)."""


def aperture_shape(name: str) -> ApertureShape:
    """The declared :class:`ApertureShape` called ``name`` (one of :data:`APERTURES`);
    ``ValueError`` naming the allowed ones otherwise."""
    try:
        return APERTURES[name]
    except (KeyError, TypeError):
        raise ValueError(f"aperture={name!r}; allowed: {', '.join(APERTURES)}") from None


def safe_sqrt(x):
    """sqrt with a finite (zero) gradient at 0 (double-where)."""
    positive = x > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, x, 1.0)), 0.0)


def disk_edge_distance(r2_mm2, radius_mm, edge_scale_mm):
    """Signed distance (mm) inside the edge of a disc whose logistic edge keeps its area.

    ``sigmoid(distance / s)`` integrates to π(R'² + π²s²/3); the shifted radius R' makes the
    covered area exactly π·radius², so results are continuous and differentiable in centre
    and diameter with no area bias.
    """
    r = safe_sqrt(r2_mm2)
    return safe_sqrt(radius_mm**2 - (math.pi**2 / 3.0) * edge_scale_mm**2) - r


def soft_disk(r2_mm2, radius_mm, edge_scale_mm):
    """Anti-aliased disc amplitude transmission: logistic edge of scale ``edge_scale_mm``."""
    return jax.nn.sigmoid(disk_edge_distance(r2_mm2, radius_mm, edge_scale_mm) / edge_scale_mm)


def aperture_edge_distance(dx_mm, dy_mm, size_mm, edge_scale_mm, shape: str):
    """Signed distance (mm) inside a subaperture's edge at offsets (dx, dy) from its centre.

    Circle: the area-exact shifted radius of :func:`disk_edge_distance`.
    Square (side ``size_mm``): the distance to the nearer side (a logistic straight edge
    keeps the area exactly; the four corners are off by O(edge²)).
    Strip (width ``size_mm`` along x, unbounded along y: a lenticular view, which the pupil
    crops to its chord): the distance to the nearer vertical side.
    ``shape``: a name of :data:`APERTURES`.
    """
    if aperture_shape(shape).spans_pupil_height:
        return 0.5 * size_mm - jnp.abs(dx_mm)
    if shape == SQUARE.name:
        half = 0.5 * size_mm
        return jnp.minimum(half - jnp.abs(dx_mm), half - jnp.abs(dy_mm))
    return disk_edge_distance(dx_mm * dx_mm + dy_mm * dy_mm, 0.5 * size_mm, edge_scale_mm)


def fresnel_transfer_1d(n: int, dx_mm, wavelength_mm, distance_mm, extent_mm=None):
    """One axis of the Fresnel propagator's transfer function on a grid padded to
    ``next_fast_size(2n)`` samples (FFT order), for a field of n samples of ``dx_mm`` (mm).

    The field lives in a region of width E = ``extent_mm`` (default n·dx; the pipeline
    passes the pupil) and is wanted only there, so only the impulse response
    h(x) = exp(iπx²/(λz))/√(iλz) for |x| < E matters: a linear convolution, exact on a grid
    padded to ≥ 2n. Two samplings of that kernel:

    * far (λz ≥ 2E·dx): h itself is resolved (its local frequency x/(λz) < 1/(2dx) on the
      whole |x| < E), so the transfer function is dx·DFT(h) of its samples — no truncation
      ripple, which a hard band limit of the analytic chirp leaves (≈ 0.07 of the on-axis
      field at Fresnel number 0.5);
    * near (λz < 2E·dx): the analytic exp(−iπλz f²) is resolved on the padded grid
      (λz ≤ n_pad·dx²), and h reaches no farther than λz/(2dx) < E, so nothing wraps.

    Neither depends on n beyond n·dx ≥ E, so windows of different sizes give one answer.

    Both branches are evaluated and one is selected (``jnp.where``) so ``distance_mm``
    stays differentiable and traceable. Returns complex (n_pad,).
    """
    n_pad = next_fast_size(2 * n)
    real = jnp.result_type(float)
    lam_z = wavelength_mm * distance_mm
    f = jnp.asarray(np.fft.fftfreq(n_pad), real) / dx_mm  # cycles/mm
    near = jnp.exp(-1j * jnp.pi * lam_z * f * f)
    k = np.fft.fftfreq(n_pad, 1.0 / n_pad)  # sample offsets, FFT order
    x = jnp.asarray(k, real) * dx_mm
    extent = n * dx_mm if extent_mm is None else extent_mm
    inside = jnp.abs(x) < extent
    # √(iλz) on the principal branch: exp(iπ/4)·√(λz)
    h = jnp.where(inside, jnp.exp(1j * jnp.pi * x * x / lam_z), 0.0) * (
        jnp.exp(-0.25j * jnp.pi) / jnp.sqrt(lam_z))
    far = jnp.fft.fft(h) * dx_mm
    return jnp.where(lam_z >= 2.0 * extent * dx_mm, far, near)


def fresnel_propagate(field, dx_mm, wavelength_mm, distance_mm, extent_mm=None,
                      along_y: bool = True):
    """Fresnel propagation of a sampled field (…, n, n) over ``distance_mm`` (mm).

    A linear convolution with the Fresnel impulse response, computed by FFT on a grid padded
    to ≥ 2n with the separable transfer function of :func:`fresnel_transfer_1d` (exact in
    the window for a field that is zero outside it). Normalised so that z → 0 returns the
    field (the constant phase exp(ikz) dropped). ``extent_mm``: the width of the region
    (mm, ≤ n·dx) holding the field and where it is wanted. ``along_y=False`` propagates
    along x only (a cylindrical lenslet diffracts across its axis only). Returns complex
    (…, n, n).
    """
    n = field.shape[-1]
    transfer = fresnel_transfer_1d(n, dx_mm, wavelength_mm, distance_mm, extent_mm)
    n_pad = transfer.shape[0]
    pad = [(0, 0)] * (field.ndim - 2) + [(0, n_pad - n), (0, n_pad - n)]
    if not along_y:
        pad_x = [(0, 0)] * (field.ndim - 1) + [(0, n_pad - n)]
        out = jnp.fft.ifft(jnp.fft.fft(jnp.pad(field, pad_x), axis=-1) * transfer, axis=-1)
        return out[..., :n]
    spectrum = jnp.fft.fft2(jnp.pad(field, pad))
    out = jnp.fft.ifft2(spectrum * transfer[:, None] * transfer[None, :])
    return out[..., :n, :n]


__all__ = [
    "ApertureShape",
    "APERTURES",
    "CIRCLE",
    "SQUARE",
    "STRIP",
    "aperture_shape",
    "safe_sqrt",
    "disk_edge_distance",
    "soft_disk",
    "aperture_edge_distance",
    "fresnel_transfer_1d",
    "fresnel_propagate",
]
