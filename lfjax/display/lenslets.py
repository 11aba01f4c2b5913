"""Beyond the ideal display: lenslet diffraction and finite pixels (paper Eq. 2 and §Limitations).

The paper's display is ideal: every view fills a geometric subaperture of the pupil and
comes from a point on the central depth plane (CDP). A real integral-imaging display has a
lenslet (or pinhole) array at distance z_m from the eye and a pixel panel at the gap z_0
behind it. This module models two of the effects the paper leaves out, each an optional
component of the pure pipeline, differentiable in its parameters:

**Lenslet diffraction (Eq. 2).** A pixel at z_0 behind a thin lenslet of focal length f is
imaged to the CDP, at v = 1/(1/z_0 − 1/f) behind the lenslet (virtual image; v = ∞ when
z_0 = f), L = z_m + v from the eye. In the paraxial (Fresnel) approximation the field the
lenslet sends into the eye's pupil plane factorises exactly (complete the square in the
two Fresnel kernels) into

    U(p) = exp(iπ|p − s′|²/(λL)) · Fr_{z_eff}[P](p − p_n),

the spherical wave of the CDP image point s′ — which the eye model already carries (the
eye's defocus is relative to the CDP; the view's direction is its display shift) — times the
Fresnel diffraction pattern of the lenslet aperture P magnified by M = L/v = 1 + z_m/v onto
the pupil (diameter M·a, centred on the geometric subaperture centre p_n) and propagated
over the effective distance z_eff = z_m·M. The Fresnel number N = (M a/2)²/(λ z_eff) =
(a/2)²/(λ z_m v/L) is the same in both planes. N → ∞ gives back the geometric subaperture
(the paper's ideal display); N ≲ 1 spreads each view over much of the pupil, and its phase
is then that of a source on the lenslet plane rather than on the CDP.

The paper's Eq. 2 keeps only the modulus |Fr[…]| of the pattern; ``diffraction="modulus"``
does that, ``"fresnel"`` (default) keeps the complex pattern, the physically complete
field (its phase is what makes a small lenslet look like a source at the lenslet plane).

The pattern is computed on the pupil window as a linear convolution with the Fresnel
impulse response, by FFT on a grid padded twice: the kernel is sampled in space where it is
resolved (far field) and as the analytic transfer function exp(−iπλz f²) where that is
(near field) — :func:`fresnel_transfer_1d` (Voelz & Roggemann 2009 give the criterion).
With diffraction on, every view's
window is the whole pupil (a diffracted beam is not confined to its subaperture), so a view
costs what the open pupil costs.

**Finite pixels.** An emitter of width w on the panel is an extended, incoherent source;
its image on the CDP subtends w/(z_0·M) rad at the eye (w/f for a collimating lenslet). Each
rendered OTF is multiplied by its transfer function sinc(a f_x)·sinc(a f_y) (a square
pixel aligned with the display axes, a in rad, f in cycles/rad). Width 0 changes nothing.

Reference: J. W. Goodman, *Introduction to Fourier Optics*, 4th ed. (2017), ch. 4–5
(Fresnel diffraction, the lens as a phase transformation); D. G. Voelz & M. C. Roggemann,
Appl. Opt. 48, 6132 (2009) (transfer-function versus impulse-response sampling).
"""

from __future__ import annotations

import dataclasses

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import as_real_array
from lfjax.base.types import is_concrete as _concrete
from lfjax.base.apertures import APERTURES, ApertureShape, aperture_shape
from lfjax.base.apertures import aperture_edge_distance as aperture_edge_distance
from lfjax.base.apertures import fresnel_propagate as fresnel_propagate
from lfjax.base.apertures import fresnel_transfer_1d as fresnel_transfer_1d
from lfjax.model.layouts import Layout
from lfjax.base.units import ARCMIN_PER_RADIAN
from lfjax.display.aberrations import LensletAberration

MAX_Y_DEFOCUS_D = 40.0
"""Largest |y_defocus_D| accepted, D (a near-eye lenticular's is about 28.5 D)."""


