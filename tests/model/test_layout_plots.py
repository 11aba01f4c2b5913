"""Layout figures (lfjax.model.layout_plots): each declared aperture shape is drawn as
itself, a strip spanning the pupil's height."""

from __future__ import annotations

import numpy as np
import pytest

from matplotlib.figure import Figure

from lfjax.model.layout_plots import draw_layout, fig_layouts
from lfjax.model.layouts import grid_layout
from lfjax.model.strips import strip_layout


@pytest.mark.parametrize("aperture, kind, height", [
    ("circle", "Circle", 1.5), ("square", "Rectangle", 1.5), ("strip", "Rectangle", 3.0)])
def test_each_shape_is_drawn_as_declared(aperture, kind, height):
    """Two patches per view (area, dashed edge) after the pupil's outline; a strip is the
    pupil tall (mm), a square as tall as it is wide."""
    layout = strip_layout(2, 3.0) if aperture == "strip" else grid_layout(2, 3.0)
    ax = Figure().add_subplot()
    draw_layout(ax, layout, 3.0, aperture=aperture)
    views = ax.patches[1:]
    assert len(views) == 2 * layout.n_subapertures
    assert {type(p).__name__ for p in views} == {kind}
    if kind == "Rectangle":
        assert views[0].get_height() == pytest.approx(height)
        assert views[0].get_width() == pytest.approx(float(np.asarray(layout.diameters_mm)[0]))
    with pytest.raises(ValueError, match="allowed: circle, square, strip"):
        draw_layout(ax, layout, 3.0, aperture="hexagon")


def test_fig_layouts_has_one_panel_per_layout():
    fig = fig_layouts({"before": grid_layout(2, 3.0), "after": grid_layout(3, 3.0)}, 3.0)
    assert len(fig.axes) == 2
