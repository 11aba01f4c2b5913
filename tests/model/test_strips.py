"""Strip (HPO) layouts and view neighbours (lfjax.model.strips)."""

from __future__ import annotations

import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.model.layouts import grid_layout
from lfjax.model.strips import neighbour_matrix, strip_layout


def test_strips_fill_the_pupil_at_the_grid_pitch():
    layout = strip_layout(4, 3.0)
    np.testing.assert_allclose(np.asarray(layout.centres_mm), [[-1.125, 0], [-0.375, 0], [0.375, 0], [1.125, 0]])
    np.testing.assert_allclose(np.asarray(layout.diameters_mm), 0.75)
    assert layout.window_diameter_mm == 3.0  # a strip spans the pupil's height
    # the same pitch as the 4x4 grid of the same pupil
    assert np.unique(np.round(np.asarray(grid_layout(4, 3.0).centres_mm)[:, 0], 9)).tolist() == \
        np.round(np.asarray(layout.centres_mm)[:, 0], 9).tolist()


def test_overlap_and_gap_widths():
    assert float(strip_layout(3, 3.0, width_mm=1.5).diameters_mm[0]) == 1.5
    assert strip_layout(3, 3.0, width_mm=1.5).name == "1x3 strips w/p 1.5"


@pytest.mark.parametrize("kwargs, parameter", [
    ({"n_views": 0}, "n_views"), ({"n_views": 2.5}, "n_views"),
    ({"n_views": 2, "width_mm": -1.0}, "width_mm"), ({"n_views": 2, "width_mm": 7.0}, "width_mm"),
    ({"n_views": 2, "pitch_mm": float("nan")}, "pitch_mm"),
    ({"n_views": 2, "pupil_diameter_mm": 0.0}, "pupil_diameter_mm"),
])
def test_bad_strips_name_the_parameter_unit_and_range(kwargs, parameter):
    with pytest.raises(ParameterError) as info:
        strip_layout(**kwargs)
    assert info.value.parameter == parameter
    assert parameter in str(info.value)


def test_neighbours_are_the_nearest_views():
    a = neighbour_matrix(strip_layout(3, 3.0))
    np.testing.assert_array_equal(a, [[0, 1, 0], [1, 0, 1], [0, 1, 0]])
    g = neighbour_matrix(grid_layout(2, 3.0))
    np.testing.assert_array_equal(g.sum(1), [2, 2, 2, 2])  # edge neighbours, not the diagonal
    assert neighbour_matrix(strip_layout(1, 3.0)).sum() == 0
