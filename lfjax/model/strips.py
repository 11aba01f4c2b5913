"""Horizontal-parallax-only (HPO) views: 1×n vertical strips of the pupil, and view neighbours.

A lenticular (cylindrical-lenslet) display separates its views along x only: each view
fills a strip of the pupil, ``width`` wide along x and unbounded along y (the pupil crops it
to its chord). :func:`strip_layout` puts n such strips side by side, ``pitch`` apart and
centred on the pupil; a width above the pitch overlaps neighbouring views, below it leaves
gaps. A :class:`~lfjax.model.layouts.Layout` carries centres and widths only; the strip
*shape* is the display's (``DisplayOptics(aperture="strip")`` or
:class:`lfjax.display.lenticular.ViewOptics`), which every computation on a strip layout
must be given (:func:`lfjax.display.lenticular.strip_display`).

:func:`neighbour_matrix` says which views are neighbours (the nearest ones in the layout),
the geometry of the leakage model of :mod:`lfjax.display.lenticular`.
"""

from __future__ import annotations

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.model.layouts import Layout, make_layout


def _positive(name: str, value, unit: str = "mm") -> float:
    v = float(value)
    if not (np.isfinite(v) and v > 0):
        raise ParameterError(name, "{%s} must be finite and > 0 %s, got {got}" % (name, unit),
                             got=v)
    return v


def strip_layout(n_views: int, pupil_diameter_mm: float = 3.0, *, pitch_mm: float | None = None,
                 width_mm: float | None = None, name: str | None = None) -> Layout:
    """n vertical strips side by side along x, centred on the pupil (an HPO layout).

    Parameters
    ----------
    n_views : number of strips across the pupil, integer ≥ 1
    pupil_diameter_mm : the pupil they fill, mm
    pitch_mm : centre spacing along x, mm (default pupil/n: n tangent strips filling it, the
        pitch of the paper's n×n grid of the same pupil)
    width_mm : each strip's width along x, mm (default the pitch; > pitch overlaps the
        neighbours, < pitch leaves gaps)
    name : label (default ``"1xN strips"``, with the width/pitch ratio when not 1)

    The layout's window is the pupil (a strip spans the pupil's height). Raises
    :class:`~lfjax.base.errors.ParameterError` naming the parameter, its unit and range.

    Examples
    --------
    >>> from lfjax.model.strips import strip_layout
    >>> layout = strip_layout(3, 3.0)
    >>> [float(x) for x in layout.centres_mm[:, 0]]  # mm
    [-1.0, 0.0, 1.0]
    """
    if isinstance(n_views, bool) or int(n_views) != n_views or n_views < 1:
        raise ParameterError("n_views", "{n_views} must be an integer >= 1 (views across the "
                             "pupil), got {got!r}", got=n_views)
    n = int(n_views)
    pupil = _positive("pupil_diameter_mm", pupil_diameter_mm)
    pitch = pupil / n if pitch_mm is None else _positive("pitch_mm", pitch_mm)
    width = pitch if width_mm is None else _positive("width_mm", width_mm)
    if width > 2.0 * pupil:
        raise ParameterError("width_mm", "{width_mm} must be in (0, {limit:g}] mm (twice the "
                             "pupil: a wider strip is the open pupil), got {got:g}",
                             limit=2.0 * pupil, got=width)
    x = (np.arange(n) - (n - 1) / 2.0) * pitch
    centres = np.stack([x, np.zeros(n)], axis=1)
    if name is None:
        ratio = width / pitch
        name = f"1x{n} strips" + ("" if abs(ratio - 1) < 1e-12 else f" w/p {ratio:.3g}")
    return make_layout(centres, np.full(n, width), pupil, name=name, window_diameter_mm=pupil)


def neighbour_matrix(layout: Layout, tolerance: float = 1e-6) -> np.ndarray:
    """(n, n) 0/1 matrix of each view's nearest neighbours in ``layout`` (host, float64).

    Views m and n are neighbours when their centres are the layout's smallest centre spacing
    apart (within ``tolerance`` relative): the adjacent strips of a 1×n layout, the four
    edge neighbours on an n×n grid. One view has none (a zero matrix)."""
    c = np.asarray(layout.centres_mm, float).reshape(-1, 2)
    n = c.shape[0]
    if n == 1:
        return np.zeros((1, 1))
    d = np.hypot(c[:, None, 0] - c[None, :, 0], c[:, None, 1] - c[None, :, 1])
    off = d[~np.eye(n, dtype=bool)]
    nearest = off.min()
    return ((np.abs(d - nearest) <= tolerance * nearest) & ~np.eye(n, dtype=bool)).astype(float)


__all__ = ["strip_layout", "neighbour_matrix"]
