"""Lenslet aberrations: each view's beam carries its lenslet's wavefront error into the pupil.

Model (thin lenslets, third order, paraxial mapping). A lenslet's wavefront error W over
its aperture a (measured against the reference sphere centred on the paraxial image of its
pixel on the CDP) is carried along the rays to the eye's pupil, where the lenslet's beam is
its aperture magnified M = 1 + z_m·V times (:class:`lfjax.display.lenslets.LensletArray`).
The optical path difference along a ray does not change on the way, so the view's
wavefront in the pupil is W(u/M) at the local coordinate u = p − p_n from the view's centre
p_n: a rim coefficient of the lenslet (at its aperture's edge, ρ = 1) is the same rim
coefficient of the view (at M·a/2). With lenslet diffraction on, the phase multiplies the
magnified aperture before its Fresnel propagation (the factorisation of
:mod:`lfjax.display.lenslets` holds for any complex aperture function); without it, it adds
to the eye's wavefront over the geometric subaperture.

The primary (Seidel) terms of every view, ρ = |u|/(d_n/2) (d_n the view's diameter, or side
for square apertures), φ the angle of u from the field direction ψ:

    W = W040 ρ⁴ + W131 (ρ³ − t ρ) cos φ + W222 ρ² cos² φ + W220 ρ²

with t = 2/3 (circle) or 14/15 (square): the least-squares tilt of ρ³ cos φ over the
aperture is removed, because it only moves the image, by the same angle for every view of
a point (a distortion the renderer calibrates out), as the eye's own tilt is dropped.

Thin lenslet, stop at the lens (every lenslet is its own beam's stop), in air, refractive
index n, power K = 1/f, marginal height y = a/2, field angle θ (rad) — Welford,
*Aberrations of Optical Systems* (1986), §7.4 (thin-lens Seidel sums), with the shape factor
B = (c₁ + c₂)/(c₁ − c₂) and the conjugate factor C, both written for light travelling from
the eye towards the panel (aberrations are reversible): c₁ is the curvature of the surface
facing the eye, and the beam arrives converging on the CDP image point v = 1/V behind the
lenslet and focuses on the pixel at z_0, so C = −(1 + 2V/K) (−1 for a collimating
lenslet):

    S_I  = y⁴K³/4 · [(n/(n−1))² + (n+2)/(n(n−1)²) B² + 4(n+1)/(n(n−1)) B C + (3n+2)/n C²]
    S_II = y³θK²/2 · [(n+1)/(n(n−1)) B + (2n+1)/n C]
    S_III = θ²y²K,   S_IV = θ²y²K/n,   S_V = 0
    W040 = S_I/8,  W131 = S_II/2,  W222 = S_III/2,  W220 = S_IV/4.

Lens forms (:data:`LENS_FORMS`): ``"plano-convex-eye"`` (B = +1, curved face towards the
eye, the collimated side: the right way round), ``"plano-convex-panel"`` (B = −1, curved
face towards the panel, about 3.9 times the spherical aberration at n = 1.5),
``"biconvex"`` (B = 0) and ``"best-form"`` (B = −2(n² − 1)C/(n + 2), least spherical
aberration). At n = 1.5 and C = −1 this gives W040 = 0.292·y⁴/f³ plano-convex and
0.268·y⁴/f³ best form (the classical 0.268). tests/display/test_aberrations.py traces exact
rays through plano-convex lenses of both orientations and checks S_I.

Field. The lenslets that send a point seen at visual angle θ from the display's normal
into the pupil all work at field angle θ (to within p_n·V/M, the view's own angle, below
0.1° for the presets), so every view of the point carries the same coefficients, in its own
local coordinates, with the field direction ψ (the point's azimuth on the display).
Astigmatism and field curvature do not depend on the lens form or the conjugate (stop at
the lens); coma does. The sign of the coma term sets only which way its flare points; the
VSOTF and MTF of a point are the same either way (the NCSF is even in frequency).

What the model leaves out: aberrations of order five and above (at f/3 and below they
reach a few per cent of the third-order terms), thickness (a real lenslet's sag and
substrate shift the Seidel sums by O(thickness/f)), distortion (S_V = 0 for a thin lens
with its stop at the lens), the dependence of the pixel's own field on the lenslet
(a pixel is a point source on the panel) and manufacturing errors (given directly as
coefficients, :class:`LensletAberration`).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import as_real_array
from lfjax.base.types import is_concrete as _concrete

LENS_FORMS = ("plano-convex-eye", "plano-convex-panel", "biconvex", "best-form")
"""Named lens forms of :func:`seidel_coefficients` (module docstring)."""

COMA_TILT = {"circle": 2.0 / 3.0, "square": 14.0 / 15.0}
"""Least-squares tilt t of ρ³ cos φ over the aperture (in units of the rim ρ = 1): ⟨x²r²⟩/⟨x²⟩
over a unit disc, 2/3, and over a square of half-side 1, (1/5 + 1/9)·3 = 14/15."""

_FIELDS = ("spherical_um", "coma_um", "astigmatism_um", "field_curvature_um")
MAX_RIM_UM = 100.0
"""Largest rim coefficient accepted, µm (about 180 waves at 550 nm: beyond it the field guard's
sampling would need more samples than any computation here affords)."""


def _check_scalar(name: str, value, lo: float, hi: float, unit: str, lo_open: bool = False) -> float:
    v = np.asarray(value, float)
    if v.shape != ():
        raise ParameterError(name, "{%s} must be a scalar (%s), got shape {shape}" % (name, unit),
                             shape=v.shape)
    x = float(v)
    ok = math.isfinite(x) and (x > lo if lo_open else x >= lo) and x <= hi
    if not ok:
        left = "(" if lo_open else "["
        raise ParameterError(name, "{%s} must be in %s{lo:g}, {hi:g}] %s, got {got}" % (name, left, unit),
                             lo=lo, hi=hi, got=x)
    return x


class LensletAberration(eqx.Module):
    """The primary wavefront error every view carries, as rim coefficients (all leaves arrays).

    Attributes (µm at the view's rim, ρ = 1 at half its diameter or side; each in
    [−:data:`MAX_RIM_UM`, :data:`MAX_RIM_UM`] µm)
    ----------
    spherical_um : () W040, spherical aberration (ρ⁴)
    coma_um : () W131, coma with its tilt removed ((ρ³ − tρ) cos φ)
    astigmatism_um : () W222 (ρ² cos² φ)
    field_curvature_um : () W220, the field's (Petzval) defocus of the view (ρ²)
    field_azimuth_rad : () ψ, the field direction in the pupil, rad from +x towards +y (any
        finite value)

    All zero is the aberration-free lenslet: the pipeline's numbers are then those without
    an aberration, bit for bit.
    """

    spherical_um: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)
    coma_um: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)
    astigmatism_um: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)
    field_curvature_um: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)
    field_azimuth_rad: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)

    def __check_init__(self):
        leaves = [getattr(self, f) for f in _FIELDS] + [self.field_azimuth_rad]
        if not _concrete(*leaves):
            return
        for name in _FIELDS:
            _check_scalar(name, getattr(self, name), -MAX_RIM_UM, MAX_RIM_UM, "µm at the view's rim")
        _check_scalar("field_azimuth_rad", self.field_azimuth_rad, -1e6, 1e6, "rad")

    def wavefront_um(self, u_mm, v_mm, radius_mm, shape: str = "circle"):
        """W (µm) at local pupil coordinates ``u_mm``, ``v_mm`` (mm from the view's centre,
        broadcast) of a view of rim radius ``radius_mm`` (mm: half its diameter or side)."""
        c, s = jnp.cos(self.field_azimuth_rad), jnp.sin(self.field_azimuth_rad)
        x = u_mm / radius_mm
        y = v_mm / radius_mm
        along = c * x + s * y  # ρ cos φ
        r2 = x * x + y * y
        return (self.spherical_um * r2 * r2
                + self.coma_um * (r2 - COMA_TILT[shape]) * along
                + self.astigmatism_um * along * along
                + self.field_curvature_um * r2)

    def slope_rad(self, radius_mm, shape: str = "circle") -> float:
        """Host bound on |∇W| (rad) over a view of rim radius ``radius_mm`` (mm; the
        smallest view of a layout): what the PSF field must hold beyond the eye's blur."""
        rim = math.sqrt(2.0) if shape == "square" else 1.0
        a = [abs(float(np.asarray(getattr(self, f)))) for f in _FIELDS]
        per_rim = (4 * a[0] * rim**3 + a[1] * (3 * rim**2 + COMA_TILT[shape])
                   + 2 * a[2] * rim + 2 * a[3] * rim)
        return per_rim / float(radius_mm) * 1e-3  # µm/mm = mrad

    def checked(self) -> LensletAberration:
        """Traced-value checks (``eqx.error_if``) for use inside the pipeline."""
        values = []
        for name in _FIELDS:
            v = getattr(self, name)
            values.append(eqx.error_if(v, ~(jnp.isfinite(v) & (jnp.abs(v) <= MAX_RIM_UM)),
                                       f"{name} must be finite and in [-{MAX_RIM_UM:g}, {MAX_RIM_UM:g}] µm"))
        psi = eqx.error_if(self.field_azimuth_rad, ~jnp.isfinite(self.field_azimuth_rad),
                           "field_azimuth_rad must be finite")
        return LensletAberration(*values, psi)