def _optional_real(value):
    """A float leaf, or None (the field's "nothing")."""
    return None if value is None else as_real_array(value)


def _check_optional(name: str, value, lo: float, hi: float, unit: str, why: str,
                    owner: str = "DisplayOptics") -> None:
    """Host check of an optional scalar field (skipped for None and traced values)."""
    if value is None or not _concrete(value):
        return
    v = np.asarray(value, float)
    if v.shape != ():
        raise ParameterError(name, "{%s} must be a scalar (%s), got shape {shape}" % (name, unit),
                             owner=owner, shape=v.shape)
    x = float(v)
    if not (math.isfinite(x) and lo <= x <= hi):
        raise ParameterError(name, "{%s} must be in [{lo:g}, {hi:g}] %s (%s), got {got}" % (name, unit, why),
                             owner=owner, lo=lo, hi=hi, got=x)

DIFFRACTION_MODES = ("off", "fresnel", "modulus")
APERTURE_SHAPES = tuple(APERTURES)
"""Every subaperture shape (:data:`lfjax.base.apertures.APERTURES`): circle, square, strip."""
SPHERICAL_APERTURE_SHAPES = tuple(n for n, a in APERTURES.items() if not a.spans_pupil_height)
"""The shapes a lenslet with power along both axes can have (a :class:`~lfjax.display.panel.Panel`'s);
a strip is a cylindrical lenticule's view (:class:`lfjax.display.lenticular.LenticularPanel`)."""
_CHOICES = {"aperture": APERTURE_SHAPES, "diffraction": DIFFRACTION_MODES}


def check_choices(owner: str, *, spherical: bool = False, **values: str) -> None:
    """Refuse a static option outside its choices (``aperture``: :data:`APERTURE_SHAPES`, or
    :data:`SPHERICAL_APERTURE_SHAPES` with ``spherical``; ``diffraction``:
    :data:`DIFFRACTION_MODES`), in the order given: ``ValueError``
    ``"Owner.name='value'; allowed: …"``."""
    for name, value in values.items():
        allowed = SPHERICAL_APERTURE_SHAPES if spherical and name == "aperture" else _CHOICES[name]
        if value not in allowed:
            why = ("" if value not in _CHOICES[name] else
                   " (a strip is a cylindrical lenticule's view: lfjax.display.lenticular.LenticularPanel)")
            raise ValueError(f"{owner}.{name}={value!r}; allowed: {', '.join(allowed)}{why}")


