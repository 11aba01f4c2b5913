"""Point-spread functions and OTFs of eyes: one monochromatic PSF at any angular sampling,
and polychromatic OTFs for eyes × rendered depths × accommodation states.

:func:`monochromatic_psf` evaluates one PSF by a matrix Fourier transform (MFT).

Conventions (docs/design.md#conventions): pupil function ``A · exp(−i 2π W / λ)``, PSF = |forward
transform|², arrays ``[y, x]``. The pupil is a soft-edged disc (:func:`lfjax.base.apertures.soft_disk`)
sampled with ``pupil_samples`` samples across its diameter; the PSF is evaluated directly
on the requested angles, so any pixel size and field can be asked for.

:func:`monochromatic_psf` is a plain function that works under ``jax.jit``, ``jax.vmap``
and ``jax.grad`` applied from outside: values known on the host are validated eagerly
(``ValueError``), traced values with ``eqx.error_if`` (a bad value raises at run time
instead of returning NaN). Structural arguments (``measured_pupil_mm``, ``n_pixels``,
``pupil_samples``, ``edge_width_samples``, ``tolerance``) are static Python values.

:func:`polychromatic_otf` is the host-side entry point to the pure pipeline's first half
(:func:`lfjax.kernel.pipeline.otf_stack`): it checks its inputs, builds the ``Scene`` and
``Accommodation`` pytrees (:func:`lfjax.vision.prepare.prepare`) and calls the compiled
pipeline once.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Complex, Float, Real

from lfjax.base.types import FULL, shape_checked
from lfjax.base.apertures import soft_disk
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout
from lfjax.kernel.optics import full_plane, validate_pupil
from lfjax.model.options import ModelOptions
from lfjax.kernel.pipeline import otf_stack
from lfjax.base.sampling import EDGE_EXTENT_SCALES, Sampling
from lfjax.model.spectral import Spectrum
from lfjax.base.units import ARCMIN_PER_RADIAN, dioptres_to_c20_um
from lfjax.vision.prepare import States, prepare
from lfjax.base.zernike import zernike_mode, zernike_mode_host
from lfjax.vision.viewing import Viewing, check_viewing

WAVELENGTH_RANGE_NM = (380.0, 830.0)
"""Wavelengths accepted by :func:`monochromatic_psf` (nm)."""

DEFAULT_TOLERANCE = 1e-3
"""Target of the default sampling: max |PSF − converged PSF| / max(converged PSF)."""

TRACED_RMS_WAVES = 1.0
"""RMS wavefront (waves) assumed for the traced part of the wavefront (``coefficients_um``
and/or ``defocus_D``) when the default ``pupil_samples`` is chosen: their values are not
known when the shapes are fixed. Larger wavefronts under a transformation need an
explicit ``pupil_samples``, e.g. from :func:`pupil_samples_for`."""

# Measured error model of the soft-edged, sampled pupil (benchmarks/validation/psf_defaults.py, edge
# 0.25 samples): max error / peak ≈ (a·U + b·w²) / N², U the field in λ/d, w the RMS
# wavefront in waves; a ≤ 0.90 (the soft edge dims wide angles, so the field-sum
# normalisation drifts), b ≤ 665 with a = 1 (pure defocus is the worst case; a first-order
# edge-perturbation estimate at the PSF centre gives 780). Both scale with
# edge_width_samples². The default aims at half the tolerance (a margin of 2).
_ERROR_PER_FIELD = 1.0
_ERROR_PER_WAVE2 = 700.0
_MARGIN = 2.0
_SLOPE_PER_RMS_WAVE = 8.0 * math.sqrt(3.0)  # blur radius (λ/d) per RMS wave of defocus
_ALIAS_GUARD = 8.0  # λ/d between the field edge and the nearest replica's blur
_RMS_GRID = 65  # host grid across the pupil for the RMS wavefront and its slope


def _is_traced(x) -> bool:
    return any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(x))


def _scalar(name: str, value):
    """A traced scalar as it is; a concrete one as a NumPy float (host checks stay on the
    host even inside a user's jit, where jnp operations on constants are staged out)."""
    x = value if _is_traced(value) else np.asarray(value, dtype=jnp.result_type(float))
    if np.ndim(x) != 0:
        raise ValueError(
            f"{name} must be a scalar, got shape {np.shape(x)}; map over a batch with jax.vmap"
        )
    return x


def _static_int(name: str, value, minimum: int) -> int:
    message = f"{name} must be an integer >= {minimum}, got {value!r}"
    if _is_traced(value):
        raise ValueError(f"{message} (a traced value: {name} is static, pass a Python int)")
    try:
        n = operator.index(value)
    except TypeError:
        if isinstance(value, float) and value.is_integer():
            n = int(value)
        else:
            raise ValueError(message) from None
    if n < minimum:
        raise ValueError(message)
    return n


def _ladder(n: float) -> int:
    """Round up to 8 sizes per octave (multiples of 2^(k−3) in [2^k, 2^(k+1))), ≥ 16."""
    n = max(int(math.ceil(n)), 16)
    step = 2 ** (int(math.floor(math.log2(n))) - 3)
    return -(-n // step) * step


def _wavefront_size(coefficients_um, measured_pupil_mm, pupil_mm, wavelength_nm, defocus_D):
    """(RMS wavefront in waves, largest ray angle in λ/d) over the calculation pupil, on the
    host (concrete values only)."""
    rho = np.linspace(-1.0, 1.0, _RMS_GRID)
    xx, yy = np.meshgrid(rho, rho)
    inside = xx * xx + yy * yy <= 1.0
    scale = pupil_mm / measured_pupil_mm
    c = np.asarray(coefficients_um, dtype=np.float64)
    w_um = np.zeros_like(xx)
    for j in range(c.shape[0]):
        if c[j] != 0.0:
            w_um += c[j] * zernike_mode_host(j, xx * scale, yy * scale)
    if defocus_D != 0.0:
        with jax.ensure_compile_time_eval():  # evaluated now, also inside a user's jit
            c20_um = float(dioptres_to_c20_um(defocus_D, pupil_mm))
        w_um += c20_um * zernike_mode_host(4, xx, yy)
    waves = w_um[inside] * (1e3 / wavelength_nm)
    rms = float(np.sqrt(np.mean((waves - waves.mean()) ** 2)))
    h_mm = pupil_mm / (_RMS_GRID - 1)
    gy, gx = np.gradient(w_um, h_mm)  # µm/mm = mrad
    slope_mrad = float(np.sqrt(gx * gx + gy * gy)[inside].max())
    return rms, slope_mrad * 1e-3 / (wavelength_nm * 1e-6 / pupil_mm)


def pupil_samples_for(
    coefficients_um,
    measured_pupil_mm: float,
    pupil_diameter_mm,
    wavelength_nm,
    pixel_arcmin,
    n_pixels: int,
    defocus_D=0.0,
    *,
    edge_width_samples: float = 0.25,
    tolerance: float = DEFAULT_TOLERANCE,
) -> int:
    """Pupil samples that :func:`monochromatic_psf` uses when ``pupil_samples=None``.

    Parameters
    ----------
    coefficients_um : (n_modes,) array, µm
        OSA/ANSI Zernike coefficients on ``measured_pupil_mm``.
    measured_pupil_mm : float, mm
    pupil_diameter_mm : float, mm
    wavelength_nm : float, nm
    pixel_arcmin : float, arcmin
    n_pixels : int
    defocus_D : float, D
    edge_width_samples : float, pupil samples
    tolerance : float
        Target max |PSF − converged PSF| / peak (default 1e-3); the rule aims at half of it.

    Returns
    -------
    int
        ``N = max(sqrt((U + 700 w²)·(e/0.25)² / (tolerance/2)), U/2 + B + 8)``, rounded up
        to 8 sizes per octave, where ``U = n_pixels·pixel_arcmin / (λ/d)`` is the field in
        diffraction units, ``w`` the RMS wavefront (waves, ``defocus_D`` included) over the
        calculation pupil, ``B`` its largest ray angle in λ/d and ``e`` the edge width.

    Traced values are replaced by bounds: the pupil by ``measured_pupil_mm``, the
    wavelength by 380 nm, and traced coefficients and/or defocus count as
    :data:`TRACED_RMS_WAVES` of RMS wavefront (added to that of the concrete part). A
    traced ``pixel_arcmin`` has no bound: it is a ``ValueError``.
    Call this eagerly to fix the sampling of a sweep or of a transformed call; for a
    batch (``vmap`` over eyes or defocus) take the largest value over its members.
    """
    n_pixels = _static_int("n_pixels", n_pixels, 2)
    if not tolerance > 0:
        raise ValueError(f"tolerance must be > 0, got {tolerance}")
    if _is_traced(pixel_arcmin):
        raise ValueError(
            "pixel_arcmin is traced, so the default pupil_samples (chosen from the field "
            "n_pixels × pixel_arcmin) cannot be computed: pass pupil_samples explicitly, "
            "e.g. pupil_samples_for(...) evaluated with a concrete pixel_arcmin"
        )
    pupil = float(measured_pupil_mm) if _is_traced(pupil_diameter_mm) else float(pupil_diameter_mm)
    wavelength = WAVELENGTH_RANGE_NM[0] if _is_traced(wavelength_nm) else float(wavelength_nm)
    values = (pupil, wavelength, float(pixel_arcmin), float(edge_width_samples))
    if not all(0.0 < v < math.inf for v in values):
        raise ValueError(
            "pupil_diameter_mm, wavelength_nm, pixel_arcmin and edge_width_samples must be "
            f"> 0 and finite, got {values}"
        )
    field_units = n_pixels * float(pixel_arcmin) / ARCMIN_PER_RADIAN / (wavelength * 1e-6 / pupil)

    coefficients_traced = _is_traced(coefficients_um)
    defocus_traced = _is_traced(defocus_D)
    rms, blur = _wavefront_size(
        np.zeros(0) if coefficients_traced else coefficients_um, float(measured_pupil_mm),
        pupil, wavelength, 0.0 if defocus_traced else float(defocus_D),
    )
    allowance = TRACED_RMS_WAVES if (coefficients_traced or defocus_traced) else 0.0
    rms += allowance
    blur += _SLOPE_PER_RMS_WAVE * allowance

    edge = float(edge_width_samples) / 0.25
    n_accuracy = math.sqrt(
        (_ERROR_PER_FIELD * field_units + _ERROR_PER_WAVE2 * rms**2) * edge**2
        / (tolerance / _MARGIN)
    )
    n_alias = 0.5 * field_units + blur + _ALIAS_GUARD
    return _ladder(max(n_accuracy, n_alias))


def _check_traced(x, bad, message: str):
    """``eqx.error_if(x, bad(x), message)`` on a traced value (the returned array must be
    used); a concrete value was checked on the host and is returned as it is."""
    return eqx.error_if(x, bad(x), message) if _is_traced(x) else x


@shape_checked
def monochromatic_psf(
    coefficients_um: Real[ArrayLike, " n_modes"] | Sequence[float],
    measured_pupil_mm: float,
    pupil_diameter_mm,
    wavelength_nm,
    pixel_arcmin,
    n_pixels: int,
    defocus_D=0.0,
    sce_rho_per_mm2=0.0,
    pupil_samples: int | None = None,
    edge_width_samples: float = 0.25,
    tolerance: float = DEFAULT_TOLERANCE,
) -> Float[Array, "n_pixels n_pixels"]:
    """Monochromatic PSF of one eye, point-sampled on a square grid, normalised to unit sum.

    Parameters
    ----------
    coefficients_um : (n_modes,) array, µm
        OSA/ANSI Zernike coefficients (RMS-normalised) measured on ``measured_pupil_mm``.
    measured_pupil_mm : float, mm, static
        Pupil diameter the coefficients were measured on.
    pupil_diameter_mm : float, mm
        Calculation pupil, in (0, measured_pupil_mm].
    wavelength_nm : float, nm
        In 380–830 nm.
    pixel_arcmin : float, arcmin
        Angular pixel of the PSF, > 0.
    n_pixels : int, static
        The PSF is ``n_pixels × n_pixels``, >= 2.
    defocus_D : float, D
        Defocus added to the eye's, as c(2,0) on the calculation pupil; positive is myopic.
    sce_rho_per_mm2 : float, 1/mm²
        Stiles–Crawford ρ: amplitude apodisation ``10^(−ρ r²)``, r in mm.
    pupil_samples : int or None, static
        Samples across the pupil diameter (the grid extends past the edge so the soft edge
        is evaluated in full). None (default): chosen by :func:`pupil_samples_for` from
        the field, the pupil, the wavelength and the wavefront, to meet ``tolerance``.
    edge_width_samples : float, pupil samples, static
        Logistic edge scale of the pupil.
    tolerance : float, static
        Accuracy target of the default sampling: max |PSF − converged PSF| / its peak.

    Returns
    -------
    (n_pixels, n_pixels) array ``[y, x]``
        Point samples of the PSF at visual angles ``θ = (i − n_pixels // 2) · pixel_arcmin``
        (index ``n_pixels // 2`` is zero angle), summing to 1. Rows grow towards +y and
        columns towards +x: a positive y-tilt c(1,−1) (ANSI j = 1) moves the PSF to lower
        rows (−y), a positive x-tilt c(1,1) (j = 2) to lower columns (−x) (tested).
        ISETBio's PSFs put +y in the first row (its pupil grid flips y), so its rows grow
        towards −y and the same tilt moves its PSF to higher rows: ``np.flipud`` one of the
        two to compare (for even ``n_pixels`` flipud moves the zero-angle row
        ``n_pixels // 2`` to ``n_pixels // 2 − 1``; use an odd size or roll by one).

    Notes
    -----
    Default sampling (``pupil_samples=None``, :func:`pupil_samples_for`). The soft pupil
    edge limits the accuracy, as ≈ (a·U + b·w²)/N² of the peak: it dims wide angles, so
    the unit-sum normalisation over the field drifts (a ≤ 0.90, U = n_pixels ·
    pixel_arcmin / (λ/d), the field in diffraction units), and a wavefront of w waves RMS
    adds b·w² (b ≤ 665; pure defocus is the worst case); both ∝ edge_width_samples². The
    rule takes a = 1, b = 700 and aims at ``tolerance``/2, rounded up to 8 sizes per
    octave (and at least U/2 + blur radius + 8 in λ/d, so the sampled pupil's periodic
    replicas stay outside the field; never the binding term in the measurements).
    Measured (benchmarks/validation/psf_defaults.py): aberration-free 3 mm, 550 nm, 201 × 0.117
    arcmin, against 2048 samples: 128 samples (the former default) 2.1e-3 of peak, 256:
    5.3e-4, the default 288: 4.2e-4; against up to 4× the samples (Richardson in 1/N²),
    45 seeded random cases
    (aberration-free and Thibos eyes, pupils 2–6 mm, 450–650 nm, 0.117–1 arcmin,
    0–2 D): worst 4.7e-4 at the default, worst 9.3e-4 at N/√2 (half the cost). The cost
    grows with w²: 288–1800 samples for 3 mm eyes (0.03–0.6 s after compiling), 7168
    for a 6 mm pupil with 2 D of defocus at 450 nm (about 10 s on 2 CPU cores).

    Traced arguments take bounds in the rule (:func:`pupil_samples_for`), so a transformed
    call may sample more finely than the eager one: both meet the target, and they agree
    to that accuracy, not to round-off. Pass ``pupil_samples`` for identical sampling, for
    finite differences (the default steps with the values) and for wavefronts above
    :data:`TRACED_RMS_WAVES` under a transformation.
    """
    n_pixels, pupil_samples, measured_pupil_mm, edge_width_samples, coefficients_um = (
        _psf_structure(coefficients_um, measured_pupil_mm, n_pixels, pupil_samples,
                       edge_width_samples))
    coefficients_um, pupil, wavelength, pixel, defocus, sce_rho = _psf_values(
        coefficients_um, measured_pupil_mm, pupil_diameter_mm, wavelength_nm, pixel_arcmin,
        defocus_D, sce_rho_per_mm2)
    if pupil_samples is None:
        pupil_samples = pupil_samples_for(
            coefficients_um, measured_pupil_mm, pupil, wavelength, pixel, n_pixels, defocus,
            edge_width_samples=edge_width_samples, tolerance=tolerance,
        )
    return _monochromatic_psf(
        coefficients_um, measured_pupil_mm, pupil, wavelength, pixel, n_pixels, defocus,
        sce_rho, pupil_samples, edge_width_samples,
    )


def _psf_structure(coefficients_um, measured_pupil_mm, n_pixels, pupil_samples,
                   edge_width_samples):
    """:func:`monochromatic_psf`'s tier-1 checks, of its structure (static, known at trace
    time): (n_pixels, pupil_samples, measured_pupil_mm, edge_width_samples, coefficients_um)
    as it computes with them."""
    n_pixels = _static_int("n_pixels", n_pixels, 2)
    if pupil_samples is not None:
        pupil_samples = _static_int("pupil_samples", pupil_samples, 2)
    if _is_traced(measured_pupil_mm):
        raise ValueError("measured_pupil_mm must be a static Python float, got a traced value")
    measured_pupil_mm = float(measured_pupil_mm)
    edge_width_samples = float(edge_width_samples)
    if not edge_width_samples > 0:
        raise ValueError(f"edge_width_samples must be > 0, got {edge_width_samples}")
    if not _is_traced(coefficients_um):
        coefficients_um = np.asarray(coefficients_um, dtype=jnp.result_type(float))
    if np.ndim(coefficients_um) != 1:
        raise ValueError(
            f"coefficients_um must have shape (n_modes,), got {np.shape(coefficients_um)}; "
            "map over eyes with jax.vmap"
        )
    return n_pixels, pupil_samples, measured_pupil_mm, edge_width_samples, coefficients_um


def _psf_values(coefficients_um, measured_pupil_mm: float, pupil_diameter_mm, wavelength_nm,
                pixel_arcmin, defocus_D, sce_rho_per_mm2):
    """:func:`monochromatic_psf`'s checks of its values: concrete ones on the host (tier 2a,
    messages name the parameter), traced ones when the program runs (tier 2b). Returns
    (coefficients_um, pupil mm, wavelength nm, pixel arcmin, defocus D, SCE ρ 1/mm²)."""
    pupil = _scalar("pupil_diameter_mm", pupil_diameter_mm)
    wavelength = _scalar("wavelength_nm", wavelength_nm)
    pixel = _scalar("pixel_arcmin", pixel_arcmin)
    defocus = _scalar("defocus_D", defocus_D)
    sce_rho = _scalar("sce_rho_per_mm2", sce_rho_per_mm2)

    # ---- tier 2a: concrete values, on the host (messages name the parameter)
    validate_pupil(pupil, measured_pupil_mm)
    if not _is_traced(pixel) and not (0.0 < float(pixel) < math.inf):
        raise ValueError(f"pixel_arcmin must be > 0, got {float(pixel)}")
    if not _is_traced(coefficients_um) and not np.all(np.isfinite(coefficients_um)):
        raise ValueError("zernike_um contains non-finite values (NaN or inf)")
    lo, hi = WAVELENGTH_RANGE_NM
    if not _is_traced(wavelength) and not (lo <= float(wavelength) <= hi):
        raise ValueError(f"wavelength_nm must be in 380–830 nm, got {float(wavelength)}")
    for name, value in (("defocus_D", defocus), ("sce_rho_per_mm2", sce_rho)):
        if not _is_traced(value) and not math.isfinite(float(value)):
            raise ValueError(f"{name} must be finite, got {float(value)}")

    # ---- tier 2b: traced values, checked when the program runs
    pupil = _check_traced(pupil, lambda d: ~(d > 0), "pupil_diameter_mm must be > 0 mm")
    pupil = _check_traced(
        pupil, lambda d: d > measured_pupil_mm + 1e-9,
        f"pupil_diameter_mm exceeds the measured pupil of the eyes ({measured_pupil_mm:g} mm)",
    )
    pixel = _check_traced(pixel, lambda p: ~((p > 0) & jnp.isfinite(p)), "pixel_arcmin must be > 0")
    coefficients_um = _check_traced(
        coefficients_um, lambda c: ~jnp.all(jnp.isfinite(c)),
        "zernike_um contains non-finite values (NaN or inf)",
    )
    wavelength = _check_traced(
        wavelength, lambda w: ~((w >= lo) & (w <= hi)), "wavelength_nm must be in 380–830 nm"
    )
    defocus = _check_traced(defocus, lambda x: ~jnp.isfinite(x), "defocus_D must be finite")
    sce_rho = _check_traced(sce_rho, lambda x: ~jnp.isfinite(x), "sce_rho_per_mm2 must be finite")
    return coefficients_um, pupil, wavelength, pixel, defocus, sce_rho


@partial(
    jax.jit,
    static_argnames=("measured_pupil_mm", "n_pixels", "pupil_samples", "edge_width_samples"),
)
def _monochromatic_psf(
    coefficients_um, measured_pupil_mm, pupil_diameter_mm, wavelength_nm, pixel_arcmin,
    n_pixels, defocus_D, sce_rho, pupil_samples, edge_width_samples,
):
    dx = pupil_diameter_mm / pupil_samples
    n_grid = pupil_samples + 2 * int(math.ceil(EDGE_EXTENT_SCALES * edge_width_samples + 1))
    x = (jnp.arange(n_grid) - (n_grid - 1) / 2.0) * dx  # mm; rows of the grid grow to +y
    xx, yy = jnp.meshgrid(x, x)
    r2 = xx * xx + yy * yy
    r_pupil = 0.5 * pupil_diameter_mm
    amp = soft_disk(r2, r_pupil, edge_width_samples * dx) * jnp.power(10.0, -sce_rho * r2)
    # Σ c_j Z_j one mode at a time (no (n_modes, n_grid, n_grid) basis in memory)
    r_meas = 0.5 * measured_pupil_mm
    w = dioptres_to_c20_um(defocus_D, pupil_diameter_mm) * zernike_mode(
        4, xx / r_pupil, yy / r_pupil
    )
    for j in range(coefficients_um.shape[0]):
        w = w + coefficients_um[j] * zernike_mode(j, xx / r_meas, yy / r_meas)
    field = amp * jnp.exp((-2j * jnp.pi / (wavelength_nm * 1e-3)) * w)
    theta_rad = (jnp.arange(n_pixels) - n_pixels // 2) * pixel_arcmin / ARCMIN_PER_RADIAN
    kernel = jnp.exp((-2j * jnp.pi / (wavelength_nm * 1e-6)) * theta_rad[:, None] * x[None, :])
    g = jnp.matmul(jnp.matmul(kernel, field, precision=FULL), kernel.T,
                   precision=FULL)  # rows: θ_y, columns: θ_x
    psf = jnp.abs(g) ** 2
    return psf / jnp.sum(psf)


# ----------------------------------------------------------------------------- polychromatic OTFs


class OTFStack(eqx.Module):
    """Polychromatic OTFs on a common frequency grid, with their axes.

    Attributes
    ----------
    otf : complex array (n_eyes, n_depth, n_acc, L, L//2+1), OTF(0) = 1.
        Half plane f_x ≥ 0 (``rfft2`` layout: axis −2 in FFT order over f_y, axis −1 over
        f_x = 0 … L/2 · df); the OTF is Hermitian, ``full_plane`` restores the rest.
    accommodation_D : (n_acc,) absolute accommodation states, D.
    depths_D : (n_depth,) rendered depths, D.
    freq_step_cpd : float (static) frequency step, cpd.
    """

    otf: Complex[Array, "n_eyes n_depth n_acc L L_half"]
    accommodation_D: Float[Array, " n_acc"]
    depths_D: Float[Array, " n_depth"]
    freq_step_cpd: float = eqx.field(static=True)

    @property
    def n_fft(self) -> int:
        return int(self.otf.shape[-2])

    def full_plane(self):
        """OTFs on the full L × L FFT-order plane."""
        return full_plane(self.otf, self.n_fft)

    @property
    def pixel_arcmin(self) -> float:
        return 60.0 / self.freq_step_cpd / self.n_fft


@shape_checked
def polychromatic_otf(
    eyes: Eyes,
    accommodation_D: Real[ArrayLike, " n_acc"] | float | Sequence[float],
    viewing: Viewing = Viewing(),  # noqa: B008 - frozen, checked once
    *,
    layout: Layout | None = None,
    depths_D: Real[ArrayLike, " n_depth"] | float | Sequence[float] | None = None,
    spectrum: Spectrum | None = None,
    sampling: Sampling = Sampling(),
    options: ModelOptions = ModelOptions(),
    eye_chunk: int | None = None,
    check_aliasing: bool = True,
) -> OTFStack:
    """Polychromatic OTFs for eyes × rendered depths × accommodation states.

    One compiled call, vmapped over accommodation and subapertures, scanned over wavelength
    (reduced inside) and mapped over eyes in chunks of ``eye_chunk`` (memory bound).

    Parameters
    ----------
    eyes : Eyes
        Batch of eyes (coefficients in µm on ``eyes.measured_pupil_mm``).
    accommodation_D : array (n_acc,), D
        Absolute accommodation states 1/z_acc.
    viewing : :class:`~lfjax.vision.viewing.Viewing`
        Calculation pupil (mm, 0 < d ≤ eyes.measured_pupil_mm), the display's central depth
        plane (D, where it forms its image points) and its optics (lenslet diffraction and
        finite pixels; default the paper's ideal display); pupil and CDP may be traced.
    spectrum : Spectrum
        Wavelengths, weights, LCA and SCE (default: 400–700 nm / 10 nm, V(λ)).
    sampling : Sampling
        Frequency step and window sizes.
    options : ModelOptions
    layout : Layout
        Subapertures; default the open pupil (natural viewing).
    depths_D : array (n_depth,), D
        Rendered depths; default ``[viewing.cdp_D]`` (a point on the display plane).
    check_aliasing : bool
        Raise if the field 60/df arcmin cannot hold the blur (default True).

    Returns
    -------
    OTFStack with ``otf`` of shape (n_eyes, n_depth, n_acc, L, L), OTF(0) = 1.
    """
    check_viewing(viewing)
    states = States.every(accommodation_D, viewing.cdp_D if depths_D is None else depths_D)
    prepared = prepare(eyes, layout, states, viewing, spectrum=spectrum, options=options,
                       sampling=sampling, check_aliasing=check_aliasing, eye_chunk=eye_chunk)
    otf = otf_stack(eyes, prepared.scene, prepared.spectrum, prepared.accommodation(options),
                    prepared.config)
    return OTFStack(otf, states.states_D, states.depths_D, prepared.sampling.freq_step_cpd)


__all__ = [
    "monochromatic_psf",
    "polychromatic_otf",
    "OTFStack",
    "pupil_samples_for",
    "DEFAULT_TOLERANCE",
    "TRACED_RMS_WAVES",
    "WAVELENGTH_RANGE_NM",
]