def shape_factor(lens_form: str | float, refractive_index, conjugate):
    """B of ``lens_form`` (a name of :data:`LENS_FORMS`, or B itself as a number in [−10, 10])
    for the conjugate factor ``conjugate`` C (module docstring)."""
    if isinstance(lens_form, str):
        if lens_form not in LENS_FORMS:
            raise ParameterError("lens_form", "{lens_form} must be one of %s or a shape factor in "
                                 "[-10, 10], got {got!r}" % ", ".join(LENS_FORMS), got=lens_form)
        if lens_form == "best-form":
            n = refractive_index
            return -2.0 * (n * n - 1.0) * conjugate / (n + 2.0)
        return {"plano-convex-eye": 1.0, "plano-convex-panel": -1.0, "biconvex": 0.0}[lens_form]
    if _concrete(lens_form):
        _check_scalar("lens_form", lens_form, -10.0, 10.0, "(shape factor B)")
    return lens_form


def check_lens_inputs(focal_length_mm, aperture_mm, image_vergence_per_mm, refractive_index,
                      field_angle_deg, field_azimuth_deg) -> None:
    """Refuse, before any work, a lens input outside its range (each named with its unit)."""
    if _concrete(focal_length_mm):
        f = float(np.asarray(focal_length_mm, float))
        if not (f > 0 and (math.isfinite(f) or f == math.inf)):
            raise ParameterError("focal_length_mm", "{focal_length_mm} must be in (0, inf] mm, got {got}",
                                 got=f)
    if _concrete(aperture_mm):
        _check_scalar("aperture_mm", aperture_mm, 0.0, 1e3, "mm", lo_open=True)
    if _concrete(image_vergence_per_mm):
        _check_scalar("image_vergence_per_mm", image_vergence_per_mm, 0.0, 1e3, "1/mm")
    if _concrete(refractive_index):
        _check_scalar("refractive_index", refractive_index, 1.0, 4.0, "(unitless)", lo_open=True)
    if _concrete(field_angle_deg):
        _check_scalar("field_angle_deg", field_angle_deg, 0.0, 60.0, "deg")
    if _concrete(field_azimuth_deg):
        _check_scalar("field_azimuth_deg", field_azimuth_deg, -360.0, 360.0, "deg")


