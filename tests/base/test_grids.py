"""Host grids in dioptres and nanometres (lfjax.base.grids): the end point kept, every
point the same float whichever way it is reached, and DepthGrid's depths and states."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from lfjax.base.grids import DECIMALS, DepthGrid, grid_size, inclusive_grid


@pytest.mark.parametrize("start, stop, step, points", [
    (0.0, 0.6, 0.2, [0.0, 0.2, 0.4, 0.6]),   # 3 × 0.2 = 0.6000000000000001 in floats
    (0.0, 0.7, 0.2, [0.0, 0.2, 0.4, 0.6]),   # stop off the grid: left out
    (400.0, 700.0, 100.0, [400.0, 500.0, 600.0, 700.0]),
    (1.5, 1.5, 0.1, [1.5]),
])
def test_inclusive_grid_keeps_the_end_on_the_grid(start, stop, step, points):
    grid = inclusive_grid(start, stop, step)
    assert grid.dtype == np.float64
    assert grid.tolist() == points  # exact: the points are rounded to 1e-9
    assert grid_size(start, stop, step) == len(points)


def test_a_point_is_the_same_float_however_it_is_reached():
    # 0.6 D as the 4th point of a 0.2 D grid and as the 7th of a 0.1 D grid
    assert inclusive_grid(0.0, 0.6, 0.2)[3] == inclusive_grid(0.0, 0.6, 0.1)[6] == 0.6
    grid = inclusive_grid(0.0, 5.0, 0.05)
    assert np.array_equal(grid, np.round(grid, DECIMALS))
    assert grid[-1] == 5.0 and grid.size == 101


def test_grid_size_of_a_zero_step_raises():
    with pytest.raises(ZeroDivisionError):
        grid_size(0.0, 1.0, 0.0)


@dataclass(frozen=True)
class _Config(DepthGrid):
    cdp_D: float = 2.0
    depth_offsets_D: tuple = (-0.3, 0.0, 0.1)
    accommodation_step_D: float = 0.25
    accommodation_max_D: float = 1.0


def test_depth_grid_reads_its_fields():
    config = _Config()
    assert config.depths_D.tolist() == [1.7, 2.0, 2.1]  # 2.0 + 0.1 = 2.1 exactly after rounding
    assert config.accommodation_D.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