class DisplayOptics(eqx.Module):
    """What a real display adds to every view, as the pipeline needs it (all leaves arrays).

    Attributes
    ----------
    diffraction : str (static)
        ``"off"`` (geometric subapertures, the paper's ideal display), ``"fresnel"`` (the
        complex Fresnel pattern of each lenslet aperture) or ``"modulus"`` (its modulus, the
        paper's Eq. 2 read literally).
    aperture : str (static)
        Subaperture shape, one of :data:`APERTURE_SHAPES`: ``"circle"`` (diameter),
        ``"square"`` (side, axis-aligned) or ``"strip"`` (width along x, spanning the
        pupil's height: a lenticular view, diffracting along x only); applies to the
        geometric subapertures too (:attr:`shape`).
    fresnel_distance_mm : () effective propagation distance z_eff = z_m·M in pupil
        coordinates, mm (> 0; used when ``diffraction`` is on).
    pixel_width_arcmin : () angular width of one emitter's image on the CDP seen from the
        eye, arcmin (≥ 0; 0 = point emitters, the paper's ideal).
    aberration : :class:`lfjax.display.aberrations.LensletAberration` or None: the
        lenslets' wavefront error every view carries (None, or all zero: aberration-free
        lenslets, the numbers without it bit for bit).

    What a lenticular or leaky display does to its views (:mod:`lfjax.display.lenticular`;
    each None by default: nothing, the numbers without it bit for bit; 0 in
    :class:`lfjax.display.lenticular.ViewOptics`, whose leaves are then differentiable):

    y_defocus_D : () the views' extra defocus along y relative to x, D, in
        [−:data:`MAX_Y_DEFOCUS_D`, +:data:`MAX_Y_DEFOCUS_D`] (a lenticular beam), or None.
    leakage_weight : () weight of each neighbour's content in a view, in [0, 1], or None (0).
    neighbours : (n_views, n_views) 0/1 matrix of which views leak into which, or None.
    pixel_height_arcmin : () the emitter's angular height along y, arcmin (≥ 0), or None
        (its width: a square pixel).
    """

    diffraction: str = eqx.field(static=True, default="off")
    aperture: str = eqx.field(static=True, default="circle")
    fresnel_distance_mm: jnp.ndarray = eqx.field(converter=as_real_array, default=1.0)
    pixel_width_arcmin: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)
    aberration: LensletAberration | None = None
    y_defocus_D: jnp.ndarray | None = eqx.field(converter=_optional_real, default=None)
    leakage_weight: jnp.ndarray | None = eqx.field(converter=_optional_real, default=None)
    neighbours: jnp.ndarray | None = None
    pixel_height_arcmin: jnp.ndarray | None = eqx.field(converter=_optional_real, default=None)

    def __check_init__(self):
        check_choices("DisplayOptics", diffraction=self.diffraction, aperture=self.aperture)
        if self.aberration is not None and not isinstance(self.aberration, LensletAberration):
            raise ParameterError("aberration", "{aberration} must be a LensletAberration or None, got "
                                 "{got}", owner="DisplayOptics", got=type(self.aberration).__name__)
        if _concrete(self.fresnel_distance_mm, self.pixel_width_arcmin):
            z = np.asarray(self.fresnel_distance_mm, float)
            w = np.asarray(self.pixel_width_arcmin, float)
            if z.shape != () or w.shape != ():
                raise ValueError("DisplayOptics.fresnel_distance_mm and pixel_width_arcmin must be scalars")
            if not (np.isfinite(z) and z > 0):
                raise ValueError(f"fresnel_distance_mm must be finite and > 0 mm, got {float(z)}")
            if not (np.isfinite(w) and w >= 0):
                raise ParameterError("pixel_width_arcmin",
                                     "{pixel_width_arcmin} must be finite and >= 0 arcmin, got {got}",
                                     got=float(w))
        _check_optional("y_defocus_D", self.y_defocus_D, -MAX_Y_DEFOCUS_D, MAX_Y_DEFOCUS_D, "D",
                        "the views' extra defocus along y", type(self).__name__)
        _check_optional("leakage_weight", self.leakage_weight, 0.0, 1.0, "unitless",
                        "each neighbour's weight in a view; 0 = no leakage", type(self).__name__)
        _check_optional("pixel_height_arcmin", self.pixel_height_arcmin, 0.0, math.inf, "arcmin",
                        "the emitter's angular height along y", type(self).__name__)
        if self.neighbours is not None and _concrete(self.neighbours):
            a = np.asarray(self.neighbours, float)
            if a.ndim != 2 or a.shape[0] != a.shape[1] or not np.all((a == 0) | (a == 1)):
                raise ParameterError("neighbours", "{neighbours} must be a square 0/1 matrix "
                                     "(n_views, n_views), got shape {shape}", owner=type(self).__name__,
                                     shape=a.shape)

    @property
    def diffracts(self) -> bool:
        return self.diffraction != "off"

    @property
    def pixel_width_rad(self):
        return self.pixel_width_arcmin / ARCMIN_PER_RADIAN

    @property
    def pixel_height_rad(self):
        """The emitter's angular height (rad): ``pixel_height_arcmin``, or its width (a
        square pixel imaged by a lenslet with power along both axes; a lenticular view's
        differs: its lenticule has none along y)."""
        if self.pixel_height_arcmin is None:
            return self.pixel_width_rad
        return self.pixel_height_arcmin / ARCMIN_PER_RADIAN

    @property
    def shape(self) -> ApertureShape:
        """The declared :class:`~lfjax.base.apertures.ApertureShape` of ``aperture``."""
        return aperture_shape(self.aperture)

    @property
    def strips(self) -> bool:
        """The views are strips spanning the pupil's height (a lenticular display): lenslet
        diffraction acts along x only."""
        return self.shape.spans_pupil_height

    @property
    def fills_pupil(self) -> bool:
        """A view's light may reach any point of the pupil (diffracted beams, or strips
        along y): each view is computed on a window the pupil's size."""
        return self.diffracts or self.strips

    def window_x_mm(self, widest_mm: float, pupil_diameter_mm: float) -> float | None:
        """Width (mm) of every view's numerical window along x where it is narrower than
        along y, or None (square windows): the shape's rule
        (:meth:`~lfjax.base.apertures.ApertureShape.window_x_mm`, ``widest_mm`` the widest
        view, mm), except that diffracted beams fill the pupil both ways."""
        if self.diffracts:
            return None
        return self.shape.window_x_mm(widest_mm, pupil_diameter_mm)

    def beam_wavefront_um(self, zernike_um, measured_pupil_mm: float):
        """The eye's coefficients (…, n_modes) µm plus the views' common astigmatism
        W = Δ·y²/2 (µm, y in mm; Zernike c(2,0) += Δ R²/(8√3), c(2,2) −= Δ R²/(4√6) on the
        measured radius R; at least 6 modes returned); unchanged without ``y_defocus_D``."""
        if self.y_defocus_D is None:
            return zernike_um
        if zernike_um.shape[-1] < 6:
            zernike_um = jnp.pad(zernike_um, [(0, 0)] * (zernike_um.ndim - 1)
                                 + [(0, 6 - zernike_um.shape[-1])])
        r2 = (0.5 * measured_pupil_mm) ** 2
        delta = self.y_defocus_D.astype(zernike_um.dtype)
        return (zernike_um.at[..., 4].add(delta * (r2 / (8.0 * math.sqrt(3.0))))
                .at[..., 5].add(delta * (-r2 / (4.0 * math.sqrt(6.0)))))

    @property
    def view_mixing(self):
        """K (n, n): view n carries Σ_m K[n, m]·(view m's content), rows summing to 1
        (K = (I + w·A)/(1 + w·Σ_m A[n, m]), A the neighbours); None without ``neighbours``."""
        if self.neighbours is None:
            return None
        w = jnp.asarray(0.0) if self.leakage_weight is None else self.leakage_weight
        a = jnp.asarray(self.neighbours, w.dtype)
        k = jnp.eye(a.shape[0], dtype=a.dtype) + w * a
        return k / (1.0 + w * jnp.sum(a, axis=1))[:, None]

    def fresnel_number(self, diameter_mm, wavelength_nm):
        """N = (d/2)²/(λ z_eff) of a subaperture of ``diameter_mm`` (mm) at ``wavelength_nm``."""
        return (0.5 * diameter_mm) ** 2 / (wavelength_nm * 1e-6 * self.fresnel_distance_mm)

    def checked(self) -> DisplayOptics:
        """Traced-value checks (``eqx.error_if``) for use inside the pipeline."""
        z = eqx.error_if(self.fresnel_distance_mm,
                         ~(jnp.isfinite(self.fresnel_distance_mm) & (self.fresnel_distance_mm > 0)),
                         "fresnel_distance_mm must be finite and > 0 mm")
        w = eqx.error_if(self.pixel_width_arcmin,
                         ~(jnp.isfinite(self.pixel_width_arcmin) & (self.pixel_width_arcmin >= 0)),
                         "pixel_width_arcmin must be finite and >= 0 arcmin")
        aberration = None if self.aberration is None else self.aberration.checked()
        y, leak, height = self.y_defocus_D, self.leakage_weight, self.pixel_height_arcmin
        if y is not None:
            y = eqx.error_if(y, ~(jnp.abs(y) <= MAX_Y_DEFOCUS_D),
                             f"y_defocus_D must be in [-{MAX_Y_DEFOCUS_D:g}, {MAX_Y_DEFOCUS_D:g}] D")
        if leak is not None:
            leak = eqx.error_if(leak, ~((leak >= 0) & (leak <= 1)), "leakage_weight must be in [0, 1]")
        if height is not None:
            height = eqx.error_if(height, ~(jnp.isfinite(height) & (height >= 0)),
                                  "pixel_height_arcmin must be finite and >= 0 arcmin")
        return dataclasses.replace(self, fresnel_distance_mm=z, pixel_width_arcmin=w,
                                   aberration=aberration, y_defocus_D=y, leakage_weight=leak,
                                   pixel_height_arcmin=height)

    def aberration_slope_rad(self, diameters_mm) -> float:
        """Host bound on the lenslet aberration's ray angle (rad) over views of
        ``diameters_mm`` (mm; the smallest decides); 0 without an aberration."""
        if self.aberration is None:
            return 0.0
        d = float(np.min(np.asarray(diameters_mm, float)))
        return self.aberration.slope_rad(0.5 * d, self.aperture)

    def with_aberration(self, aberration: LensletAberration | None) -> DisplayOptics:
        """This display (of its own class: a lenticular display keeps its views' fields)
        with the lenslets' ``aberration`` (None: aberration-free)."""
        return dataclasses.replace(self, aberration=aberration)


