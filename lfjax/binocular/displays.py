"""What each eye receives from a point rendered on the midline, per kind of display.

Each display says, for rendered depths d (D), which monocular computations each eye's
through-focus is (:meth:`runs`): the layout of views entering the pupil, the depths the
eye's image is rendered at and the :class:`~lfjax.Viewing` (whose CDP is where a single
view's image lies: a real point at d is a sharp image at a "screen" at d). The vergence demand is the rendered depth itself
(:mod:`lfjax.binocular.geometry`) for every display: both eyes' images are placed for a
point at d.

* :class:`NaturalViewing` — a real point: each eye sees it through its open pupil at d.
* :class:`StereoDisplay` — a conventional stereo display: each eye a sharp image on the
  screen, so each eye's stimulus is the screen (``screen_D``) whatever d.
* :class:`NearEyeDisplay` — a binocular near-eye light-field display: one display per eye,
  each eye its own views (``views``, e.g. n×n) of the point at d, the monocular model per
  eye; both displays carry the same layout (a real headset mirrors the right display;
  for layouts symmetric in x, as every grid is, the two agree).
* :class:`PanelDisplay` — a desktop or phone light-field panel (:class:`~lfjax.display.panel.Panel`) seen
  by both eyes from their own positions, x = ∓IPD/2 from the midline: the lenslet grid is
  aligned so that an eye on the midline sees the panel's design layout
  (:meth:`lfjax.display.panel.Panel.layout`), and an eye at x sees the same views shifted by −x, wrapped
  into half a view pitch (the paraxial geometry is the same behind every lenslet). Both
  eyes must lie inside the panel's viewing zone (:meth:`lfjax.display.panel.Panel.eye_box_mm`, centred on
  the midline): IPD + pupil ≤ its width, else the viewer is refused.

:meth:`runs` returns ``(layout, depths_D, viewing, eye_rows)`` tuples; ``eye_rows`` says which
eyes of the stacked batch (the n left eyes, then the n right eyes) the run computes (None: all).
"""


from __future__ import annotations

import equinox as eqx
import numpy as np

from lfjax.vision.viewing import Viewing

from lfjax.base.errors import ParameterError
from lfjax.base.units import check_dioptres
from lfjax.display.panel import Panel
from lfjax.model.layouts import Layout


class NaturalViewing(eqx.Module):
    """A real point at the rendered depth, seen through each eye's open pupil."""

    name: str = eqx.field(static=True, default="natural")

    def runs(self, depths_D, viewing: Viewing, ipd_mm=None) -> list:
        """One monocular run per depth: the open pupil, the point sharp at d (CDP d)."""
        return [(None, np.asarray([d]), Viewing(viewing.pupil_diameter_mm, float(d)), None)
                for d in np.asarray(depths_D, float)]

    def check_fits(self, viewer, pupil_diameter_mm: float) -> None:
        """Nothing to refuse: every pair of eyes sees a real point."""


class StereoDisplay(eqx.Module):
    """A conventional stereo display: each eye a sharp image at the screen.

    Attributes
    ----------
    screen_D : the screen's dioptric distance, D, in the model's range [0, 10] D
    """

    screen_D: float = eqx.field(static=True, converter=float)
    name: str = eqx.field(static=True, default="stereo")

    def __check_init__(self):
        check_dioptres("screen_D", self.screen_D, "screen distance")

    def runs(self, depths_D, viewing: Viewing, ipd_mm=None) -> list:
        """One run, the screen: the eyes' through-focus does not depend on d."""
        return [(None, np.asarray([self.screen_D]),
                 Viewing(viewing.pupil_diameter_mm, self.screen_D), None)]

    def check_fits(self, viewer, pupil_diameter_mm: float) -> None:
        """Nothing to refuse: a screen is seen from anywhere in front of it."""


