"""Retinal images: a scene in visual angle convolved with the eye's PSF (Miyanishi et al. Fig. 9).

A scene is a 2-D luminance array ``[y, x]`` sampled at ``pixel_arcmin`` (arcmin per pixel,
the same in x and y), in lfjax's orientation: x right, y up, so the row index grows upwards
(show it with ``imshow(..., origin="lower")``), as for the PSFs of :mod:`lfjax.kernel.optics`.
The retinal image is the scene convolved with the point-spread function; here this is done
by multiplying the scene's spectrum by the OTF on the scene's own frequency grid.

The OTFs of :mod:`lfjax.kernel.optics` live on another grid: frequency step ``df`` (cpd), so the
PSF is periodic with period (field) 60/df arcmin and sampled at 60/(df·L) arcmin. The
resampling onto the scene grid is exact for that band-limited PSF: each scene pixel's
kernel weight is the integral of the PSF over the pixel, evaluated from the OTF as a
trigonometric sum (OTF × pixel-aperture sinc, summed at the pixel centres). So the scene
pixel may be finer or coarser than the PSF pixel; nothing is interpolated.

Everything here is ``jax.numpy``: differentiable in the scene, the OTF and (for
:func:`snellen_e`) the letter size.
"""

from __future__ import annotations

import math
from functools import partial

import jax
import jax.numpy as jnp

from lfjax.base.types import FULL
from lfjax.kernel.optics import full_plane

ORIENTATIONS = ("right", "up", "left", "down")
"""Directions the Snellen E can open towards."""

BOUNDARIES = ("edge", "periodic", "constant")


# ----------------------------------------------------------------------------- optotype


def _interval_overlap(lo, hi, edges_lo, edges_hi):
    """Length of [lo, hi] ∩ [edges_lo, edges_hi] (elementwise, differentiable)."""
    return jnp.clip(jnp.minimum(hi, edges_hi) - jnp.maximum(lo, edges_lo), 0.0, None)


def snellen_e(
    letter_arcmin: float,
    pixel_arcmin: float,
    n_pixels: int | None = None,
    orientation: str = "right",
    contrast: float = 1.0,
    background: float = 1.0,
):
    """A tumbling Snellen E, anti-aliased by exact pixel coverage.

    The letter is a 5 × 5 grid of strokes (stroke width = letter/5; the 20/20 letter is
    5 arcmin tall), drawn dark on a bright background and centred on the array centre
    (between pixels ``n//2 − 1`` and ``n//2`` for even ``n``).

    Parameters
    ----------
    letter_arcmin : float, arcmin
        Letter height (and width), > 0. May be a traced value (differentiable).
    pixel_arcmin : float, arcmin
        Pixel size, > 0.
    n_pixels : int, optional
        Image size (square). Default: twice the letter, rounded up to an even number.
    orientation : {"right", "up", "left", "down"}
        Direction of the opening (the standard letter E opens to the right).
    contrast : float
        Weber contrast of the letter, 0 < contrast ≤ 1 (1: black letter).
    background : float
        Background luminance (> 0, arbitrary units).

    Returns
    -------
    (n_pixels, n_pixels) array ``[y, x]``: ``background·(1 − contrast·coverage)``.
    """
    if orientation not in ORIENTATIONS:
        raise ValueError(f"orientation must be one of {ORIENTATIONS}, got {orientation!r}")
    pixel = _positive_scalar(pixel_arcmin, "pixel_arcmin")
    if not _is_traced(letter_arcmin):
        letter_value = _positive_scalar(letter_arcmin, "letter_arcmin")
    else:
        letter_value = None
    if not (0.0 < float(contrast) <= 1.0):
        raise ValueError(f"contrast must be in (0, 1], got {contrast}")
    if not (float(background) > 0 and math.isfinite(float(background))):
        raise ValueError(f"background must be > 0, got {background}")
    if n_pixels is None:
        if letter_value is None:
            raise ValueError("give n_pixels when letter_arcmin is traced")
        n_pixels = int(math.ceil(2.0 * letter_value / pixel))
        n_pixels += n_pixels % 2
    if int(n_pixels) != n_pixels or n_pixels < 2:
        raise ValueError(f"n_pixels must be an integer >= 2, got {n_pixels}")
    n = int(n_pixels)
    if letter_value is not None and letter_value > n * pixel:
        raise ValueError(
            f"a {letter_value:g} arcmin letter does not fit in {n} pixels of {pixel:g} arcmin "
            f"(field {n * pixel:g} arcmin); increase n_pixels"
        )
    size = jnp.asarray(letter_arcmin, float)
    stroke = size / 5.0
    # pixel edges in arcmin, origin at the array centre
    lo = (jnp.arange(n) - n / 2.0) * pixel
    hi = lo + pixel
    # the E opening right in stroke units (u right, v up), origin at its lower-left corner:
    # the spine (column 0) and the three bars (rows 0, 2, 4), as disjoint rectangles
    rects = [
        (0.0, 1.0, 0.0, 5.0),
        (1.0, 5.0, 0.0, 1.0),
        (1.0, 5.0, 2.0, 3.0),
        (1.0, 5.0, 4.0, 5.0),
    ]
    coverage = jnp.zeros((n, n))
    for u0, u1, v0, v1 in rects:
        x0, x1 = (u0 - 2.5) * stroke, (u1 - 2.5) * stroke
        y0, y1 = (v0 - 2.5) * stroke, (v1 - 2.5) * stroke
        ox = _interval_overlap(x0, x1, lo, hi) / pixel
        oy = _interval_overlap(y0, y1, lo, hi) / pixel
        coverage = coverage + oy[:, None] * ox[None, :]
    # quarter turns counter-clockwise in the y-up frame (rows increase upwards)
    coverage = jnp.rot90(coverage, k=-ORIENTATIONS.index(orientation))
    return float(background) * (1.0 - float(contrast) * coverage)