def ideal_display() -> DisplayOptics:
    """The paper's ideal display: geometric circular subapertures, point emitters."""
    return DisplayOptics()


def __getattr__(name: str):
    # IDEAL_DISPLAY is built on first use, not at import: its leaves are JAX arrays, and
    # creating one starts JAX's backend, after which jax.distributed.initialize refuses
    # (``lfjax sweep --distributed`` imports lfjax first).
    if name == "IDEAL_DISPLAY":
        return ideal_display()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _check_positive(name: str, value, allow_inf: bool = False) -> None:
    if not _concrete(value):
        return
    v = np.asarray(value, float)
    ok = (v > 0) & (np.isfinite(v) | (allow_inf & np.isposinf(v)))
    if not np.all(ok):
        extra = " (inf for a pinhole or barrier: no lens)" if allow_inf else ""
        raise ValueError(f"{name} must be > 0 mm{extra}, got {v.ravel().tolist()}")


class LensletArray(eqx.Module):
    """A lenslet (or pinhole) array in front of a pixel panel: the display's physical optics.

    Attributes (mm; every float a differentiable leaf)
    ----------
    pitch_mm : () lenslet pitch Δu on the modulation plane
    aperture_mm : () lenslet aperture: diameter (circle) or side (square), ≤ pitch
    focal_length_mm : () focal length f (> 0; ``inf`` for a pinhole or barrier)
    gap_mm : () panel–lenslet distance z_0, ≤ f (the CDP is a virtual image behind the
        display, or at infinity when z_0 = f)
    distance_mm : () eye pupil–lenslet distance z_m
    aperture : one of :data:`APERTURE_SHAPES` (static): ``"circle"`` or ``"square"``
        (spherical lenslets), or ``"strip"``: cylindrical lenticules with power along x
        only (a lenticular sheet, :class:`lfjax.display.lenticular.LenticularPanel`), the
        aperture its width along x
    diffraction : "fresnel" or "modulus" (static, see :class:`DisplayOptics`)

    All derived quantities are written with the image vergence V = 1/z_0 − 1/f (1/mm), so a
    collimating lenslet (V = 0, CDP at infinity) needs no special case. Along x every shape
    has the same thin-lens geometry; along y a strip's lenticule has none (:attr:`y_defocus_D`,
    :meth:`pixel_height_arcmin`).
    """

    pitch_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    aperture_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    focal_length_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    gap_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    distance_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    aperture: str = eqx.field(static=True, default="circle")
    diffraction: str = eqx.field(static=True, default="fresnel")

    def __check_init__(self):
        check_choices("LensletArray", aperture=self.aperture, diffraction=self.diffraction)
        _check_positive("pitch_mm", self.pitch_mm)
        _check_positive("aperture_mm", self.aperture_mm)
        _check_positive("focal_length_mm", self.focal_length_mm, allow_inf=True)
        _check_positive("gap_mm", self.gap_mm)
        _check_positive("distance_mm", self.distance_mm)
        if _concrete(self.pitch_mm, self.aperture_mm, self.focal_length_mm, self.gap_mm):
            if float(self.aperture_mm) > float(self.pitch_mm) * (1 + 1e-9):
                raise ValueError(
                    f"aperture_mm={float(self.aperture_mm):g} must be <= pitch_mm={float(self.pitch_mm):g} "
                    "(lenslet apertures cannot overlap)"
                )
            if float(self.gap_mm) > float(self.focal_length_mm) * (1 + 1e-12):
                raise ValueError(
                    f"gap_mm={float(self.gap_mm):g} must be <= focal_length_mm="
                    f"{float(self.focal_length_mm):g}: the CDP is then a virtual image behind the "
                    "display (or at infinity); the real-image mode is not modelled"
                )

    @property
    def image_vergence_per_mm(self):
        """V = 1/z_0 − 1/f, 1/mm (0: collimated, CDP at infinity)."""
        return 1.0 / self.gap_mm - 1.0 / self.focal_length_mm

    @property
    def magnification(self):
        """M = L/v = 1 + z_m·V: lenslet plane → pupil plane scale of pitch and aperture."""
        return 1.0 + self.distance_mm * self.image_vergence_per_mm

    @property
    def cdp_D(self):
        """Central depth plane 1/L (D), L = z_m + v from the eye."""
        v_per_mm = self.image_vergence_per_mm
        return 1000.0 * v_per_mm / (1.0 + self.distance_mm * v_per_mm)

    @property
    def shape(self) -> ApertureShape:
        """The declared :class:`~lfjax.base.apertures.ApertureShape` of ``aperture``."""
        return aperture_shape(self.aperture)

    @property
    def panel_D(self):
        """Vergence of the pixel plane at the eye, 1000/(z_m + z_0) D: what focuses a beam
        along an axis where the lenslet has no power."""
        return 1000.0 / (self.distance_mm + self.gap_mm)

    @property
    def y_defocus_D(self):
        """The views' extra defocus along y relative to x, D: CDP − :attr:`panel_D` for
        lenticules (a strip: no power along y, the beam keeps the pixel's divergence there;
        ≤ 0 for z_0 ≤ f), 0 for spherical lenslets."""
        if self.shape.spans_pupil_height:
            return self.cdp_D - self.panel_D
        return jnp.zeros_like(self.cdp_D)

    @property
    def subaperture_pitch_mm(self):
        """Spacing of the views in the pupil, M·Δu (paper Eq. 1 at the CDP), mm."""
        return self.magnification * self.pitch_mm

    @property
    def subaperture_diameter_mm(self):
        """Geometric subaperture in the pupil, M·a (diameter or side), mm."""
        return self.magnification * self.aperture_mm

    @property
    def fresnel_distance_mm(self):
        """z_eff = z_m·M, the distance over which the magnified aperture diffracts, mm."""
        return self.distance_mm * self.magnification

    def fresnel_number(self, wavelength_nm=550.0):
        """(a/2)²·M²/(λ z_eff) of one lenslet (unitless; large = geometric)."""
        return (0.5 * self.subaperture_diameter_mm) ** 2 / (wavelength_nm * 1e-6 * self.fresnel_distance_mm)

    def pixel_width_arcmin(self, pixel_pitch_mm, fill_factor=1.0):
        """Angular width (arcmin) of one emitter's image on the CDP, seen from the eye.

        ``pixel_pitch_mm`` (mm) on the panel; ``fill_factor`` the emitting fraction of the
        pixel's area (square emitter of side pitch·√fill). Width w/(z_0·M) rad.
        """
        width = pixel_pitch_mm * jnp.sqrt(fill_factor)
        return width / (self.gap_mm * self.magnification) * ARCMIN_PER_RADIAN

    def pixel_height_arcmin(self, pixel_pitch_mm, fill_factor=1.0):
        """Angular height (arcmin) of one emitter seen from the eye: its image on the CDP,
        as :meth:`pixel_width_arcmin`, for spherical lenslets; for lenticules (a strip, no
        power along y) the pixel itself, w/(z_m + z_0) rad."""
        if not self.shape.spans_pupil_height:
            return self.pixel_width_arcmin(pixel_pitch_mm, fill_factor)
        width = pixel_pitch_mm * jnp.sqrt(fill_factor)
        return width / (self.distance_mm + self.gap_mm) * ARCMIN_PER_RADIAN

    def optics(self, pixel_pitch_mm=0.0, fill_factor=1.0, diffraction: str | None = None) -> DisplayOptics:
        """The :class:`DisplayOptics` of this array (pixels of ``pixel_pitch_mm``, mm, and
        area ``fill_factor``; 0 mm: point emitters). ``diffraction`` overrides the array's."""
        if _concrete(pixel_pitch_mm, fill_factor, self.pitch_mm):
            p, f = float(np.asarray(pixel_pitch_mm)), float(np.asarray(fill_factor))
            if not (math.isfinite(p) and p >= 0):
                raise ValueError(f"pixel_pitch_mm must be finite and >= 0 mm, got {p}")
            if p > float(self.pitch_mm) * (1 + 1e-9):
                raise ValueError(
                    f"pixel_pitch_mm={p:g} is larger than the lenslet pitch_mm={float(self.pitch_mm):g}: "
                    "each lenslet needs at least one pixel behind it (allowed 0 <= pixel_pitch_mm <= pitch_mm)"
                )
            if not (0 < f <= 1):
                raise ValueError(f"fill_factor must be in (0, 1] (emitting area fraction), got {f}")
        width = self.pixel_width_arcmin(pixel_pitch_mm, fill_factor)
        if not self.shape.spans_pupil_height:
            return DisplayOptics(self.diffraction if diffraction is None else diffraction,
                                 self.aperture, self.fresnel_distance_mm, width)
        return DisplayOptics(self.diffraction if diffraction is None else diffraction,
                             self.aperture, self.fresnel_distance_mm, width,
                             y_defocus_D=self.y_defocus_D,
                             pixel_height_arcmin=self.pixel_height_arcmin(pixel_pitch_mm, fill_factor))

    def layout(self, pupil_diameter_mm: float, n_per_side: int, offset_mm=(0.0, 0.0),
               name: str | None = None) -> Layout:
        """The n×n views nearest the pupil centre (1×n side by side along x for strips,
        which span the pupil's height): centres M·Δu apart shifted by ``offset_mm`` (mm),
        diameters M·a (a side for square apertures, a width for strips). Differentiable in
        the array's parameters; the numerical window is the pupil (what diffraction needs)."""
        n = int(n_per_side)
        if n != n_per_side or n < 1:
            raise ValueError(f"n_per_side must be an integer >= 1, got {n_per_side}")
        k = jnp.arange(n, dtype=jnp.result_type(float)) - (n - 1) / 2.0
        if self.shape.spans_pupil_height:
            xx, yy, label = k, jnp.zeros_like(k), f"1x{n} lenticules"
        else:
            xx, yy = jnp.meshgrid(k, k)
            label = f"{n}x{n} lenslets"
        centres = jnp.stack([xx.ravel(), yy.ravel()], axis=1) * self.subaperture_pitch_mm
        centres = centres + jnp.asarray(offset_mm, centres.dtype)
        diameters = jnp.full((centres.shape[0],), 1.0, centres.dtype) * self.subaperture_diameter_mm
        return Layout(centres, diameters, float(pupil_diameter_mm), name or label)