class NearEyeDisplay(eqx.Module):
    """A binocular near-eye light-field display: one display per eye, each with ``views``.

    Attributes
    ----------
    views : the views each eye's pupil receives (:class:`~lfjax.Layout`)
    lens_separation_mm : distance between the two displays' optical axes, mm, or None (set
        to each viewer's IPD)
    eye_box_mm : diameter of each display's eye box (the region its pupil may occupy), mm,
        or None (unbounded). With both set, each viewer's pupil must lie inside its eye
        box: |IPD − separation| / 2 + pupil / 2 ≤ eye_box / 2.
    """

    views: Layout
    lens_separation_mm: float | None = eqx.field(static=True, default=None)
    eye_box_mm: float | None = eqx.field(static=True, default=None)
    name: str = eqx.field(static=True, default="near_eye")

    def __check_init__(self):
        if not isinstance(self.views, Layout):
            raise ParameterError("views", "{views} must be lfjax.Layout (each eye's views), "
                                 "got {got}", owner="NearEyeDisplay",
                                 got=type(self.views).__name__)
        for field, low, high in (("lens_separation_mm", 40.0, 90.0), ("eye_box_mm", 0.0, 40.0)):
            value = getattr(self, field)
            if value is not None and not (low < float(value) <= high):
                raise ParameterError(field, "{%s} must lie in (%g, %g] mm or be None, got {got}"
                                     % (field, low, high), owner="NearEyeDisplay", got=value)

    def runs(self, depths_D, viewing: Viewing, ipd_mm=None) -> list:
        """One run: each eye's display renders every depth with ``views`` (the CDP and
        optics of ``viewing``)."""
        return [(self.views, np.asarray(depths_D, float), viewing, None)]

    def check_fits(self, viewer, pupil_diameter_mm: float) -> None:
        """Refuse viewers whose pupils do not fit the eye boxes (ParameterError naming
        ``eye_box_mm``, mm and the viewers' IPDs), before any work."""
        if self.eye_box_mm is None or self.lens_separation_mm is None:
            return
        ipd = np.asarray(viewer.ipd_mm, float)
        reach = np.abs(ipd - self.lens_separation_mm) / 2.0 + pupil_diameter_mm / 2.0
        bad = reach > self.eye_box_mm / 2.0 + 1e-12
        if np.any(bad):
            raise ParameterError(
                "eye_box_mm", "{eye_box_mm} = {box:g} mm cannot hold both eyes: with lenses "
                "{sep:g} mm apart and a {pupil:g} mm pupil it needs IPDs within ±{room:g} mm "
                "of {sep:g} mm, got IPDs {got} mm", owner="NearEyeDisplay",
                box=self.eye_box_mm, sep=self.lens_separation_mm, pupil=pupil_diameter_mm,
                room=max(self.eye_box_mm - pupil_diameter_mm, 0.0),
                got=np.round(ipd[bad], 3).tolist()[:5])


class PanelDisplay(eqx.Module):
    """A light-field panel seen by both eyes from their own positions.

    Attributes
    ----------
    panel : :class:`~lfjax.display.panel.Panel` (its CDP, optics and design pupil; the computation's pupil
        is the panel's design pupil)
    n_per_side : views per side of each eye's grid, or None (the panel's
        :meth:`~lfjax.display.panel.Panel.n_views_per_side`)
    """

    panel: Panel
    n_per_side: int | None = eqx.field(static=True, default=None)
    name: str = eqx.field(static=True, default="panel")

    def __check_init__(self):
        if not isinstance(self.panel, Panel):
            raise ParameterError("panel", "{panel} must be lfjax.Panel, got {got}",
                                 owner="PanelDisplay", got=type(self.panel).__name__)

    def eye_offsets_mm(self, ipd_mm) -> np.ndarray:
        """(2, n_viewers) each eye's view-grid offset in its pupil, mm: −x wrapped into
        [−pitch/2, pitch/2), x = −IPD/2 (left eye) and +IPD/2 (right eye)."""
        pitch = float(self.panel.view_pitch_mm)
        x = 0.5 * np.asarray(ipd_mm, float)[None] * np.array([[-1.0], [1.0]])
        return (-x + 0.5 * pitch) % pitch - 0.5 * pitch

    def runs(self, depths_D, viewing: Viewing, ipd_mm=None) -> list:
        """One run per eye (its own offset), every depth, the panel's CDP and optics."""
        offsets = self.eye_offsets_mm(ipd_mm)
        n = offsets.shape[1]
        own = Viewing(self.panel.pupil_diameter_mm, float(self.panel.cdp_D),
                      self.panel.optics())
        depths = np.asarray(depths_D, float)
        return [(self.panel.layout(self.n_per_side, (float(offsets[side, i]), 0.0)), depths,
                 own, [side * n + i]) for side in (0, 1) for i in range(n)]

    def check_fits(self, viewer, pupil_diameter_mm: float) -> None:
        """Refuse viewers whose eyes do not both lie in the panel's viewing zone."""
        zone = float(self.panel.eye_box_mm())
        ipd = np.asarray(viewer.ipd_mm, float)
        bad = ipd + self.panel.pupil_diameter_mm > zone + 1e-12
        if np.any(bad):
            raise ParameterError(
                "eye_box_mm", "the panel's viewing zone ({eye_box_mm}) is {zone:.4g} mm wide and "
                "cannot hold both eyes: it needs IPD + pupil ≤ {zone:.4g} mm, got IPDs {got} mm "
                "with a {pupil:g} mm pupil", owner="Panel", zone=zone,
                pupil=self.panel.pupil_diameter_mm, got=np.round(ipd[bad], 3).tolist()[:5])


Display = NaturalViewing | StereoDisplay | NearEyeDisplay | PanelDisplay
DISPLAYS = (NaturalViewing, StereoDisplay, NearEyeDisplay, PanelDisplay)


def check_display(display) -> Display:
    """``display`` itself when it is one of :data:`DISPLAYS`; else a ParameterError."""
    if not isinstance(display, DISPLAYS):
        raise ParameterError("display", "{display} must be NaturalViewing(), StereoDisplay("
                             "screen_D), NearEyeDisplay(views) or PanelDisplay(panel), got {got}",
                             got=type(display).__name__)
    return display


__all__ = ["NaturalViewing", "StereoDisplay", "NearEyeDisplay", "PanelDisplay", "Display",
           "DISPLAYS",
           "check_display"]