# ----------------------------------------------------------------------------- retinal image


def _is_traced(x) -> bool:
    return any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(x))


def _positive_scalar(x, name: str) -> float:
    try:
        value = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {x!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise ValueError(f"{name} must be > 0 and finite, got {x!r}")
    return value


def _otf_from_psf(psf, psf_pixel_arcmin: float):
    """Half-plane OTF (OTF(0) = 1) and its frequency step (cpd) of a centred PSF image."""
    n = psf.shape[-1]
    total = jnp.sum(psf, axis=(-2, -1), keepdims=True)
    centred = jnp.fft.ifftshift(psf / total, axes=(-2, -1))
    return jnp.fft.rfft2(centred), 60.0 / (psf_pixel_arcmin * n), n


def psf_on_grid(otf_half, freq_step_cpd: float, pixel_arcmin: float, n_pixels: int,
                n_fft: int | None = None):
    """Pixel-integrated PSF on an ``n_pixels`` square grid of ``pixel_arcmin`` (sums to ≈ 1).

    Zero angle is at index ``n_pixels // 2``. The value of pixel m is the integral of the
    band-limited PSF over that pixel, computed exactly from the OTF:
    ``Σ_f OTF(f) sinc(f_x p) sinc(f_y p) exp(2πi f·θ_m) (df/60)² p²`` with f in cycles per
    arcmin. Pixels farther than half the PSF field (30/df arcmin) from the centre are zero
    (the model's PSF is periodic with that period).

    Parameters
    ----------
    otf_half : complex (…, L, L//2+1) half-plane OTF (``rfft2`` layout, FFT order), OTF(0)=1
    freq_step_cpd : float, cpd
    pixel_arcmin : float, arcmin
    n_pixels : int
    n_fft : int, optional; L (default: ``otf_half.shape[-2]``)
    """
    otf_half = jnp.asarray(otf_half)
    L = int(otf_half.shape[-2]) if n_fft is None else int(n_fft)
    if otf_half.ndim < 2 or otf_half.shape[-2] != L or otf_half.shape[-1] != L // 2 + 1:
        raise ValueError(
            f"otf_half must have shape (..., L, L//2+1) in rfft2 layout, got {otf_half.shape}"
        )
    df = _positive_scalar(freq_step_cpd, "freq_step_cpd")
    p = _positive_scalar(pixel_arcmin, "pixel_arcmin")
    if int(n_pixels) != n_pixels or n_pixels < 2:
        raise ValueError(f"n_pixels must be an integer >= 2, got {n_pixels}")
    return _psf_on_grid(otf_half, df, p, int(n_pixels), L)


@partial(jax.jit, static_argnames=("n", "L"))
def _psf_on_grid(otf_half, df, p, n: int, L: int):
    otf = full_plane(otf_half, L)  # (…, L, L) FFT order
    f = jnp.fft.fftfreq(L, 1.0 / L) * df / 60.0  # cycles per arcmin (FFT order)
    aperture = jnp.sinc(f * p)  # pixel box integration (sinc(x) = sin(πx)/(πx))
    theta = (jnp.arange(n) - n // 2) * p
    kernel = jnp.exp(2j * jnp.pi * theta[:, None] * f[None, :]) * aperture[None, :]  # (n, L)
    psf = jnp.einsum("ik,...kl,jl->...ij", kernel, otf, kernel, precision=FULL)
    psf = jnp.real(psf) * (df / 60.0) ** 2 * p * p
    inside = jnp.abs(theta) <= 30.0 / df  # one period of the model's periodic PSF
    return psf * (inside[:, None] & inside[None, :])


def retinal_image(
    scene,
    pixel_arcmin: float,
    otf_half=None,
    freq_step_cpd: float | None = None,
    *,
    psf=None,
    psf_pixel_arcmin: float | None = None,
    boundary: str = "edge",
    constant: float = 0.0,
):
    """Retinal image of a scene: the scene convolved with the PSF (multiplied by the OTF).

    Give the optics either as a half-plane OTF (as :func:`lfjax.polychromatic_otf` returns,
    ``otf_half`` with ``freq_step_cpd``) or as a centred PSF image (``psf`` sampled at
    ``psf_pixel_arcmin``, zero angle at index L//2, any normalisation: it is scaled to unit
    sum). Both are resampled onto the scene grid exactly (see :func:`psf_on_grid`), so the
    scene's ``pixel_arcmin`` need not match the PSF sampling.

    Parameters
    ----------
    scene : (H, W) or (…, H, W) real array ``[y, x]``, luminance (any unit)
    pixel_arcmin : float, arcmin per scene pixel
    otf_half : complex (L, L//2+1) or broadcastable (…, L, L//2+1); OTF(0) = 1
    freq_step_cpd : float, cpd, the OTF's frequency step
    psf, psf_pixel_arcmin : alternative to ``otf_half``: square PSF image and its pixel
    boundary : {"edge", "periodic", "constant"}
        How the scene continues beyond its border while blurring: repeat the border pixels
        (default), wrap around, or take the value ``constant``.

    Returns
    -------
    Array of the scene's shape (batched like ``scene`` and ``otf_half``): the retinal
    image in the scene's luminance unit (the PSF integrates to OTF(0) = 1).
    """
    if (otf_half is None) == (psf is None):
        raise ValueError("give exactly one of otf_half (with freq_step_cpd) or psf "
                         "(with psf_pixel_arcmin)")
    if boundary not in BOUNDARIES:
        raise ValueError(f"boundary must be one of {BOUNDARIES}, got {boundary!r}")
    scene = jnp.asarray(scene)
    if scene.ndim < 2 or scene.shape[-1] < 2 or scene.shape[-2] < 2:
        raise ValueError(f"scene must be a 2-D image (…, H, W) with H, W >= 2, got {scene.shape}")
    if jnp.iscomplexobj(scene):
        raise ValueError("scene must be real (luminance)")
    if not _is_traced(scene) and not bool(jnp.all(jnp.isfinite(scene))):
        raise ValueError("scene contains non-finite values (NaN or inf)")
    p = _positive_scalar(pixel_arcmin, "pixel_arcmin")
    if psf is not None:
        psf = jnp.asarray(psf)
        if psf.ndim < 2 or psf.shape[-1] != psf.shape[-2] or psf.shape[-1] < 2:
            raise ValueError(f"psf must be a square image (…, L, L), got {psf.shape}")
        if psf_pixel_arcmin is None:
            raise ValueError("psf_pixel_arcmin is required with psf")
        q = _positive_scalar(psf_pixel_arcmin, "psf_pixel_arcmin")
        if not _is_traced(psf) and not bool(jnp.all(jnp.sum(psf, axis=(-2, -1)) > 0)):
            raise ValueError("psf must have a positive sum")
        otf_half, freq_step_cpd, n_fft = _otf_from_psf(psf, q)
    else:
        if freq_step_cpd is None:
            raise ValueError("freq_step_cpd is required with otf_half")
        otf_half = jnp.asarray(otf_half)
        n_fft = int(otf_half.shape[-2]) if otf_half.ndim >= 2 else 0
        if otf_half.ndim < 2 or otf_half.shape[-1] != n_fft // 2 + 1:
            raise ValueError(
                f"otf_half must have shape (..., L, L//2+1) in rfft2 layout, got {otf_half.shape}"
            )
    df = _positive_scalar(freq_step_cpd, "freq_step_cpd")
    H, W = int(scene.shape[-2]), int(scene.shape[-1])
    # Kernel extent: the PSF field (60/df arcmin), at most what the scene can see.
    field_px = int(math.ceil(60.0 / df / p))
    half = min(field_px // 2 + 1, max(H, W))
    return _convolve(scene, otf_half, float(df), float(p), int(n_fft), half, boundary,
                     float(constant))


@partial(jax.jit, static_argnames=("L", "half", "boundary"))
def _convolve(scene, otf_half, df, p, L, half, boundary, constant):
    H, W = scene.shape[-2], scene.shape[-1]
    n_kernel = 2 * half + 1
    kernel = _psf_on_grid(otf_half, df, p, n_kernel, L)  # (…, n_kernel, n_kernel)
    # pad the scene so the circular convolution does not wrap (unless periodic)
    pad = 0 if boundary == "periodic" else half
    if pad:
        widths = [(0, 0)] * (scene.ndim - 2) + [(pad, pad), (pad, pad)]
        if boundary == "edge":
            padded = jnp.pad(scene, widths, mode="edge")
        else:
            padded = jnp.pad(scene, widths, mode="constant", constant_values=constant)
    else:
        padded = scene
    big_h, big_w = padded.shape[-2], padded.shape[-1]
    # kernel centre at index (0, 0); a periodic scene smaller than the kernel wraps it
    ky = (jnp.arange(n_kernel) - half) % big_h
    kx = (jnp.arange(n_kernel) - half) % big_w
    placed = jnp.zeros(kernel.shape[:-2] + (big_h, big_w), kernel.dtype)
    placed = placed.at[..., ky[:, None], kx[None, :]].add(kernel)
    spectrum = jnp.fft.rfft2(padded) * jnp.fft.rfft2(placed)
    image = jnp.fft.irfft2(spectrum, s=(big_h, big_w))
    return image[..., pad : pad + H, pad : pad + W]


__all__ = ["ORIENTATIONS", "snellen_e", "psf_on_grid", "retinal_image"]