def lenslets_for_layout(n_per_side: int, pupil_diameter_mm: float, cdp_D: float, distance_mm: float,
                        fill: float = 1.0, f_number: float = 3.0, aperture: str = "circle",
                        diffraction: str = "fresnel") -> LensletArray:
    """The lenslet array at ``distance_mm`` (mm) from the eye that puts n×n tangent views in
    a pupil of ``pupil_diameter_mm`` (the paper's layouts: view pitch pupil/n) with its CDP
    at ``cdp_D`` (D; the CDP lies behind the display, so cdp_D < 1000/distance_mm).
    ``fill`` = aperture/pitch (linear); ``f_number`` = f/aperture sets the focal length and
    gap (optically only V = 1/z_0 − 1/f matters for the views; the gap sets the pixels'
    angular size)."""
    if not (cdp_D >= 0):
        raise ValueError(f"cdp_D must be >= 0 D, got {cdp_D}")
    if cdp_D * distance_mm >= 1000.0:
        raise ValueError(
            f"cdp_D={cdp_D:g} D puts the CDP in front of a display at {distance_mm:g} mm: "
            f"need cdp_D < {1000.0 / distance_mm:.4g} D (a virtual image behind the display)"
        )
    # 1/L = V/(1 + z_m V) → V = (1/L)/(1 − z_m/L)
    inv_l = cdp_D / 1000.0
    vergence = inv_l / (1.0 - distance_mm * inv_l)
    magnification = 1.0 + distance_mm * vergence
    pitch = pupil_diameter_mm / n_per_side / magnification
    focal = f_number * fill * pitch
    gap = 1.0 / (vergence + 1.0 / focal)
    return LensletArray(pitch, fill * pitch, focal, gap, distance_mm, aperture, diffraction)


