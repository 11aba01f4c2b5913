"""Image-quality metrics on half-plane OTFs: NCSF, VSOTF, Strehl, radial MTF, cut-off.

OTFs here are half planes in ``rfft2`` layout (axis −2: f_y in FFT order, axis −1:
f_x = 0 … L/2), OTF(0) = 1, on the frequency step ``freq_step_cpd``. Sums over the whole
frequency plane use the Hermitian multiplicity of each half-plane column.
"""

from __future__ import annotations

import math
from functools import lru_cache

import jax.numpy as jnp
import numpy as np

from lfjax.base.types import FULL
from lfjax.base.sampling import frequencies_cpd, half_frequencies_cpd

# ----------------------------------------------------------------------------- NCSF


def _array_module(*arrays):
    """numpy when every input is a NumPy array or scalar (no dispatch or compiles), else jax."""
    if all(isinstance(a, (np.ndarray, float, int, np.floating)) for a in arrays):
        return np
    return jnp


def ncsf_watson_ahumada_2005(fx_cpd, fy_cpd):
    """ModelFest CSF of Watson & Ahumada (2005) with the oblique effect (unitless sensitivity).

    .. math::
        S(f) = 373.08\\,[\\mathrm{sech}((f/4.1726)^{0.7786}) - 0.8493\\,\\mathrm{sech}(f/1.3625)]

    times O(f, θ) = 1 for f ≤ 3.481 cpd, else 1 − (1 − e^{−(f−3.481)/13.57149}) sin²(2θ).
    It was measured through the observers' own optics, so it is not purely neural; the paper
    uses it as the NCSF (Watson & Ahumada 2005, J Vis 5:717; 2012).
    NumPy arrays in give NumPy out (host planning); anything else is evaluated with jax.
    """
    jnp = _array_module(fx_cpd, fy_cpd)
    f2 = fx_cpd * fx_cpd + fy_cpd * fy_cpd
    positive = f2 > 0
    f = jnp.where(positive, jnp.sqrt(jnp.where(positive, f2, 1.0)), 0.0)
    base = 373.08 * (
        1.0 / jnp.cosh((f / 4.1726) ** 0.7786) - 0.8493 / jnp.cosh(f / 1.3625)
    )
    # sin²(2θ) = (2 fx fy / f²)² without arctan2
    sin2 = jnp.where(positive, (2.0 * fx_cpd * fy_cpd / jnp.where(positive, f2, 1.0)) ** 2, 0.0)
    oblique = jnp.where(
        f <= 3.481, 1.0, 1.0 - (1.0 - jnp.exp(-(f - 3.481) / 13.57149)) * sin2
    )
    return base * oblique


def ncsf_campbell_green_2004(fx_cpd, fy_cpd):
    """Neural CSF of Campbell & Green as fitted by Thibos et al. (2004); radially symmetric.

    log10 S = 2.8876e-8 f⁵ − 5.2957e-6 f⁴ + 3.5818e-4 f³ − 1.1241e-2 f² + 0.12704 f + 1.8636,
    zero above 64 cpd.
    """
    jnp = _array_module(fx_cpd, fy_cpd)
    f = jnp.sqrt(fx_cpd * fx_cpd + fy_cpd * fy_cpd)
    log_s = (
        ((((2.8876e-8 * f - 5.2957e-6) * f + 3.5818e-4) * f - 1.1241e-2) * f + 0.12704) * f
        + 1.8636
    )
    return jnp.where(f <= 64.0, 10.0**log_s, 0.0)


NCSF_FUNCTIONS = {
    "watson_ahumada_2005": ncsf_watson_ahumada_2005,
    "campbell_green_2004": ncsf_campbell_green_2004,
}


def ncsf(fx_cpd, fy_cpd, model: str = "watson_ahumada_2005"):
    """Neural contrast sensitivity at (fx, fy) cpd for the named model."""
    if model not in NCSF_FUNCTIONS:
        raise ValueError(f"ncsf model must be one of {sorted(NCSF_FUNCTIONS)}, got {model!r}")
    return NCSF_FUNCTIONS[model](fx_cpd, fy_cpd)


# ----------------------------------------------------------------------------- grids