def seidel_coefficients(focal_length_mm, aperture_mm, image_vergence_per_mm=0.0, *,
                        refractive_index=1.5, lens_form: str | float = "plano-convex-eye",
                        field_angle_deg=0.0) -> dict:
    """Rim wavefront coefficients (µm) of one thin lenslet, stop at the lens (module docstring).

    ``focal_length_mm`` f (mm, (0, inf]; inf, a pinhole, has none), ``aperture_mm`` a (mm,
    diameter or side: y = a/2), ``image_vergence_per_mm`` V = 1/z_0 − 1/f (1/mm, ≥ 0),
    ``refractive_index`` n in (1, 4], ``lens_form`` (:data:`LENS_FORMS` or a shape factor B in
    [−10, 10]), ``field_angle_deg`` θ in [0, 60]°. Differentiable in every number. Returns
    ``{"spherical_um", "coma_um", "astigmatism_um", "field_curvature_um"}``.
    """
    check_lens_inputs(focal_length_mm, aperture_mm, image_vergence_per_mm, refractive_index,
                      field_angle_deg, 0.0)
    n = refractive_index
    k = 1.0 / jnp.asarray(focal_length_mm, jnp.result_type(float))
    v = image_vergence_per_mm
    y = 0.5 * jnp.asarray(aperture_mm, k.dtype)
    theta = jnp.deg2rad(jnp.asarray(field_angle_deg, k.dtype))
    # C = −(K + 2V)/K; every term is written with K·C = −(K + 2V), so a pinhole (K = 0) is 0
    kc = -(k + 2.0 * v)
    b = shape_factor(lens_form, n, kc / jnp.where(k > 0, k, 1.0))
    s1 = (y**4 / 4.0) * (k**3 * (n / (n - 1.0)) ** 2 + k**3 * (n + 2.0) / (n * (n - 1.0) ** 2) * b * b
                        + 4.0 * (n + 1.0) / (n * (n - 1.0)) * b * k * k * kc
                        + (3.0 * n + 2.0) / n * k * kc * kc)
    s2 = (y**3 * theta / 2.0) * ((n + 1.0) / (n * (n - 1.0)) * b * k * k + (2.0 * n + 1.0) / n * k * kc)
    s3 = theta**2 * y**2 * k
    s4 = s3 / n
    um = 1e3  # the sums are in mm
    return {"spherical_um": um * s1 / 8.0, "coma_um": um * s2 / 2.0,
            "astigmatism_um": um * s3 / 2.0, "field_curvature_um": um * s4 / 4.0}