def display_optics_at(distance_mm: float, cdp_D: float, pixel_width_arcmin: float = 0.0,
                      diffraction: str = "fresnel", aperture: str = "circle") -> DisplayOptics:
    """The :class:`DisplayOptics` of any lenslet array at ``distance_mm`` (mm, eye pupil to
    lenslets) whose CDP lies at ``cdp_D`` (D): its Fresnel distance z_m·M with
    M = L/(L − z_m), L = 1000/cdp_D mm, depends on neither the lenslets' size nor their
    pitch, so one DisplayOptics serves every layout such an array can make (the layout
    optimiser's and the sweep's). ``pixel_width_arcmin``: the emitters' angular width."""
    if not (math.isfinite(distance_mm) and distance_mm > 0):
        raise ParameterError("distance_mm", "{distance_mm} (the display distance) must be > 0 mm, "
                             "got {got}", got=distance_mm)
    if not (math.isfinite(cdp_D) and cdp_D >= 0):
        raise ParameterError("cdp_D", "{cdp_D} must be >= 0 D, got {got}", got=cdp_D)
    if cdp_D * distance_mm >= 1000.0:
        raise ParameterError(
            "distance_mm", "a display at {distance_mm} = {zm:g} mm cannot put its CDP at {cdp_D} = "
            "{cdp:g} D: the CDP is a virtual image behind the display, so the distance must be "
            "< {top:.4g} mm", zm=distance_mm, cdp=cdp_D, top=1000.0 / cdp_D)
    magnification = 1.0 / (1.0 - distance_mm * cdp_D / 1000.0)
    return DisplayOptics(diffraction, aperture, distance_mm * magnification, pixel_width_arcmin)


def pixel_transfer(fx_cpr, fy_cpr, display: DisplayOptics | None):
    """OTF of one emitter (a rectangle ``display.pixel_width_rad`` wide along x and
    ``display.pixel_height_rad`` high along y: a square for a spherical lenslet) at
    frequencies in cycles/radian, broadcast (…, L) × (…, Lx); 1 without a display."""
    if display is None:
        return 1.0
    return (jnp.sinc(display.pixel_height_rad * fy_cpr)[:, None]
            * jnp.sinc(display.pixel_width_rad * fx_cpr)[None, :])


__all__ = [
    "DisplayOptics",
    "IDEAL_DISPLAY",
    "ideal_display",
    "LensletArray",
    "lenslets_for_layout",
    "display_optics_at",
    "pixel_transfer",
    "DIFFRACTION_MODES",
    "APERTURE_SHAPES",
    "SPHERICAL_APERTURE_SHAPES",
    "check_choices",
]
