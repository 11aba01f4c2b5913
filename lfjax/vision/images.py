"""Retinal images: a scene in visual angle convolved with the eye's PSF (Miyanishi et al. Fig. 9).

A scene is a 2-D luminance array ``[y, x]`` sampled at ``pixel_arcmin`` (arcmin per pixel,
the same in x and y), in lfjax's orientation: x right, y up, so the row index grows upwards
(show it with ``imshow(..., origin="lower")``), as for the PSFs of :mod:`lfjax.kernel.optics`.
The retinal image is the scene convolved with the point-spread function; here this is done
by multiplying the scene's spectrum by the OTF on the scene's own frequency grid.

The OTFs of :mod:`lfjax.kernel.optics` live on another grid: frequency step ``df`` (cpd), so the
PSF is the band-limited function with those Fourier coefficients, periodic with period
(field) ``T = 60/df`` arcmin; the model's PSF is one period of it, ``[-T/2, T/2]²``, and zero
outside. The resampling onto the scene grid is exact for that PSF at any pixel size: each
scene pixel's kernel weight is the integral of the PSF over the part of the pixel inside
the field, evaluated from the OTF as a trigonometric sum (:func:`psf_on_grid`), and the
kernel spans the whole field. Pixels finer than the PSF's samples (``T/L``) see the PSF
between its samples as its band limit defines it; pixels coarser than the field hold the
whole PSF in one pixel (the retinal image is the scene). The weights sum to OTF(0) = 1, so a
uniform scene stays uniform at its luminance and the light of any scene is conserved,
within float32 rounding (about 1e-6 relative); tests/vision/test_images.py checks it from
0.01 to 1000 arcmin and against a direct float64 convolution.

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


def kernel_half_width(freq_step_cpd: float, pixel_arcmin: float) -> int:
    """Half width (pixels) of the scene-grid kernel that tiles the PSF's whole field.

    The model's PSF is one period ``T = 60/freq_step_cpd`` arcmin wide; pixels ``-h … h``
    of ``pixel_arcmin`` cover ``[-T/2, T/2]`` when ``(h + ½)·pixel ≥ T/2``. One pixel
    more is kept so rounding never leaves a sliver of the field uncovered (its weight is
    the PSF over an empty overlap: zero)."""
    period = 60.0 / _positive_scalar(freq_step_cpd, "freq_step_cpd")
    return int(math.floor(period / (2.0 * _positive_scalar(pixel_arcmin, "pixel_arcmin"))
                          + 0.5)) + 1


def psf_on_grid(otf_half, freq_step_cpd: float, pixel_arcmin: float, n_pixels: int,
                n_fft: int | None = None):
    """Pixel-integrated PSF on an ``n_pixels`` square grid of ``pixel_arcmin`` (sums to 1 on a
    grid that covers the PSF's field).

    Zero angle is at index ``n_pixels // 2``. The PSF is the model's: the band-limited
    function whose Fourier coefficients are the OTF samples (period ``T = 60/df`` arcmin),
    taken over one period ``[-T/2, T/2]²`` and zero outside it (the field the optics were
    computed for). The value of pixel m is the integral of that PSF over the part of the
    pixel inside the field, computed exactly from the OTF as a trigonometric sum: with
    ``[a, b]`` the pixel's overlap with ``[-T/2, T/2]`` along each axis, width ``w = b − a``
    and centre ``c``, ``Σ_f OTF(f) w sinc(f w) exp(2πi f c)`` per axis, over ``T²``, f in
    cycles per arcmin. Pixels that tile the field sum to OTF(0) = 1 at any pixel size
    (larger than the field: the centre pixel holds the whole PSF, weight 1); a grid smaller
    than the field keeps only its part of the PSF.

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
    order = jnp.fft.fftfreq(L, 1.0 / L)  # harmonic k: f = k/T, T = 60/df arcmin the field
    u = p * df / 60.0  # the pixel, in periods
    m = jnp.arange(n) - n // 2.0
    # the pixel's overlap with the field [-½, ½] (periods): interior pixels are exactly u
    # wide (not a difference of two far-off edges, which loses digits in float32)
    over_hi = jnp.maximum((m + 0.5) * u - 0.5, 0.0)
    over_lo = jnp.maximum(-0.5 - (m - 0.5) * u, 0.0)
    width = jnp.maximum(u - over_hi - over_lo, 0.0)
    centre = m * u + 0.5 * (over_lo - over_hi)
    cycles = order[None, :] * centre[:, None]
    cycles = cycles - jnp.round(cycles)  # the phase k·c reduced to [-½, ½) cycles
    # (n, L): ∫ over pixel m's part of the field of e^{2πikθ/T} dθ / T
    kernel = width[:, None] * jnp.sinc(order[None, :] * width[:, None]) * jnp.exp(
        2j * jnp.pi * cycles)
    # Pixels that tile the field integrate every harmonic but k = 0 over whole periods: their
    # sums are exactly 0 (and 1 for k = 0). The float32 residue of those sums is spread over
    # the pixels in proportion to their overlap and removed, so the kernel sums to OTF(0).
    covers = (n // 2 + 0.5) * u >= 0.5
    total = jnp.sum(width)
    residue = jnp.sum(kernel, axis=0) - (order == 0) * total
    kernel = jnp.where(covers, kernel - width[:, None] * residue[None, :] / total, kernel)
    psf = jnp.einsum("ik,...kl,jl->...ij", kernel, otf, kernel, precision=FULL)
    return jnp.real(psf)


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
    sum). Both are resampled onto the scene grid exactly (module docstring,
    :func:`psf_on_grid`), so the scene's ``pixel_arcmin`` need not match the PSF sampling.
    The scene is padded by the kernel's half width (:func:`kernel_half_width`: half the
    PSF's field in scene pixels) for the "edge" and "constant" boundaries: memory grows as
    ``(H + 60/(df·pixel_arcmin))·(W + …)`` for pixels much finer than the field.

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
    # The kernel tiles the PSF's whole field, however small the scene: light from beyond
    # the scene's border (its edge or constant continuation) reaches it.
    half = kernel_half_width(df, p)
    return _convolve(scene, otf_half, float(df), float(p), int(n_fft), half, boundary,
                     float(constant))


def _fold(kernel, half: int, big_h: int, big_w: int):
    """The (…, 2·half+1, 2·half+1) kernel on a (big_h, big_w) torus, its centre at (0, 0):
    a periodic scene smaller than the kernel wraps it, and the wrapped entries are summed as
    a reduction (a scatter-add of thousands of entries per cell loses digits in float32)."""
    n = 2 * half + 1
    reps_h, reps_w = -(-n // big_h), -(-n // big_w)
    widths = [(0, 0)] * (kernel.ndim - 2) + [(0, reps_h * big_h - n), (0, reps_w * big_w - n)]
    tiles = jnp.pad(kernel, widths).reshape(kernel.shape[:-2] + (reps_h, big_h, reps_w, big_w))
    return jnp.roll(jnp.sum(tiles, axis=(-4, -2)), (-half, -half), axis=(-2, -1))


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
    placed = _fold(kernel, half, big_h, big_w)
    spectrum = jnp.fft.rfft2(padded) * jnp.fft.rfft2(placed)
    image = jnp.fft.irfft2(spectrum, s=(big_h, big_w))
    return image[..., pad : pad + H, pad : pad + W]


__all__ = ["ORIENTATIONS", "snellen_e", "kernel_half_width", "psf_on_grid", "retinal_image"]