def half_plane_weights_np(n_fft: int) -> np.ndarray:
    """:func:`half_plane_weights` as a float64 NumPy array (host planning)."""
    w = np.full(n_fft // 2 + 1, 2.0)
    w[0] = 1.0
    if n_fft % 2 == 0:
        w[-1] = 1.0
    return w


def half_plane_weights(n_fft: int):
    """Multiplicity of each half-plane column in a full-plane sum: 1 at f_x = 0 (and at the
    Nyquist column of even L), 2 elsewhere."""
    return jnp.asarray(half_plane_weights_np(n_fft))


def half_plane_frequencies(n_fft: int, freq_step_cpd: float):
    """(fx, fy) cpd grids of shape (L, L//2+1) matching a half-plane OTF."""
    fy = frequencies_cpd(n_fft, freq_step_cpd)
    fx = half_frequencies_cpd(n_fft, freq_step_cpd)
    return jnp.meshgrid(fx, fy)


def ncsf_half_plane(n_fft: int, freq_step_cpd: float, model: str = "watson_ahumada_2005",
                    host: bool = False):
    """NCSF on the half plane times the Hermitian multiplicity (ready for VSOTF sums),
    (L, L//2+1).

    ``host=True``: the same weights as a float64 NumPy array, computed on the host without
    JAX (the planner's proxy, :mod:`lfjax.planner.proxy`, which compiles nothing); the
    frequencies are the same host grids either way."""
    if host:
        fy = np.fft.fftfreq(n_fft, 1.0 / n_fft) * freq_step_cpd
        fx = np.fft.rfftfreq(n_fft, 1.0 / n_fft) * freq_step_cpd
        weights = np.asarray(ncsf(fx[None, :], fy[:, None], model), float)
        return weights * half_plane_weights_np(n_fft)[None, :]
    fx, fy = half_plane_frequencies(n_fft, freq_step_cpd)
    return ncsf(fx, fy, model) * half_plane_weights(n_fft)[None, :]


# ----------------------------------------------------------------------------- metrics


def vsotf_numerator(otf_half, weighted_ncsf):
    """Σ_f NCSF(f) Re OTF(f) over the whole plane (half plane × multiplicity)."""
    return jnp.sum(jnp.real(otf_half) * weighted_ncsf, axis=(-2, -1))


def vsotf(otf_half, reference_otf_half, n_fft: int, freq_step_cpd: float,
          model: str = "watson_ahumada_2005", reference_n_fft: int | None = None):
    """Visual Strehl ratio computed from the OTF (Miyanishi et al. ``eq:VSOTF``).

    .. math:: \\mathrm{VSOTF} = \\frac{\\int \\mathrm{NCSF}\\,\\mathrm{Re\\,OTF}}
              {\\int \\mathrm{NCSF}\\,\\mathrm{Re\\,OTF_{DL}}}

    Both OTFs share the frequency step; the reference may live on another window size.
    """
    ref_n = n_fft if reference_n_fft is None else reference_n_fft
    num = vsotf_numerator(otf_half, ncsf_half_plane(n_fft, freq_step_cpd, model))
    den = vsotf_numerator(reference_otf_half, ncsf_half_plane(ref_n, freq_step_cpd, model))
    return num / den


def psf_peak(otf_half, n_fft: int, freq_step_cpd: float):
    """Largest PSF density (per arcmin²) of half-plane OTFs (…, L, L//2+1)."""
    psf = jnp.fft.irfft2(otf_half, s=(n_fft, n_fft)) * (n_fft * n_fft) * (freq_step_cpd / 60.0) ** 2
    return jnp.max(psf, axis=(-2, -1))


def strehl_ratio(otf_half, reference_otf_half, n_fft: int, freq_step_cpd: float,
                 reference_n_fft: int | None = None):
    """Strehl ratio: PSF peak over the reference PSF peak (both with OTF(0) = 1).

    The peak is the largest sample of the PSF on its pixel grid (60/(df·L) arcmin), as a
    sampled PSF gives it.
    """
    ref_n = n_fft if reference_n_fft is None else reference_n_fft
    return psf_peak(otf_half, n_fft, freq_step_cpd) / psf_peak(
        reference_otf_half, ref_n, freq_step_cpd
    )


@lru_cache(maxsize=32)
def radial_bins(n_fft: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ring k = 0 … L/2 of the half-plane grid as a padded gather: ``index`` (n_bins,
    max_ring) int32 positions in the flattened (L, L//2+1) plane and ``weights`` (n_bins,
    max_ring) their share of the ring mean (half-plane multiplicity / the ring's full-plane
    count; 0 on padding). O(L²) host data — a dense (n_bins, L·(L//2+1)) matrix would be
    O(L³) (5.8 GiB at L = 1458) — and a fixed summation order (a scatter-add's would vary
    between GPU runs)."""
    fy = np.fft.fftfreq(n_fft, 1.0 / n_fft)
    fx = np.fft.rfftfreq(n_fft, 1.0 / n_fft)
    ring = np.rint(np.hypot(fx[None, :], fy[:, None])).astype(np.int64).ravel()
    mult = np.broadcast_to(half_plane_weights_np(n_fft)[None, :],
                           (n_fft, n_fft // 2 + 1)).ravel()
    n_bins = n_fft // 2 + 1
    keep = np.flatnonzero(ring < n_bins)  # the corners beyond L/2 belong to no ring
    ring, mult = ring[keep], mult[keep]
    order = np.argsort(ring, kind="stable")
    ring, position, mult = ring[order], keep[order], mult[order]
    sizes = np.bincount(ring, minlength=n_bins)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    slot = np.arange(ring.size) - starts[ring]
    index = np.zeros((n_bins, int(sizes.max())), np.int32)
    weights = np.zeros(index.shape)
    index[ring, slot] = position
    weights[ring, slot] = mult / np.bincount(ring, weights=mult, minlength=n_bins)[ring]
    return index, weights, np.arange(n_bins, dtype=float)


def radial_mtf(otf_half, n_fft: int, freq_step_cpd: float):
    """MTF averaged over meridians (ring average of |OTF|) at f = k·df, k = 0 … L/2.

    Returns (radial_mtf (…, L//2+1), frequencies_cpd (L//2+1,)). Memory O(L²) per OTF.
    """
    index, weights, k = radial_bins(n_fft)
    mod = jnp.abs(otf_half).reshape(otf_half.shape[:-2] + (-1,))
    rings = mod[..., jnp.asarray(index)]  # (…, n_bins, max_ring)
    return (jnp.sum(rings * jnp.asarray(weights, mod.dtype), axis=-1),
            jnp.asarray(k * freq_step_cpd))


def cutoff_frequency(radial, frequencies_cpd_, threshold: float = 0.05):
    """First frequency (cpd) where a radial MTF falls to ``threshold`` (linear interpolation).

    Returns the last frequency when the MTF never falls that low. NumPy arrays in give NumPy
    out (the planner's proxy reads its cut-offs with this rule); anything else is evaluated
    with jax.
    """
    if not (0.0 < threshold < 1.0):
        raise ValueError(f"threshold must be in (0, 1), got {threshold}")
    jnp = _array_module(radial, frequencies_cpd_)
    below = radial[..., 1:] <= threshold
    has = jnp.any(below, axis=-1)
    idx = jnp.argmax(below, axis=-1) + 1  # first index at/below threshold
    hi = jnp.take_along_axis(radial, idx[..., None], axis=-1)[..., 0]
    lo = jnp.take_along_axis(radial, (idx - 1)[..., None], axis=-1)[..., 0]
    f_hi = frequencies_cpd_[idx]
    f_lo = frequencies_cpd_[idx - 1]
    frac = jnp.clip((lo - threshold) / jnp.where(lo - hi > 0, lo - hi, 1.0), 0.0, 1.0)
    return jnp.where(has, f_lo + frac * (f_hi - f_lo), frequencies_cpd_[-1])


def diffraction_limited_mtf(freq_cpd, pupil_diameter_mm: float, wavelength_nm: float):
    """Analytic MTF of an aberration-free circular pupil (incoherent), for tests and plots."""
    cutoff = pupil_diameter_mm / (wavelength_nm * 1e-6) / (180.0 / math.pi)  # cpd
    nu = jnp.clip(jnp.abs(freq_cpd) / cutoff, 0.0, 1.0)
    return (2.0 / jnp.pi) * (jnp.arccos(nu) - nu * jnp.sqrt(1.0 - nu * nu))


__all__ = [
    "ncsf",
    "ncsf_watson_ahumada_2005",
    "ncsf_campbell_green_2004",
    "ncsf_half_plane",
    "half_plane_weights",
    "half_plane_weights_np",
    "radial_bins",
    "half_plane_frequencies",
    "vsotf",
    "vsotf_numerator",
    "psf_peak",
    "strehl_ratio",
    "radial_mtf",
    "cutoff_frequency",
    "diffraction_limited_mtf",
]

