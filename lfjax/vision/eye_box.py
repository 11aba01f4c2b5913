"""The eye box as the eye sees it: the answers over a grid of pupil displacements.

A headset or a viewer's head rarely puts the pupil exactly where the display was designed
for. :class:`~lfjax.vision.viewing.Viewing`'s ``pupil_offset_mm`` moves the pupil by
Δ = (x, y) mm in the display's frame (+x to the viewer's right, +y up), gaze straight ahead;
every view then enters the pupil at ``centre − Δ`` and the pupil crops it
(:func:`~lfjax.vision.prepare.moved_layout`). This module maps what that does:

* :func:`views_reaching` — the views of a layout that still reach into the moved pupil
  (a view wholly outside brings no light; a computation refuses it);
* :func:`clipping_onset_mm` — how far the pupil moves along a direction before the first
  view starts to leave it (the geometry: pupil radius − |view centre| − view radius for a
  view on the line of motion);
* :func:`panel_views` — every view a :class:`~lfjax.display.panel.Panel` puts across its
  eye box (:meth:`~lfjax.display.panel.Panel.eye_box_mm`, the zone where each lenslet shows
  its own elemental image), not only the n×n that fill the design pupil;
* :func:`eye_box_map` — predicted accommodation and MTF cut-off over a grid of
  displacements, and the eye box: where the accommodation of every eye and depth stays
  within a tolerance (0.25 D by default) of the centred answer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.sampling import Sampling
from lfjax.display.panel import Panel
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import Spectrum
from lfjax.vision.focus import through_focus
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

DEFAULT_TOLERANCE_D = 0.25
"""Largest change of predicted accommodation, D, from the centred answer that the eye box
allows (a quarter dioptre, about the eye's depth of focus for a 3 mm pupil)."""


def _views(layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    return (np.asarray(layout.centres_mm, float).reshape(-1, 2),
            np.asarray(layout.diameters_mm, float).reshape(-1))


def views_reaching(layout: Layout, pupil_diameter_mm: float,
                   pupil_offset_mm=(0.0, 0.0)) -> Layout | None:
    """The views of ``layout`` that reach into a displaced pupil.

    ``layout`` in design coordinates (mm); the pupil of ``pupil_diameter_mm`` (mm) displaced
    by ``pupil_offset_mm`` (x, y) mm; the views with |centre − Δ| − diameter/2 < pupil/2. Still in design coordinates (a computation moves
    them, :func:`~lfjax.vision.prepare.moved_layout`), the window and name kept; None when
    no view reaches it (host)."""
    c, d = _views(layout)
    offset = np.asarray(pupil_offset_mm, float).reshape(2)
    keep = np.hypot(*(c - offset).T) - 0.5 * d < 0.5 * float(pupil_diameter_mm)
    if not np.any(keep):
        return None
    return Layout(c[keep], d[keep], layout.window_diameter_mm, layout.name)


def clipping_onset_mm(layout: Layout, pupil_diameter_mm: float, direction=(1.0, 0.0)) -> float:
    """How far (mm, ≥ 0) a pupil of ``pupil_diameter_mm`` (mm) moves from the design
    position along ``direction`` (x, y; normalised here) before the edge of some view of
    ``layout`` reaches the pupil's edge: the smallest t ≥ 0 with |c − t·u| + d/2 = D/2. A
    view already cropped at the design position gives 0; a view larger than the pupil is
    skipped (it is always cropped). For a view on the line of motion, behind it,
    t = D/2 − |c| − d/2. Host float; ``inf`` when no view qualifies."""
    c, d = _views(layout)
    u = np.asarray(direction, float).reshape(2)
    norm = float(np.hypot(*u))
    if not (norm > 0 and np.isfinite(norm)):
        raise ParameterError("direction", "{direction} must be a finite non-zero (x, y), got "
                             "{got!r}", got=direction)
    u = u / norm
    reach = 0.5 * float(pupil_diameter_mm) - 0.5 * d  # |c − t·u| may grow to this
    along = c @ u
    onsets = []
    for r, a, cc in zip(reach, along, c):
        if r < 0:
            continue
        inside = r * r - float(cc @ cc)
        if inside <= 0:
            onsets.append(0.0)
        else:  # the positive root of t² − 2at − inside = 0
            onsets.append(float(a + np.sqrt(a * a + inside)))
    return min(onsets) if onsets else float("inf")


def panel_views(panel: Panel) -> Layout:
    """Every view ``panel`` puts across its eye box: the views M·Δu apart on the grid of the
    design pupil's (:meth:`~lfjax.display.panel.Panel.layout`, same parity, so that the
    centred pupil sees the n×n central ones), those with both centre coordinates within
    ±eye_box/2 (:meth:`~lfjax.display.panel.Panel.eye_box_mm`). Beyond the box a lenslet
    shows its neighbour's elemental image (a ghost of the scene elsewhere), which this layout
    leaves out. Host arrays, design coordinates, mm."""
    half_box = 0.5 * float(panel.eye_box_mm())
    pitch = float(panel.view_pitch_mm)
    n = panel.n_views_per_side()
    across = n + 2 * int(np.ceil(half_box / pitch))
    wide = panel.layout(across)
    c, d = _views(wide)
    keep = np.all(np.abs(c) <= half_box * (1 + 1e-9), axis=1)
    return Layout(c[keep], d[keep], wide.window_diameter_mm, f"{panel.name} eye box")


@dataclass(frozen=True)
class EyeBoxMap:
    """Answers over a grid of pupil displacements (:func:`eye_box_map`).

    Attributes
    ----------
    offsets_x_mm : (n_x,) displacements along x, mm (+x the viewer's right)
    offsets_y_mm : (n_y,) displacements along y, mm (+y up)
    depths_D : (n_depth,) rendered depths, D
    accommodation_D : (n_eyes, n_depth, n_y, n_x) predicted accommodation (continuous VSOTF
        peak), D; NaN where no view reaches the pupil
    cutoff_cpd : (n_eyes, n_depth, n_y, n_x) MTF cut-off (5 % of the radial MTF) at the grid
        peak, cpd; NaN where no view reaches the pupil
    n_views : (n_y, n_x) views reaching the moved pupil
    centred_D : (n_eyes, n_depth) the answer at zero displacement, D
    tolerance_D : the eye box's tolerance, D
    """

    offsets_x_mm: np.ndarray
    offsets_y_mm: np.ndarray
    depths_D: np.ndarray
    accommodation_D: np.ndarray
    cutoff_cpd: np.ndarray
    n_views: np.ndarray
    centred_D: np.ndarray
    tolerance_D: float

    @property
    def inside(self) -> np.ndarray:
        """(n_y, n_x) bool: every eye's and depth's accommodation within ``tolerance_D`` of
        its centred answer (False where no view reaches the pupil)."""
        change = np.abs(self.accommodation_D - self.centred_D[..., None, None])
        return np.all(change <= self.tolerance_D + 1e-9, axis=(0, 1))

    def extent_mm(self, axis: str = "x") -> tuple[float, float]:
        """(low, high) mm: the grid displacements along ``axis`` ("x" through y = 0, "y"
        through x = 0) between which the eye box runs unbroken from the centre; the box's
        edge lies between each and the next grid point out."""
        xs, ys = self.offsets_x_mm, self.offsets_y_mm
        if axis == "x":
            line, values = self.inside[int(np.argmin(np.abs(ys))), :], xs
        elif axis == "y":
            line, values = self.inside[:, int(np.argmin(np.abs(xs)))], ys
        else:
            raise ParameterError("axis", "{axis} must be 'x' or 'y', got {got!r}", got=axis)
        centre = int(np.argmin(np.abs(values)))
        low = high = centre
        while low - 1 >= 0 and line[low - 1]:
            low -= 1
        while high + 1 < line.size and line[high + 1]:
            high += 1
        return float(values[low]), float(values[high])


def _offsets(name: str, values) -> np.ndarray:
    v = np.atleast_1d(np.asarray(values, float))
    if v.ndim != 1 or not np.all(np.isfinite(v)) or not np.any(v == 0):
        raise ParameterError(name, "{%s} must be a 1-D grid of finite displacements, mm, that "
                             "holds 0 (the centred answer), got {got!r}" % name, got=values)
    return v


def eye_box_map(eyes: Eyes, layout: Layout, depths_D, viewing: Viewing, offsets_x_mm,
                offsets_y_mm=(0.0,), *, tolerance_D: float = DEFAULT_TOLERANCE_D,
                spectrum: Spectrum | None = None, sampling: Sampling | None = None,
                options: ModelOptions = ModelOptions()) -> EyeBoxMap:
    """Predicted accommodation and MTF cut-off over a grid of pupil displacements.

    Parameters
    ----------
    eyes : the eyes
    layout : every view the display puts in the pupil plane, design coordinates, mm (a
        panel's whole eye box: :func:`panel_views`); at each displacement the views that
        reach the moved pupil are computed (:func:`views_reaching`)
    depths_D : (n_depth,) rendered depths, D; each through focus −1 … +1 D in 0.2 D steps
    viewing : pupil, CDP and display optics; its ``pupil_offset_mm`` is replaced by each
        grid point
    offsets_x_mm, offsets_y_mm : 1-D grids of displacements, mm, each holding 0
    tolerance_D : the eye box's tolerance on the accommodation change, D (> 0)
    spectrum, options : as :func:`~lfjax.vision.focus.through_focus`
    sampling : one sampling for every displacement (default: the one planned for the
        centred pupil), so that the map's changes are the displacement's, not the plan's

    The centred answer is the (0, 0) grid point's. Host loop, one compiled program per
    distinct number of views.
    """
    xs, ys = _offsets("offsets_x_mm", offsets_x_mm), _offsets("offsets_y_mm", offsets_y_mm)
    if not (float(tolerance_D) > 0):
        raise ParameterError("tolerance_D", "{tolerance_D} must be > 0 D, got {got!r}",
                             got=tolerance_D)
    states = States.around(depths_D)
    peaks = PeakOptions(metrics=("vsotf",))
    pupil = float(viewing.pupil_diameter_mm)

    def answer(x, y, sampling):
        views = views_reaching(layout, pupil, (x, y))
        if views is None:
            return None
        moved = Viewing(viewing.pupil_diameter_mm, viewing.cdp_D, viewing.display, (x, y))
        tf = through_focus(eyes, views, states, moved, spectrum=spectrum, sampling=sampling,
                           options=options, peaks=peaks)
        return tf, views.n_subapertures

    centred = answer(0.0, 0.0, sampling)
    if centred is None:
        raise ParameterError("layout", "{layout} {name!r} has no view in the centred pupil",
                             name=layout.name)
    sampling = centred[0].sampling
    n_eyes, n_depth = eyes.n_eyes, states.host_depths_D.size
    acc = np.full((n_eyes, n_depth, ys.size, xs.size), np.nan)
    cut = np.full_like(acc, np.nan)
    count = np.zeros((ys.size, xs.size), int)
    for iy, y in enumerate(ys):
        for ix, x in enumerate(xs):
            got = centred if x == 0 and y == 0 else answer(float(x), float(y), sampling)
            if got is None:
                continue
            tf, count[iy, ix] = got
            acc[..., iy, ix] = tf.continuous_accommodation_D()
            cut[..., iy, ix] = np.asarray(tf.cutoff_cpd())
    return EyeBoxMap(xs, ys, states.host_depths_D, acc, cut, count,
                     centred[0].continuous_accommodation_D(), float(tolerance_D))


__all__ = ["views_reaching", "clipping_onset_mm", "panel_views", "EyeBoxMap", "eye_box_map",
           "DEFAULT_TOLERANCE_D"]