def lenslet_aberration(focal_length_mm, aperture_mm, image_vergence_per_mm=0.0, *,
                       refractive_index=1.5, lens_form: str | float = "plano-convex-eye",
                       field_angle_deg=0.0, field_azimuth_deg=0.0,
                       spherical_um=None) -> LensletAberration:
    """The :class:`LensletAberration` of thin lenslets (:func:`seidel_coefficients`), the
    field towards ``field_azimuth_deg`` (deg in [−360, 360], from +x). ``spherical_um`` (µm
    at the rim, [−100, 100]) replaces the lens form's spherical aberration with a given
    coefficient (a measured lenslet, an aspheric one: 0). Checked before any work."""
    check_lens_inputs(focal_length_mm, aperture_mm, image_vergence_per_mm, refractive_index,
                      field_angle_deg, field_azimuth_deg)
    if spherical_um is not None and _concrete(spherical_um):
        _check_scalar("spherical_um", spherical_um, -MAX_RIM_UM, MAX_RIM_UM, "µm at the view's rim")
    c = seidel_coefficients(focal_length_mm, aperture_mm, image_vergence_per_mm,
                            refractive_index=refractive_index, lens_form=lens_form,
                            field_angle_deg=field_angle_deg)
    if spherical_um is not None:
        c["spherical_um"] = spherical_um
    return LensletAberration(c["spherical_um"], c["coma_um"], c["astigmatism_um"],
                             c["field_curvature_um"], jnp.deg2rad(jnp.asarray(field_azimuth_deg, float)))


def panel_aberration(panel, *, refractive_index=1.5, lens_form: str | float = "plano-convex-eye",
                     field_angle_deg=0.0, field_azimuth_deg=0.0, spherical_um=None) -> LensletAberration:
    """The lenslets' aberration of a :class:`lfjax.display.panel.Panel` (its focal length,
    aperture fill·Δu and image vergence) for a point at ``field_angle_deg`` (deg, [0, 60])
    from the display's normal; other arguments as :func:`lenslet_aberration`."""
    return lenslet_aberration(panel.focal_length_mm, panel.aperture_mm, panel.image_vergence_per_mm,
                              refractive_index=refractive_index, lens_form=lens_form,
                              field_angle_deg=field_angle_deg, field_azimuth_deg=field_azimuth_deg,
                              spherical_um=spherical_um)


__all__ = [
    "LensletAberration",
    "LENS_FORMS",
    "COMA_TILT",
    "MAX_RIM_UM",
    "seidel_coefficients",
    "lenslet_aberration",
    "panel_aberration",
    "shape_factor",
    "check_lens_inputs",
]
