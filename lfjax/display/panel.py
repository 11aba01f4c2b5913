"""The display as built: a pixel panel behind a lenslet array, at a viewing distance.

A display maker chooses a panel (pixel pitch and count), a lenslet array (pitch, fill,
focal length, gap) and a viewing distance. :class:`Panel` holds those numbers as
differentiable leaves and derives from them what the rest of lfjax needs: the views it puts
in the eye's pupil (a :class:`~lfjax.model.layouts.Layout`), its central depth plane (CDP), the
lenslets' Fresnel number and the :class:`~lfjax.display.lenslets.DisplayOptics` (lenslet diffraction
and pixel blur) of the pipeline; and what a maker is quoted: the pixel's angular size and
the spatial sampling the lenslet array imposes on the image the eye sees.

Geometry (thin lenses, paraxial; lengths in mm; the eye's pupil at 0, the lenslets at
z_m, the panel at z_m + z_0). A pixel at the gap z_0 behind a lenslet of focal length f is
imaged to the CDP, a virtual image v = 1/V behind the lenslets, V = 1/z_0 − 1/f, so
L = z_m + v from the eye and CDP = 1000/L D (:class:`~lfjax.display.lenslets.LensletArray`). The
beam of one lenslet aimed at a CDP point fills its aperture a and, seen from that point,
reaches the pupil magnified by M = L/v = 1 + z_m·V: each view is M·a wide and the views of
neighbouring lenslets are M·Δu apart (Δu the lenslet pitch; the paper's Eq. 1 at the CDP).
So the pupil of diameter D holds D/(M·Δu) views across (:attr:`Panel.views_across`).

Views per pupil. The design convention of this module: the eye's pupil is centred on the
grid of views (on a view when the count is odd, between four when even), and the views
counted are the n×n central ones that fit across the pupil, n = ⌊D/(M·Δu)⌋: their discs
reach at most n·M·Δu/2 ≤ D/2 from the centre along each axis, as the paper's tangent n×n
grids do (which are n = D/(M·Δu) exactly). A panel with fewer than one view across the
pupil is refused: some eye positions would then receive no view, and none a light field.

What each lenslet shows. One pixel pitch p on the panel subtends p/(z_0·M) rad at the eye
once imaged to the CDP (:meth:`Panel.pixel_arcmin`); the lenslet pitch subtends Δu/z_m rad
(:meth:`Panel.lenslet_arcmin`). A lenslet's elemental image, Δu·(z_m + z_0)/z_m wide so
that every lenslet aims its views at one eye box, is seen through the lenslet's centre from
a zone Δu·(1 + z_m/z_0) wide at the eye (:meth:`Panel.eye_box_mm`, the viewing zone of
integral imaging).

Validation happens on construction, on concrete values only (under ``jit`` or ``grad`` the
values are tracers and are not checked): every length finite and > 0 (the focal length may
be ``inf``: a pinhole or barrier array), fills in (0, 1], a gap at most the focal length
(otherwise the CDP is a real image in front of the display, not modelled), a lenslet at
least one pixel wide, and at least one view across the pupil.

Presets (:func:`near_eye_microdisplay`, :func:`phone_panel`) are two real classes of panel
with the source of each number stated in their docstrings.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lfjax.display.lenslets import DisplayOptics, LensletArray, check_choices
from lfjax.model.layouts import Layout
from lfjax.base.errors import ParameterError
from lfjax.base.units import ARCMIN_PER_RADIAN, DEGREES_PER_RADIAN, check_dioptres

MM_PER_INCH = 25.4


def _as_real(x):
    return jnp.asarray(x, dtype=jnp.result_type(float))


def _concrete(*values) -> bool:
    try:
        for v in values:
            np.asarray(v, float)
    except Exception:  # noqa: BLE001 - a tracer cannot become a host array
        return False
    return True


def _scalar(name: str, value, lo: float, hi: float = math.inf, lo_open: bool = True,
            allow_inf: bool = False, unit: str = "mm") -> float:
    v = np.asarray(value, float)
    if v.shape != ():
        raise ParameterError(name, "{%s} must be a scalar, got shape {shape}" % name, owner="Panel",
                             shape=v.shape)
    x = float(v)
    ok_lo = x > lo if lo_open else x >= lo
    ok = ok_lo and x <= hi and (math.isfinite(x) or (allow_inf and x == math.inf))
    if not ok:
        left = "(" if lo_open else "["
        right = "inf]" if allow_inf and hi == math.inf else (f"{hi:g}]" if math.isfinite(hi) else "inf)")
        extra = " (inf: a pinhole or barrier array)" if allow_inf else ""
        raise ParameterError(name, "{%s} must be in {left}{lo:g}, {right} {unit}{extra}, got {x:g}" % name,
                             owner="Panel", left=left, lo=lo, right=right, unit=unit, extra=extra, x=x)
    return x


class Panel(eqx.Module):
    """A light-field display as built: pixel panel, lenslet array and viewing distance.

    Attributes (array leaves are differentiable; lengths in mm)
    ----------
    pixel_pitch_mm : () pixel pitch p of the panel, mm
    lenslet_pitch_mm : () lenslet pitch Δu, mm (≥ p: a lenslet covers at least one pixel)
    fill : () lenslet aperture / pitch (linear), in (0, 1]; a = fill·Δu
    focal_length_mm : () lenslet focal length f, mm (> 0; ``inf`` for a pinhole array)
    gap_mm : () panel–lenslet distance z_0, mm, in (0, f]
    distance_mm : () viewing distance z_m, eye pupil to lenslet array, mm
    pixel_fill : () emitting fraction of a pixel's area, in (0, 1] (square emitter of side
        p·√pixel_fill; this, not the pitch, blurs the image)
    pixel_count : (static) pixels (horizontal, vertical) of the panel
    pupil_diameter_mm : (static) the eye pupil the panel is designed for, mm (views per
        pupil and the layout are counted in it; validation needs one view across it)
    aperture, diffraction : (static) lenslet aperture shape (``"circle"``, ``"square"``)
        and diffraction mode (:data:`lfjax.display.lenslets.DIFFRACTION_MODES`)
    name : (static) label

    Examples
    --------
    A 460 ppi phone panel behind 0.45 mm lenslets of 3 mm focal length, seen from 350 mm,
    its gap set for a CDP at 2 D:

    >>> import lfjax
    >>> panel = lfjax.Panel.with_cdp(cdp_D=2.0, pixel_pitch_mm=0.0552, lenslet_pitch_mm=0.45,
    ...                              focal_length_mm=3.0, distance_mm=350.0)
    >>> panel.n_views_per_side()  # 2×2 views in the 3 mm design pupil
    2
    >>> round(float(panel.fresnel_number()), 2)  # at 550 nm: each view diffracts
    0.88
    >>> panel.layout().centres_mm.shape  # the views as a Layout for through_focus
    (4, 2)
    """

    pixel_pitch_mm: jnp.ndarray = eqx.field(converter=_as_real)
    lenslet_pitch_mm: jnp.ndarray = eqx.field(converter=_as_real)
    fill: jnp.ndarray = eqx.field(converter=_as_real)
    focal_length_mm: jnp.ndarray = eqx.field(converter=_as_real)
    gap_mm: jnp.ndarray = eqx.field(converter=_as_real)
    distance_mm: jnp.ndarray = eqx.field(converter=_as_real)
    pixel_fill: jnp.ndarray = eqx.field(converter=_as_real, default=1.0)
    pixel_count: tuple = eqx.field(static=True, default=(1920, 1080))
    pupil_diameter_mm: float = eqx.field(static=True, default=3.0)
    aperture: str = eqx.field(static=True, default="circle")
    diffraction: str = eqx.field(static=True, default="fresnel")
    name: str = eqx.field(static=True, default="panel")

    def __check_init__(self):
        check_choices("Panel", aperture=self.aperture, diffraction=self.diffraction, spherical=True)
        counts = tuple(self.pixel_count)
        if (len(counts) != 2 or any(isinstance(c, bool) or int(c) != c or c < 1 for c in counts)):
            raise ParameterError("pixel_count", "{pixel_count} must be two integers >= 1 (horizontal, "
                                 "vertical), got {got!r}", owner="Panel", got=self.pixel_count)
        pupil = float(self.pupil_diameter_mm)
        if not (math.isfinite(pupil) and pupil > 0):
            raise ValueError(f"Panel.pupil_diameter_mm must be in (0, inf) mm, got {pupil:g}")
        leaves = (self.pixel_pitch_mm, self.lenslet_pitch_mm, self.fill, self.focal_length_mm,
                  self.gap_mm, self.distance_mm, self.pixel_fill)
        if not _concrete(*leaves):
            return
        p = _scalar("pixel_pitch_mm", self.pixel_pitch_mm, 0.0)
        du = _scalar("lenslet_pitch_mm", self.lenslet_pitch_mm, 0.0)
        _scalar("fill", self.fill, 0.0, 1.0, unit="(aperture/pitch)")
        _scalar("pixel_fill", self.pixel_fill, 0.0, 1.0, unit="(emitting area fraction)")
        f = _scalar("focal_length_mm", self.focal_length_mm, 0.0, allow_inf=True)
        g = _scalar("gap_mm", self.gap_mm, 0.0)
        zm = _scalar("distance_mm", self.distance_mm, 0.0)
        if g > f * (1 + 1e-9):
            image = 1.0 / (1.0 / f - 1.0 / g)  # real image this far in front of the lenslets
            where = ("behind the eye" if image >= zm else f"{zm - image:.4g} mm in front of the eye")
            raise ValueError(
                f"Panel.gap_mm={g:g} mm exceeds focal_length_mm={f:g} mm: the CDP would be a real "
                f"image {image:.4g} mm in front of the display ({where}), not a virtual image behind "
                f"it; allowed gap_mm in (0, {f:g}] mm (gap = f puts the CDP at infinity)")
        if du < p * (1 - 1e-9):
            raise ValueError(
                f"Panel.lenslet_pitch_mm={du:g} mm is smaller than a pixel (pixel_pitch_mm={p:g} mm): "
                f"every lenslet needs at least one pixel behind it; allowed lenslet_pitch_mm >= {p:g} mm")
        across = float(self.views_across)
        if across < 1.0 - 1e-9:
            limit = du / across
            raise ValueError(
                f"no view in the pupil: views are M·Δu = {limit:.4g} mm apart in the pupil "
                f"(lenslet_pitch_mm={du:g} mm magnified by M = {float(self.magnification):.4g}), wider "
                f"than the {pupil:g} mm pupil ({across:.3g} views across); allowed lenslet_pitch_mm "
                f"in [{p:g}, {du * across:.4g}] mm")

    # ------------------------------------------------------------------ constructors

    @classmethod
    def with_cdp(cls, *, cdp_D: float, pixel_pitch_mm, lenslet_pitch_mm, focal_length_mm,
                 distance_mm, fill=1.0, **kwargs) -> Panel:
        """A panel whose gap puts the CDP at ``cdp_D`` (D, in [0, 1000/distance_mm) and in the
        model's range, :func:`~lfjax.base.units.check_dioptres`) for lenslets of focal length
        ``focal_length_mm`` (mm, in (0, inf]; checked before the gap is computed):
        V = (1/L)/(1 − z_m/L) with L = 1000/cdp_D mm, gap = 1/(V + 1/f). Other keywords as
        :class:`Panel`."""
        cdp, zm = float(cdp_D), float(distance_mm)
        if not (math.isfinite(zm) and zm > 0):
            raise ParameterError("distance_mm", "{distance_mm} must be in (0, inf) mm, got {zm:g}", zm=zm)
        if not (math.isfinite(cdp) and 0 <= cdp < 1000.0 / zm):
            raise ParameterError(
                "cdp_D", "{cdp_D} must be in [0, {top:.4g}) D for a display at {distance_mm} = {zm:g} mm "
                "(the CDP is a virtual image behind the display), got {cdp:g}",
                top=1000.0 / zm, zm=zm, cdp=cdp)
        check_dioptres("cdp_D", cdp, "CDP")
        if _concrete(focal_length_mm):  # the gap divides by it (traced: Panel checks nothing)
            _scalar("focal_length_mm", focal_length_mm, 0.0, allow_inf=True)
        gap = gap_for_cdp_mm(cdp, focal_length_mm, zm)
        return cls(pixel_pitch_mm, lenslet_pitch_mm, fill, focal_length_mm, gap, zm, **kwargs)

    # ------------------------------------------------------------------ optics

    @property
    def lenslets(self) -> LensletArray:
        """The :class:`~lfjax.display.lenslets.LensletArray` of this panel (aperture fill·Δu)."""
        return LensletArray(self.lenslet_pitch_mm, self.fill * self.lenslet_pitch_mm,
                            self.focal_length_mm, self.gap_mm, self.distance_mm, self.aperture,
                            self.diffraction)

    @property
    def aperture_mm(self):
        """Lenslet aperture a = fill·Δu, mm (diameter, or side for square apertures)."""
        return self.fill * self.lenslet_pitch_mm

    @property
    def image_vergence_per_mm(self):
        """V = 1/z_0 − 1/f, 1/mm (0: the CDP at infinity)."""
        return self.lenslets.image_vergence_per_mm

    @property
    def magnification(self):
        """M = 1 + z_m·V: lenslet plane → pupil plane scale of the views (unitless, ≥ 1)."""
        return self.lenslets.magnification

    @property
    def cdp_D(self):
        """The central depth plane 1000/L, D (L = z_m + 1/V from the eye, mm; 0 when V = 0)."""
        return self.lenslets.cdp_D

    @property
    def view_pitch_mm(self):
        """Spacing of the views in the pupil, M·Δu, mm."""
        return self.lenslets.subaperture_pitch_mm

    @property
    def view_diameter_mm(self):
        """Geometric width of each view in the pupil, M·a, mm (diameter or side)."""
        return self.lenslets.subaperture_diameter_mm

    @property
    def views_across(self):
        """Views across the design pupil, D/(M·Δu) (continuous; the paper's n×n grids: n)."""
        return self.pupil_diameter_mm / self.view_pitch_mm

    def n_views_per_side(self) -> int:
        """n = ⌊D/(M·Δu)⌋, the views per side of the n×n grid in the pupil (host int ≥ 1)."""
        return max(int(math.floor(float(self.views_across) + 1e-4)), 1)

    def layout(self, n_per_side: int | None = None, offset_mm=(0.0, 0.0)) -> Layout:
        """The n×n central views in the design pupil (default n = :meth:`n_views_per_side`):
        centres M·Δu apart, shifted by ``offset_mm`` (mm), diameters M·a. Differentiable in
        the panel's leaves for a fixed n."""
        n = self.n_views_per_side() if n_per_side is None else n_per_side
        return self.lenslets.layout(self.pupil_diameter_mm, n, offset_mm,
                                    name=f"{self.name} {int(n)}x{int(n)}")

    @property
    def fresnel_distance_mm(self):
        """z_eff = z_m·M, the distance over which each magnified aperture diffracts, mm."""
        return self.lenslets.fresnel_distance_mm

    def fresnel_number(self, wavelength_nm=550.0):
        """Fresnel number of one lenslet, (a/2)²/(λ·z_m·v/L) = (M·a/2)²/(λ·z_eff)
        (unitless; ≫ 1 geometric views, ≲ 1 each view spreads over much of the pupil)."""
        return self.lenslets.fresnel_number(wavelength_nm)

    def optics(self, diffraction: str | None = None) -> DisplayOptics:
        """The pipeline's :class:`~lfjax.display.lenslets.DisplayOptics`: lenslet diffraction over
        z_eff and emitters of :meth:`emitter_arcmin`. ``diffraction`` overrides the panel's."""
        mode = self.diffraction if diffraction is None else diffraction
        return DisplayOptics(mode, self.aperture, self.fresnel_distance_mm, self.emitter_arcmin())

    # ------------------------------------------------------------------ what the eye sees

    def pixel_arcmin(self):
        """Angle one pixel pitch subtends at the eye once imaged to the CDP, p/(z_0·M) rad,
        in arcmin."""
        return self.pixel_pitch_mm / (self.gap_mm * self.magnification) * ARCMIN_PER_RADIAN

    def emitter_arcmin(self):
        """Angular width of one emitter (side p·√pixel_fill) on the CDP, arcmin."""
        return self.pixel_arcmin() * jnp.sqrt(self.pixel_fill)

    def lenslet_arcmin(self):
        """Angle the lenslet pitch subtends at the eye, Δu/z_m rad, in arcmin: the spacing
        of the image samples one point of the pupil sees (one per lenslet)."""
        return self.lenslet_pitch_mm / self.distance_mm * ARCMIN_PER_RADIAN

    def aperture_arcmin(self):
        """Angle a lenslet aperture subtends at the eye, a/z_m rad, in arcmin."""
        return self.aperture_mm / self.distance_mm * ARCMIN_PER_RADIAN

    def nyquist_cpd(self):
        """Nyquist frequency of the lenslet sampling seen by the eye, 1/(2·Δu/z_m) cycles
        per radian, in cpd (Hoshino et al. 1998's β_nyq = L/(2·p_L))."""
        return self.distance_mm / (2.0 * self.lenslet_pitch_mm) / DEGREES_PER_RADIAN

    def pixel_nyquist_cpd(self):
        """Nyquist frequency of the pixels imaged to the CDP, 1/(2·pixel angle), cpd."""
        return 1.0 / (2.0 * self.pixel_arcmin() / 60.0)

    def pixels_per_lenslet(self):
        """Pixels across one lenslet, Δu/p (unitless; the directions each lenslet emits)."""
        return self.lenslet_pitch_mm / self.pixel_pitch_mm

    def depth_step_D(self):
        """The change of rendered depth, D, that moves the images of two neighbouring views
        apart by one pixel: pixel angle (rad) × 1000 / view pitch (mm). Two views M·Δu apart
        part by M·Δu·ΔD/1000 rad per ΔD dioptres, and a renderer that lights whole pixels
        can only turn a view in pixel steps; finer depths need a point spread over
        neighbouring pixels (:mod:`lfjax.studies.array_views`)."""
        return self.pixel_arcmin() / ARCMIN_PER_RADIAN * 1000.0 / self.view_pitch_mm

    def emitter_sweep_mm(self):
        """How far a lenslet's beam footprint moves at the eye across one emitter,
        z_m·p·√pixel_fill/z_0, mm. The pipeline's pixel blur (one footprint for the whole
        emitter) holds while this is small beside the view width M·a; beyond it, different
        parts of a pixel reach different parts of the pupil (:mod:`lfjax.studies.array_views`)."""
        return self.distance_mm * self.pixel_pitch_mm * jnp.sqrt(self.pixel_fill) / self.gap_mm

    def eye_box_mm(self):
        """Width of the zone at the eye's distance from which every lenslet shows its own
        elemental image, Δu·(1 + z_m/z_0), mm."""
        return self.lenslet_pitch_mm * (1.0 + self.distance_mm / self.gap_mm)

    @property
    def active_size_mm(self) -> tuple[float, float]:
        """Active area (width, height) of the panel, pixel_count × p, mm (host floats)."""
        p = float(self.pixel_pitch_mm)
        return (self.pixel_count[0] * p, self.pixel_count[1] * p)

    def lenslet_count(self) -> tuple[float, float]:
        """Lenslets across the active area (width, height), host floats."""
        du = float(self.lenslet_pitch_mm)
        w, h = self.active_size_mm
        return (w / du, h / du)

    def field_of_view_deg(self) -> tuple[float, float]:
        """Angles (horizontal, vertical) the lenslet array over the active area subtends at
        the eye, 2·atan(size/(2·z_m)), degrees (host floats)."""
        zm = float(self.distance_mm)
        return tuple(2.0 * math.degrees(math.atan(0.5 * s / zm)) for s in self.active_size_mm)

    def summary(self, wavelength_nm: float = 550.0) -> dict:
        """Every derived quantity as host numbers, keyed with their units."""
        w, h = self.active_size_mm
        fov = self.field_of_view_deg()
        cnt = self.lenslet_count()
        f = float(self.focal_length_mm)
        return {
            "cdp_D": float(self.cdp_D),
            "magnification": float(self.magnification),
            "view_pitch_mm": float(self.view_pitch_mm),
            "view_diameter_mm": float(self.view_diameter_mm),
            "views_across_pupil": float(self.views_across),
            "views_per_side": self.n_views_per_side(),
            "fresnel_number": float(self.fresnel_number(wavelength_nm)),
            "pixel_arcmin": float(self.pixel_arcmin()),
            "emitter_arcmin": float(self.emitter_arcmin()),
            "lenslet_arcmin": float(self.lenslet_arcmin()),
            "nyquist_cpd": float(self.nyquist_cpd()),
            "pixel_nyquist_cpd": float(self.pixel_nyquist_cpd()),
            "pixels_per_lenslet": float(self.pixels_per_lenslet()),
            "eye_box_mm": float(self.eye_box_mm()),
            "emitter_sweep_mm": float(self.emitter_sweep_mm()),
            "depth_step_D": float(self.depth_step_D()),
            "f_number": f / float(self.aperture_mm) if math.isfinite(f) else math.inf,
            "active_width_mm": w, "active_height_mm": h,
            "lenslets_horizontal": cnt[0], "lenslets_vertical": cnt[1],
            "field_of_view_h_deg": fov[0], "field_of_view_v_deg": fov[1],
        }


def gap_for_cdp_mm(cdp_D, focal_length_mm, distance_mm):
    """The gap z_0 (mm) that puts the CDP at ``cdp_D`` (D) for lenslets of focal length f
    (mm) at ``distance_mm`` (mm): V = (1/L)/(1 − z_m/L), z_0 = 1/(V + 1/f), L = 1000/cdp_D.
    Differentiable; no checks (see :meth:`Panel.with_cdp`)."""
    inv_l = cdp_D / 1000.0
    vergence = inv_l / (1.0 - distance_mm * inv_l)
    return 1.0 / (vergence + 1.0 / focal_length_mm)


# ----------------------------------------------------------------------------- resolution


def sampling_limit_cpd(panel: Panel, depths_D):
    """Highest frequency (cpd) the display's ray sampling carries for a scene at
    ``depths_D`` (D, any shape): above it the pattern aliases into a coarser one.

    A bundle of rays from the display is one lenslet (position x on the lenslet plane,
    sampled every Δu) and one pixel (its image y on the CDP, sampled every p·v/z_0). A
    pattern of angular frequency β (cycles/rad, seen from the eye) at depth D varies along
    x with the weight (1 − t) and along y with t, where t places its plane between the
    lenslets (t = 0) and the CDP (t = 1); both samplings must hold it (Nyquist), which gives

        β_max(D) = (D_m − D_c) / (2·max(α_l·|D − D_c|, α_p·|D_m − D|)) cycles/rad,

    D_m = 1000/z_m the lenslet plane's and D_c the CDP's dioptres, α_l = Δu/z_m and
    α_p = p/(z_0·M) the angles (rad) of the lenslet pitch and of a pixel
    (:meth:`Panel.lenslet_arcmin`, :meth:`Panel.pixel_arcmin`). On the lenslet plane it is
    the lenslets' Nyquist frequency :meth:`Panel.nyquist_cpd` (Hoshino et al. 1998's
    β_nyq = L/(2·p_L)); on the CDP it is the pixels' :meth:`Panel.pixel_nyquist_cpd`;
    between and beyond, the depth-dependent bandwidth of a sampled light field (Zwicker et
    al. 2006). Differentiable in the panel's leaves and the depths; same shape as
    ``depths_D``.

    References: H. Hoshino, F. Okano, H. Isono & I. Yuyama, "Analysis of resolution
    limitation of integral photography", J. Opt. Soc. Am. A 15, 2059–2065 (1998);
    M. Zwicker, W. Matusik, F. Durand & H. Pfister, "Antialiasing for automultiscopic 3D
    displays", Eurographics Symposium on Rendering (2006).
    """
    d = jnp.asarray(depths_D, dtype=jnp.result_type(float))
    d_m = 1000.0 / panel.distance_mm
    d_c = panel.cdp_D
    alpha_l = panel.lenslet_pitch_mm / panel.distance_mm
    alpha_p = panel.pixel_arcmin() / ARCMIN_PER_RADIAN
    worst = jnp.maximum(alpha_l * jnp.abs(d - d_c), alpha_p * jnp.abs(d_m - d))
    return (d_m - d_c) / (2.0 * worst) / DEGREES_PER_RADIAN


# ----------------------------------------------------------------------------- presets


def near_eye_microdisplay(distance_mm: float = 30.0, cdp_D: float = 1.5,
                          lenslet_pitch_mm: float = 1.0, focal_length_mm: float = 3.3,
                          fill: float = 1.0, pupil_diameter_mm: float = 3.0) -> Panel:
    """A near-eye integral-imaging display on a 0.7-inch 1920×1080 OLED microdisplay.

    Panel: the 0.7-inch (17.8 mm diagonal) 16:9 full-HD OLED microdisplay class (e.g. Sony
    ECX335, published as 0.7-type, 1920×1080): its diagonal over √(1920² + 1080²) pixels
    gives a pitch of 8.1 µm, and ``pixel_fill`` 1 (OLED microdisplays have nearly
    contiguous emitters). Lenslets: typical of near-eye light-field prototypes, a
    1 mm pitch, 3.3 mm focal-length microlens array a few centimetres (``distance_mm`` =
    30 mm) from the eye, gap set for a CDP at ``cdp_D`` (1.5 D). Typical values, not one
    product's."""
    pitch = 0.7 * MM_PER_INCH / math.hypot(1920, 1080)
    return Panel.with_cdp(cdp_D=cdp_D, pixel_pitch_mm=pitch, lenslet_pitch_mm=lenslet_pitch_mm,
                          focal_length_mm=focal_length_mm, distance_mm=distance_mm, fill=fill,
                          pixel_count=(1920, 1080), pupil_diameter_mm=pupil_diameter_mm,
                          name="near-eye microdisplay")


def phone_panel(distance_mm: float = 350.0, cdp_D: float = 2.0, lenslet_pitch_mm: float = 0.45,
                focal_length_mm: float = 3.0, fill: float = 1.0,
                pupil_diameter_mm: float = 3.0) -> Panel:
    """A phone-sized light-field display viewed at arm's length (350 mm).

    Panel: a 460 ppi, 2532×1170 OLED phone panel (the published resolution and density of
    e.g. the iPhone 12 Pro): pitch 25.4/460 = 55.2 µm. Lenslets: typical, a 0.45 mm
    pitch (two views across a 3 mm pupil at a 2 D CDP) and 3 mm focal length, which gives
    an eye box of about 50 mm, gap set for a CDP at ``cdp_D`` (2 D, 500 mm). Typical values,
    not one product's."""
    return Panel.with_cdp(cdp_D=cdp_D, pixel_pitch_mm=MM_PER_INCH / 460.0,
                          lenslet_pitch_mm=lenslet_pitch_mm, focal_length_mm=focal_length_mm,
                          distance_mm=distance_mm, fill=fill, pixel_count=(2532, 1170),
                          pupil_diameter_mm=pupil_diameter_mm, name="phone panel")


PRESETS = {"near-eye": near_eye_microdisplay, "phone": phone_panel}
"""Named presets for the command line: ``lfjax design --panel near-eye|phone``."""


__all__ = [
    "Panel",
    "gap_for_cdp_mm",
    "sampling_limit_cpd",
    "perceivable_cutoff_cpd",
    "perceivable_cutoff_at_peak",
    "near_eye_microdisplay",
    "phone_panel",
    "PRESETS",
    "MM_PER_INCH",
]
