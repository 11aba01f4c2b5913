"""Lenticular (horizontal-parallax-only) displays and cross-talk between views.

**The beam of one lenticular view.** A lenticular sheet is an array of cylindrical
lenslets with power along x only, at z_m from the eye, in front of a pixel panel at the
(air-equivalent) gap z_0: a substrate of thickness t and index n counts as t/n. Along x a
pixel is imaged as by a spherical lenslet (:mod:`lfjax.display.lenslets`): to the CDP, a
virtual image v = 1/V behind the lenslets (V = 1/z_0 − 1/f), so its rays reach the pupil
with the vergence of the CDP, 1000/(z_m + v) D; the view is a strip M·a wide (M = 1 + z_m·V,
a the lenslet aperture) centred on its view position, and it carries the x parallax of
the rendered point. Along y the lenslet has no power: the light keeps the divergence of the
pixel itself, 1000/(z_m + z_0) D, and no lenslet edge limits it, so the strip spans the
pupil's height, and no view is displaced along y (every view shows the point at the panel's
height). Each view's beam is therefore astigmatic: relative to a beam focused on the CDP in
both directions its wavefront has the extra term

    W(x, y) = Δ·y²/2 µm (y in mm),  Δ = CDP − 1000/(z_m + z_0)  D  (≤ 0 for z_0 ≤ f),

the same for every view, so it is carried as a fixed astigmatic wavefront added to the
eye's (:meth:`ViewOptics.beam_wavefront_um`; Zernike c(2,0) += Δ R²/(8√3), c(2,2) −= Δ R²/(4√6)
on the eyes' measured radius R). Lenslet diffraction acts along x only: the strip's edge
field is Fresnel-propagated across the strip, not along it.

**Leakage.** A view's light also carries a weighted copy of its neighbours' content
(pixel cross-talk on the panel, light spilling into the neighbouring elemental image,
imperfect view separation). Through the subaperture of view n the eye then sees, besides
view n's image of a point rendered at depth d, view m's image of it: the pixel that renders
the point for view m lies where the line from view m's pupil position p_m through the point
meets the CDP, so seen from p_n it is displaced by exactly view m's parallax shift
(d − CDP)·p_m. With weight w and N_n neighbours, view n carries (content_n +
w Σ_neighbours content_m)/(1 + w N_n): its energy is unchanged, w = 0 is the ideal display and
w = 1 mixes each view equally with its neighbours. (A pixel seen through the *adjacent*
lenslet reaches the pupil one eye box, Δu(1 + z_m/z_0), away: :meth:`LenticularPanel.eye_box_mm`;
inside a 3 mm pupil only when the eye box is below the pupil plus a view.)
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import as_real_array
from lfjax.base.types import is_concrete as _concrete
from lfjax.base.apertures import STRIP
from lfjax.display.lenslets import MAX_Y_DEFOCUS_D, DisplayOptics, LensletArray
from lfjax.model.layouts import Layout
from lfjax.model.strips import neighbour_matrix, strip_layout


class ViewOptics(DisplayOptics):
    """:class:`~lfjax.display.lenslets.DisplayOptics` whose lenticular and leakage fields
    (declared there: ``y_defocus_D``, ``leakage_weight``, ``neighbours``,
    ``pixel_height_arcmin``) default to 0 instead of None, so that the y defocus and the
    leakage weight are differentiable leaves (0 changes nothing: the numbers of the display
    without them, bit for bit).

    Attributes (as DisplayOptics')
    ----------
    y_defocus_D : () the views' extra defocus along y relative to x, D, in
        [−:data:`MAX_Y_DEFOCUS_D`, +:data:`MAX_Y_DEFOCUS_D`] (a lenticular beam:
        CDP − panel-plane vergence; module docstring). 0: no astigmatism.
    leakage_weight : () weight of each neighbour's content in a view, in [0, 1] (unitless).
    neighbours : (n_views, n_views) 0/1 matrix of which views leak into which
        (:func:`lfjax.model.strips.neighbour_matrix`), or None (no leakage path at all).
    pixel_height_arcmin : () the emitter's angular height along y, arcmin (≥ 0), or None
        (default: its width, a square pixel). A lenticule has no power along y, so there the
        eye sees the pixel itself, p/(z_m + z_0), not its image on the CDP, p/(z_0·M)
        (:meth:`LenticularPanel.pixel_height_arcmin`).
    """

    y_defocus_D: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)
    leakage_weight: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)


def strip_display(layout: Layout | None = None, *, y_defocus_D=0.0, leakage_weight=0.0,
                  aperture: str = STRIP.name, diffraction: str = "off", fresnel_distance_mm=1.0,
                  pixel_width_arcmin=0.0, pixel_height_arcmin=None) -> ViewOptics:
    """The :class:`ViewOptics` of a layout: strips (``aperture="strip"``, the default) or
    circles, with the views' y defocus (D) and leakage weight; the neighbours are the
    layout's (:func:`~lfjax.model.strips.neighbour_matrix`), or none without a layout;
    ``pixel_height_arcmin``: the emitter's height along y (None: its width)."""
    neighbours = None if layout is None else jnp.asarray(neighbour_matrix(layout))
    return ViewOptics(diffraction, aperture, fresnel_distance_mm, pixel_width_arcmin,
                      y_defocus_D=y_defocus_D, leakage_weight=leakage_weight,
                      neighbours=neighbours, pixel_height_arcmin=pixel_height_arcmin)


def check_display_for_layout(display: DisplayOptics | None, layout: Layout, *,
                             parameter: str = "display", path: str = "") -> None:
    """A display's neighbour matrix (a strip display's, :func:`strip_display`) must have one
    row per view of ``layout``: one built for another layout would mix the wrong views (or
    fail inside the compiled program). Shapes only, so it holds for traced arrays too.

    A refused display is a :class:`~lfjax.base.errors.ParameterError` naming ``parameter``
    (the entry point's name of the display; ``path`` is appended to it, e.g.
    ``parameter="viewing", path=".display"``), the views it was built for and the layout's.
    The one check of that concept: every entry point that takes a display with a layout
    (:func:`lfjax.vision.prepare.prepare`, :func:`lfjax.vision.peaks.accommodation_peaks`,
    the planner's :class:`~lfjax.planner.scene.PlanScene`, the layout optimiser's
    problem) calls it."""
    a = None if display is None else display.neighbours
    n = int(np.shape(layout.diameters_mm)[0])
    if a is not None and np.shape(a)[0] != n:
        raise ParameterError(
            parameter, "{%s}%s is a strip display built for %d views (its neighbours matrix "
            "has %d rows), but layout {name!r} has {n} views: build it with "
            "strip_display(layout, ...) for that layout" % (parameter, path, np.shape(a)[0],
                                                             np.shape(a)[0]),
            name=getattr(layout, "name", "custom"), n=n)


class LenticularPanel(eqx.Module):
    """A pixel panel behind a cylindrical-lenslet (lenticular) sheet, at a viewing distance.

    Attributes (mm unless stated; every float a differentiable leaf)
    ----------
    pixel_pitch_mm : () panel pixel pitch
    lens_pitch_mm : () lenticule pitch Δu along x
    fill : () lenticule aperture / pitch, (0, 1]
    focal_length_mm : () focal length f of a lenticule (power along x only)
    gap_mm : () air-equivalent panel–lenticule distance z_0, (0, f]
    distance_mm : () eye pupil–lenticule distance z_m
    leakage_weight : () neighbouring views' content in each view, [0, 1]
    """

    pixel_pitch_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    lens_pitch_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    fill: jnp.ndarray = eqx.field(converter=as_real_array)
    focal_length_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    gap_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    distance_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    leakage_weight: jnp.ndarray = eqx.field(converter=as_real_array, default=0.0)

    def __check_init__(self):
        for name in ("pixel_pitch_mm", "lens_pitch_mm", "focal_length_mm", "gap_mm", "distance_mm"):
            v = getattr(self, name)
            if _concrete(v) and not (np.isfinite(float(v)) and float(v) > 0):
                raise ParameterError(name, "{%s} must be finite and > 0 mm, got {got}" % name,
                                     owner="LenticularPanel", got=float(v))
        if _concrete(self.fill) and not (0 < float(self.fill) <= 1):
            raise ParameterError("fill", "{fill} must be in (0, 1] (aperture / pitch), got {got}",
                                 owner="LenticularPanel", got=float(self.fill))
        if _concrete(self.gap_mm, self.focal_length_mm) and float(self.gap_mm) > float(self.focal_length_mm) * (1 + 1e-9):
            raise ParameterError("gap_mm", "{gap_mm} must be in (0, {f:g}] mm (at most the focal "
                                 "length: the CDP is then a virtual image), got {got:g}",
                                 owner="LenticularPanel", f=float(self.focal_length_mm),
                                 got=float(self.gap_mm))
        if _concrete(self.leakage_weight) and not (0 <= float(self.leakage_weight) <= 1):
            raise ParameterError("leakage_weight", "{leakage_weight} must be in [0, 1] "
                                 "(unitless), got {got}", owner="LenticularPanel",
                                 got=float(self.leakage_weight))

    @classmethod
    def with_cdp(cls, cdp_D: float, *, pixel_pitch_mm: float, lens_pitch_mm: float,
                 focal_length_mm: float, distance_mm: float, fill: float = 1.0,
                 leakage_weight: float = 0.0) -> LenticularPanel:
        """The gap that puts the CDP (along x) at ``cdp_D`` D: 1/z_0 = 1/f + 1/(L − z_m)."""
        length = 1000.0 / cdp_D if cdp_D > 0 else math.inf
        if not length > distance_mm:
            raise ParameterError("cdp_D", "{cdp_D} must be below {hi:g} D (the CDP lies behind "
                                 "the display, {d:g} mm away), got {got:g}", hi=1000.0 / distance_mm,
                                 d=distance_mm, got=cdp_D)
        v = length - distance_mm
        gap = 1.0 / (1.0 / focal_length_mm + (0.0 if math.isinf(v) else 1.0 / v))
        return cls(pixel_pitch_mm, lens_pitch_mm, fill, focal_length_mm, gap, distance_mm,
                   leakage_weight)

    @property
    def lenslets(self) -> LensletArray:
        """The sheet's thin-lens geometry: a :class:`~lfjax.display.lenslets.LensletArray` of
        strip apertures (cylindrical lenticules, aperture fill·Δu along x), whose numbers
        every derived quantity below is."""
        return LensletArray(self.lens_pitch_mm, self.fill * self.lens_pitch_mm,
                            self.focal_length_mm, self.gap_mm, self.distance_mm, STRIP.name)

    @property
    def image_vergence_per_mm(self):
        """V = 1/z_0 − 1/f, 1/mm (0: the CDP at infinity)."""
        return self.lenslets.image_vergence_per_mm

    @property
    def magnification(self):
        """M = 1 + z_m·V: a lenticule's aperture is M times wider in the pupil."""
        return self.lenslets.magnification

    @property
    def cdp_D(self):
        """The CDP along x, D: 1000·V/(1 + z_m V)."""
        return self.lenslets.cdp_D

    @property
    def panel_D(self):
        """Vergence of the pixel plane at the eye (what focuses the beam along y), D."""
        return self.lenslets.panel_D

    @property
    def y_defocus_D(self):
        """Δ = CDP − panel vergence, D: the views' extra defocus along y."""
        return self.lenslets.y_defocus_D

    @property
    def view_pitch_mm(self):
        """Spacing of the strips in the pupil, M·Δu, mm."""
        return self.lenslets.subaperture_pitch_mm

    @property
    def view_width_mm(self):
        """Width of each strip in the pupil, M·fill·Δu, mm."""
        return self.lenslets.subaperture_diameter_mm

    @property
    def fresnel_distance_mm(self):
        """z_eff = z_m·M, the distance over which a strip's edge diffracts, mm."""
        return self.lenslets.fresnel_distance_mm

    def eye_box_mm(self):
        """Δu(1 + z_m/z_0): where a pixel seen through the adjacent lenticule lands, mm."""
        return self.lens_pitch_mm * (1.0 + self.distance_mm / self.gap_mm)

    def pixel_arcmin(self):
        """One pixel's image on the CDP along x, arcmin: p/(z_0·M)."""
        return self.lenslets.pixel_width_arcmin(self.pixel_pitch_mm)

    def pixel_height_arcmin(self):
        """One pixel along y, arcmin: the lenticule has no power there, so the eye sees the
        pixel itself, p/(z_m + z_0) (about 1/45 of :meth:`pixel_arcmin` for the phone)."""
        return self.lenslets.pixel_height_arcmin(self.pixel_pitch_mm)

    def views_across(self, pupil_diameter_mm: float) -> int:
        """Whole strips across the pupil (host), ⌊D/(M·Δu)⌋, at least 1 required."""
        n = int(math.floor(float(pupil_diameter_mm) / float(self.view_pitch_mm) + 1e-9))
        if n < 1:
            raise ParameterError("lens_pitch_mm", "{lens_pitch_mm} gives views {w:.3g} mm apart "
                                 "in the pupil, wider than the {p:g} mm pupil: fewer than one "
                                 "view across it", owner="LenticularPanel",
                                 w=float(self.view_pitch_mm), p=float(pupil_diameter_mm))
        return n

    def layout(self, pupil_diameter_mm: float = 3.0) -> Layout:
        """The strips this panel puts in a pupil centred on its views (host)."""
        n = self.views_across(pupil_diameter_mm)
        return strip_layout(n, pupil_diameter_mm, pitch_mm=float(self.view_pitch_mm),
                            width_mm=float(self.view_width_mm), name=f"lenticular 1x{n}")

    def optics(self, layout: Layout, diffraction: str = "off") -> ViewOptics:
        """The pipeline's :class:`ViewOptics` for ``layout`` (usually :meth:`layout`)."""
        return strip_display(layout, y_defocus_D=self.y_defocus_D,
                             leakage_weight=self.leakage_weight, diffraction=diffraction,
                             fresnel_distance_mm=self.fresnel_distance_mm,
                             pixel_width_arcmin=self.pixel_arcmin(),
                             pixel_height_arcmin=self.pixel_height_arcmin())


def lenticular_phone(distance_mm: float = 350.0, cdp_D: float = 2.0,
                     lens_pitch_mm: float = 0.45, focal_length_mm: float = 3.0,
                     leakage_weight: float = 0.0) -> LenticularPanel:
    """The phone preset (:func:`lfjax.display.panel.phone_panel`: 460 ppi, lenslets 0.45 mm
    pitch, f = 3 mm, 350 mm away, CDP 2 D) with cylindrical lenslets: Δ ≈ −0.83 D."""
    return LenticularPanel.with_cdp(cdp_D, pixel_pitch_mm=25.4 / 460.0, lens_pitch_mm=lens_pitch_mm,
                                    focal_length_mm=focal_length_mm, distance_mm=distance_mm,
                                    leakage_weight=leakage_weight)


def lenticular_near_eye(distance_mm: float = 30.0, cdp_D: float = 1.5,
                        lens_pitch_mm: float = 1.0, focal_length_mm: float = 3.3) -> LenticularPanel:
    """The near-eye preset (:func:`lfjax.display.panel.near_eye_microdisplay`) with cylindrical
    lenslets: Δ ≈ −28.5 D, far beyond any accommodation (vertical structure never focuses)."""
    return LenticularPanel.with_cdp(cdp_D, pixel_pitch_mm=0.7 * 25.4 / math.hypot(1920, 1080),
                                    lens_pitch_mm=lens_pitch_mm, focal_length_mm=focal_length_mm,
                                    distance_mm=distance_mm)


__all__ = [
    "ViewOptics",
    "strip_display",
    "check_display_for_layout",
    "LenticularPanel",
    "lenticular_phone",
    "lenticular_near_eye",
    "MAX_Y_DEFOCUS_D",
]
